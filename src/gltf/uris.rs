//! URIs: external buffers and images still found from the output's
//! directory.
//!
//! In: the output document's JSON, the input's directory and the output's.
//! Out: the same JSON, every relative `uri` of `buffers` and `images`
//! rewritten relative to the output's directory (data URIs, absolute paths
//! and URLs untouched).

use super::container::percent_decode;
use crate::error::{Error, Result};
use serde_json::{Value, json};
use std::path::Path;

/// Percent-encodes the characters a relative URI cannot hold.
fn encode_uri_path(p: &str) -> String {
    let mut out = String::with_capacity(p.len());
    for c in p.chars() {
        match c {
            ' ' => out.push_str("%20"),
            '%' => out.push_str("%25"),
            '#' => out.push_str("%23"),
            '?' => out.push_str("%3F"),
            '\\' => out.push('/'),
            c => out.push(c),
        }
    }
    out
}

/// The path of `target` relative to directory `base` (both absolute).
fn relative_path(target: &Path, base: &Path) -> std::path::PathBuf {
    let t: Vec<_> = target.components().collect();
    let b: Vec<_> = base.components().collect();
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = std::path::PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c);
    }
    out
}

/// Rewrites the relative URIs of external buffers and images so they still
/// resolve from `to_dir` (the output's directory) instead of `from_dir`.
pub(crate) fn relocate_uris(json: &mut Value, from_dir: &Path, to_dir: &Path) -> Result<()> {
    let from = std::fs::canonicalize(from_dir).map_err(|e| Error::io(from_dir, e))?;
    let to = std::fs::canonicalize(to_dir).map_err(|e| Error::io(to_dir, e))?;
    if from == to {
        return Ok(());
    }
    for key in ["buffers", "images"] {
        let Some(items) = json.get_mut(key).and_then(Value::as_array_mut) else {
            continue;
        };
        for item in items {
            let Some(uri) = item.get("uri").and_then(Value::as_str) else {
                continue;
            };
            if uri.starts_with("data:") || uri.contains("://") || uri.starts_with('/') {
                continue;
            }
            let decoded = percent_decode(uri);
            let rel = relative_path(&from.join(decoded), &to);
            item["uri"] = json!(encode_uri_path(&rel.to_string_lossy()));
        }
    }
    Ok(())
}
