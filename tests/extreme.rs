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
fn floor_ao(b: &aobake::pipeline::Baked, pick: impl Fn(DVec3) -> bool) -> Vec<f32> {
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
    let beside = floor_ao(&b, |p| {
        let d = p.x.abs().max(p.y.abs());
        d > 0.22 && d < 0.26
    });
    assert!(
        mean(&beside) > 0.35 && mean(&beside) < 0.8,
        "{}",
        mean(&beside)
    );
    // Far from the box the floor is open.
    let far = floor_ao(&b, |p| p.x.abs().max(p.y.abs()) > 0.85);
    assert!(mean(&far) > 0.95, "{}", mean(&far));
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
