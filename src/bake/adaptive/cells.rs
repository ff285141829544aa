//! Contact receivers per hemisphere cell: the paper's per-cell decision
//! (Algorithm 1: filter a cell where its neighbours give it enough
//! weight, brute-force it where they do not) for the receivers the
//! filter leaves alone.
//!
//! In: [`Receivers`], a [`Tracer`], the [`TexelGrid`], per receiver its
//! ray count, inside mark, own z_min and what its first rays saw
//! ([`FirstRays`], from the pre-pass and the adaptive pass), the split
//! receivers ([`splits`]), [`AdaptiveOptions`], [`BakeParams`]. Out: per
//! split receiver the rays it cast and its 10 values (AO and the occluded
//! SH share, as an unfiltered receiver lends them to the filter,
//! [`super::sums::below_compensated`]).
//!
//! A receiver in contact (its filter under half a texel) is split into the
//! 4x4 cells of its sequence's square. Its first [`FIRST`] rays (4 per
//! cell: the scrambled sequence's first 64 points are a (0,6,2)-net) ask
//! whether they hit nearer than its far depth ([`far_depth`]: where a
//! filter of [`FAR_SIGMA`] texels is allowed). A cell where one did, or
//! where a ray lies below the geometric plane, is *near*: it gets the rest
//! of the receiver's count (each near cell the same share of it, so the
//! near cells' rays are Monte Carlo at the receiver's count). A *far* cell
//! keeps its 4 rays and takes its occluded fraction from the receivers
//! within [`FAR_REACH`] texels whose same cell is far too (Gaussian
//! weights of [`FAR_SIGMA`] texels on the tangent-plane offset, times the
//! lender's rays in the cell, through the leak rule and the filter's
//! normal agreement, within the far depth). The SH estimate weights each
//! of the cell's own rays by that fraction, with the open projection as a
//! control variate ([`sh::occluded_share`]), so closed and open receivers
//! stay exact.

use super::filter::LENDER_NORMAL_AGREEMENT;
use super::grid::TexelGrid;
use super::options::AdaptiveOptions;
use super::sums::{CHUNK, below_fraction};
use crate::atlas::Receivers;
use crate::bake::sheared::lends_rays;
use crate::bake::{BakeParams, ReceiverRays};
use crate::sh::{self, SH_COUNT};
use crate::trace::{Closest, Hit, RayBatch, Tracer, for_each_receiver, for_each_receiver_query};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// The rays every cell of a split receiver gets: its sequence's first
/// points, 4 per cell.
pub const FIRST: u32 = 64;
/// Cells of the hemisphere (4 x 4 of the square).
pub const CELLS: usize = 16;
/// The far cells' filter width in texels; a cell is far when nothing in
/// it lies nearer than the depth that allows it.
pub const FAR_SIGMA: f32 = 1.0;
/// Texels a far cell's filter reads on each side (2 sigma).
pub const FAR_REACH: isize = 2;

/// The cell of a point of the square.
#[inline]
pub fn cell(u: Vec2) -> usize {
    let x = ((u.x * 4.0) as usize).min(3);
    let y = ((u.y * 4.0) as usize).min(3);
    y * 4 + x
}

/// The depth below which an occluder makes a cell of a receiver with
/// footprint `fp` near: where its filter could be [`FAR_SIGMA`] texels
/// wide (z = 2 mu Omega_h sigma), at most `exact` (the pre-pass's cut); `exact` for a
/// footprint that is not positive and finite.
#[inline]
pub fn far_depth(fp: f32, o: &AdaptiveOptions, exact: f32) -> f32 {
    let d = fp * 2.0 * o.mu * o.omega_h * FAR_SIGMA;
    if d.is_finite() && d > 0.0 {
        d.min(exact)
    } else {
        exact
    }
}

/// What a receiver's first [`FIRST`] rays saw, one bit per ray.
#[derive(Clone, Copy, Debug, Default)]
pub struct FirstRays {
    /// Occluded (below the plane included).
    pub hits: u64,
    /// Below the plane, or (where the query asked) hit nearer than the
    /// receiver's far depth.
    pub near: u64,
    /// Below the plane.
    pub below: u64,
}

impl FirstRays {
    /// Records ray `i` (nothing past [`FIRST`]).
    #[inline]
    pub fn set(&mut self, i: u32, hit: bool, near: bool) {
        if i < FIRST {
            let b = 1u64 << i;
            if hit {
                self.hits |= b;
            }
            if near {
                self.near |= b;
            }
        }
    }

    /// Records ray `i` below the plane: occluded, near.
    #[inline]
    pub fn set_below(&mut self, i: u32) {
        if i < FIRST {
            self.set(i, true, true);
            self.below |= 1 << i;
        }
    }

    #[inline]
    pub fn is_below(&self, i: u32) -> bool {
        self.below >> i & 1 == 1
    }

    #[inline]
    fn hit(&self, i: u32) -> bool {
        self.hits >> i & 1 == 1
    }

    #[inline]
    fn is_near(&self, i: u32) -> bool {
        self.near >> i & 1 == 1
    }
}

/// Which receivers are split: in contact (not filtered), not inside, with
/// more rays than every cell's first ones, when the pre-pass casts no more
/// than those.
pub fn splits(sigma_texels: &[f32], inside: &[bool], rays: &[u32], o: &AdaptiveOptions) -> Vec<u32> {
    if o.pre_rays > FIRST {
        return Vec::new();
    }
    (0..rays.len())
        .filter(|&r| sigma_texels[r] <= 0.0 && !inside[r] && rays[r] > FIRST)
        .map(|r| r as u32)
        .collect()
}

/// A split receiver's rays as they are traced.
#[derive(Clone, Copy, Debug, Default)]
pub struct SplitRays {
    pub first: FirstRays,
    /// Its near cells, one bit each.
    pub near: u16,
    /// Over the near cells' rays: visible ones, and the SH sums of the
    /// occluded and of all ([`sh::occluded_share`]).
    visible: u32,
    occ: [f32; SH_COUNT],
    all: [f32; SH_COUNT],
}

impl SplitRays {
    /// Rays cast for a receiver of count `rays`: every cell's first, the
    /// rest in the near cells.
    pub fn cast(&self, rays: u32) -> u32 {
        FIRST + (rays - FIRST) / CELLS as u32 * self.near.count_ones()
    }

    #[inline]
    fn add(&mut self, d: Vec3, occluded: bool) {
        sh::accumulate(&mut self.all, 1.0, d);
        if occluded {
            sh::accumulate(&mut self.occ, 1.0, d);
        } else {
            self.visible += 1;
        }
    }
}

/// Traces the split receivers (`split`, receiver indices): rays from
/// `pre_rays` to [`FIRST`] as closest hits cut at the far depth, which
/// decide the near cells, then the rest of each one's count in its near
/// cells. `pre[r]`: what the pre-pass's rays of receiver r saw.
#[allow(clippy::too_many_arguments)]
pub fn split_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    split: &[u32],
    pre: &[FirstRays],
    rays: &[u32],
    exact: f32,
    o: &AdaptiveOptions,
    p: &BakeParams,
) -> Vec<SplitRays> {
    let far = |r: usize| far_depth(receivers.footprint[r], o, exact);
    let t_max = p.max_distance;
    let mut states: Vec<SplitRays> = split
        .iter()
        .map(|&r| SplitRays {
            first: pre[r as usize],
            ..Default::default()
        })
        .collect();
    for_each_receiver_query::<Closest, SplitRays>(
        tracer,
        &mut states,
        CHUNK,
        |k, _, batch: &mut RayBatch| {
            let r = split[k] as usize;
            let ray = ReceiverRays::new(receivers, r, p.seed);
            for i in o.pre_rays..FIRST {
                let d = ray.direction(i);
                if d.dot(ray.geo_normal) <= 0.0 {
                    batch.push_blocked(d);
                } else {
                    batch.push_within(ray.origin, d, t_max, far(r));
                }
            }
        },
        |k, s, dirs, hits: &[Option<Hit>]| {
            let r = split[k] as usize;
            let (far, geo) = (far(r), receivers.geo_normal[r]);
            for (i, (&d, hit)) in (o.pre_rays..FIRST).zip(dirs.iter().zip(hits)) {
                if d.dot(geo) <= 0.0 {
                    s.first.set_below(i);
                } else if let Some(h) = hit {
                    s.first.set(i, true, h.distance_within(t_max, far) < far);
                }
            }
            let ray = ReceiverRays::new(receivers, r, p.seed);
            let cells: [u8; FIRST as usize] = std::array::from_fn(|i| cell(ray.point(i as u32)) as u8);
            for i in 0..FIRST {
                if s.first.is_near(i) {
                    s.near |= 1 << cells[i as usize];
                }
            }
            for i in 0..FIRST {
                if s.near >> cells[i as usize] & 1 == 1 {
                    let d = ray.direction(i);
                    let hit = s.first.hit(i);
                    s.add(d, hit);
                }
            }
        },
        &|_| {},
    );
    for_each_receiver(
        tracer,
        &mut states,
        CHUNK,
        |k, s, batch| {
            let r = split[k] as usize;
            let ray = ReceiverRays::new(receivers, r, p.seed);
            for i in FIRST..rays[r] {
                let u = ray.point(i);
                if s.near >> cell(u) & 1 == 1 {
                    let d = ray.direction_of(u);
                    if d.dot(ray.geo_normal) <= 0.0 {
                        batch.push_blocked(d);
                    } else {
                        batch.push(ray.origin, d, t_max);
                    }
                }
            }
        },
        |_, s, dirs, occluded| {
            for (&d, &o) in dirs.iter().zip(occluded) {
                s.add(d, o);
            }
        },
        &|_| {},
    );
    states
}

/// What a receiver lends split receivers' far cells: per cell its first
/// rays and their hits, and the cells it may lend.
#[derive(Clone, Copy, Debug, Default)]
pub struct Loan {
    rays: [u8; CELLS],
    hits: [u8; CELLS],
    far: u16,
}

/// The loans of every receiver within [`FAR_REACH`] texels of a split one
/// (default elsewhere): the cells with no ray below its plane. Whether a
/// lender's own rays hit near does not count: choosing lenders by what
/// their rays saw biases the average towards the open (lenders whose
/// rays missed a near occluder are the brighter ones).
#[allow(clippy::too_many_arguments)]
pub fn loans(
    receivers: &Receivers,
    grid: &TexelGrid,
    split: &[u32],
    states: &[SplitRays],
    first: &[FirstRays],
    rays: &[u32],
    seed: u64,
) -> Vec<Loan> {
    let n = receivers.len();
    // Per receiver: the index of its split state + 1, or 0.
    let mut split_of = vec![0u32; n];
    let mut needed = vec![false; n];
    for (k, &r) in split.iter().enumerate() {
        split_of[r as usize] = k as u32 + 1;
        for dy in -FAR_REACH..=FAR_REACH {
            for dx in -FAR_REACH..=FAR_REACH {
                if let Some(j) = grid.at(receivers, r as usize, dx, dy) {
                    needed[j] = true;
                }
            }
        }
    }
    (0..n)
        .into_par_iter()
        .with_min_len(256)
        .map(|j| {
            if !needed[j] {
                return Loan::default();
            }
            let bits = match split_of[j] {
                0 => first[j],
                k => states[k as usize - 1].first,
            };
            let mut loan = Loan::default();
            let mut below = 0u16;
            let ray = ReceiverRays::new(receivers, j, seed);
            for i in 0..rays[j].min(FIRST) {
                let c = cell(ray.point(i));
                loan.rays[c] += 1;
                loan.hits[c] += bits.hit(i) as u8;
                if bits.is_below(i) {
                    below |= 1 << c;
                }
            }
            loan.far = !below;
            loan
        })
        .collect()
}

/// The 10 values of each split receiver (see the module doc): near cells
/// from their own rays, far cells' occluded fraction from the loans.
#[allow(clippy::too_many_arguments)]
pub fn values(
    receivers: &Receivers,
    grid: &TexelGrid,
    split: &[u32],
    states: &[SplitRays],
    loans: &[Loan],
    inside: &[bool],
    rays: &[u32],
    exact: f32,
    o: &AdaptiveOptions,
    seed: u64,
) -> Vec<[f32; 10]> {
    let rc = receivers;
    split
        .par_iter()
        .zip(states)
        .with_min_len(64)
        .map(|(&r, s)| {
            let r = r as usize;
            let (n, geo, fp, pr) = (rc.normal[r], rc.geo_normal[r], rc.footprint[r], rc.position[r]);
            let far = far_depth(fp, o, exact);
            let far_cells = !s.near;
            let inv2s2 = 1.0 / (2.0 * (FAR_SIGMA * fp).powi(2));
            // A lender: not inside, within the far depth, through the
            // leak rule and the normal agreement; its weight.
            let lender = |dx: isize, dy: isize| -> Option<(usize, f32)> {
                let j = grid.at(rc, r, dx, dy)?;
                let rel = rc.position[j] - pr;
                if inside[j]
                    || !(rel.length() <= far)
                    || !lends_rays(rel, n, geo, rc.normal[j], rc.geo_normal[j], fp)
                    || rc.normal[j].dot(n) < LENDER_NORMAL_AGREEMENT
                {
                    return None;
                }
                let t = rel - geo * rel.dot(geo);
                Some((j, (-t.length_squared() * inv2s2).exp()))
            };
            let own = &loans[r];
            let (mut num, mut den) = ([0.0f32; CELLS], [0.0f32; CELLS]);
            for c in 0..CELLS {
                num[c] = own.hits[c] as f32;
                den[c] = own.rays[c] as f32;
            }
            // Lenders in opposite pairs, each cell lent by both or
            // neither, so the weights stay centred on the receiver (a
            // one-sided average of a gradient is biased by it: beside a
            // wall, the lenders nearer it have that cell near).
            for dy in 0..=FAR_REACH {
                for dx in -FAR_REACH..=FAR_REACH {
                    if dy == 0 && dx <= 0 {
                        continue;
                    }
                    let (Some((a, wa)), Some((b, wb))) = (lender(dx, dy), lender(-dx, -dy)) else {
                        continue;
                    };
                    let (la, lb) = (&loans[a], &loans[b]);
                    let mut cells = far_cells & la.far & lb.far;
                    while cells != 0 {
                        let c = cells.trailing_zeros() as usize;
                        cells &= cells - 1;
                        num[c] += wa * la.hits[c] as f32 + wb * lb.hits[c] as f32;
                        den[c] += wa * la.rays[c] as f32 + wb * lb.rays[c] as f32;
                    }
                }
            }
            let occluded: [f32; CELLS] =
                std::array::from_fn(|c| if den[c] > 0.0 { num[c] / den[c] } else { 0.0 });
            // Near cells: Monte Carlo at the receiver's count; far cells:
            // a sixteenth each, their own first rays' Y weighted by the
            // cell's filtered occluded fraction.
            let per_ray = 1.0 / rays[r] as f32;
            let per_first = 1.0 / FIRST as f32;
            let mut visible = s.visible as f32 * per_ray;
            let mut occ = s.occ.map(|v| v * per_ray);
            let mut all = s.all.map(|v| v * per_ray);
            let ray = ReceiverRays::new(rc, r, seed);
            for i in 0..FIRST {
                let u = ray.point(i);
                let c = cell(u);
                if far_cells >> c & 1 == 1 {
                    let d = ray.direction_of(u);
                    visible += (1.0 - occluded[c]) * per_first;
                    sh::accumulate(&mut occ, occluded[c] * per_first, d);
                    sh::accumulate(&mut all, per_first, d);
                }
            }
            let open = sh::open_hemisphere(n);
            let share = sh::occluded_share(&open, &occ, &all, 1.0, visible);
            let below = sh::below_plane(n, geo);
            let mut v = [0.0f32; 10];
            v[0] = visible + below_fraction(n, geo);
            for i in 0..SH_COUNT {
                v[1 + i] = share[i] + below[i];
            }
            v
        })
        .collect()
}
