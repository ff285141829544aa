//! Extreme but valid scenes bake correctly: geometry resting on or running
//! through other geometry, one triangle, slivers, zero-area UVs, tiny and
//! large atlases.

mod common;
use common::*;
use glam::DVec3;

/// A closed axis-aligned box, faces outward (counter-clockwise).
fn closed_box(lo: [f32; 3], hi: [f32; 3]) -> MeshSpec {
    let c =
        |x: usize, y: usize, z: usize| [[lo[0], hi[0]][x], [lo[1], hi[1]][y], [lo[2], hi[2]][z]];
    let quads = [
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)],
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)],
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
    ];
    let mut m = MeshSpec {
        positions: vec![],
        normals: None,
        indices: vec![],
    };
    for q in quads {
        let b = m.positions.len() as u32;
        m.positions.extend(q);
        m.indices.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
    }
    m
}

fn floor() -> MeshSpec {
    quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)
}

/// AO of the output lightmap at each floor receiver (up-facing, at z = 0)
/// whose world position satisfies `pick`.
fn floor_ao(b: &aobake::job::Baked, pick: impl Fn(DVec3) -> bool) -> Vec<f32> {
    let space = b.geometry.space;
    let r = &b.receivers;
    (0..r.len())
        .filter(|&i| r.geo_normal[i].z > 0.99)
        .map(|i| (i, r.position[i].as_dvec3() * space.diagonal + space.center))
        .filter(|&(_, p)| p.z.abs() < 1e-4 && pick(p))
        .map(|(i, _)| i)
        .map(|i| b.lightmap.ao[r.texel[i] as usize])
        .collect()
}

/// Floor points in a ring 0.02-0.06 outside the 0.4 x 0.4 box footprint.
fn beside_the_box(p: DVec3) -> bool {
    let d = p.x.abs().max(p.y.abs());
    d > 0.22 && d < 0.26
}

fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len().max(1) as f32
}

#[test]
fn floor_under_a_box_resting_on_it_is_not_black() {
    let g = glb(
        &[floor(), closed_box([-0.2, -0.2, 0.0], [0.2, 0.2, 0.4])],
        plain_nodes(2),
    );
    let b = aobake::bake_scene(&scene(&g), &settings(128, 64, Some(0.5))).unwrap();
    assert!(b.report.texels_inside > 0);
    let under = floor_ao(&b, |p| p.x.abs() < 0.15 && p.y.abs() < 0.15);
    assert!(!under.is_empty());
    // Filled from the contact texels around the box (AO about 0.5 there), not
    // baked black from inside the box.
    assert!(mean(&under) > 0.3, "under the box: {}", mean(&under));
    assert!(under.iter().all(|&a| a > 0.2));
    // Just outside the box: the contact shadow, not black.
    let beside = floor_ao(&b, beside_the_box);
    assert!(
        mean(&beside) > 0.35 && mean(&beside) < 0.8,
        "{}",
        mean(&beside)
    );
    // Far from the box the floor is open.
    let far = floor_ao(&b, |p| p.x.abs().max(p.y.abs()) > 0.85);
    assert!(mean(&far) > 0.95, "{}", mean(&far));
    // --no-inside-fill: baked as they are, black under the box.
    let s = aobake::BakeSettings {
        fill_inside: false,
        ..settings(128, 64, Some(0.5))
    };
    let b = aobake::bake_scene(&scene(&g), &s).unwrap();
    assert_eq!(b.report.texels_inside, 0);
    let under = floor_ao(&b, |p| p.x.abs() < 0.15 && p.y.abs() < 0.15);
    assert!(mean(&under) < 0.1, "{}", mean(&under));
}

#[test]
fn floor_running_through_a_wall_is_filled_inside_the_wall() {
    // A thick wall crossing the floor plane.
    let g = glb(
        &[floor(), closed_box([-0.05, -1.0, -0.3], [0.05, 1.0, 0.3])],
        plain_nodes(2),
    );
    let b = aobake::bake_scene(&scene(&g), &settings(128, 64, Some(0.5))).unwrap();
    let inside = floor_ao(&b, |p| p.x.abs() < 0.03);
    assert!(!inside.is_empty());
    let beside = floor_ao(&b, |p| p.x.abs() > 0.06 && p.x.abs() < 0.09);
    // Inside texels show a neighbour's contact value, not black.
    assert!(mean(&inside) > 0.3, "{}", mean(&inside));
    assert!((mean(&inside) - mean(&beside)).abs() < 0.15);
}

#[test]
fn the_adaptive_pre_pass_finds_the_validity_stages_inside_texels() {
    // The validity stage casts the first rays of the bake's own sequence,
    // closest-hit, as the adaptive pre-pass does: the pre-pass makes the
    // same test on the same rays (continuing it past its own rays when it
    // has fewer), so the adaptive method runs no validity stage.
    use aobake::job::Level;
    use aobake::stage::StageTimer;
    let run = aobake::RunOptions::QUIET;
    let scenes = [
        glb(
            &[floor(), closed_box([-0.2, -0.2, 0.0], [0.2, 0.2, 0.4])],
            plain_nodes(2),
        ),
        glb(
            &[floor(), closed_box([-0.05, -1.0, -0.3], [0.05, 1.0, 0.3])],
            plain_nodes(2),
        ),
    ];
    for g in &scenes {
        let mc = aobake::BakeSettings {
            seed: 7,
            ..settings(128, 64, Some(0.5))
        };
        let sc = scene(g);
        let level = Level::new(&sc, &mc, &run, &mut StageTimer::new()).unwrap();
        let p = level.page(0, &sc, &mut StageTimer::new()).unwrap();
        let expected = p.inside.clone().unwrap();
        let count = expected.iter().filter(|&&x| x).count();
        assert!(count > 20 && count < expected.len() / 2, "{count}");
        for pre_rays in [4, 16, 32] {
            let mut s = aobake::BakeSettings {
                method: aobake::Method::Adaptive,
                ..mc.clone()
            };
            s.adaptive.pre_rays = pre_rays;
            let passes = p
                .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
                .unwrap();
            assert!(
                passes.adaptive_stats.unwrap().inside == expected,
                "{pre_rays} rays"
            );
        }
        // Prepared for the adaptive method: no validity stage, the same
        // texels filled.
        let s = aobake::BakeSettings {
            method: aobake::Method::Adaptive,
            ..mc.clone()
        };
        let mut timer = StageTimer::new();
        let level = Level::new(&sc, &s, &run, &mut timer).unwrap();
        let pa = level.page(0, &sc, &mut timer).unwrap();
        assert!(pa.inside.is_none());
        assert!(timer.stages().iter().all(|st| st.stage != "validity"));
        let b = aobake::bake_scene(&scene(g), &s).unwrap();
        assert_eq!(b.report.texels_inside, count);
    }
}

#[test]
fn sheet_facing_the_floor_occludes_and_nothing_is_inside() {
    // A single-sided quad facing down floats above the floor: the floor
    // under it sees front faces, so it is valid, and occluded.
    let sheet = quad([0.0, 0.0, 0.2], [0.0, 0.3, 0.0], [0.3, 0.0, 0.0], true);
    let g = glb(&[floor(), sheet], plain_nodes(2));
    let b = aobake::bake_scene(&scene(&g), &settings(128, 64, Some(0.5))).unwrap();
    assert_eq!(b.report.texels_inside, 0);
    let under = floor_ao(&b, |p| p.x.abs() < 0.05 && p.y.abs() < 0.05);
    // Centre of a 0.6 x 0.6 sheet at height 0.2, max distance 0.5: mostly covered.
    assert!(mean(&under) < 0.5, "{}", mean(&under));
}

/// A (n x n)-quad grid in the z = 0 plane over [-1, 1]^2: 2 n^2 triangles.
fn grid(n: usize) -> MeshSpec {
    let mut m = MeshSpec {
        positions: Vec::with_capacity((n + 1) * (n + 1)),
        normals: Some(Vec::with_capacity((n + 1) * (n + 1))),
        indices: Vec::with_capacity(6 * n * n),
    };
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (
                i as f32 / n as f32 * 2.0 - 1.0,
                j as f32 / n as f32 * 2.0 - 1.0,
            );
            m.positions.push([x, y, 0.0]);
            m.normals.as_mut().unwrap().push([0.0, 0.0, 1.0]);
        }
    }
    let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    for j in 0..n {
        for i in 0..n {
            m.indices.extend([
                at(i, j),
                at(i + 1, j),
                at(i + 1, j + 1),
                at(i, j),
                at(i + 1, j + 1),
                at(i, j + 1),
            ]);
        }
    }
    m
}

fn assert_sane(b: &aobake::job::Baked) {
    assert!(b.bake.ao.iter().all(|a| (0.0..=1.0).contains(a)));
    assert!(b.bake.sh.iter().flatten().all(|c| c.is_finite()));
    assert!(b.lightmap.ao.iter().all(|a| a.is_finite()));
}

#[test]
fn one_triangle_bakes_open() {
    let tri = MeshSpec {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        normals: None,
        indices: vec![0, 1, 2],
    };
    let b =
        aobake::bake_scene(&scene(&glb(&[tri], plain_nodes(1))), &settings(32, 8, None)).unwrap();
    assert!(b.receivers.len() > 50);
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
    assert_sane(&b);
}

#[test]
fn coincident_duplicate_faces_do_not_occlude_each_other() {
    // The same quad twice (a common export artefact): the origin offset
    // lifts rays off both, so neither turns the other black.
    let a = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let b2 = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let b = aobake::bake_scene(
        &scene(&glb(&[a, b2], plain_nodes(2))),
        &settings(64, 16, None),
    )
    .unwrap();
    assert_eq!(b.report.texels_inside, 0);
    assert!(
        b.bake.ao.iter().all(|&a| a == 1.0),
        "min AO {}",
        b.bake.ao.iter().fold(1.0f32, |m, &a| m.min(a))
    );
}

#[test]
fn sliver_and_degenerate_triangles_bake_without_nan() {
    // A fan of 200 slivers (1e-4 wide at the tip end) plus zero-area
    // triangles (repeated index, collinear), under a parallel plane.
    let mut m = MeshSpec {
        positions: vec![[0.0, 0.0, 0.0]],
        normals: None,
        indices: vec![],
    };
    for k in 0..=200 {
        let t = k as f32 / 200.0 * 0.02;
        m.positions.push([1.0, t, 0.0]);
    }
    for k in 1..=200u32 {
        m.indices.extend([0, k, k + 1]);
    }
    let base = m.positions.len() as u32;
    m.positions
        .extend([[0.0, -1.0, 0.0], [0.5, -1.0, 0.0], [1.0, -1.0, 0.0]]);
    m.indices
        .extend([base, base, base + 1, base, base + 1, base + 2]);
    let roof = quad([0.5, 0.0, 0.3], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], true);
    let b = aobake::bake_scene(
        &scene(&glb(&[m, roof], plain_nodes(2))),
        &settings(128, 16, Some(1.0)),
    )
    .unwrap();
    assert_sane(&b);
    // The slivers under the roof are occluded.
    assert!(b.bake.ao.iter().any(|&a| a < 0.6));
    // And the filtered method on the same scene.
    let s = aobake::BakeSettings {
        method: aobake::Method::Sheared,
        ..settings(128, 16, Some(1.0))
    };
    assert_sane(&aobake::bake_scene(&scene(&glb(&[grid(2)], plain_nodes(1))), &s).unwrap());
}

#[test]
fn tiny_and_large_atlases() {
    let g = glb(
        &[quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)],
        plain_nodes(1),
    );
    for (res, rays) in [(16, 8), (2048, 1)] {
        let b = aobake::bake_scene(&scene(&g), &settings(res, rays, None)).unwrap();
        assert!(b.report.atlas_width <= res && b.report.atlas_height <= res);
        assert!(b.report.atlas_width.max(b.report.atlas_height) > res / 2);
        assert!(b.bake.ao.iter().all(|&a| a == 1.0));
        assert_sane(&b);
    }
}

#[test]
fn one_million_triangles() {
    // 708^2 quads: 1,002,528 triangles.
    let g = glb(&[grid(708)], plain_nodes(1));
    let sc = scene(&g);
    assert!(sc.geometries[0].triangles.len() / 3 > 1_000_000);
    let b = aobake::bake_scene(&sc, &settings(256, 1, None)).unwrap();
    assert!(b.receivers.len() > 10_000);
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
}

#[test]
fn mirrored_box_on_a_floor_is_still_seen_from_outside() {
    // The box placed by a node with a negative scale: its triangles wind
    // clockwise in world space, so front faces must be flipped back, or the
    // whole floor around it would see "back faces" and be filled.
    let nodes = vec![
        serde_json::json!({"mesh": 0}),
        serde_json::json!({"mesh": 1, "scale": [-1.0, 1.0, 1.0]}),
    ];
    let g = glb(
        &[floor(), closed_box([-0.2, -0.2, 0.0], [0.2, 0.2, 0.4])],
        nodes,
    );
    let b = aobake::bake_scene(&scene(&g), &settings(128, 64, Some(0.5))).unwrap();
    // Only the floor under the box is inside (0.4^2 of the 2^2 floor = 4%,
    // plus the box's own faces, which see nothing behind them).
    let inside = b.report.texels_inside as f64 / b.report.texels as f64;
    assert!(inside > 0.01 && inside < 0.08, "{inside}");
    let beside = floor_ao(&b, beside_the_box);
    assert!(
        mean(&beside) > 0.35 && mean(&beside) < 0.8,
        "{}",
        mean(&beside)
    );
}

#[test]
fn zero_area_uv_triangles_in_an_existing_set_cover_nothing() {
    // TEXCOORD_1: the first triangle of the floor maps to one point, the
    // second to half the page.
    let f = floor();
    let (mut j, mut bin) = split(&glb(&[f], plain_nodes(1)));
    let uvs = [[0.5, 0.5], [0.5, 0.5], [1.0, 1.0], [0.0, 1.0]];
    add_texcoord1(&mut j, &mut bin, &uvs, &[0]);
    let g = aobake::gltf::container::glb_bytes(&j, &bin);
    let s = aobake::BakeSettings {
        uv: aobake::UvSource::Existing(1),
        ..settings(64, 8, None)
    };
    let b = aobake::bake_scene(&scene(&g), &s).unwrap();
    // Only the second triangle (0.5, 0.5)-(1, 1)-(0, 1) covers texels:
    // a quarter of the page, and every texel of it is open.
    let covered = b.receivers.len() as f64 / (64.0 * 64.0);
    assert!((covered - 0.25).abs() < 0.05, "{covered}");
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
    assert_sane(&b);
}
