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
//! traced at each point by [`FIT_RAYS`]-ray Monte Carlo, the points of one
//! texel's area taking successive runs of one scrambled Sobol sequence
//! (interleaved sampling), so that where they see much the same
//! hemisphere their errors cancel in the fit's average.
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

mod points;

pub use points::{FitPoint, GRID, SLIVER_SUB, points};

use super::seams::Anchor;
use crate::atlas::Receivers;
use crate::atlas::rasterize::SurfaceTri;
use crate::bake::{BakeParams, mc, validity, visibility};
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::trace::{Tracer, for_each_receiver};
use points::cell_taps;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Rays of each fitted point's target. The points of a texel's block
/// share one sequence ([`FitPoint::block`]), so a texel's four points hold
/// a stratified set of four times as many: on Sponza that takes back about
/// half of what halving the rays costs, but on the flight helmet 32 rays a
/// point (16 for the visibility layer) still cost its relight error 1.07x
/// / 1.11x (interior / border), over the 1.05x a bake may lose
/// (`docs/measurements/border-fit-cost.md`).
pub const FIT_RAYS: u32 = 64;

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

/// Where the fit works on a page ([`fit_at`]).
#[derive(Debug)]
pub struct FitAt {
    /// The texels fitted: the border band and, with [`BorderMode::Fit`],
    /// the [`step_texels`].
    pub free: Vec<bool>,
    /// The free texels whose cells hold points ([`fitted_taps`]; none
    /// with [`BorderMode::Off`]).
    pub fitted: Vec<bool>,
    /// Step texels outside the band.
    pub step_texels: usize,
}

/// Where the fit works on a `width` x `height` page whose texels hold
/// `ao` (`covered`: a receiver's texel): the border band for a lookup
/// reaching `reach` texels (`seams::band_within`), the step cells
/// at [`step_span`] and the fitted taps at [`flat_span`] of `noise_rays`.
#[allow(clippy::too_many_arguments)]
pub fn fit_at(
    ao: &[f32],
    covered: &[bool],
    width: u32,
    height: u32,
    reach: u32,
    mode: BorderMode,
    noise_rays: Option<u32>,
) -> FitAt {
    let mut free = super::seams::band_within(covered, width, height, reach);
    let mut steps = 0;
    if mode == BorderMode::Fit {
        let step = step_texels(ao, covered, width, height, step_span(noise_rays));
        for (f, s) in free.iter_mut().zip(step) {
            steps += (s && !*f) as usize;
            *f |= s;
        }
    }
    let fitted = match mode {
        BorderMode::Off => vec![false; free.len()],
        _ => fitted_taps(ao, covered, &free, width, height, flat_span(noise_rays)),
    };
    FitAt {
        free,
        fitted,
        step_texels: steps,
    }
}

/// Per receiver, whether the fit sets its texel ([`FitAt::fitted`]) when
/// the page's receivers hold `ao` (`inside`: inside geometry, shown by
/// their neighbours' values as the lightmap shows them, [`super::dilate`]):
/// what the adaptive bake asks before it spends a receiver's last rays
/// ([`crate::bake::adaptive::FitSets`]). The lightmap stage decides the
/// fit again from the final values.
pub fn fit_sets(
    receivers: &Receivers,
    ao: &[f32],
    inside: &[bool],
    reach: u32,
    mode: BorderMode,
    noise_rays: Option<u32>,
) -> Vec<bool> {
    let (w, h) = (receivers.width, receivers.height);
    let fill = super::dilate::fill_map(w, h, &receivers.texel, inside);
    let shown = super::spread::shown(&fill, 1.0, |r| ao[r]);
    let covered = super::spread::covered(receivers);
    let at = fit_at(&shown, &covered, w, h, reach, mode, noise_rays);
    // An edge receiver (its texel's centre outside its chart) is the
    // target of its texel's edge row ([`super::edge`]): its own value is
    // read on the chart's edge, so it keeps its rays.
    (receivers.texel.iter().zip(&receivers.center_inside))
        .map(|(&t, &centre)| centre && at.fitted[t as usize])
        .collect()
}

/// A page's traced fit (its [`anchors`]), kept by the page so that runs
/// baking it again (`aobake report`'s sweep) trace it once: valid for the
/// same free texels and layer.
#[derive(Debug, Default)]
pub struct FitTargets {
    pub layer: bool,
    /// Rays a point.
    pub per_point: u32,
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

/// A seam row's scale with the border fit on: twice the seams-only weight
/// against the data term, so the two sides' noisy fits still meet.
/// Cross-page anchors are seam rows and scale alike
/// (`docs/measurements/constants.md`, SEAM_SCALE).
pub const SEAM_SCALE: f64 = 2.0;

/// The anchors of a page's border band: [`points`] on `tris` traced with
/// `per_point` rays each ([`FIT_RAYS`] in a bake), and with `layer` the
/// uniform band rays the adaptive bake gives a receiver of as many
/// (`visibility::band_rays`; the cap takes the point's own rays) for the
/// visibility layer's coefficients after them, inside-geometry
/// points left out. `seed`: the page's own (its points and rays depend on
/// nothing else). `known`: per texel, whether its value is known (a bake
/// of part of a page, [`super::build`]); a point whose cell has a tap not
/// known is not traced and becomes a row whose target is NaN in every
/// channel, so that the solve leaves whatever it ties not known. Returns
/// the anchors and the rays cast at points outside geometry, the layer's
/// included (the inside test's not counted).
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
    per_point: u32,
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
            let kept = all_but(&points, &unknown);
            (points, kept)
        }
    };
    // Each point's rays are keyed by where it lies on the page, not by its
    // place in the list: an edit that adds or removes points elsewhere
    // (a moved mesh's cells turning flat or varied) leaves every other
    // point's rays as they were, so the fit changes only near the edit.
    let receivers_of = |points: &[FitPoint]| {
        let mut r = Receivers {
            width,
            height,
            ..Default::default()
        };
        for p in points {
            r.push_surface_point(p.block, &tris[p.tri as usize], p.bary, true);
        }
        r
    };
    let mut r = receivers_of(&points);
    let params = BakeParams { max_distance, seed };
    let inside = validity::inside_geometry(&r, tracer, max_distance, seed);
    // A point inside geometry is left out of the fit, so its rays are not
    // traced: the others' rays come out the same without it (above).
    let outside = all_but(&points, &inside);
    if outside.len() < points.len() {
        r = receivers_of(&outside);
    }
    let (w, h) = (width as f32, height as f32);
    let uv = |p: &FitPoint| [p.uv.x / w, p.uv.y / h];
    let slots: Vec<u32> = outside.iter().map(|p| p.slot).collect();
    let (traced, v) = targets(&r, &slots, tracer, &params, per_point, layer);
    let anchors: Vec<Anchor> = outside
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let mut target = Vec::with_capacity(1 + SH_COUNT + VIS_COUNT);
            target.push(traced[k].0);
            target.extend_from_slice(&traced[k].1);
            if let Some(v) = &v {
                target.extend_from_slice(&v[k]);
            }
            Anchor {
                uv: uv(p),
                target,
                weight: FIT_WEIGHT,
            }
        })
        .collect();
    let n = outside.len() as u64;
    let band = visibility::band_rays(per_point) as u64;
    let rays = n * per_point as u64 + if layer { n * band } else { 0 };
    if all.is_empty() {
        return (anchors, rays);
    }
    let channels = 1 + SH_COUNT + if layer { VIS_COUNT } else { 0 };
    let traced = (0..points.len()).filter(|&k| !inside[k]).zip(anchors);
    let uvs = all.iter().map(uv);
    let rows = super::known::with_nan_rows(uvs, &unknown, traced, channels, FIT_WEIGHT);
    (rows, rays)
}

/// The points of `points` whose `left_out` is false, in their order.
fn all_but(points: &[FitPoint], left_out: &[bool]) -> Vec<FitPoint> {
    (points.iter().zip(left_out))
        .filter(|&(_, &l)| !l)
        .map(|(p, _)| *p)
        .collect()
}

/// AO and SH at every receiver of `r` (the fit's points, each keyed by its
/// block) from its `rays`-ray run `slots[k]` of its sequence, and
/// with `layer` the visibility layer's coefficients from the same rays in
/// the cap and its band-ray run `slots[k]` of the layer's
/// band sequence ([`visibility::shares_cap_band`]).
#[allow(clippy::type_complexity)]
fn targets(
    r: &Receivers,
    slots: &[u32],
    tracer: &Tracer,
    params: &BakeParams,
    rays: u32,
    layer: bool,
) -> (Vec<(f32, [f32; SH_COUNT])>, Option<Vec<[f32; VIS_COUNT]>>) {
    let mut traced = vec![(0.0f32, [0.0f32; SH_COUNT]); r.len()];
    let mut cap = vec![visibility::CapSums::default(); if layer { r.len() } else { 0 }];
    let mut states = visibility::with_caps(&mut traced, &mut cap);
    for_each_receiver(
        tracer,
        &mut states,
        64,
        |k, _, batch| mc::emit_receiver(r, k, slots[k] * rays, rays, params, batch),
        |k, (out, cap), directions, occluded| {
            **out = mc::integrate_receiver(r, k, directions, occluded);
            if let Some(c) = cap {
                let (n, geo) = (r.normal[k], r.geo_normal[k]);
                for (&d, &hit) in directions.iter().zip(occluded) {
                    if d.dot(geo) > 0.0 {
                        c.add(n, d, hit);
                    }
                }
            }
        },
        &|_| {},
    );
    drop(states);
    let v = layer.then(|| {
        let n = visibility::band_rays(rays);
        let band = |k: usize| (slots[k] * n, n);
        let shares = visibility::shares_cap_band(r, tracer, &cap, |_| rays, band, params);
        visibility::finish(r, shares)
    });
    (traced, v)
}

#[cfg(test)]
mod tests;
