//! The lightmap stage: a page's baked receivers into the texel values the
//! engine's bilinear lookups will read.
//!
//! In: a baked page ([`PageBake`]: its receivers, their [`Bake`], which of
//! them lie inside geometry, the page's charts and what its seams need).
//! Out: the page's float [`Lightmap`] (every texel's AO, SH and visibility
//! layer), which [`crate::encode`] only quantizes and writes, and the seam
//! figures ([`Built`]).
//!
//! Every post-bake stage lives here, in order:
//!
//! 1. [`dilate`]: the receiver each texel shows (gutters, and texels inside
//!    geometry filled from their nearest valid receiver);
//! 2. `spread`: receiver results over the page through that
//!    map;
//! 3. [`border`]: surface points of the border band's bilinear cells,
//!    traced, for the texels there to be fitted to (`--border fit`), and
//!    [`edge`]: the border texels' own receivers as rows where they were
//!    baked, on the chart's edge;
//! 4. [`seams`]: the two sides of every smooth seam stitched to agree
//!    (within the page, and to a shared target across pages), solved in
//!    one least-squares system with the border fit's points.
//!
//! A new post-bake stage goes into [`build`], between these, reading and
//! writing the [`Lightmap`]. A bake of part of a page carries NaN through
//! them for "not known" ([`build`]); [`known`] tells whether the known
//! texels hold all an edit can change. [`engine_view`] measures the result where an
//! engine reads it (bilinear lookups at surface points).

pub mod border;
pub mod dilate;
pub mod edge;
pub mod engine_view;
pub(crate) mod filter;
pub mod known;
pub mod seams;
pub(crate) mod spread;

pub use spread::spread;

use crate::atlas::rasterize::surface_triangles;
use crate::atlas::{Atlas, PageSize, Receivers};
use crate::bake::Bake;
use crate::bits::mix64;
use crate::error::Result;
use crate::geometry::ReceiverMesh;
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::stage::StageTimer;
use crate::trace::Tracer;
pub use border::BorderMode;
pub use filter::{Filter, bilinear_taps};
use rayon::prelude::*;
use seams::{CrossSeam, FLAT_DEGREES, SMOOTH_DEGREES, SeamMode, SeamReport, SolveRange};
use serde::Serialize;

/// A bicubic page's centre row's weight (`centre_rows`), relative to a
/// seam row's: one row per texel, as heavy per texel as the border fit's
/// [`GRID`]^2 points of [`border::FIT_WEIGHT`]. Every texel's data term
/// (its coefficient kept near its baked value) weighs 1 as on a bilinear
/// page: a tenth of it measured the same in more than twice the solve's
/// time, as did a centre weight of 2 (`docs/measurements/constants.md`,
/// CENTRE_WEIGHT).
///
/// [`GRID`]: border::GRID
pub const CENTRE_WEIGHT: f32 = 1.0;

/// Mixed into the seed of the border fit's points and rays.
const BORDER_SEED: u64 = 0xb0_4de4_f17e;

/// What the border fit did on a page.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct BorderReport {
    /// Points fitted (inside-geometry points left out).
    pub points: usize,
    /// Rays traced for their targets (the visibility layer's and the
    /// inside test's not counted).
    pub rays: u64,
    /// Mean |AO lookup - AO traced| at them before and after the solve.
    pub ao_before: f64,
    pub ao_after: f64,
    /// Edge receivers fitted where they were baked ([`edge`]).
    pub edge_rows: usize,
    /// Texels inside charts that the fit moves: the taps of its step
    /// cells ([`border::step_texels`]) outside the border band.
    pub step_texels: usize,
}

/// Float lightmap images, row-major, row 0 at the top (glTF v = 0).
#[derive(Clone, Debug)]
pub struct Lightmap {
    pub width: u32,
    pub height: u32,
    pub ao: Vec<f32>,
    pub sh: Vec<[f32; SH_COUNT]>,
    /// Whether each texel holds a receiver of its own (not dilated).
    pub covered: Vec<bool>,
    /// The visibility layer v_0..v_15, when baked.
    pub visibility: Option<Vec<[f32; VIS_COUNT]>>,
}

/// What the lightmap stage reads of one baked page.
pub struct PageBake<'a> {
    /// The page's index among the level's pages.
    pub page: u32,
    /// Every page's size (the cross-page seams' sides are measured on them).
    pub pages: &'a [PageSize],
    /// The receiver meshes of the level (bake space).
    pub meshes: &'a [ReceiverMesh],
    /// This page alone, as a one-page atlas.
    pub atlas: &'a Atlas,
    pub receivers: &'a Receivers,
    pub bake: &'a Bake,
    /// Per receiver: inside or behind geometry (its texel shows its nearest
    /// valid receiver instead); empty: none is.
    pub inside: &'a [bool],
    /// The level's seams whose sides lie on two pages.
    pub cross_seams: &'a [CrossSeam],
    /// For the cross-page seams' targets: the occluders, their max distance
    /// (bake units) and the bake's seed.
    pub tracer: &'a Tracer,
    pub max_distance: f32,
    pub seed: u64,
    /// The scene's bounding-box diagonal (bake units to world units).
    pub diagonal: f64,
    /// Per receiver: the adaptive filter's sigma in texels (`--method
    /// adaptive`), the scale below which its signal is smooth.
    pub sigma_texels: Option<&'a [f32]>,
    /// The page's traced border fit from an earlier run, if any.
    pub fit_cache: Option<&'a border::FitCache>,
    /// The solve's range in an earlier bake of the page (`--reuse`), which
    /// the page's own widens ([`seams::stitch_page`]).
    pub solve_range: Option<&'a SolveRange>,
    /// Per receiver, whether `bake` holds its value: `None` when every
    /// receiver's does; else a bake of part of the page (`--reuse`), and
    /// the texels whose value the others decide come out NaN ([`build`]).
    pub known: Option<&'a [bool]>,
    /// In such a bake, per texel whether the edit changed its inputs (its
    /// value before the solve, the rows in its cell), for
    /// [`Built::may_change`].
    pub changed: Option<&'a [bool]>,
    /// The Monte Carlo ray count whose noise the page's values carry
    /// ([`crate::job::settings::BakeSettings::noise_rays`]), which a step
    /// cell must stand out from ([`border::step_span`]); `None` for the
    /// sheared filter.
    pub noise_rays: Option<u32>,
    /// Rays of each border fit point ([`border::FIT_RAYS`] in a bake).
    pub fit_rays: u32,
}

/// What the lightmap stage made of a page.
pub struct Built {
    pub lightmap: Lightmap,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
    /// The border fit's figures (`--border fit`).
    pub border: Option<BorderReport>,
    /// With `seam_maps`: the AO jump at the seams before and after
    /// stitching, one grey byte per texel ([`seams::jump_map`]).
    pub seam_maps: Option<[Vec<u8>; 2]>,
    /// The range the solve kept the page in (with the border fit).
    pub solve_range: Option<SolveRange>,
    /// With [`PageBake::changed`], per texel whether the edit can change
    /// it ([`seams::Stitched::may_change`]), when the page was stitched.
    pub may_change: Option<Vec<bool>>,
    /// And whether a texel that may change reads it
    /// ([`seams::Stitched::reads`]).
    pub reads: Option<Vec<bool>>,
}

/// Runs the post-bake stages on one page: dilate, spread, the border fit
/// and the seams' stitch (one least-squares solve). Fails if a baked value
/// is NaN or infinite (it must never reach a texture).
///
/// A bake of part of a page (`p.known`) gives every texel the value the
/// whole page's bake gives it, or NaN where that value depends on a
/// receiver not known. NaN marks "not known" through every stage: a
/// texel showing a receiver not known is NaN; a bilinear cell with a NaN
/// tap counts as a step, and the texels of such cells are made NaN after
/// the structure is decided (their own structure read only known values);
/// fit points in a cell with a NaN tap are not traced and become NaN rows
/// in their places; an edge row that reads a NaN is a NaN row; a solve
/// component reading a NaN is not solved (NaN); the active set's second
/// solve makes NaN the texels whose membership a NaN decides. So every
/// texel that comes out finite was computed from exactly the inputs, rows
/// and components of the whole page's bake, in the same order.
pub fn build(
    p: &PageBake,
    seam_mode: SeamMode,
    border_mode: BorderMode,
    filter: Filter,
    seam_maps: bool,
    timer: &mut StageTimer,
) -> Result<Built> {
    timer.restart();
    let r = p.receivers;
    let fill = dilate::fill_map(r.width, r.height, &r.texel, p.inside);
    let mut lightmap = spread(r, p.bake, &fill, p.known)?;
    timer.lap("dilate");
    let (w, h) = (lightmap.width, lightmap.height);
    let bicubic = filter == Filter::Bicubic;
    if seam_mode == SeamMode::Off && border_mode == BorderMode::Off && !bicubic {
        return Ok(Built {
            lightmap,
            seams: None,
            border: None,
            seam_maps: None,
            solve_range: None,
            may_change: None,
            reads: None,
        });
    }
    let stitch = seam_mode == SeamMode::Stitch;
    let found = match stitch {
        true => seams::find::smooth_seams(p.meshes, p.atlas, SMOOTH_DEGREES, FLAT_DEGREES),
        false => Vec::new(),
    };
    let map = |lm: &Lightmap| {
        let points = seams::metric::points(&found, w, h, &lm.ao, &lm.sh, filter);
        seams::jump_map(&points, w, h)
    };
    let before = (seam_maps && stitch).then(|| map(&lightmap));
    // Seams to other pages: this side meets the target both compute.
    let anchors = match stitch {
        true => seams::anchor::anchors(
            p.cross_seams,
            p.page,
            p.pages,
            p.tracer,
            p.max_distance,
            p.seed,
            lightmap.visibility.is_some(),
        ),
        false => Vec::new(),
    };
    // The texels fitted to traced surface points: the border band (every
    // texel but the interior ones, for the filter's reach) and, with
    // `--border fit`, the step cells inside charts.
    let at = border::fit_at(
        &lightmap.ao,
        &lightmap.covered,
        w,
        h,
        filter.reach(),
        border_mode,
        p.noise_rays,
    );
    let (fit_at, step_texels) = (at.free, at.step_texels);
    // The texels the solve moves: bilinear, those fitted; bicubic, every
    // texel a surface lookup reads (its coefficients are not samples).
    let free = match filter {
        Filter::Bilinear => fit_at.clone(),
        Filter::Bicubic => seams::reach(&lightmap.covered, w, h, filter.reach()),
    };
    let fitted = (border_mode != BorderMode::Off).then_some(at.fitted);
    // Part of a page: the structure is decided; texels next to one not
    // known are not known (their cells' structure read a NaN).
    let known = p.known.map(|_| known::unknown_cells_to_nan(&mut lightmap));
    let known = known.as_deref();
    // The border fit's points, traced (once per page, free texels and
    // fitted taps).
    let fit: Option<std::sync::Arc<border::FitTargets>> = match (border_mode, fitted) {
        (BorderMode::Off, _) | (_, None) => None,
        (BorderMode::Fit | BorderMode::Band, Some(fitted)) => {
            let layer = lightmap.visibility.is_some();
            let trace = |free: Vec<bool>, fitted: Vec<bool>| {
                let tris = surface_triangles(p.meshes, p.atlas);
                let seed = mix64(p.seed ^ BORDER_SEED ^ mix64(p.page as u64));
                let (tracer, d) = (p.tracer, p.max_distance);
                let inside = r.centers_inside();
                let per_point = p.fit_rays;
                let (anchors, rays) = border::anchors(
                    &tris, w, h, &fitted, &inside, known, tracer, d, seed, per_point, layer,
                );
                std::sync::Arc::new(border::FitTargets {
                    layer,
                    per_point,
                    free,
                    fitted,
                    anchors,
                    rays,
                })
            };
            let fit = match p.fit_cache.filter(|_| known.is_none()) {
                None => trace(fit_at.clone(), fitted),
                Some(cache) => {
                    let mut kept = cache.lock().unwrap_or_else(|e| e.into_inner());
                    match &*kept {
                        Some(t)
                            if t.layer == layer
                                && t.per_point == p.fit_rays
                                && t.free == fit_at
                                && t.fitted == fitted =>
                        {
                            t.clone()
                        }
                        _ => {
                            let t = trace(fit_at.clone(), fitted);
                            *kept = Some(t.clone());
                            t
                        }
                    }
                }
            };
            timer.lap("border points");
            Some(fit)
        }
    };
    let points: &[seams::Anchor] = fit.as_ref().map_or(&[], |f| &f.anchors);
    let fit_rays = fit.as_ref().map_or(0, |f| f.rays);
    let gap = |lm: &Lightmap| seams::anchor_gap(points, w, h, &lm.ao, filter);
    let fit_before = gap(&lightmap);
    let edge = match &fit {
        None => edge::EdgeRows::default(),
        Some(fit) => {
            let free = &fit.free;
            let on_seam = edge::seam_texels(&found, &anchors, w, h, filter);
            let tris = surface_triangles(p.meshes, p.atlas);
            let lm = &lightmap;
            let channels = seams::channels(lm.visibility.is_some());
            // Edge receivers the adaptive filter widened (no contact).
            let smooth = |j: usize| p.sigma_texels.is_some_and(|s| s[j] > 0.0);
            edge::rows(
                r,
                p.inside,
                &smooth,
                &tris,
                free,
                &on_seam,
                points,
                channels,
                |t, out| seams::write_channels(&lm.ao, &lm.sh, lm.visibility.as_deref(), t, out),
            )
        }
    };
    let mut fitted: Vec<seams::Anchor> = points.iter().chain(&edge.rows).cloned().collect();
    if bicubic {
        fitted.extend(centre_rows(&lightmap, &fit_at));
    }
    let seam_scale = match border_mode {
        BorderMode::Fit | BorderMode::Band => border::SEAM_SCALE,
        BorderMode::Off => 1.0,
    };
    let stitched = seams::stitch_page(
        &found,
        &anchors,
        &fitted,
        &|t| edge.data_weight(t),
        seam_scale,
        p.diagonal,
        w,
        h,
        filter,
        &free,
        p.solve_range,
        p.changed,
        &mut lightmap.ao,
        &mut lightmap.sh,
        lightmap.visibility.as_deref_mut(),
    );
    let (report, solve_range) = (stitched.report, stitched.range);
    let (may_change, reads) = (stitched.may_change, stitched.reads);
    let border = (!points.is_empty() || !edge.rows.is_empty()).then(|| BorderReport {
        points: points.len(),
        rays: fit_rays,
        ao_before: fit_before,
        ao_after: gap(&lightmap),
        edge_rows: edge.rows.len(),
        step_texels,
    });
    let seam_maps = before.map(|b| [b, map(&lightmap)]);
    timer.lap(if stitch { "seams" } else { "border solve" });
    Ok(Built {
        lightmap,
        seams: stitch.then_some(report),
        border,
        seam_maps,
        solve_range,
        may_change,
        reads,
    })
}

/// A bicubic page's centre rows: at every covered texel not fitted to
/// traced points (`fit_at`), the lookup at its centre reads its baked value
/// (every channel), weighing [`CENTRE_WEIGHT`]. Over a chart's inside these
/// rows are the B-spline's interpolation condition (the coefficients whose
/// spline passes through the samples), solved together with the border
/// band's and the step cells' traced points and the seams.
fn centre_rows(lm: &Lightmap, fit_at: &[bool]) -> Vec<seams::Anchor> {
    let (w, h) = (lm.width, lm.height);
    let channels = seams::channels(lm.visibility.is_some());
    (0..w * h)
        .into_par_iter()
        .filter(|&t| lm.covered[t as usize] && !fit_at[t as usize])
        .map(|t| {
            let mut target = vec![0.0f32; channels];
            let v = lm.visibility.as_deref();
            seams::write_channels(&lm.ao, &lm.sh, v, t as usize, &mut target);
            seams::Anchor {
                uv: [
                    ((t % w) as f32 + 0.5) / w as f32,
                    ((t / w) as f32 + 0.5) / h as f32,
                ],
                target,
                weight: CENTRE_WEIGHT,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bicubic_centre_rows_make_the_spline_pass_through_a_quadratic() {
        // Every texel of a 24 x 24 page covered and baked to f at its
        // centre (texel units), f quadratic in x: the cubic B-spline with
        // the solved coefficients reproduces f between the centres, where
        // read of the samples themselves it is off by f''/6 at a centre and
        // bilinearly by f''/8 between two.
        let (w, h) = (24u32, 24u32);
        let n = (w * h) as usize;
        let f = |x: f32, y: f32| 0.05 + 0.0016 * x * x + 0.001 * y;
        let centre = |t: usize| ((t % 24) as f32, (t / 24) as f32);
        let ao: Vec<f32> = (0..n).map(|t| f(centre(t).0, centre(t).1)).collect();
        let mut lm = Lightmap {
            width: w,
            height: h,
            ao: ao.clone(),
            sh: vec![[0.0; SH_COUNT]; n],
            covered: vec![true; n],
            visibility: None,
        };
        let rows = centre_rows(&lm, &vec![false; n]);
        assert_eq!(rows.len(), n);
        let free = vec![true; n];
        let (ao_out, sh_out) = (&mut lm.ao, &mut lm.sh);
        let report = seams::stitch_page(
            &[],
            &[],
            &rows,
            &|_| 1.0,
            1.0,
            1.0,
            w,
            h,
            Filter::Bicubic,
            &free,
            None,
            None,
            ao_out,
            sh_out,
            None,
        )
        .report;
        assert!(report.solve.converged, "{:?}", report.solve);
        // Away from the page's edge (clamp to edge bends the spline there).
        let (mut fitted, mut raw, mut linear) = (0.0f32, 0.0f32, 0.0f32);
        for k in 0..400 {
            let (x, y) = (4.0 + (k % 20) as f32 * 0.77, 4.0 + (k / 20) as f32 * 0.77);
            let uv = [(x + 0.5) / w as f32, (y + 0.5) / h as f32];
            let want = f(x, y);
            fitted = fitted.max((Filter::Bicubic.lookup1(&lm.ao, w, h, uv) - want).abs());
            raw = raw.max((Filter::Bicubic.lookup1(&ao, w, h, uv) - want).abs());
            linear = linear.max((Filter::Bilinear.lookup1(&ao, w, h, uv) - want).abs());
        }
        assert!(fitted < 1e-4, "{fitted}");
        assert!(raw > 4e-4 && linear > 2e-4, "{raw} {linear}");
    }
}
