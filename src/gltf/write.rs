//! Write-back: the input document plus the bake, as GLB bytes.
//!
//! In: the loaded [`Scene`], its [`BakeGeometry`] and [`Atlas`], and the
//! [`Encoded`] images. Out: the GLB bytes, serialized once (the pipeline
//! writes them with [`crate::file::write_atomic`]). The document is edited as
//! `serde_json::Value`, so every field of the input survives except the
//! documented edits:
//! - each baked primitive: attributes re-indexed through the unwrapper's
//!   vertex map into new accessors, a new `TEXCOORD_n` (n = lowest free
//!   index), new triangle-list indices (`mode` 4), and
//!   `extensions.AOBAKE_lightmap`;
//! - a mesh placed by several nodes is copied so each node owns its lightmap
//!   region; a primitive with charts on several atlas pages becomes one
//!   primitive per page in its mesh; materials gain `occlusionTexture`
//!   (copied where shared across UV sets, pages or with unbaked
//!   primitives); each page's PNG images and their textures, and one
//!   sampler, are appended; the root gains `extensions.AOBAKE_lightmap`
//!   and the name in `extensionsUsed`;
//! - relative URIs of external buffers and images are rewritten to resolve
//!   from the output's directory (`super::uris`).

use super::accessor::{self, array};
use super::append::{Bin, f32_accessor, gather_accessor, index_accessor, insert_bin_buffer, push};
use super::container::{Document, glb_bytes};
use super::scene::Scene;
use super::uris::relocate_uris;
use crate::atlas::Atlas;
use crate::atlas::unwrap::ChartedMesh;
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::geometry::BakeGeometry;
use serde_json::{Value, json};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;

/// The extension name written to primitives and the root.
pub(crate) const EXTENSION: &str = "AOBAKE_lightmap";

/// What to do with a material that already has an occlusionTexture:
/// keep it (the bake is still in the extension), or replace it with the
/// baked AO.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum OcclusionMode {
    #[default]
    Keep,
    Replace,
}

/// Root-level facts recorded in `extensions.AOBAKE_lightmap`.
#[derive(Clone, Debug)]
pub struct BakeRecord {
    pub method: String,
    pub rays: u32,
    pub seed: u64,
    /// World units.
    pub max_distance: f64,
    pub width: u32,
    pub height: u32,
    /// The lookup the texels are fitted for (written when not bilinear).
    pub filter: crate::lightmap::Filter,
    /// `fingerprint` (`crate::job::reuse`), when the input's bytes are
    /// known; written last, unsealed.
    pub fingerprint: Option<Value>,
}

/// How the bake is written.
#[derive(Clone, Debug)]
pub struct OutputOptions {
    pub record: BakeRecord,
    pub occlusion: OcclusionMode,
    /// Per receiver mesh: it gets the visibility layer's fields (when the
    /// encoded lightmap has the layer).
    pub visibility_meshes: Vec<bool>,
    /// Bake into this existing TEXCOORD set instead of a generated one.
    pub existing_uv: Option<usize>,
    /// The directory the GLB will be written to: relative URIs of external
    /// buffers and images are rewritten to resolve from there. `None`:
    /// they stay relative to the input's directory.
    pub output_dir: Option<PathBuf>,
}

/// A baked primitive's new JSON, before it is placed into a mesh: one
/// primitive per atlas page it has charts on (the first takes the
/// original's place, the others are appended to the mesh).
struct PrimitiveEdit {
    node: usize,
    mesh: usize,
    primitive: usize,
    json: Vec<Value>,
}

/// Builds the output GLB.
pub fn build_glb(
    scene: &Scene,
    geometry: &BakeGeometry,
    atlas: &Atlas,
    pages: &[&Encoded],
    options: &OutputOptions,
    warnings: &mut Vec<String>,
) -> Result<Vec<u8>> {
    let doc = &scene.doc;
    let record = &options.record;
    let mut json = doc.json.clone();
    let mut bin = if doc.glb_bin {
        Bin::of(doc)
    } else {
        insert_bin_buffer(&mut json);
        Bin { data: Vec::new() }
    };

    // Images, sampler and textures of the bake, page by page.
    let sampler = push(
        &mut json,
        "samplers",
        json!({"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}),
    );
    let multi_page = pages.len() > 1;
    let layer_wanted = options.visibility_meshes.iter().any(|&v| v);
    let mut page_ext = Vec::with_capacity(pages.len());
    let mut visibility_order = None;
    for (p, encoded) in pages.iter().enumerate() {
        // Page 0's images keep the one-page names.
        let name = |base: &str| {
            if p == 0 {
                format!("aobake_{base}")
            } else {
                format!("aobake_page{p}_{base}")
            }
        };
        let mut texture = |json: &mut Value, png: &[u8], name: &str| -> usize {
            let view = bin.push_view(json, png, None, None);
            let image = push(
                json,
                "images",
                json!({"name": name, "mimeType": "image/png", "bufferView": view}),
            );
            push(
                json,
                "textures",
                json!({"name": name, "sampler": sampler, "source": image}),
            )
        };
        let occlusion_tex = texture(&mut json, &encoded.occlusion_png, &name("occlusion"));
        let sh_tex: Vec<usize> = (0..3)
            .map(|i| texture(&mut json, &encoded.sh_png[i], &name(&format!("sh{i}"))))
            .collect();
        let mut ext = json!({
            "texCoord": 0,
            "occlusion": {"index": occlusion_tex},
            "sh": sh_tex.iter().map(|&t| json!({"index": t})).collect::<Vec<_>>(),
            "shScale": encoded.sh_scale,
            "shOffset": encoded.sh_offset,
        });
        if multi_page {
            ext["page"] = json!(p);
        }
        // The visibility layer's textures, when any primitive gets it.
        let layer = encoded.visibility.as_ref().filter(|_| layer_wanted).map(|layer| {
            let tex: Vec<Value> = layer
                .png
                .iter()
                .enumerate()
                .map(|(i, png)| json!({"index": texture(&mut json, png, &name(&format!("visibility{i}")))}))
                .collect();
            visibility_order = Some(if layer.scale.len() == 16 { 3 } else { 2 });
            json!({"visibility": tex, "visibilityScale": layer.scale, "visibilityOffset": layer.offset})
        });
        page_ext.push((ext, layer));
    }

    // New primitives: one per page a baked primitive has charts on.
    let mut edits = Vec::new();
    for (k, rm) in geometry.receivers.iter().enumerate() {
        let inst = &scene.instances[rm.instance];
        let g = &scene.geometries[inst.geometry];
        let charted = &atlas.meshes[k];
        let what = g.label();
        let original = &doc.json["meshes"][g.mesh]["primitives"][g.primitive];
        let mesh_pages = charted.pages();
        let pieces: Vec<(u32, std::borrow::Cow<ChartedMesh>)> = match mesh_pages.as_slice() {
            [] => vec![(0, std::borrow::Cow::Borrowed(charted))],
            [p] => vec![(*p, std::borrow::Cow::Borrowed(charted))],
            many => many
                .iter()
                .map(|&p| (p, std::borrow::Cow::Owned(charted.compact_page(p))))
                .collect(),
        };
        let mut prims = Vec::with_capacity(pieces.len());
        for (page, piece) in pieces {
            let mut prim = original.clone();
            let tex_coord = match options.existing_uv {
                Some(set) => set,
                None => add_lightmap_uvs(
                    &mut json,
                    &mut bin,
                    doc,
                    &mut prim,
                    &piece,
                    g.positions.len(),
                    &what,
                    warnings,
                )?,
            };
            let (page_ext, layer) = &page_ext[page as usize];
            let mut ext = page_ext.clone();
            ext["texCoord"] = json!(tex_coord);
            if let Some(layer) = layer
                && options.visibility_meshes.get(k).copied().unwrap_or(false)
            {
                for (key, v) in layer.as_object().expect("layer fields") {
                    ext[key] = v.clone();
                }
            }
            set_extension(&mut prim, ext);
            prims.push(prim);
        }
        edits.push(PrimitiveEdit {
            node: inst.node,
            mesh: g.mesh,
            primitive: g.primitive,
            json: prims,
        });
    }

    place_primitives(&mut json, edits.as_slice())?;
    assign_materials(&mut json, options.occlusion);

    // Root extension.
    let obj = json.as_object_mut().expect("root");
    let exts = obj.entry("extensions").or_insert_with(|| json!({}));
    exts[EXTENSION] = json!({
        "version": if multi_page { 2 } else { 1 },
        "method": record.method,
        "rays": record.rays,
        "seed": record.seed,
        "maxDistance": record.max_distance,
        "resolution": [record.width, record.height],
    });
    if multi_page {
        exts[EXTENSION]["pages"] = Value::Array(
            atlas
                .pages
                .iter()
                .map(|p| json!([p.width, p.height]))
                .collect(),
        );
    }
    if let Some(order) = visibility_order {
        exts[EXTENSION]["visibilityOrder"] = json!(order);
    }
    if !record.filter.is_bilinear() {
        exts[EXTENSION]["filter"] = json!(record.filter.name());
    }
    if let Some(f) = &record.fingerprint {
        exts[EXTENSION]["fingerprint"] = f.clone();
    }
    let used = obj.entry("extensionsUsed").or_insert_with(|| json!([]));
    if let Some(u) = used.as_array_mut()
        && !u.iter().any(|e| e == EXTENSION)
    {
        u.push(json!(EXTENSION));
    }
    while bin.data.len() % 4 != 0 {
        bin.data.push(0);
    }
    json["buffers"][0]["byteLength"] = json!(bin.data.len());
    if let Some(to) = &options.output_dir {
        relocate_uris(&mut json, &doc.base_dir, to)?;
    }
    #[cfg(feature = "contract-check")]
    super::schema_check::assert_valid(&json);
    Ok(glb_bytes(&json, &bin.data))
}

/// Re-indexes a primitive's attributes through the unwrapper's vertex map
/// into new accessors and adds the atlas UVs as `TEXCOORD_n` (n = the lowest
/// free index) with new triangle-list indices. Returns n.
#[allow(clippy::too_many_arguments)]
fn add_lightmap_uvs(
    json: &mut Value,
    bin: &mut Bin,
    doc: &Document,
    prim: &mut Value,
    charted: &ChartedMesh,
    vertex_count: usize,
    what: &str,
    warnings: &mut Vec<String>,
) -> Result<usize> {
    let attrs = prim["attributes"]
        .as_object()
        .ok_or_else(|| Error::Invalid(format!("{what}.attributes is not an object")))?
        .clone();
    let mut new_attrs = serde_json::Map::new();
    for (name, acc) in &attrs {
        let a = acc
            .as_u64()
            .ok_or_else(|| Error::Invalid(format!("{what}.attributes.{name} is not an index")))?;
        let raw = accessor::read(doc, a as usize)?;
        if raw.count != vertex_count {
            return Err(Error::Invalid(format!(
                "{what}.attributes.{name} has {} elements, POSITION has {}",
                raw.count, vertex_count
            )));
        }
        let had_bounds =
            doc.json["accessors"][a as usize].get("min").is_some() || name == "POSITION";
        new_attrs.insert(
            name.clone(),
            json!(gather_accessor(json, bin, &raw, &charted.xref, had_bounds)),
        );
    }
    let tex_coord = (0..)
        .find(|n| !attrs.contains_key(&format!("TEXCOORD_{n}")))
        .unwrap_or(0);
    if tex_coord > 3 {
        warnings.push(format!(
                "{what}: the lightmap UVs are TEXCOORD_{tex_coord}; several engines read only TEXCOORD_0..3"
            ));
    }
    let uv: Vec<f32> = charted.uv.iter().flatten().copied().collect();
    let uv_acc = f32_accessor(json, bin, &uv, "VEC2", 2);
    new_attrs.insert(format!("TEXCOORD_{tex_coord}"), json!(uv_acc));
    prim["attributes"] = Value::Object(new_attrs);
    prim["indices"] = json!(index_accessor(
        json,
        bin,
        &charted.triangles,
        charted.xref.len()
    ));
    if prim.get("mode").is_some() {
        prim["mode"] = json!(4);
    }
    Ok(tex_coord)
}

/// Sets `extensions.AOBAKE_lightmap` of a primitive, keeping other extensions.
fn set_extension(prim: &mut Value, ext: Value) {
    let obj = prim.as_object_mut().expect("primitive is an object");
    let exts = obj.entry("extensions").or_insert_with(|| json!({}));
    exts[EXTENSION] = ext;
}

/// Puts new primitives into meshes: in place when the mesh is placed only by
/// baked nodes (the first keeps the original), else in a copy per node.
fn place_primitives(json: &mut Value, edits: &[PrimitiveEdit]) -> Result<()> {
    let mut by_node: BTreeMap<usize, (usize, Vec<&PrimitiveEdit>)> = BTreeMap::new();
    for e in edits {
        by_node
            .entry(e.node)
            .or_insert((e.mesh, Vec::new()))
            .1
            .push(e);
    }
    let mut refs: HashMap<usize, BTreeSet<usize>> = HashMap::new();
    for (ni, n) in array(json, "nodes").iter().enumerate() {
        if let Some(m) = n.get("mesh").and_then(Value::as_u64) {
            refs.entry(m as usize).or_default().insert(ni);
        }
    }
    let mut in_place_taken: BTreeSet<usize> = BTreeSet::new();
    for (&node, (mesh, prims)) in &by_node {
        let all_baked = refs.get(mesh).is_some_and(|r| {
            r.iter()
                .all(|n| by_node.get(n).is_some_and(|(m, _)| m == mesh))
        });
        let target = if all_baked && in_place_taken.insert(*mesh) {
            *mesh
        } else {
            let copy = json["meshes"][*mesh].clone();
            let idx = push(json, "meshes", copy);
            json["nodes"][node]["mesh"] = json!(idx);
            idx
        };
        for e in prims {
            json["meshes"][target]["primitives"][e.primitive] = e.json[0].clone();
            if let Some(list) = json["meshes"][target]["primitives"].as_array_mut() {
                list.extend(e.json[1..].iter().cloned());
            }
        }
    }
    Ok(())
}

/// Gives every baked primitive a material showing the AO through the core
/// occlusionTexture, duplicating materials shared across UV sets or with
/// unbaked primitives.
fn assign_materials(json: &mut Value, mode: OcclusionMode) {
    // (mesh, primitive, material, (tex_coord, AO texture) or None for unbaked)
    type Use = (usize, usize, Option<usize>, Option<(usize, usize)>);
    let mut uses: Vec<Use> = Vec::new();
    for (mi, m) in array(json, "meshes").iter().enumerate() {
        for (pi, p) in array(m, "primitives").iter().enumerate() {
            let mat = p
                .get("material")
                .and_then(Value::as_u64)
                .map(|v| v as usize);
            let field = |f: &str| {
                p.pointer(&format!("/extensions/{EXTENSION}/{f}"))
                    .and_then(Value::as_u64)
                    .map(|v| v as usize)
            };
            let n = field("texCoord").zip(field("occlusion/index"));
            uses.push((mi, pi, mat, n));
        }
    }
    let shared_with_unbaked: BTreeSet<usize> = uses
        .iter()
        .filter(|u| u.3.is_none())
        .filter_map(|u| u.2)
        .collect();
    // As in the input: a material gets one occlusionTexture per page.
    let had_occlusion: BTreeSet<usize> = array(json, "materials")
        .iter()
        .enumerate()
        .filter(|(_, m)| m.get("occlusionTexture").is_some())
        .map(|(i, _)| i)
        .collect();
    let mut chosen: HashMap<(Option<usize>, (usize, usize)), usize> = HashMap::new();
    let mut edited_in_place: BTreeSet<usize> = BTreeSet::new();
    for &(mi, pi, mat, n) in &uses {
        let Some(n) = n else { continue };
        if mat.is_some_and(|m| had_occlusion.contains(&m)) && mode == OcclusionMode::Keep {
            continue;
        }
        let target = *chosen.entry((mat, n)).or_insert_with(|| match mat {
            Some(m) if !shared_with_unbaked.contains(&m) && edited_in_place.insert(m) => m,
            Some(m) => {
                let copy = json["materials"][m].clone();
                push(json, "materials", copy)
            }
            None => push(
                json,
                "materials",
                json!({"name": "aobake_default", "pbrMetallicRoughness": {}}),
            ),
        });
        let (n, occlusion_tex) = n;
        json["materials"][target]["occlusionTexture"] =
            json!({"index": occlusion_tex, "texCoord": n});
        if mat != Some(target) {
            json["meshes"][mi]["primitives"][pi]["material"] = json!(target);
        }
    }
}
