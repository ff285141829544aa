//! `--reuse PREV`: an unchanged input takes PREV as its output, byte for
//! byte, and that is what a full bake writes; every PREV that is not this
//! bake's output (other settings, another input, an edited, truncated or
//! foreign file) gets a line saying why and a full bake, whose bytes are a
//! fresh bake's; an edited input on PREV's atlas carries PREV's page-wide
//! numbers, so texels out of the edit's reach keep PREV's bytes; a PREV
//! that cannot be read, or that is OUT, is an error.

mod common;

use aobake::gltf::container::{glb_bytes, glb_chunks};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SCENE: &str = "assets/cornell_box.glb";
/// Small enough for a debug build, with every stage of a default bake.
const SIZE: &str = "48";

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE)
}

fn aobake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_aobake"))
        .args(args)
        .output()
        .unwrap()
}

/// Bakes `input` into `out` at [`SIZE`] with `extra` arguments; returns
/// stderr and the report.
fn bake(input: &Path, out: &Path, extra: &[&str]) -> (String, Value) {
    let report = out.with_extension("json");
    let mut args = vec![
        input.to_str().unwrap(),
        out.to_str().unwrap(),
        "--resolution",
        SIZE,
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = aobake(&args);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "aobake {args:?}: {err}");
    let report = serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap();
    (err, report)
}

/// A GLB with its JSON edited by `edit`.
fn edited(bytes: &[u8], edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let (json, bin) = glb_chunks(bytes).unwrap();
    let mut json: Value = serde_json::from_slice(json).unwrap();
    edit(&mut json);
    glb_bytes(&json, bin.unwrap_or_default())
}

#[test]
fn an_unchanged_input_takes_prev_which_is_what_a_full_bake_writes() {
    let dir = tempfile::tempdir().unwrap();
    let prev = dir.path().join("prev.glb");
    let (_, full) = bake(&scene(), &prev, &[]);
    assert!(full.get("reuse").is_none());
    let prev_bytes = std::fs::read(&prev).unwrap();

    // The fingerprint is in the extension, sealed (not the zeros).
    let (json, _) = glb_chunks(&prev_bytes).unwrap();
    let json: Value = serde_json::from_slice(json).unwrap();
    let f = &json["extensions"]["AOBAKE_lightmap"]["fingerprint"];
    for key in ["input", "settings", "integrity"] {
        let v = f[key].as_str().unwrap();
        assert!(
            v.len() == 16 && v.chars().all(|c| c.is_ascii_hexdigit()),
            "{f}"
        );
    }
    assert_ne!(f["integrity"], "0000000000000000");

    let out = dir.path().join("out.glb");
    let (err, report) = bake(&scene(), &out, &["--reuse", prev.to_str().unwrap()]);
    assert!(err.contains("reused"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), prev_bytes);
    let r = &report["reuse"];
    assert_eq!(r["reused"], true, "{r}");
    assert_eq!(r["texels_baked"], 0);
    assert_eq!(r["pages_reused"], 1);
    assert_eq!(report["rays_cast"], 0);

    // --rebake all bakes every texel again: the same bytes, so the copy
    // above is exactly a bake.
    let all = dir.path().join("all.glb");
    let (err, report) = bake(
        &scene(),
        &all,
        &["--reuse", prev.to_str().unwrap(), "--rebake", "all"],
    );
    assert!(err.contains("baked"), "{err}");
    assert!(report["rays_cast"].as_u64().unwrap() > 0);
    assert_eq!(report["reuse"]["reused"], false);
    assert_eq!(report["reuse"]["texels_baked"], report["texels"]);
    assert_eq!(std::fs::read(&all).unwrap(), prev_bytes);
    // PREV was only read.
    assert_eq!(std::fs::read(&prev).unwrap(), prev_bytes);
}

#[test]
fn every_prev_that_is_not_this_bakes_output_gets_a_reason_and_a_full_bake() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let prev = p("prev.glb");
    bake(&scene(), &prev, &[]);
    let prev_bytes = std::fs::read(&prev).unwrap();
    let fresh = p("fresh.glb");
    bake(&scene(), &fresh, &[]);
    let fresh_bytes = std::fs::read(&fresh).unwrap();

    // The input with one box moved: its own fresh bake.
    let input_bytes = std::fs::read(scene()).unwrap();
    let moved_input = p("moved_input.glb");
    std::fs::write(
        &moved_input,
        edited(&input_bytes, |j| {
            j["nodes"][2]["translation"][0] = serde_json::json!(-180.0);
        }),
    )
    .unwrap();

    let mut seed = edited(&prev_bytes, |j| {
        j["extensions"]["AOBAKE_lightmap"]["seed"] = serde_json::json!(7);
    });
    // Same length, so only the integrity can tell.
    assert_eq!(seed.len(), prev_bytes.len());
    let mut image = prev_bytes.clone();
    let last = image.len() - 40;
    image[last] ^= 1;
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "truncated",
            prev_bytes[..prev_bytes.len() / 2].to_vec(),
            "not a GLB",
        ),
        (
            "edited extension",
            std::mem::take(&mut seed),
            "changed after aobake wrote it",
        ),
        ("edited image", image, "changed after aobake wrote it"),
        (
            "not an aobake output",
            input_bytes.clone(),
            "not an aobake output",
        ),
        ("not a GLB", b"hello".to_vec(), "not a GLB"),
        (
            "no fingerprint",
            edited(&prev_bytes, |j| {
                let ext = j["extensions"]["AOBAKE_lightmap"].as_object_mut().unwrap();
                ext.remove("fingerprint");
            }),
            "no fingerprint",
        ),
    ];
    for (what, bytes, reason) in cases {
        let bad = p("bad.glb");
        std::fs::write(&bad, &bytes).unwrap();
        let out = p("out.glb");
        let (err, report) = bake(&scene(), &out, &["--reuse", bad.to_str().unwrap()]);
        let r = &report["reuse"];
        assert_eq!(r["reused"], false, "{what}: {r}");
        let why = r["full_bake"].as_str().unwrap();
        assert!(why.contains(reason), "{what}: {why}");
        assert!(
            err.contains("full bake") && err.contains(reason),
            "{what}: {err}"
        );
        assert_eq!(std::fs::read(&out).unwrap(), fresh_bytes, "{what}");
        assert_eq!(std::fs::read(&bad).unwrap(), bytes, "{what}: PREV written");
    }

    // Other settings: the seed named, the seed's own bake written.
    let out = p("seed1.glb");
    let (_, report) = bake(
        &scene(),
        &out,
        &["--reuse", prev.to_str().unwrap(), "--seed", "1"],
    );
    let why = report["reuse"]["full_bake"].as_str().unwrap();
    assert!(why.contains("seed 0, this bake 1"), "{why}");
    let seed1 = p("seed1_fresh.glb");
    bake(&scene(), &seed1, &["--seed", "1"]);
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&seed1).unwrap());
    // A setting the extension does not name.
    let (_, report) = bake(
        &scene(),
        &p("pad.glb"),
        &["--reuse", prev.to_str().unwrap(), "--padding", "3"],
    );
    assert!(
        (report["reuse"]["full_bake"].as_str().unwrap()).contains("other settings"),
        "{report}"
    );

    // Another input on PREV's atlas: PREV's bake space, atlas,
    // allocation and ranges carried, every texel baked; the same bytes
    // with `--rebake all`.
    let out = p("moved.glb");
    let (err, report) = bake(&moved_input, &out, &["--reuse", prev.to_str().unwrap()]);
    let r = &report["reuse"];
    assert_eq!(r["carried"], true, "{r}");
    let why = r["full_bake"].as_str().unwrap();
    assert!(why.contains("input differs"), "{why}");
    assert!(
        why.contains("moved nodes[2] \"small.box\"; 3 unchanged"),
        "{why}"
    );
    assert!(err.contains("atlas, allocation and ranges"), "{err}");
    let nodes = &r["nodes"];
    assert_eq!(nodes["moved"], serde_json::json!([2]), "{nodes}");
    assert_eq!(nodes["unchanged"], 3, "{nodes}");
    let dirty = r["texels_dirty"].as_u64().unwrap();
    assert!(
        dirty > 0 && dirty <= r["texels_baked"].as_u64().unwrap(),
        "{r}"
    );
    let all = p("moved_all.glb");
    bake(
        &moved_input,
        &all,
        &["--reuse", prev.to_str().unwrap(), "--rebake", "all"],
    );
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&all).unwrap());
    assert_ne!(std::fs::read(&out).unwrap(), prev_bytes);

    // A node added: another atlas, so a full bake, a fresh bake's bytes.
    let added = p("added_input.glb");
    std::fs::write(
        &added,
        edited(&input_bytes, |j| {
            let mut node = j["nodes"][2].clone();
            node["name"] = serde_json::json!("extra");
            node["translation"][0] = serde_json::json!(-300.0);
            let k = j["nodes"].as_array().unwrap().len();
            j["nodes"].as_array_mut().unwrap().push(node);
            j["scenes"][0]["nodes"]
                .as_array_mut()
                .unwrap()
                .push(serde_json::json!(k));
        }),
    )
    .unwrap();
    let (fresh_added, out) = (p("added_fresh.glb"), p("added.glb"));
    bake(&added, &fresh_added, &[]);
    let (_, report) = bake(&added, &out, &["--reuse", prev.to_str().unwrap()]);
    let r = &report["reuse"];
    assert_eq!(r["carried"], false, "{r}");
    let why = r["full_bake"].as_str().unwrap();
    assert!(why.contains("added nodes[4] \"extra\""), "{why}");
    assert!(why.contains("moves the atlas's charts"), "{why}");
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&fresh_added).unwrap());

    // An older PREV (its fingerprint without the atlas, sealed as that
    // aobake sealed it): the edited input is baked in full.
    let older = p("older.glb");
    let mut f = serde_json::Value::Null;
    let mut bytes = edited(&prev_bytes, |j| {
        let fp = &mut j["extensions"]["AOBAKE_lightmap"]["fingerprint"];
        for k in [
            "space",
            "atlas",
            "scales",
            "solveRanges",
            "inside",
            "integrity",
        ] {
            fp.as_object_mut().unwrap().remove(k);
        }
        fp["integrity"] = serde_json::json!("0000000000000000");
        f = fp.clone();
    });
    aobake::job::reuse::seal(&mut bytes, &f);
    std::fs::write(&older, &bytes).unwrap();
    let (fresh_moved, out) = (p("moved_fresh.glb"), p("moved_older.glb"));
    bake(&moved_input, &fresh_moved, &[]);
    let (_, report) = bake(&moved_input, &out, &["--reuse", older.to_str().unwrap()]);
    let why = report["reuse"]["full_bake"].as_str().unwrap();
    assert!(
        why.contains("moved nodes[2]") && why.contains("records no atlas"),
        "{why}"
    );
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&fresh_moved).unwrap());
}

/// A 10 x 10 floor (node 0) with a cube of side 0.5 on it (node 1) at
/// `x`.
fn floor_and_cube(x: f32) -> Vec<u8> {
    let floor = common::quad([0.0; 3], [5.0, 0.0, 0.0], [0.0, 0.0, -5.0], true);
    let a = 0.25;
    let faces = [
        ([a, 0.0, 0.0], [0.0, 0.0, -a], [0.0, a, 0.0]),
        ([-a, 0.0, 0.0], [0.0, 0.0, a], [0.0, a, 0.0]),
        ([0.0, 0.0, a], [a, 0.0, 0.0], [0.0, a, 0.0]),
        ([0.0, 0.0, -a], [-a, 0.0, 0.0], [0.0, a, 0.0]),
        ([0.0, a, 0.0], [a, 0.0, 0.0], [0.0, 0.0, -a]),
    ];
    let cube = common::merge(&faces.map(|(o, u, v)| common::quad(o, u, v, true)));
    common::glb(
        &[floor, cube],
        vec![
            serde_json::json!({"mesh": 0, "name": "floor"}),
            serde_json::json!({"mesh": 1, "name": "cube", "translation": [x, a, 0.0]}),
        ],
    )
}

/// A float accessor's values, `dims` per element.
fn floats(json: &Value, bin: &[u8], accessor: usize) -> Vec<f32> {
    let a = &json["accessors"][accessor];
    assert_eq!(a["componentType"], 5126, "{a}");
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let at = |v: &Value| v.as_u64().unwrap_or(0) as usize;
    let start = at(&view["byteOffset"]) + at(&a["byteOffset"]);
    let dims = match a["type"].as_str().unwrap() {
        "VEC2" => 2,
        "VEC3" => 3,
        t => panic!("{t}"),
    };
    let stride = view["byteStride"].as_u64().unwrap_or(4 * dims as u64) as usize;
    (0..at(&a["count"]))
        .flat_map(|i| (0..dims).map(move |k| start + i * stride + 4 * k))
        .map(|o| f32::from_le_bytes(bin[o..o + 4].try_into().unwrap()))
        .collect()
}

/// Every channel of the output's page-0 images (AO, then the SH's RGBA),
/// per texel, and the page's size.
fn texels(json: &Value, bin: &[u8]) -> (u32, u32, Vec<Vec<u8>>) {
    let ext = json["meshes"][0]["primitives"][0]["extensions"]["AOBAKE_lightmap"].clone();
    let image = |texture: &Value| {
        let t = &json["textures"][texture["index"].as_u64().unwrap() as usize];
        let im = &json["images"][t["source"].as_u64().unwrap() as usize];
        let view = &json["bufferViews"][im["bufferView"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = view["byteLength"].as_u64().unwrap() as usize;
        image::load_from_memory(&bin[start..start + len]).unwrap()
    };
    let ao = image(&ext["occlusion"]).into_luma8();
    let (w, h) = ao.dimensions();
    let mut per_texel: Vec<Vec<u8>> = ao.into_raw().into_iter().map(|v| vec![v]).collect();
    for sh in ext["sh"].as_array().unwrap() {
        for (t, px) in image(sh).into_rgba8().into_raw().chunks(4).enumerate() {
            per_texel[t].extend_from_slice(px);
        }
    }
    (w, h, per_texel)
}

#[test]
fn an_edit_on_prevs_atlas_changes_only_the_texels_within_reach_of_it() {
    // The cube moved 0.3 along x: with PREV's globals carried, the floor's
    // texels farther than maxDistance (1) from the cube's box before and
    // after the move keep PREV's bytes; the filter, the border fit, the
    // gutters and the seams' solve may carry a change a few texels
    // further (REACH_TEXELS).
    const REACH_TEXELS: f32 = 4.0;
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let (before, after) = (p("before.glb"), p("after.glb"));
    std::fs::write(&before, floor_and_cube(-3.0)).unwrap();
    std::fs::write(&after, floor_and_cube(-2.7)).unwrap();
    let prev = p("prev.glb");
    let args = ["--max-distance", "1.0"];
    bake(&before, &prev, &args);
    let out = p("out.glb");
    let (_, report) = bake(
        &after,
        &out,
        &["--max-distance", "1.0", "--reuse", prev.to_str().unwrap()],
    );
    assert_eq!(report["reuse"]["carried"], true, "{report}");
    let (pj, pb) = common::split(&std::fs::read(&prev).unwrap());
    let (oj, ob) = common::split(&std::fs::read(&out).unwrap());
    let (w, h, old) = texels(&pj, &pb);
    let (_, _, new) = texels(&oj, &ob);
    // The floor's lightmap UVs and positions, as the output writes them.
    let prim = &oj["meshes"][0]["primitives"][0];
    let set = prim["extensions"]["AOBAKE_lightmap"]["texCoord"]
        .as_u64()
        .unwrap();
    let accessor = |name: &str| prim["attributes"][name].as_u64().unwrap() as usize;
    let uv = floats(&oj, &ob, accessor(&format!("TEXCOORD_{set}")));
    let pos = floats(&oj, &ob, accessor("POSITION"));
    let idx: Vec<usize> = {
        let a = &oj["accessors"][prim["indices"].as_u64().unwrap() as usize];
        let view = &oj["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let n = a["count"].as_u64().unwrap() as usize;
        match a["componentType"].as_u64().unwrap() {
            5125 => (0..n)
                .map(|i| {
                    u32::from_le_bytes(ob[start + 4 * i..start + 4 * i + 4].try_into().unwrap())
                        as usize
                })
                .collect(),
            5123 => (0..n)
                .map(|i| {
                    u16::from_le_bytes(ob[start + 2 * i..start + 2 * i + 2].try_into().unwrap())
                        as usize
                })
                .collect(),
            t => panic!("index type {t}"),
        }
    };
    // World units per texel on the floor: its 10 units over its UV span.
    let (umin, umax) = (uv.iter().step_by(2)).fold((1f32, 0f32), |(a, b), &u| (a.min(u), b.max(u)));
    let texel = 10.0 / ((umax - umin) * w as f32);
    // The cube's boxes before and after, and the distance from them.
    let boxes = [-3.0f32, -2.7].map(|x| ([x - 0.25, 0.0, -0.25], [x + 0.25, 0.5, 0.25]));
    let distance = |q: [f32; 3]| {
        (boxes.iter())
            .map(|(lo, hi)| {
                let d: Vec<f32> = (0..3)
                    .map(|k| (lo[k] - q[k]).max(q[k] - hi[k]).max(0.0))
                    .collect();
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            })
            .fold(f32::INFINITY, f32::min)
    };
    let (mut far, mut near_changed) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let c = [(x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32];
            // The floor point under the texel's centre, if any.
            let world = idx.chunks(3).find_map(|t| {
                let [a, b, d] = [t[0], t[1], t[2]].map(|i| [uv[2 * i], uv[2 * i + 1]]);
                let det = (b[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (b[1] - a[1]);
                let l1 = ((c[0] - a[0]) * (d[1] - a[1]) - (d[0] - a[0]) * (c[1] - a[1])) / det;
                let l2 = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / det;
                let l0 = 1.0 - l1 - l2;
                (l0 >= 0.0 && l1 >= 0.0 && l2 >= 0.0).then(|| {
                    let v = |i: usize, k: usize| pos[3 * t[i] + k];
                    [0, 1, 2].map(|k| l0 * v(0, k) + l1 * v(1, k) + l2 * v(2, k))
                })
            });
            let Some(q) = world else { continue };
            let t = (y * w + x) as usize;
            let d = distance(q);
            if d > 1.0 + REACH_TEXELS * texel {
                far += 1;
                assert_eq!(
                    old[t], new[t],
                    "texel ({x}, {y}) at {q:?}, {d} from the cube"
                );
            } else if old[t] != new[t] {
                near_changed += 1;
            }
        }
    }
    // Both sets are there: the check can fail either way.
    assert!(far > 1000, "{far} floor texels out of reach");
    assert!(near_changed > 50, "{near_changed} changed within reach");
}

#[test]
fn an_edit_rebakes_only_the_texels_it_can_change_with_the_bytes_of_rebaking_all() {
    // The cube moved 0.3 along x on a 256 page, `--rebake texels`: the
    // texels the edit can change are baked again, written over PREV's, and
    // the file is byte for byte a bake of every texel on the same atlas
    // (`--rebake all`).
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let (before, after) = (p("before.glb"), p("after.glb"));
    std::fs::write(&before, floor_and_cube(-3.0)).unwrap();
    std::fs::write(&after, floor_and_cube(-2.7)).unwrap();
    let run = |input: &Path, out: &Path, extra: &[&str]| -> Value {
        let report = out.with_extension("json");
        let mut args = vec![input.to_str().unwrap(), out.to_str().unwrap()];
        // (At 1.0 the edit's reach and the halo ask for 40.5% of the
        // page, past the 40% a part may take: a page baked whole.)
        args.extend_from_slice(&["--resolution", "256", "--max-distance", "0.9"]);
        args.extend_from_slice(&["--report", report.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let o = aobake(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap()
    };
    let prev = p("prev.glb");
    run(&before, &prev, &[]);
    let prev_arg = prev.to_str().unwrap();
    let (out, all) = (p("out.glb"), p("all.glb"));
    let report = run(&after, &out, &["--reuse", prev_arg, "--rebake", "texels"]);
    let all_report = run(&after, &all, &["--reuse", prev_arg, "--rebake", "all"]);
    let baked = |r: &Value| r["reuse"]["texels_baked"].as_u64().unwrap();
    assert!(
        baked(&report) * 2 < baked(&all_report),
        "{} of {} texels baked",
        baked(&report),
        baked(&all_report)
    );
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&all).unwrap());
}

#[test]
fn a_prev_that_cannot_be_read_or_is_out_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let prev = dir.path().join("prev.glb");
    bake(&scene(), &prev, &[]);
    let before = std::fs::read(&prev).unwrap();
    let s = scene();
    let args = |prev: &str, out: &str| -> Output {
        aobake(&[
            s.to_str().unwrap(),
            out,
            "--resolution",
            SIZE,
            "--reuse",
            prev,
        ])
    };
    let o = args(prev.to_str().unwrap(), prev.to_str().unwrap());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("is OUT"), "{err}");
    assert_eq!(std::fs::read(&prev).unwrap(), before);

    let missing = dir.path().join("missing.glb");
    let out = dir.path().join("out.glb");
    let o = args(missing.to_str().unwrap(), out.to_str().unwrap());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--reuse: cannot read"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!out.exists());

    let o = aobake(&[
        s.to_str().unwrap(),
        out.to_str().unwrap(),
        "--rebake",
        "all",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--rebake needs --reuse"));
}

#[test]
fn a_multi_page_edit_bakes_only_the_pages_it_reaches_with_the_bytes_of_rebaking_all() {
    // The courtyard on 8 pages of 128 with seams across them; one bench
    // moved 0.3 along x. Pages that no ray of the edit reaches, and that
    // no seam ties to one it does, are PREV's; the output is byte for
    // byte `--rebake all`'s, which bakes every page.
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let input = common::asset_path("generated/courtyard.glb");
    let moved = p("moved.glb");
    let bytes = std::fs::read(&input).unwrap();
    std::fs::write(
        &moved,
        edited(&bytes, |j| {
            j["nodes"][20]["translation"] = serde_json::json!([0.3, 0.0, 0.0]);
        }),
    )
    .unwrap();
    let run = |input: &Path, out: &Path, extra: &[&str]| -> Value {
        let report = out.with_extension("json");
        let mut a = vec![
            input.to_str().unwrap(),
            out.to_str().unwrap(),
            "--texel-density",
            "3",
            "--page-size",
            "128",
            "--quality",
            "16",
            "--max-distance",
            "1.0",
            "--report",
            report.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let o = aobake(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap()
    };
    let prev = p("prev.glb");
    let full = run(&input, &prev, &[]);
    let prev_s = prev.to_str().unwrap();
    let (part, all) = (p("part.glb"), p("all.glb"));
    let r = run(&moved, &part, &["--reuse", prev_s]);
    run(&moved, &all, &["--reuse", prev_s, "--rebake", "all"]);
    assert!(
        std::fs::read(&part).unwrap() == std::fs::read(&all).unwrap(),
        "the pages taken from PREV differ from rebaking them"
    );
    let reuse = &r["reuse"];
    assert_eq!(reuse["carried"], true, "{reuse}");
    let reused = reuse["pages_reused"].as_u64().unwrap();
    let pages = r["pages"].as_array().unwrap();
    assert_eq!(pages.len(), 8);
    assert!(reused >= 1, "{reuse}");
    let baked_pages = pages.iter().filter(|p| p["baked"] == true).count() as u64;
    assert_eq!(baked_pages + reused, 8);
    let texels = full["texels"].as_u64().unwrap();
    let baked = reuse["texels_baked"].as_u64().unwrap();
    assert!(baked < texels, "{baked} of {texels}");
    // The pages it took are PREV's, and PREV's images differ from the
    // edit's where it baked (else the equality above proves nothing).
    assert_ne!(std::fs::read(&part).unwrap(), std::fs::read(&prev).unwrap());

    // Sharded, then merged: the same bytes as in one process; and shards
    // of the unchanged input give PREV's bytes.
    for (input, same_as) in [(&moved, &part), (&input, &prev)] {
        let out = p("sharded.glb");
        for i in 0..2 {
            run(
                input,
                &out,
                &["--reuse", prev_s, "--shard", &format!("{i}/2")],
            );
        }
        let o = aobake(&["merge", out.to_str().unwrap(), "-q"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(same_as).unwrap(),
            "the merged shards of {} differ",
            input.display()
        );
    }
}
