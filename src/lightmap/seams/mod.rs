//! Seams: the two sides of every smooth chart border agree.
//!
//! In: the receiver meshes and their atlas, the dilated float images of a
//! page (AO, SH and the visibility layer). Out: the same images stitched
//! along the page's smooth seams, and the seam figures before and after.
//!
//! 1. [`find`]: the seams, where two triangles share an edge in world space
//!    but map it to different UVs, with vertex normals within
//!    [`SMOOTH_DEGREES`] at both ends and faces within [`FLAT_DEGREES`]
//!    (creases keep their jump);
//! 2. [`metric`]: the jump a viewer sees along them (bilinear lookups on
//!    both sides, weighted by world length);
//! 3. [`solve`]: least-squares stitching of the border and gutter texels
//!    in the seams' bilinear footprints;
//! 4. [`anchor`]: for seams whose sides lie on two pages, the target both
//!    pages' sides are stitched to (once every page is encoded, the job
//!    solves those seams' two sides together: `crate::job::across`).

pub mod anchor;
pub mod find;
pub mod metric;
mod reads;
pub mod solve;
pub mod solver;

pub use find::{CrossSeam, Seam};
pub use metric::SeamFigures;
pub use solve::Anchor;
pub use solve::StitchStats;

use super::filter::Filter;
use crate::sh::{SH_COUNT, VIS_COUNT};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// What happens at smooth seams (`--seams`): `Stitch`, least-squares
/// stitching of both sides ([`stitch_page`]), or `Off`, each side keeping
/// its own baked and dilated texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum SeamMode {
    #[default]
    Stitch,
    Off,
}

/// Seams whose two sides' vertex normals agree within this angle at both
/// ends are stitched (and measured); the seams issue's metric uses 10.
pub const SMOOTH_DEGREES: f32 = 10.0;

/// ... and whose two faces' geometric normals agree within this angle. An
/// edge shaded smooth across a crease of the geometry is a crease of the
/// contract's AO: each side's points see their own face's plane (the ray
/// origin is offset along the geometric normal, and the part of the
/// shading normal's hemisphere behind the face is occluded by it), so the
/// reference itself jumps there, more the further the faces turn, and
/// stitching such a seam moves both sides off the reference
/// (`probes/seam_sides`; `docs/measurements/constants.md`, FLAT_DEGREES).
pub const FLAT_DEGREES: f32 = 20.0;

/// Each channel's lowest and highest value (AO, the SH coefficients, the
/// visibility layer's) over a page before its solve: the solve keeps
/// every texel within it ([`stitch_page`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SolveRange {
    pub lo: Vec<f32>,
    pub hi: Vec<f32>,
}

impl SolveRange {
    /// The smallest range holding both (`self` alone when their channels
    /// differ: a carried range of another layer says nothing).
    pub fn union(&self, other: &SolveRange) -> SolveRange {
        if self.lo.len() != other.lo.len() {
            return self.clone();
        }
        let pick = |a: &[f32], b: &[f32], f: fn(f32, f32) -> f32| {
            a.iter().zip(b).map(|(&x, &y)| f(x, y)).collect()
        };
        SolveRange {
            lo: pick(&self.lo, &other.lo, f32::min),
            hi: pick(&self.hi, &other.hi, f32::max),
        }
    }
}

/// What stitching a page did, for the report.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct SeamReport {
    pub seams: usize,
    /// Total seam length, world units.
    pub length: f64,
    pub before: SeamFigures,
    pub after: SeamFigures,
    pub solve: StitchStats,
    /// Seams whose other side is on another page: this page's side
    /// against the shared target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_page: Option<CrossPageFigures>,
}

/// This page's side of its cross-page seams against their targets.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct CrossPageFigures {
    /// Anchor points (3 per texel of seam length).
    pub points: usize,
    /// Mean |AO lookup - AO target| before and after stitching.
    pub ao_before: f64,
    pub ao_after: f64,
}

/// Mean |AO lookup - AO target| over `anchors`.
pub(crate) fn anchor_gap(
    anchors: &[Anchor],
    width: u32,
    height: u32,
    ao: &[f32],
    filter: Filter,
) -> f64 {
    let sum: f64 = anchors
        .iter()
        .map(|a| {
            let v = filter.lookup1(ao, width, height, a.uv);
            (v - a.target[0]).abs() as f64
        })
        .sum();
    sum / anchors.len().max(1) as f64
}

/// The channels a page's solve holds: AO, the SH and, with `layer`, the
/// visibility layer's.
pub fn channels(layer: bool) -> usize {
    1 + SH_COUNT + if layer { VIS_COUNT } else { 0 }
}

/// Writes texel `t`'s channels ([`channels`]) into `out`: AO, then the
/// SH, then the layer's coefficients if `v` holds them.
pub(crate) fn write_channels(
    ao: &[f32],
    sh: &[[f32; SH_COUNT]],
    v: Option<&[[f32; VIS_COUNT]]>,
    t: usize,
    out: &mut [f32],
) {
    out[0] = ao[t];
    out[1..1 + SH_COUNT].copy_from_slice(&sh[t]);
    if let Some(v) = v {
        out[1 + SH_COUNT..].copy_from_slice(&v[t]);
    }
}

/// Stitches the page's images in place (AO clamped to [0, 1] after) along
/// `seams` (bake units; `diagonal` turns lengths into world units).
/// The texels marked `free` move (border and gutter texels: every texel
/// but the [`interior`] ones, and with the border fit its step cells'
/// taps); the others keep their values.
/// `anchors`: this page's side of seams that cross pages
/// ([`anchor::anchors`]), pulled to their targets; `fitted`: the border
/// fit's points ([`crate::lightmap::border`]), solved in the same system,
/// where a seam's rows (two-sided, and the anchors) are scaled by
/// `seam_scale`; `data_weight(t)`: the weight of texel t's data term (1,
/// less where an edge row holds its value: [`crate::lightmap::edge`]);
/// `filter`: the lookup every row reads through. `carried`: an earlier
/// bake's [`SolveRange`] of the page (`--reuse`), widened by the page's
/// own, so that a bake of only the texels an edit reaches (whose other
/// texels hold values inside the carried range) keeps the range a bake of
/// the whole page keeps. `changed`: in such a bake, the texels whose
/// inputs the edit changed (their values before the solve, the rows in
/// their cells), for [`Stitched::may_change`].
#[allow(clippy::too_many_arguments)]
pub fn stitch_page(
    seams: &[Seam],
    anchors: &[Anchor],
    fitted: &[Anchor],
    data_weight: &(dyn Fn(u32) -> f64 + Sync),
    seam_scale: f64,
    diagonal: f64,
    width: u32,
    height: u32,
    filter: Filter,
    free: &[bool],
    carried: Option<&SolveRange>,
    changed: Option<&[bool]>,
    ao: &mut [f32],
    sh: &mut [[f32; SH_COUNT]],
    visibility: Option<&mut [[f32; VIS_COUNT]]>,
) -> Stitched {
    let before = metric::measure(seams, width, height, ao, sh, filter);
    let gap_before = anchor_gap(anchors, width, height, ao, filter);
    let channels = channels(visibility.is_some());
    // The page's solve with `fixed` texels held and `baked` values, and
    // which of its unknowns read a texel of `seeds`.
    let stitch = |fixed: &dyn Fn(u32) -> bool,
                  baked: &(dyn Fn(u32, &mut [f32]) + Sync),
                  seeds: Option<&[bool]>| {
        solve::stitch(
            seams,
            anchors,
            fitted,
            width,
            height,
            seam_scale,
            channels,
            filter,
            fixed,
            data_weight,
            baked,
            seeds,
        )
    };
    // What an edit can change (`changed`): S1, the first solve's unknowns
    // reading a texel within one of a changed one (a row reads its cell's
    // four taps); W, the texels within two of S1 and the changed ones
    // (whether they are solved again); S2, the second solve's unknowns
    // reading a texel within one of W.
    let grow = |mask: &[bool], by: u32| reach(mask, width, height, by);
    let seeds = changed.map(|c| grow(c, 1));
    let (texels, values, solve, reached) = {
        let (ao, sh, v) = (&*ao, &*sh, visibility.as_deref());
        let baked = |t: u32, out: &mut [f32]| write_channels(ao, sh, v, t as usize, out);
        stitch(&|t| !free[t as usize], &baked, seeds.as_deref())
    };
    // An unknown within the solve's reach of a seed may change; one
    // within twice it is read by one that may.
    let mut reads = changed.map(|c| c.to_vec());
    let mut mark = |texels: &[u32], r: &Option<solve::Reads>, may: &mut [bool]| {
        let (Some(r), Some(reads)) = (r, &mut reads) else {
            return;
        };
        for (&t, &d) in texels.iter().zip(&r.depth) {
            may[t as usize] |= d <= r.reach;
            reads[t as usize] |= d != u32::MAX;
        }
        r.fixed.iter().for_each(|&t| reads[t as usize] = true);
    };
    let within = changed.map(|changed| {
        let mut s1 = changed.to_vec();
        mark(&texels, &reached, &mut s1);
        grow(&s1, 2)
    });
    let seeds = within.as_ref().map(|w| grow(w, 1));
    let mut visibility = visibility;
    // With the border fit, the solve keeps every channel within the range
    // the page held before it: the encoding's scale and offset cover each
    // coefficient's range over the page, and a gutter texel extrapolated
    // past it would coarsen every texel's quantization, the interior's
    // too (`docs/measurements/constants.md`, the solve's range).
    let range = (!fitted.is_empty()).then(|| {
        let extend = |(mut lo, mut hi): (Vec<f32>, Vec<f32>), t: usize| {
            let vis = visibility.as_deref().map_or(&[][..], |v| &v[t][..]);
            let all = std::iter::once(&ao[t]).chain(&sh[t]).chain(vis);
            for (c, &x) in all.enumerate() {
                lo[c] = lo[c].min(x);
                hi[c] = hi[c].max(x);
            }
            (lo, hi)
        };
        let empty = || {
            (
                vec![f32::INFINITY; channels],
                vec![f32::NEG_INFINITY; channels],
            )
        };
        // (min and max are exact in any order: the same on any thread count.)
        let (lo, hi) = (0..ao.len())
            .into_par_iter()
            .with_min_len(4096)
            .fold(empty, extend)
            .reduce(empty, |(lo, hi), (l2, h2)| {
                let lo = lo.iter().zip(&l2).map(|(a, b)| a.min(*b)).collect();
                let hi = hi.iter().zip(&h2).map(|(a, b)| a.max(*b)).collect();
                (lo, hi)
            });
        let own = SolveRange { lo, hi };
        carried.map_or_else(|| own.clone(), |c| own.union(c))
    });
    // Where the AO solved falls outside the range, clamping it leaves its
    // neighbours fitted to a value it no longer holds (a step into black:
    // the optimum overshoots on both sides). One step of an active set:
    // those texels keep their clamped values and the free texels within
    // two of them are solved again around them, from their baked values.
    let again = range.as_ref().and_then(|SolveRange { lo, hi }| {
        let over: Vec<u32> = (texels.iter().enumerate())
            .filter(|&(k, _)| !(lo[0]..=hi[0]).contains(&values[k * channels]))
            .map(|(_, &t)| t)
            .collect();
        (!over.is_empty()).then(|| around(&over, free, width, height))
    });
    // Solved texels not known (NaN, a bake of part of a page) count as
    // outside the range: whether the texels within two of them are solved
    // again is not known, so their saved values are NaN (every component
    // of the second solve holding one is not known).
    let unknown: Vec<u32> = (texels.iter().enumerate())
        .filter(|&(k, _)| values[k * channels].is_nan())
        .map(|(_, &t)| t)
        .collect();
    let undecided = (!unknown.is_empty()).then(|| around(&unknown, free, width, height));
    // The baked values of the texels solved again, by texel.
    let saved = again.as_ref().map(|again| {
        let mut slot = vec![u32::MAX; free.len()];
        let mut saved = vec![0.0f32; again.len() * channels];
        let v = visibility.as_deref();
        for (k, &t) in again.iter().enumerate() {
            slot[t as usize] = k as u32;
            write_channels(
                ao,
                sh,
                v,
                t as usize,
                &mut saved[k * channels..(k + 1) * channels],
            );
        }
        for &t in undecided.iter().flatten() {
            if let Some(k) = Some(slot[t as usize]).filter(|&k| k != u32::MAX) {
                saved[k as usize * channels..][..channels].fill(f32::NAN);
            }
        }
        (slot, saved)
    });
    let vis = visibility.as_deref_mut();
    write_solved(&texels, &values, range.as_ref(), ao, sh, vis);
    let mut solve = solve;
    let mut may_change = within;
    if let Some((slot, saved)) = saved {
        let (texels, values, second, reached) = {
            let (ao, sh, v) = (&*ao, &*sh, visibility.as_deref());
            stitch(
                &|t| slot[t as usize] == u32::MAX,
                &|t, out| match slot[t as usize] {
                    u32::MAX => write_channels(ao, sh, v, t as usize, out),
                    k => out.copy_from_slice(&saved[k as usize * channels..][..channels]),
                },
                seeds.as_deref(),
            )
        };
        write_solved(&texels, &values, range.as_ref(), ao, sh, visibility);
        solve.max_iterations = solve.max_iterations.max(second.max_iterations);
        solve.converged &= second.converged;
        if let Some(may) = &mut may_change {
            mark(&texels, &reached, may);
        }
    }
    let after = metric::measure(seams, width, height, ao, sh, filter);
    let cross_page = (!anchors.is_empty()).then(|| CrossPageFigures {
        points: anchors.len(),
        ao_before: gap_before,
        ao_after: anchor_gap(anchors, width, height, ao, filter),
    });
    let report = SeamReport {
        seams: seams.len(),
        length: seams.iter().map(|s| s.length as f64).sum::<f64>() * diagonal,
        before,
        after,
        solve,
        cross_page,
    };
    Stitched {
        report,
        range,
        may_change,
        reads,
    }
}

/// What [`stitch_page`] did.
pub struct Stitched {
    pub report: SeamReport,
    /// The range the solve kept (none without the border fit's points).
    pub range: Option<SolveRange>,
    /// With `changed`: per texel, whether the edit can change its value
    /// (it changed, or a solve's value there reads one that did).
    pub may_change: Option<Vec<bool>>,
    /// With `changed`: per texel, whether a value that may change reads it
    /// (a rebake must know it), as far as the structure known tells.
    pub reads: Option<Vec<bool>>,
}

/// The solve's values (`channels` per texel of `texels`) into the page's
/// images, each channel clamped to `range` where given and AO to [0, 1].
fn write_solved(
    texels: &[u32],
    values: &[f32],
    range: Option<&SolveRange>,
    ao: &mut [f32],
    sh: &mut [[f32; SH_COUNT]],
    mut visibility: Option<&mut [[f32; VIS_COUNT]]>,
) {
    let channels = values.len() / texels.len().max(1);
    let mut clamped = Vec::new();
    for (k, &t) in texels.iter().enumerate() {
        let (t, mut at) = (t as usize, &values[k * channels..(k + 1) * channels]);
        if let Some(SolveRange { lo, hi }) = range {
            clamped.clear();
            clamped.extend((0..channels).map(|c| at[c].clamp(lo[c], hi[c])));
            at = &clamped;
        }
        ao[t] = at[0].clamp(0.0, 1.0);
        sh[t].copy_from_slice(&at[1..1 + SH_COUNT]);
        // c0 = Y0 AO holds for every baked and target value, so for the
        // solve's too; the clamp keeps it (a white environment relights
        // as the AO). One-sided anchors overshoot [0, 1] more often.
        sh[t][0] += crate::sh::K0 as f32 * (ao[t] - at[0]);
        if let Some(v) = visibility.as_deref_mut() {
            v[t].copy_from_slice(&at[1 + SH_COUNT..]);
        }
    }
}

/// The `free` texels of a `width` x `height` page within two texels
/// (Chebyshev) of one of `over`, less those: in texel order.
fn around(over: &[u32], free: &[bool], width: u32, height: u32) -> Vec<u32> {
    let mut mark = vec![false; free.len()];
    for &t in over {
        let (x, y) = (t % width, t / width);
        for j in y.saturating_sub(2)..=(y + 2).min(height - 1) {
            for i in x.saturating_sub(2)..=(x + 2).min(width - 1) {
                mark[(j * width + i) as usize] = true;
            }
        }
    }
    for &t in over {
        mark[t as usize] = false;
    }
    (0..free.len() as u32)
        .filter(|&t| mark[t as usize] && free[t as usize])
        .collect()
}

/// A grey map of the page for `--debug-dir`: each texel under one of the
/// metric's `points` (on either side) shows the largest AO jump there,
/// white at 0.1 or more; black elsewhere.
pub fn jump_map(points: &[metric::SeamPoint], width: u32, height: u32) -> Vec<u8> {
    let mut img = vec![0u8; (width * height) as usize];
    let texel = |uv: [f32; 2]| {
        let x = ((uv[0] * width as f32) as i64).clamp(0, width as i64 - 1);
        let y = ((uv[1] * height as f32) as i64).clamp(0, height as i64 - 1);
        (y * width as i64 + x) as usize
    };
    for p in points {
        let v = ((p.ao_jump / 0.1).min(1.0) * 255.0).round() as u8;
        for uv in [p.a, p.b] {
            let i = texel(uv);
            img[i] = img[i].max(v.max(1));
        }
    }
    img
}

/// Whether texel `t` is interior: covered (a receiver of its own) and so
/// is every texel of its 3 x 3 neighbourhood. Stitching moves only the
/// others (border and gutter texels), so the receivers' own estimates
/// inside every chart stay as baked. (Fixing every texel whose centre lies
/// inside a triangle instead leaves too little to move:
/// `docs/measurements/constants.md`, interior texels.)
pub fn interior(covered: &[bool], width: u32, height: u32, t: u32) -> bool {
    interior_within(covered, width, height, t, 1)
}

/// Whether texel `t` and every texel within `reach` of it (Chebyshev) are
/// covered, none of them past the page's edge. `reach` 1: [`interior`].
fn interior_within(covered: &[bool], width: u32, height: u32, t: u32, reach: u32) -> bool {
    let (xs, ys, clipped) = window(t, width, height, reach);
    !clipped
        && ys
            .clone()
            .all(|j| xs.clone().all(|i| covered[(j * width + i) as usize]))
}

/// The columns and rows within `reach` (Chebyshev) of texel `t` of a
/// `width` x `height` page, clipped to the page, and whether it clipped
/// them.
fn window(
    t: u32,
    width: u32,
    height: u32,
    reach: u32,
) -> (
    std::ops::RangeInclusive<u32>,
    std::ops::RangeInclusive<u32>,
    bool,
) {
    let (x, y) = (t % width, t / width);
    let (x0, y0) = (x.saturating_sub(reach), y.saturating_sub(reach));
    let (x1, y1) = ((x + reach).min(width - 1), (y + reach).min(height - 1));
    let clipped = x0 + reach != x || y0 + reach != y || x1 != x + reach || y1 != y + reach;
    (x0..=x1, y0..=y1, clipped)
}

/// The border band of a `width` x `height` page: per texel, whether it is
/// not [`interior`] (what the stitch moves, and the border fit fits).
pub fn band(covered: &[bool], width: u32, height: u32) -> Vec<bool> {
    band_within(covered, width, height, 1)
}

/// The border band for a lookup reaching `reach` texels: per texel,
/// whether some texel within `reach` (Chebyshev, the page's edge
/// included) is not covered. `reach` 1: [`band`].
pub(crate) fn band_within(covered: &[bool], width: u32, height: u32, reach: u32) -> Vec<bool> {
    (0..width * height)
        .into_par_iter()
        .map(|t| !interior_within(covered, width, height, t, reach))
        .collect()
}

/// Per texel of a `width` x `height` page, whether a covered texel lies
/// within `reach` (Chebyshev): every texel a lookup on the surface reads.
/// Any mask grows so (a bake of part of a page grows its texels by tens).
/// The square is rows, then columns: O(reach) a texel, not O(reach^2).
pub fn reach(covered: &[bool], width: u32, height: u32, reach: u32) -> Vec<bool> {
    let (w, h, by) = (width as usize, height as usize, reach as usize);
    let rows: Vec<bool> = (0..w * h)
        .into_par_iter()
        .map(|t| {
            let (x, y) = (t % w, t / w);
            (x.saturating_sub(by)..=(x + by).min(w - 1)).any(|x| covered[y * w + x])
        })
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|t| {
            let (x, y) = (t % w, t / w);
            (y.saturating_sub(by)..=(y + by).min(h - 1)).any(|y| rows[y * w + x])
        })
        .collect()
}
