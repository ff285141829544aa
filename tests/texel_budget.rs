//! `--texel-budget signal`: each mesh's texel density from how close its
//! occluders are (`bake::signal`), against the closed form of the
//! pre-pass's rule on a floor under a roof and an open floor.

mod common;

use aobake::bake::signal::TexelBudget;
use aobake::job::{Job, RunOptions};
use aobake::stage::StageTimer;
use common::{glb, plain_nodes, quad, scene, settings};

/// Texels per world unit of receiver mesh `k` of a bake's atlas (square
/// root of UV area, in texels, over world area).
fn density(level: &aobake::job::Level, k: usize) -> f64 {
    let m = &level.atlas.meshes[k];
    let page = level.atlas.pages[0];
    let uv_area: f64 = (m.triangles.chunks_exact(3))
        .map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| m.uv[i as usize]);
            let (w, h) = (page.width as f64, page.height as f64);
            0.5 * (((b[0] - a[0]) as f64 * w) * ((c[1] - a[1]) as f64 * h)
                - ((c[0] - a[0]) as f64 * w) * ((b[1] - a[1]) as f64 * h))
                .abs()
        })
        .sum();
    (uv_area / level.geometry.receivers[k].surface_area()).sqrt()
}

#[test]
fn a_floor_under_a_roof_gets_the_square_root_of_the_distance_ratio_in_density() {
    // A unit floor with a roof 0.25 above it, and an open unit floor;
    // occluders reach 1.0. The roof's and the open floor's points see
    // nothing (z = 1.0); the covered floor's nearest hit is about 0.25
    // straight up, so its density scale is (1.0 / 0.25)^(1/2) = 2 times
    // theirs (1/z^2 averaged, to the fourth root).
    let half = [0.5, 0.0, 0.0];
    let up = [0.0, 0.5, 0.0];
    let covered = quad([0.0, 0.0, 0.0], half, up, true);
    let roof = quad([0.0, 0.0, 0.25], half, up, true);
    let open = quad([3.0, 0.0, 0.0], half, up, true);
    let sc = scene(&glb(&[covered, roof, open], plain_nodes(3)));
    let mut s = settings(128, 16, Some(1.0));
    s.texel_budget = TexelBudget::Signal;
    let mut job = Job::new(&sc, &s, &RunOptions::QUIET, StageTimer::new());
    let level = job.level().unwrap();
    let d: Vec<f64> = (0..3).map(|k| density(&level, k)).collect();
    eprintln!(
        "texels per world unit: covered {:.1}, roof {:.1}, open {:.1}",
        d[0], d[1], d[2]
    );
    let ratio = d[0] / d[2];
    assert!((1.8..=2.05).contains(&ratio), "covered / open {ratio}");
    assert!(
        (d[1] / d[2] - 1.0).abs() < 0.05,
        "roof / open {}",
        d[1] / d[2]
    );
    // Uniform: the same density everywhere.
    s.texel_budget = TexelBudget::Uniform;
    let mut job = Job::new(&sc, &s, &RunOptions::QUIET, StageTimer::new());
    let level = job.level().unwrap();
    let u: Vec<f64> = (0..3).map(|k| density(&level, k)).collect();
    assert!((u[0] / u[2] - 1.0).abs() < 0.05, "{u:?}");
}
