//! Accessor decoding with every range checked before anything is allocated:
//! byteStride, byteOffset, sparse substitution, normalized and plain integer
//! components (KHR_mesh_quantization).
//!
//! In: a [`Document`] and an accessor index. Out: a [`RawAccessor`] holding
//! the elements tightly packed in their original component type, convertible
//! to `f32` vectors or `u32` indices.

use super::container::Document;
use crate::error::{Error, Result};
use serde_json::Value;

/// Largest accessor the loader will materialize (bytes); protects the machine
/// from documents that declare huge counts without backing data.
pub(crate) const MAX_ACCESSOR_BYTES: u64 = 2 << 30;

/// glTF component types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Component {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl Component {
    pub fn from_gl(code: u64) -> Option<Self> {
        Some(match code {
            5120 => Component::I8,
            5121 => Component::U8,
            5122 => Component::I16,
            5123 => Component::U16,
            5125 => Component::U32,
            5126 => Component::F32,
            _ => return None,
        })
    }
    pub fn size(self) -> usize {
        match self {
            Component::I8 | Component::U8 => 1,
            Component::I16 | Component::U16 => 2,
            Component::U32 | Component::F32 => 4,
        }
    }
    /// Reads one component as f32, applying glTF's normalization rule if asked.
    #[inline]
    fn read(self, b: &[u8], normalized: bool) -> f32 {
        match self {
            Component::I8 => {
                let v = b[0] as i8 as f32;
                if normalized { (v / 127.0).max(-1.0) } else { v }
            }
            Component::U8 => {
                let v = b[0] as f32;
                if normalized { v / 255.0 } else { v }
            }
            Component::I16 => {
                let v = i16::from_le_bytes([b[0], b[1]]) as f32;
                if normalized {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            Component::U16 => {
                let v = u16::from_le_bytes([b[0], b[1]]) as f32;
                if normalized { v / 65535.0 } else { v }
            }
            Component::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            Component::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        }
    }
}

/// Number of components for an accessor `type` string.
pub(crate) fn type_dims(ty: &str) -> Option<usize> {
    Some(match ty {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// An accessor's elements, tightly packed, in the original component type.
#[derive(Debug, Clone)]
pub struct RawAccessor {
    pub component: Component,
    pub dims: usize,
    pub normalized: bool,
    pub count: usize,
    pub type_name: String,
    pub bytes: Vec<u8>,
}

impl RawAccessor {
    pub fn element_size(&self) -> usize {
        self.component.size() * self.dims
    }

    /// Elements as `[f32; N]`, normalized where the accessor says so.
    /// Fails if the accessor has fewer than N components.
    pub fn to_f32<const N: usize>(&self, what: &str) -> Result<Vec<[f32; N]>> {
        if self.dims < N {
            return Err(Error::Invalid(format!(
                "{what}: accessor has {} components, expected {N}",
                self.dims
            )));
        }
        let cs = self.component.size();
        let es = self.element_size();
        Ok(self
            .bytes
            .chunks_exact(es)
            .map(|e| std::array::from_fn(|k| self.component.read(&e[k * cs..], self.normalized)))
            .collect())
    }

    /// Every component as f32, as stored (never normalized): the domain of
    /// an accessor's `min` and `max`.
    pub fn stored_values(&self) -> Vec<f32> {
        let cs = self.component.size();
        self.bytes
            .chunks_exact(cs)
            .map(|b| self.component.read(b, false))
            .collect()
    }

    /// Elements as u32 indices (u8/u16/u32 scalars only).
    pub fn to_indices(&self, what: &str) -> Result<Vec<u32>> {
        if self.dims != 1
            || !matches!(
                self.component,
                Component::U8 | Component::U16 | Component::U32
            )
        {
            return Err(Error::Invalid(format!(
                "{what}: indices must be unsigned byte/short/int scalars"
            )));
        }
        let cs = self.component.size();
        Ok(self
            .bytes
            .chunks_exact(cs)
            .map(|b| match cs {
                1 => b[0] as u32,
                2 => u16::from_le_bytes([b[0], b[1]]) as u32,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            })
            .collect())
    }
}

pub(crate) fn field_usize(v: &Value, key: &str, what: &str) -> Result<Option<usize>> {
    match v.get(key) {
        None => Ok(None),
        Some(x) => x
            .as_u64()
            .map(|n| Some(n as usize))
            .ok_or_else(|| Error::Invalid(format!("{what}.{key} is not a non-negative integer"))),
    }
}

pub(crate) fn array<'a>(json: &'a Value, key: &str) -> &'a [Value] {
    json.get(key)
        .and_then(Value::as_array)
        .map(Vec::as_slice)
        .unwrap_or(&[])
}

/// How errors and warnings name a primitive: `meshes[m].primitives[p]`.
pub fn primitive_label(mesh: usize, primitive: usize) -> String {
    format!("meshes[{mesh}].primitives[{primitive}]")
}

/// A checked byte range of a buffer view: (bytes of the view, stride).
pub(super) fn view_bytes<'d>(
    doc: &'d Document,
    view: usize,
    what: &str,
) -> Result<(&'d [u8], Option<usize>)> {
    let views = array(&doc.json, "bufferViews");
    let v = views
        .get(view)
        .ok_or_else(|| Error::Invalid(format!("{what}: bufferView {view} does not exist")))?;
    let vw = format!("bufferViews[{view}]");
    let buffer = field_usize(v, "buffer", &vw)?
        .ok_or_else(|| Error::Invalid(format!("{vw}.buffer is missing")))?;
    let data = doc
        .buffers
        .get(buffer)
        .ok_or_else(|| Error::Invalid(format!("{vw}: buffer {buffer} does not exist")))?;
    let offset = field_usize(v, "byteOffset", &vw)?.unwrap_or(0);
    let len = field_usize(v, "byteLength", &vw)?
        .ok_or_else(|| Error::Invalid(format!("{vw}.byteLength is missing")))?;
    let end = offset
        .checked_add(len)
        .filter(|&e| e <= data.len())
        .ok_or_else(|| {
            Error::Invalid(format!(
                "{vw}: bytes {offset}..{} lie outside buffers[{buffer}] ({} bytes)",
                offset as u128 + len as u128,
                data.len()
            ))
        })?;
    let stride = field_usize(v, "byteStride", &vw)?;
    Ok((&data[offset..end], stride))
}

/// Reads accessor `index`, applying byteStride and sparse substitution.
pub fn read(doc: &Document, index: usize) -> Result<RawAccessor> {
    let what = format!("accessors[{index}]");
    let acc = array(&doc.json, "accessors")
        .get(index)
        .ok_or_else(|| Error::Invalid(format!("{what} does not exist")))?;
    let component = acc
        .get("componentType")
        .and_then(Value::as_u64)
        .and_then(Component::from_gl)
        .ok_or_else(|| Error::Invalid(format!("{what}.componentType is missing or invalid")))?;
    let type_name = acc
        .get("type")
        .and_then(Value::as_str)
        .ok_or_else(|| Error::Invalid(format!("{what}.type is missing")))?;
    let dims = type_dims(type_name)
        .ok_or_else(|| Error::Invalid(format!("{what}.type \"{type_name}\" is invalid")))?;
    if type_name.starts_with("MAT") && component.size() < 4 && type_name != "MAT4" {
        return Err(Error::Unsupported(format!(
            "{what}: {type_name} with {}-byte components (padded matrix columns)",
            component.size()
        )));
    }
    let normalized = acc
        .get("normalized")
        .and_then(Value::as_bool)
        .unwrap_or(false);
    let count = field_usize(acc, "count", &what)?
        .ok_or_else(|| Error::Invalid(format!("{what}.count is missing")))?;
    let es = component.size() * dims;
    let total = (count as u64).saturating_mul(es as u64);
    if total > MAX_ACCESSOR_BYTES {
        return Err(Error::Limit(format!(
            "{what} declares {count} elements ({total} bytes), more than the {} byte limit",
            MAX_ACCESSOR_BYTES
        )));
    }
    let mut bytes = match field_usize(acc, "bufferView", &what)? {
        None => vec![0u8; total as usize],
        Some(view) => {
            let (data, stride) = view_bytes(doc, view, &what)?;
            let stride = stride.unwrap_or(es);
            if stride < es {
                return Err(Error::Invalid(format!(
                    "{what}: byteStride {stride} of bufferViews[{view}] is smaller than the element size {es}"
                )));
            }
            let offset = field_usize(acc, "byteOffset", &what)?.unwrap_or(0);
            if count > 0 {
                let need = (offset as u128) + (stride as u128) * (count as u128 - 1) + es as u128;
                if need > data.len() as u128 {
                    return Err(Error::Invalid(format!(
                        "{what}: {count} elements need {need} bytes but bufferViews[{view}] has {}",
                        data.len()
                    )));
                }
            }
            let mut out = Vec::with_capacity(total as usize);
            for i in 0..count {
                let s = offset + i * stride;
                out.extend_from_slice(&data[s..s + es]);
            }
            out
        }
    };
    if let Some(sparse) = acc.get("sparse") {
        apply_sparse(doc, sparse, &what, count, es, &mut bytes)?;
    }
    Ok(RawAccessor {
        component,
        dims,
        normalized,
        count,
        type_name: type_name.to_string(),
        bytes,
    })
}

fn apply_sparse(
    doc: &Document,
    sparse: &Value,
    what: &str,
    count: usize,
    es: usize,
    bytes: &mut [u8],
) -> Result<()> {
    let sw = format!("{what}.sparse");
    let n = field_usize(sparse, "count", &sw)?
        .ok_or_else(|| Error::Invalid(format!("{sw}.count is missing")))?;
    let idx = sparse
        .get("indices")
        .ok_or_else(|| Error::Invalid(format!("{sw}.indices is missing")))?;
    let val = sparse
        .get("values")
        .ok_or_else(|| Error::Invalid(format!("{sw}.values is missing")))?;
    let ic = idx
        .get("componentType")
        .and_then(Value::as_u64)
        .and_then(Component::from_gl)
        .filter(|c| matches!(c, Component::U8 | Component::U16 | Component::U32))
        .ok_or_else(|| Error::Invalid(format!("{sw}.indices.componentType is invalid")))?;
    let iview = field_usize(idx, "bufferView", &sw)?
        .ok_or_else(|| Error::Invalid(format!("{sw}.indices.bufferView is missing")))?;
    let vview = field_usize(val, "bufferView", &sw)?
        .ok_or_else(|| Error::Invalid(format!("{sw}.values.bufferView is missing")))?;
    let (idata, _) = view_bytes(doc, iview, &sw)?;
    let (vdata, _) = view_bytes(doc, vview, &sw)?;
    let ioff = field_usize(idx, "byteOffset", &sw)?.unwrap_or(0);
    let voff = field_usize(val, "byteOffset", &sw)?.unwrap_or(0);
    let ics = ic.size();
    if (ioff as u128 + (n as u128) * ics as u128) > idata.len() as u128
        || (voff as u128 + (n as u128) * es as u128) > vdata.len() as u128
    {
        return Err(Error::Invalid(format!(
            "{sw}: {n} entries run past their buffer views"
        )));
    }
    for k in 0..n {
        let b = &idata[ioff + k * ics..];
        let target = match ics {
            1 => b[0] as usize,
            2 => u16::from_le_bytes([b[0], b[1]]) as usize,
            _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
        };
        if target >= count {
            return Err(Error::Invalid(format!(
                "{sw}: index {target} is past the accessor count {count}"
            )));
        }
        bytes[target * es..(target + 1) * es]
            .copy_from_slice(&vdata[voff + k * es..voff + (k + 1) * es]);
    }
    Ok(())
}
