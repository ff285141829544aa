//! The brute-force Monte Carlo baker (`--method mc`): the reference method.
//!
//! In: [`Receivers`], a [`Tracer`], the ray count and [`BakeParams`]. Out:
//! a [`Bake`], estimated with stratified cosine-weighted directions (so
//! each ray contributes V and V Y_i(w) with equal weight) from each
//! receiver's own [`ReceiverRays`]; the SH through the open hemisphere's
//! exact coefficients as a control variate weighted by the visible
//! fraction ([`sh::from_sums`]), so open and closed receivers are
//! exact at any ray count.

use super::{Bake, BakeParams, ReceiverRays};
use crate::atlas::Receivers;
use crate::sh::{self, SH_COUNT};
use crate::trace::{RayBatch, Tracer, for_each_receiver};
use glam::Vec3;

/// Receivers per batch of rays (and parallel work item).
const CHUNK: usize = 64;

/// Bakes every receiver by Monte Carlo with `rays` rays each. `progress`
/// is called with the number of receivers finished since its last call.
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    rays: u32,
    p: &BakeParams,
    progress: &(dyn Fn(u64) + Sync),
) -> Bake {
    let n = receivers.len();
    let mut out = vec![(0.0f32, [0.0f32; SH_COUNT]); n];
    for_each_receiver(
        tracer,
        &mut out,
        CHUNK,
        |r, _, batch| emit_receiver(receivers, r, 0, rays, p, batch),
        |r, out, directions, occluded| {
            *out = integrate_receiver(receivers, r, directions, occluded);
        },
        progress,
    );
    let (ao, sh) = out.into_iter().unzip();
    Bake {
        ao,
        sh,
        rays: n as u64 * rays as u64,
        visibility: None,
    }
}

/// Receiver `r`'s `rays` rays from point `first` of its sequence on, in
/// its order: a direction at or below its geometric plane is blocked (it
/// enters the surface itself; shading normals send ~8% of Sponza's
/// cosine-weighted rays there).
pub fn emit_receiver(
    receivers: &Receivers,
    r: usize,
    first: u32,
    rays: u32,
    p: &BakeParams,
    batch: &mut RayBatch,
) {
    let sequence = ReceiverRays::new(receivers, r, p.seed);
    for i in first..first + rays {
        let dir = sequence.direction(i);
        if dir.dot(sequence.geo_normal) > 0.0 {
            batch.push(sequence.origin, dir, p.max_distance);
        } else {
            batch.push_blocked(dir);
        }
    }
}

/// AO and SH of receiver `r` from its rays' directions and whether each
/// is occluded.
pub(crate) fn integrate_receiver(
    receivers: &Receivers,
    r: usize,
    directions: &[Vec3],
    occluded: &[bool],
) -> (f32, [f32; SH_COUNT]) {
    let rays = directions.len() as u32;
    let mut visible = 0u32;
    let mut occluded_sum = [0.0f32; SH_COUNT];
    let mut all = [0.0f32; SH_COUNT];
    for (&dir, &hit) in directions.iter().zip(occluded) {
        sh::accumulate(&mut all, 1.0, dir);
        if hit {
            sh::accumulate(&mut occluded_sum, 1.0, dir);
        } else {
            visible += 1;
        }
    }
    let ao = visible as f32 / rays.max(1) as f32;
    (
        ao,
        sh::from_sums(receivers.normal[r], &occluded_sum, &all, rays, ao),
    )
}
