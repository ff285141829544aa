//! Partial: one shard's finished pages in a file of their own.
//!
//! In: a [`Partial`] (what identifies the bake, the shard, its pages'
//! encoded images). Out: the file's bytes, and back. Layout:
//!
//! ```text
//! "AOBAKE-PARTIAL\n\0"            16 B magic
//! header length                    u64 LE
//! header                           JSON: PartialHeader
//! blobs                            the PNGs, back to back
//! length of everything above       u64 LE
//! CRC-32 of everything above       u32 LE
//! "END\0"                          4 B
//! ```
//!
//! A file cut short, or changed, fails the trailer or the CRC: [`read`]
//! refuses it. Floats (scales, offsets) are stored as their bits, so the
//! merged file holds exactly the shard's values.

use crate::bake::adaptive::Scale;
use crate::encode::{Encoded, EncodedVisibility};
use crate::lightmap::seams::SolveRange;
use crate::sh::SH_COUNT;
use serde::{Deserialize, Serialize};

const MAGIC: &[u8; 16] = b"AOBAKE-PARTIAL\n\0";
const END: &[u8; 4] = b"END\0";
/// The layout's version: a merge refuses another.
pub(crate) const FORMAT: u32 = 1;

/// What makes two shards parts of the same bake.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// The aobake version that baked it.
    pub aobake: String,
    /// Hash of the input file's bytes ([`super::hash64`]), hex.
    pub input_hash: String,
    /// Hash of the settings' JSON, hex.
    pub settings_hash: String,
    /// Shards in the set.
    pub count: u32,
    /// Pages of the atlas.
    pub pages: u32,
}

/// The header of a partial.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartialHeader {
    pub format: u32,
    pub identity: Identity,
    /// This shard's index.
    pub shard: u32,
    /// The input's absolute path when the shard ran.
    pub input: String,
    /// The bake's settings (their hash is in the identity).
    pub settings: serde_json::Value,
    pub pages: Vec<PageImages>,
    /// With `--reuse`: the bake space taken from PREV (centre, unit), so
    /// the merge builds the level the shards baked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub space: Option<[f64; 4]>,
    /// With `--reuse`: this shard's pages that are PREV's images (no ray
    /// of the edit reaches them); the merge's pass across pages leaves
    /// their seams as PREV solved them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub from_prev: Vec<u32>,
    /// A small page's atlas options as the engine view measured them and
    /// the one kept (`--ladder view`; the bake report's `ladder`), so the
    /// merge builds the level the shards baked without baking them again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ladder: Option<serde_json::Value>,
}

/// One page's encoded images: blob indices and the floats' bits.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PageImages {
    pub page: u32,
    pub occlusion: usize,
    pub sh: [usize; 3],
    pub sh_scale: Vec<u32>,
    pub sh_offset: Vec<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub visibility: Option<VisibilityImages>,
    /// The adaptive allocation's scale: log2 scale's and margin's bits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<(u32, u64)>,
    /// The solve's range: each channel's lowest and highest value's bits.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_range: Option<(Vec<u32>, Vec<u32>)>,
    /// The receivers inside geometry, as runs of texels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inside: Option<Vec<u32>>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct VisibilityImages {
    pub png: Vec<usize>,
    pub scale: Vec<u32>,
    pub offset: Vec<u32>,
}

/// A shard's pages, decoded.
#[derive(Clone, Debug)]
pub struct Partial {
    pub header: PartialHeader,
    /// `(page, images)` for every page of the shard.
    pub pages: Vec<(u32, Encoded)>,
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn floats(v: &[u32]) -> Vec<f32> {
    v.iter().map(|&b| f32::from_bits(b)).collect()
}

/// The file's bytes (`header.pages` is filled from `pages`).
pub fn write<'a>(mut header: PartialHeader, pages: &[(u32, &'a Encoded)]) -> Vec<u8> {
    let mut owned: Vec<&'a [u8]> = Vec::new();
    let mut add = |b: &'a [u8]| {
        owned.push(b);
        owned.len() - 1
    };
    header.pages = pages
        .iter()
        .map(|&(page, e)| PageImages {
            page,
            occlusion: add(&e.occlusion_png),
            sh: [add(&e.sh_png[0]), add(&e.sh_png[1]), add(&e.sh_png[2])],
            sh_scale: bits(&e.sh_scale),
            sh_offset: bits(&e.sh_offset),
            visibility: e.visibility.as_ref().map(|v| VisibilityImages {
                png: v.png.iter().map(|p| add(p)).collect(),
                scale: bits(&v.scale),
                offset: bits(&v.offset),
            }),
            scale: e.scale.map(|s| (s.log_scale.to_bits(), s.margin.to_bits())),
            solve_range: (e.solve_range.as_ref()).map(|r| (bits(&r.lo), bits(&r.hi))),
            inside: e.inside.clone(),
        })
        .collect();
    let sizes: Vec<usize> = owned.iter().map(|b| b.len()).collect();
    let json = serde_json::to_vec(&(&header, sizes)).expect("a header serializes");
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(json.len() as u64).to_le_bytes());
    out.extend_from_slice(&json);
    for b in &owned {
        out.extend_from_slice(b);
    }
    let len = out.len() as u64;
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&crc.to_le_bytes());
    out.extend_from_slice(END);
    out
}

/// Reads a partial's bytes; `Err` says what is wrong with them.
pub fn read(bytes: &[u8]) -> Result<Partial, String> {
    let trailer = 8 + 4 + END.len();
    if bytes.len() < MAGIC.len() + 8 + trailer || &bytes[..MAGIC.len()] != MAGIC {
        return Err("not an aobake partial (no magic, or too short)".into());
    }
    let body = bytes.len() - trailer;
    if &bytes[bytes.len() - END.len()..] != END {
        return Err("truncated (no end marker)".into());
    }
    let len = u64::from_le_bytes(bytes[body..body + 8].try_into().expect("8 bytes"));
    let crc = u32::from_le_bytes(bytes[body + 8..body + 12].try_into().expect("4 bytes"));
    if len != body as u64 {
        return Err(format!(
            "truncated ({body} bytes before the trailer, {len} written)"
        ));
    }
    if crc32fast::hash(&bytes[..body]) != crc {
        return Err("corrupt (checksum mismatch)".into());
    }
    let at = MAGIC.len();
    let hlen = u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes")) as usize;
    let hstart = at + 8;
    if hstart.checked_add(hlen).is_none_or(|e| e > body) {
        return Err("corrupt (header length)".into());
    }
    let (header, sizes): (PartialHeader, Vec<usize>) =
        serde_json::from_slice(&bytes[hstart..hstart + hlen])
            .map_err(|e| format!("corrupt header ({e})"))?;
    if header.format != FORMAT {
        return Err(format!(
            "partial format {} (this aobake reads {FORMAT})",
            header.format
        ));
    }
    let mut blobs = Vec::with_capacity(sizes.len());
    let mut pos = hstart + hlen;
    for s in sizes {
        let end = pos
            .checked_add(s)
            .filter(|&e| e <= body)
            .ok_or("corrupt (blob length)")?;
        blobs.push(bytes[pos..end].to_vec());
        pos = end;
    }
    let blob = |i: usize| blobs.get(i).cloned().ok_or("corrupt (blob index)");
    let arr = |v: &[u32]| -> Result<[f32; SH_COUNT], String> {
        floats(v)
            .try_into()
            .map_err(|_| "corrupt (SH scale length)".to_string())
    };
    let mut pages = Vec::with_capacity(header.pages.len());
    for p in &header.pages {
        let encoded = Encoded {
            occlusion_png: blob(p.occlusion)?,
            sh_png: [blob(p.sh[0])?, blob(p.sh[1])?, blob(p.sh[2])?],
            sh_scale: arr(&p.sh_scale)?,
            sh_offset: arr(&p.sh_offset)?,
            visibility: match &p.visibility {
                Some(v) => Some(EncodedVisibility {
                    png: v.png.iter().map(|&i| blob(i)).collect::<Result<_, _>>()?,
                    scale: floats(&v.scale),
                    offset: floats(&v.offset),
                }),
                None => None,
            },
            scale: p.scale.map(|(l, m)| Scale {
                log_scale: f32::from_bits(l),
                margin: f64::from_bits(m),
            }),
            solve_range: (p.solve_range.as_ref()).map(|(lo, hi)| SolveRange {
                lo: floats(lo),
                hi: floats(hi),
            }),
            inside: p.inside.clone(),
        };
        pages.push((p.page, encoded));
    }
    Ok(Partial { header, pages })
}
