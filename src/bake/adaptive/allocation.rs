//! Ray counts: how many rays each receiver gets so that the bake's
//! predicted error is `quality`-ray Monte Carlo's.
//!
//! In: per receiver, the one-ray variance of its visibility before the
//! filter and what its filter leaves of it (from the pre-pass's visible
//! share and strata crossings, over its neighbourhood; over its N_eff),
//! [`AdaptiveOptions`]. Out: a power-of-two ray count per receiver in
//! [`pre_rays`, `max_rays`] ([`allocate_variances`]): the page's [`Scale`]
//! ([`allocation_scale`]), then each receiver's count from its own
//! variances at that scale ([`counts`]).

use super::options::AdaptiveOptions;
use super::strata::{Strata, exponent_at_least, exponent_at_most};
use rayon::prelude::*;

/// The standard deviation of one ray's visibility from `visible` of
/// `rays` (smoothed so that all or none visible is not certainty).
#[inline]
pub fn visibility_sd(visible: u32, rays: u32) -> f32 {
    let p = (visible as f32 + 0.5) / (rays as f32 + 1.0);
    (p * (1.0 - p)).sqrt()
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
/// At one visible share, a receiver whose strata cross the boundary more
/// often errs more, which the binomial sd cannot see; the crossings alone
/// send too few rays to a receiver whose few rays happen to agree. The
/// geometric mean keeps both signals (measured: [`stratified_sd`] in
/// `docs/measurements/constants.md`).
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
/// stratified estimate goes as rays^-ALPHA, faster than the rays^-1 of
/// independent samples, as Monte Carlo's own error curve falls
/// (`docs/measurements/constants.md`, ALPHA).
pub const ALPHA: f64 = 1.4;

/// How much lower than `quality`-ray Monte Carlo's the predicted variance
/// of an unfiltered receiver is aimed. The prediction leaves out the noise
/// of the pre-pass's spread estimate and the receivers whose neighbourhood
/// saw nothing, so without a margin the method lands above Monte Carlo's
/// error. Where the filter removes most of the variance, Monte Carlo's
/// error budget moves to the unfiltered receivers, whose noise is where
/// the p99 tail lies; this margin keeps them at Monte Carlo's noise (the
/// smallest that holds every metric of Monte Carlo's on the test scenes:
/// `docs/measurements/constants.md`, UNFILTERED_MARGIN). It is reached
/// where the filter removes [`MOVED_FOR_FULL_MARGIN`] of the atlas's Monte
/// Carlo variance ([`unfiltered_margin`]).
pub const UNFILTERED_MARGIN: f64 = 1.2;

/// The share of the atlas's predicted Monte Carlo variance the filter
/// removes (the error budget that moves to the unfiltered receivers) at
/// which the unfiltered receivers get all of [`UNFILTERED_MARGIN`]; below
/// it they get that share of it: a scene whose texels are nearly all
/// unfiltered moves little of the budget and needs no margin, one where
/// the filter removes a fifth or more needs all of it
/// (`docs/measurements/constants.md`, MOVED_FOR_FULL_MARGIN).
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
/// filter leaves more of the L2 band's error than N_eff predicts; 2.0 is
/// the smallest margin that keeps the L2 band at Monte Carlo's error
/// (`docs/measurements/constants.md`, FILTERED_MARGIN).
pub(crate) const FILTERED_MARGIN: f64 = 2.0;

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

/// The page's two numbers that turn every receiver's predicted variance
/// into its ray count (`allocation_scale`, `counts`): log2 of the
/// scale and the unfiltered receivers' margin. Apart from them a
/// receiver's count is its own: a later bake that takes them from an
/// earlier one (`--reuse`) gives every receiver whose neighbourhood did
/// not change the count it had.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// log2 of the scale a receiver's demand is multiplied by.
    pub log_scale: f32,
    /// `unfiltered_margin` of the share of the page's variance the
    /// filter removes.
    pub margin: f64,
}

/// Ray counts for receivers whose one-ray variance is `unfiltered` before
/// the filter and `filtered` after it (sd^2 / n_eff for one cell; the mean
/// over the cells otherwise; 0: pre-pass only). Counts are
/// power_of_two(scale x sqrt(margin) sd / sqrt(n_eff)) ([`ray_exponent`]; the allocation
/// that minimizes the summed variance margin sd^2 / (rays^ALPHA n_eff) for
/// a given number of rays; margin: [`model_margin`]), with the scale found
/// by bisection ([`allocation_scale`]).
#[cfg(test)]
pub fn allocate_variances(filtered: &[f32], unfiltered: &[f32], o: &AdaptiveOptions) -> Vec<u32> {
    let scale = allocation_scale(filtered, unfiltered, o);
    counts(filtered, unfiltered, scale, o)
}

/// Per receiver: demand sd / sqrt(n_eff) and variance share sd^2 / n_eff,
/// both of the variance raised by the receiver's model margin.
#[inline]
fn term(v: f32, u: f32, margin: f64) -> (f32, f64) {
    if v > 0.0 {
        let v = v as f64 * model_margin(v, u, margin);
        (v.sqrt() as f32, v)
    } else {
        (0.0, 0.0)
    }
}

/// The ray counts at `scale`: each receiver's from its own variances
/// alone, 2^round(log2 scale + log2 demand) within [`pre_rays`,
/// `max_rays`] (a receiver with no demand: the pre-pass's).
pub fn counts(filtered: &[f32], unfiltered: &[f32], scale: Scale, o: &AdaptiveOptions) -> Vec<u32> {
    let (lo_exp, hi_exp) = (exponent_at_least(o.pre_rays), exponent_at_most(o.max_rays));
    (filtered.par_iter().zip(unfiltered))
        .with_min_len(4096)
        .map(|(&v, &u)| {
            let d = term(v, u, scale.margin).0;
            1 << ray_exponent(scale.log_scale + d.log2(), lo_exp, hi_exp)
        })
        .collect()
}

/// The page's [`Scale`]: the margin from the share of the page's
/// predicted variance its filter removes, and the smallest scale (by
/// bisection to f32's resolution on its log2) whose counts' predicted
/// mean variance is at most `quality`-ray Monte Carlo's, mean sd^2 /
/// quality^ALPHA, or with `mean_rays` set, whose mean count reaches it.
pub fn allocation_scale(filtered: &[f32], unfiltered: &[f32], o: &AdaptiveOptions) -> Scale {
    // The predicted variance, and the share of it the filter removes.
    let total: f64 = unfiltered.iter().map(|&v| v as f64).sum();
    let kept: f64 = filtered.iter().map(|&v| v as f64).sum();
    let margin = unfiltered_margin(1.0 - kept / total);
    let terms: Vec<(f32, f64)> = (filtered.iter().zip(unfiltered))
        .map(|(&v, &u)| term(v, u, margin))
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
        // No receiver asks for more than the pre-pass: every count is
        // the pre-pass's at any scale.
        return Scale {
            log_scale: 0.0,
            margin,
        };
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
    Scale {
        log_scale: hi,
        margin,
    }
}

/// The one-ray visibility variance a receiver may still have when `count`
/// receivers' `rays` rays each (its neighbourhood's) all saw nothing:
/// [`visibility_sd`] of all of them visible, squared.
#[inline]
pub(crate) fn nothing_seen_variance(rays: u32, count: f32) -> f32 {
    // The occluded side's smoothed fraction, without 1 - p's cancellation.
    let q = 0.5 / (rays as f32 * count.max(1.0) + 1.0);
    q * (1.0 - q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::adaptive::strata::STRATA_WORDS;
    use glam::Vec2;

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
}
