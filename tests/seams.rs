//! Seam stitching: the two sides of a cut through a smooth surface agree
//! in the written file (read back independently: the decoded AO texture,
//! bilinear with the glTF conventions), creases keep their jump.

mod common;
use aobake::lightmap::seams::SeamMode;
use common::*;
use serde_json::Value;

/// A cylinder of radius 0.3 and height 1 standing on a floor, its side
/// unrolled into TEXCOORD_1 over u in [0.05, 0.95], v in [0.05, 0.45]: the
/// vertices at angle 0 are duplicated, so the edge there is one world edge
/// seen at u = 0.05 and at u = 0.95 (a seam through a smooth surface). The
/// floor gets v in [0.55, 0.95].
fn cylinder_on_floor() -> aobake::gltf::Scene {
    let segments = 48;
    let (mut pos, mut nor, mut uv, mut idx) = (vec![], vec![], vec![], vec![]);
    for i in 0..=segments {
        let a = i as f32 / segments as f32 * std::f32::consts::TAU;
        let (s, c) = a.sin_cos();
        for (k, z) in [0.0f32, 1.0].into_iter().enumerate() {
            pos.push([0.3 * c, 0.3 * s, z]);
            nor.push([c, s, 0.0]);
            uv.push([
                0.05 + 0.9 * i as f32 / segments as f32,
                0.45 - 0.4 * k as f32,
            ]);
        }
    }
    for i in 0..segments as u32 {
        let (a, b) = (2 * i, 2 * i + 2);
        idx.extend([a, b, b + 1, a, b + 1, a + 1]);
    }
    let side = MeshSpec {
        positions: pos,
        normals: Some(nor),
        indices: idx,
    };
    let floor = quad([0.0; 3], [1.5, 0.0, 0.0], [0.0, 1.5, 0.0], true);
    let (mut json, mut bin) = split(&glb(&[side, floor], plain_nodes(2)));
    let floor_uv = [[0.05, 0.95], [0.95, 0.95], [0.95, 0.55], [0.05, 0.55]];
    add_texcoord1(&mut json, &mut bin, &uv, &[0]);
    add_texcoord1(&mut json, &mut bin, &floor_uv, &[1]);
    scene(&aobake::gltf::container::glb_bytes(&json, &bin))
}

fn bake(sc: &aobake::gltf::Scene, seams: SeamMode) -> aobake::job::Baked {
    let s = aobake::BakeSettings {
        uv: aobake::UvSource::Existing(1),
        size: aobake::atlas::AtlasSize::Resolution(128),
        seams,
        // Off: each side as baked, without the border fit either (the fit
        // alone already narrows the cut: 0.022 mean). Stitched: with the
        // band's fit, not the step cells' (at 8 rays noise spans more than
        // a step in many cells, and the test below checks that interior
        // texels stay as baked).
        border: if seams == SeamMode::Off {
            aobake::lightmap::BorderMode::Off
        } else {
            aobake::lightmap::BorderMode::Band
        },
        // Few rays: each side of the cut gets its own noise.
        rays: 8,
        max_distance: Some(1.0),
        ..settings(128, 8, Some(1.0))
    };
    aobake::bake_scene(sc, &s).unwrap()
}

/// The AO of the written file at (u, v), bilinear, from its PNG.
fn decoded_ao(glb: &[u8]) -> impl Fn(f32, f32) -> f32 {
    let (json, bin) = split(glb);
    let ext: &Value = &json["meshes"][0]["primitives"][0]["extensions"]["AOBAKE_lightmap"];
    let tex = ext["occlusion"]["index"].as_u64().unwrap() as usize;
    let img = json["textures"][tex]["source"].as_u64().unwrap() as usize;
    let view = &json["bufferViews"][json["images"][img]["bufferView"].as_u64().unwrap() as usize];
    let off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = view["byteLength"].as_u64().unwrap() as usize;
    let png = image::load_from_memory(&bin[off..off + len])
        .unwrap()
        .to_luma8();
    move |u: f32, v: f32| {
        let (w, h) = (png.width() as f32, png.height() as f32);
        let (x, y) = (u * w - 0.5, v * h - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let at = |i: f32, j: f32| {
            let i = i.clamp(0.0, w - 1.0) as u32;
            let j = j.clamp(0.0, h - 1.0) as u32;
            png.get_pixel(i, j)[0] as f32 / 255.0
        };
        let (fx, fy) = (x - x0, y - y0);
        (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x0 + 1.0, y0))
            + fy * ((1.0 - fx) * at(x0, y0 + 1.0) + fx * at(x0 + 1.0, y0 + 1.0))
    }
}

/// Mean and largest |AO jump| across the cut, from the file.
fn cut_jump(glb: &[u8]) -> (f32, f32) {
    let ao = decoded_ao(glb);
    let n = 200;
    let jumps: Vec<f32> = (0..n)
        .map(|k| {
            let v = 0.05 + 0.4 * (k as f32 + 0.5) / n as f32;
            (ao(0.05, v) - ao(0.95, v)).abs()
        })
        .collect();
    (
        jumps.iter().sum::<f32>() / n as f32,
        jumps.iter().copied().fold(0.0, f32::max),
    )
}

#[test]
fn a_cut_through_a_cylinder_is_stitched_to_the_8_bit_level() {
    let sc = cylinder_on_floor();
    let off = bake(&sc, SeamMode::Off);
    let on = bake(&sc, SeamMode::Stitch);
    let (before, before_max) = cut_jump(&off.glb);
    let (after, after_max) = cut_jump(&on.glb);
    eprintln!("cut: mean {before:.4} (max {before_max:.4}) -> {after:.4} (max {after_max:.4})");
    // 8 rays per texel: the two sides' noise differs by several 8-bit steps.
    assert!(before > 6.0 / 255.0, "{before}");
    // After: about one 8-bit step, no visible line.
    assert!(after < 1.5 / 255.0, "{after}");
    assert!(after_max < 8.0 / 255.0, "{after_max}");
    let report = on.report.seams.unwrap();
    assert!(report.seams >= 1 && report.solve.converged, "{report:?}");
    // The cut's world length: 1 (plus nothing else smooth).
    assert!((report.length - 1.0).abs() < 1e-3, "{}", report.length);
    // Interior texels away from the cut's two sides are untouched (the
    // border fit moves only the border band: tests/border_fit.rs).
    let (w, h) = (on.lightmap.width, on.lightmap.height);
    for (t, (a, b)) in on.lightmap.ao.iter().zip(&off.lightmap.ao).enumerate() {
        let x = t as u32 % w;
        let interior = aobake::lightmap::seams::interior(&off.lightmap.covered, w, h, t as u32);
        if (8..=112).contains(&x) && interior {
            assert_eq!(a, b, "texel {t} moved");
        }
    }
}

/// The six faces of a unit box centred on the origin, each with its own
/// flat normals.
fn box_faces() -> [MeshSpec; 6] {
    [
        quad([0.0, 0.0, 0.5], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], true),
        quad([0.0, 0.0, -0.5], [0.0, 0.5, 0.0], [0.5, 0.0, 0.0], true),
        quad([0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5], true),
        quad([-0.5, 0.0, 0.0], [0.0, 0.0, 0.5], [0.0, 0.5, 0.0], true),
        quad([0.0, 0.5, 0.0], [0.0, 0.0, 0.5], [0.5, 0.0, 0.0], true),
        quad([0.0, -0.5, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.5], true),
    ]
}

/// `cube` resting on a floor.
fn on_floor(cube: MeshSpec) -> aobake::gltf::Scene {
    let floor = quad([0.0, 0.0, -0.5], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], true);
    scene(&glb(&[cube, floor], plain_nodes(2)))
}

/// Stitching finds no seam in `sc` and writes the same bytes as `--seams
/// off`.
fn assert_left_as_baked(sc: &aobake::gltf::Scene, s: &aobake::BakeSettings) {
    let on = aobake::bake_scene(sc, s).unwrap();
    let off = aobake::bake_scene(
        sc,
        &aobake::BakeSettings {
            seams: SeamMode::Off,
            ..s.clone()
        },
    )
    .unwrap();
    assert_eq!(on.report.seams.unwrap().seams, 0);
    assert_eq!(on.glb, off.glb);
}

#[test]
fn a_box_keeps_its_creases() {
    // Six faces with their own flat normals: every shared edge is a crease.
    let sc = on_floor(merge(&box_faces()));
    assert_left_as_baked(&sc, &settings(128, 16, None));
}

#[test]
fn a_box_shaded_smooth_keeps_its_creases() {
    // The same box with one normal per corner (the corner's direction), so
    // the two sides of every edge agree on their vertex normals, but their
    // faces are 90 degrees apart: a crease of the contract's AO (each side
    // sees its own face's plane), left as baked. Without the face test
    // (`FLAT_DEGREES` 180) every one of its edges would be stitched.
    let mut cube = merge(&box_faces());
    cube.normals = Some(
        cube.positions
            .iter()
            .map(|p| {
                let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                p.map(|c| c / l)
            })
            .collect(),
    );
    let sc = on_floor(cube);
    let s = settings(128, 16, None);
    let mut timer = aobake::stage::StageTimer::new();
    let level = aobake::job::Level::new(&sc, &s, &aobake::RunOptions::QUIET, &mut timer).unwrap();
    let find = |faces: f32| {
        aobake::lightmap::seams::find::smooth_seams(
            &level.geometry.receivers,
            &level.atlas,
            aobake::lightmap::seams::SMOOTH_DEGREES,
            faces,
        )
        .len()
    };
    assert!(
        find(180.0) > 0,
        "the corner normals make every cut edge smooth"
    );
    assert_eq!(find(aobake::lightmap::seams::FLAT_DEGREES), 0);
    assert_left_as_baked(&sc, &s);
}
