//! Append: new data in the output's BIN buffer, as glTF accessors.
//!
//! In: the document being written (`serde_json::Value`) and values to add
//! (re-indexed vertex attributes, lightmap UVs, triangle indices). Out: new
//! 4-byte-aligned bufferViews in buffers\[0\] and accessors over them
//! (with `min`/`max` where the input had them or glTF requires them),
//! their indices returned.

use super::accessor::{Component, RawAccessor};
use serde_json::{Value, json};

/// Appends 4-byte-aligned bufferViews to the GLB BIN buffer (buffers[0]).
pub(super) struct Bin {
    pub(super) data: Vec<u8>,
}

impl Bin {
    /// The BIN buffer of a document whose `buffers[0]` is the GLB BIN
    /// chunk: its declared bytes (the chunk may be padded past them).
    pub(super) fn of(doc: &super::container::Document) -> Bin {
        let len = doc.json["buffers"][0]["byteLength"].as_u64().unwrap_or(0) as usize;
        Bin {
            data: doc.buffers[0][..len.min(doc.buffers[0].len())].to_vec(),
        }
    }

    pub(super) fn push_view(
        &mut self,
        json: &mut Value,
        bytes: &[u8],
        stride: Option<usize>,
        target: Option<u32>,
    ) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        let mut view =
            json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()});
        if let Some(s) = stride {
            view["byteStride"] = json!(s);
        }
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.data.extend_from_slice(bytes);
        push(json, "bufferViews", view)
    }
}

/// Appends `item` to the root array `key` (creating it) and returns its index.
pub(super) fn push(json: &mut Value, key: &str, item: Value) -> usize {
    let arr = json
        .as_object_mut()
        .expect("root is an object")
        .entry(key)
        .or_insert_with(|| Value::Array(Vec::new()));
    if !arr.is_array() {
        *arr = Value::Array(Vec::new());
    }
    let a = arr.as_array_mut().expect("array");
    a.push(item);
    a.len() - 1
}

fn component_gl(c: Component) -> u32 {
    match c {
        Component::I8 => 5120,
        Component::U8 => 5121,
        Component::I16 => 5122,
        Component::U16 => 5123,
        Component::U32 => 5125,
        Component::F32 => 5126,
    }
}

/// Writes the elements `xref` of `raw` as a new vertex-attribute accessor.
pub(super) fn gather_accessor(
    json: &mut Value,
    bin: &mut Bin,
    raw: &RawAccessor,
    xref: &[u32],
    with_bounds: bool,
) -> usize {
    let es = raw.element_size();
    let stride = es.next_multiple_of(4);
    let mut bytes = vec![0u8; stride * xref.len()];
    for (i, &x) in xref.iter().enumerate() {
        bytes[i * stride..i * stride + es]
            .copy_from_slice(&raw.bytes[x as usize * es..(x as usize + 1) * es]);
    }
    let view = bin.push_view(json, &bytes, (stride != es).then_some(stride), Some(34962));
    let mut acc = json!({
        "bufferView": view,
        "componentType": component_gl(raw.component),
        "count": xref.len(),
        "type": raw.type_name,
    });
    if raw.normalized {
        acc["normalized"] = json!(true);
    }
    if with_bounds && !xref.is_empty() {
        let (lo, hi) = bounds(
            &raw.stored_values(),
            raw.dims,
            xref.iter().map(|&x| x as usize),
        );
        let num = |v: f32| {
            if raw.component == Component::F32 {
                json!(v)
            } else {
                json!(v as i64)
            }
        };
        acc["min"] = Value::Array(lo.into_iter().map(num).collect());
        acc["max"] = Value::Array(hi.into_iter().map(num).collect());
    }
    push(json, "accessors", acc)
}

/// Per-component min and max of the elements of `values` (flat, `dims`
/// components each) picked by `elements`.
fn bounds(
    values: &[f32],
    dims: usize,
    elements: impl Iterator<Item = usize>,
) -> (Vec<f32>, Vec<f32>) {
    let mut lo = vec![f32::INFINITY; dims];
    let mut hi = vec![f32::NEG_INFINITY; dims];
    for e in elements {
        for k in 0..dims {
            lo[k] = lo[k].min(values[e * dims + k]);
            hi[k] = hi[k].max(values[e * dims + k]);
        }
    }
    (lo, hi)
}

pub(super) fn f32_accessor(
    json: &mut Value,
    bin: &mut Bin,
    data: &[f32],
    ty: &str,
    dims: usize,
) -> usize {
    let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
    let view = bin.push_view(json, &bytes, None, Some(34962));
    let (lo, hi) = bounds(data, dims, 0..data.len() / dims);
    let mut acc =
        json!({"bufferView": view, "componentType": 5126, "count": data.len() / dims, "type": ty});
    if !data.is_empty() {
        acc["min"] = json!(lo);
        acc["max"] = json!(hi);
    }
    push(json, "accessors", acc)
}

pub(super) fn index_accessor(
    json: &mut Value,
    bin: &mut Bin,
    indices: &[u32],
    vertex_count: usize,
) -> usize {
    let (bytes, ct): (Vec<u8>, u32) = if vertex_count <= u16::MAX as usize {
        (
            indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect(),
            5123,
        )
    } else {
        (
            indices.iter().flat_map(|&i| i.to_le_bytes()).collect(),
            5125,
        )
    };
    let view = bin.push_view(json, &bytes, None, Some(34963));
    push(
        json,
        "accessors",
        json!({"bufferView": view, "componentType": ct, "count": indices.len(), "type": "SCALAR"}),
    )
}

/// Makes room for the GLB BIN buffer at `buffers[0]`, shifting references.
pub(super) fn insert_bin_buffer(json: &mut Value) {
    let obj = json.as_object_mut().expect("root");
    let buffers = obj.entry("buffers").or_insert_with(|| json!([]));
    if let Some(b) = buffers.as_array_mut() {
        b.insert(0, json!({"byteLength": 0}));
    }
    if let Some(views) = obj.get_mut("bufferViews").and_then(Value::as_array_mut) {
        for v in views {
            if let Some(b) = v.get("buffer").and_then(Value::as_u64) {
                v["buffer"] = json!(b + 1);
            }
            for ext in ["EXT_meshopt_compression", "KHR_meshopt_compression"] {
                if let Some(e) = v.pointer_mut(&format!("/extensions/{ext}"))
                    && let Some(b) = e.get("buffer").and_then(Value::as_u64)
                {
                    e["buffer"] = json!(b + 1);
                }
            }
        }
    }
}
