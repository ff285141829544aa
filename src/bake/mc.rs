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
use crate::trace::Tracer;
use rayon::prelude::*;

/// Receivers per parallel work item.
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
    let mut ao = vec![0.0f32; n];
    let mut shv = vec![[0.0f32; SH_COUNT]; n];
    ao.par_chunks_mut(CHUNK)
        .zip(shv.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, (ao, shv))| {
            for k in 0..ao.len() {
                let r = c * CHUNK + k;
                let (a, coeffs) = integrate_receiver(receivers, r, tracer, rays, p);
                ao[k] = a;
                shv[k] = coeffs;
            }
            progress(ao.len() as u64);
        });
    Bake {
        ao,
        sh: shv,
        rays: n as u64 * rays as u64,
        visibility: None,
    }
}

/// Estimates AO and SH of receiver `r` with `rays` rays.
pub fn integrate_receiver(
    receivers: &Receivers,
    r: usize,
    tracer: &Tracer,
    rays: u32,
    p: &BakeParams,
) -> (f32, [f32; SH_COUNT]) {
    let sequence = ReceiverRays::new(receivers, r, p.seed);
    let mut visible = 0u32;
    let mut occluded = [0.0f32; SH_COUNT];
    let mut all = [0.0f32; SH_COUNT];
    for i in 0..rays {
        let dir = sequence.direction(i);
        sh::accumulate(&mut all, 1.0, dir);
        if tracer.receiver_visible(sequence.origin, sequence.geo_normal, dir, p.max_distance) {
            visible += 1;
        } else {
            sh::accumulate(&mut occluded, 1.0, dir);
        }
    }
    let ao = visible as f32 / rays.max(1) as f32;
    (
        ao,
        sh::from_sums(receivers.normal[r], &occluded, &all, rays, ao),
    )
}
