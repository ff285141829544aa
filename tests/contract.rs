//! The output contract and file safety: encoded textures decode to the baked
//! coefficients, `--uv existing` reuses a UV set, failures leave nothing.
#![allow(clippy::needless_range_loop)]

mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

fn wall_scene() -> Vec<u8> {
    let recv = quad([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 0.5, 0.0], true);
    glb(&[recv, wall], plain_nodes(2))
}

fn png_channels(json: &Value, bin: &[u8], texture: u64) -> (u32, u32, Vec<u8>, usize) {
    let image = json["textures"][texture as usize]["source"]
        .as_u64()
        .unwrap() as usize;
    let view = &json["bufferViews"][json["images"][image]["bufferView"].as_u64().unwrap() as usize];
    let o = view["byteOffset"].as_u64().unwrap() as usize;
    let bytes = &bin[o..o + view["byteLength"].as_u64().unwrap() as usize];
    let img = image::load_from_memory(bytes).unwrap();
    let channels = img.color().channel_count() as usize;
    (img.width(), img.height(), img.into_bytes(), channels)
}

#[test]
fn encoded_textures_decode_to_the_baked_coefficients() {
    let b = aobake::bake_scene(&scene(&wall_scene()), &settings(64, 64, Some(1.0))).unwrap();
    let (json, bin) = split(&b.glb);
    let prim = &json["meshes"][0]["primitives"][0];
    let ext = &prim["extensions"]["AOBAKE_lightmap"];
    let scale: Vec<f32> = ext["shScale"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    let offset: Vec<f32> = ext["shOffset"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    let (w, h, ao, ch) = png_channels(&json, &bin, ext["occlusion"]["index"].as_u64().unwrap());
    assert_eq!((w, h, ch), (b.lightmap.width, b.lightmap.height, 1));
    let pages: Vec<_> = (0..3)
        .map(|p| png_channels(&json, &bin, ext["sh"][p]["index"].as_u64().unwrap()))
        .collect();
    assert!(pages.iter().all(|p| p.3 == 4));
    let mut occluded = 0;
    for t in 0..(w * h) as usize {
        assert!((ao[t] as f32 / 255.0 - b.lightmap.ao[t]).abs() <= 0.5 / 255.0 + 1e-6);
        if b.lightmap.covered[t] && b.lightmap.ao[t] < 0.9 {
            occluded += 1;
        }
        for i in 0..9 {
            let channel = pages[i / 4].2[t * 4 + i % 4] as f32 / 255.0;
            let c = scale[i] * channel + offset[i];
            assert!(
                (c - b.lightmap.sh[t][i]).abs() <= scale[i] * 0.5 / 255.0 + 1e-5,
                "texel {t} c{i}"
            );
        }
        // c0 = 0.282095 AO exactly, per the definitions.
        assert!((b.lightmap.sh[t][0] - 0.282_094_8 * b.lightmap.ao[t]).abs() < 1e-5);
    }
    assert!(occluded > 50, "the wall must darken part of the floor");
    // The material shows the AO through the core occlusionTexture.
    let mat = &json["materials"][prim["material"].as_u64().unwrap() as usize];
    assert_eq!(mat["occlusionTexture"]["index"], ext["occlusion"]["index"]);
    assert_eq!(mat["occlusionTexture"]["texCoord"], ext["texCoord"]);
    assert_eq!(json["extensions"]["AOBAKE_lightmap"]["version"], 1);
    assert!(
        (json["extensions"]["AOBAKE_lightmap"]["maxDistance"]
            .as_f64()
            .unwrap()
            - 1.0)
            .abs()
            < 1e-12
    );
}

#[test]
fn rebake_into_existing_uvs_reproduces_the_bake() {
    let s = settings(64, 256, Some(1.0));
    let first = aobake::bake_scene(&scene(&wall_scene()), &s).unwrap();
    let n = 0; // the quads had no UVs: the generated set is TEXCOORD_0
    let again = aobake::bake_scene(
        &scene(&first.glb),
        &aobake::BakeSettings {
            uv: aobake::UvSource::Existing(n),
            ..s.clone()
        },
    )
    .unwrap();
    let (json, _) = split(&again.glb);
    let p = &json["meshes"][0]["primitives"][0];
    assert_eq!(p["extensions"]["AOBAKE_lightmap"]["texCoord"], n);
    assert!(p["attributes"].get("TEXCOORD_1").is_none(), "no new UV set");
    // Same layout on a square page (the first atlas was cropped to its used
    // rows): compare at the same UV position.
    let (a, f) = (&again.lightmap, &first.lightmap);
    assert_eq!((a.width, a.height), (64, 64));
    let mut diff = 0.0f64;
    let mut count = 0;
    for t in 0..a.ao.len() {
        let (x, y) = (t % 64, t / 64);
        let v = (y as f32 + 0.5) / 64.0;
        let fy = (v * f.height as f32) as usize;
        let ft = fy * f.width as usize + x;
        if a.covered[t] && fy < f.height as usize && f.covered[ft] {
            diff += (a.ao[t] - f.ao[ft]).abs() as f64;
            count += 1;
        }
    }
    assert!(count > 500);
    assert!(
        diff / (count as f64) < 0.01,
        "mean |AO diff| {}",
        diff / count as f64
    );
}

#[test]
fn overlapping_existing_uvs_are_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box.glb");
    let err = aobake::bake_file(
        &path,
        &aobake::BakeSettings {
            uv: aobake::UvSource::Existing(1),
            ..settings(64, 4, None)
        },
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(
        err.contains("overlap") && err.contains("TEXCOORD_1"),
        "{err}"
    );
    let err = aobake::bake_file(
        &path,
        &aobake::BakeSettings {
            uv: aobake::UvSource::Existing(5),
            ..settings(64, 4, None)
        },
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(err.contains("no TEXCOORD_5"), "{err}");
}

#[test]
fn output_equal_to_input_is_refused_and_input_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("scene.glb");
    std::fs::write(&p, wall_scene()).unwrap();
    let before = std::fs::read(&p).unwrap();
    let err = aobake::bake(&p, &p, &settings(32, 4, None), &aobake::RunOptions::QUIET)
        .unwrap_err()
        .to_string();
    assert!(err.contains("is the input file"), "{err}");
    assert_eq!(std::fs::read(&p).unwrap(), before);
    let err = aobake::bake(
        &p,
        &dir.path().join("./scene.glb"),
        &settings(32, 4, None),
        &aobake::RunOptions::QUIET,
    )
    .unwrap_err();
    assert!(err.to_string().contains("is the input file"));
}

#[test]
fn failed_write_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("scene.glb");
    std::fs::write(&p, wall_scene()).unwrap();
    let out = dir.path().join("no_such_dir/out.glb");
    let err = aobake::bake(&p, &out, &settings(32, 4, None), &aobake::RunOptions::QUIET)
        .unwrap_err()
        .to_string();
    assert!(err.contains("no_such_dir"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
}

#[test]
fn cli_reports_one_line_errors_and_nonzero_exit() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.glb");
    std::fs::write(&bad, b"glTF\x02\x00\x00\x00\xff\xff\x00\x00").unwrap();
    let out = dir.path().join("out.glb");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
        .arg(&bad)
        .arg(&out)
        .output()
        .unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("aobake: error: invalid glTF container: GLB truncated"),
        "{stderr}"
    );
    assert!(!out.exists());
}

/// Writes `scene.gltf` + `scene data.bin` + `tex ture.png` into `dir`.
fn write_gltf(dir: &Path, with_image: bool) {
    let (json, bin) = split(&wall_scene());
    let mut json = json;
    json["buffers"][0]["uri"] = serde_json::json!("scene%20data.bin");
    std::fs::write(dir.join("scene data.bin"), &bin).unwrap();
    json["images"] = serde_json::json!([{"uri": "tex%20ture.png"}]);
    json["textures"] = serde_json::json!([{"source": 0}]);
    json["materials"] =
        serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    json["meshes"][0]["primitives"][0]["material"] = serde_json::json!(0);
    if with_image {
        let png = image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 100, 50, 255]));
        png.save(dir.join("tex ture.png")).unwrap();
    }
    std::fs::write(
        dir.join("scene.gltf"),
        serde_json::to_vec_pretty(&json).unwrap(),
    )
    .unwrap();
}

#[test]
fn gltf_with_external_files_bakes_into_another_directory() {
    let dir = tempfile::tempdir().unwrap();
    let (src, dst) = (dir.path().join("in"), dir.path().join("out/deeper"));
    std::fs::create_dir_all(&src).unwrap();
    std::fs::create_dir_all(&dst).unwrap();
    write_gltf(&src, true);
    let out = dst.join("baked.glb");
    aobake::bake(
        &src.join("scene.gltf"),
        &out,
        &settings(64, 8, Some(1.0)),
        &aobake::RunOptions::QUIET,
    )
    .unwrap();
    let (json, bin) = split(&std::fs::read(&out).unwrap());
    // The GLB's own buffer comes first; the external one moved to index 1
    // and its URI now resolves from the output's directory.
    assert!(json["buffers"][0].get("uri").is_none());
    assert_eq!(json["buffers"][1]["uri"], "../../in/scene%20data.bin");
    assert_eq!(json["images"][0]["uri"], "../../in/tex%20ture.png");
    assert_eq!(
        json["buffers"][0]["byteLength"].as_u64().unwrap() as usize,
        bin.len()
    );
    let scene = aobake::gltf::load(&out).expect("output loads, external files resolve");
    assert_eq!(scene.baked_count(), 2);
}

#[test]
fn missing_external_image_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    write_gltf(dir.path(), false);
    let out = dir.path().join("out.glb");
    let err = aobake::bake(
        &dir.path().join("scene.gltf"),
        &out,
        &settings(32, 4, None),
        &aobake::RunOptions::QUIET,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("images[0]") && err.contains("tex ture.png"),
        "{err}"
    );
    assert!(!out.exists());
}

#[cfg(unix)]
#[test]
fn outputs_get_the_mode_of_a_normal_file() {
    use std::os::unix::fs::PermissionsExt;
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o7777;
    let dir = tempfile::tempdir().unwrap();
    // What a plain create gives here (0666 less the umask), not the
    // temporary file's private 0600.
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).unwrap();
    let out = dir.path().join("out.glb");
    aobake::file::write_atomic(&out, b"first").unwrap();
    assert_eq!(mode(&out), mode(&plain));
    // Replacing a file keeps its mode.
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o640)).unwrap();
    aobake::file::write_atomic(&out, b"second").unwrap();
    assert_eq!(mode(&out), 0o640);
    assert_eq!(std::fs::read(&out).unwrap(), b"second");
}
