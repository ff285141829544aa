//! Bounds: each receiver's filter from the occluders' depth, and the
//! variance its ray count must beat.
//!
//! In: [`Receivers`], the [`TexelGrid`], the pre-pass ([`PrePass`]: own
//! z_min, visible counts, strata crossings, inside marks),
//! [`AdaptiveOptions`]. Out: [`Bounds`]: per receiver the z_min its
//! filter may read up to and the filter's sigma in texels (0: contact,
//! not filtered), and the one-ray variance of its visibility before and
//! after the filter, which the allocation reads.
//!
//! Filter width sigma = z_min / (2 mu Omega_h) ([`sigma_in_texels`]), at
//! most `max_reach / 2` texels; below half a texel (contact) no
//! filtering. z_min is spread: per reach k, the minimum of the compatible
//! receivers' own z_min within k texels (rows, then columns) allows a
//! filter of at most k / 2 texels, and each receiver takes the widest
//! such filter ([`widest_filters`]), so an open-looking receiver beside
//! occluded ones is not filtered wide and no filter reads a receiver
//! that saw a nearer occluder than its width allows. The variance reads
//! the minimum over the support of the receiver's own z_min (2 sigma,
//! `max_reach` when it saw nothing) and the spread of the pre-pass's
//! stratified estimate over the neighbourhood ([`stratified_sd`]), over
//! N_eff, the receivers its filter really averages.

use super::allocation::{nothing_seen_variance, stratified_sd};
use super::filter::FilterSupport;
use super::grid::{TexelGrid, along_line, neighbourhood_count, neighbourhood_mean, spread_min};
use super::line::{ContactLines, contact_lines};
use super::options::{AdaptiveOptions, MAX_REACH};
use super::prepass::PrePass;
use super::strata::Strata;
use super::width::sigma_in_texels;
use crate::atlas::Receivers;
use rayon::prelude::*;

/// Least reach, in texels, of the neighbourhood whose visibility spread
/// sets a receiver's ray count (16 pre-pass rays of one texel are too few).
const SD_REACH: u32 = 2;

/// Each receiver's filter and variances.
pub struct Bounds {
    /// The z_min the filter reads up to (filtered), or the spread z_min
    /// over the receiver's own support (unfiltered), bake units; INFINITY
    /// if none.
    pub z_min: Vec<f32>,
    /// Filter sigma in texels (0: not filtered).
    pub sigma_texels: Vec<f32>,
    /// The receivers filtered along a contact line ([`super::line`]).
    pub lines: ContactLines,
    /// One-ray variance before the filter (0: the pre-pass only).
    pub unfiltered: Vec<f32>,
    /// The same after the filter (over N_eff).
    pub filtered: Vec<f32>,
}

/// The bounds of every receiver (see the module doc).
pub fn bounds(
    receivers: &Receivers,
    grid: &TexelGrid,
    pre: &PrePass,
    o: &AdaptiveOptions,
) -> Bounds {
    let n = receivers.len();
    let inside = &pre.inside[..];
    let own = &pre.own_z[..];
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
    // z_min spread over each receiver's own support (2 sigma of its own
    // z_min, all of max_reach when it saw nothing): a receiver is filtered
    // no wider than the nearest occluder any texel under its filter saw.
    let support: Vec<u32> = (0..n).map(|r| support_of(own[r], r)).collect();
    let z = spread_min(receivers, grid, inside, own, &support);
    // The filter: the widest whose support's own z_min allow it.
    let (mut z_filter, sigma) = widest_filters(receivers, grid, inside, own, o, width);
    // Unfiltered: the spread z_min, as the allocation reads it.
    for ((zf, &s), &z) in z_filter.iter_mut().zip(&sigma).zip(&z) {
        if s <= 0.0 {
            *zf = z;
        }
    }
    // The visibility spread of the neighbourhood rather than the
    // receiver's own, so a count does not depend on the receiver's own
    // first rays. Measured: no change on the floor beside a wall (beyond
    // 0.35, AO bias -0.0046 with its own sd, -0.0049 with the
    // neighbourhood's, within that band's noise). The spread of a
    // stratified estimate, from the visible share and the strata's
    // crossings ([`stratified_sd`]).
    let strata = Strata::of(o.pre_rays);
    let own_sd: Vec<f32> = (0..n)
        .map(|r| {
            let visible = pre.sums[r].visible;
            stratified_sd(visible, o.pre_rays, pre.crossings[r] as u32, strata)
        })
        .collect();
    let sd_reach: Vec<u32> = support.iter().map(|&s| s.max(SD_REACH)).collect();
    let sd = neighbourhood_mean(receivers, grid, inside, &own_sd, &sd_reach);
    let lines = contact_lines(receivers, grid, inside, &sigma, o);
    let n_eff = FilterSupport {
        receivers,
        grid,
        inside,
        sigma_texels: &sigma,
        z_min: &z_filter,
        lines: Some(&lines),
    }
    .effective_neighbours();
    // A receiver whose neighbourhood saw nothing: the variance that all of
    // the neighbourhood's rays (pre_rays per receiver) seeing nothing
    // still allows, not none (its own 16 rays seeing nothing leave a
    // 1-in-10 occluder unseen). Receivers inside geometry: the pre-pass
    // only.
    let seen_nothing = z.iter().any(|z| z.is_infinite());
    let count = if seen_nothing {
        neighbourhood_count(receivers, grid, inside, &sd_reach)
    } else {
        Vec::new()
    };
    let (unfiltered, filtered) = (0..n)
        .map(|r| {
            if inside[r] {
                return (0.0, 0.0);
            }
            let v = if z[r].is_infinite() {
                nothing_seen_variance(o.pre_rays, count[r])
            } else {
                sd[r] * sd[r]
            };
            (v, v / n_eff[r].max(1.0))
        })
        .unzip();
    Bounds {
        z_min: z_filter,
        sigma_texels: sigma,
        lines,
        unfiltered,
        filtered,
    }
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
pub fn widest_filters(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
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
            along_line(receivers, grid, inside, r, reach, false, |j, d| {
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
            along_line(receivers, grid, inside, r, reach, true, |j, d| {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::adaptive::grid::flat_grid;

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
        let (z, sigma) = widest_filters(&rc, &grid, &inside, &own, &o, width);
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
}
