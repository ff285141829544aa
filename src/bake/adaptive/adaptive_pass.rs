//! The adaptive pass: each receiver's sequence continued from where its
//! sums stop (the pre-pass's `pre_rays`, or an earlier round's count) to
//! its ray count, added to its sums.
//!
//! In: [`Receivers`], a [`Tracer`], the sums so far ([`RaySums`]), each
//! receiver's rays so far and its ray count, whether it is filtered,
//! [`BakeParams`]. Out:
//! the sums over all of each receiver's rays; a filtered receiver's leave
//! out its rays below the geometric plane, which are counted only
//! ([`super::sums::below_compensated`]).

use super::sums::{CHUNK, RaySums};
use crate::atlas::Receivers;
use crate::bake::visibility::{CapSums, with_caps};
use crate::bake::{BakeParams, ReceiverRays};
use crate::sh;
use crate::trace::{Tracer, for_each_receiver};

/// Where a round of the adaptive pass starts: every receiver at the end
/// of the pre-pass's `pre_rays`, or each at its count of an earlier round.
#[derive(Clone, Copy, Debug)]
pub enum Start<'a> {
    PrePass(u32),
    Earlier(&'a [u32]),
}

impl Start<'_> {
    fn of(&self, r: usize) -> u32 {
        match self {
            Start::PrePass(n) => *n,
            Start::Earlier(counts) => counts[r],
        }
    }
}

/// Traces the rays from `from` to `rays[r]` of every receiver r into
/// `sums` (and, where `cap` holds the receiver, the visibility layer's
/// cap sums; empty without the layer); `filtered(r)`: its sums leave out
/// the rays below the plane. `progress` is told the receivers done.
#[allow(clippy::too_many_arguments)]
pub fn adaptive_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    sums: &mut [RaySums],
    cap: &mut [CapSums],
    from: Start,
    rays: &[u32],
    filtered: impl Fn(usize) -> bool + Sync,
    p: &BakeParams,
    progress: &(dyn Fn(u64) + Sync),
) {
    let mut states = with_caps(sums, cap);
    for_each_receiver(
        tracer,
        &mut states,
        CHUNK,
        |r, _, batch| {
            let ray = ReceiverRays::new(receivers, r, p.seed);
            let above_only = filtered(r);
            for i in from.of(r)..rays[r] {
                let d = ray.direction(i);
                // Below the surface: occluded without tracing
                // ([`Tracer::receiver_visible`]'s test; a filtered
                // receiver only counts those).
                if d.dot(ray.geo_normal) > 0.0 {
                    batch.push(ray.origin, d, p.max_distance);
                } else if !above_only {
                    batch.push_blocked(d);
                }
            }
        },
        |r, (s, cap), directions, occluded| {
            let geo_normal = receivers.geo_normal[r];
            let above_only = filtered(r);
            // (`below` counts the pre-pass's rays below so far: none,
            // nothing to take out. A later round finds them taken out.)
            if let (true, Start::PrePass(pre_rays)) = (above_only && s.below > 0, from) {
                // The pre-pass summed its rays below into both sums.
                let ray = ReceiverRays::new(receivers, r, p.seed);
                for i in 0..pre_rays {
                    let d = ray.direction(i);
                    if d.dot(ray.geo_normal) <= 0.0 {
                        sh::accumulate(&mut s.sh, -1.0, d);
                        sh::accumulate(&mut s.all, -1.0, d);
                    }
                }
            }
            // A filtered receiver's rays below were not cast: counted only.
            let cast = directions.len() as u32;
            if above_only {
                s.below += rays[r].saturating_sub(from.of(r)) - cast;
            }
            // The layer's cap, summed in a copy (kept in registers) and
            // written back: the same sums in the same order as in place,
            // so rounds add up to one round's bits.
            let mut layer: Option<CapSums> = cap.as_deref().copied();
            for (&d, &hit) in directions.iter().zip(occluded) {
                if !above_only && d.dot(geo_normal) <= 0.0 {
                    s.below += 1;
                } else if let Some(c) = &mut layer {
                    c.add(receivers.normal[r], d, hit);
                }
                sh::accumulate(&mut s.all, 1.0, d);
                if hit {
                    sh::accumulate(&mut s.sh, 1.0, d);
                } else {
                    s.visible += 1;
                }
            }
            if let (Some(c), Some(layer)) = (cap, layer) {
                **c = layer;
            }
        },
        progress,
    );
}
