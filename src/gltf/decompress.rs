//! Decompress: compressed geometry decoded into plain buffer views.
//!
//! In: a [`Document`] as read. Out: the same document with every
//! `EXT_meshopt_compression` / `KHR_meshopt_compression` bufferView and
//! every `KHR_draco_mesh_compression` primitive decoded into the BIN buffer
//! (`buffers[0]`, created when the input has none), the extensions removed
//! from those views and primitives and from `extensionsUsed` /
//! `extensionsRequired`, and the meshopt fallback buffers (placeholders
//! without data) dropped; one warning line per extension decoded.
//! Everything else is left as it was, so the write-back keeps it.
//!
//! The codecs are `draco_gltf`'s: a pure-Rust port of Google's Draco
//! decoder and of meshoptimizer's vertex, index and filter decoders, every
//! read bounds-checked. A corrupt stream is refused with one line naming
//! the bufferView or primitive.

use super::accessor::{Component, RawAccessor, array, field_usize, primitive_label, view_bytes};
use super::append::{Bin, gather_accessor, index_accessor, insert_bin_buffer};
use super::container::Document;
use crate::error::{Error, Result};
use draco_gltf::meshopt::{self, MeshoptFilter, MeshoptMode};
use draco_gltf::{DracoPrimitiveContract, DracoPrimitiveExtension, JsonValue, PrimitiveMode};
use serde_json::{Value, json};
use std::collections::HashMap;

/// The Draco primitive extension.
pub(crate) const DRACO: &str = "KHR_draco_mesh_compression";

/// The meshopt bufferView extensions (the EXT one and its KHR successor).
pub(crate) const MESHOPT: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// Most bytes one decoded bufferView may take.
const MAX_VIEW_BYTES: usize = 2 << 30;

/// Decodes every compressed bufferView and primitive of `doc` in place;
/// returns the warnings to show (empty when nothing was compressed).
pub fn decompress(doc: &mut Document) -> Result<Vec<String>> {
    let meshopt_views: Vec<(usize, &'static str)> = array(&doc.json, "bufferViews")
        .iter()
        .enumerate()
        .filter_map(|(i, v)| {
            MESHOPT
                .into_iter()
                .find(|e| v.pointer(&format!("/extensions/{e}")).is_some())
                .map(|e| (i, e))
        })
        .collect();
    let draco_prims: Vec<(usize, usize)> = array(&doc.json, "meshes")
        .iter()
        .enumerate()
        .flat_map(|(mi, m)| {
            array(m, "primitives")
                .iter()
                .enumerate()
                .filter(|(_, p)| p.pointer(&format!("/extensions/{DRACO}")).is_some())
                .map(move |(pi, _)| (mi, pi))
        })
        .collect();
    if meshopt_views.is_empty() && draco_prims.is_empty() {
        return Ok(Vec::new());
    }
    if !doc.glb_bin {
        insert_bin_buffer(&mut doc.json);
        doc.buffers.insert(0, Vec::new());
        doc.glb_bin = true;
    }
    let mut warnings = Vec::new();
    let mut bin = Bin::of(doc);

    // Meshopt views: decoded first, so a Draco stream could sit in one.
    let mut decoded_views = Vec::with_capacity(meshopt_views.len());
    for &(i, ext) in &meshopt_views {
        decoded_views.push(decode_meshopt_view(doc, i, ext)?);
    }
    for (&(i, ext), bytes) in meshopt_views.iter().zip(decoded_views) {
        while !bin.data.len().is_multiple_of(4) {
            bin.data.push(0);
        }
        let view = &mut doc.json["bufferViews"][i];
        view["buffer"] = json!(0);
        view["byteOffset"] = json!(bin.data.len());
        view["byteLength"] = json!(bytes.len());
        remove_extension(view, ext);
        bin.data.extend_from_slice(&bytes);
    }
    put_bin(doc, &bin.data);
    if !meshopt_views.is_empty() {
        drop_fallback_buffers(doc);
        for ext in MESHOPT {
            if meshopt_views.iter().any(|&(_, e)| e == ext) {
                warnings.push(format!(
                    "{ext}: {} bufferViews decoded; the output stores them uncompressed and no longer lists {ext}",
                    meshopt_views.iter().filter(|&&(_, e)| e == ext).count()
                ));
                unlist(&mut doc.json, ext);
            }
        }
    }

    // Draco primitives.
    let mut done: HashMap<usize, usize> = HashMap::new();
    for &(mi, pi) in &draco_prims {
        let what = primitive_label(mi, pi);
        let geometry = decode_draco(doc, mi, pi).map_err(|e| e.within(&what))?;
        let prim_path = format!("/meshes/{mi}/primitives/{pi}");
        let mut json = std::mem::take(&mut doc.json);
        let prim = json.pointer(&prim_path).cloned().unwrap_or(Value::Null);
        let mut new_attributes = prim["attributes"].clone();
        for attr in geometry.attributes() {
            let Some(old) = prim["attributes"]
                .get(attr.semantic())
                .and_then(Value::as_u64)
            else {
                continue;
            };
            let raw = packed(
                attr.component_type(),
                attr.components(),
                attr.normalized(),
                attr.count(),
                attr.bytes(),
            )?;
            let xref: Vec<u32> = (0..attr.count() as u32).collect();
            let new = gather_accessor(&mut json, &mut bin, &raw, &xref, true);
            let index = replace_accessor(&mut json, old as usize, new, &mut done);
            new_attributes[attr.semantic()] = json!(index);
        }
        let prim = json.pointer_mut(&prim_path).expect("the primitive");
        prim["attributes"] = new_attributes;
        if let (Some(indices), Some(old)) = (
            geometry.indices(),
            prim.get("indices").and_then(Value::as_u64),
        ) {
            let list = packed(
                indices.component_type(),
                1,
                false,
                indices.count(),
                indices.bytes(),
            )?
            .to_indices(&format!("{what} indices"))?;
            let new = index_accessor(&mut json, &mut bin, &list, geometry.vertex_count());
            let index = replace_accessor(&mut json, old as usize, new, &mut done);
            json.pointer_mut(&prim_path).expect("the primitive")["indices"] = json!(index);
        }
        remove_extension(json.pointer_mut(&prim_path).expect("the primitive"), DRACO);
        doc.json = json;
    }
    if !draco_prims.is_empty() {
        put_bin(doc, &bin.data);
        unlist(&mut doc.json, DRACO);
        warnings.push(format!(
            "{DRACO}: {} primitives decoded; the output stores their geometry uncompressed and no longer lists {DRACO}",
            draco_prims.len()
        ));
    }
    Ok(warnings)
}

/// Makes `data` the BIN buffer.
fn put_bin(doc: &mut Document, data: &[u8]) {
    doc.json["buffers"][0]["byteLength"] = json!(data.len());
    doc.buffers[0] = data.to_vec();
}

/// A decoded attribute or index stream as a [`RawAccessor`] (tightly
/// packed, in its glTF component type).
fn packed(
    component: draco_gltf::ComponentType,
    dims: u8,
    normalized: bool,
    count: usize,
    bytes: &[u8],
) -> Result<RawAccessor> {
    Ok(RawAccessor {
        component: Component::from_gl(component as u64).expect("a glTF component type"),
        dims: dims as usize,
        normalized,
        count,
        type_name: type_name(dims)?.to_string(),
        bytes: bytes.to_vec(),
    })
}

/// The accessor `type` of `n` components.
fn type_name(n: u8) -> Result<&'static str> {
    Ok(match n {
        1 => "SCALAR",
        2 => "VEC2",
        3 => "VEC3",
        4 => "VEC4",
        _ => {
            return Err(Error::Invalid(format!(
                "a decoded attribute has {n} components"
            )));
        }
    })
}

/// Decodes bufferView `i`'s meshopt stream into its plain bytes.
fn decode_meshopt_view(doc: &Document, i: usize, ext: &str) -> Result<Vec<u8>> {
    let what = format!("bufferViews[{i}]");
    let e = &doc.json["bufferViews"][i]["extensions"][ext];
    let field = |k: &str| field_usize(e, k, &format!("{what}.extensions.{ext}"));
    let missing = |k: &str| Error::Invalid(format!("{what}.extensions.{ext}.{k} is missing"));
    let buffer = field("buffer")?.ok_or_else(|| missing("buffer"))?;
    let offset = field("byteOffset")?.unwrap_or(0);
    let length = field("byteLength")?.ok_or_else(|| missing("byteLength"))?;
    let stride = field("byteStride")?.ok_or_else(|| missing("byteStride"))?;
    let count = field("count")?.ok_or_else(|| missing("count"))?;
    let name = |k: &str, default: &str| -> String {
        e.get(k)
            .and_then(Value::as_str)
            .unwrap_or(default)
            .to_string()
    };
    let bad = |m: String| Error::Invalid(format!("{what}: {ext} {m}"));
    let mode = MeshoptMode::from_name(&name("mode", ""))
        .map_err(|_| bad(format!("mode {:?} is not supported", name("mode", ""))))?;
    let filter = MeshoptFilter::from_name(&name("filter", "NONE")).map_err(|_| {
        bad(format!(
            "filter {} is not supported",
            name("filter", "NONE")
        ))
    })?;
    let source = doc
        .buffers
        .get(buffer)
        .and_then(|b| b.get(offset..offset.checked_add(length)?))
        .ok_or_else(|| {
            bad(format!(
                "bytes {offset}+{length} lie outside buffers[{buffer}]"
            ))
        })?;
    let size = count
        .checked_mul(stride)
        .filter(|&s| s <= MAX_VIEW_BYTES)
        .ok_or_else(|| bad(format!("count {count} x byteStride {stride} is too large")))?;
    let mut out = vec![0u8; size];
    meshopt::decode_buffer_view(&mut out, source, mode, filter, count, stride)
        .map_err(|e| bad(format!("data is corrupt: {}", plain(&e.to_string(), ext))))?;
    Ok(out)
}

/// A decoder's message without its own "Invalid glTF: <ext>:" prefix.
fn plain<'m>(message: &'m str, ext: &str) -> &'m str {
    let m = message.strip_prefix("Invalid glTF: ").unwrap_or(message);
    m.strip_prefix(ext)
        .map_or(m, |m| m.trim_start_matches(": "))
}

/// Decodes primitive `mi`/`pi`'s Draco stream.
fn decode_draco(doc: &Document, mi: usize, pi: usize) -> Result<draco_gltf::PackedGeometry> {
    let prim = &doc.json["meshes"][mi]["primitives"][pi];
    let ext_json = &prim["extensions"][DRACO];
    let bad = |m: String| Error::Invalid(format!("{DRACO} {m}"));
    let ext = JsonValue::parse(&serde_json::to_vec(ext_json).expect("json"))
        .map_err(bad)
        .and_then(|v| DracoPrimitiveExtension::from_json(&v).map_err(|e| bad(e.to_string())))?;
    let (payload, _) = view_bytes(doc, ext.buffer_view(), DRACO)?;
    let accessors = array(&doc.json, "accessors");
    let declared = |index: Option<u64>| -> Result<&Value> {
        index
            .and_then(|i| accessors.get(i as usize))
            .ok_or_else(|| bad("names an accessor that does not exist".into()))
    };
    let mut contract = DracoPrimitiveContract::new().with_mode(
        match prim.get("mode").and_then(Value::as_u64).unwrap_or(4) {
            4 => PrimitiveMode::Triangles,
            5 => PrimitiveMode::TriangleStrip,
            m => return Err(bad(format!("on a primitive of mode {m}"))),
        },
    );
    for (semantic, _) in ext.attributes() {
        let acc = declared(prim["attributes"].get(semantic).and_then(Value::as_u64))?;
        let count = acc.get("count").and_then(Value::as_u64).unwrap_or(0);
        let normalized = acc.get("normalized").and_then(Value::as_bool) == Some(true);
        contract = contract.with_attribute(semantic, count, normalized);
    }
    if let Some(i) = prim.get("indices") {
        let acc = declared(i.as_u64())?;
        contract = contract.with_indices(acc.get("count").and_then(Value::as_u64).unwrap_or(0));
    }
    ext.decode(payload, &contract).map_err(|e| {
        let e = e.to_string();
        bad(format!(
            "data is corrupt: {}",
            plain(&e, "Draco decode error: ")
        ))
    })
}

/// Moves the accessor just appended at `new` into `old`'s place (keeping
/// its name), unless `old` was already replaced by another primitive's
/// decode: then the new one stays where it is. Returns the index to use.
fn replace_accessor(
    json: &mut Value,
    old: usize,
    new: usize,
    done: &mut HashMap<usize, usize>,
) -> usize {
    if done.contains_key(&old) {
        return new;
    }
    let accessors = json["accessors"].as_array_mut().expect("accessors");
    let mut acc = accessors.pop().expect("the new accessor");
    debug_assert_eq!(accessors.len(), new);
    if let Some(name) = accessors[old].get("name") {
        acc["name"] = name.clone();
    }
    accessors[old] = acc;
    done.insert(old, new);
    old
}

/// Removes `extensions.<name>` (and `extensions` when it empties).
fn remove_extension(object: &mut Value, name: &str) {
    if let Some(exts) = object.get_mut("extensions").and_then(Value::as_object_mut) {
        exts.remove(name);
        if exts.is_empty() {
            object.as_object_mut().expect("object").remove("extensions");
        }
    }
}

/// Takes `name` out of `extensionsUsed` and `extensionsRequired`.
fn unlist(json: &mut Value, name: &str) {
    let root = json.as_object_mut().expect("root");
    for key in ["extensionsUsed", "extensionsRequired"] {
        if let Some(list) = root.get_mut(key).and_then(Value::as_array_mut) {
            list.retain(|v| v.as_str() != Some(name));
            if list.is_empty() {
                root.remove(key);
            }
        }
    }
}

/// Drops the buffers marked as meshopt fallbacks that no bufferView reads
/// any more, renumbering the views' buffer references.
fn drop_fallback_buffers(doc: &mut Document) {
    let used: Vec<bool> = {
        let n = array(&doc.json, "buffers").len();
        let mut used = vec![false; n];
        for v in array(&doc.json, "bufferViews") {
            if let Some(b) = v
                .get("buffer")
                .and_then(Value::as_u64)
                .filter(|&b| (b as usize) < n)
            {
                used[b as usize] = true;
            }
        }
        used
    };
    let fallback = |b: &Value| {
        MESHOPT
            .iter()
            .any(|e| b.pointer(&format!("/extensions/{e}/fallback")) == Some(&json!(true)))
    };
    let drop: Vec<bool> = array(&doc.json, "buffers")
        .iter()
        .enumerate()
        .map(|(i, b)| i > 0 && !used[i] && fallback(b))
        .collect();
    if !drop.contains(&true) {
        return;
    }
    let mut new_index = Vec::with_capacity(drop.len());
    let mut next = 0u64;
    for &d in &drop {
        new_index.push(next);
        next += u64::from(!d);
    }
    if let Some(views) = doc.json["bufferViews"].as_array_mut() {
        for v in views {
            if let Some(b) = v.get("buffer").and_then(Value::as_u64) {
                v["buffer"] = json!(new_index[b as usize]);
            }
        }
    }
    let buffers = doc.json["buffers"].as_array_mut().expect("buffers");
    let mut k = 0;
    buffers.retain(|_| {
        k += 1;
        !drop[k - 1]
    });
    let mut k = 0;
    doc.buffers.retain(|_| {
        k += 1;
        !drop[k - 1]
    });
}
