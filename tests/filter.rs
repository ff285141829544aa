//! `--filter bicubic`: texels fitted for the cubic B-spline lookup, the
//! file saying so, and the lookups that read them right, against a
//! Monte Carlo reference at surface points (independent of the fit).

mod common;

use aobake::job::{Job, RunOptions};
use aobake::lightmap::Filter;
use aobake::lightmap::engine_view;
use aobake::stage::StageTimer;
use common::{floor_and_wall, settings, split};

/// The engine-view AO RMSE (all points) of one bake of the floor and wall
/// (the wall's foot a contact line across the floor's chart), read through
/// `bilinear` and through `bicubic`, against one 2048-ray reference.
fn read_both_ways(filter: Filter) -> (f64, f64) {
    let sc = floor_and_wall();
    // At 16 texels across, the contact darkening at the wall's foot spans
    // about a texel: where the lookup decides what is seen.
    let mut s = settings(16, 256, Some(1.0));
    s.method = aobake::Method::Adaptive;
    s.filter = filter;
    let mut job = Job::new(&sc, &s, &RunOptions::QUIET, StageTimer::new());
    let level = job.level().unwrap();
    let mut kept = None;
    job.pages(&level, &[0], &mut |page, _, out| {
        kept = Some((page.receivers, out.encoded));
    })
    .unwrap();
    let (receivers, encoded) = kept.unwrap();
    let lm = aobake::encode::decode(&encoded).unwrap();
    let page = level.page(0, &sc, &mut StageTimer::new()).unwrap();
    let tris = aobake::atlas::rasterize::surface_triangles(&level.geometry.receivers, &page.atlas);
    let points = engine_view::surface_points(&tris, lm.width, lm.height, 8000, 3);
    let reference =
        engine_view::reference(&points, &level.tracer, level.max_distance, 2048, 3, false);
    let centers = receivers.centers_inside();
    let error = |f: Filter| {
        engine_view::measure(&points, &lm, f, &reference, &centers, &[], 0)
            .all
            .ao_rmse
    };
    (error(Filter::Bilinear), error(Filter::Bicubic))
}

#[test]
fn bicubic_texels_read_right_bicubically_and_bilinear_ones_bilinearly() {
    let (bl_bl, bl_bc) = read_both_ways(Filter::Bilinear);
    let (bc_bl, bc_bc) = read_both_ways(Filter::Bicubic);
    eprintln!(
        "AO RMSE (texels fitted for / read as): bilinear/bilinear {bl_bl:.4}, \
         bilinear/bicubic {bl_bc:.4}, bicubic/bicubic {bc_bc:.4}, bicubic/bilinear {bc_bl:.4}"
    );
    // Each bake reads best through the lookup it was fitted for: a
    // B-spline blurs texels that are samples, and a bilinear lookup of
    // B-spline coefficients shows them sharpened.
    assert!(bc_bc < 0.9 * bc_bl, "{bc_bc} against {bc_bl}");
    assert!(bc_bc < 0.9 * bl_bc, "{bc_bc} against {bl_bc}");
    // And the bicubic bake, read bicubically, is as good as the bilinear
    // bake read bilinearly.
    assert!(bc_bc < 1.1 * bl_bl, "{bc_bc} against {bl_bl}");
}

#[test]
fn the_file_records_a_bicubic_filter_and_a_bilinear_bake_writes_none() {
    let sc = floor_and_wall();
    let root = |filter: Filter| {
        let mut s = settings(32, 16, Some(1.0));
        s.filter = filter;
        let glb = aobake::bake_scene(&sc, &s).unwrap().glb;
        let (json, _) = split(&glb);
        json["extensions"]["AOBAKE_lightmap"].clone()
    };
    assert_eq!(root(Filter::Bicubic)["filter"], "bicubic");
    assert!(root(Filter::Bilinear).get("filter").is_none());
}
