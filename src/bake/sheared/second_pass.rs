//! The second pass of one receiver: Monte Carlo over the cells Algorithm 1
//! cannot serve, on the receiver's own sparse sequence continued, and the
//! receiver's AO and SH from both.
//!
//! In: a [`Pass`] and a receiver's [`Pending`] (its marked cells). Out: the
//! rays to trace, pushed to a [`RayBatch`] ([`emit_brute_force`]), then
//! from their answers a [`ReceiverResult`] ([`finish`]).

use super::gather::filter_receiver;
use super::receiver::{CellSums, Pass, Pending, ReceiverResult, Scratch};
use super::types::{SPARSE_STREAM, Samples, ShearedOptions};
use crate::atlas::Receivers;
use crate::bake::{BakeParams, ReceiverRays};
use crate::sample::{CELL_COUNT, square_cell};
use crate::sh;
use crate::trace::{RayBatch, Tracer};
use glam::{Vec2, Vec3};

/// Receiver `r`'s AO and SH: the filtered cells' share in `pending`, plus
/// the second pass over its marked cells from the rays [`emit_brute_force`]
/// cast (`directions`, `occluded`, in that order).
pub(super) fn finish(
    f: &Pass,
    r: usize,
    pending: &Pending,
    directions: &[Vec3],
    occluded: &[bool],
) -> ReceiverResult {
    let n = f.receivers.normal[r];
    let Pending {
        mut occ_ao,
        mut occ_sh,
        marked,
        ..
    } = *pending;
    let inv_cells = 1.0 / CELL_COUNT as f32;
    let brute_rays = if marked != 0 {
        let (traced, cells) = brute_force_cells(f, r, marked, directions, occluded);
        for c in 0..CELL_COUNT {
            if marked & (1 << c) != 0 && cells.occ[c] > 0.0 {
                let inv = inv_cells / cells.w[c];
                occ_ao += cells.occ[c] * inv;
                for (acc, v) in occ_sh.iter_mut().zip(cells.occ_sh[c]) {
                    *acc += v * inv;
                }
            }
        }
        traced
    } else {
        0
    };
    let open_sh = sh::open_hemisphere(n);
    ReceiverResult {
        ao: (1.0 - occ_ao).clamp(0.0, 1.0),
        sh: std::array::from_fn(|i| open_sh[i] - occ_sh[i]),
        filtered: pending.filtered,
        brute: pending.brute,
        contact: pending.contact,
        no_hit: pending.no_hit,
        open: pending.open,
        brute_rays,
        z_min: pending.z_min,
        neighbours: pending.neighbours,
    }
}

/// The points of receiver `r`'s second pass in order: (point index, its
/// cell) for the cells set in `marked`.
///
/// The rays are the receiver's own sparse sequence continued: points
/// `0..64 m` (m = `cell_rays`) of the same Owen-scrambled Sobol sequence,
/// kept where they fall in a marked cell. Each aligned block of 64 points
/// of a (0,2)-sequence is a (0,6,2)-net, which puts exactly one point in
/// each of the 8x8 cells, so every marked cell gets exactly m points, and
/// those of the first K are the sparse rays already traced (reused, not
/// traced again). Together the points keep the sequence's stratification
/// across cells: with every cell marked this equals `--method mc` at 64 m
/// rays, where m rays drawn per cell independently erred more
/// (`docs/measurements/constants.md`, second_pass_points).
fn second_pass_points<'r>(
    rays: &'r ReceiverRays,
    cell_rays: u32,
    marked: u64,
) -> impl Iterator<Item = (u32, usize, Vec2)> + 'r {
    (0..CELL_COUNT as u32 * cell_rays.max(1)).filter_map(move |i| {
        let u = rays.point(i);
        let c = square_cell(u);
        (marked & (1 << c) != 0).then_some((i, c, u))
    })
}

/// The rays receiver `r`'s second pass traces, into `batch`: those of its
/// marked cells past the sparse ones (a direction below the geometric
/// plane blocked, to keep the order).
pub(super) fn emit_brute_force(f: &Pass, r: usize, pending: &Pending, batch: &mut RayBatch) {
    if pending.marked == 0 {
        return;
    }
    let (receivers, params) = (f.receivers, f.params);
    let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
    let k = f.samples.per_receiver;
    for (i, _, u) in second_pass_points(&rays, f.s.cell_rays, pending.marked) {
        if (i as usize) < k {
            continue;
        }
        let d = rays.direction_of(u);
        if d.dot(rays.geo_normal) > 0.0 {
            batch.push(rays.origin, d, params.max_distance);
        } else {
            batch.push_blocked(d);
        }
    }
}

/// The second pass for receiver `r`: Monte Carlo over the cells set in
/// `marked`, from the sparse samples and the traced rays
/// ([`emit_brute_force`]'s, in order). Returns the rays traced (those
/// above the geometric plane) and the cells' sums.
fn brute_force_cells(
    f: &Pass,
    r: usize,
    marked: u64,
    directions: &[Vec3],
    occluded: &[bool],
) -> (u32, CellSums) {
    let Pass {
        receivers,
        samples,
        s,
        params,
        ..
    } = *f;
    let mut cells = CellSums::new();
    // The sparse pass's sequence (stream 1).
    let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
    let geo = rays.geo_normal;
    let k = samples.per_receiver;
    let mut traced = 0u32;
    let mut next = directions.iter().zip(occluded);
    for (i, c, _) in second_pass_points(&rays, s.cell_rays, marked) {
        let (d, occluded) = if (i as usize) < k {
            let si = r * k + i as usize;
            let t = samples.t[si];
            (samples.dir[si], t < 0.0 || t <= params.max_distance)
        } else {
            let (&d, &hit) = next
                .next()
                .expect("one traced ray per point past the sparse ones");
            traced += (d.dot(geo) > 0.0) as u32;
            (d, hit)
        };
        cells.add(c, 1.0, occluded, d);
    }
    (traced, cells)
}

/// Debugging aid: per cell of receiver `r`, the filter weight, occluded
/// weight and brute-force mark, before the second pass.
#[doc(hidden)]
pub fn cell_estimates(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &ShearedOptions,
    params: &BakeParams,
    r: usize,
) -> Vec<(f32, f32, bool)> {
    let pass = Pass::new(receivers, samples, s, params).expect("k-d tree");
    let mut sc = Scratch::new();
    let pending = filter_receiver(&pass, r, &mut sc);
    let mut batch = RayBatch::new();
    emit_brute_force(&pass, r, &pending, &mut batch);
    let mut occluded = Vec::new();
    tracer.occluded_batch(&batch, &mut occluded);
    let (_, cells) = brute_force_cells(&pass, r, pending.marked, batch.directions(), &occluded);
    (0..CELL_COUNT)
        .map(|c| match pending.marked & (1 << c) != 0 {
            true => (cells.w[c], cells.occ[c], sc.brute[c]),
            false => (sc.sums.w[c], sc.sums.occ[c], sc.brute[c]),
        })
        .collect()
}
