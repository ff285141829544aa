//! Load: a `.glb`/`.gltf` file into placed triangle geometry.
//!
//! In: a path. Out: a [`Scene`]: the untouched [`Document`] (for the
//! write-back), each triangle primitive decoded once ([`PrimitiveGeometry`]),
//! and every placement of it in the default scene ([`Instance`]) with its
//! world transform and whether it is baked or only occludes. [`Scene::bake_geometry`]
//! then maps everything into *bake space* (world recentred on the scene's
//! bounding box and divided by its diagonal), where the rest of the pipeline
//! works at unit scale whatever the file's units.

pub use super::accessor::primitive_label;
use super::accessor::{self, array, field_usize};
use super::container::{self, Document};
use super::decompress;
use crate::error::{Error, Result};
use crate::geometry::{BakeGeometry, BakeSpace, ReceiverMesh};
use glam::{DMat3, DMat4, DQuat, DVec3, Vec3A};
use serde_json::Value;
use std::collections::HashMap;
use std::path::Path;

/// Roughness below which a material's specular lobe is glossy enough to
/// need occluding by direction (`--visibility auto`): at roughness 0.3 AO
/// times the unoccluded reflection misses by about 0.2 where the layer
/// gives 0.02 (`shared/notes/visibility-sh.md`). 0.5 itself is left out:
/// it is Blender's default for a material nobody tuned (the Cornell box's
/// diffuse walls carry it), and its lobe is nearly as wide as the diffuse
/// one.
pub const GLOSSY_ROUGHNESS: f64 = 0.4;

/// Most triangles a scene may have (all instances), protecting memory.
pub const MAX_TRIANGLES: usize = 50_000_000;

/// One triangle primitive of one mesh, decoded.
#[derive(Debug, Clone)]
pub struct PrimitiveGeometry {
    pub mesh: usize,
    pub primitive: usize,
    /// POSITION in mesh space (dequantized).
    pub positions: Vec<[f32; 3]>,
    /// NORMAL in mesh space, if present.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Triangle list (strips and fans expanded), indexing `positions`.
    pub triangles: Vec<u32>,
    /// The primitive has morph targets (occludes in its base pose, not baked).
    pub morphed: bool,
    /// Its material is `doubleSided` (back faces are real surfaces).
    pub double_sided: bool,
}

impl PrimitiveGeometry {
    /// [`primitive_label`] of this primitive.
    pub fn label(&self) -> String {
        primitive_label(self.mesh, self.primitive)
    }
}

/// A placement of a primitive in the scene.
#[derive(Debug, Clone)]
pub struct Instance {
    pub node: usize,
    pub geometry: usize,
    /// Mesh space to world space.
    pub transform: DMat4,
    /// Whether this placement receives a lightmap (otherwise it only occludes).
    pub baked: bool,
}

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub doc: Document,
    pub geometries: Vec<PrimitiveGeometry>,
    pub instances: Vec<Instance>,
    /// Things the user should know (not baked, ignored), one line each.
    pub warnings: Vec<String>,
}

/// Reads a file and builds the [`Scene`].
pub fn load(path: &Path) -> Result<Scene> {
    let doc = container::read_file(path)?;
    Scene::from_document(doc)
}

/// [`load`], also returning the file's bytes (read once), for callers
/// that fingerprint the input they bake.
pub fn load_with_bytes(path: &Path) -> Result<(Vec<u8>, Scene)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let doc = container::parse(&bytes, crate::file::parent_dir(path))?;
    Ok((bytes, Scene::from_document(doc)?))
}

fn node_local(node: &Value, what: &str) -> Result<DMat4> {
    let nums = |key: &str, n: usize| -> Result<Option<Vec<f64>>> {
        match node.get(key) {
            None => Ok(None),
            Some(v) => {
                let a = v.as_array().filter(|a| a.len() == n).ok_or_else(|| {
                    Error::Invalid(format!("{what}.{key} must be an array of {n} numbers"))
                })?;
                a.iter()
                    .map(|x| {
                        x.as_f64().ok_or_else(|| {
                            Error::Invalid(format!("{what}.{key} must be an array of {n} numbers"))
                        })
                    })
                    .collect::<Result<Vec<_>>>()
                    .map(Some)
            }
        }
    };
    let m = if let Some(m) = nums("matrix", 16)? {
        DMat4::from_cols_slice(&m)
    } else {
        let t = nums("translation", 3)?.map_or(DVec3::ZERO, |v| DVec3::new(v[0], v[1], v[2]));
        let r = nums("rotation", 4)?.map_or(DQuat::IDENTITY, |v| {
            DQuat::from_xyzw(v[0], v[1], v[2], v[3]).normalize()
        });
        let s = nums("scale", 3)?.map_or(DVec3::ONE, |v| DVec3::new(v[0], v[1], v[2]));
        DMat4::from_scale_rotation_translation(s, r, t)
    };
    if !m.is_finite() {
        return Err(Error::Invalid(format!("{what}: transform is not finite")));
    }
    Ok(m)
}

/// Expands a primitive's index list to a triangle list by mode.
fn triangle_list(mode: u64, idx: &[u32]) -> Vec<u32> {
    match mode {
        4 => idx[..idx.len() - idx.len() % 3].to_vec(),
        5 => (0..idx.len().saturating_sub(2))
            .flat_map(|i| {
                if i % 2 == 0 {
                    [idx[i], idx[i + 1], idx[i + 2]]
                } else {
                    [idx[i], idx[i + 2], idx[i + 1]]
                }
            })
            .collect(),
        6 => (1..idx.len().saturating_sub(1))
            .flat_map(|i| [idx[i], idx[i + 1], idx[0]])
            .collect(),
        _ => Vec::new(),
    }
}

impl Scene {
    /// Decodes geometry and walks the default scene.
    /// Draco and meshopt geometry is decoded first (`decompress`), so the
    /// scene and its write-back see plain accessors.
    pub fn from_document(mut doc: Document) -> Result<Scene> {
        let decoded = decompress::decompress(&mut doc)?;
        let json = &doc.json;
        let nodes = array(json, "nodes");
        let meshes = array(json, "meshes");
        let roots: Vec<usize> = match json.get("scenes").and_then(Value::as_array) {
            Some(scenes) if !scenes.is_empty() => {
                let s = field_usize(json, "scene", "root")?.unwrap_or(0);
                let scene = scenes
                    .get(s)
                    .ok_or_else(|| Error::Invalid(format!("scene {s} does not exist")))?;
                let mut roots = Vec::new();
                for v in array(scene, "nodes") {
                    roots.push(v.as_u64().ok_or_else(|| {
                        Error::Invalid(format!("scenes[{s}].nodes holds a non-index"))
                    })? as usize);
                }
                roots
            }
            _ => {
                let mut is_child = vec![false; nodes.len()];
                for n in nodes {
                    for c in array(n, "children") {
                        if let Some(c) = c.as_u64().filter(|&c| (c as usize) < nodes.len()) {
                            is_child[c as usize] = true;
                        }
                    }
                }
                (0..nodes.len()).filter(|&i| !is_child[i]).collect()
            }
        };

        let mut geometries: Vec<PrimitiveGeometry> = Vec::new();
        let mut instances: Vec<Instance> = Vec::new();
        let mut warnings: Vec<String> = decoded;
        let mut geometry_of: HashMap<(usize, usize), Option<usize>> = HashMap::new();
        let mut visited = vec![false; nodes.len()];
        let mut stack: Vec<(usize, DMat4)> =
            roots.iter().rev().map(|&r| (r, DMat4::IDENTITY)).collect();
        let mut skipped_modes = 0usize;
        let mut triangle_total = 0usize;
        while let Some((ni, parent)) = stack.pop() {
            let what = format!("nodes[{ni}]");
            let node = nodes
                .get(ni)
                .ok_or_else(|| Error::Invalid(format!("{what} does not exist")))?;
            if std::mem::replace(&mut visited[ni], true) {
                return Err(Error::Invalid(format!(
                    "{what} is reached twice: the node hierarchy has a cycle or a shared child"
                )));
            }
            let world = parent * node_local(node, &what)?;
            for c in array(node, "children").iter().rev() {
                let c = c
                    .as_u64()
                    .ok_or_else(|| Error::Invalid(format!("{what}.children holds a non-index")))?;
                stack.push((c as usize, world));
            }
            let Some(mi) = field_usize(node, "mesh", &what)? else {
                continue;
            };
            let mesh = meshes
                .get(mi)
                .ok_or_else(|| Error::Invalid(format!("{what}.mesh {mi} does not exist")))?;
            let skinned = node.get("skin").is_some();
            let gpu = node.pointer("/extensions/EXT_mesh_gpu_instancing");
            // The transform of a skinned node is ignored (glTF spec): rest pose.
            let placements: Vec<DMat4> = match gpu {
                Some(g) => gpu_instances(&doc, g, &what)?
                    .into_iter()
                    .map(|m| world * m)
                    .collect(),
                None if skinned => vec![DMat4::IDENTITY],
                None => vec![world],
            };
            if skinned {
                warn(
                    &mut warnings,
                    format!("{what}: skinned mesh {mi} occludes in its rest pose but is not baked"),
                );
            }
            if gpu.is_some() {
                warn(
                    &mut warnings,
                    format!(
                        "{what}: {} EXT_mesh_gpu_instancing copies of mesh {mi} occlude but are not baked",
                        placements.len()
                    ),
                );
            }
            for (pi, _) in array(mesh, "primitives").iter().enumerate() {
                let g = match geometry_of.get(&(mi, pi)) {
                    Some(g) => *g,
                    None => {
                        let g = decode_primitive(&doc, mi, pi)?.map(|geometry| {
                            geometries.push(geometry);
                            geometries.len() - 1
                        });
                        if g.is_none() {
                            skipped_modes += 1;
                        }
                        geometry_of.insert((mi, pi), g);
                        g
                    }
                };
                let Some(g) = g else { continue };
                if geometries[g].morphed && !skinned && gpu.is_none() {
                    warn(
                        &mut warnings,
                        format!(
                            "{}: morph targets; occludes in its base pose but is not baked",
                            primitive_label(mi, pi)
                        ),
                    );
                }
                let baked = !skinned && gpu.is_none() && !geometries[g].morphed;
                triangle_total += geometries[g].triangles.len() / 3 * placements.len();
                if triangle_total > MAX_TRIANGLES {
                    return Err(Error::Limit(format!(
                        "the scene has more than {MAX_TRIANGLES} triangles (all instances)"
                    )));
                }
                for &transform in &placements {
                    instances.push(Instance {
                        node: ni,
                        geometry: g,
                        transform,
                        baked,
                    });
                }
            }
        }
        if skipped_modes > 0 {
            warn(
                &mut warnings,
                format!(
                    "{skipped_modes} point or line primitive(s) are neither baked nor occluders"
                ),
            );
        }
        Ok(Scene {
            doc,
            geometries,
            instances,
            warnings,
        })
    }
    /// Whether the material of primitive `geometry` can use the visibility
    /// layer (`--visibility auto`): it has a `normalTexture` (the layer
    /// relights the normal-mapped normal), or a glossy lobe worth
    /// occluding: `roughnessFactor` below [`GLOSSY_ROUGHNESS`] (glTF's
    /// default is 1, rough) or a `KHR_materials_clearcoat` layer with a
    /// non-zero `clearcoatFactor`. A primitive without a material has
    /// glTF's default one: rough, no normal map.
    pub fn material_reads_visibility(&self, geometry: usize) -> bool {
        let g = &self.geometries[geometry];
        let prim = &self.doc.json["meshes"][g.mesh]["primitives"][g.primitive];
        let Some(m) = prim.get("material").and_then(Value::as_u64) else {
            return false;
        };
        let mat = &self.doc.json["materials"][m as usize];
        let roughness = mat["pbrMetallicRoughness"]["roughnessFactor"]
            .as_f64()
            .unwrap_or(1.0);
        let clearcoat = mat["extensions"]["KHR_materials_clearcoat"]["clearcoatFactor"]
            .as_f64()
            .unwrap_or(0.0);
        mat.get("normalTexture").is_some_and(Value::is_object)
            || roughness < GLOSSY_ROUGHNESS
            || clearcoat > 0.0
    }

    /// The existing lightmap UV set `set` (`TEXCOORD_set`) of every receiver
    /// mesh, one UV per vertex, for [`crate::atlas::unwrap::existing`]. Fails,
    /// naming the primitive, if a primitive lacks the set, has UVs outside
    /// [0, 1] or non-finite, or is placed by several nodes (they would share
    /// one lightmap region).
    pub fn lightmap_uvs(&self, meshes: &[ReceiverMesh], set: usize) -> Result<Vec<Vec<[f32; 2]>>> {
        let mut placements: HashMap<usize, usize> = HashMap::new();
        for m in meshes {
            *placements
                .entry(self.instances[m.instance].geometry)
                .or_default() += 1;
        }
        let mut out = Vec::with_capacity(meshes.len());
        for m in meshes {
            let g = &self.geometries[self.instances[m.instance].geometry];
            let what = g.label();
            if placements[&self.instances[m.instance].geometry] > 1 {
                return Err(Error::option_conflict(
                    "uv",
                    format!(
                        "{what} is placed by several nodes, which would share one lightmap region; use generated UVs"
                    ),
                ));
            }
            let prim = &self.doc.json["meshes"][g.mesh]["primitives"][g.primitive];
            let acc = prim["attributes"][format!("TEXCOORD_{set}")]
                .as_u64()
                .ok_or_else(|| {
                    Error::option_conflict("uv", format!("{what} has no TEXCOORD_{set}"))
                })?;
            let uv = accessor::read(&self.doc, acc as usize)?.to_f32::<2>(&what)?;
            if uv.len() != m.positions.len() {
                return Err(Error::Invalid(format!(
                    "{what}: TEXCOORD_{set} and POSITION counts differ"
                )));
            }
            if let Some((v, p)) = uv
                .iter()
                .enumerate()
                .find(|(_, p)| !p.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)))
            {
                return Err(Error::Invalid(format!(
                    "{what}: TEXCOORD_{set} vertex {v} is ({}, {}), outside [0, 1]; an existing lightmap UV set must lie inside the unit square",
                    p[0], p[1]
                )));
            }
            out.push(uv);
        }
        Ok(out)
    }

    /// Number of placements that receive a lightmap.
    pub fn baked_count(&self) -> usize {
        self.instances.iter().filter(|i| i.baked).count()
    }

    /// World-space bounding box of all placed triangles' vertices.
    pub fn world_bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for inst in &self.instances {
            let g = &self.geometries[inst.geometry];
            for &i in &g.triangles {
                let p = inst
                    .transform
                    .transform_point3(DVec3::from(g.positions[i as usize].map(f64::from)));
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
    }

    /// Maps every instance into bake space.
    pub fn bake_geometry(&self) -> Result<BakeGeometry> {
        self.bake_geometry_in(None)
    }

    /// Maps every instance into bake space: `space` when given (an
    /// earlier bake's, `--reuse`), else the scene's bounding box's.
    pub fn bake_geometry_in(&self, space: Option<BakeSpace>) -> Result<BakeGeometry> {
        let (lo, hi) = self
            .world_bounds()
            .ok_or_else(|| Error::Empty("the scene has no triangles".into()))?;
        let diagonal = (hi - lo).length();
        if !(diagonal > 0.0 && diagonal.is_finite()) {
            return Err(Error::Empty(format!(
                "the scene's triangles have no extent (bounding-box diagonal {diagonal})"
            )));
        }
        let space = space.unwrap_or(BakeSpace {
            center: (lo + hi) * 0.5,
            diagonal,
        });
        let mut occluders = Vec::new();
        let mut occluder_single_sided = Vec::new();
        let mut receivers = Vec::new();
        for (ii, inst) in self.instances.iter().enumerate() {
            let g = &self.geometries[inst.geometry];
            let positions: Vec<[f32; 3]> = g
                .positions
                .iter()
                .map(|p| {
                    space
                        .to_bake(
                            inst.transform
                                .transform_point3(DVec3::from(p.map(f64::from))),
                        )
                        .to_array()
                })
                .collect();
            let mirrored = DMat3::from_mat4(inst.transform).determinant() < 0.0;
            for t in g.triangles.chunks_exact(3) {
                let mut v = [0, 1, 2].map(|k| Vec3A::from(positions[t[k] as usize]));
                if mirrored {
                    v.swap(1, 2);
                }
                if (v[1] - v[0]).cross(v[2] - v[0]).length_squared() > 0.0 {
                    occluders.push(v);
                    occluder_single_sided.push(!g.double_sided);
                }
            }
            if !inst.baked {
                continue;
            }
            let linear = DMat3::from_mat4(inst.transform);
            let normal_matrix = linear.inverse().transpose();
            let normals = g
                .normals
                .as_ref()
                .filter(|_| normal_matrix.is_finite())
                .map(|ns| {
                    ns.iter()
                        .map(|n| {
                            let w =
                                (normal_matrix * DVec3::from(n.map(f64::from))).normalize_or_zero();
                            w.as_vec3().to_array()
                        })
                        .collect()
                });
            let shape = (g.positions.iter())
                .map(|p| {
                    let p = linear * DVec3::from(p.map(f64::from)) / space.diagonal;
                    p.as_vec3().to_array()
                })
                .collect();
            receivers.push(ReceiverMesh {
                instance: ii,
                positions,
                shape,
                normals,
                triangles: g.triangles.clone(),
                mirrored: linear.determinant() < 0.0,
            });
        }
        Ok(BakeGeometry {
            space,
            occluders,
            occluder_single_sided,
            receivers,
        })
    }
}

/// Adds a warning unless the same line is already there.
fn warn(warnings: &mut Vec<String>, line: String) {
    if !warnings.contains(&line) {
        warnings.push(line);
    }
}

/// Decodes `meshes[mi].primitives[pi]`; `None` for points and lines.
fn decode_primitive(doc: &Document, mi: usize, pi: usize) -> Result<Option<PrimitiveGeometry>> {
    let what = primitive_label(mi, pi);
    let prim = &array(&doc.json, "meshes")[mi]["primitives"][pi];
    let mode = prim
        .get("mode")
        .map_or(Some(4), Value::as_u64)
        .unwrap_or(99);
    if mode > 6 {
        return Err(Error::Invalid(format!("{what}.mode is invalid")));
    }
    if mode < 4 {
        return Ok(None);
    }
    let pos_acc = field_usize(&prim["attributes"], "POSITION", &what)?
        .ok_or_else(|| Error::Invalid(format!("{what} has no POSITION attribute")))?;
    let positions: Vec<[f32; 3]> = accessor::read(doc, pos_acc)
        .map_err(|e| e.within(&format!("{what} POSITION")))?
        .to_f32::<3>(&what)?;
    if let Some(v) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(Error::Invalid(format!(
            "{what}: POSITION (accessors[{pos_acc}]) is not finite at vertex {v}"
        )));
    }
    let normals = match field_usize(&prim["attributes"], "NORMAL", &what)? {
        Some(n) => {
            let n = accessor::read(doc, n)
                .map_err(|e| e.within(&format!("{what} NORMAL")))?
                .to_f32::<3>(&what)?;
            (n.len() == positions.len()).then_some(n)
        }
        None => None,
    };
    let indices: Vec<u32> = match field_usize(prim, "indices", &what)? {
        Some(i) => accessor::read(doc, i)
            .map_err(|e| e.within(&format!("{what} indices")))?
            .to_indices(&what)?,
        None => (0..positions.len() as u32).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
        return Err(Error::Invalid(format!(
            "{what}: index {bad} points past the {} vertices",
            positions.len()
        )));
    }
    let triangles = triangle_list(mode, &indices);
    let morphed = prim
        .get("targets")
        .and_then(Value::as_array)
        .is_some_and(|t| !t.is_empty());
    // The writer edits the material (occlusionTexture): it must exist.
    let double_sided = match field_usize(prim, "material", &what)? {
        None => false,
        Some(m) => {
            let material = array(&doc.json, "materials")
                .get(m)
                .ok_or_else(|| Error::Invalid(format!("{what}.material {m} does not exist")))?;
            if !material.is_object() {
                return Err(Error::Invalid(format!("materials[{m}] is not an object")));
            }
            material
                .get("doubleSided")
                .and_then(Value::as_bool)
                .unwrap_or(false)
        }
    };
    Ok(Some(PrimitiveGeometry {
        mesh: mi,
        primitive: pi,
        positions,
        normals,
        triangles,
        morphed,
        double_sided,
    }))
}

/// Per-instance transforms of an EXT_mesh_gpu_instancing node.
fn gpu_instances(doc: &Document, ext: &Value, what: &str) -> Result<Vec<DMat4>> {
    let attrs = &ext["attributes"];
    let read = |key: &str| -> Result<Option<Vec<[f32; 4]>>> {
        match field_usize(attrs, key, what)? {
            None => Ok(None),
            Some(a) => {
                let acc = accessor::read(doc, a)?;
                let dims = acc.dims;
                let v = match dims {
                    3 => acc
                        .to_f32::<3>(what)?
                        .into_iter()
                        .map(|v| [v[0], v[1], v[2], 0.0])
                        .collect(),
                    4 => acc.to_f32::<4>(what)?,
                    _ => {
                        return Err(Error::Invalid(format!(
                            "{what}: EXT_mesh_gpu_instancing {key} has {dims} components"
                        )));
                    }
                };
                Ok(Some(v))
            }
        }
    };
    let t = read("TRANSLATION")?;
    let r = read("ROTATION")?;
    let s = read("SCALE")?;
    let n = [&t, &r, &s]
        .iter()
        .filter_map(|a| a.as_ref().map(Vec::len))
        .max()
        .unwrap_or(0);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let tr = t.as_ref().and_then(|v| v.get(i)).map_or(DVec3::ZERO, |v| {
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        });
        let ro = r
            .as_ref()
            .and_then(|v| v.get(i))
            .map_or(DQuat::IDENTITY, |v| {
                DQuat::from_xyzw(v[0] as f64, v[1] as f64, v[2] as f64, v[3] as f64).normalize()
            });
        let sc = s.as_ref().and_then(|v| v.get(i)).map_or(DVec3::ONE, |v| {
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        });
        let m = DMat4::from_scale_rotation_translation(sc, ro, tr);
        if !m.is_finite() {
            return Err(Error::Invalid(format!(
                "{what}: EXT_mesh_gpu_instancing instance {i} is not finite"
            )));
        }
        out.push(m);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_expand_with_gltf_winding() {
        assert_eq!(triangle_list(5, &[0, 1, 2, 3]), vec![0, 1, 2, 1, 3, 2]);
        assert_eq!(triangle_list(6, &[0, 1, 2, 3]), vec![1, 2, 0, 2, 3, 0]);
        assert_eq!(triangle_list(4, &[0, 1, 2, 3]), vec![0, 1, 2]);
        assert!(triangle_list(5, &[0, 1]).is_empty());
    }
}
