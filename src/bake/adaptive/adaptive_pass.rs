//! The adaptive pass: each receiver's sequence continued from `pre_rays`
//! to its ray count, added to the pre-pass's sums.
//!
//! In: [`Receivers`], a [`Tracer`], the pre-pass's [`RaySums`], each
//! receiver's ray count and whether it is filtered, [`BakeParams`]. Out:
//! the sums over all of each receiver's rays; a filtered receiver's leave
//! out its rays below the geometric plane, which are counted only
//! ([`super::sums::below_compensated`]).

use super::sums::{CHUNK, RaySums};
use crate::atlas::Receivers;
use crate::bake::{BakeParams, ReceiverRays};
use crate::sh;
use crate::trace::{Tracer, for_each_receiver};

/// Traces the rays from `pre_rays` to `rays[r]` of every receiver r into
/// `sums`; `filtered(r)`: its sums leave out the rays below the plane.
/// `progress` is told the receivers done.
#[allow(clippy::too_many_arguments)]
pub fn adaptive_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    sums: &mut [RaySums],
    pre_rays: u32,
    rays: &[u32],
    filtered: impl Fn(usize) -> bool + Sync,
    p: &BakeParams,
    progress: &(dyn Fn(u64) + Sync),
) {
    for_each_receiver(
        tracer,
        sums,
        CHUNK,
        |r, _, batch| {
            let ray = ReceiverRays::new(receivers, r, p.seed);
            let above_only = filtered(r);
            for i in pre_rays..rays[r] {
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
        |r, s, directions, occluded| {
            let geo_normal = receivers.geo_normal[r];
            let above_only = filtered(r);
            // (`below` counts the pre-pass's rays below so far: none,
            // nothing to take out.)
            if above_only && s.below > 0 {
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
                s.below += rays[r].saturating_sub(pre_rays) - cast;
            }
            for (&d, &hit) in directions.iter().zip(occluded) {
                if !above_only && d.dot(geo_normal) <= 0.0 {
                    s.below += 1;
                }
                sh::accumulate(&mut s.all, 1.0, d);
                if hit {
                    sh::accumulate(&mut s.sh, 1.0, d);
                } else {
                    s.visible += 1;
                }
            }
        },
        progress,
    );
}
