//! The pre-pass: the first `pre_rays` rays of each receiver's own sequence
//! (the Monte Carlo baker's, stream 0).
//!
//! In: [`Receivers`], a [`Tracer`], whether to find the receivers inside
//! geometry, [`AdaptiveOptions`], [`BakeParams`]. Out: [`PrePass`]: per
//! receiver its own z_min (nearest hit within the max distance, as far as
//! the bounds can use it), its running [`RaySums`] (visible count, rays
//! below the plane, SH sums), how many pairs of its strata the visibility
//! boundary crosses ([`Strata::crossings`]) and whether it lies inside
//! geometry.
//!
//! Its closest hits' faces also tell which receivers lie inside geometry:
//! the validity stage's test on the same rays (the bake's sequence), so
//! the adaptive method needs no stage of its own for it. Rays outside
//! that test ask only for the distances z_min can use: below the
//! receiver's running z_min and below the depth where every receiver's
//! filter is at its widest ([`exact_depth`]); deeper, a hit is only a
//! hit. Below the depth where every receiver is in contact
//! ([`contact_depth`]) a receiver's z_min bounds nothing a nearer one
//! would not, so its further rays ask only for any hit. Same bounds and
//! sums as full closest-hit queries (byte-identical output; own z_min of
//! contact receivers may stay above their nearest hit, below the contact
//! depth). Measured on the curtains at 1024: pre-pass 1.48 -> 1.34 s with
//! the depth, 1.31 -> 1.03 s with the contact depth and the receivers'
//! world order ([`crate::atlas::order`]), where 16-ray Monte Carlo's
//! trace takes 0.91 s.

use super::options::AdaptiveOptions;
use super::strata::{STRATA_WORDS, Strata};
use super::sums::{CHUNK, RaySums};
use super::width::{contact_depth, exact_depth};
use crate::atlas::Receivers;
use crate::bake::validity::{self, BackFaces};
use crate::bake::{BakeParams, ReceiverRays};
use crate::sh;
use crate::trace::Tracer;
use rayon::prelude::*;

/// What the pre-pass found, per receiver.
pub struct PrePass {
    pub sums: Vec<RaySums>,
    /// Own z_min, bake units (INFINITY: nothing hit; below
    /// [`contact_depth`] a bound, not the nearest hit).
    pub own_z: Vec<f32>,
    /// Pairs of neighbouring strata whose rays disagree.
    pub crossings: Vec<u16>,
    /// Inside geometry (all false without `fill_inside`).
    pub inside: Vec<bool>,
}

/// Traces the pre-pass (see the module doc).
pub fn pre_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    fill_inside: bool,
    o: &AdaptiveOptions,
    p: &BakeParams,
) -> PrePass {
    let n = receivers.len();
    let mut sums = vec![RaySums::default(); n];
    let mut own_z = vec![f32::INFINITY; n];
    let mut inside = vec![false; n];
    let mut crossings = vec![0u16; n];
    let strata = Strata::of(o.pre_rays);
    let exact = exact_depth(&receivers.footprint, o, p.max_distance);
    let contact = contact_depth(&receivers.footprint, o);
    // Without single-sided triangles no receiver is inside: no face to test.
    let test_faces = fill_inside && tracer.has_single_sided();
    sums.par_chunks_mut(CHUNK)
        .zip(own_z.par_chunks_mut(CHUNK))
        .zip(inside.par_chunks_mut(CHUNK))
        .zip(crossings.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, (((sums, zs), inside), crossings))| {
            for (k, (((s, z), inside), crossings)) in sums
                .iter_mut()
                .zip(zs)
                .zip(inside)
                .zip(crossings)
                .enumerate()
            {
                let r = c * CHUNK + k;
                let rays = ReceiverRays::new(receivers, r, p.seed);
                let mut faces = BackFaces::default();
                let mut occluded = [0u64; STRATA_WORDS];
                for i in 0..o.pre_rays {
                    let u = rays.point(i);
                    let d = rays.direction_of(u);
                    let stratum = strata.index(u);
                    sh::accumulate(&mut s.all, 1.0, d);
                    if d.dot(rays.geo_normal) <= 0.0 {
                        // Below the surface: occluded, by nothing at a depth.
                        s.below += 1;
                        sh::accumulate(&mut s.sh, 1.0, d);
                        occluded[stratum / 64] |= 1 << (stratum % 64);
                        continue;
                    }
                    // The validity test needs the closest hit's face; z_min
                    // only distances below the running z_min and `exact`.
                    let hit = if test_faces && faces.counts(i) {
                        let hit = tracer.closest_hit_side(rays.origin, d, p.max_distance);
                        faces.add(matches!(hit, Some((_, true))));
                        hit.map(|(t, _)| t)
                    } else if *z < contact {
                        // In contact already: a nearer hit bounds nothing
                        // more, so any hit will do.
                        tracer
                            .occluded(rays.origin, d, p.max_distance)
                            .then_some(*z)
                    } else {
                        tracer.hit_depth_within(rays.origin, d, p.max_distance, z.min(exact))
                    };
                    match hit {
                        Some(t) => {
                            *z = z.min(t);
                            sh::accumulate(&mut s.sh, 1.0, d);
                            occluded[stratum / 64] |= 1 << (stratum % 64);
                        }
                        None => s.visible += 1,
                    }
                }
                *crossings = strata.crossings(&occluded).min(u16::MAX as u32) as u16;
                *inside = test_faces
                    && validity::finish_inside(&rays, tracer, p.max_distance, o.pre_rays, faces);
            }
        });
    PrePass {
        sums,
        own_z,
        crossings,
        inside,
    }
}
