//! Adaptive sampling with an axis-aligned filter (`--method adaptive`):
//! the cheap form of Egan et al.'s frequency analysis, after Mehta, Wang
//! and Ramamoorthi 2012/2013 (see `shared/notes/axis-aligned-filtering.md`).
//! Measured against 256-ray Monte Carlo at equal error in the README's
//! comparison table.
//!
//! In: [`Receivers`] with their `inside` marks, a [`Tracer`],
//! [`AdaptiveOptions`], [`BakeParams`], the [`StageTimer`]. Out: a [`Bake`]
//! and [`AdaptiveStats`].
//!
//! 1. *Pre-pass*: `pre_rays` closest-hit rays per receiver, the first points
//!    of its own sequence (the Monte Carlo baker's, stream 0): its own
//!    z_min (nearest hit distance within the max distance), the visible
//!    count and the occluded rays' SH sums.
//! 2. *Bounds*: filter width sigma = z_min / (2 mu Omega_h) (occlusion
//!    from occluders at >= z_min is bandlimited in space at
//!    Omega_h / z_min), at most `max_reach / 2` texels; below half a texel
//!    (contact) no filtering. z_min is spread: per reach k, the minimum of
//!    the compatible receivers' own z_min within k texels (rows, then
//!    columns) allows a filter of at most k / 2 texels, and each receiver
//!    takes the widest such filter ([`widest_filters`]), so an
//!    open-looking receiver beside occluded ones is not filtered wide and
//!    no filter reads a receiver that saw a nearer occluder than its
//!    width allows. The ray counts read the minimum over the support of
//!    the receiver's own z_min (2 sigma, `max_reach` when it saw nothing).
//! 3. *Ray counts*: each receiver's total in proportion to
//!    sd / sqrt(N_eff) (sd of a stratified estimate from the pre-pass's
//!    visible share and how many pairs of its strata the visibility
//!    boundary crosses ([`stratified_sd`]), over its neighbourhood; N_eff
//!    the receivers its filter really averages),
//!    scaled so the predicted error is `quality`-ray Monte Carlo's (or the
//!    mean is `mean_rays`), rounded to powers of two (whole Sobol blocks
//!    keep the stratification) in [`pre_rays`, `max_rays`]; the second
//!    batch continues the receiver's sequence. A receiver whose
//!    neighbourhood saw nothing has the variance all of the
//!    neighbourhood's pre-pass rays seeing nothing allow: few rays beside
//!    many open receivers, more on a small chart.
//! 4. *Filter*: each receiver's integrated AO and the occluded rays' 9 SH
//!    sums averaged over its atlas neighbours with Gaussian weights on the
//!    offset in its tangent plane, rows then columns (separable), through
//!    the leak rule ([`lends_rays`]), within z_min of the receiver; texels
//!    inside geometry neither receive nor lend. The same weights for all 10
//!    values; the SH is then the open hemisphere's exact projection for the
//!    receiver's own normal plus the filtered occluded share (less), each
//!    receiver's share estimated with the open projection as a control
//!    variate weighted by its visible fraction ([`sh::occluded_share`]):
//!    Cornell 1024, quality 256, SH L2 RMSE 0.00133 -> 0.00127, contact
//!    texels' 0.0028 -> 0.0025; Sponza 1024 L2 0.00196, equal to 256-ray
//!    Monte Carlo's.
//!    The share of the hemisphere below the receiver's geometric plane
//!    (where a shading normal tilts from it) is not filtered either: each
//!    value carries its receiver's exact share, which the bake subtracts
//!    per receiver after the filter, and a filtered receiver's own rays
//!    below are counted, not summed ([`below_compensated`]).
//!
//! Expert: `cross_charts` lets a receiver whose filter reaches a chart
//! border gather in world space across charts ([`World`]); measured even
//! with the grid filter or worse on four of five scenes, better on the
//! curtains (see [`AdaptiveOptions::cross_charts`]).
//!
//! Expert: `cells` 4 gives each 2x2 quadrant of the hemisphere its own
//! z_min, spread, N_eff and filter (the issue's per-cell variant); measured
//! worse than one cell per receiver on Sponza (see [`CELL_AGREEMENT`]).

use super::sheared::lends_rays;
use super::validity::{self, BackFaces};
use super::{Bake, BakeParams, ReceiverRays};
use crate::atlas::Receivers;
use crate::error::{Error, Result};
use crate::sample::Frame;
use crate::sh::{self, SH_COUNT};
use crate::stage::StageTimer;
use crate::trace::Tracer;
use glam::{Vec2, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// Options of the adaptive method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveOptions {
    /// Closest-hit rays per receiver in the pre-pass (a power of two).
    pub pre_rays: u32,
    /// The quality knob: the bake's predicted AO error is that of
    /// `quality`-ray Monte Carlo (its predicted RMSE over the atlas).
    pub quality: u32,
    /// Expert: a fixed mean rays per texel over the atlas instead of
    /// `quality` (0: from `quality`).
    pub mean_rays: u32,
    /// Most rays one receiver gets (a power of two).
    pub max_rays: u32,
    /// Expert: the spatial bandlimit constant Omega_h (sigma = z_min / (2
    /// mu Omega_h)).
    pub omega_h: f32,
    /// Expert: mu, how far inside the bandlimit the filter stays.
    pub mu: f32,
    /// Widest filter reach in texels (2 sigma).
    pub max_reach: u32,
    /// Hemisphere cells with bounds and a filter of their own: 1 (the
    /// whole hemisphere per receiver) or 4 (the 2x2 quadrants of the
    /// receiver's sample square, azimuthal quadrants of its frame).
    pub cells: u32,
    /// Expert: receivers whose filter reaches a chart border gather their
    /// neighbours in world space, across charts and UV seams (one cell
    /// only). Off by default (the five scenes' measurement ends this
    /// note). Its first version measured worse on Sponza 1024 (quality
    /// 256, 2048-ray reference): AO RMSE 0.0062 -> 0.0067, p99 0.0205 ->
    /// 0.0234, SH L1 0.00189 -> 0.00213, for 2% fewer rays, until the
    /// worst texels (AO 0.09-0.11 darker) showed their lenders: faces of a
    /// bevelled edge sharing a shading normal with different shares of the
    /// hemisphere below them ([`BELOW_AGREEMENT`]) and faces across creases
    /// ([`LENDER_NORMAL_AGREEMENT`]). With both rules: AO RMSE 0.00616
    /// against the grid filter's 0.00618, p99 0.0201 against 0.0205, SH
    /// L0/L1/L2 0.00174/0.00189/0.00197 against 0.00174/0.00189/0.00196,
    /// 108.0 rays per texel against 108.6: about even. On the five
    /// scenes at quality 256 (with the filtered margin): even on the Cornell
    /// box and Sponza 1024, 4% lower AO RMSE on the curtains for 1% more
    /// rays, but 3% higher AO RMSE and p99 on the engine and 5% / 6% / 10%
    /// higher AO RMSE / p99 / L2 on Sponza at 512, so it stays off.
    pub cross_charts: bool,
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        AdaptiveOptions {
            pre_rays: 16,
            quality: 256,
            mean_rays: 0,
            max_rays: 1024,
            omega_h: 2.8,
            mu: 0.7,
            max_reach: 4,
            cells: 1,
            cross_charts: false,
        }
    }
}

/// Largest `max_rays` and `mean_rays`.
pub const MAX_ADAPTIVE_RAYS: u32 = 4096;
/// Largest `max_reach` in texels.
pub const MAX_REACH: u32 = 32;

impl AdaptiveOptions {
    /// Checks every option's range.
    pub fn validate(&self) -> Result<()> {
        let pow2 = |v: u32| v.is_power_of_two() && v <= MAX_ADAPTIVE_RAYS;
        if !pow2(self.pre_rays) {
            return Err(Error::option(
                "pre_rays",
                format!(
                    "{} must be a power of two up to {MAX_ADAPTIVE_RAYS}",
                    self.pre_rays
                ),
            ));
        }
        if !pow2(self.max_rays) || self.max_rays < self.pre_rays {
            return Err(Error::option(
                "max_rays",
                format!(
                    "{} must be a power of two in {}..={MAX_ADAPTIVE_RAYS}",
                    self.max_rays, self.pre_rays
                ),
            ));
        }
        if !(1..=MAX_ADAPTIVE_RAYS).contains(&self.quality) {
            return Err(Error::option(
                "quality",
                format!("{} is outside 1..={MAX_ADAPTIVE_RAYS}", self.quality),
            ));
        }
        if self.mean_rays != 0 && !(self.pre_rays..=self.max_rays).contains(&self.mean_rays) {
            return Err(Error::option(
                "mean_rays",
                format!(
                    "{} is outside {}..={} (pre_rays..=max_rays), or 0 for quality",
                    self.mean_rays, self.pre_rays, self.max_rays
                ),
            ));
        }
        for (name, v) in [("omega_h", self.omega_h), ("mu", self.mu)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::option(name, format!("{v} must be finite and > 0")));
            }
        }
        if !(self.cells == 1 || self.cells == 4) || self.cells > self.pre_rays {
            return Err(Error::option(
                "cells",
                format!("{} must be 1 or 4 (and at most pre_rays)", self.cells),
            ));
        }
        if self.max_reach > MAX_REACH {
            return Err(Error::option(
                "max_reach",
                format!("{} is outside 0..={MAX_REACH} texels", self.max_reach),
            ));
        }
        Ok(())
    }

    /// Bytes per atlas texel beyond what every method holds (its results,
    /// AO and SH, which the filter's column pass writes), at the larger of
    /// two peaks. The bounds: the running sums (80 B per cell: visible
    /// and below counts, occluded and all rays' SH sums), own z_min (4 B
    /// per cell), the pre-pass strata's crossings (2 B), the texel map
    /// (4 B) and the bounds' working arrays (spread and filter z_min,
    /// sigma, supports, sd twice, N_eff and its row sums,
    /// the allocation's terms and counts: about 64 B; the widest filter's
    /// row minima, 4 B per texel of `max_reach`). The filter's row pass:
    /// ray counts (4 B), z_min and sigma (8 B per cell), the texel map
    /// (4 B), the filter's input (AO and SH: 40 B) and its row pass (44 B);
    /// with more than one cell
    /// the cells' running sums are held through it. With `cross_charts`,
    /// the k-d tree of the positions (about 20 B: point, index and its
    /// share of the nodes) through both, and own z_min through the filter.
    pub fn bytes_per_texel(&self) -> u64 {
        let cells = self.cells as u64;
        let sums = std::mem::size_of::<CellSums>() as u64 * cells;
        let world = if self.cross_charts && cells == 1 {
            20
        } else {
            0
        };
        let bounds = sums + 4 * cells + 2 + 4 + 64 + 4 * self.max_reach as u64 + world;
        let held = if cells > 1 { sums } else { 0 };
        let filter = 4 + 8 * cells + 4 + 40 + 44 + held + world + world / 5;
        bounds.max(filter)
    }

    /// Bytes per receiver the bake keeps after it ends, in
    /// [`AdaptiveStats`]: rays, z_min, sigma and inside (which the other
    /// methods' validity stage holds instead).
    pub const KEPT_BYTES_PER_TEXEL: u64 = 13;
}

/// What the adaptive bake did.
#[derive(Clone, Debug, Default)]
pub struct AdaptiveStats {
    pub pre_rays: u64,
    pub adaptive_rays: u64,
    /// Per receiver: rays cast, spread z_min (bake units, INFINITY if
    /// none; below [`contact_depth`] a bound, not the nearest hit), filter
    /// sigma in texels (0: not filtered).
    pub rays: Vec<u32>,
    pub z_min: Vec<f32>,
    pub sigma_texels: Vec<f32>,
    /// Per receiver: inside geometry (the validity stage's test, made on
    /// the pre-pass's rays; all false without `fill_inside`).
    pub inside: Vec<bool>,
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

/// One receiver cell's running sums.
#[derive(Clone, Copy, Debug, Default)]
struct CellSums {
    visible: u32,
    /// Rays below the geometric plane (occluded without tracing).
    below: u32,
    /// Sum of Y_i over the occluded rays ([`sh::occluded_share`]); a
    /// filtered receiver's leave out the rays below ([`below_compensated`]).
    sh: [f32; SH_COUNT],
    /// Sum of Y_i over all rays (the same).
    all: [f32; SH_COUNT],
}

/// The cell (of `cells`, 1 or 4) of a point `u` of the sample square: its
/// 2x2 quadrant, which the concentric map sends to an azimuthal quadrant of
/// the receiver's frame. Every aligned block of 4 points of the (Owen
/// scrambled) Sobol sequence has one point in each.
#[inline]
pub fn cell_of_point(u: Vec2, cells: usize) -> usize {
    if cells == 4 {
        (u.x >= 0.5) as usize + 2 * (u.y >= 0.5) as usize
    } else {
        0
    }
}

/// The frame tangent a receiver with shading normal `n` compares its
/// neighbours' with: none with one cell (every compatible neighbour lends).
#[inline]
fn cell_tangent(cells: usize, n: Vec3) -> Option<Vec3> {
    (cells > 1).then(|| Frame::from_normal(n).tangent)
}

/// Whether a neighbour with shading normal `b` has cells that see the same
/// directions as those of the receiver with `tangent` ([`cell_tangent`]):
/// their frames' tangents within [`CELL_AGREEMENT`]. (The frame of
/// [`Frame::from_normal`] turns by half a turn where a normal's z changes
/// sign.)
#[inline]
fn cells_agree(tangent: Option<Vec3>, b: Vec3) -> bool {
    tangent.is_none_or(|t| t.dot(Frame::from_normal(b).tangent) >= CELL_AGREEMENT)
}

/// Frame agreement of cells that lend to each other: cos 5 degrees.
/// Measured on Sponza 1024 (cells 4, quality 256, 2048-ray reference): AO
/// RMSE 0.0082 at 25 degrees (contact texels' L2 SH RMSE 0.0042, against
/// 0.0023 with one cell: a cell of a turned frame sees other directions),
/// 0.0075 at 5 degrees, 0.0077 at 2.
const CELL_AGREEMENT: f32 = 0.996;

/// Filter sigma in world units for an occluder depth bound: z_min / (2 mu
/// Omega_h); infinite for no occluder, 0 for contact or NaN.
#[inline]
pub fn filter_sigma(z_min: f32, mu: f32, omega_h: f32) -> f32 {
    let s = z_min / (2.0 * mu * omega_h);
    if s.is_nan() || s <= 0.0 { 0.0 } else { s }
}

/// Filter sigma in texels of a receiver with footprint `fp` for `z_min`:
/// [`filter_sigma`] over the footprint, at most `max_reach / 2`; 0 (not
/// filtered) below half a texel or inside geometry.
#[inline]
pub fn sigma_in_texels(z_min: f32, fp: f32, inside: bool, o: &AdaptiveOptions) -> f32 {
    let s = filter_sigma(z_min, o.mu, o.omega_h);
    // A texel size -> 0 filters as wide as allowed; a NaN one not at all.
    let t = if fp > 0.0 {
        s / fp
    } else if fp == 0.0 {
        f32::INFINITY
    } else {
        0.0
    };
    let t = t.min(o.max_reach as f32 / 2.0);
    if t.is_nan() || t < 0.5 || inside {
        0.0
    } else {
        t
    }
}

/// The occluder depth at which a receiver of footprint `fp` reaches its
/// widest filter ([`sigma_in_texels`] at `max_reach / 2`): z_min beyond it
/// changes nothing.
#[inline]
pub fn saturating_depth(fp: f32, o: &AdaptiveOptions) -> f32 {
    fp * o.max_reach as f32 * o.mu * o.omega_h
}

/// Twice the largest [`saturating_depth`] of the atlas's footprints (one
/// value for all, so z_min values cut at it compare equal); `max_distance`
/// when that is not positive and finite (no filter, or no footprint).
pub fn exact_depth(footprint: &[f32], o: &AdaptiveOptions, max_distance: f32) -> f32 {
    let fp = footprint
        .iter()
        .copied()
        .filter(|f| f.is_finite())
        .fold(0.0f32, f32::max);
    let d = 2.0 * saturating_depth(fp, o);
    if d > 0.0 && d.is_finite() {
        d.min(max_distance)
    } else {
        max_distance
    }
}

/// The depth below which every receiver of the atlas is in contact
/// ([`sigma_in_texels`] 0 for its footprint, whoever's filter asks): the
/// smallest footprint's contact edge, fp mu Omega_h, less a rounding
/// margin. A z_min below it bounds nothing a nearer one would not: no
/// filter reaches such a receiver or starts from it. 0 when a footprint
/// is 0 (it filters at any depth); footprints that filter at no depth
/// (NaN, negative, infinite) do not count; infinite when none is left or
/// no filter is allowed (`max_reach` 0).
pub fn contact_depth(footprint: &[f32], o: &AdaptiveOptions) -> f32 {
    if (o.max_reach as f32) < 1.0 {
        return f32::INFINITY;
    }
    let fp = footprint
        .iter()
        .copied()
        .filter(|f| f.is_finite() && *f >= 0.0)
        .fold(f32::INFINITY, f32::min);
    fp * o.mu * o.omega_h * (1.0 - 1e-3)
}

/// The standard deviation of one ray's visibility from `visible` of
/// `rays` (smoothed so that all or none visible is not certainty).
#[inline]
pub fn visibility_sd(visible: u32, rays: u32) -> f32 {
    let p = (visible as f32 + 0.5) / (rays as f32 + 1.0);
    (p * (1.0 - p)).sqrt()
}

/// The pre-pass's strata: the `cols` x `rows` grid of the sample square
/// (2^ceil(m/2) x 2^floor(m/2) for `pre_rays` = 2^m) whose every cell holds
/// exactly one of the first `pre_rays` points of a receiver's (Owen
/// scrambled) Sobol sequence, a (0,m,2)-net.
#[derive(Clone, Copy, Debug)]
pub struct Strata {
    pub cols: u32,
    pub rows: u32,
}

/// Pre-pass rays at most (the largest `pre_rays`), in 64-bit words.
pub const STRATA_WORDS: usize = MAX_ADAPTIVE_RAYS as usize / 64;

impl Strata {
    pub fn of(pre_rays: u32) -> Strata {
        let m = exponent_at_most(pre_rays);
        Strata {
            cols: 1 << m.div_ceil(2),
            rows: 1 << (m / 2),
        }
    }

    /// The stratum of a point of the square.
    #[inline]
    pub fn index(&self, u: Vec2) -> usize {
        let x = ((u.x * self.cols as f32) as u32).min(self.cols - 1);
        let y = ((u.y * self.rows as f32) as u32).min(self.rows - 1);
        (y * self.cols + x) as usize
    }

    /// Pairs of strata sharing an edge.
    pub fn pairs(&self) -> u32 {
        (self.cols - 1) * self.rows + self.cols * (self.rows - 1)
    }

    /// The crossings of a straight boundary halving the square: `rows`
    /// along a column, `cols` along a row, their geometric mean (4 of the
    /// 4x4 grid's 24 pairs).
    pub fn halving(&self) -> f32 {
        ((self.cols * self.rows) as f32).sqrt()
    }

    /// Pairs of edge-sharing strata whose rays disagree (one occluded, one
    /// not), from the occluded strata's bits (`occluded[i / 64] >> i % 64`).
    pub fn crossings(&self, occluded: &[u64; STRATA_WORDS]) -> u32 {
        let bit = |i: u32| (occluded[(i / 64) as usize] >> (i % 64)) & 1;
        let mut n = 0;
        for y in 0..self.rows {
            for x in 0..self.cols {
                let i = y * self.cols + x;
                if x + 1 < self.cols {
                    n += (bit(i) ^ bit(i + 1)) as u32;
                }
                if y + 1 < self.rows {
                    n += (bit(i) ^ bit(i + self.cols)) as u32;
                }
            }
        }
        n
    }
}

/// The one-ray variance of a stratified estimate of a receiver's
/// visibility, from how many of its pre-pass strata pairs the visibility
/// boundary crosses: stratified sampling's error comes from the strata a
/// boundary cuts (about its length times sqrt(rays), each adding at most
/// 1/4), not from the visible share p alone, so a half-occluded receiver
/// beside a straight wall is quieter than one under a lattice with the
/// same p. Scaled so that a straight boundary halving the square
/// ([`Strata::halving`]) is p(1 - p) at 1/2, for any grid; half a crossing
/// added, so a receiver whose rays all agree keeps the variance of an
/// unseen boundary. No grid (one ray): 1/4.
#[inline]
pub fn boundary_variance(crossings: u32, strata: Strata) -> f32 {
    let pairs = strata.pairs();
    if pairs == 0 {
        return 0.25;
    }
    // (crossings + 1/2) / (halving + 1/2) / 4, as a share of the pairs.
    let scale = 0.25 * pairs as f32 / (strata.halving() + 0.5);
    (crossings as f32 + 0.5) / pairs as f32 * scale
}

/// The spread that sets a receiver's ray count: the geometric mean of the
/// binomial sd of its visible share ([`visibility_sd`]) and the sd its
/// strata's boundary crossings predict ([`boundary_variance`]).
///
/// Measured on Sponza 1024 (an oracle allocation of continuous counts at
/// equal total rays, per texel, 256-ray Monte Carlo's error against a
/// 2048-ray reference): within one band of visible share (8-11 of 16),
/// the squared error grows 4x from 0-2 to 9-11 crossings, which the
/// binomial sd cannot see; counts from the crossings alone lower the AO
/// RMSE 0.00626 -> 0.00610 and the p99 0.01965 -> 0.01879. In the method
/// (quality 256, 2048-ray reference, five scenes at 1024 and Sponza at
/// 512), the crossings alone save 2-6% of the rays but fail the curtains'
/// p99 (0.02197 against Monte Carlo's 0.02148: a receiver whose 16 rays
/// happen to agree is sent too few); the geometric mean holds every
/// metric on all five (curtains p99 0.02148, equal) for 1-4% fewer rays
/// than the binomial sd.
#[inline]
pub fn stratified_sd(visible: u32, rays: u32, crossings: u32, strata: Strata) -> f32 {
    (boundary_variance(crossings, strata).sqrt() * visibility_sd(visible, rays)).sqrt()
}

/// The exponent of the power of two nearest `2^log2_n` in log scale,
/// within [lo, hi] (exponents): a ray count of `2^ray_exponent(..)`. NaN
/// and -inf (no demand) give `lo`.
#[inline]
pub fn ray_exponent(log2_n: f32, lo: u32, hi: u32) -> u32 {
    let e = log2_n.round();
    if e >= lo as f32 {
        (e as u32).min(hi)
    } else {
        lo
    }
}

/// How a receiver's error falls with its ray count: the variance of a
/// stratified estimate goes as rays^-ALPHA. Measured on Monte Carlo's own
/// curve (AO RMSE at 64, 128 and 256 rays: 1.62-1.64x lower per doubling on
/// the Cornell box and about 1.6-1.7x on Sponza at 1024, so RMSE ~
/// rays^-0.7).
pub const ALPHA: f64 = 1.4;

/// How much lower than `quality`-ray Monte Carlo's the predicted variance
/// of an unfiltered receiver is aimed. The prediction leaves out the noise
/// of the pre-pass's spread estimate and the receivers whose neighbourhood
/// saw nothing; measured without a margin, `quality` 256 landed at 1.15x
/// 256-ray Monte Carlo's AO RMSE on the Cornell box and 1.23x on Sponza
/// (1024 texels, 2048-ray reference). Measured on five scenes at 1024
/// (Sponza also at 512), quality 256, 2048-ray reference, with the exact
/// share below the plane ([`below_compensated`]) and lenders within
/// [`LENDER_NORMAL_AGREEMENT`]: with the filtered margin at 2.0, 1.2 holds
/// every metric of Monte Carlo's on all of them (Sponza 512's p99 equal,
/// the others 1-15% under); 1.0 (with 2.1) fails Sponza's p99 at both
/// sizes (0.0216 against 0.0205 at 1024) and the engine's AO and L1. Where
/// the filter removes most of the variance, Monte Carlo's error budget
/// moves to the unfiltered receivers, whose noise is where the p99 tail
/// lies (Sponza 512: 53% contact texels carry 0.93 of the 1% above Monte
/// Carlo's p99); this margin keeps them at Monte Carlo's noise. It is
/// reached where the filter removes [`MOVED_FOR_FULL_MARGIN`] of the
/// atlas's Monte Carlo variance ([`unfiltered_margin`]).
pub const UNFILTERED_MARGIN: f64 = 1.2;

/// The share of the atlas's predicted Monte Carlo variance the filter
/// removes (the error budget that moves to the unfiltered receivers) at
/// which the unfiltered receivers get all of [`UNFILTERED_MARGIN`]; below
/// it they get that share of it. Measured (quality 256, 2048-ray
/// reference; the share in parentheses): Sponza 512 (0.21) fails its p99
/// at an unfiltered margin of 1.0, so it needs the whole margin, as do
/// Sponza 1024 (0.56), the engine (0.41) and the Cornell box (0.86); on
/// the curtains (0.04: 93% of texels unfiltered, the budget barely moves)
/// every metric holds at 1.0 and the margin only added rays (280 per
/// texel against 242).
pub const MOVED_FOR_FULL_MARGIN: f64 = 0.2;

/// The unfiltered receivers' margin when the filter removes the share
/// `moved` of the atlas's predicted variance: 1 (Monte Carlo's variance)
/// plus [`UNFILTERED_MARGIN`]'s excess in proportion to `moved` up to
/// [`MOVED_FOR_FULL_MARGIN`]. NaN counts as nothing moved.
#[inline]
pub fn unfiltered_margin(moved: f64) -> f64 {
    let t = (moved / MOVED_FOR_FULL_MARGIN).clamp(0.0, 1.0);
    let t = if t.is_nan() { 0.0 } else { t };
    1.0 + (UNFILTERED_MARGIN - 1.0) * t
}

/// The margin of a receiver whose filter averages many receivers: the
/// filter's width is set by the clamped cosine's bandlimit (Omega_h), the
/// L2 band's basis functions vary faster over the hemisphere, so the
/// filter leaves more of the L2 band's error than N_eff predicts (Cornell
/// 1024, quality 256, margins 1.5 / 1.5: L2 RMSE 0.00127 against Monte
/// Carlo's 0.00120 while AO is 0.00387 against 0.00400; the widely filtered
/// texels' L2 / AO error ratio 0.34 against Monte Carlo's 0.30). With the
/// unfiltered margin at 1.2: 1.8 leaves the Cornell box's L2 at 0.00121
/// (over), 2.0 at 0.00114, for 4% more rays there.
pub const FILTERED_MARGIN: f64 = 2.0;

/// A receiver's margin from the share of its variance its filter removes
/// (1 - 1/N_eff: 0 unfiltered, near 1 filtered wide): the unfiltered
/// margin (`unfiltered`, from [`unfiltered_margin`]) blended linearly
/// towards the filtered one.
#[inline]
pub fn model_margin(filtered: f32, unfiltered: f32, unfiltered_margin: f64) -> f64 {
    let removed = 1.0 - filtered as f64 / unfiltered as f64;
    // A NaN share (no variance) counts as unfiltered.
    let removed = if removed.is_nan() {
        0.0
    } else {
        removed.clamp(0.0, 1.0)
    };
    unfiltered_margin + (FILTERED_MARGIN - unfiltered_margin) * removed
}

/// Ray counts for receivers whose one-ray variance is `unfiltered` before
/// the filter and `filtered` after it (sd^2 / n_eff for one cell; the mean
/// over the cells otherwise; 0: pre-pass only). Counts are
/// power_of_two(scale x sqrt(margin) sd / sqrt(n_eff)) ([`ray_exponent`]; the allocation
/// that minimizes the summed variance margin sd^2 / (rays^ALPHA n_eff) for
/// a given number of rays; margin: [`model_margin`]), with the scale found
/// by bisection: the smallest whose predicted mean variance is at most
/// `quality`-ray Monte Carlo's, mean sd^2 / quality^ALPHA, or with
/// `mean_rays` set, whose mean count reaches it.
pub fn allocate_variances(filtered: &[f32], unfiltered: &[f32], o: &AdaptiveOptions) -> Vec<u32> {
    // The predicted variance, and the share of it the filter removes.
    let total: f64 = unfiltered.iter().map(|&v| v as f64).sum();
    let kept: f64 = filtered.iter().map(|&v| v as f64).sum();
    let margin = unfiltered_margin(1.0 - kept / total);
    // Per receiver: demand sd / sqrt(n_eff) and variance share sd^2 / n_eff,
    // both of the variance raised by the receiver's model margin.
    let terms: Vec<(f32, f64)> = filtered
        .iter()
        .zip(unfiltered)
        .map(|(&v, &u)| {
            if v > 0.0 {
                let v = v as f64 * model_margin(v, u, margin);
                (v.sqrt() as f32, v)
            } else {
                (0.0, 0.0)
            }
        })
        .collect();
    // Counts in log2: a receiver's count at scale s is the power of two
    // nearest s d in log scale, 2^round(log2 s + log2 d) within the bounds,
    // so the bisection below reads each log2 d once.
    let (lo_exp, hi_exp) = (exponent_at_least(o.pre_rays), exponent_at_most(o.max_rays));
    let log_demand: Vec<f32> = terms.iter().map(|&(d, _)| d.log2()).collect();
    let exponent = |log_scale: f32, l: f32| ray_exponent(log_scale + l, lo_exp, hi_exp);
    // k^-ALPHA for every power of two k.
    let inv_pow: [f64; 32] = std::array::from_fn(|e| (2f64.powi(e as i32)).powf(-ALPHA));
    let goal: f64 = if o.mean_rays > 0 {
        o.mean_rays as f64 * terms.len() as f64
    } else {
        let q = (o.quality as f64).powf(-ALPHA);
        // At least what one pre-pass of an open receiver could tell per
        // receiver: a scene that looks quieter everywhere (an open plane,
        // whose receivers' variance is what all of its neighbourhood's
        // rays seeing nothing allow) stops at the pre-pass instead of
        // chasing its own tiny variance.
        let counted = unfiltered.iter().filter(|&&v| v > 0.0).count() as f64;
        let floor = counted * nothing_seen_variance(o.pre_rays, 1.0) as f64;
        total.max(floor) * q
    };
    // Whether the counts at `scale` fall short of the goal: fewer rays than
    // the mean asks, or more predicted variance than the quality allows.
    let short = |log_scale: f32| -> bool {
        let (rays, variance) = terms
            .par_iter()
            .zip(&log_demand)
            .with_min_len(4096)
            .map(|(&(_, v), &l)| {
                let e = exponent(log_scale, l);
                ((1u64 << e) as f64, v * inv_pow[e as usize])
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        if o.mean_rays > 0 {
            rays < goal
        } else {
            variance > goal
        }
    };
    // Bisection on log2 of the scale, between one where every receiver
    // gets the fewest rays and one where every receiver gets the most,
    // to f32's resolution.
    let (l_min, l_max) = log_demand
        .iter()
        .filter(|l| l.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &l| {
            (a.min(l), b.max(l))
        });
    if l_min > l_max {
        // No receiver asks for more than the pre-pass.
        return vec![o.pre_rays; terms.len()];
    }
    let (mut lo, mut hi) = (lo_exp as f32 - 1.0 - l_max, hi_exp as f32 + 1.0 - l_min);
    loop {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if short(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let log_scale = hi;
    log_demand
        .iter()
        .map(|&l| 1 << exponent(log_scale, l))
        .collect()
}

/// The exponent of the smallest power of two at least `n` (n >= 1).
fn exponent_at_least(n: u32) -> u32 {
    n.max(1).next_power_of_two().trailing_zeros()
}

/// The exponent of the largest power of two at most `n` (n >= 1).
fn exponent_at_most(n: u32) -> u32 {
    31 - n.max(1).leading_zeros()
}

/// Receivers per parallel work item.
const CHUNK: usize = 64;

/// Least reach, in texels, of the neighbourhood whose visibility spread
/// sets a receiver's ray count (16 pre-pass rays of one texel are too few).
const SD_REACH: u32 = 2;

/// Normal agreement of the z_min spread (cos 25 degrees, the leak rule's).
const SPREAD_AGREEMENT: f32 = 0.906;

/// The adaptive bake (see the module doc). `fill_inside`: find the
/// receivers inside geometry ([`super::validity`], from the pre-pass's
/// rays; they get the pre-pass only and neither lend nor receive in the
/// filter), returned in [`AdaptiveStats::inside`]. Options validated.
/// Laps: `pre-pass`, `bounds`, `adaptive pass`, `filter`.
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    fill_inside: bool,
    o: &AdaptiveOptions,
    p: &BakeParams,
    timer: &mut StageTimer,
    progress: &(dyn Fn(u64) + Sync),
) -> (Bake, AdaptiveStats) {
    let n = receivers.len();
    let cells = o.cells as usize;
    // 1. Pre-pass. Per receiver and cell (receiver-major): running sums and
    // own z_min.
    // Its closest hits' faces also tell which receivers lie inside
    // geometry: the validity stage's test on the same rays (the bake's
    // sequence), so the adaptive method needs no stage of its own for it.
    // Rays outside that test ask only for the distances z_min can use:
    // below the cell's running z_min and below the depth where every
    // receiver's filter is at its widest ([`exact_depth`]); deeper, a hit
    // is only a hit. Below the depth where every receiver is in contact
    // ([`contact_depth`]) a cell's z_min bounds nothing a nearer one would
    // not, so its further rays ask only for any hit. Same bounds and sums
    // as full closest-hit queries (byte-identical output; own z_min of
    // contact cells may stay above their nearest hit, below the contact
    // depth). Measured on the curtains at 1024: pre-pass 1.48 -> 1.34 s
    // with the depth, 1.31 -> 1.03 s with the contact depth and the
    // receivers' world order ([`crate::atlas::order`]), where 16-ray Monte
    // Carlo's trace takes 0.91 s.
    let mut sums = vec![CellSums::default(); n * cells];
    let mut own_z = vec![f32::INFINITY; n * cells];
    let mut inside_found = vec![false; n];
    let mut crossings = vec![0u16; n];
    let strata = Strata::of(o.pre_rays);
    let exact = exact_depth(&receivers.footprint, o, p.max_distance);
    let contact = contact_depth(&receivers.footprint, o);
    // Without single-sided triangles no receiver is inside: no face to test.
    let test_faces = fill_inside && tracer.has_single_sided();
    sums.par_chunks_mut(CHUNK * cells)
        .zip(own_z.par_chunks_mut(CHUNK * cells))
        .zip(inside_found.par_chunks_mut(CHUNK))
        .zip(crossings.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, (((sums, zs), inside), crossings))| {
            for (k, (inside, crossings)) in inside.iter_mut().zip(crossings).enumerate() {
                let r = c * CHUNK + k;
                let rays = ReceiverRays::new(receivers, r, p.seed);
                let mut faces = BackFaces::default();
                let mut occluded = [0u64; STRATA_WORDS];
                for i in 0..o.pre_rays {
                    let u = rays.point(i);
                    let cell = k * cells + cell_of_point(u, cells);
                    let (s, z) = (&mut sums[cell], &mut zs[cell]);
                    let d = rays.direction_of(u);
                    let stratum = strata.index(u);
                    sh::accumulate(&mut s.all, 1.0, d);
                    if d.dot(rays.geo_normal) <= 0.0 {
                        // Below the surface: occluded, by nothing at a depth.
                        s.below += 1;
                        sh::accumulate(&mut s.sh, 1.0, d);
                        occluded[stratum / 64] |= 1 << (stratum % 64);
                        continue;
                    }
                    // The validity test needs the closest hit's face; z_min
                    // only distances below the running z_min and `exact`.
                    let hit = if test_faces && faces.counts(i) {
                        let hit = tracer.closest_hit_side(rays.origin, d, p.max_distance);
                        faces.add(matches!(hit, Some((_, true))));
                        hit.map(|(t, _)| t)
                    } else if *z < contact {
                        // In contact already: a nearer hit bounds nothing
                        // more, so any hit will do.
                        tracer
                            .occluded(rays.origin, d, p.max_distance)
                            .then_some(*z)
                    } else {
                        tracer.hit_depth_within(rays.origin, d, p.max_distance, z.min(exact))
                    };
                    match hit {
                        Some(t) => {
                            *z = z.min(t);
                            sh::accumulate(&mut s.sh, 1.0, d);
                            occluded[stratum / 64] |= 1 << (stratum % 64);
                        }
                        None => s.visible += 1,
                    }
                }
                *crossings = strata.crossings(&occluded).min(u16::MAX as u32) as u16;
                *inside = test_faces
                    && validity::finish_inside(&rays, tracer, p.max_distance, o.pre_rays, faces);
            }
        });
    let inside = &inside_found[..];
    timer.lap("pre-pass");
    // The world-space neighbourhood across chart borders (one cell: a
    // receiver's own z_min is its cell's). Without a tree (it cannot be
    // built), the filter stays on the atlas grid.
    let tree = (cells == 1 && o.cross_charts && o.max_reach > 0)
        .then(|| position_tree(receivers).ok())
        .flatten();

    // 2. Bounds, per cell.
    let grid = TexelGrid::new(receivers);
    // The bounds' working arrays end with this block (the memory estimate
    // counts its outputs only).
    let (z_min, sigma_texels, target) = {
        let width = |z: f32, r: usize| sigma_in_texels(z, receivers.footprint[r], inside[r], o);
        // A receiver's filter support for its own z_min: 2 sigma, all of
        // max_reach when it saw nothing.
        let support_of = |z: f32, r: usize| {
            if z.is_infinite() {
                o.max_reach
            } else {
                (2.0 * width(z, r)).ceil() as u32
            }
        };
        let mut z_min: Vec<Vec<f32>> = Vec::with_capacity(cells);
        let mut sigma_texels: Vec<Vec<f32>> = Vec::with_capacity(cells);
        // Per receiver, sum over its cells of sd^2 / n_eff and of sd^2: how
        // much of its variance the filter leaves.
        let mut left = vec![(0.0f32, 0.0f32); n];
        // Per receiver, whether any cell's neighbourhood saw an occluder.
        let mut seen = vec![false; n];
        let cell_rays = o.pre_rays / o.cells;
        for cell in 0..cells {
            let own: Vec<f32> = (0..n).map(|r| own_z[r * cells + cell]).collect();
            // z_min spread over each receiver's own support (2 sigma of its
            // own z_min, all of max_reach when it saw nothing): a receiver is
            // filtered no wider than the nearest occluder any texel under its
            // filter saw.
            let support: Vec<u32> = (0..n).map(|r| support_of(own[r], r)).collect();
            let z = spread_min(receivers, &grid, inside, cells, &own, &support);
            // The filter: the widest whose support's own z_min allow it.
            let (mut z_filter, sigma) =
                widest_filters(receivers, &grid, inside, cells, &own, o, width);
            drop(own);
            // Unfiltered: the spread z_min, as the allocation reads it.
            for ((zf, &s), &z) in z_filter.iter_mut().zip(&sigma).zip(&z) {
                if s <= 0.0 {
                    *zf = z;
                }
            }
            // 3. Ray counts, from the neighbourhood's visibility spread rather
            // than the receiver's own, so a count does not depend on the
            // receiver's own first rays. Measured: no change on the floor
            // beside a wall (beyond 0.35, AO bias -0.0046 with its own sd,
            // -0.0049 with the neighbourhood's, within that band's noise).
            // One cell: the spread of a stratified estimate, from the
            // visible share and the strata's crossings ([`stratified_sd`]);
            // more cells (whose 4 rays each make no grid): the binomial sd.
            let own_sd: Vec<f32> = (0..n)
                .map(|r| {
                    let visible = sums[r * cells + cell].visible;
                    if cells == 1 {
                        stratified_sd(visible, cell_rays, crossings[r] as u32, strata)
                    } else {
                        visibility_sd(visible, cell_rays)
                    }
                })
                .collect();
            let sd_reach: Vec<u32> = support.iter().map(|&s| s.max(SD_REACH)).collect();
            let sd = neighbourhood_mean(receivers, &grid, inside, cells, &own_sd, &sd_reach);
            let n_eff = FilterSupport {
                receivers,
                grid: &grid,
                inside,
                cells,
                sigma_texels: &sigma,
                z_min: &z_filter,
                world: World::of(tree.as_ref(), &own_z),
            }
            .effective_neighbours();
            // A cell whose neighbourhood saw nothing: the variance that
            // all of the neighbourhood's rays (cell_rays per receiver)
            // seeing nothing still allows, not none (its own 16 rays
            // seeing nothing leave a 1-in-10 occluder unseen).
            let seen_nothing = (0..n).any(|r| z[r].is_infinite());
            let count = if seen_nothing {
                neighbourhood_count(receivers, &grid, inside, cells, &sd_reach)
            } else {
                Vec::new()
            };
            for r in 0..n {
                let v = if z[r].is_infinite() {
                    nothing_seen_variance(cell_rays, count[r])
                } else {
                    sd[r] * sd[r]
                };
                left[r].0 += v / n_eff[r].max(1.0);
                left[r].1 += v;
                seen[r] |= z[r].is_finite();
            }
            z_min.push(z_filter);
            sigma_texels.push(sigma);
        }
        // The receiver's variance from its whole pre-pass (its cells' 4-ray
        // spreads are too coarse to add up: smoothed, a fully occluded cell
        // looks as noisy as a half-occluded one), times the share the cells'
        // filters leave; when no cell's neighbourhood saw anything, the
        // variance all of its rays allow. Receivers inside geometry: the
        // pre-pass only.
        let (unfiltered, filtered): (Vec<f32>, Vec<f32>) = if cells == 1 {
            left.iter()
                .enumerate()
                .map(|(r, &(f, u))| if inside[r] { (0.0, 0.0) } else { (u, f) })
                .unzip()
        } else {
            let own_sd: Vec<f32> = (0..n)
                .map(|r| {
                    let visible = (0..cells).map(|c| sums[r * cells + c].visible).sum();
                    visibility_sd(visible, o.pre_rays)
                })
                .collect();
            let reach: Vec<u32> = (0..n)
                .map(|r| {
                    let z = (0..cells)
                        .map(|c| own_z[r * cells + c])
                        .fold(f32::INFINITY, f32::min);
                    // (Nothing seen: max_reach, not raised to SD_REACH as
                    // the one-cell path raises it.)
                    let support = support_of(z, r);
                    if z.is_infinite() {
                        support
                    } else {
                        support.max(SD_REACH)
                    }
                })
                .collect();
            let sd = neighbourhood_mean(receivers, &grid, inside, 1, &own_sd, &reach);
            // Only where some receiver saw nothing (as with one cell).
            let count = if seen.iter().all(|&s| s) {
                Vec::new()
            } else {
                neighbourhood_count(receivers, &grid, inside, 1, &reach)
            };
            (0..n)
                .map(|r| {
                    let (f, u) = left[r];
                    let v = if seen[r] {
                        sd[r] * sd[r]
                    } else {
                        nothing_seen_variance(o.pre_rays, count[r])
                    };
                    if inside[r] || u <= 0.0 {
                        (0.0, 0.0)
                    } else {
                        (v, v * f / u)
                    }
                })
                .unzip()
        };
        drop(left);
        drop(crossings);
        let target = allocate_variances(&filtered, &unfiltered, o);
        (z_min, sigma_texels, target)
    };
    // Kept for the world-space filter only.
    let own_z = if tree.is_some() { own_z } else { Vec::new() };
    timer.lap("bounds");

    // The second batch: the sequence continued to each receiver's count.
    let rays: Vec<u32> = target.iter().map(|&t| t.max(o.pre_rays)).collect();
    drop(target);
    // Receivers whose sums leave out the rays below the geometric plane
    // (counted only; see [`below_compensated`]): the filtered ones.
    let above_only = |r: usize| cells == 1 && sigma_texels[0][r] > 0.0;
    sums.par_chunks_mut(CHUNK * cells)
        .enumerate()
        .for_each(|(c, sums)| {
            for k in 0..sums.len() / cells {
                let r = c * CHUNK + k;
                let ray = ReceiverRays::new(receivers, r, p.seed);
                let above_only = above_only(r);
                // (`below` counts the pre-pass's rays below so far: none,
                // nothing to take out.)
                if above_only && sums[k].below > 0 {
                    // The pre-pass summed its rays below into both sums.
                    let s = &mut sums[k];
                    for i in 0..o.pre_rays {
                        let d = ray.direction(i);
                        if d.dot(ray.geo_normal) <= 0.0 {
                            sh::accumulate(&mut s.sh, -1.0, d);
                            sh::accumulate(&mut s.all, -1.0, d);
                        }
                    }
                }
                for i in o.pre_rays..rays[r] {
                    let u = ray.point(i);
                    let s = &mut sums[k * cells + cell_of_point(u, cells)];
                    let d = ray.direction_of(u);
                    // Below the surface: occluded without tracing
                    // ([`Tracer::receiver_visible`]'s test, made here
                    // because a filtered receiver only counts those).
                    let below = d.dot(ray.geo_normal) <= 0.0;
                    if below {
                        s.below += 1;
                        if above_only {
                            continue;
                        }
                    }
                    sh::accumulate(&mut s.all, 1.0, d);
                    if below || tracer.occluded(ray.origin, d, p.max_distance) {
                        sh::accumulate(&mut s.sh, 1.0, d);
                    } else {
                        s.visible += 1;
                    }
                }
            }
            progress((sums.len() / cells) as u64);
        });
    timer.lap("adaptive pass");

    // 4. Filter, each cell on its own bounds; the AO and SH are the sums
    // of the cells' filtered shares. Equal weight per receiver: weighting
    // by ray count (inverse variance) biases dark, because the allocation
    // sends more rays to occluded receivers (Cornell 512, adaptive:64: AO
    // bias -0.0021 with it).
    let mut ao = Vec::new();
    let mut sh: Vec<[f32; SH_COUNT]> = Vec::new();
    for cell in 0..cells {
        // The cell's share of the AO and of the occluded rays' SH (less).
        let values: Vec<[f32; 10]> = (0..n)
            .into_par_iter()
            .with_min_len(1024)
            .map(|r| {
                let s = &sums[r * cells + cell];
                if cells == 1 {
                    return below_compensated(
                        s,
                        rays[r],
                        receivers.normal[r],
                        receivers.geo_normal[r],
                        above_only(r),
                    );
                }
                // A cell's share of the open projection is not known: the
                // occluded rays' share alone (control variate weight 0).
                let inv = 1.0 / rays[r] as f32;
                let mut v = [0.0f32; 10];
                v[0] = s.visible as f32 * inv;
                let open = sh::open_hemisphere(receivers.normal[r]);
                let share = sh::occluded_share(&open, &s.sh, &s.all, inv, 1.0);
                v[1..].copy_from_slice(&share);
                v
            })
            .collect();
        if cell + 1 == cells {
            sums = Vec::new();
        }
        let (cell_ao, cell_sh) = FilterSupport {
            receivers,
            grid: &grid,
            inside,
            cells,
            sigma_texels: &sigma_texels[cell],
            z_min: &z_min[cell],
            world: World::of(tree.as_ref(), &own_z),
        }
        .filter(values);
        if cell == 0 {
            (ao, sh) = (cell_ao, cell_sh);
        } else {
            ao.par_iter_mut()
                .zip(&mut sh)
                .zip(cell_ao.par_iter().zip(&cell_sh))
                .for_each(|((a, s), (ca, cs))| {
                    *a += ca;
                    for (s, c) in s.iter_mut().zip(cs) {
                        *s += c;
                    }
                });
        }
    }
    drop(sums);
    drop(grid);
    // The open hemisphere's exact projection for the receiver's own normal
    // (sh::open_hemisphere), added after the filter: filtering it with the
    // occluded share mixed the neighbours' normals into the L1 band on
    // curved surfaces (Sponza 1024, quality 256: L1 RMSE 0.0026 against
    // 256-ray Monte Carlo's 0.0019, and 0.0023 still at quality 512). So
    // is, less, the exact share below the receiver's own geometric plane
    // (one cell; see [`below_compensated`]).
    ao.par_iter_mut()
        .zip(&mut sh)
        .enumerate()
        .for_each(|(r, (a, s))| {
            let normal = receivers.normal[r];
            let (below, below_sh) = if cells == 1 {
                let geo = receivers.geo_normal[r];
                (below_fraction(normal, geo), sh::below_plane(normal, geo))
            } else {
                (0.0, [0.0; SH_COUNT])
            };
            *a = (*a - below).clamp(0.0, 1.0);
            for ((s, o), b) in s.iter_mut().zip(sh::open_hemisphere(normal)).zip(below_sh) {
                *s += o - b;
            }
        });
    timer.lap("filter");

    let pre_rays = n as u64 * o.pre_rays as u64;
    let total: u64 = rays.iter().map(|&r| r as u64).sum();
    let bake = Bake {
        ao,
        sh,
        rays: total,
    };
    // Per receiver, its nearest cell's bounds.
    let (z_min, sigma_texels) = if cells == 1 {
        let mut z = z_min;
        let mut s = sigma_texels;
        (z.remove(0), s.remove(0))
    } else {
        (0..n)
            .map(|r| {
                let c = (0..cells)
                    .min_by(|&a, &b| z_min[a][r].total_cmp(&z_min[b][r]))
                    .unwrap_or(0);
                (z_min[c][r], sigma_texels[c][r])
            })
            .unzip()
    };
    let stats = AdaptiveStats {
        pre_rays,
        adaptive_rays: total - pre_rays,
        rays,
        z_min,
        sigma_texels,
        inside: inside_found,
    };
    (bake, stats)
}

/// The 10 values (AO, then the occluded share of the 9 SH, less) that one
/// receiver lends the filter: estimates of the occlusion above its
/// geometric plane, plus the exact share below it (AO
/// [`below_fraction`] b, SH [`sh::below_plane`] L), which the bake
/// subtracts again per receiver after the filter. Filtering the whole
/// occlusion mixed the neighbours' shares below their planes, which
/// differ on a curved surface with shading normals (and a 16-ray receiver
/// keeps the sampling error of its rays below); measured at 1024, quality
/// 256, AO RMSE per texel class: the wide filters' 0.0099 -> 0.0061 on the
/// curtains.
///
/// `above_only` (a filtered receiver): `s` holds the rays above the plane
/// only and `s.below` counts the others; the estimate is the exact share
/// below plus (1 - b) times the above rays' (its rays below tell nothing
/// then: none of their sampling error is left). Otherwise (an unfiltered
/// receiver, whose value the filter returns as it is) the usual estimate
/// of all of its rays ([`sh::occluded_share`]) plus (b, L): its own value
/// after the bake subtracts them again. (The exact share as a control
/// variate there measured worse: in contact the rays below and the hits
/// above are one occluded region, and subtracting the exact share from an
/// AO near 0 then clamping biased it bright: curtains, 256-ray Monte
/// Carlo, AO RMSE 0.00715 -> 0.00745, bias +0.0004.)
fn below_compensated(s: &CellSums, rays: u32, n: Vec3, geo: Vec3, above_only: bool) -> [f32; 10] {
    let b = below_fraction(n, geo);
    let below_sh = sh::below_plane(n, geo);
    let open = sh::open_hemisphere(n);
    let mut v = [0.0f32; 10];
    if above_only {
        let above = rays.saturating_sub(s.below);
        // Per above ray, its share of the hemisphere's 1 - b; the visible
        // fraction of the above rays (1 when there are none).
        let (per_ray, visible) = if above > 0 {
            ((1.0 - b) / above as f32, s.visible as f32 / above as f32)
        } else {
            (0.0, 1.0)
        };
        let open_above: [f32; SH_COUNT] = std::array::from_fn(|i| open[i] - below_sh[i]);
        let hits = above - s.visible.min(above);
        v[0] = 1.0 - hits as f32 * per_ray;
        let share = sh::occluded_share(&open_above, &s.sh, &s.all, per_ray, visible);
        v[1..].copy_from_slice(&share);
    } else {
        let inv = 1.0 / rays.max(1) as f32;
        v[0] = s.visible as f32 * inv + b;
        let share = sh::occluded_share(&open, &s.sh, &s.all, inv, s.visible as f32 * inv);
        for ((v, s), b) in v[1..].iter_mut().zip(share).zip(below_sh) {
            *v = s + b;
        }
    }
    v
}

/// Receiver index of each atlas texel.
struct TexelGrid {
    width: usize,
    height: usize,
    receiver: Vec<u32>,
}

const NO_RECEIVER: u32 = u32::MAX;

impl TexelGrid {
    fn new(receivers: &Receivers) -> TexelGrid {
        let (width, height) = (receivers.width as usize, receivers.height as usize);
        let mut receiver = vec![NO_RECEIVER; width * height];
        for (r, &t) in receivers.texel.iter().enumerate() {
            receiver[t as usize] = r as u32;
        }
        TexelGrid {
            width,
            height,
            receiver,
        }
    }

    /// The receiver `k` texels (signed) from receiver `r`'s texel along a
    /// row (`vertical` false) or a column, if any.
    #[inline]
    fn offset(&self, receivers: &Receivers, r: usize, k: isize, vertical: bool) -> Option<usize> {
        let t = receivers.texel[r] as usize;
        let (x, y) = ((t % self.width) as isize, (t / self.width) as isize);
        let (x, y) = if vertical { (x, y + k) } else { (x + k, y) };
        if x < 0 || y < 0 || x >= self.width as isize || y >= self.height as isize {
            return None;
        }
        let j = self.receiver[y as usize * self.width + x as usize];
        (j != NO_RECEIVER).then_some(j as usize)
    }

    /// Receivers within `reach` texels of receiver `r`'s texel along a row
    /// (`vertical` false) or a column, each with its distance in texels.
    #[inline]
    fn line(
        &self,
        receivers: &Receivers,
        r: usize,
        reach: usize,
        vertical: bool,
    ) -> impl Iterator<Item = (usize, usize)> + '_ {
        let t = receivers.texel[r] as usize;
        let (x, y) = (t % self.width, t / self.width);
        let (pos, len) = if vertical {
            (y, self.height)
        } else {
            (x, self.width)
        };
        let lo = pos.saturating_sub(reach);
        let hi = (pos + reach).min(len - 1);
        (lo..=hi).filter_map(move |k| {
            let texel = if vertical {
                k * self.width + x
            } else {
                y * self.width + k
            };
            let j = self.receiver[texel];
            (j != NO_RECEIVER).then_some((j as usize, k.abs_diff(pos)))
        })
    }
}

/// A separable reduction over the compatible (normals within 25 degrees,
/// not inside; with more than one cell, frames agreeing: [`cells_agree`])
/// receivers within `reach` texels, rows then columns: `fold` over the
/// values (the receiver's own included), then `finish` with the count.
#[allow(clippy::too_many_arguments)]
fn separable(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    values: &[f32],
    reach: &[u32],
    fold: impl Fn(f32, f32) -> f32 + Sync,
    init: f32,
    finish: impl Fn(f32, u32) -> f32 + Sync,
) -> Vec<f32> {
    let pass = |src: &[f32], vertical: bool| -> Vec<f32> {
        (0..receivers.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|r| {
                let n = receivers.normal[r];
                let tangent = cell_tangent(cells, n);
                let (acc, count) = grid
                    .line(receivers, r, reach[r] as usize, vertical)
                    .filter(|&(j, _)| spreads_to(receivers, inside, r, n, tangent, j))
                    .fold((init, 0u32), |(a, c), (j, _)| (fold(a, src[j]), c + 1));
                finish(acc, count)
            })
            .collect()
    };
    let rows = pass(values, false);
    pass(&rows, true)
}

/// Each receiver's filter: per reach k = 0..=max_reach texels, the spread
/// z_min m_k (the minimum of the receivers' `own` over the compatible
/// receivers within k texels) allows sigma_k = min(width(m_k), k / 2), a
/// filter that reads only receivers whose own z_min is at least m_k; the
/// widest sigma_k wins (ties: the smaller k, the larger z_min). Returns
/// each receiver's (z_min, sigma in texels), sigma 0 (contact) when no
/// reach allows half a texel. Spreading over the support of the
/// receiver's own z_min instead made an open receiver 3 texels from a
/// contact occluder a contact receiver (sigma of the occluder's z_min),
/// though a 2-texel filter reads only open receivers.
fn widest_filters(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    own: &[f32],
    o: &AdaptiveOptions,
    width: impl Fn(f32, usize) -> f32 + Sync,
) -> (Vec<f32>, Vec<f32>) {
    let n = receivers.len();
    let reach = o.max_reach as usize;
    if reach == 0 {
        return (own.to_vec(), vec![0.0; n]);
    }
    // Every reach in one walk per pass (the minimum within k texels is the
    // running minimum of the offsets up to k): rows, then columns of the
    // rows' minima, as [`spread_min`] at reach k would take them, reading
    // each neighbour once instead of once per k.
    // Per receiver j and reach k: the minimum over its row within k.
    let mut rows = vec![f32::INFINITY; n * reach];
    rows.par_chunks_mut(reach)
        .enumerate()
        .with_min_len(256)
        .for_each(|(r, m)| {
            along_line(receivers, grid, inside, cells, r, reach, false, |j, d| {
                for m in &mut m[d.max(1) - 1..] {
                    *m = m.min(own[j]);
                }
            })
        });
    (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|r| {
            let mut m = [f32::INFINITY; MAX_REACH as usize];
            let m = &mut m[..reach];
            along_line(receivers, grid, inside, cells, r, reach, true, |j, d| {
                // Reaches d and up (the receiver itself: all of them).
                let from = d.max(1) - 1;
                for (m, &row) in m[from..].iter_mut().zip(&rows[j * reach + from..]) {
                    *m = m.min(row);
                }
            });
            let mut best = (own[r], 0.0f32);
            for (k, &z) in (1..).zip(m.iter()) {
                let s = width(z, r).min(k as f32 / 2.0);
                if s >= 0.5 && s > best.1 {
                    best = (z, s);
                }
            }
            best
        })
        .unzip()
}

/// Calls `f(j, d)` for every receiver j at most `reach` texels (d of them)
/// from receiver `r` along its row (`vertical` false) or column that
/// counts in its neighbourhood ([`spreads_to`], as [`separable`] takes
/// them).
#[allow(clippy::too_many_arguments)]
#[inline]
fn along_line(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    r: usize,
    reach: usize,
    vertical: bool,
    mut f: impl FnMut(usize, usize),
) {
    let n = receivers.normal[r];
    let tangent = cell_tangent(cells, n);
    for (j, d) in grid.line(receivers, r, reach, vertical) {
        if spreads_to(receivers, inside, r, n, tangent, j) {
            f(j, d);
        }
    }
}

/// Whether receiver `j` counts in receiver `r`'s neighbourhood (normal
/// `n`, cell tangent `tangent`) for the bounds: itself, or outside
/// geometry with a normal within [`SPREAD_AGREEMENT`] and agreeing cells.
#[inline]
fn spreads_to(
    receivers: &Receivers,
    inside: &[bool],
    r: usize,
    n: Vec3,
    tangent: Option<Vec3>,
    j: usize,
) -> bool {
    let nj = receivers.normal[j];
    j == r || (!inside[j] && nj.dot(n) >= SPREAD_AGREEMENT && cells_agree(tangent, nj))
}

/// The number of compatible receivers within `reach` texels of each
/// receiver (the support of [`neighbourhood_mean`]), its own included.
fn neighbourhood_count(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    reach: &[u32],
) -> Vec<f32> {
    let ones = vec![1.0f32; receivers.len()];
    separable(
        receivers,
        grid,
        inside,
        cells,
        &ones,
        reach,
        |a, v| a + v,
        0.0,
        |s, _| s,
    )
}

/// The one-ray visibility variance a receiver may still have when `count`
/// receivers' `rays` rays each (its neighbourhood's) all saw nothing:
/// [`visibility_sd`] of all of them visible, squared.
#[inline]
pub fn nothing_seen_variance(rays: u32, count: f32) -> f32 {
    // The occluded side's smoothed fraction, without 1 - p's cancellation.
    let q = 0.5 / (rays as f32 * count.max(1.0) + 1.0);
    q * (1.0 - q)
}

/// z_min spread: the minimum of the receivers' own z_min over the
/// compatible receivers within each one's `reach` texels, its own included.
fn spread_min(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    own: &[f32],
    reach: &[u32],
) -> Vec<f32> {
    separable(
        receivers,
        grid,
        inside,
        cells,
        own,
        reach,
        f32::min,
        f32::INFINITY,
        |m, _| m,
    )
}

/// The mean of `values` over the compatible receivers within `reach`
/// texels (rows, then columns of row means).
fn neighbourhood_mean(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    cells: usize,
    values: &[f32],
    reach: &[u32],
) -> Vec<f32> {
    separable(
        receivers,
        grid,
        inside,
        cells,
        values,
        reach,
        |a, v| a + v,
        0.0,
        |s, c| s / c.max(1) as f32,
    )
}

/// What the filter reads: the receivers, their bounds and widths.
#[derive(Clone, Copy)]
struct FilterSupport<'a> {
    receivers: &'a Receivers,
    grid: &'a TexelGrid,
    inside: &'a [bool],
    /// Cells per receiver: with more than one, only receivers whose frames
    /// agree lend.
    cells: usize,
    sigma_texels: &'a [f32],
    z_min: &'a [f32],
    /// Across chart borders: receivers whose filter reaches a missing
    /// texel gather their neighbours in world space instead ([`World`]).
    world: Option<World<'a>>,
}

/// The world-space neighbourhood of the filter across chart borders: the
/// k-d tree of the receivers' positions and each receiver's own z_min (of
/// its pre-pass, before spreading), which decides whether it may lend.
#[derive(Clone, Copy)]
struct World<'a> {
    tree: &'a ImmutableKdTree<f32, 3>,
    own_z: &'a [f32],
}

impl<'a> World<'a> {
    fn of(tree: Option<&'a ImmutableKdTree<f32, 3>>, own_z: &'a [f32]) -> Option<World<'a>> {
        tree.map(|tree| World { tree, own_z })
    }
}

thread_local! {
    /// A worker's lenders of one world-space gather: receiver and offset in
    /// the tangent plane.
    static WORLD_LENDERS: std::cell::RefCell<Vec<(u32, Vec2)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// The share of a receiver's cosine-weighted hemisphere (about shading
/// normal `n`) below its geometric plane (normal `geo`): (1 - n.geo) / 2
/// (the plane cuts the hemisphere's projected unit disc along a half
/// ellipse of semi-axes 1 and n.geo). Those directions are occluded
/// without tracing.
#[inline]
pub fn below_fraction(n: Vec3, geo: Vec3) -> f32 {
    ((1.0 - n.dot(geo)) / 2.0).clamp(0.0, 1.0)
}

/// Most a world-space lender's [`below_fraction`] may differ from the
/// receiver's. Two faces of a bevelled edge can share a shading normal
/// and agree in geometric normal within the leak rule's 25 degrees while
/// a third and a half of their hemispheres lie below them: on Sponza, the
/// filter's worst texels (AO 0.09-0.11 darker) read such faces' texels
/// across the chart border.
pub const BELOW_AGREEMENT: f32 = 0.01;

/// Shading-normal agreement of lenders, on the atlas grid and in world
/// space: cos 10 degrees (the leak rule's 25 let too much through). The
/// filter averages occlusion projected on SH in world axes, so a lender
/// whose normal turns away lends a lobe turned with it: on curved surfaces
/// the L1 band blurs. Measured on the two-cylinder engine at 1024 (quality
/// 256, 2048-ray reference): SH L0/L1/L2 RMSE 0.00169/0.00179/0.00179
/// with the leak rule's 25 degrees (L1 and L2 over 256-ray Monte Carlo's
/// 0.00177/0.00180), 0.00167/0.00168/0.00170 at 10 degrees for 1% more
/// rays, 0.00167/0.00167/0.00169 at 5 for 2% more. Across a
/// chart border (Sponza 1024, quality 256): AO RMSE 0.00633 with the leak
/// rule's alone, 0.00616 at 10 degrees, 0.00614 at 5.
pub const LENDER_NORMAL_AGREEMENT: f32 = 0.985;

/// How far, in texels, from a world-space lender's mirror image through
/// the receiver another lender must lie for both to count: half a texel's
/// diagonal, the most two charts' texel lattices are offset by.
pub const MIRROR_TOLERANCE: f32 = 0.75;

/// The k-d tree of the receivers' positions.
fn position_tree(receivers: &Receivers) -> Result<ImmutableKdTree<f32, 3>> {
    let points: Vec<[f32; 3]> = receivers.position.iter().map(|p| p.to_array()).collect();
    ImmutableKdTree::<f32, 3>::new_from_slice_parallel(&points)
        .map_err(|e| Error::Limit(format!("cannot build the receivers' k-d tree: {e}")))
}

impl FilterSupport<'_> {
    /// The reach in texels of receiver `r`'s filter, if it is filtered.
    #[inline]
    fn reach(&self, r: usize) -> Option<usize> {
        let sigma = self.sigma_texels[r];
        (sigma > 0.0).then(|| ((2.0 * sigma).ceil() as usize).min(MAX_REACH as usize))
    }

    /// Whether receiver `r`'s filter gathers in world space: it is
    /// filtered, a world neighbourhood is given and a texel within its
    /// reach along its row or column has no receiver (a chart border,
    /// where the atlas grid stops and the surface may go on in another
    /// chart).
    #[inline]
    fn crosses_border(&self, r: usize) -> bool {
        let (Some(reach), Some(_)) = (self.reach(r), self.world) else {
            return false;
        };
        (1..=reach as isize).any(|k| {
            [(-k, false), (k, false), (-k, true), (k, true)]
                .iter()
                .any(|&(k, v)| self.grid.offset(self.receivers, r, k, v).is_none())
        })
    }

    /// Whether receiver j, at `rel` from receiver r, may lend to it on
    /// the grid or in world space: not inside geometry, within r's z_min,
    /// through the leak rule and with a shading normal within
    /// [`LENDER_NORMAL_AGREEMENT`].
    #[inline]
    fn lends(&self, r: usize, j: usize, rel: Vec3) -> bool {
        let rc = self.receivers;
        let (n, geo) = (rc.normal[r], rc.geo_normal[r]);
        // (Written as the rejections, so a NaN passes as it did.)
        !(self.inside[j]
            || rel.length() > self.z_min[r]
            || !lends_rays(rel, n, geo, rc.normal[j], rc.geo_normal[j], rc.footprint[r])
            || rc.normal[j].dot(n) < LENDER_NORMAL_AGREEMENT)
    }

    /// Calls `f(j, w)` for each receiver j that lends to receiver `r`
    /// (which [`Self::crosses_border`]) in world space, on any chart: within
    /// its reach (times its footprint) and z_min, not inside geometry,
    /// through the leak rule, with a shading normal within
    /// [`LENDER_NORMAL_AGREEMENT`] and as much of its hemisphere below its
    /// geometric plane ([`BELOW_AGREEMENT`]), with an own z_min not below
    /// r's (the widest
    /// filter's rule, [`widest_filters`], which the atlas-grid spread
    /// cannot check beyond the chart); w the Gaussian of the offset in r's
    /// tangent plane. r itself comes with w = 1.
    ///
    /// Symmetric, as the grid filter's runs are: a lender counts only when
    /// another lender lies within [`MIRROR_TOLERANCE`] texels of its mirror
    /// image through r, so where the surface ends (a mesh edge, a rejected
    /// crease) the weights stay centred on r and a gradient is not shifted.
    #[inline]
    fn for_each_world_weight(&self, r: usize, mut f: impl FnMut(usize, f32)) {
        let (Some(reach), Some(world)) = (self.reach(r), self.world) else {
            return;
        };
        let rc = self.receivers;
        let fp = rc.footprint[r];
        let sigma_world = self.sigma_texels[r] * fp;
        let inv2s2 = 1.0 / (2.0 * sigma_world * sigma_world);
        let radius = reach as f32 * fp;
        let (pr, n, geo, z) = (
            rc.position[r],
            rc.normal[r],
            rc.geo_normal[r],
            self.z_min[r],
        );
        let frame = Frame::from_normal(geo);
        let below = below_fraction(n, geo);
        let tolerance2 = (MIRROR_TOLERANCE * fp).powi(2);
        f(r, 1.0);
        WORLD_LENDERS.with_borrow_mut(|lenders| {
            lenders.clear();
            world
                .tree
                .query(&pr.to_array())
                .within::<SquaredEuclidean<f32>>(radius * radius)
                .unsorted()
                .visit(|it| {
                    let j = it.item as usize;
                    let rel = rc.position[j] - pr;
                    if j == r
                        || world.own_z[j] < z
                        || !self.lends(r, j, rel)
                        || (below - below_fraction(rc.normal[j], rc.geo_normal[j])).abs()
                            > BELOW_AGREEMENT
                    {
                        return;
                    }
                    let t = Vec2::new(rel.dot(frame.tangent), rel.dot(frame.bitangent));
                    lenders.push((j as u32, t));
                });
            for &(j, t) in lenders.iter() {
                if lenders
                    .iter()
                    .any(|&(_, m)| (m + t).length_squared() <= tolerance2)
                {
                    f(j as usize, (-t.length_squared() * inv2s2).exp());
                }
            }
        });
    }

    /// Calls `f(j, w)` for each receiver j that lends to receiver `r` along
    /// its row (`vertical` false) or column, with its Gaussian weight w on
    /// the offset in r's tangent plane; r itself has w = 1. A side's run
    /// ends at the first neighbour inside geometry, beyond z_min, failing
    /// the leak rule or [`LENDER_NORMAL_AGREEMENT`] or missing (a chart
    /// border), and both sides keep the
    /// shorter run's length. Nothing for an unfiltered receiver.
    #[inline]
    fn for_each_weight(&self, r: usize, vertical: bool, mut f: impl FnMut(usize, f32)) {
        let Some(reach) = self.reach(r) else {
            return;
        };
        let rc = self.receivers;
        let fp = rc.footprint[r];
        let sigma_world = self.sigma_texels[r] * fp;
        let inv2s2 = 1.0 / (2.0 * sigma_world * sigma_world);
        let (pr, n, geo) = (rc.position[r], rc.normal[r], rc.geo_normal[r]);
        let tangent = cell_tangent(self.cells, n);
        // Each side's run of lending receivers, outward from r, up to the
        // first that does not lend (or no receiver: a chart border).
        let side = |dir: isize, out: &mut [(usize, f32); MAX_REACH as usize]| -> usize {
            for k in 1..=reach {
                let Some(j) = self.grid.offset(rc, r, dir * k as isize, vertical) else {
                    return k - 1;
                };
                let rel = rc.position[j] - pr;
                if !self.lends(r, j, rel) || !cells_agree(tangent, rc.normal[j]) {
                    return k - 1;
                }
                let t = rel - geo * rel.dot(geo);
                out[k - 1] = (j, (-t.length_squared() * inv2s2).exp());
            }
            reach
        };
        let mut lo = [(0usize, 0.0f32); MAX_REACH as usize];
        let mut hi = [(0usize, 0.0f32); MAX_REACH as usize];
        // Symmetric truncation: as many texels on each side as the shorter
        // run, so the weights stay centred on r where a chart border or a
        // rejected neighbour cuts one side (a one-sided average of a
        // gradient is biased by the gradient times the offset).
        let k = side(-1, &mut lo).min(side(1, &mut hi));
        f(r, 1.0);
        for (&(a, wa), &(b, wb)) in lo[..k].iter().zip(&hi[..k]) {
            f(a, wa);
            f(b, wb);
        }
    }

    /// Effective number of receivers the separable filter averages for
    /// each receiver: (sum W)^2 / sum W^2 over its final weights W (1 when
    /// not filtered). With row sums S_j = sum w, Q_j = sum w^2 and column
    /// weights c_j this is (sum c_j S_j)^2 / sum c_j^2 Q_j.
    fn effective_neighbours(&self) -> Vec<f32> {
        let n = self.receivers.len();
        let rows: Vec<(f32, f32)> = (0..n)
            .into_par_iter()
            .with_min_len(256)
            .map(|r| {
                let (mut s, mut q) = (0.0f32, 0.0f32);
                self.for_each_weight(r, false, |_, w| {
                    s += w;
                    q += w * w;
                });
                if s > 0.0 { (s, q) } else { (1.0, 1.0) }
            })
            .collect();
        (0..n)
            .into_par_iter()
            .with_min_len(256)
            .map(|r| {
                let (mut num, mut den) = (0.0f32, 0.0f32);
                if self.crosses_border(r) {
                    self.for_each_world_weight(r, |_, w| {
                        num += w;
                        den += w * w;
                    });
                } else {
                    self.for_each_weight(r, true, |j, c| {
                        num += c * rows[j].0;
                        den += c * c * rows[j].1;
                    });
                }
                if den > 0.0 {
                    (num * num / den).max(1.0)
                } else {
                    1.0
                }
            })
            .collect()
    }

    /// One pass of the separable filter over `src` (rows, or columns
    /// when `vertical`), each value weighted by `src_w` (the row pass's
    /// weight sums) if given: per receiver its filtered values and their
    /// weight sum; unfiltered receivers keep their own. With `world`
    /// given (the unfiltered values), receivers that [`Self::crosses_border`]
    /// take their world-space average instead.
    fn pass<'s>(
        &'s self,
        src: &'s [[f32; 10]],
        src_w: Option<&'s [f32]>,
        vertical: bool,
        world: Option<&'s [[f32; 10]]>,
    ) -> impl IndexedParallelIterator<Item = ([f32; 10], f32)> + 's {
        (0..self.receivers.len())
            .into_par_iter()
            .with_min_len(256)
            .map(move |r| {
                if let Some(values) = world
                    && self.crosses_border(r)
                {
                    let mut mean = WeightedMean::default();
                    self.for_each_world_weight(r, |j, w| mean.add(w, values[j]));
                    return mean.get().unwrap_or((values[r], 1.0));
                }
                let mut mean = WeightedMean::default();
                self.for_each_weight(r, vertical, |j, w| {
                    mean.add(w * src_w.map_or(1.0, |s| s[j]), src[j]);
                });
                mean.get().unwrap_or((src[r], src_w.map_or(1.0, |s| s[r])))
            })
    }

    /// The separable Gaussian filter of the integrated values (see the
    /// module doc), rows then columns; each row result carries its weight
    /// sum into the column pass. `values` (AO, then the 9 SH) is dropped
    /// after the row pass, unless receivers gather in world space; the
    /// column pass writes the filtered AO and SH arrays themselves.
    fn filter(&self, values: Vec<[f32; 10]>) -> (Vec<f32>, Vec<[f32; SH_COUNT]>) {
        let (row_values, row_weights): (Vec<[f32; 10]>, Vec<f32>) =
            self.pass(&values, None, false, None).unzip();
        let world = self.world.map(|_| values);
        self.pass(&row_values, Some(&row_weights), true, world.as_deref())
            .map(|(v, _)| (v[0], std::array::from_fn(|i| v[1 + i])))
            .unzip()
    }
}

/// A weighted mean of the filter's values (AO, then the 9 SH).
#[derive(Default)]
struct WeightedMean {
    sum: [f32; 10],
    weight: f32,
}

impl WeightedMean {
    #[inline]
    fn add(&mut self, w: f32, v: [f32; 10]) {
        for (a, v) in self.sum.iter_mut().zip(v) {
            *a += w * v;
        }
        self.weight += w;
    }

    /// The mean and the weight sum; none without weight.
    #[inline]
    fn get(&self) -> Option<([f32; 10], f32)> {
        (self.weight > 0.0).then(|| (self.sum.map(|a| a / self.weight), self.weight))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`allocate_variances`] for receivers of one cell with visibility
    /// spread `sd` whose filter averages `n_eff` receivers.
    fn allocate(sd: &[f32], n_eff: &[f32], o: &AdaptiveOptions) -> Vec<u32> {
        let unfiltered: Vec<f32> = sd.iter().map(|s| s * s).collect();
        let filtered: Vec<f32> = unfiltered
            .iter()
            .zip(n_eff)
            .map(|(v, m)| v / m.max(1.0))
            .collect();
        allocate_variances(&filtered, &unfiltered, o)
    }

    /// The sums of `rays` rays of a receiver with shading normal `n` and
    /// geometric normal Z, visible where `visible(d)` (above the plane),
    /// with or without the rays below in the SH sums.
    fn sums_of(n: Vec3, rays: u32, above_only: bool, visible: impl Fn(Vec3) -> bool) -> CellSums {
        let frame = Frame::from_normal(n);
        let mut s = CellSums::default();
        for i in 0..rays {
            let d = frame
                .to_world(crate::sample::cosine_hemisphere(crate::sample::sobol_2d(
                    i, 3,
                )))
                .normalize();
            if d.z <= 0.0 {
                s.below += 1;
                if above_only {
                    continue;
                }
            } else if visible(d) {
                s.visible += 1;
                sh::accumulate(&mut s.all, 1.0, d);
                continue;
            }
            sh::accumulate(&mut s.all, 1.0, d);
            sh::accumulate(&mut s.sh, 1.0, d);
        }
        s
    }

    /// A receiver's AO and SH from the values it lends the filter, as the
    /// bake finishes them when its filter returns them as they are.
    fn finished(v: [f32; 10], n: Vec3) -> (f32, [f32; SH_COUNT]) {
        let open = sh::open_hemisphere(n);
        let below = sh::below_plane(n, Vec3::Z);
        (
            v[0] - below_fraction(n, Vec3::Z),
            std::array::from_fn(|i| v[1 + i] + open[i] - below[i]),
        )
    }

    #[test]
    fn below_compensated_values_are_exact_for_open_and_closed_receivers() {
        let n = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let b = (1.0 - n.z) / 2.0;
        let (open, below) = (sh::open_hemisphere(n), sh::below_plane(n, Vec3::Z));
        // Everything above the plane visible: 1 - b and the open hemisphere
        // less the part below, exactly (16 rays see 2 or 3 below).
        let s = sums_of(n, 16, true, |_| true);
        assert!(s.below > 0);
        let (ao, c) = finished(below_compensated(&s, 16, n, Vec3::Z, true), n);
        assert!((ao - (1.0 - b)).abs() < 1e-6, "{ao}");
        assert!((0..SH_COUNT).all(|i| (c[i] - (open[i] - below[i])).abs() < 1e-6));
        // Everything occluded: zero.
        let s = sums_of(n, 16, true, |_| false);
        let (ao, c) = finished(below_compensated(&s, 16, n, Vec3::Z, true), n);
        assert!(ao.abs() < 1e-6, "{ao}");
        assert!(c.iter().all(|c| c.abs() < 1e-6), "{c:?}");
    }

    #[test]
    fn below_compensated_values_keep_l0_the_ao_and_unfiltered_ones_monte_carlo() {
        let n = Vec3::new(0.0, -0.6, 0.8);
        // Half of the above rays blocked, by a wall on +x.
        let wall = |d: Vec3| d.x < 0.2;
        for rays in [16, 64, 256] {
            // Filtered: L0 is Y_0 times the AO.
            let s = sums_of(n, rays, true, wall);
            let (ao, c) = finished(below_compensated(&s, rays, n, Vec3::Z, true), n);
            assert!(
                (c[0] - 0.282_094_8 * ao).abs() < 1e-6,
                "{rays}: {} {ao}",
                c[0]
            );
            // Unfiltered: Monte Carlo's estimate of the same rays.
            let s = sums_of(n, rays, false, wall);
            let (ao, c) = finished(below_compensated(&s, rays, n, Vec3::Z, false), n);
            let mc = s.visible as f32 / rays as f32;
            let mc_sh = sh::from_sums(n, &s.sh, &s.all, rays, mc);
            assert!((ao - mc).abs() < 1e-6, "{rays}: {ao} vs {mc}");
            assert!((0..SH_COUNT).all(|i| (c[i] - mc_sh[i]).abs() < 1e-5));
        }
    }

    #[test]
    fn every_block_of_four_rays_has_one_in_each_cell() {
        for seed in [0u64, 1, 0xdead_beef_1234_5678] {
            for block in 0..64u32 {
                let mut seen = [0; 4];
                for i in 4 * block..4 * block + 4 {
                    seen[cell_of_point(crate::sample::sobol_2d(i, seed), 4)] += 1;
                }
                assert_eq!(seen, [1; 4], "seed {seed} block {block}");
            }
        }
        assert_eq!(cell_of_point(Vec2::new(0.9, 0.9), 1), 0);
        // The concentric map sends the square's quadrants to the frame's.
        for (u, c) in [
            ((0.7, 0.7), 3),
            ((0.3, 0.7), 2),
            ((0.3, 0.3), 0),
            ((0.7, 0.3), 1),
        ] {
            let d = crate::sample::cosine_hemisphere(Vec2::new(u.0, u.1));
            assert_eq!(cell_of_point(Vec2::new(u.0, u.1), 4), c);
            assert_eq!((d.x > 0.0) as usize + 2 * (d.y > 0.0) as usize, c);
        }
    }

    #[test]
    fn below_fraction_matches_counted_directions() {
        // Cosine-weighted directions about n below a plane tilted by theta:
        // counted over 4096 Sobol points against (1 - cos theta) / 2.
        let n = Vec3::Z;
        for deg in [0.0f32, 10.0, 30.0, 60.0, 90.0] {
            let th = deg.to_radians();
            let geo = Vec3::new(th.sin(), 0.0, th.cos());
            let below = (0..4096u32)
                .filter(|&i| {
                    let d = crate::sample::cosine_hemisphere(crate::sample::sobol_2d(i, 7));
                    d.dot(geo) < 0.0
                })
                .count() as f32
                / 4096.0;
            assert!(
                (below - below_fraction(n, geo)).abs() < 0.005,
                "{deg}: {below}"
            );
        }
        assert_eq!(below_fraction(n, n), 0.0);
    }

    #[test]
    fn the_margin_grows_with_the_share_the_filter_removes() {
        let m = |f: f32, u: f32| model_margin(f, u, 1.2);
        assert_eq!(m(1.0, 1.0), 1.2);
        assert_eq!(m(0.0, 0.0), 1.2);
        assert_eq!(m(f32::NAN, 1.0), 1.2);
        assert_eq!(m(2.0, 1.0), 1.2, "no filter adds variance");
        assert_eq!(m(0.0, 1.0), FILTERED_MARGIN);
        // N_eff 4: three quarters of the way.
        assert!((m(0.25, 1.0) - (1.2 + 0.8 * 0.75)).abs() < 1e-9);
        assert!((model_margin(0.25, 1.0, 1.0) - (1.0 + 1.0 * 0.75)).abs() < 1e-9);
    }

    #[test]
    fn the_unfiltered_margin_grows_with_the_budget_the_filter_moves() {
        assert_eq!(unfiltered_margin(0.0), 1.0);
        assert_eq!(unfiltered_margin(f64::NAN), 1.0);
        assert_eq!(unfiltered_margin(-0.5), 1.0);
        assert!((unfiltered_margin(0.1) - 1.1).abs() < 1e-12);
        assert_eq!(unfiltered_margin(0.2), UNFILTERED_MARGIN);
        assert_eq!(unfiltered_margin(0.9), UNFILTERED_MARGIN);
    }

    #[test]
    fn sigma_of_stiff_depths() {
        // z_min -> 0: no filtering; nothing hit: unbounded; NaN: 0.
        assert_eq!(filter_sigma(0.0, 0.7, 2.8), 0.0);
        assert_eq!(filter_sigma(f32::NAN, 0.7, 2.8), 0.0);
        assert_eq!(filter_sigma(f32::INFINITY, 0.7, 2.8), f32::INFINITY);
        assert!((filter_sigma(3.92, 0.7, 2.8) - 1.0).abs() < 1e-6);
        assert!(filter_sigma(1e-30, 0.7, 2.8) > 0.0);
        // In texels: capped at max_reach / 2 for far or no occluders and a
        // texel size -> 0; contact, NaN and inside receivers unfiltered.
        let o = AdaptiveOptions::default();
        let cap = o.max_reach as f32 / 2.0;
        assert_eq!(sigma_in_texels(f32::INFINITY, 0.01, false, &o), cap);
        assert_eq!(sigma_in_texels(1.0, 0.0, false, &o), cap);
        assert_eq!(sigma_in_texels(1.0, 1e-30, false, &o), cap);
        assert_eq!(sigma_in_texels(0.0, 0.01, false, &o), 0.0);
        assert_eq!(sigma_in_texels(f32::NAN, 0.01, false, &o), 0.0);
        assert_eq!(sigma_in_texels(1.0, f32::NAN, false, &o), 0.0);
        assert_eq!(sigma_in_texels(1.0, 0.01, true, &o), 0.0);
        // Half a texel is the contact threshold: z_min = 2 mu Omega_h x 0.5.
        let edge = 2.0 * o.mu * o.omega_h * 0.5;
        assert_eq!(sigma_in_texels(edge * 0.99, 1.0, false, &o), 0.0);
        assert!(sigma_in_texels(edge * 1.01, 1.0, false, &o) > 0.5);
    }

    /// A flat `side` x `side` grid of receivers, one per texel, footprint 1.
    fn flat_grid(side: u32) -> Receivers {
        use glam::Vec3;
        let n = (side * side) as usize;
        Receivers {
            width: side,
            height: side,
            texel: (0..n as u32).collect(),
            position: (0..n as u32)
                .map(|t| Vec3::new((t % side) as f32, (t / side) as f32, 0.0))
                .collect(),
            normal: vec![Vec3::Z; n],
            geo_normal: vec![Vec3::Z; n],
            footprint: vec![1.0; n],
            overlapping_texels: 0,
            first_overlap: None,
        }
    }

    /// The grid filter's inputs over some receivers: nothing inside, one
    /// cell, the same sigma and z_min everywhere.
    struct Uniform {
        grid: TexelGrid,
        inside: Vec<bool>,
        sigma_texels: Vec<f32>,
        z_min: Vec<f32>,
    }

    impl Uniform {
        fn new(rc: &Receivers, sigma: f32, z_min: f32) -> Uniform {
            let n = rc.len();
            Uniform {
                grid: TexelGrid::new(rc),
                inside: vec![false; n],
                sigma_texels: vec![sigma; n],
                z_min: vec![z_min; n],
            }
        }

        /// The atlas-grid filter over `rc` (no world-space gather).
        fn support<'a>(&'a self, rc: &'a Receivers) -> FilterSupport<'a> {
            FilterSupport {
                receivers: rc,
                grid: &self.grid,
                inside: &self.inside,
                cells: 1,
                sigma_texels: &self.sigma_texels,
                z_min: &self.z_min,
                world: None,
            }
        }
    }

    /// (sum w)^2 / sum w^2 of a Gaussian of `sigma` texels over the texel
    /// offsets `xs` x `ys`: the effective neighbours, summed directly.
    fn gaussian_n_eff(
        sigma: f32,
        xs: std::ops::RangeInclusive<i32>,
        ys: std::ops::RangeInclusive<i32>,
    ) -> f64 {
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        for y in ys {
            for x in xs.clone() {
                let w = (-((x * x + y * y) as f64) / (2.0 * (sigma as f64).powi(2))).exp();
                s1 += w;
                s2 += w * w;
            }
        }
        s1 * s1 / s2
    }

    #[test]
    fn effective_neighbours_of_the_separable_filter_on_a_plane() {
        // Against the direct sum (sum w)^2 / sum w^2 of a Gaussian over the
        // square of reach ceil(2 sigma) around the centre, the filter's
        // support; at a corner, a quarter of it.
        let side = 21u32;
        let rc = flat_grid(side);
        let n = rc.len();
        for sigma in [0.75f32, 1.0, 2.0] {
            let uniform = Uniform::new(&rc, sigma, f32::INFINITY);
            let support = uniform.support(&rc);
            let ours = support.effective_neighbours();
            let reach = (2.0 * sigma).ceil() as i32;
            let direct = |xs: std::ops::RangeInclusive<i32>| gaussian_n_eff(sigma, xs.clone(), xs);
            let centre = (side * side / 2) as usize;
            let (c, d) = (ours[centre] as f64, direct(-reach..=reach));
            assert!((c - d).abs() / d < 1e-3, "{sigma}: {c} vs {d}");
            // Near a border both sides keep the shorter run: one texel in
            // from a corner, a 3x3 square; the corner itself, alone.
            let (c, d) = (ours[(side + 1) as usize] as f64, direct(-1..=1));
            assert!((c - d).abs() / d < 1e-3, "by a corner {sigma}: {c} vs {d}");
            assert_eq!(ours[0], 1.0);
            // Unfiltered receivers average only themselves.
            let none = vec![0.0f32; n];
            let alone = FilterSupport {
                sigma_texels: &none,
                ..support
            };
            assert!(alone.effective_neighbours().iter().all(|&v| v == 1.0));
        }
    }

    #[test]
    fn lenders_whose_shading_normal_turns_beyond_ten_degrees_do_not_lend() {
        // A flat grid whose shading normals turn about y from column to
        // column (a curved surface's normals on a flat chart): at 15
        // degrees per column (within the leak rule's 25) the row lends
        // nothing, so the centre averages its column only; at 4 degrees
        // (8 at two columns) the whole square lends.
        let side = 9u32;
        let sigma = 1.0f32;
        let reach = 2i32;
        let direct = |xs, ys| gaussian_n_eff(sigma, xs, ys);
        let centre = (side * side / 2) as usize;
        for (degrees, want) in [
            (15.0f32, direct(0..=0, -reach..=reach)),
            (4.0, direct(-reach..=reach, -reach..=reach)),
        ] {
            let mut rc = flat_grid(side);
            for (t, n) in rc.normal.iter_mut().enumerate() {
                let a = (degrees * ((t as u32 % side) as f32 - 4.0)).to_radians();
                *n = Vec3::new(a.sin(), 0.0, a.cos());
            }
            let uniform = Uniform::new(&rc, sigma, f32::INFINITY);
            let got = uniform.support(&rc).effective_neighbours()[centre] as f64;
            assert!(
                (got - want).abs() / want < 1e-3,
                "{degrees}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn nothing_seen_leaves_less_variance_the_more_rays_saw_nothing() {
        // 16 rays seeing nothing: p = 0.5 / 17 occluded, variance p (1 - p).
        let p = 0.5f32 / 17.0;
        assert!((nothing_seen_variance(16, 1.0) - p * (1.0 - p)).abs() < 1e-6);
        // No count is one receiver; more receivers, less variance, never 0.
        assert_eq!(
            nothing_seen_variance(16, 0.0),
            nothing_seen_variance(16, 1.0)
        );
        let v: Vec<f32> = [1.0f32, 9.0, 81.0, 1e12]
            .iter()
            .map(|&c| nothing_seen_variance(16, c))
            .collect();
        assert!(v.windows(2).all(|w| w[1] < w[0]) && v[3] > 0.0, "{v:?}");
        assert!((v[2] * 16.0 * 81.0 - 0.5).abs() < 0.01);
    }

    #[test]
    fn a_filter_reads_only_receivers_whose_own_z_min_allow_its_width() {
        // Open receivers (nothing seen) around one that saw an occluder at
        // 0.5 texels (contact: sigma 0.13). Footprint 1, max_reach 4.
        let rc = flat_grid(9);
        let grid = TexelGrid::new(&rc);
        let n = rc.len();
        let inside = vec![false; n];
        let mut own = vec![f32::INFINITY; n];
        let at = |x: usize, y: usize| y * 9 + x;
        own[at(4, 4)] = 0.5;
        let o = AdaptiveOptions::default();
        let width = |z: f32, r: usize| sigma_in_texels(z, rc.footprint[r], inside[r], &o);
        let (z, sigma) = widest_filters(&rc, &grid, &inside, 1, &own, &o, width);
        // The contact receiver and its neighbours: not filtered.
        assert_eq!(sigma[at(4, 4)], 0.0);
        assert_eq!(sigma[at(5, 4)], 0.0);
        assert_eq!(sigma[at(5, 5)], 0.0);
        // 3 texels away: a 2-texel reach (sigma 1) reads only open
        // receivers; 4 away, 3 texels (sigma 1.5); the support's z_min
        // stays unbounded.
        assert_eq!((z[at(7, 4)], sigma[at(7, 4)]), (f32::INFINITY, 1.0));
        assert_eq!((z[at(0, 0)], sigma[at(0, 0)]), (f32::INFINITY, 1.5));
        // No reach of any filter holds the contact receiver.
        for (r, &s) in sigma.iter().enumerate() {
            let reach = (2.0 * s).ceil() as usize;
            let (dx, dy) = ((r % 9).abs_diff(4), (r / 9).abs_diff(4));
            assert!(s == 0.0 || dx.max(dy) > reach, "texel {r}");
        }
    }

    #[test]
    fn the_filter_keeps_a_gradient_up_to_a_chart_border() {
        // AO rising linearly across a chart whose right part is missing
        // (another chart's texels): a one-sided average beside the border
        // would be biased by the slope times the weights' offset; the
        // symmetric support keeps the ramp exact to rounding.
        let side = 12u32;
        let full = flat_grid(side);
        // Keep columns 0..8: the chart border is between columns 7 and 8.
        let keep: Vec<usize> = (0..full.len())
            .filter(|&t| t % side as usize <= 7)
            .collect();
        let rc = Receivers {
            texel: keep.iter().map(|&t| t as u32).collect(),
            position: keep.iter().map(|&t| full.position[t]).collect(),
            normal: keep.iter().map(|&t| full.normal[t]).collect(),
            geo_normal: keep.iter().map(|&t| full.geo_normal[t]).collect(),
            footprint: keep.iter().map(|&t| full.footprint[t]).collect(),
            ..full
        };
        let uniform = Uniform::new(&rc, 2.0, f32::INFINITY);
        assert_filter_keeps(&uniform.support(&rc), |p| 0.1 + 0.1 * p.x);
    }

    /// `support`'s filter keeps a linear function of position exactly (to
    /// rounding), in the AO and every SH value.
    fn assert_filter_keeps(support: &FilterSupport, f: impl Fn(Vec3) -> f32) {
        let rc = support.receivers;
        let values: Vec<[f32; 10]> = rc.position.iter().map(|&p| [f(p); 10]).collect();
        let (ao, sh) = support.filter(values);
        for (r, &p) in rc.position.iter().enumerate() {
            assert!((ao[r] - f(p)).abs() < 1e-5, "{p}: {}", ao[r]);
            assert!(sh[r].iter().all(|&v| (v - f(p)).abs() < 1e-5), "{p}");
        }
    }

    /// One plane, x in 0..12 and y in 0..8 world texels, in two charts: x
    /// < 6 at atlas columns 0..6 and x >= 6 at atlas columns 9..15 (a gap
    /// of 3 texels between them).
    fn plane_in_two_charts() -> Receivers {
        let (w, h) = (16u32, 8u32);
        let mut rc = Receivers {
            width: w,
            height: h,
            ..Default::default()
        };
        for y in 0..h {
            for x in 0..12u32 {
                let ax = if x < 6 { x } else { x + 3 };
                rc.texel.push(y * w + ax);
                rc.position.push(Vec3::new(x as f32, y as f32, 0.0));
                rc.normal.push(Vec3::Z);
                rc.geo_normal.push(Vec3::Z);
                rc.footprint.push(1.0);
            }
        }
        rc
    }

    #[test]
    fn the_world_filter_crosses_a_chart_border_and_keeps_a_ramp() {
        // A ramp along x over one plane cut into two charts: beside the cut,
        // the grid filter keeps only the shorter side's run (nothing, at the
        // border column), while the world-space gather reads the other chart
        // and averages as many receivers as in the plane's interior; the
        // ramp stays exact (mirrored lenders keep the weights centred, also
        // at the plane's own edges).
        let rc = plane_in_two_charts();
        let n = rc.len();
        let own_z = vec![f32::INFINITY; n];
        let tree = position_tree(&rc).unwrap();
        let uniform = Uniform::new(&rc, 1.0, f32::INFINITY);
        let grid_only = uniform.support(&rc);
        let world = FilterSupport {
            world: World::of(Some(&tree), &own_z),
            ..grid_only
        };
        let at = |x: f32, y: f32| {
            (0..n)
                .find(|&r| rc.position[r] == Vec3::new(x, y, 0.0))
                .unwrap()
        };
        let (border, interior) = (at(5.0, 4.0), at(8.0, 4.0));
        assert!(world.crosses_border(border) && !world.crosses_border(interior));
        let (g, w) = (
            grid_only.effective_neighbours(),
            world.effective_neighbours(),
        );
        // The disc of radius 2 sigma around the border receiver: 13
        // receivers (every offset with x^2 + y^2 <= 4) at the Gaussian's
        // weights.
        let (mut s1, mut s2) = (0.0f32, 0.0f32);
        for y in -2i32..=2 {
            for x in -2i32..=2 {
                if x * x + y * y <= 4 {
                    let v = (-((x * x + y * y) as f32) / 2.0).exp();
                    s1 += v;
                    s2 += v * v;
                }
            }
        }
        assert!((w[border] - s1 * s1 / s2).abs() < 1e-4, "{}", w[border]);
        // The grid filter: the column alone (3.5 receivers).
        assert!(g[border] < 3.6 && w[border] > 2.5 * g[border]);
        assert_filter_keeps(&world, |p| 0.1 + 0.05 * p.x + 0.02 * p.y);
        // A receiver that saw a nearer occluder than the border receiver's
        // filter allows does not lend to it across the border.
        let mut own_z = own_z.clone();
        let near = at(6.0, 4.0);
        own_z[near] = 3.0;
        let z_min = vec![10.0f32; n];
        let strict = FilterSupport {
            z_min: &z_min,
            world: World::of(Some(&tree), &own_z),
            ..world
        };
        let mut read = Vec::new();
        strict.for_each_world_weight(border, |j, _| read.push(j));
        assert!(!read.contains(&near) && read.contains(&at(5.0, 3.0)));
        // Nor does a face whose geometric normal turns by 20 degrees under
        // the same shading normal (3% of its hemisphere below it), though
        // the leak rule's 25 degrees let it.
        let mut bevel = rc.clone();
        let turned = at(6.0, 3.0);
        bevel.geo_normal[turned] =
            Vec3::new(20f32.to_radians().sin(), 0.0, 20f32.to_radians().cos());
        let bevelled = FilterSupport {
            receivers: &bevel,
            ..world
        };
        let mut read = Vec::new();
        bevelled.for_each_world_weight(border, |j, _| read.push(j));
        assert!(!read.contains(&turned) && read.contains(&at(6.0, 5.0)));
    }

    #[test]
    fn the_filter_keeps_a_constant_and_does_not_cross_z_min() {
        // A constant is kept exactly; a neighbour beyond z_min is not read.
        let rc = flat_grid(9);
        let n = rc.len();
        let uniform = Uniform::new(&rc, 2.0, 1.5);
        let support = uniform.support(&rc);
        let (ao, sh) = support.filter(vec![[0.25f32; 10]; n]);
        assert!(
            ao.iter()
                .chain(sh.iter().flatten())
                .all(|&v| (v - 0.25).abs() < 1e-6)
        );
        // One bright texel: only receivers within 1.5 texels (row or column
        // offsets of 1) see it.
        let mut values = vec![[0.0f32; 10]; n];
        values[40] = [1.0; 10];
        let (out, _) = support.filter(values.clone());
        for (r, v) in out.iter().enumerate() {
            let (dx, dy) = ((r % 9) as i32 - 4, (r / 9) as i32 - 4);
            let reach = dx.abs() <= 1 && dy.abs() <= 1;
            assert_eq!(*v > 0.0, reach, "texel {dx},{dy}");
        }
        // Inside receivers lend nothing.
        let mut inside = vec![false; n];
        inside[40] = true;
        let masked = FilterSupport {
            inside: &inside,
            ..support
        };
        let (out, _) = masked.filter(values);
        assert!(out.iter().enumerate().all(|(r, &v)| r == 40 || v == 0.0));
    }

    #[test]
    fn ray_counts_are_powers_of_two_with_the_asked_mean() {
        let o = AdaptiveOptions {
            mean_rays: 64,
            max_rays: 512,
            ..Default::default()
        };
        let rays = |n: f32| 1u32 << ray_exponent(n.log2(), 4, 9);
        assert_eq!(rays(0.0), 16);
        assert_eq!(rays(f32::NAN), 16);
        assert_eq!(rays(-3.0), 16);
        assert_eq!(rays(90.0), 64);
        assert_eq!(rays(100.0), 128);
        assert_eq!(rays(1e9), 512);
        assert_eq!(rays(f32::INFINITY), 512);
        assert_eq!((exponent_at_least(16), exponent_at_most(512)), (4, 9));
        assert_eq!((exponent_at_least(20), exponent_at_most(1000)), (5, 9));
        // Half the receivers open (no demand), half with demand 1..2.
        let sd: Vec<f32> = (0..1000)
            .map(|i| {
                if i % 2 == 0 {
                    0.0
                } else {
                    0.2 + (i % 7) as f32 / 25.0
                }
            })
            .collect();
        let c = allocate(&sd, &vec![1.0; 1000], &o);
        assert!(
            c.iter()
                .all(|&v| v.is_power_of_two() && (16..=512).contains(&v))
        );
        assert!(
            c.iter().step_by(2).all(|&v| v == 16),
            "open receivers stay at the pre-pass"
        );
        let mean = c.iter().map(|&v| v as f64).sum::<f64>() / c.len() as f64;
        assert!((mean - 64.0).abs() / 64.0 < 0.35, "mean {mean}");
        // More spread, more rays.
        assert!(c[13] >= c[7] || sd[13] <= sd[7]);
    }

    #[test]
    fn ray_counts_for_a_quality_match_monte_carlos_predicted_error() {
        // Equal receivers need k with k^ALPHA n_eff >= quality^ALPHA x
        // margin. All unfiltered (no budget moves: margin 1): 256. A filter
        // over 16 receivers everywhere (15/16 of the variance removed: the
        // unfiltered margin 1.2, blended to 1.2 + 0.8 x 15/16 = 1.95): 256 x
        // (1.95 / 16)^(1/1.4) = 57, so 64.
        let o = AdaptiveOptions::default();
        let sd = vec![0.5f32; 100];
        let need = |n_eff: f64, unfiltered: f64| {
            let margin = unfiltered + (2.0 - unfiltered) * (1.0 - 1.0 / n_eff);
            let k = (256f64.powf(ALPHA) * margin / n_eff).powf(1.0 / ALPHA);
            (k.ceil() as u32).next_power_of_two()
        };
        assert_eq!((need(1.0, 1.0), need(16.0, 1.2)), (256, 64));
        assert!(allocate(&sd, &vec![1.0; 100], &o).iter().all(|&c| c == 256));
        assert!(allocate(&sd, &vec![16.0; 100], &o).iter().all(|&c| c == 64));
        // The cap holds; no spread anywhere: the pre-pass alone.
        let few = AdaptiveOptions { quality: 4096, ..o };
        assert!(
            allocate(&sd, &vec![1.0; 100], &few)
                .iter()
                .all(|&c| c == 1024)
        );
        assert!(
            allocate(&vec![0.0; 100], &vec![1.0; 100], &o)
                .iter()
                .all(|&c| c == 16)
        );
    }

    #[test]
    fn z_min_is_exact_to_twice_the_widest_footprints_saturating_depth() {
        let o = AdaptiveOptions::default();
        // sigma_in_texels reaches max_reach / 2 at the saturating depth.
        let fp = 0.01f32;
        let z = saturating_depth(fp, &o);
        assert!((sigma_in_texels(z, fp, false, &o) - o.max_reach as f32 / 2.0).abs() < 1e-4);
        assert!(sigma_in_texels(0.9 * z, fp, false, &o) < o.max_reach as f32 / 2.0);
        // The widest finite footprint sets it; never beyond max_distance.
        let d = exact_depth(&[0.005, fp, f32::NAN, f32::INFINITY], &o, 10.0);
        assert!((d - 2.0 * z).abs() < 1e-6);
        assert_eq!(exact_depth(&[fp], &o, 0.1), 0.1);
        // Nothing to gain: no receivers, no filter, zero footprints.
        assert_eq!(exact_depth(&[], &o, 0.5), 0.5);
        assert_eq!(exact_depth(&[0.0], &o, 0.5), 0.5);
        let unfiltered = AdaptiveOptions {
            max_reach: 0,
            ..Default::default()
        };
        assert_eq!(exact_depth(&[fp], &unfiltered, 0.5), 0.5);
    }

    #[test]
    fn below_the_contact_depth_every_receiver_is_in_contact() {
        let o = AdaptiveOptions::default();
        let atlas = [
            0.003f32,
            0.0023,
            0.006,
            1e-30,
            1e30,
            f32::NAN,
            -1.0,
            f32::INFINITY,
        ];
        let c = contact_depth(&atlas, &o);
        // No receiver filters at it (nor, sigma rising with z_min, below it).
        for &fp in &atlas {
            assert_eq!(sigma_in_texels(c, fp, false, &o), 0.0, "{fp}");
        }
        // Tight: the smallest footprint filters just above it.
        let c = contact_depth(&[0.003, 0.0023, 0.006], &o);
        assert_eq!(sigma_in_texels(c, 0.0023, false, &o), 0.0);
        assert!(sigma_in_texels(1.01 * c, 0.0023, false, &o) >= 0.5);
        // A zero footprint filters at any depth: nothing is contact for sure.
        assert_eq!(contact_depth(&[0.003, 0.0], &o), 0.0);
        // Footprints that never filter, none, or no filter at all: every
        // depth is contact.
        assert_eq!(
            contact_depth(&[f32::NAN, -1.0, f32::INFINITY], &o),
            f32::INFINITY
        );
        assert_eq!(contact_depth(&[], &o), f32::INFINITY);
        let unfiltered = AdaptiveOptions {
            max_reach: 0,
            ..Default::default()
        };
        assert_eq!(contact_depth(&[0.003], &unfiltered), f32::INFINITY);
        let reach1 = AdaptiveOptions {
            max_reach: 1,
            ..Default::default()
        };
        assert!(contact_depth(&[0.003], &reach1).is_finite());
    }

    #[test]
    fn every_pre_pass_stratum_holds_one_point() {
        for m in 0..=12 {
            let pre = 1u32 << m;
            let strata = Strata::of(pre);
            assert_eq!(strata.cols * strata.rows, pre);
            assert!(strata.cols == strata.rows || strata.cols == 2 * strata.rows);
            for seed in [0u64, 7, 0xdead_beef] {
                let mut seen = vec![false; pre as usize];
                for i in 0..pre {
                    let k = strata.index(crate::sample::sobol_2d(i, seed));
                    assert!(!seen[k], "two of {pre} points in stratum {k}");
                    seen[k] = true;
                }
            }
        }
        assert_eq!(Strata::of(16).pairs(), 24);
        assert_eq!(Strata::of(1).pairs(), 0);
        // Points on the square's far edges stay in the grid.
        assert_eq!(Strata::of(16).index(Vec2::ONE), 15);
    }

    #[test]
    fn crossings_count_the_boundary_between_strata() {
        let strata = Strata::of(16);
        let bits = |f: &dyn Fn(u32, u32) -> bool| {
            let mut b = [0u64; STRATA_WORDS];
            for y in 0..4 {
                for x in 0..4 {
                    if f(x, y) {
                        b[0] |= 1 << (y * 4 + x);
                    }
                }
            }
            b
        };
        assert_eq!(strata.crossings(&bits(&|_, _| false)), 0);
        assert_eq!(strata.crossings(&bits(&|_, _| true)), 0);
        // A straight wall over half of the square: one crossing per row.
        assert_eq!(strata.crossings(&bits(&|x, _| x < 2)), 4);
        // A lattice: every pair.
        assert_eq!(strata.crossings(&bits(&|x, y| (x + y) % 2 == 0)), 24);
        // Past the first word (64 strata of 128 rays: 16 x 8).
        let strata = Strata::of(128);
        let mut b = [0u64; STRATA_WORDS];
        for i in 64..128 {
            b[1] |= 1 << (i - 64);
        }
        assert_eq!(strata.crossings(&b), 16);
    }

    /// The premise of [`boundary_variance`]: at equal visible share, the
    /// stratified estimate's error grows with the boundary's length, and
    /// the crossings of 16 points rank it. Two visibilities of the square
    /// occluded on half of it: a straight edge and stripes.
    #[test]
    fn crossings_rank_the_stratified_error_at_equal_visible_share() {
        // (Tilted, so that no edge lies on the strata's.)
        let edge = |u: Vec2| u.x + 0.3 * u.y < 0.65;
        let lattice = |u: Vec2| (u.x * 13.7 + u.y * 7.3).floor() as i32 % 2 == 0;
        let strata = Strata::of(16);
        let measure = |f: &dyn Fn(Vec2) -> bool| {
            // The occluded share, on a fine grid.
            let m = 1024;
            let share = (0..m * m)
                .filter(|k| f((Vec2::new((k % m) as f32, (k / m) as f32) + 0.5) / m as f32))
                .count() as f64
                / (m * m) as f64;
            assert!((share - 0.5).abs() < 0.03, "{share}");
            let (mut predicted, mut err2) = (0.0f64, 0.0f64);
            let seeds = 400;
            for seed in 0..seeds {
                let mut b = [0u64; STRATA_WORDS];
                for i in 0..16 {
                    let u = crate::sample::sobol_2d(i, seed);
                    if f(u) {
                        let k = strata.index(u);
                        b[k / 64] |= 1 << (k % 64);
                    }
                }
                predicted += boundary_variance(strata.crossings(&b), strata) as f64;
                let occluded = (0..256)
                    .filter(|&i| f(crate::sample::sobol_2d(i, seed)))
                    .count();
                err2 += (occluded as f64 / 256.0 - share).powi(2);
            }
            (predicted / seeds as f64, err2 / seeds as f64)
        };
        let (edge_predicted, edge_err2) = measure(&edge);
        let (lattice_predicted, lattice_err2) = measure(&lattice);
        // The measured errors differ by far more than the binomial model
        // (equal for both, p = 1/2) allows ...
        assert!(lattice_err2 > 4.0 * edge_err2, "{lattice_err2} {edge_err2}");
        // ... and the crossings predict the order, the edge near the
        // calibration point (p(1 - p) = 1/4 for a straight half split).
        assert!(lattice_predicted > 2.0 * edge_predicted);
        assert!((0.2..0.45).contains(&edge_predicted), "{edge_predicted}");
    }

    #[test]
    fn stratified_sd_lies_between_its_two_models() {
        let strata = Strata::of(16);
        for visible in [0, 1, 8, 15, 16] {
            for crossings in [0, 4, 12, 24] {
                let s = stratified_sd(visible, 16, crossings, strata);
                let a = visibility_sd(visible, 16);
                let b = boundary_variance(crossings, strata).sqrt();
                assert!(s.is_finite() && s > 0.0);
                assert!(s >= a.min(b) * 0.9999 && s <= a.max(b) * 1.0001);
            }
        }
        // A straight wall halving the square: the calibration point, where
        // both models agree.
        let half = stratified_sd(8, 16, 4, strata);
        assert!((half - visibility_sd(8, 16)).abs() < 0.02, "{half}");
        // At equal visible share, more crossings ask for more rays.
        assert!(stratified_sd(8, 16, 20, strata) > 1.3 * stratified_sd(8, 16, 2, strata));
        // The calibration holds on every grid: a straight halving is 1/4,
        // along rows or columns (between them where the grid is 2:1).
        for pre in [16u32, 64, 256] {
            let strata = Strata::of(pre);
            let v = boundary_variance(strata.rows, strata);
            assert!((v - 0.25).abs() < 1e-6, "{pre}: {v}");
        }
        let strata = Strata::of(32);
        assert!(boundary_variance(strata.rows, strata) < 0.25);
        assert!(boundary_variance(strata.cols, strata) > 0.25);
        // No grid (one pre-pass ray): the largest boundary variance.
        assert!(stratified_sd(1, 1, 0, Strata::of(1)).is_finite());
    }

    #[test]
    fn visibility_sd_is_largest_at_half() {
        assert!(visibility_sd(8, 16) > visibility_sd(15, 16));
        assert!(visibility_sd(16, 16) > 0.0);
        assert!(visibility_sd(0, 16) > 0.0);
    }

    #[test]
    fn options_are_checked() {
        assert!(AdaptiveOptions::default().validate().is_ok());
        for bad in [
            AdaptiveOptions {
                pre_rays: 12,
                ..Default::default()
            },
            AdaptiveOptions {
                max_rays: 8,
                ..Default::default()
            },
            AdaptiveOptions {
                mean_rays: 2048,
                ..Default::default()
            },
            AdaptiveOptions {
                mean_rays: 8,
                ..Default::default()
            },
            AdaptiveOptions {
                quality: 0,
                ..Default::default()
            },
            AdaptiveOptions {
                mu: f32::NAN,
                ..Default::default()
            },
            AdaptiveOptions {
                cells: 2,
                ..Default::default()
            },
            AdaptiveOptions {
                cells: 4,
                pre_rays: 2,
                max_rays: 2,
                ..Default::default()
            },
            AdaptiveOptions {
                omega_h: 0.0,
                ..Default::default()
            },
            AdaptiveOptions {
                max_reach: 100,
                ..Default::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
