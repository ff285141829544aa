//! Bad input: every case of the corpus gets exit code 1, one line on stderr
//! naming the problem (and the glTF object where there is one), no output
//! file, and an untouched input. The cases are built from a valid scene by
//! one edit each; `tests/corpus/` holds the same files (regenerate with
//! `AOBAKE_WRITE_CORPUS=1 cargo test --test bad_input`), which also seed
//! the loader fuzzer (`fuzz/`).

mod common;
use common::*;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// A valid scene: a floor and a wall, positions / normals / indices each
/// in their own buffer view (accessors 0-2 floor, 3-5 wall).
fn base() -> (Value, Vec<u8>) {
    let floor = quad([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 0.5, 0.0], true);
    split(&glb(&[floor, wall], plain_nodes(2)))
}

fn pack(json: &Value, bin: &[u8]) -> Vec<u8> {
    aobake::gltf::container::glb_bytes(json, bin)
}

/// The valid base scene written as `dir/in.glb`.
fn base_input(dir: &std::path::Path) -> std::path::PathBuf {
    let (j, b) = base();
    let input = dir.join("in.glb");
    std::fs::write(&input, pack(&j, &b)).unwrap();
    input
}

/// Byte offset of accessor `a`'s data in the BIN chunk.
fn accessor_offset(json: &Value, a: usize) -> usize {
    let v = json["accessors"][a]["bufferView"].as_u64().unwrap() as usize;
    json["bufferViews"][v]["byteOffset"].as_u64().unwrap_or(0) as usize
}

fn with_json(edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let (mut j, b) = base();
    edit(&mut j);
    pack(&j, &b)
}

fn with_bin(edit: impl FnOnce(&Value, &mut Vec<u8>)) -> Vec<u8> {
    let (j, mut b) = base();
    edit(&j, &mut b);
    pack(&j, &b)
}

/// (file name, bytes, what stderr must say, extra CLI arguments).
type Case = (&'static str, Vec<u8>, &'static str, Vec<&'static str>);

fn corpus() -> Vec<Case> {
    let valid = {
        let (j, b) = base();
        pack(&j, &b)
    };
    let le = |v: u32| v.to_le_bytes();
    let mut cases: Vec<Case> = vec![
        ("empty_file.glb", vec![], "not a glTF file", vec![]),
        (
            "truncated.glb",
            valid[..valid.len() / 2].to_vec(),
            "GLB truncated",
            vec![],
        ),
        (
            "wrong_magic.glb",
            [b"glTX".as_slice(), &valid[4..]].concat(),
            "not a glTF file",
            vec![],
        ),
        (
            "wrong_version.glb",
            [&valid[..4], &le(1), &valid[8..]].concat(),
            "GLB version 1 is not supported",
            vec![],
        ),
        (
            "chunk_past_end.glb",
            [&valid[..12], &le(0x7fff_fff0), &valid[16..]].concat(),
            "GLB chunk 0 declares",
            vec![],
        ),
        (
            "json_syntax_error.gltf",
            b"{\"asset\": {\"version\": \"2.0\"},".to_vec(),
            "JSON syntax error",
            vec![],
        ),
        (
            "accessor_past_buffer_view.glb",
            with_json(|j| j["accessors"][0]["count"] = json!(400)),
            "accessors[0]",
            vec![],
        ),
        (
            "index_past_vertex_count.glb",
            with_bin(|j, b| {
                let o = accessor_offset(j, 2) + 4;
                b[o..o + 4].copy_from_slice(&le(99));
            }),
            "meshes[0].primitives[0]",
            vec![],
        ),
        (
            "byte_stride_too_small.glb",
            with_json(|j| j["bufferViews"][0]["byteStride"] = json!(4)),
            "byteStride",
            vec![],
        ),
        (
            "nan_position.glb",
            with_bin(|j, b| {
                let o = accessor_offset(j, 0);
                b[o..o + 4].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
            "meshes[0].primitives[0]",
            vec![],
        ),
        (
            "inf_position.glb",
            with_bin(|j, b| {
                let o = accessor_offset(j, 3) + 8;
                b[o..o + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
            }),
            "meshes[1].primitives[0]",
            vec![],
        ),
        (
            "empty_scene.glb",
            with_json(|j| j["scenes"][0]["nodes"] = json!([])),
            "nothing to bake",
            vec![],
        ),
        (
            "no_triangles.glb",
            with_json(|j| {
                for m in 0..2 {
                    j["meshes"][m]["primitives"][0]["mode"] = json!(0);
                }
            }),
            "no triangle primitive",
            vec![],
        ),
        (
            "only_degenerate_triangles.glb",
            with_bin(|j, b| {
                // Every vertex of both meshes at one point.
                for a in [0, 3] {
                    let o = accessor_offset(j, a);
                    let first: Vec<u8> = b[o..o + 12].to_vec();
                    for v in 1..4 {
                        b[o + 12 * v..o + 12 * v + 12].copy_from_slice(&first);
                    }
                }
            }),
            "degenerate",
            vec![],
        ),
        (
            "huge_accessor_count.glb",
            with_json(|j| j["accessors"][0]["count"] = json!(4_000_000_000u64)),
            "accessors[0]",
            vec![],
        ),
        (
            "huge_buffer_length.glb",
            with_json(|j| j["buffers"][0]["byteLength"] = json!(1u64 << 40)),
            "buffers[0]",
            vec![],
        ),
        (
            "index_accessor_float.glb",
            with_json(|j| j["accessors"][2]["componentType"] = json!(5126)),
            "meshes[0].primitives[0]",
            vec![],
        ),
        (
            "missing_accessor.glb",
            with_json(|j| j["meshes"][1]["primitives"][0]["attributes"]["POSITION"] = json!(42)),
            "meshes[1].primitives[0]",
            vec![],
        ),
        (
            "node_cycle.glb",
            with_json(|j| {
                j["nodes"][0]["children"] = json!([1]);
                j["nodes"][1]["children"] = json!([0]);
            }),
            "nodes[",
            vec![],
        ),
        (
            "uv_out_of_range.glb",
            {
                // TEXCOORD_1 with a coordinate of 1.5.
                let (mut j, mut b) = base();
                let uvs = [[0.0, 0.0], [1.5, 0.0], [1.0, 1.0], [0.0, 1.0]];
                add_texcoord1(&mut j, &mut b, &uvs, &[0, 1]);
                pack(&j, &b)
            },
            "TEXCOORD_1",
            vec!["--uv", "existing", "--uv-set", "1"],
        ),
    ];
    // Found by the bake fuzzer: a material index with no materials array
    // panicked in the writer.
    cases.push((
        "material_missing.glb",
        with_json(|j| j["meshes"][0]["primitives"][0]["material"] = json!(0)),
        "meshes[0].primitives[0].material 0 does not exist",
        vec![],
    ));
    cases.push((
        "material_not_an_object.glb",
        with_json(|j| {
            j["materials"] = json!([5]);
            j["meshes"][1]["primitives"][0]["material"] = json!(0);
        }),
        "materials[0] is not an object",
        vec![],
    ));
    // Compressed geometry (tests/data/): one edit each to a valid file.
    cases.extend(compressed_cases());
    // Garbage after a valid GLB magic and version.
    let mut garbage = b"glTF".to_vec();
    garbage.extend_from_slice(&le(2));
    garbage.extend_from_slice(&le(64));
    garbage.extend((0..52u32).map(|i| (i * 37 % 251) as u8));
    cases.push((
        "garbage_chunks.glb",
        garbage,
        "invalid glTF container",
        vec![],
    ));
    cases
}

/// A GLB of tests/data, edited.
fn edited(name: &str, edit: impl FnOnce(&mut Value, &mut Vec<u8>)) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let (mut j, mut b) = split(&std::fs::read(path).unwrap());
    edit(&mut j, &mut b);
    pack(&j, &b)
}

/// Corrupt Draco and meshopt streams, each named by its object.
fn compressed_cases() -> Vec<Case> {
    let draco_view = |j: &Value| {
        let v = j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
            ["bufferView"]
            .as_u64()
            .unwrap() as usize;
        let o = j["bufferViews"][v]["byteOffset"].as_u64().unwrap_or(0) as usize;
        (v, o)
    };
    let meshopt = "/extensions/EXT_meshopt_compression";
    let meshopt_offset = |j: &Value, v: usize| {
        j["bufferViews"][v]
            .pointer(&format!("{meshopt}/byteOffset"))
            .unwrap()
            .as_u64()
            .unwrap() as usize
    };
    vec![
        (
            "draco_bad_magic.glb",
            edited("lantern_draco.glb", |j, b| {
                let (_, o) = draco_view(j);
                b[o..o + 5].copy_from_slice(b"XXXXX");
            }),
            "meshes[0].primitives[0]: KHR_draco_mesh_compression data is corrupt",
            vec![],
        ),
        (
            "draco_truncated.glb",
            edited("lantern_draco.glb", |j, _| {
                let (v, _) = draco_view(j);
                let n = j["bufferViews"][v]["byteLength"].as_u64().unwrap();
                j["bufferViews"][v]["byteLength"] = json!(n / 3);
            }),
            "meshes[0].primitives[0]: KHR_draco_mesh_compression data is corrupt",
            vec![],
        ),
        (
            "meshopt_bad_header.glb",
            edited("lantern_meshopt.glb", |j, b| {
                let o = meshopt_offset(j, 1);
                b[o] = 0xff;
            }),
            "bufferViews[1]: EXT_meshopt_compression data is corrupt",
            vec![],
        ),
        (
            "meshopt_truncated.glb",
            edited("lantern_meshopt.glb", |j, _| {
                let e = j["bufferViews"][1].pointer_mut(meshopt).unwrap();
                let n = e["byteLength"].as_u64().unwrap();
                e["byteLength"] = json!(n / 2);
            }),
            "bufferViews[1]: EXT_meshopt_compression data is corrupt",
            vec![],
        ),
        (
            "meshopt_index_garbage.glb",
            edited("lantern_meshopt.glb", |j, b| {
                let o = meshopt_offset(j, 2) + 20;
                b[o..o + 3000].fill(0x37);
            }),
            "bufferViews[2]: EXT_meshopt_compression data is corrupt",
            vec![],
        ),
        (
            "meshopt_outside_buffer.glb",
            edited("lantern_meshopt.glb", |j, _| {
                j["bufferViews"][2].pointer_mut(meshopt).unwrap()["byteOffset"] = json!(10_000_000);
            }),
            "bufferViews[2]: EXT_meshopt_compression bytes 10000000+",
            vec![],
        ),
        (
            "meshopt_unknown_filter.glb",
            edited("lantern_meshopt.glb", |j, _| {
                j["bufferViews"][1].pointer_mut(meshopt).unwrap()["filter"] = json!("SPIRAL");
            }),
            "bufferViews[1]: EXT_meshopt_compression filter SPIRAL is not supported",
            vec![],
        ),
    ]
}

fn run_cli(input: &Path, output: &Path, extra: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
        .arg(input)
        .arg(output)
        .arg("-q")
        .args(if extra.contains(&"--rays") {
            &[][..]
        } else {
            &["--rays", "4"][..]
        })
        .args(
            if extra.contains(&"--resolution") || extra.contains(&"--texel-density") {
                &[][..]
            } else {
                &["--resolution", "64"][..]
            },
        )
        .args(extra)
        .output()
        .unwrap()
}

fn assert_refused(input: &Path, output: &Path, extra: &[&str], expect: &str) {
    let before = std::fs::read(input).unwrap();
    let run = run_cli(input, output, extra);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    let name = input.file_name().unwrap().to_string_lossy();
    assert_eq!(run.status.code(), Some(1), "{name}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{name}: {stderr}");
    assert!(stderr.starts_with("aobake: error: "), "{name}: {stderr}");
    assert!(
        stderr.contains(expect),
        "{name}: expected '{expect}' in: {stderr}"
    );
    assert!(!output.exists(), "{name}: output left behind");
    assert_eq!(
        std::fs::read(input).unwrap(),
        before,
        "{name}: input changed"
    );
    // Nothing else (no temporary file) left next to the output either.
    let dir = output.parent().unwrap();
    let leftovers: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains(".aobake-"))
        .collect();
    assert!(leftovers.is_empty(), "{name}: {leftovers:?}");
}

#[test]
fn every_corpus_case_is_refused_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let write_corpus = std::env::var_os("AOBAKE_WRITE_CORPUS").is_some();
    let corpus_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut failures = Vec::new();
    for (name, bytes, expect, extra) in corpus() {
        let input = dir.path().join(name);
        std::fs::write(&input, &bytes).unwrap();
        if write_corpus {
            std::fs::create_dir_all(&corpus_dir).unwrap();
            std::fs::write(corpus_dir.join(name), &bytes).unwrap();
        }
        let out_dir = tempfile::tempdir().unwrap();
        let out = out_dir.path().join("out.glb");
        let result = std::panic::catch_unwind(|| assert_refused(&input, &out, &extra, expect));
        if let Err(e) = result {
            let why = e
                .downcast_ref::<String>()
                .cloned()
                .unwrap_or_else(|| "panic".into());
            failures.push(why);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn checked_in_corpus_matches_the_generator() {
    let corpus_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    for (name, bytes, _, _) in corpus() {
        let path = corpus_dir.join(name);
        let stored = std::fs::read(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e}; regenerate with AOBAKE_WRITE_CORPUS=1",
                path.display()
            )
        });
        assert_eq!(stored, bytes, "{name} differs from the generator");
    }
}

#[test]
fn missing_external_buffer_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("scene.gltf");
    let doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "missing.bin", "byteLength": 48}],
    });
    std::fs::write(&input, serde_json::to_vec(&doc).unwrap()).unwrap();
    assert_refused(&input, &dir.path().join("out.glb"), &[], "missing.bin");
}

#[test]
fn unwritable_output_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = base_input(dir.path());
    // A directory that does not exist.
    let missing = dir.path().join("no/such/dir/out.glb");
    assert_refused(&input, &missing, &[], "no/such/dir");
    // An output path that is a directory.
    let as_dir = dir.path().join("taken");
    std::fs::create_dir(&as_dir).unwrap();
    let run = run_cli(&input, &as_dir, &[]);
    assert_eq!(run.status.code(), Some(1));
    assert!(as_dir.is_dir());
}

#[test]
fn output_equal_to_input_is_refused_even_through_another_path() {
    let dir = tempfile::tempdir().unwrap();
    let input = base_input(dir.path());
    let before = std::fs::read(&input).unwrap();
    let other = dir.path().join(".").join("sub/../in.glb");
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let run = run_cli(&input, &other, &[]);
    assert_eq!(run.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("is the input file"), "{stderr}");
    assert_eq!(std::fs::read(&input).unwrap(), before);
}

#[test]
fn memory_estimate_refuses_huge_atlases_before_allocating() {
    // A valid TEXCOORD_1 on the floor only, baked into a 16000^2 page.
    let floor = quad([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], true);
    let (mut j, mut b) = split(&glb(&[floor], plain_nodes(1)));
    let uvs = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    add_texcoord1(&mut j, &mut b, &uvs, &[0]);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.glb");
    std::fs::write(&input, pack(&j, &b)).unwrap();
    let start = std::time::Instant::now();
    assert_refused(
        &input,
        &dir.path().join("out.glb"),
        &["--uv", "existing", "--uv-set", "1", "--resolution", "16000"],
        "GiB limit",
    );
    // Refused from the estimate, not after allocating 16000^2 texels.
    assert!(start.elapsed().as_secs_f64() < 5.0);
    // The same file at a sane size bakes.
    let out = dir.path().join("ok.glb");
    let run = run_cli(&input, &out, &["--uv", "existing", "--uv-set", "1"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// A build without the GPU backend refuses `--device gpu` at once (`auto`
/// traces on the CPU).
#[cfg(not(feature = "gpu"))]
#[test]
fn a_gpu_without_the_backend_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = base_input(dir.path());
    let out = dir.path().join("out.glb");
    assert_refused(
        &input,
        &out,
        &["--device", "gpu"],
        "--device gpu: this build has no GPU backend",
    );
}

#[test]
fn bad_options_are_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let input = base_input(dir.path());
    let out = dir.path().join("out.glb");
    for (args, expect) in [
        (vec!["--resolution", "8"], "--resolution 8 is outside"),
        (vec!["--texel-density", "0"], "--texel-density 0"),
        (vec!["--rays", "0"], "--rays must be at least 1"),
        (vec!["--max-distance", "0"], "--max-distance 0"),
        (
            vec!["--method", "filtered", "--sparse-rays", "0"],
            "--sparse-rays 0",
        ),
        (
            vec!["--method", "filtered", "--cell-rays", "0"],
            "--cell-rays 0",
        ),
        (
            vec!["--method", "filtered", "--gather-radius", "1e30"],
            "--gather-radius",
        ),
        (
            vec!["--method", "filtered", "--omega-v", "inf"],
            "--omega-v inf",
        ),
        (
            vec!["--method", "filtered", "--min-weight", "nan"],
            "--min-weight NaN",
        ),
    ] {
        assert_refused(&input, &out, &args, expect);
    }
}
