//! Border fit: the texels of a chart's border band, and of the cells the
//! signal steps across inside it, take the values whose bilinear lookups
//! match the signal at the chart's own surface points.
//!
//! In: a page's triangles ([`surface_triangles`]), which texels are free
//! to move (every texel but the stitch's [`interior`] ones, and with
//! `--border fit` the taps of the [`step_texels`]' cells), the tracer.
//! Out: [`Anchor`]s, one-sided constraints "the lookup at this UV reads
//! this value", at surface points of every bilinear cell that has a free
//! tap, with the contract's AO, SH (and visibility layer) traced at each
//! point; the seams' solve ([`super::seams::solve::stitch`]) fits them
//! together with the seams.
//!
//! Why: a texel whose centre lies outside its chart holds the value of the
//! chart's point nearest its centre (up to 0.7 texels away), but every
//! lookup reads it as if it were the value at its centre; where the signal
//! bends within a texel (contact darkening along a chart's edge) the
//! bilinear reconstruction between it and the chart's inside texels is
//! wrong all across the border band. Kavan, Bargteil and Sloan, "Least
//! Squares Vertex Baking" (EGSR 2011), fit the stored values to the signal
//! through the reconstruction instead: minimise the integral over the
//! surface of (f - Sum_t phi_t x_t)^2, with phi_t each texel's bilinear hat
//! clipped to its chart. Here the integral is a quadrature over a jittered
//! grid of [`GRID`] x [`GRID`] points per texel of UV area (equal
//! weights), restricted to the cells where something can move, with f
//! traced at each point by [`FIT_RAYS`]-ray Monte Carlo.
//!
//! Inside a chart the same holds wherever the signal steps within a cell
//! (a strap lying on the helmet, a column's foot on the floor): the texel
//! centres sample a step at four points and the lookup between them draws
//! a ramp that is wrong on both sides of it. A smooth signal is what the
//! texels' own filtered values already reconstruct, and fit targets there
//! only add their noise, so the fit reaches in only where the baked AO of
//! a cell's four taps spans more than [`STEP`] ([`step_texels`]): the
//! contact lines, a small share of the page.
//!
//! Where the band's values are flat the same holds: the texels held at
//! their chart's edge points are already what a lookup should read, and
//! fit points there buy nothing but their noise (a point's 64 rays carry
//! an AO error of about 0.05, a texel's ~16 points about 0.0125; the
//! reconstruction's error in a flat cell is smaller). So points go only
//! into cells with a free tap that belongs to a cell spanning more than
//! [`flat_span`] ([`fitted_taps`]): Sponza's band points fall by a fifth
//! for the same engine view (`docs/measurements/border-fit-cost.md`).
//!
//! Points inside geometry (the contract's rule, [`validity`]) are left
//! out: no camera sees them and their traced value is black. A triangle
//! too small to hold a grid point in a cell with a free tap gets one at
//! its centroid, and the cells where no tap's centre lies inside a
//! triangle (a chart thinner than a texel there) get [`SLIVER_SUB`]^2
//! points per grid cell, so slivers are fitted too.
//!
//! [`interior`]: super::seams::interior
//! [`surface_triangles`]: crate::atlas::rasterize::surface_triangles

use super::filter::bilinear_taps as taps;
use super::seams::Anchor;
use crate::atlas::Receivers;
use crate::atlas::rasterize::{SurfaceTri, closest_point_barycentric, inside};
use crate::bake::{BakeParams, mc, validity, visibility};
use crate::bits::{mix64, unit};
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::trace::Tracer;
use glam::Vec2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Quadrature points per texel edge: GRID^2 points per texel of UV area.
pub const GRID: u32 = 2;

/// Rays of each fitted point's target.
pub const FIT_RAYS: u32 = 64;

/// Uniform rays of each fitted point's visibility layer: as the adaptive
/// bake gives its receivers, half the cosine-weighted count
/// ([`crate::bake::adaptive::visibility_rays`]). Measured on the flight
/// helmet at 1024 against 64: border points stage 0.84x, relight error
/// interior / border 1.018x / 1.021x, engine-view AO and SH unchanged
/// (`docs/measurements/border-fit-cost.md`).
pub const FIT_VISIBILITY_RAYS: u32 = FIT_RAYS / crate::bake::adaptive::VISIBILITY_RAY_DIVISOR;

/// A fitted point's row weight relative to a seam row's (seams-only):
/// the fit has ~4 rows per texel of the border band against each texel's
/// data term of 1.
pub const FIT_WEIGHT: f32 = 0.5;

/// Least AO span of a cell's four taps (max - min) that makes it a step
/// cell, fitted inside a chart ([`step_texels`]). A bilinear ramp
/// misplaces a step by up to half a texel, so the error it leaves grows
/// with the step's height; a smooth gradient spans a few hundredths per
/// texel at most. Half of it doubles the cells, and the fit's noise where
/// nothing steps takes back what the added cells gain (`docs/measurements/engine-view-levers.md`).
pub const STEP: f32 = 0.1;

/// Which texels are fitted (`--border`): `Fit`, the border band and the
/// step cells inside charts ([`step_texels`]); `Band`, the border band
/// alone; `Off`, none (border texels keep their edge receivers' values).
/// The fit's [`anchors`] are solved with the seams.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum BorderMode {
    #[default]
    Fit,
    Band,
    Off,
}

/// The least span of a step cell for a page whose values carry the noise
/// of `noise_rays`-ray Monte Carlo (as
/// [`crate::job::settings::BakeSettings::noise_rays`] counts it for each
/// method; `None`: the sheared filter, [`STEP`]): four standard errors of a binary estimate at its
/// widest (0.5 / sqrt(rays)), so that noise alone spans it rarely, and
/// never less than [`STEP`]. At 4 rays nothing is a step; at 400 and more,
/// STEP. So a cheaper bake, whose noise crosses more cells, does not fit
/// more of them.
pub fn step_span(noise_rays: Option<u32>) -> f32 {
    match noise_rays {
        None => STEP,
        Some(n) => STEP.max(2.0 / (n.max(1) as f32).sqrt()),
    }
}

/// The span under which a cell is flat for the fit's points: half a
/// step's ([`step_span`]). Measured on Sponza 1024 (engine view, 60,000
/// points): band points only where a cell spans more than 0.05, 0.1, or
/// none left out: border error 0.0324, 0.0328, 0.0325, for 0.81x, 0.74x,
/// 1x the points.
pub fn flat_span(noise_rays: Option<u32>) -> f32 {
    0.5 * step_span(noise_rays)
}

/// The free taps whose cells get fit points: `free` texels that are a tap
/// of a cell (with a covered tap) whose baked AO spans more than `span`
/// ([`flat_span`]). A cell gets points when one of its taps is such a
/// texel, so a varied cell's neighbours are fitted too.
pub fn fitted_taps(
    ao: &[f32],
    covered: &[bool],
    free: &[bool],
    width: u32,
    height: u32,
    span: f32,
) -> Vec<bool> {
    let varied = step_texels(ao, covered, width, height, span);
    free.iter().zip(varied).map(|(&f, v)| f && v).collect()
}

/// The taps of every bilinear cell of a `width` x `height` page that
/// holds a `covered` texel and whose four baked AO values span more than
/// `span` ([`step_span`]): where the signal steps within a cell and the
/// texels' own values, each sampled at its centre, do not make the lookup
/// between them right.
pub fn step_texels(ao: &[f32], covered: &[bool], width: u32, height: u32, span: f32) -> Vec<bool> {
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![false; w * h];
    if w < 2 || h < 2 {
        return out;
    }
    // Each row of cells marks its own two rows of texels; rows are
    // joined in order (the result does not depend on the thread count).
    let rows: Vec<Vec<usize>> = (0..h - 1)
        .into_par_iter()
        .map(|y| {
            let mut cells = Vec::new();
            for x in 0..w - 1 {
                let taps = [
                    y * w + x,
                    y * w + x + 1,
                    (y + 1) * w + x,
                    (y + 1) * w + x + 1,
                ];
                if !taps.iter().any(|&t| covered[t]) {
                    continue;
                }
                let (lo, hi) = taps
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &t| {
                        (lo.min(ao[t]), hi.max(ao[t]))
                    });
                // A tap not known (NaN, a bake of part of a page) may
                // hide a step: the cell counts as one.
                if hi - lo > span || taps.iter().any(|&t| ao[t].is_nan()) {
                    cells.push(y * w + x);
                }
            }
            cells
        })
        .collect();
    for c in rows.into_iter().flatten() {
        for t in [c, c + 1, c + w, c + w + 1] {
            out[t] = true;
        }
    }
    out
}

/// A page's traced fit (its [`anchors`]), kept by the page so that runs
/// baking it again (`aobake report`'s sweep) trace it once: valid for the
/// same free texels and layer.
#[derive(Debug, Default)]
pub struct FitTargets {
    pub layer: bool,
    /// The texels the solve moves.
    pub free: Vec<bool>,
    /// The free texels whose cells hold the points ([`fitted_taps`]).
    pub fitted: Vec<bool>,
    pub anchors: Vec<Anchor>,
    /// Rays cast for them.
    pub rays: u64,
}

/// Where a page keeps its [`FitTargets`].
pub(crate) type FitCache = std::sync::Mutex<Option<std::sync::Arc<FitTargets>>>;

/// A surface point of the fit: its UV in texels and where it lies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitPoint {
    /// Lightmap position in texel units of the page.
    pub uv: Vec2,
    /// Its triangle (index into the page's triangles) and barycentrics.
    pub tri: u32,
    pub bary: [f32; 3],
}

/// The four texels (indices into a `width` x `height` page) of the
/// bilinear cell of a lookup at `uv` (texel units): the engine view's
/// [`taps`], so the fit and the metric agree on every cell.
fn cell_taps(uv: Vec2, width: u32, height: u32) -> [usize; 4] {
    taps([uv.x / width as f32, uv.y / height as f32], width, height).map(|(t, _)| t as usize)
}

/// Whether the bilinear cell of a lookup at `uv` (texel units) has a
/// free tap (`free` per texel of a `width` x `height` page).
pub(crate) fn cell_has_free(uv: Vec2, width: u32, height: u32, free: &[bool]) -> bool {
    cell_taps(uv, width, height).iter().any(|&t| free[t])
}

/// Whether no tap of the bilinear cell at `uv` (texel units) has its
/// centre inside a triangle: a sliver's cell, as the engine view
/// classifies its lookups.
fn is_sliver_cell(uv: Vec2, width: u32, height: u32, center_inside: &[bool]) -> bool {
    !cell_taps(uv, width, height)
        .iter()
        .any(|&t| center_inside[t])
}

/// The grid point of global grid cell (`gx`, `gy`): jittered in its cell
/// of 1 / [`GRID`] texels, the same wherever it is asked for.
fn grid_point(gx: i64, gy: i64, seed: u64) -> Vec2 {
    let key = mix64(seed ^ mix64((gx as u64) << 32 ^ (gy as u64 & 0xffff_ffff)));
    let g = GRID as f32;
    Vec2::new(
        (gx as f32 + unit(key)) / g,
        (gy as f32 + unit(key ^ 0x5bd1_e995)) / g,
    )
}

/// The fit's points on `tris` (one page's, `width` x `height`): every
/// grid point inside a triangle whose cell has a free tap, and the
/// centroid of a triangle holding none such but whose centroid's cell
/// has one. In a sliver cell (no tap's centre inside a triangle,
/// `center_inside` per texel) each grid cell holds [`SLIVER_SUB`]^2 points
/// instead of one. In triangle order, deterministic for `seed`.
pub fn points(
    tris: &[SurfaceTri],
    width: u32,
    height: u32,
    free: &[bool],
    center_inside: &[bool],
    seed: u64,
) -> Vec<FitPoint> {
    let g = GRID as f32;
    let per_tri: Vec<Vec<FitPoint>> = tris
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let mut out = Vec::new();
            let lo = t.uv.iter().fold(Vec2::INFINITY, |a, &p| a.min(p));
            let hi = t.uv.iter().fold(Vec2::NEG_INFINITY, |a, &p| a.max(p));
            if !(lo.is_finite() && hi.is_finite()) {
                return out;
            }
            let (gx0, gy0) = ((lo.x * g).floor() as i64, (lo.y * g).floor() as i64);
            let (gx1, gy1) = ((hi.x * g).floor() as i64, (hi.y * g).floor() as i64);
            // Whether any grid point falls inside the triangle.
            let mut any = false;
            let mut push = |p: Vec2, out: &mut Vec<FitPoint>| {
                if !inside(p, &t.uv) {
                    return;
                }
                any = true;
                if cell_has_free(p, width, height, free) {
                    let (bary, _) = closest_point_barycentric(p, t.uv[0], t.uv[1], t.uv[2]);
                    out.push(FitPoint {
                        uv: p,
                        tri: i as u32,
                        bary,
                    });
                }
            };
            for gy in gy0..=gy1 {
                for gx in gx0..=gx1 {
                    let centre = Vec2::new(gx as f32 + 0.5, gy as f32 + 0.5) / g;
                    if is_sliver_cell(centre, width, height, center_inside) {
                        let s = SLIVER_SUB as i64;
                        for sy in 0..s {
                            for sx in 0..s {
                                let f = grid_point(gx * s + sx, gy * s + sy, seed ^ SLIVER_SEED);
                                push(f / SLIVER_SUB as f32, &mut out);
                            }
                        }
                    } else {
                        push(grid_point(gx, gy, seed), &mut out);
                    }
                }
            }
            let centroid = (t.uv[0] + t.uv[1] + t.uv[2]) / 3.0;
            if !any && cell_has_free(centroid, width, height, free) {
                let third = 1.0 / 3.0;
                out.push(FitPoint {
                    uv: centroid,
                    tri: i as u32,
                    bary: [third; 3],
                });
            }
            out
        })
        .collect();
    per_tri.into_iter().flatten().collect()
}

/// The key of a fit point's rays (its receiver's `texel`, which seeds its
/// sequence): a hash of its UV's bits. Points are placed by the global
/// grid, so a point keeps its key whatever else is on the page.
fn point_key(uv: Vec2) -> u32 {
    mix64(u64::from(uv.x.to_bits()) << 32 | u64::from(uv.y.to_bits())) as u32
}

/// Points per grid cell edge in a sliver's cell: SLIVER_SUB^2 points where
/// the grid has one, each a full fit row. A chart's acute tip or a strip
/// thinner than the grid spacing gets a grid point only here and there, and
/// its few rows lose to the texels' data terms, so its lookups keep the
/// edge receivers' values. Full rows matter: weighted by their share of
/// the cell they did worse than none; 8 per edge does no better than 4
/// for far more points (`docs/measurements/constants.md`, SLIVER_SUB).
pub const SLIVER_SUB: u32 = 4;

const SLIVER_SEED: u64 = 0x51f1_7e55;

/// A seam row's scale with the border fit on: twice the seams-only weight
/// against the data term, so the two sides' noisy fits still meet.
/// Cross-page anchors are seam rows and scale alike
/// (`docs/measurements/constants.md`, SEAM_SCALE).
pub const SEAM_SCALE: f64 = 2.0;

/// The anchors of a page's border band: [`points`] on `tris` traced with
/// [`FIT_RAYS`] rays (AO, SH), and with `layer` [`FIT_VISIBILITY_RAYS`]
/// for the visibility layer's coefficients after them, inside-geometry
/// points left out. `seed`: the page's own (its points and rays depend on
/// nothing else). `known`: per texel, whether its value is known (a bake
/// of part of a page, [`super::build`]); a point whose cell has a tap not
/// known is not traced and becomes a row whose target is NaN in every
/// channel, so that the solve leaves whatever it ties not known. Returns
/// the anchors and the rays cast, the layer's included (the inside test's
/// not counted).
#[allow(clippy::too_many_arguments)]
pub fn anchors(
    tris: &[SurfaceTri],
    width: u32,
    height: u32,
    free: &[bool],
    center_inside: &[bool],
    known: Option<&[bool]>,
    tracer: &Tracer,
    max_distance: f32,
    seed: u64,
    layer: bool,
) -> (Vec<Anchor>, u64) {
    let points = points(tris, width, height, free, center_inside, seed);
    if points.is_empty() {
        return (Vec::new(), 0);
    }
    // Points in cells not known: rows with NaN targets, in their places.
    let traced =
        |p: &FitPoint| known.is_none_or(|k| cell_taps(p.uv, width, height).iter().all(|&t| k[t]));
    let unknown: Vec<bool> = points.iter().map(|p| !traced(p)).collect();
    let (all, points): (Vec<FitPoint>, Vec<FitPoint>) = match known {
        None => (Vec::new(), points),
        Some(_) => {
            let kept = (points.iter().zip(&unknown))
                .filter(|&(_, &u)| !u)
                .map(|(p, _)| *p)
                .collect();
            (points, kept)
        }
    };
    let mut r = Receivers {
        width,
        height,
        ..Default::default()
    };
    // Each point's rays are keyed by where it lies on the page, not by its
    // place in the list: an edit that adds or removes points elsewhere
    // (a moved mesh's cells turning flat or varied) leaves every other
    // point's rays as they were, so the fit changes only near the edit.
    for p in &points {
        r.push_surface_point(point_key(p.uv), &tris[p.tri as usize], p.bary, true);
    }
    let params = BakeParams { max_distance, seed };
    let inside = validity::inside_geometry(&r, tracer, max_distance, seed);
    let (w, h) = (width as f32, height as f32);
    let uv = |p: &FitPoint| [p.uv.x / w, p.uv.y / h];
    let bake = mc::bake(&r, tracer, FIT_RAYS, &params, &|_| {});
    let v = layer.then(|| visibility::bake(&r, tracer, FIT_VISIBILITY_RAYS, &params));
    let anchors: Vec<Anchor> = points
        .iter()
        .enumerate()
        .filter(|&(k, _)| !inside[k])
        .map(|(k, p)| {
            let mut target = Vec::with_capacity(1 + SH_COUNT + VIS_COUNT);
            target.push(bake.ao[k]);
            target.extend_from_slice(&bake.sh[k]);
            if let Some(v) = &v {
                target.extend_from_slice(&v.v[k]);
            }
            Anchor {
                uv: uv(p),
                target,
                weight: FIT_WEIGHT,
            }
        })
        .collect();
    let rays = bake.rays + v.map_or(0, |v| v.rays);
    if all.is_empty() {
        return (anchors, rays);
    }
    let channels = 1 + SH_COUNT + if layer { VIS_COUNT } else { 0 };
    let traced = (0..points.len()).filter(|&k| !inside[k]).zip(anchors);
    let uvs = all.iter().map(uv);
    let rows = super::known::with_nan_rows(uvs, &unknown, traced, channels, FIT_WEIGHT);
    (rows, rays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec3, Vec3A};

    fn square(w: f32) -> Vec<SurfaceTri> {
        // A w x w texel square at (2, 2), as two triangles.
        let c = [
            Vec2::new(2.0, 2.0),
            Vec2::new(2.0 + w, 2.0),
            Vec2::new(2.0 + w, 2.0 + w),
            Vec2::new(2.0, 2.0 + w),
        ];
        let p = c.map(|c| Vec3::new(c.x, c.y, 0.0));
        [[0, 1, 2], [0, 2, 3]]
            .iter()
            .map(|i| SurfaceTri {
                mesh: 0,
                uv: i.map(|k| c[k]),
                pos: i.map(|k| p[k]),
                nrm: None,
                geo: Vec3::Z,
                footprint: 1.0,
            })
            .collect()
    }

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
            let (anchors, _) = anchors(tris, 10, 10, &all, &all, None, &tracer, 3.0, 5, false);
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
    fn grid_points_are_the_same_from_either_triangle() {
        assert_eq!(grid_point(7, -3, 11), grid_point(7, -3, 11));
        let p = grid_point(7, -3, 11);
        assert!(p.x >= 3.5 && p.x < 4.0 && p.y >= -1.5 && p.y < -1.0, "{p}");
    }

    #[test]
    fn points_cover_the_cells_with_a_free_tap_at_the_grid_density() {
        // A 6 x 6 texel square on a 10 x 10 page, every texel free: its
        // area times GRID^2 points, each once.
        let tris = square(6.0);
        let all = vec![true; 100];
        let pts = points(&tris, 10, 10, &all, &all, 3);
        let expected = 36.0 * (GRID * GRID) as f32;
        assert!((pts.len() as f32 - expected).abs() <= 2.0, "{}", pts.len());
        // No texel free: no point.
        assert!(points(&tris, 10, 10, &[false; 100], &all, 3).is_empty());
        // Only texel (2, 2) free: points only in the four cells around its
        // centre (2.5, 2.5), i.e. within one texel of it.
        let mut one = vec![false; 100];
        one[2 * 10 + 2] = true;
        let pts = points(&tris, 10, 10, &one, &all, 3);
        assert!(!pts.is_empty());
        for p in &pts {
            assert!(
                (p.uv - Vec2::splat(2.5)).abs().max_element() <= 1.0,
                "{p:?}"
            );
        }
    }

    #[test]
    fn a_triangle_smaller_than_the_grid_gets_its_centroid() {
        let tris = square(0.05);
        let all = vec![true; 100];
        let pts = points(&tris, 10, 10, &all, &all, 3);
        assert_eq!(pts.len(), 2, "{pts:?}");
        for p in &pts {
            assert_eq!(p.bary, [1.0 / 3.0; 3]);
        }
    }

    #[test]
    fn a_slivers_cells_hold_the_dense_points() {
        // A strip 0.3 x 6 texels at (2, 2) on a 10 x 10 page, every texel
        // free. With no texel centre inside a triangle every cell is a
        // sliver's: SLIVER_SUB^2 times the grid's points per area.
        let mut tris = square(6.0);
        for t in &mut tris {
            for p in &mut t.uv {
                p.y = 2.0 + (p.y - 2.0) * 0.05;
            }
        }
        let all = vec![true; 100];
        let none = vec![false; 100];
        let area = 6.0 * 0.3;
        let grid = points(&tris, 10, 10, &all, &all, 3).len() as f32;
        let dense = points(&tris, 10, 10, &all, &none, 3).len() as f32;
        let per = (GRID * GRID) as f32;
        let sub = (SLIVER_SUB * SLIVER_SUB) as f32;
        assert!((grid - area * per).abs() <= 4.0, "{grid}");
        assert!(
            (dense - area * per * sub).abs() <= 0.15 * area * per * sub,
            "{dense}"
        );
        // Deterministic, and every point inside the strip.
        let again = points(&tris, 10, 10, &all, &none, 3);
        assert_eq!(again, points(&tris, 10, 10, &all, &none, 3));
        for p in &again {
            assert!(
                p.uv.y >= 2.0 && p.uv.y <= 2.3 && p.uv.x >= 2.0 && p.uv.x <= 8.0,
                "{p:?}"
            );
        }
    }
}
