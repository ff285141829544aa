//! `--reuse PREV`: an unchanged input takes PREV as its output, byte for
//! byte, and that is what a full bake writes; every PREV that is not this
//! bake's output (other settings, another input, an edited, truncated or
//! foreign file) gets a line saying why and a full bake, whose bytes are a
//! fresh bake's; a PREV that cannot be read, or that is OUT, is an error.

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
    let moved_fresh = p("moved_fresh.glb");
    bake(&moved_input, &moved_fresh, &[]);

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

    // Another input: the edited scene's own bake, not PREV's.
    let out = p("moved.glb");
    let (_, report) = bake(&moved_input, &out, &["--reuse", prev.to_str().unwrap()]);
    let why = report["reuse"]["full_bake"].as_str().unwrap();
    assert!(why.contains("input differs"), "{why}");
    assert!(
        why.contains("moved nodes[2] \"small.box\"; 3 unchanged"),
        "{why}"
    );
    let nodes = &report["reuse"]["nodes"];
    assert_eq!(nodes["moved"], serde_json::json!([2]), "{nodes}");
    assert_eq!(nodes["unchanged"], 3, "{nodes}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&moved_fresh).unwrap()
    );
    assert_ne!(std::fs::read(&out).unwrap(), prev_bytes);
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
