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
//! An input that differs from PREV's, baked by this aobake under the same
//! settings, is [`Decision::Edited`]: the bake may carry PREV's page-wide
//! numbers and take PREV's images for the pages no ray of the edit reaches
//! ([`super::carry`], `job/incremental.rs`); rebaking only the changed
//! texels within a page is not here yet (`docs/incremental.md`).

use super::carry;
use super::settings::{BakeSettings, Device};
use crate::atlas::Atlas;
use crate::bits::mix64;
use crate::encode::Encoded;
use crate::geometry::BakeSpace;
use crate::gltf::container::glb_chunks;
use crate::gltf::{Document, PrimitiveGeometry, Scene};
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
    /// Every node that places a triangle primitive ([`node_prints`]).
    pub nodes: Vec<NodePrint>,
    /// The bake space ([`carry::space_json`]).
    pub space: Value,
    /// [`carry::atlas_hash`] of the atlas, hex.
    pub atlas: String,
    /// Per page what a later bake carries ([`carry::pages_json`]: `scales`,
    /// `solveRanges`, `inside`), a JSON object.
    pub pages: Value,
}

/// A node's part of the scene as the bake reads it: the shape of what it
/// places (mesh space) and where (its world transform), hashed apart, so a
/// later bake can say which nodes moved, which changed shape, which came
/// and went.
#[derive(Clone, Debug, PartialEq)]
pub struct NodePrint {
    pub node: usize,
    /// Hash of its primitives' positions, normals, triangles and the flags
    /// the bake reads (double-sided, morphed), hex.
    pub shape: String,
    /// Hash of its world transforms and whether each placement is baked.
    pub transform: String,
    /// The world bounding box of its triangles' vertices, min then max
    /// (none when it has no finite vertex): how far an edit of it can
    /// reach ([`carry::dirty`]).
    pub bounds: Option<[f64; 6]>,
}

/// Every node's [`NodePrint`], by node index.
pub fn node_prints(scene: &Scene) -> Vec<NodePrint> {
    let shapes: Vec<u64> = scene.geometries.iter().map(shape_hash).collect();
    type Print = (u64, u64, Option<[f64; 6]>);
    let mut by_node: std::collections::BTreeMap<usize, Print> = Default::default();
    for inst in &scene.instances {
        let (shape, transform, bounds) = by_node.entry(inst.node).or_insert((0x5eed, 0x7a5e, None));
        *shape = mix64(*shape ^ shapes[inst.geometry]);
        let words = inst.transform.to_cols_array().map(f64::to_bits);
        *transform =
            (words.iter().chain([&(inst.baked as u64)])).fold(*transform, |h, &w| mix64(h ^ w));
        let g = &scene.geometries[inst.geometry];
        for &i in &g.triangles {
            let p = inst
                .transform
                .transform_point3(glam::DVec3::from(g.positions[i as usize].map(f64::from)));
            if p.is_finite() {
                let b = bounds.get_or_insert([p.x, p.y, p.z, p.x, p.y, p.z]);
                for k in 0..3 {
                    b[k] = b[k].min(p[k]);
                    b[k + 3] = b[k + 3].max(p[k]);
                }
            }
        }
    }
    (by_node.into_iter())
        .map(|(node, (shape, transform, bounds))| NodePrint {
            node,
            shape: hex(shape),
            transform: hex(transform),
            bounds,
        })
        .collect()
}

fn shape_hash(g: &PrimitiveGeometry) -> u64 {
    let f = |h: u64, v: &[f32; 3]| {
        mix64(h ^ (u64::from(v[0].to_bits()) << 32 | u64::from(v[1].to_bits())))
            ^ u64::from(v[2].to_bits())
    };
    let mut h =
        mix64(g.positions.len() as u64 ^ (g.double_sided as u64) << 40 ^ (g.morphed as u64) << 41);
    h = g.positions.iter().fold(h, f);
    if let Some(n) = &g.normals {
        h = n.iter().fold(mix64(h ^ 1), f);
    }
    g.triangles
        .iter()
        .fold(mix64(h ^ 2), |h, &t| mix64(h ^ u64::from(t)))
}

impl Fingerprint {
    /// The fingerprint of a bake of an input with [`input_hash`] `input`
    /// under `s`, in `space` on `atlas`, its pages encoded as `pages`.
    pub fn new(
        input: u64,
        s: &BakeSettings,
        scene: &Scene,
        space: &BakeSpace,
        atlas: &Atlas,
        pages: &[&Encoded],
    ) -> Fingerprint {
        Fingerprint {
            aobake: env!("CARGO_PKG_VERSION").to_string(),
            input: hex(input),
            settings: hex(settings_hash(s)),
            nodes: node_prints(scene),
            space: carry::space_json(space),
            atlas: hex(carry::atlas_hash(atlas)),
            pages: carry::pages_json(pages),
        }
    }

    /// Its JSON, `integrity` last and unsealed (see [`seal`]).
    pub fn to_json(&self) -> Value {
        let mut f = json!({
            "aobake": self.aobake,
            "input": self.input,
            "settings": self.settings,
            "nodes": self.nodes.iter().map(|n| json!([n.node, n.shape, n.transform, n.bounds])).collect::<Vec<_>>(),
            "space": self.space,
            "atlas": self.atlas,
        });
        let map = f.as_object_mut().expect("an object");
        if let Some(pages) = self.pages.as_object() {
            map.extend(pages.clone());
        }
        map.insert("integrity".into(), json!(UNSEALED));
        f
    }
}

fn hex(h: u64) -> String {
    format!("{h:016x}")
}

/// The input as a bake reads it: the file's bytes, then every buffer it
/// resolves (a `.gltf`'s external `.bin` files among them). Images are not
/// read by a bake, only their URIs, which are in the file.
pub fn input_hash(file_bytes: &[u8], doc: &Document) -> u64 {
    (doc.buffers.iter()).fold(hash64(file_bytes), |h, b| mix64(h ^ hash64(b)))
}

/// The settings as they decide the output's bytes: their JSON, with the
/// device left out: a GPU's answers are the CPU's (to the bit on a
/// software adapter, within the agreement `tests/gpu.rs` checks on
/// hardware), so a bake traced on either is the input's bake.
pub fn settings_hash(s: &BakeSettings) -> u64 {
    let mut s = s.clone();
    s.device = Device::Auto;
    hash64(&serde_json::to_vec(&s).expect("settings serialize"))
}

/// Writes the integrity of `glb` (written with the fingerprint `f`
/// unsealed, [`Fingerprint::to_json`]) into it: the hash of every byte of
/// the file with `integrity` as zeros. Same length, so the GLB stays
/// valid.
pub fn seal(glb: &mut [u8], f: &Value) {
    if let Some(at) = integrity_at(glb, f) {
        let h = hex(hash64(glb));
        glb[at..at + UNSEALED.len()].copy_from_slice(h.as_bytes());
    }
}

/// Where the value of fingerprint `f`'s `integrity` lies in `glb`: the
/// fingerprint is found as the writer serialized it (compact, fields in
/// order: its hashes make it unique in the file), its integrity the last
/// field.
fn integrity_at(glb: &[u8], f: &Value) -> Option<usize> {
    let text = serde_json::to_string(f).ok()?;
    let value = f.get("integrity")?.as_str()?;
    let at = glb.windows(text.len()).position(|w| w == text.as_bytes())?;
    Some(at + text.rfind(value)?)
}

/// Whether a bake may take PREV as its output.
#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    /// PREV is this bake's output, byte for byte.
    Reuse,
    /// PREV was baked by this aobake under these settings, from an input
    /// whose nodes changed as listed (none with `--rebake all` of the
    /// same input): the new bake may carry PREV's record ([`carry`]) if
    /// its atlas is PREV's. Why PREV is not the output, in a clause.
    Edited(String, NodeChanges, carry::PrevRecord),
    /// Bake everything; why PREV could not be used, in one line, and
    /// which nodes changed when the input did.
    Full(String, Option<NodeChanges>),
}

/// What the new bake is: its input's [`input_hash`], its settings, and
/// whether its output's bytes depend on the output's directory (relative
/// URIs of external files) and then whether PREV lies in the same one.
pub struct Wanted<'a> {
    pub input: u64,
    pub settings: &'a BakeSettings,
    /// The input's [`node_prints`], and a node's name for the messages.
    pub nodes: Vec<NodePrint>,
    pub node_name: &'a dyn Fn(usize) -> Option<String>,
    /// The input has relative URIs and PREV lies in another directory
    /// than the output.
    pub moved_uris: bool,
}

/// Decides whether PREV (`prev`, its bytes) is the output the new bake
/// would write (see the module doc); with `all` (`--rebake all`) it
/// never is, but its record may still be carried.
pub fn decide(prev: &[u8], want: &Wanted, all: bool) -> Decision {
    let older = "PREV's fingerprint records no atlas (written by an older aobake)";
    let (why, changes, json) = match check_file(prev, want) {
        Ok(_) if !all && !want.moved_uris => return Decision::Reuse,
        Ok(json) if all => ("--rebake all".to_string(), None, json),
        // Only the JSON's URIs differ: the texels are PREV's.
        Ok(json) => (
            "the input has relative URIs and OUT lies in another directory than PREV".into(),
            None,
            json,
        ),
        Err(Why::Text(why)) => return Decision::Full(why, None),
        Err(Why::Input(b)) => {
            let (changes, json) = *b;
            (
                format!(
                    "the input differs from the one PREV was baked from: {}",
                    changes.describe(want.node_name)
                ),
                Some(changes),
                json,
            )
        }
    };
    let bin = glb_chunks(prev)
        .ok()
        .and_then(|(_, bin)| bin)
        .unwrap_or_default();
    match carry::read(&json, bin) {
        Some(record) => Decision::Edited(why, changes.unwrap_or_default(), record),
        None => Decision::Full(format!("{why}; {older}"), changes),
    }
}

/// Why a check failed: a line, or the input's node changes (with PREV's
/// JSON).
enum Why {
    Text(String),
    Input(Box<(NodeChanges, Value)>),
}

impl From<String> for Why {
    fn from(s: String) -> Why {
        Why::Text(s)
    }
}

impl From<&str> for Why {
    fn from(s: &str) -> Why {
        Why::Text(s.to_string())
    }
}

/// PREV's JSON when PREV is this bake's output.
fn check_file(prev: &[u8], want: &Wanted) -> Result<Value, Why> {
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
        nodes: read_nodes(f).ok_or("PREV's fingerprint has no readable nodes")?,
        space: Value::Null,
        atlas: String::new(),
        pages: Value::Null,
    };
    // The integrity first: an edited file's other fields prove nothing.
    let at = (integrity_at(prev, f))
        .filter(|_| integrity.len() == UNSEALED.len())
        .ok_or("PREV was changed after aobake wrote it (its fingerprint is not as written)")?;
    let mut copy = prev.to_vec();
    copy[at..at + UNSEALED.len()].copy_from_slice(UNSEALED.as_bytes());
    if hex(hash64(&copy)) != integrity {
        return Err(
            "PREV was changed after aobake wrote it (its integrity hash does not match)".into(),
        );
    }
    let this = env!("CARGO_PKG_VERSION");
    if recorded.aobake != this {
        return Err(format!(
            "PREV was baked by aobake {}, this is {this}",
            recorded.aobake
        )
        .into());
    }
    if recorded.settings != hex(settings_hash(want.settings)) {
        return Err(format!(
            "PREV was baked with other settings ({})",
            differing(ext, want.settings)
        )
        .into());
    }
    if recorded.input != hex(want.input) {
        let changes = NodeChanges::between(&recorded.nodes, &want.nodes);
        return Err(Why::Input(Box::new((changes, json))));
    }
    Ok(json)
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

/// What `--reuse PREV` bakes again (`--rebake`): the pages an edit can change (none for an
/// unchanged input: PREV is the output), with `Texels` on them only the texels it can change
/// where the page's solve allows (`job/partial.rs`); `All`: every texel (PREV checked).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Rebake {
    #[default]
    Changed,
    Texels,
    All,
}

fn read_nodes(f: &Value) -> Option<Vec<NodePrint>> {
    (f.get("nodes")?.as_array()?.iter())
        .map(|n| {
            Some(NodePrint {
                node: n.get(0)?.as_u64()? as usize,
                shape: n.get(1)?.as_str()?.to_string(),
                transform: n.get(2)?.as_str()?.to_string(),
                bounds: (n.get(3).and_then(Value::as_array))
                    .and_then(|b| b.iter().map(Value::as_f64).collect::<Option<Vec<_>>>())
                    .and_then(|b| b.try_into().ok()),
            })
        })
        .collect()
}

/// Which nodes an edit touched, by node index: between PREV's prints and
/// the input's.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct NodeChanges {
    /// Same shape, another transform.
    pub moved: Vec<usize>,
    /// Another shape (and maybe another transform).
    pub reshaped: Vec<usize>,
    pub added: Vec<usize>,
    pub deleted: Vec<usize>,
    pub unchanged: usize,
    /// The world boxes of every changed node before and after the edit
    /// (`None`: one that PREV did not record or that has no finite
    /// vertex, which bounds nothing).
    #[serde(skip)]
    pub boxes: Vec<Option<[f64; 6]>>,
}

impl NodeChanges {
    pub fn between(prev: &[NodePrint], now: &[NodePrint]) -> NodeChanges {
        let before: std::collections::BTreeMap<usize, &NodePrint> =
            prev.iter().map(|n| (n.node, n)).collect();
        let after: std::collections::BTreeMap<usize, &NodePrint> =
            now.iter().map(|n| (n.node, n)).collect();
        let mut c = NodeChanges::default();
        for (&k, a) in &after {
            match before.get(&k) {
                None => c.added.push(k),
                Some(b) if b.shape != a.shape => c.reshaped.push(k),
                Some(b) if b.transform != a.transform => c.moved.push(k),
                Some(_) => {
                    c.unchanged += 1;
                    continue;
                }
            }
            c.boxes.push(a.bounds);
            if let Some(b) = before.get(&k) {
                c.boxes.push(b.bounds);
            }
        }
        c.deleted = before
            .keys()
            .filter(|k| !after.contains_key(k))
            .copied()
            .collect();
        c.boxes.extend(c.deleted.iter().map(|k| before[k].bounds));
        c
    }

    /// One clause: the changes by kind, nodes named (a few of each).
    pub fn describe(&self, name: &dyn Fn(usize) -> Option<String>) -> String {
        let list = |nodes: &[usize]| {
            let mut parts: Vec<String> = (nodes.iter().take(3))
                .map(|&k| match name(k) {
                    Some(n) => format!("nodes[{k}] \"{n}\""),
                    None => format!("nodes[{k}]"),
                })
                .collect();
            if nodes.len() > 3 {
                parts.push(format!("{} more", nodes.len() - 3));
            }
            parts.join(", ")
        };
        let mut out: Vec<String> = [
            ("moved", &self.moved),
            ("reshaped", &self.reshaped),
            ("added", &self.added),
            ("deleted", &self.deleted),
        ]
        .into_iter()
        .filter(|(_, v)| !v.is_empty())
        .map(|(what, v)| format!("{what} {}", list(v)))
        .collect();
        if out.is_empty() {
            out.push("no node's geometry or placement changed (other data did)".into());
        } else {
            out.push(format!("{} unchanged", self.unchanged));
        }
        out.join("; ")
    }
}

/// What `--reuse` did, for the report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ReuseReport {
    /// PREV's path.
    pub prev: String,
    /// PREV was taken as the output (nothing the bake reads changed).
    pub reused: bool,
    /// PREV's page-wide numbers were carried into this bake ([`carry`]):
    /// texels out of an edit's reach are PREV's.
    pub carried: bool,
    /// Why every texel was baked, when they were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub full_bake: Option<String>,
    /// With another input: the nodes that moved, changed shape, came or
    /// went.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nodes: Option<NodeChanges>,
    /// Texels baked: the atlas's on a full bake, a part's on a page by texels.
    pub texels_baked: usize,
    /// Receivers an edit could change ([`carry::dirty`]; all on a full bake, none if reused).
    pub texels_dirty: usize,
    /// Atlas pages whose images are PREV's (all of them when reused).
    pub pages_reused: usize,
    /// Pages an edit reaches baked whole, and why (`job/partial.rs`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pages_whole: Vec<(u32, String)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn print(node: usize, shape: &str, transform: &str) -> NodePrint {
        NodePrint {
            bounds: None,
            node,
            shape: shape.into(),
            transform: transform.into(),
        }
    }

    #[test]
    fn node_changes_name_what_moved_reshaped_came_and_went() {
        let prev = [
            print(0, "a", "x"),
            print(1, "b", "y"),
            print(2, "c", "z"),
            print(4, "e", "w"),
        ];
        let now = [
            print(0, "a", "x"),  // unchanged
            print(1, "b", "y2"), // moved
            print(2, "c2", "z"), // reshaped
            print(3, "d", "v"),  // added; 4 deleted
        ];
        let c = NodeChanges::between(&prev, &now);
        assert_eq!(c.moved, [1]);
        assert_eq!(c.reshaped, [2]);
        assert_eq!(c.added, [3]);
        assert_eq!(c.deleted, [4]);
        assert_eq!(c.unchanged, 1);
        let name = |k: usize| (k == 1).then(|| "crate".to_string());
        assert_eq!(
            c.describe(&name),
            "moved nodes[1] \"crate\"; reshaped nodes[2]; added nodes[3]; deleted nodes[4]; 1 unchanged"
        );
        let same = NodeChanges::between(&prev, &prev);
        assert!(same.describe(&name).starts_with("no node's geometry"));
    }

    #[test]
    fn a_sealed_file_checks_and_any_changed_byte_does_not() {
        // A stand-in GLB whose JSON holds an unsealed fingerprint.
        let f = json!({"aobake": "x", "input": "0123456789abcdef", "integrity": UNSEALED});
        let doc = json!({"asset": {"version": "2.0"}, "extensions": {"AOBAKE_lightmap": {"fingerprint": f}}});
        let mut glb = crate::gltf::container::glb_bytes(&doc, &[1, 2, 3, 4]);
        seal(&mut glb, &f);
        let (json, _) = glb_chunks(&glb).unwrap();
        let sealed: Value = serde_json::from_slice(json).unwrap();
        let f = &sealed["extensions"]["AOBAKE_lightmap"]["fingerprint"];
        let integrity = f["integrity"].as_str().unwrap();
        assert_ne!(integrity, UNSEALED);
        // The hash of the file with the zeros back in place.
        let at = integrity_at(&glb, f).unwrap();
        let mut zeros = glb.clone();
        zeros[at..at + 16].copy_from_slice(UNSEALED.as_bytes());
        assert_eq!(hex(hash64(&zeros)), integrity);
        // A changed byte of the BIN chunk changes the hash.
        let last = zeros.len() - 1;
        zeros[last] ^= 1;
        assert_ne!(hex(hash64(&zeros)), integrity);
    }
}
