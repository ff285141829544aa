//! Reuse of an earlier bake (`--reuse PREV`): what an output records about
//! the bake that made it, and whether a new bake may take PREV's result.
//!
//! In: PREV's bytes, the input's bytes and its resolved buffers, the
//! settings. Out: a [`Decision`]: reuse PREV as it is, or bake everything,
//! with the one-line reason; and for every output, the [`Fingerprint`]
//! written into `extensions.AOBAKE_lightmap.fingerprint` and sealed by
//! [`seal`].
//!
//! The rule is exact because a bake is deterministic: the same input
//! bytes (and external buffers), the same settings and the same aobake
//! give the same output bytes on any thread count and in any sharding.
//! So an output whose fingerprint matches the new bake's *is* the new
//! bake's output, and is copied. Anything else is baked in full, with the
//! reason said: never a mix of two bakes. The `integrity` field, a hash
//! of the whole file with the field itself written as zeros, tells an
//! output edited after aobake wrote it (its images, its extension, any
//! byte) from one that was not.
//!
//! Rebaking only the texels an edit can change is not here yet: an
//! input that differs from PREV's is baked in full, and the reason says
//! so (`docs/incremental.md`).

use super::settings::{BakeSettings, Device};
use crate::bits::mix64;
use crate::gltf::Document;
use crate::gltf::container::glb_chunks;
use crate::shard::hash64;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::Path;

/// The fingerprint's integrity before it is sealed: 16 hex zeros.
const UNSEALED: &str = "0000000000000000";

/// What an output records about the bake that wrote it: enough to tell
/// whether a later bake of an input would write the same bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Fingerprint {
    /// The aobake that baked it (`CARGO_PKG_VERSION`).
    pub aobake: String,
    /// [`input_hash`] of the input baked, hex.
    pub input: String,
    /// [`settings_hash`] of the settings, hex.
    pub settings: String,
    /// Where the rays were traced: `cpu` or `gpu`.
    pub device: Device,
}

impl Fingerprint {
    /// The fingerprint of a bake of an input with [`input_hash`] `input`
    /// under `s`, traced on `device`.
    pub fn new(input: u64, s: &BakeSettings, device: Device) -> Fingerprint {
        Fingerprint {
            aobake: env!("CARGO_PKG_VERSION").to_string(),
            input: hex(input),
            settings: hex(settings_hash(s)),
            device,
        }
    }

    /// Its JSON, `integrity` last and unsealed (see [`seal`]).
    pub fn to_json(&self) -> Value {
        json!({
            "aobake": self.aobake,
            "input": self.input,
            "settings": self.settings,
            "device": device_name(self.device),
            "integrity": UNSEALED,
        })
    }
}

fn hex(h: u64) -> String {
    format!("{h:016x}")
}

fn device_name(d: Device) -> &'static str {
    match d {
        Device::Gpu => "gpu",
        _ => "cpu",
    }
}

/// The input as a bake reads it: the file's bytes, then every buffer it
/// resolves (a `.gltf`'s external `.bin` files among them). Images are not
/// read by a bake, only their URIs, which are in the file.
pub fn input_hash(file_bytes: &[u8], doc: &Document) -> u64 {
    (doc.buffers.iter()).fold(hash64(file_bytes), |h, b| mix64(h ^ hash64(b)))
}

/// The settings as they decide the output's bytes: their JSON, with the
/// device left out (recorded apart, as the device it resolved to).
pub fn settings_hash(s: &BakeSettings) -> u64 {
    let mut s = s.clone();
    s.device = Device::Auto;
    hash64(&serde_json::to_vec(&s).expect("settings serialize"))
}

/// The byte pattern of an unsealed fingerprint's tail in a GLB's JSON:
/// unique to it (it holds the settings hash and the device).
fn unsealed_tail(f: &Fingerprint) -> String {
    format!(
        "\"settings\":\"{}\",\"device\":\"{}\",\"integrity\":\"{UNSEALED}\"",
        f.settings,
        device_name(f.device)
    )
}

/// Writes the integrity of `glb` (written with `f` unsealed) into it: the
/// hash of every byte of the file with `integrity` as zeros. Same length,
/// so the GLB stays valid.
pub fn seal(glb: &mut [u8], f: &Fingerprint) {
    let tail = unsealed_tail(f);
    let Some(at) = find(glb, tail.as_bytes()) else {
        return;
    };
    let h = hex(hash64(glb));
    let start = at + tail.len() - 1 - UNSEALED.len();
    glb[start..start + UNSEALED.len()].copy_from_slice(h.as_bytes());
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Whether a bake may take PREV as its output.
#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    /// PREV is this bake's output, byte for byte.
    Reuse,
    /// Bake everything; why PREV could not be used, in one line.
    Full(String),
}

/// What the new bake is: its input's [`input_hash`], its settings, and
/// whether its output's bytes depend on the output's directory (relative
/// URIs of external files) and then whether PREV lies in the same one.
pub struct Wanted<'a> {
    pub input: u64,
    pub settings: &'a BakeSettings,
    /// The input has relative URIs and PREV lies in another directory
    /// than the output.
    pub moved_uris: bool,
}

/// Decides whether PREV (`prev`, its bytes) is the output the new bake
/// would write (see the module doc).
pub fn decide(prev: &[u8], want: &Wanted) -> Decision {
    match check(prev, want) {
        Ok(()) => Decision::Reuse,
        Err(why) => Decision::Full(why),
    }
}

fn check(prev: &[u8], want: &Wanted) -> Result<(), String> {
    let (json, _) =
        glb_chunks(prev).map_err(|e| format!("PREV is not a GLB aobake can read ({e})"))?;
    let json: Value =
        serde_json::from_slice(json).map_err(|e| format!("PREV's JSON does not parse ({e})"))?;
    let ext = json
        .pointer("/extensions/AOBAKE_lightmap")
        .ok_or("PREV has no AOBAKE_lightmap extension: it is not an aobake output")?;
    let f = ext.get("fingerprint").ok_or(
        "PREV's AOBAKE_lightmap has no fingerprint (written by an older aobake or another tool)",
    )?;
    let field = |k: &str| -> Result<&str, String> {
        f.get(k)
            .and_then(Value::as_str)
            .ok_or_else(|| format!("PREV's fingerprint has no {k}"))
    };
    let integrity = field("integrity")?;
    let recorded = Fingerprint {
        aobake: field("aobake")?.to_string(),
        input: field("input")?.to_string(),
        settings: field("settings")?.to_string(),
        device: match field("device")? {
            "gpu" => Device::Gpu,
            "cpu" => Device::Cpu,
            other => {
                return Err(format!(
                    "PREV's fingerprint names an unknown device \"{other}\""
                ));
            }
        },
    };
    // The integrity first: an edited file's other fields prove nothing.
    let sealed = format!(
        "\"settings\":\"{}\",\"device\":\"{}\",\"integrity\":\"{integrity}\"",
        recorded.settings,
        device_name(recorded.device)
    );
    let mut copy = prev.to_vec();
    let at = find(&copy, sealed.as_bytes())
        .ok_or("PREV was changed after aobake wrote it (its fingerprint is not as written)")?;
    let start = at + sealed.len() - 1 - integrity.len();
    copy[start..start + integrity.len()].copy_from_slice(UNSEALED.as_bytes());
    if integrity.len() != UNSEALED.len() || hex(hash64(&copy)) != integrity {
        return Err(
            "PREV was changed after aobake wrote it (its integrity hash does not match)".into(),
        );
    }
    let this = env!("CARGO_PKG_VERSION");
    if recorded.aobake != this {
        return Err(format!(
            "PREV was baked by aobake {}, this is {this}",
            recorded.aobake
        ));
    }
    if recorded.settings != hex(settings_hash(want.settings)) {
        return Err(format!(
            "PREV was baked with other settings ({})",
            differing(ext, want.settings)
        ));
    }
    if want.settings.device != Device::Auto && want.settings.device != recorded.device {
        return Err(format!(
            "PREV was traced on the {}, this bake asks for the {}",
            device_name(recorded.device).to_uppercase(),
            device_name(want.settings.device).to_uppercase()
        ));
    }
    if recorded.input != hex(want.input) {
        return Err(
            "the input differs from the one PREV was baked from (only an unchanged input is reused so far)"
                .into(),
        );
    }
    if want.moved_uris {
        return Err(
            "the input has relative URIs and OUT lies in another directory than PREV".into(),
        );
    }
    Ok(())
}

/// Which recorded setting differs from `s`, as far as the extension's
/// informative fields tell (else the settings as a whole).
fn differing(ext: &Value, s: &BakeSettings) -> String {
    if let Some(seed) = ext.get("seed").and_then(Value::as_u64)
        && seed != s.seed
    {
        return format!("seed {seed}, this bake {}", s.seed);
    }
    if let Some(m) = ext.get("method").and_then(Value::as_str)
        && m != s.method.name()
    {
        return format!("method {m}, this bake {}", s.method.name());
    }
    "a setting that decides the output's bytes differs".into()
}

/// Whether writing an output of the input (`doc`) into `output`'s
/// directory gives other bytes than into `prev`'s: the input has relative
/// URIs of external files, which are rewritten to resolve from the
/// output's directory, and the two directories differ.
pub fn moved_uris(doc: &Document, prev: &Path, output: &Path) -> bool {
    let relative = ["buffers", "images"].iter().any(|key| {
        (doc.json
            .get(*key)
            .and_then(Value::as_array)
            .into_iter()
            .flatten())
        .any(|item| {
            item.get("uri").and_then(Value::as_str).is_some_and(|uri| {
                !(uri.starts_with("data:") || uri.contains("://") || uri.starts_with('/'))
            })
        })
    });
    let dir = |p: &Path| std::fs::canonicalize(crate::file::parent_dir(p)).ok();
    relative && dir(prev) != dir(output)
}

/// What `--reuse PREV` bakes again (`--rebake`): `Changed`, what an edit
/// can change (with an unchanged input nothing: PREV is the output);
/// `All`, every texel (PREV is checked, not used).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Rebake {
    #[default]
    Changed,
    All,
}

/// What `--reuse` did, for the report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ReuseReport {
    /// PREV's path.
    pub prev: String,
    /// PREV was taken as the output (nothing the bake reads changed).
    pub reused: bool,
    /// Why every texel was baked, when they were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub full_bake: Option<String>,
    /// Texels this run baked (every texel of the atlas on a full bake).
    pub texels_baked: usize,
    /// Texels an edit could change: every texel on a full bake, none
    /// when PREV is reused.
    pub texels_dirty: usize,
    /// Atlas pages taken from PREV (all of its pages when reused).
    pub pages_reused: usize,
}
