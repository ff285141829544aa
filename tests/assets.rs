//! Every test scene in `assets/` either bakes with a valid, lossless output
//! or is refused with a clear reason. One test per file. The real scenes
//! are the shared test assets whose licenses let them live in the
//! repository (textures shrunk; `assets/CREDITS.md`); `assets/generated/`
//! stands in for the rest, and the script that writes it is checked here.

mod common;
use serde_json::Value;
use std::path::Path;

/// Whether `path` (JSON pointer of the input) may differ in the output.
fn is_documented_edit(path: &str) -> bool {
    let parts: Vec<&str> = path.split('/').skip(1).collect();
    matches!(
        parts.as_slice(),
        ["meshes", _, "primitives", _, "attributes", ..]
            | ["meshes", _, "primitives", _, "indices"]
            | ["meshes", _, "primitives", _, "mode"]
            | ["meshes", _, "primitives", _, "material"]
            | ["nodes", _, "mesh"]
            | ["buffers", "0", "byteLength"]
    )
}

/// Every value of `input` is present and equal in `output`, except documented edits.
fn assert_preserved(input: &Value, output: &Value, path: &str) {
    if is_documented_edit(path) {
        return;
    }
    match (input, output) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, v) in a {
                let p = format!("{path}/{k}");
                let o = b.get(k).unwrap_or_else(|| panic!("{p} was dropped"));
                assert_preserved(v, o, &p);
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            assert!(b.len() >= a.len(), "{path} lost elements");
            for (i, v) in a.iter().enumerate() {
                assert_preserved(v, &b[i], &format!("{path}/{i}"));
            }
        }
        _ => assert_eq!(input, output, "{path} changed"),
    }
}

fn view_bytes<'a>(json: &Value, bin: &'a [u8], view: usize) -> &'a [u8] {
    let v = &json["bufferViews"][view];
    let o = v["byteOffset"].as_u64().unwrap_or(0) as usize;
    &bin[o..o + v["byteLength"].as_u64().unwrap() as usize]
}

fn settings(resolution: u32) -> aobake::BakeSettings {
    common::settings(resolution, 4, None)
}

fn bakes(name: &str, resolution: u32) {
    let path = common::asset_path(name);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.glb");
    let input_bytes = std::fs::read(&path).unwrap();
    let report = aobake::bake(
        &path,
        &out,
        &settings(resolution),
        &aobake::RunOptions::QUIET,
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    assert!(report.texels > 0);
    // Seam stitching (the default) converged, and did not widen any jump.
    let seams = report.seams.as_ref().expect("seam figures");
    assert!(seams.solve.converged, "{name}: {:?}", seams.solve);
    assert!(
        seams.after.ao_mean <= seams.before.ao_mean + 1e-6,
        "{name}: {seams:?}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), input_bytes, "input touched");
    let glb = std::fs::read(&out).unwrap();
    let (ij, ibin) = common::split(&input_bytes);
    let (oj, obin) = common::split(&glb);
    assert_preserved(&ij, &oj, "");
    // Original embedded images are byte-identical.
    for (i, img) in ij["images"].as_array().into_iter().flatten().enumerate() {
        if let Some(v) = img["bufferView"].as_u64() {
            assert!(
                view_bytes(&ij, &ibin, v as usize)
                    == view_bytes(
                        &oj,
                        &obin,
                        oj["images"][i]["bufferView"].as_u64().unwrap() as usize
                    )
            );
        }
    }
    // The contract: extension in extensionsUsed only, every baked primitive
    // carries TEXCOORD_n and the extension.
    assert!(
        oj["extensionsUsed"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e == "AOBAKE_lightmap")
    );
    assert!(
        !oj["extensionsRequired"]
            .as_array()
            .into_iter()
            .flatten()
            .any(|e| e == "AOBAKE_lightmap")
    );
    let mut baked = 0;
    for m in oj["meshes"].as_array().unwrap() {
        for p in m["primitives"].as_array().unwrap() {
            if let Some(e) = p.pointer("/extensions/AOBAKE_lightmap") {
                let n = e["texCoord"].as_u64().unwrap();
                assert!(p["attributes"][format!("TEXCOORD_{n}")].is_u64());
                for k in 0..n {
                    assert!(
                        p["attributes"][format!("TEXCOORD_{k}")].is_u64(),
                        "UV sets not consecutive"
                    );
                }
                baked += 1;
            }
        }
    }
    assert_eq!(baked, report.baked_primitives);
    // The output loads again.
    aobake::gltf::load(&out).unwrap();
    if let Some((errors, warnings)) = common::validate(&out) {
        let (_, in_warnings) = common::validate(&path).unwrap();
        assert_eq!(errors, 0, "{name}: validator errors");
        assert!(
            warnings <= in_warnings,
            "{name}: {warnings} validator warnings, input had {in_warnings}"
        );
    }
}

fn refused(name: &str, reason: &str) {
    let path = common::asset_path(name);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.glb");
    let err = aobake::bake(&path, &out, &settings(256), &aobake::RunOptions::QUIET)
        .expect_err("must be refused")
        .to_string();
    assert!(err.contains(reason), "{name}: {err}");
    assert!(!err.contains('\n'));
    assert!(!out.exists(), "partial output left behind");
}

macro_rules! bake_tests {
    ($($test:ident: $file:literal at $res:literal;)*) => {$(
        #[test]
        fn $test() { bakes($file, $res) }
    )*};
}

bake_tests! {
    boombox_tiny_scale: "boombox_tiny_scale.glb" at 256;
    cad_instances: "generated/cad_instances.glb" at 512;
    cornell_box: "cornell_box.glb" at 256;
    courtyard: "generated/courtyard.glb" at 512;
    dense_detail: "generated/dense_detail.glb" at 256;
    flight_helmet: "flight_helmet.glb" at 512;
    foliage_tree_cesium: "foliage_tree_cesium.glb" at 256;
    lantern_quantized: "../tests/data/lantern_quantized.glb" at 256;
    mixed_lighting_sheen_chair: "mixed_lighting_sheen_chair.glb" at 512;
    negative_scale_floor: "negative_scale_floor.glb" at 256;
    mode_04_tristrip_nonindexed: "primitive_mode_04_tristrip_nonindexed.glb" at 64;
    mode_05_trifan_nonindexed: "primitive_mode_05_trifan_nonindexed.glb" at 64;
    mode_06_triangles_nonindexed: "primitive_mode_06_triangles_nonindexed.glb" at 64;
    mode_11_tristrip_indexed: "primitive_mode_11_tristrip_indexed.glb" at 64;
    mode_12_trifan_indexed: "primitive_mode_12_trifan_indexed.glb" at 64;
    mode_14_triangles_u8_indices: "primitive_mode_14_triangles_u8_indices.glb" at 64;
    simple_meshes_shared_mesh: "simple_meshes_shared_mesh.glb" at 64;
    simple_sparse_accessor: "simple_sparse_accessor.glb" at 64;
    thin_cloth_curtains: "thin_cloth_curtains_intel_sponza.glb" at 1024;
    tricky_fern_mask_without_alpha: "tricky_fern_mask_without_alpha.glb" at 512;
}

#[test]
fn points_are_refused() {
    refused("primitive_mode_00_points.glb", "no triangle primitive");
}
#[test]
fn lines_are_refused() {
    refused("primitive_mode_01_lines.glb", "no triangle primitive");
}
#[test]
fn skinned_only_is_refused() {
    refused("fox_skinned.glb", "skinned, morphed or GPU-instanced");
}
#[test]
fn gpu_instancing_only_is_refused() {
    refused(
        "generated/gpu_instancing.glb",
        "skinned, morphed or GPU-instanced",
    );
}

/// The generated scenes are what `tools/test_scenes.py` writes, byte for
/// byte: the committed files are the script's, not edited by hand.
#[test]
fn the_generated_scenes_are_the_scripts_output() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    // -B: no bytecode cache of tools/glb.py left in the source tree.
    let run = std::process::Command::new("python3")
        .arg("-B")
        .arg(root.join("tools/test_scenes.py"))
        .arg(dir.path())
        .status();
    let Ok(status) = run else {
        common::tools_present("the check of the generated scenes", &["python3"]);
        return;
    };
    assert!(status.success());
    let names = |d: &Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    };
    let committed = root.join("assets/generated");
    assert_eq!(names(dir.path()), names(&committed));
    for name in names(&committed) {
        assert!(
            std::fs::read(dir.path().join(&name)).unwrap()
                == std::fs::read(committed.join(&name)).unwrap(),
            "assets/generated/{name} is not what tools/test_scenes.py writes"
        );
    }
}
