//! The two passes over all receivers: the sparse pass (K rays per
//! receiver, closest hits kept) and the filter pass (every receiver
//! filtered from its neighbours' samples, in parallel).
//!
//! In: [`Receivers`] in locality order, a [`Tracer`], [`ShearedOptions`],
//! [`BakeParams`]. Out: [`Samples`], then a [`Bake`] and [`ShearedStats`].

use super::gather::filter_receiver;
use super::receiver::{Pass, Pending, ReceiverResult, Scratch};
use super::second_pass::{emit_brute_force, finish};
use super::types::{SPARSE_STREAM, Samples, ShearedOptions, ShearedStats};
use crate::atlas::Receivers;
use crate::bake::{Bake, BakeParams, ReceiverRays};
use crate::error::Result;
use crate::sample::{CELL_COUNT, square_cell};
use crate::trace::{Closest, Tracer, for_each_receiver, for_each_receiver_query};
use glam::Vec3;

/// How far sparse rays are traced: the max distance plus the widest gather
/// reach, so an occluder within the max distance of a *receiver* is found
/// by every neighbour whose rays it lends (the paper traces unbounded rays
/// and applies the distance test per receiver, Section 5).
pub fn sparse_t_max(receivers: &Receivers, s: &ShearedOptions, params: &BakeParams) -> f32 {
    let widest = receivers.footprint.iter().copied().fold(0.0f32, f32::max);
    params.max_distance + (s.gather_radius * widest).min(params.max_distance)
}

/// Casts the sparse rays.
pub fn sparse_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    s: &ShearedOptions,
    params: &BakeParams,
) -> Samples {
    let t_max = sparse_t_max(receivers, s, params);
    let k = s.sparse_rays as usize;
    let n = receivers.len();
    let mut dir = vec![Vec3::ZERO; n * k];
    let mut t = vec![0.0f32; n * k];
    let mut cell = vec![0u8; n * k];
    let mut hit_normal = vec![Vec3::ZERO; n * k];
    const CHUNK: usize = 64;
    // Per receiver, its k samples' slots.
    let mut slots: Vec<_> = dir
        .chunks_mut(k.max(1))
        .zip(t.chunks_mut(k.max(1)))
        .zip(cell.chunks_mut(k.max(1)))
        .zip(hit_normal.chunks_mut(k.max(1)))
        .collect();
    for_each_receiver_query::<Closest, _>(
        tracer,
        &mut slots,
        CHUNK,
        |r, _, batch| {
            let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
            for i in 0..k {
                let d = rays.direction(i as u32);
                if d.dot(rays.geo_normal) <= 0.0 {
                    batch.push_blocked(d);
                } else {
                    batch.push(rays.origin, d, t_max);
                }
            }
        },
        |r, (((dirs, ts), cells), normals), directions, hits| {
            let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
            for (i, (&d, &hit)) in directions.iter().zip(hits).enumerate() {
                cells[i] = square_cell(rays.point(i as u32)) as u8;
                dirs[i] = d;
                ts[i] = if d.dot(rays.geo_normal) <= 0.0 {
                    -1.0
                } else if let Some(h) = hit {
                    normals[i] = tracer.hit_normal(h);
                    h.distance_within(t_max, t_max)
                } else {
                    f32::INFINITY
                };
            }
        },
        &|_| {},
    );
    drop(slots);
    Samples {
        per_receiver: k,
        dir,
        t,
        cell,
        hit_normal,
    }
}

/// Filters every receiver from the sparse samples (Algorithm 1), casting
/// brute-force rays for the cells it marks.
pub fn filter_pass(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &ShearedOptions,
    params: &BakeParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Bake, ShearedStats)> {
    let pass = Pass::new(receivers, samples, s, params)?;
    let n = receivers.len();
    // Algorithm 1 per receiver as its chunk's batch is built (the cells it
    // cannot serve emit their rays), then each receiver finished from its
    // answers. The Scratch is per worker thread.
    thread_local! {
        static SCRATCH: std::cell::RefCell<Option<Scratch>> = const { std::cell::RefCell::new(None) };
    }
    let mut states = vec![(Pending::default(), ReceiverResult::default()); n];
    for_each_receiver(
        tracer,
        &mut states,
        64,
        |r, (pending, _), batch| {
            *pending = SCRATCH.with(|sc| {
                let mut sc = sc.borrow_mut();
                filter_receiver(&pass, r, sc.get_or_insert_with(Scratch::new))
            });
            emit_brute_force(&pass, r, pending, batch);
        },
        |r, (pending, result), directions, occluded| {
            *result = finish(&pass, r, pending, directions, occluded);
        },
        progress,
    );
    let results: Vec<ReceiverResult> = states.into_iter().map(|(_, result)| result).collect();
    let k = samples.per_receiver;
    let mut stats = ShearedStats {
        sparse_rays: samples.t.iter().filter(|&&t| t >= 0.0).count() as u64,
        ..Default::default()
    };
    let mut bake = Bake {
        ao: Vec::with_capacity(n),
        sh: Vec::with_capacity(n),
        rays: 0,
        visibility: None,
    };
    for (r, res) in results.iter().enumerate() {
        bake.ao.push(res.ao);
        bake.sh.push(res.sh);
        stats.brute_rays += res.brute_rays as u64;
        stats.cells_filtered += res.filtered as u64;
        stats.cells_brute += res.brute as u64;
        stats.cells_contact += res.contact as u64;
        stats.cells_no_hit += res.no_hit as u64;
        stats.cells_open += res.open as u64;
        stats.receivers_open += (res.open as usize == CELL_COUNT) as u64;
        stats
            .brute_fraction
            .push(res.brute as f32 / CELL_COUNT as f32);
        stats.z_min.push(res.z_min);
        stats.neighbours.push(res.neighbours);
        let own = &samples.t[r * k..(r + 1) * k];
        // Sparse rays reach past the max distance: hits beyond it are visible.
        let visible = own.iter().filter(|&&t| t > params.max_distance).count();
        stats.sparse_ao.push(visible as f32 / k as f32);
    }
    bake.rays = stats.sparse_rays + stats.brute_rays;
    Ok((bake, stats))
}
