//! The atlas grid as a neighbourhood: which receiver sits at each texel,
//! the receivers along a texel's row or column, and the separable
//! reductions the bounds take over them (minimum, mean, count).
//!
//! In: [`Receivers`] (texels, normals), the receivers inside geometry,
//! per-receiver values and reaches in texels. Out: per receiver, the
//! reduction over its compatible neighbours within its reach, rows then
//! columns ([`spreads_to`]: normals within 25 degrees, not inside).

use super::options::MAX_REACH;
use crate::atlas::Receivers;
use glam::Vec3;
use rayon::prelude::*;

/// Normal agreement of the z_min spread (cos 25 degrees, the leak rule's).
const SPREAD_AGREEMENT: f32 = 0.906;

/// Shading-normal agreement of the filter's lenders, on contact lines
/// too: cos 10 degrees (the leak rule's 25 let too much through). The
/// filter averages occlusion projected on SH in world axes, so a lender
/// whose normal turns away lends a lobe turned with it: on curved surfaces
/// the L1 band blurs. 10 degrees brings L1 and L2 under Monte Carlo's
/// error for 1% more rays (`docs/measurements/constants.md`,
/// LENDER_NORMAL_AGREEMENT).
pub const LENDER_NORMAL_AGREEMENT: f32 = 0.985;

/// Receiver index of each atlas texel.
pub struct TexelGrid {
    width: usize,
    height: usize,
    receiver: Vec<u32>,
}

const NO_RECEIVER: u32 = u32::MAX;

impl TexelGrid {
    pub fn new(receivers: &Receivers) -> TexelGrid {
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
    pub fn offset(
        &self,
        receivers: &Receivers,
        r: usize,
        k: isize,
        vertical: bool,
    ) -> Option<usize> {
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
    pub fn line(
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

/// A separable reduction over the compatible ([`spreads_to`]) receivers within `reach` texels, rows then columns: `fold` over the
/// values (the receiver's own included), then `finish` with the count.
#[allow(clippy::too_many_arguments)]
fn separable(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
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
                let (acc, count) = grid
                    .line(receivers, r, reach[r] as usize, vertical)
                    .filter(|&(j, _)| spreads_to(receivers, inside, r, n, j))
                    .fold((init, 0u32), |(a, c), (j, _)| (fold(a, src[j]), c + 1));
                finish(acc, count)
            })
            .collect()
    };
    let rows = pass(values, false);
    pass(&rows, true)
}

/// Calls `f(j, w)` for the receivers a filter along receiver `r`'s row
/// (`vertical` false) or column averages: `r` itself with w = 1, then
/// each side's run outward up to `reach` texels, `weight(j, k)` giving
/// the weight of receiver j `k` texels away or `None` where the run ends
/// (a neighbour that does not lend; a missing one, a chart border, ends
/// it too). Both sides keep the shorter run's length: the weights stay
/// centred on r where a border or a rejected neighbour cuts one side (a
/// one-sided average of a gradient is biased by the gradient times the
/// offset).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn symmetric_runs(
    grid: &TexelGrid,
    receivers: &Receivers,
    r: usize,
    reach: usize,
    vertical: bool,
    weight: impl Fn(usize, usize) -> Option<f32>,
    mut f: impl FnMut(usize, f32),
) {
    let side = |dir: isize, out: &mut [(usize, f32); MAX_REACH as usize]| -> usize {
        for k in 1..=reach {
            let Some(j) = grid.offset(receivers, r, dir * k as isize, vertical) else {
                return k - 1;
            };
            let Some(w) = weight(j, k) else {
                return k - 1;
            };
            out[k - 1] = (j, w);
        }
        reach
    };
    let mut lo = [(0usize, 0.0f32); MAX_REACH as usize];
    let mut hi = [(0usize, 0.0f32); MAX_REACH as usize];
    let k = side(-1, &mut lo).min(side(1, &mut hi));
    f(r, 1.0);
    for (&(a, wa), &(b, wb)) in lo[..k].iter().zip(&hi[..k]) {
        f(a, wa);
        f(b, wb);
    }
}

/// Calls `f(j, d)` for every receiver j at most `reach` texels (d of them)
/// from receiver `r` along its row (`vertical` false) or column that
/// counts in its neighbourhood ([`spreads_to`], as [`separable`] takes
/// them).
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn along_line(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    r: usize,
    reach: usize,
    vertical: bool,
    mut f: impl FnMut(usize, usize),
) {
    let n = receivers.normal[r];
    for (j, d) in grid.line(receivers, r, reach, vertical) {
        if spreads_to(receivers, inside, r, n, j) {
            f(j, d);
        }
    }
}

/// Whether receiver `j` counts in receiver `r`'s neighbourhood (normal
/// `n`) for the bounds: itself, or outside geometry with a normal within
/// [`SPREAD_AGREEMENT`].
#[inline]
fn spreads_to(receivers: &Receivers, inside: &[bool], r: usize, n: Vec3, j: usize) -> bool {
    j == r || (!inside[j] && receivers.normal[j].dot(n) >= SPREAD_AGREEMENT)
}

/// The number of compatible receivers within `reach` texels of each
/// receiver (the support of [`neighbourhood_mean`]), its own included.
pub(crate) fn neighbourhood_count(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    reach: &[u32],
) -> Vec<f32> {
    let ones = vec![1.0f32; receivers.len()];
    separable(
        receivers,
        grid,
        inside,
        &ones,
        reach,
        |a, v| a + v,
        0.0,
        |s, _| s,
    )
}

/// z_min spread: the minimum of the receivers' own z_min over the
/// compatible receivers within each one's `reach` texels, its own included.
pub(crate) fn spread_min(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    own: &[f32],
    reach: &[u32],
) -> Vec<f32> {
    separable(
        receivers,
        grid,
        inside,
        own,
        reach,
        f32::min,
        f32::INFINITY,
        |m, _| m,
    )
}

/// The mean of `values` over the compatible receivers within `reach`
/// texels (rows, then columns of row means).
pub fn neighbourhood_mean(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    values: &[f32],
    reach: &[u32],
) -> Vec<f32> {
    separable(
        receivers,
        grid,
        inside,
        values,
        reach,
        |a, v| a + v,
        0.0,
        |s, c| s / c.max(1) as f32,
    )
}

/// A flat `side` x `side` grid of receivers, one per texel, footprint 1.
#[cfg(test)]
pub(crate) fn flat_grid(side: u32) -> Receivers {
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
        center_inside: vec![true; n],
        overlapping_texels: 0,
        first_overlap: None,
    }
}
