//! The border fit's tests: the points' targets, their blocks' stratified
//! sets and the points inside geometry.

use super::points::tests::square;
use super::*;
use glam::{Vec2, Vec3, Vec3A};

/// A w x w texel square at UV `at`, lying at world `at + offset` in
/// the z = 0 plane.
fn square_at(at: Vec2, w: f32, offset: Vec3) -> Vec<SurfaceTri> {
    square(w)
        .into_iter()
        .map(|mut t| {
            for k in 0..3 {
                t.uv[k] += at - Vec2::splat(2.0);
                t.pos[k] = Vec3::new(t.uv[k].x, t.uv[k].y, 0.0) + offset;
            }
            t
        })
        .collect()
}

#[test]
fn a_points_target_does_not_depend_on_the_points_before_it() {
    // Square A under a slanted roof (its points' targets are noisy
    // fractions), and square B far away in the world, on another part
    // of the page and before A in the triangle list: with B or without,
    // A's points are the same and must trace the same rays, as they
    // lie on the page, not as they are counted.
    let a = square_at(Vec2::new(1.0, 1.0), 4.0, Vec3::ZERO);
    let b = square_at(Vec2::new(6.0, 6.0), 3.0, Vec3::new(100.0, 0.0, 0.0));
    let roof = [
        Vec3A::new(-5.0, -5.0, 0.5),
        Vec3A::new(10.0, -5.0, 0.5),
        Vec3A::new(-5.0, 10.0, 2.0),
    ];
    let tracer = Tracer::with_sides(&[roof], &[false]);
    let all = vec![true; 100];
    let fit = |tris: &[SurfaceTri]| {
        let (anchors, _) = anchors(
            tris, 10, 10, &all, &all, None, &tracer, 3.0, 5, FIT_RAYS, false,
        );
        anchors
    };
    let alone = fit(&a);
    let both = fit(&[b, a.clone()].concat());
    assert!(alone.len() > 20, "{}", alone.len());
    // Not all open or closed: the rays decide the targets.
    assert!(
        alone
            .iter()
            .any(|x| x.target[0] > 0.05 && x.target[0] < 0.95)
    );
    for x in &alone {
        let y = both.iter().find(|y| y.uv == x.uv).expect("the same point");
        assert_eq!(x.target, y.target, "{:?}", x.uv);
    }
}

#[test]
fn points_inside_geometry_trace_no_rays() {
    // A 4 x 4 texel square (world x in [1, 5]) whose half x < 3 lies
    // inside a closed single-sided box: the points there leave the
    // fit, and only the points outside trace their rays.
    let sq = square_at(Vec2::new(1.0, 1.0), 4.0, Vec3::ZERO);
    let (lo, hi) = (Vec3A::new(-10.0, -10.0, -1.0), Vec3A::new(3.0, 10.0, 1.0));
    let corner = |i: usize| {
        Vec3A::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let faces = [
        [0, 2, 6, 4],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 5, 7, 6],
    ];
    let centre = (lo + hi) * 0.5;
    let mut box_tris = Vec::new();
    for f in faces {
        for [a, b, c] in [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] {
            let (a, mut b, mut c) = (corner(a), corner(b), corner(c));
            // Wound to face out of the box.
            if (b - a).cross(c - a).dot(a - centre) < 0.0 {
                std::mem::swap(&mut b, &mut c);
            }
            box_tris.push([a, b, c]);
        }
    }
    let tracer = Tracer::with_sides(&box_tris, &vec![true; box_tris.len()]);
    let all = vec![true; 100];
    let every = points(&sq, 10, 10, &all, &all, 5).len();
    let (anchors, rays) = anchors(
        &sq, 10, 10, &all, &all, None, &tracer, 3.0, 5, FIT_RAYS, false,
    );
    assert!(every > 40, "{every}");
    // About half the points lie inside (x < 3 of x in [1, 5]).
    assert!(
        anchors.len() > every / 3 && anchors.len() < 2 * every / 3,
        "{} of {every}",
        anchors.len()
    );
    assert!(
        anchors.iter().all(|a| a.uv[0] * 10.0 > 2.9),
        "a point inside kept"
    );
    assert_eq!(rays, anchors.len() as u64 * FIT_RAYS as u64);
}

#[test]
fn a_blocks_points_together_trace_one_stratified_set() {
    // Four points of one block at one surface point under a slanted
    // roof: their runs of the block's sequence together are its first
    // 4 x FIT_RAYS points, so their mean AO is a 4 x FIT_RAYS-ray
    // Monte Carlo estimate of that point (mc::bake, keyed alike).
    let tri = square(4.0)[0].clone();
    let roof = [
        Vec3A::new(-5.0, -5.0, 0.5),
        Vec3A::new(10.0, -5.0, 0.5),
        Vec3A::new(-5.0, 10.0, 2.0),
    ];
    let tracer = Tracer::with_sides(&[roof], &[false]);
    let params = BakeParams {
        max_distance: 3.0,
        seed: 5,
    };
    let at = |n: usize| {
        let mut r = Receivers {
            width: 10,
            height: 10,
            ..Default::default()
        };
        for _ in 0..n {
            r.push_surface_point(77, &tri, [0.9, 0.05, 0.05], true);
        }
        r
    };
    let (runs, _) = targets(&at(4), &[0, 1, 2, 3], &tracer, &params, FIT_RAYS, false);
    let mean = runs.iter().map(|t| t.0).sum::<f32>() / 4.0;
    let whole = mc::bake(&at(1), &tracer, 4 * FIT_RAYS, &params, &|_| {});
    let first = mc::bake(&at(1), &tracer, FIT_RAYS, &params, &|_| {});
    assert!((mean - whole.ao[0]).abs() < 1e-6, "{mean} {}", whole.ao[0]);
    // The roof occludes part of the hemisphere, and one run alone is
    // not the whole set's estimate (the runs are not the same rays).
    assert!(mean > 0.1 && mean < 0.9, "{mean}");
    assert!((first.ao[0] - whole.ao[0]).abs() > 1e-3, "{}", first.ao[0]);
    assert_eq!(runs[0].0, first.ao[0]);
}
