//! Bakes of simple configurations against closed-form AO and SH.

mod common;
use aobake::sh;
use common::*;
use glam::Vec3;
use serde_json::json;

/// Cosine-weighted hemisphere quadrature (independent of the baker's
/// sampler): (1/pi) Int V(w) (n.w) f(w) dw for n = +z, by a fine midpoint
/// rule in (cos^2 theta, phi), where the cosine weight is uniform.
fn reference(visible: impl Fn(Vec3) -> bool, f: impl Fn(Vec3) -> f64) -> f64 {
    let (nz, np) = (600, 600);
    let mut s = 0.0;
    for i in 0..nz {
        let z2 = (i as f64 + 0.5) / nz as f64;
        let z = z2.sqrt();
        let r = (1.0 - z2).sqrt();
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            if visible(w) {
                s += f(w);
            }
        }
    }
    s / (nz * np) as f64
}

/// Receiver points whose position satisfies `pick`, with their results.
fn picked(b: &aobake::job::Baked, pick: impl Fn(Vec3) -> bool) -> Vec<(Vec3, f32, [f32; 9])> {
    let s = &b.geometry.space;
    (0..b.receivers.len())
        .filter_map(|i| {
            let world = s.to_world(b.receivers.position[i]);
            pick(world).then(|| (world, b.bake.ao[i], b.bake.sh[i]))
        })
        .collect()
}

#[test]
fn open_plane_is_unoccluded_with_clamped_cosine_sh() {
    let g = glb(
        &[quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)],
        plain_nodes(1),
    );
    let b = aobake::bake_scene(&scene(&g), &settings(64, 64, None)).unwrap();
    assert!(b.receivers.len() > 1000);
    let want = sh::open_hemisphere(Vec3::Z);
    for i in 0..b.receivers.len() {
        assert_eq!(b.bake.ao[i], 1.0);
        for (k, &wk) in want.iter().enumerate() {
            // Stratified 64-ray estimate of a smooth integrand.
            assert!(
                (b.bake.sh[i][k] - wk).abs() < 0.03,
                "c{k}: {} vs {}",
                b.bake.sh[i][k],
                wk
            );
        }
    }
    // Exact values of the contract's constants: c0 = 0.282095, c2 = 0.325735 (2/3 Y1), c6 = 0.078848 (1/4 * 0.315392 * 2).
    assert!((want[0] - 0.282095).abs() < 1e-6);
    assert!((want[2] - 0.488603 * 2.0 / 3.0).abs() < 1e-6);
    assert!((want[6] - 0.315392 * 2.0 / 4.0).abs() < 1e-6);
    // Averaged over receivers the MC noise vanishes: matches to 3 decimals.
    let n = b.receivers.len() as f32;
    for k in 0..9 {
        let mean: f32 = b.bake.sh.iter().map(|c| c[k]).sum::<f32>() / n;
        assert!(
            (mean - want[k]).abs() < 2e-3,
            "mean c{k} {mean} vs {}",
            want[k]
        );
    }
}

#[test]
fn receiver_under_parallel_plane_matches_closed_form() {
    // Receiver: small quad at z = 0 facing +z. Occluder: a large quad at
    // z = h facing down. A ray at cos(theta) = z hits iff h / z <= D, so
    // AO = P(z < h/D) = (h/D)^2 for cosine-weighted directions.
    let (h, d) = (1.0f32, 2.0f64);
    let recv = quad([0.0; 3], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], true);
    // Rays that hit within D land within D sin(theta) <= 1.74 of the axis.
    let occ = quad([0.0, 0.0, h], [0.0, 2.2, 0.0], [2.2, 0.0, 0.0], true);
    let g = glb(&[recv, occ], plain_nodes(2));
    let b = aobake::bake_scene(&scene(&g), &settings(256, 256, Some(d))).unwrap();
    let c = h as f64 / d;
    let ao_want = c * c;
    let pts = picked(&b, |p| {
        p.z.abs() < 1e-3 && p.x.abs() < 0.15 && p.y.abs() < 0.15
    });
    assert!(pts.len() > 20, "{} receivers", pts.len());
    let mean_ao = pts.iter().map(|p| p.1 as f64).sum::<f64>() / pts.len() as f64;
    assert!(
        (mean_ao - ao_want).abs() < 0.01,
        "AO {mean_ao} vs {ao_want}"
    );
    // SH, by symmetry only c0, c2, c6 are non-zero.
    let vis = |w: Vec3| (w.z as f64) < c;
    for k in 0..9 {
        let want = reference(vis, |w| sh::basis(w)[k] as f64);
        let mean = pts.iter().map(|p| p.2[k] as f64).sum::<f64>() / pts.len() as f64;
        assert!((mean - want).abs() < 0.01, "c{k}: {mean} vs {want}");
    }
    // Closed forms of c2 and c6 agree with the quadrature used above.
    let c2 = 0.488603 * 2.0 * c.powi(3) / 3.0;
    assert!((reference(vis, |w| sh::basis(w)[2] as f64) - c2).abs() < 1e-3);
}

#[test]
fn max_distance_clips_occluders_beyond_it() {
    let recv = quad([0.0; 3], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], true);
    let occ = quad([0.0, 0.0, 1.0], [0.0, 20.0, 0.0], [20.0, 0.0, 0.0], true);
    let g = glb(&[recv, occ], plain_nodes(2));
    let b = aobake::bake_scene(&scene(&g), &settings(64, 64, Some(0.99))).unwrap();
    let pts = picked(&b, |p| p.z.abs() < 1e-3);
    assert!(!pts.is_empty());
    assert!(
        pts.iter().all(|p| p.1 == 1.0),
        "a plane at 1.0 occluded with D = 0.99"
    );
}

#[test]
fn receiver_beside_a_wall_matches_closed_form_and_sh_sign() {
    // Floor receiver at the origin facing +z, infinite-ish wall x = a facing -x.
    // A cosine-weighted direction is its disk point lifted; it hits iff
    // w_x >= a / D, so AO = 1 - (acos(s) - s sqrt(1 - s^2)) / pi, s = a / D.
    let (a, d) = (0.5f32, 1.0f64);
    let recv = quad([0.0; 3], [0.05, 0.0, 0.0], [0.0, 0.05, 0.0], true);
    // Hits within D = 1 lie within 1 of the receiver: a 2.4-wide wall suffices.
    let wall = quad([a, 0.0, 1.2], [0.0, 0.0, 1.2], [0.0, 1.2, 0.0], true);
    let g = glb(&[recv, wall], plain_nodes(2));
    let b = aobake::bake_scene(&scene(&g), &settings(512, 256, Some(d))).unwrap();
    let pts = picked(&b, |p| {
        p.z.abs() < 1e-4 && p.x.abs() < 0.02 && p.y.abs() < 0.02
    });
    assert!(pts.len() > 10, "{}", pts.len());
    let s = a as f64 / d;
    let ao_want = 1.0 - ((s.acos() - s * (1.0 - s * s).sqrt()) / std::f64::consts::PI);
    let mean = |k: usize| pts.iter().map(|p| p.2[k] as f64).sum::<f64>() / pts.len() as f64;
    let mean_ao = pts.iter().map(|p| p.1 as f64).sum::<f64>() / pts.len() as f64;
    assert!(
        (mean_ao - ao_want).abs() < 0.01,
        "AO {mean_ao} vs {ao_want}"
    );
    let vis = |w: Vec3| (w.x as f64) < s;
    for k in 0..9 {
        let want = reference(vis, |w| sh::basis(w)[k] as f64);
        assert!((mean(k) - want).abs() < 0.01, "c{k}: {} vs {want}", mean(k));
    }
    // Convention: the occluder is toward +x, so the x coefficient (l=1, m=1,
    // index 3) drops below zero, y (index 1) stays at zero, and the xz
    // coefficient (index 7) goes negative.
    assert!(mean(3) < -0.02, "c3 {}", mean(3));
    assert!(mean(1).abs() < 0.01, "c1 {}", mean(1));
    assert!(mean(7) < -0.02, "c7 {}", mean(7));
}

/// The parallel-plane scene with every node under one extra transform.
fn transformed_scene(scale: f64, offset: [f64; 3]) -> Vec<u8> {
    let recv = quad([0.0; 3], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], true);
    let occ = quad([0.0, 0.0, 0.3], [0.0, 0.5, 0.0], [0.5, 0.0, 0.0], true);
    glb(
        &[recv, occ],
        vec![
            json!({"mesh": 0, "scale": [scale, scale, scale], "translation": offset}),
            json!({"mesh": 1, "scale": [scale, scale, scale], "translation": offset}),
        ],
    )
}

#[test]
fn scale_and_offset_invariance() {
    let base = aobake::bake_scene(
        &scene(&transformed_scene(1.0, [0.0; 3])),
        &settings(64, 64, Some(1.0)),
    )
    .unwrap();
    for (scale, offset) in [(1e-4, [0.0; 3]), (1e4, [0.0; 3]), (1.0, [1e5, -1e5, 1e5])] {
        let b = aobake::bake_scene(
            &scene(&transformed_scene(scale, offset)),
            &settings(64, 64, Some(scale)),
        )
        .unwrap();
        assert_eq!(b.lightmap.ao.len(), base.lightmap.ao.len());
        let max_diff = b
            .lightmap
            .ao
            .iter()
            .zip(&base.lightmap.ao)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max);
        let mean_base = base.lightmap.ao.iter().sum::<f32>() / base.lightmap.ao.len() as f32;
        let mean = b.lightmap.ao.iter().sum::<f32>() / b.lightmap.ao.len() as f32;
        assert!(
            (mean - mean_base).abs() < 1e-3,
            "scale {scale}: mean {mean} vs {mean_base}"
        );
        assert!(
            max_diff < 0.05,
            "scale {scale} offset {offset:?}: max texel diff {max_diff}"
        );
        assert!(
            mean_base < 0.9,
            "the occluder must matter: mean AO {mean_base}"
        );
    }
}

#[test]
fn instanced_mesh_gets_a_region_per_node_and_the_same_ao() {
    // One receiver mesh placed twice under one occluder, once rotated 90
    // degrees about z and moved; both placements see the same AO.
    let recv = quad([0.0; 3], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], true);
    let occ = quad([0.0, 0.0, 1.0], [0.0, 3.5, 0.0], [3.5, 0.0, 0.0], true);
    let g = glb(
        &[recv, occ],
        vec![
            json!({"mesh": 0, "translation": [-1.0, 0.0, 0.0]}),
            json!({"mesh": 0, "translation": [1.0, 0.0, 0.0], "rotation": [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2]}),
            json!({"mesh": 1}),
        ],
    );
    let b = aobake::bake_scene(&scene(&g), &settings(256, 128, Some(2.0))).unwrap();
    let left = picked(&b, |p| p.z.abs() < 1e-3 && p.x < 0.0);
    let right = picked(&b, |p| p.z.abs() < 1e-3 && p.x > 0.0);
    assert!(left.len() > 20 && right.len() > 20);
    let m =
        |v: &[(Vec3, f32, [f32; 9])]| v.iter().map(|p| p.1 as f64).sum::<f64>() / v.len() as f64;
    assert!(
        (m(&left) - 0.25).abs() < 0.01 && (m(&right) - 0.25).abs() < 0.01,
        "{} {}",
        m(&left),
        m(&right)
    );
    let (json, _) = split(&b.glb);
    // Node 1 now points at a copy of mesh 0; both carry the lightmap.
    assert_eq!(json["nodes"][0]["mesh"], 0);
    let copy = json["nodes"][1]["mesh"].as_u64().unwrap() as usize;
    assert_ne!(copy, 0);
    for m in [0, copy] {
        let p = &json["meshes"][m]["primitives"][0];
        assert_eq!(p["extensions"]["AOBAKE_lightmap"]["texCoord"], 0);
        assert!(p["attributes"]["TEXCOORD_0"].is_u64());
    }
    assert_ne!(
        json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"],
        json["meshes"][copy]["primitives"][0]["attributes"]["TEXCOORD_0"]
    );
}

#[test]
fn output_is_identical_for_any_thread_count() {
    let g = transformed_scene(1.0, [0.0; 3]);
    let run = |threads| glb_on_threads(&g, &settings(64, 32, Some(1.0)), threads);
    assert!(run(1) == run(2), "1-thread and 2-thread bakes differ");
}
