//! Adaptive sampling with an axis-aligned filter (`--method adaptive`, the
//! default): the cheap form of Egan et al.'s frequency analysis, after
//! Mehta, Wang and Ramamoorthi 2012/2013 (see
//! `shared/notes/axis-aligned-filtering.md` and `docs/method-adaptive.md`,
//! which maps each stage to the papers and measures each departure).
//!
//! In: [`Receivers`] with their `inside` marks, a [`Tracer`],
//! [`AdaptiveOptions`], [`BakeParams`], the [`StageTimer`]. Out: a [`Bake`]
//! and [`AdaptiveStats`].
//!
//! The stages, in the order [`bake`] calls them, one module each:
//!
//! 1. `prepass`: `pre_rays` rays per receiver, the first points of its
//!    own sequence: its own z_min, the visible count, the SH sums and the
//!    strata its visibility boundary crosses.
//! 2. `bounds`: the filter width sigma = z_min / (2 mu Omega_h) from the
//!    z_min spread over the filter's support (`width`), 0 in contact;
//!    the visibility spread over the neighbourhood (`grid`) and N_eff.
//! 3. `allocation`: ray counts in proportion to sd / sqrt(N_eff), scaled
//!    so the predicted error is `quality`-ray Monte Carlo's, powers of two
//!    (whole Sobol blocks keep the stratification).
//! 4. `adaptive_pass`: each receiver's sequence continued to its count;
//!    with [`FitSets`] in two rounds, the receivers the border fit will
//!    set stopping at [`fit_set_rays`].
//! 5. `filter`: the integrated AO and occluded SH share averaged over
//!    the atlas neighbours with Gaussian weights, rows then columns,
//!    through the leak rule and within z_min; then the exact parts added
//!    per receiver (`sums::finish`: the open hemisphere's projection, the
//!    share below the geometric plane).
//! 6. With the visibility layer (`super::visibility`): the cap of each
//!    receiver's hemisphere from its own cosine-weighted rays (summed in
//!    the pre-pass and the adaptive pass), the band at the horizon from
//!    an eighth as many uniform band rays (`visibility::band_rays`); their
//!    occluded share filtered with the same weights
//!    (`FilterSupport::filter_values`), the exact parts added per receiver.
//!
//! Below them: `options`, `sums` (what a receiver's rays add up to),
//! `strata`, `width` and `grid` (the atlas as a neighbourhood).

pub(crate) mod adaptive_pass;
pub(crate) mod allocation;
pub(crate) mod bounds;
pub(crate) mod filter;
pub(crate) mod grid;
pub(crate) mod line;
pub(crate) mod options;
pub(crate) mod prepass;
pub(crate) mod strata;
pub(crate) mod sums;
pub(crate) mod width;

pub use allocation::Scale;
pub use options::{AdaptiveOptions, MAX_ADAPTIVE_RAYS, MAX_REACH};
pub use width::Depths;

use super::visibility as vis;
use super::{Bake, BakeParams};
use crate::atlas::Receivers;
use crate::sh::SH_COUNT;
use crate::stage::StageTimer;
use crate::trace::Tracer;
use filter::FilterSupport;
use grid::TexelGrid;
use rayon::prelude::*;
use sums::RaySums;

/// What a bake takes from the whole page, or from an earlier bake, rather
/// than from its own receivers. A bake of part of a page (`--reuse`: only
/// the texels an edit reaches, with a halo of [`Self::halo`] texels) given
/// the whole page's gives every receiver deeper than the halo the value
/// the whole page's bake gives it: every other input of a receiver is its
/// own rays (keyed by its texel) and its neighbours' within the halo.
#[derive(Clone, Copy, Debug, Default)]
pub struct PageWide {
    /// The allocation's scale (an earlier bake's, `--reuse`).
    pub scale: Option<Scale>,
    /// The pre-pass's depths ([`Depths::of`] the whole page).
    pub depths: Option<Depths>,
}

impl PageWide {
    /// How far (Chebyshev, texels) a receiver's value reads other
    /// receivers' pre-pass: its lenders' values (`max_reach` away, or a
    /// contact line's reach), their counts (`line::count_reach`: the
    /// spread z_min and N_eff, `max_reach` each, or through the contact
    /// lines); with [`FitSets`] a receiver's count reads whether the fit
    /// sets it, from the first round's filtered values within 3 texels
    /// (its cells' taps and the gutter texels they show), which read the
    /// same reaches, so the lenders' reach once more and 3 texels; and a
    /// margin of 2 texels. Without contact lines, 4 `max_reach` + 5.
    pub fn halo(o: &AdaptiveOptions) -> u32 {
        let lenders = o.max_reach.max(line::line_reach(o));
        2 * lenders + line::count_reach(o) + 5
    }
}

/// What the adaptive bake did.
#[derive(Clone, Debug, Default)]
pub struct AdaptiveStats {
    pub pre_rays: u64,
    pub adaptive_rays: u64,
    /// Per receiver: rays cast, spread z_min (bake units, INFINITY if
    /// none; below `width::contact_depth` a bound, not the nearest hit), filter
    /// sigma in texels (0: not filtered).
    pub rays: Vec<u32>,
    pub z_min: Vec<f32>,
    pub sigma_texels: Vec<f32>,
    /// Per receiver: inside geometry (the validity stage's test, made on
    /// the pre-pass's rays; all false without `fill_inside`).
    pub inside: Vec<bool>,
    /// The allocation's page scale (found, or carried in).
    pub scale: Option<Scale>,
    /// Receivers filtered along a contact line ([`line`]).
    pub contact_lines: usize,
}

impl AdaptiveStats {
    /// Receivers per ray count (power of two), ascending.
    pub fn ray_histogram(&self) -> Vec<(u32, usize)> {
        let mut h: std::collections::BTreeMap<u32, usize> = Default::default();
        for &r in &self.rays {
            *h.entry(r).or_default() += 1;
        }
        h.into_iter().collect()
    }

    /// The `--debug-dir` maps, each in [0, 1]: `z_min` (spread, over the max
    /// distance), `rays_per_texel` (over the most any texel got) and
    /// `filter_sigma` (over the widest).
    pub fn debug_maps(&self, max_distance: f32) -> Vec<(&'static str, Vec<f32>)> {
        let most = self.rays.iter().copied().max().unwrap_or(1).max(1) as f32;
        let widest = self.sigma_texels.iter().copied().fold(0.0f32, f32::max);
        let widest = if widest > 0.0 { widest } else { 1.0 };
        vec![
            (
                "z_min",
                self.z_min
                    .iter()
                    .map(|&z| (z / max_distance).min(1.0))
                    .collect(),
            ),
            (
                "rays_per_texel",
                self.rays.iter().map(|&r| r as f32 / most).collect(),
            ),
            (
                "filter_sigma",
                self.sigma_texels.iter().map(|&s| s / widest).collect(),
            ),
        ]
    }
}

/// The adaptive bake (see the module doc). `visibility`: also bake the
/// visibility layer (the cap from the receiver's own rays, the band from
/// `visibility::band_rays` uniform rays; their occluded share filtered with the
/// same weights as the SH). `fill_inside`: find the
/// receivers inside geometry ([`super::validity`], from the pre-pass's
/// rays; they get the pre-pass only and neither lend nor receive in the
/// filter), returned in [`AdaptiveStats::inside`]. Options validated.
/// `page`: what to take from the whole page or an earlier bake instead
/// of finding it from `receivers` ([`PageWide`]); the scale used is in
/// [`AdaptiveStats::scale`].
/// `fit_sets`: which receivers the border fit will set, from their
/// filtered AO (and which lie inside geometry); those get at most
/// [`fit_set_rays`] rays ([`FitSets`]).
/// Laps: `pre-pass`, `bounds`, `adaptive pass`, `filter`, and with the
/// layer `visibility pass`, `visibility filter`.
#[allow(clippy::too_many_arguments)]
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    fill_inside: bool,
    visibility: bool,
    o: &AdaptiveOptions,
    page: PageWide,
    fit_sets: Option<&FitSets>,
    p: &BakeParams,
    timer: &mut StageTimer,
    progress: &(dyn Fn(u64) + Sync),
) -> (Bake, AdaptiveStats) {
    let n = receivers.len();
    let depths =
        (page.depths).unwrap_or_else(|| Depths::of(&receivers.footprint, o, p.max_distance));
    let pre = prepass::pre_pass(receivers, tracer, fill_inside, visibility, o, depths, p);
    timer.lap("pre-pass");

    // The bounds' working arrays end with their stage (the memory
    // estimate counts its outputs only).
    let grid = TexelGrid::new(receivers);
    let b = bounds::bounds(receivers, &grid, &pre, o);
    let scale =
        (page.scale).unwrap_or_else(|| allocation::allocation_scale(&b.filtered, &b.unfiltered, o));
    let rays: Vec<u32> = allocation::counts(&b.filtered, &b.unfiltered, scale, o)
        .into_iter()
        .map(|t| t.max(o.pre_rays))
        .collect();
    let (z_min, sigma_texels, lines) = (b.z_min, b.sigma_texels, b.lines);
    let (mut sums, inside, mut cap) = (pre.sums, pre.inside, pre.cap);
    timer.lap("bounds");

    // Filtered receivers' sums leave out the rays below the geometric
    // plane (counted only; see [`sums::below_compensated`]).
    let filtered = |r: usize| sigma_texels[r] > 0.0;
    let support = FilterSupport {
        receivers,
        grid: &grid,
        inside: &inside,
        sigma_texels: &sigma_texels,
        z_min: &z_min,
        lines: Some(&lines),
    };
    // A receiver's 10 values (AO, SH) from its sums at `rays` rays. Equal
    // weight per receiver in the filter: weighting by ray count (inverse
    // variance) biases dark, because the allocation sends more rays to
    // occluded receivers (Cornell 512, adaptive:64: AO bias -0.0021 with
    // it).
    let values = |sums: &[RaySums], r: usize, rays: u32| {
        let (normal, geo) = (receivers.normal[r], receivers.geo_normal[r]);
        sums::below_compensated(&sums[r], rays, normal, geo, filtered(r))
    };
    let start = adaptive_pass::Start::PrePass(o.pre_rays);
    let rays = match fit_sets {
        None => {
            adaptive_pass::adaptive_pass(
                receivers, tracer, &mut sums, &mut cap, start, &rays, filtered, p, progress,
            );
            rays
        }
        // Receivers the border fit sets: at most FIT_SET_RAYS, found
        // from the values at that count; the others go on to theirs.
        Some(sets) => {
            let first: Vec<u32> = rays.iter().map(|&n| n.min(fit_set_rays(o))).collect();
            let quiet = |_| {};
            adaptive_pass::adaptive_pass(
                receivers, tracer, &mut sums, &mut cap, start, &first, filtered, p, &quiet,
            );
            // The AO alone, filtered with the same weights.
            let ao: Vec<[f32; 1]> = (0..n)
                .into_par_iter()
                .with_min_len(1024)
                .map(|r| [values(&sums, r, first[r])[0]])
                .collect();
            let ao: Vec<f32> = (support.filter_values(ao).into_iter().enumerate())
                .map(|(r, [a])| sums::finish_ao(a, receivers.normal[r], receivers.geo_normal[r]))
                .collect();
            let set = sets(&ao, &inside);
            let rays: Vec<u32> = (0..n)
                .map(|r| if set[r] { first[r] } else { rays[r] })
                .collect();
            let start = adaptive_pass::Start::Earlier(&first);
            adaptive_pass::adaptive_pass(
                receivers, tracer, &mut sums, &mut cap, start, &rays, filtered, p, progress,
            );
            rays
        }
    };
    timer.lap("adaptive pass");
    let all: Vec<[f32; 10]> = (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map(|r| values(&sums, r, rays[r]))
        .collect();
    drop(sums);
    let (mut ao, mut sh): (Vec<f32>, Vec<[f32; SH_COUNT]>) = support.filter(all);
    sums::finish(&receivers.normal, &receivers.geo_normal, &mut ao, &mut sh);
    timer.lap("filter");

    let layer = visibility.then(|| {
        let counts = |r: usize| vis::band_rays(rays[r]);
        let cosine = |r: usize| rays[r];
        let shares = vis::shares_cap_band(receivers, tracer, &cap, cosine, |r| (0, counts(r)), p);
        timer.lap("visibility pass");
        let v = vis::finish(receivers, support.filter_values(shares));
        timer.lap("visibility filter");
        let rays = (0..n).map(|r| counts(r) as u64).sum();
        vis::Visibility { v, rays }
    });
    drop(grid);

    let pre_rays = n as u64 * o.pre_rays as u64;
    let total: u64 = rays.iter().map(|&r| r as u64).sum();
    let bake = Bake {
        ao,
        sh,
        rays: total,
        visibility: layer,
    };
    let stats = AdaptiveStats {
        pre_rays,
        adaptive_rays: total - pre_rays,
        rays,
        z_min,
        sigma_texels,
        inside,
        scale: Some(scale),
        contact_lines: lines.count(),
    };
    (bake, stats)
}

/// Which receivers the border fit will set (`crate::lightmap::border`),
/// from every receiver's filtered AO and whether it lies inside geometry.
///
/// A texel in a fitted cell takes its value mostly from the fit's traced
/// points around it (about sixteen rows against its own data term), so
/// its own rays past the fit's count buy little a lookup shows: the
/// adaptive pass gives such receivers at most [`fit_set_rays`], and the
/// rest of their allocation is not cast. Which texels are fitted depends
/// on the baked values, so the pass runs in two rounds: every receiver to
/// at most that count, the values filtered and the fitted ones found,
/// then the others on to their counts. A round continues each receiver's
/// own sequence, so a receiver not set ends with the rays and sums a
/// single round gives it.
pub type FitSets<'a> = dyn Fn(&[f32], &[bool]) -> Vec<bool> + Sync + 'a;

/// The most rays a receiver the border fit sets gets ([`FitSets`]), never
/// fewer than the pre-pass's: the fit's sixteen or so rows around it
/// outweigh its own value. Sponza 1024, with the receivers found from
/// their first round's values (edge receivers kept; against the
/// allocation's counts, engine view all / border): at most 32 0.998x /
/// 1.002x for 0.84x of the texels' rays; 16 cost the border 1.02x
/// (`docs/measurements/border-fit-cost.md`).
pub fn fit_set_rays(o: &AdaptiveOptions) -> u32 {
    FIT_SET_RAYS.max(o.pre_rays)
}

/// [`fit_set_rays`] before the pre-pass's floor.
pub const FIT_SET_RAYS: u32 = 32;
