//! The glTF container: GLB header and chunks or plain JSON, and the bytes of
//! every buffer (GLB BIN chunk, `data:` URIs, external files).
//!
//! In: the input file's bytes and directory. Out: a [`Document`] holding the
//! JSON as `serde_json::Value` (kept whole for the lossless write-back) and
//! the resolved buffers.

use crate::error::{Error, Result};
use base64::Engine;
use serde_json::Value;
use std::path::{Path, PathBuf};

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// A parsed glTF document with its buffers resolved.
#[derive(Debug, Clone)]
pub struct Document {
    /// The whole JSON document, in the input's key order.
    pub json: Value,
    /// Bytes of `buffers[i]`, at least `byteLength` long.
    pub buffers: Vec<Vec<u8>>,
    /// Whether the input was a GLB whose BIN chunk backs `buffers[0]`.
    pub glb_bin: bool,
    /// Directory against which relative URIs resolve.
    pub base_dir: PathBuf,
}

/// Reads and parses a `.glb` or `.gltf` file.
pub(crate) fn read_file(path: &Path) -> Result<Document> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, crate::file::parent_dir(path))
}

/// Parses GLB or JSON bytes; `base_dir` resolves external URIs.
pub fn parse(bytes: &[u8], base_dir: &Path) -> Result<Document> {
    let (json_bytes, bin) = if bytes.len() >= 4 && le_u32(bytes, 0) == GLB_MAGIC {
        glb_chunks(bytes)?
    } else if bytes
        .first()
        .is_some_and(|&b| b == b'{' || b.is_ascii_whitespace())
        || bytes.starts_with(&[0xEF, 0xBB, 0xBF])
    {
        (bytes, None)
    } else {
        return Err(Error::Container(
            "not a glTF file: no GLB magic \"glTF\" and no JSON object".into(),
        ));
    };
    let json_bytes = json_bytes
        .strip_prefix(&[0xEF, 0xBB, 0xBF])
        .unwrap_or(json_bytes);
    let json: Value = serde_json::from_slice(json_bytes)
        .map_err(|e| Error::Container(format!("JSON syntax error: {e}")))?;
    if !json.is_object() {
        return Err(Error::Container("the JSON root is not an object".into()));
    }
    check_version(&json)?;
    let glb_bin = bin.is_some();
    let buffers = resolve_buffers(&json, bin, base_dir)?;
    check_images(&json, base_dir)?;
    Ok(Document {
        json,
        buffers,
        glb_bin,
        base_dir: base_dir.to_path_buf(),
    })
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Splits a GLB into its JSON chunk and optional BIN chunk, checking every
/// length: the one GLB reader ([`parse`] uses it; so can tools and tests).
pub fn glb_chunks(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>)> {
    if bytes.len() < 12 {
        return Err(Error::Container(format!(
            "GLB truncated: {} bytes, the header alone needs 12",
            bytes.len()
        )));
    }
    let version = le_u32(bytes, 4);
    if version != 2 {
        return Err(Error::Container(format!(
            "GLB version {version} is not supported (only 2)"
        )));
    }
    let declared = le_u32(bytes, 8) as usize;
    if declared > bytes.len() {
        return Err(Error::Container(format!(
            "GLB truncated: header declares {declared} bytes, file has {}",
            bytes.len()
        )));
    }
    let data = &bytes[..declared];
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut index = 0;
    while at < data.len() {
        if data.len() - at < 8 {
            return Err(Error::Container(format!(
                "GLB chunk {index} header truncated at byte {at}"
            )));
        }
        let len = le_u32(data, at) as usize;
        let kind = le_u32(data, at + 4);
        let start = at + 8;
        let end = start
            .checked_add(len)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                Error::Container(format!(
                    "GLB chunk {index} declares {len} bytes past the end of the file"
                ))
            })?;
        match (index, kind) {
            (0, CHUNK_JSON) => json = Some(&data[start..end]),
            (0, _) => {
                return Err(Error::Container("GLB first chunk is not JSON".into()));
            }
            (1, CHUNK_BIN) => bin = Some(&data[start..end]),
            _ => {} // unknown chunks are ignored, as the spec requires
        }
        at = end.next_multiple_of(4).max(end);
        index += 1;
    }
    let json = json.ok_or_else(|| Error::Container("GLB has no JSON chunk".into()))?;
    Ok((json, bin))
}

/// Serializes JSON and BIN into a GLB container.
pub fn glb_bytes(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(json).expect("JSON serializes");
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let bin_len = bin.len().next_multiple_of(4);
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin_len };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out.resize(total, 0);
    }
    out
}

fn check_version(json: &Value) -> Result<()> {
    let version = json
        .pointer("/asset/version")
        .and_then(Value::as_str)
        .ok_or_else(|| Error::Invalid("asset.version is missing".into()))?;
    if !version.starts_with("2.") {
        return Err(Error::Unsupported(format!(
            "asset.version \"{version}\" (only glTF 2.x)"
        )));
    }
    Ok(())
}

/// Decodes a percent-encoded relative URI into a path fragment.
pub(crate) fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).ok();
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Resolves a URI (data: or relative path) to bytes. `what` names the object.
pub(crate) fn load_uri(uri: &str, base_dir: &Path, what: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| Error::Unsupported(format!("{what}: data URI is not base64")))?;
        return base64::engine::general_purpose::STANDARD
            .decode(payload.trim())
            .map_err(|e| Error::Invalid(format!("{what}: bad base64 in data URI: {e}")));
    }
    if uri.contains("://") {
        return Err(Error::Unsupported(format!(
            "{what}: remote URI \"{uri}\" (only data: and relative paths)"
        )));
    }
    let path = base_dir.join(percent_decode(uri));
    std::fs::read(&path)
        .map_err(|e| Error::Invalid(format!("{what}: cannot read \"{}\": {e}", path.display())))
}

/// External images are not decoded, but the output refers to them: each
/// must exist as a readable file.
fn check_images(json: &Value, base_dir: &Path) -> Result<()> {
    for (i, img) in json
        .get("images")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .enumerate()
    {
        let Some(uri) = img.get("uri").and_then(Value::as_str) else {
            continue;
        };
        if uri.starts_with("data:") || uri.contains("://") {
            continue;
        }
        let path = base_dir.join(percent_decode(uri));
        std::fs::File::open(&path).map_err(|e| {
            Error::Invalid(format!(
                "images[{i}]: cannot read \"{}\": {e}",
                path.display()
            ))
        })?;
    }
    Ok(())
}

fn resolve_buffers(json: &Value, bin: Option<&[u8]>, base_dir: &Path) -> Result<Vec<Vec<u8>>> {
    let Some(list) = json.get("buffers") else {
        return Ok(Vec::new());
    };
    let list = list
        .as_array()
        .ok_or_else(|| Error::Invalid("buffers is not an array".into()))?;
    let mut out = Vec::with_capacity(list.len());
    for (i, b) in list.iter().enumerate() {
        let what = format!("buffers[{i}]");
        let len = b
            .get("byteLength")
            .and_then(Value::as_u64)
            .ok_or_else(|| Error::Invalid(format!("{what}.byteLength is missing")))?
            as usize;
        let data = match b.get("uri").and_then(Value::as_str) {
            Some(uri) => load_uri(uri, base_dir, &what)?,
            None if i == 0 && bin.is_some() => bin.unwrap_or_default().to_vec(),
            None => {
                // A buffer without data (e.g. a meshopt fallback) reads as absent.
                Vec::new()
            }
        };
        if data.len() < len && !(data.is_empty() && b.get("uri").is_none()) {
            return Err(Error::Invalid(format!(
                "{what}: byteLength is {len} but only {} bytes are present",
                data.len()
            )));
        }
        out.push(data);
    }
    Ok(out)
}
