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
//! filter is at its widest ([`exact_depth`](super::width::exact_depth)); deeper, a hit is only a
//! hit. Below the depth where every receiver is in contact
//! ([`contact_depth`](super::width::contact_depth)) a receiver's z_min bounds nothing a nearer one
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
use super::width::Depths;
use crate::atlas::Receivers;
use crate::bake::validity::{self, BackFaces};
use crate::bake::visibility as vis;
use crate::bake::{BakeParams, ReceiverRays};
use crate::sh;
use crate::trace::{Closest, Hit, RayBatch, Tracer, for_each_receiver_query};
use glam::Vec3;
use rayon::prelude::*;

/// What the pre-pass found, per receiver.
pub struct PrePass {
    pub sums: Vec<RaySums>,
    /// Own z_min, bake units (INFINITY: nothing hit; below
    /// [`contact_depth`](super::width::contact_depth) a bound, not the nearest hit).
    pub own_z: Vec<f32>,
    /// Pairs of neighbouring strata whose rays disagree.
    pub crossings: Vec<u16>,
    /// Inside geometry (all false without `fill_inside`).
    pub inside: Vec<bool>,
    /// With the visibility layer: the layer's sums of the rays in the cap
    /// ([`vis::CapSums`]); empty without it.
    pub cap: Vec<vis::CapSums>,
}

/// A receiver's running state through the pre-pass's rounds.
/// Its strata seen occluded are bits of `occluded` (one word per 64 strata
/// the pre-pass has).
struct Running<'a> {
    sums: RaySums,
    z: f32,
    faces: BackFaces,
    occluded: &'a mut [u64],
    cap: Option<&'a mut vis::CapSums>,
}

/// Where the rounds of rays end: a receiver's queries for a round are
/// chosen from what its earlier rounds found (the validity test goes on
/// past its probe only where the probe saw a back face; a receiver in
/// contact asks only for any hit).
fn round_ends(pre_rays: u32) -> Vec<u32> {
    let mut ends: Vec<u32> = [validity::VALIDITY_PROBE, 2 * validity::VALIDITY_PROBE]
        .into_iter()
        .filter(|&e| e < pre_rays)
        .collect();
    ends.push(pre_rays);
    ends
}

/// Traces the pre-pass (see the module doc), in rounds of batches;
/// `layer`: also sums its rays for the visibility layer's cap.
pub(crate) fn pre_pass(
    receivers: &Receivers,
    tracer: &Tracer,
    fill_inside: bool,
    layer: bool,
    o: &AdaptiveOptions,
    depths: Depths,
    p: &BakeParams,
) -> PrePass {
    let n = receivers.len();
    let strata = Strata::of(o.pre_rays);
    let Depths { exact, contact } = depths;
    // Without single-sided triangles no receiver is inside: no face to test.
    let test_faces = fill_inside && tracer.has_single_sided();
    let words = (o.pre_rays as usize).div_ceil(64).clamp(1, STRATA_WORDS);
    let mut bits = vec![0u64; n * words];
    let mut cap = vec![vis::CapSums::default(); if layer { n } else { 0 }];
    let mut caps = cap.iter_mut();
    let mut running: Vec<Running> = bits
        .chunks_mut(words)
        .map(|occluded| Running {
            sums: RaySums::default(),
            z: f32::INFINITY,
            faces: BackFaces::default(),
            occluded,
            cap: caps.next(),
        })
        .collect();
    let mut from = 0;
    for end in round_ends(o.pre_rays) {
        let emit = |r: usize, s: &mut Running, batch: &mut RayBatch| {
            let rays = ReceiverRays::new(receivers, r, p.seed);
            for i in from..end {
                let d = rays.direction(i);
                if d.dot(rays.geo_normal) <= 0.0 {
                    batch.push_blocked(d);
                } else if test_faces && s.faces.counts(i) {
                    // The validity test needs the closest hit's face.
                    batch.push(rays.origin, d, p.max_distance);
                } else if s.z < contact {
                    // In contact already: a nearer hit bounds nothing
                    // more, so any hit will do (cut at once).
                    batch.push_within(rays.origin, d, p.max_distance, 0.0);
                } else {
                    // z_min needs distances below `exact` only.
                    batch.push_within(rays.origin, d, p.max_distance, exact);
                }
            }
        };
        let consume = |r: usize, s: &mut Running, dirs: &[Vec3], hits: &[Option<Hit>]| {
            let geo = receivers.geo_normal[r];
            let rays = ReceiverRays::new(receivers, r, p.seed);
            for (i, (&d, &hit)) in (from..end).zip(dirs.iter().zip(hits)) {
                let stratum = strata.index(rays.point(i));
                sh::accumulate(&mut s.sums.all, 1.0, d);
                if d.dot(geo) <= 0.0 {
                    // Below the surface: occluded, by nothing at a depth.
                    s.sums.below += 1;
                    sh::accumulate(&mut s.sums.sh, 1.0, d);
                    s.occluded[stratum / 64] |= 1 << (stratum % 64);
                    continue;
                }
                // What the ray's query in sequence order returns: the
                // validity test's full closest hit; in contact, any hit
                // at the running z_min; else the distance below the
                // running z_min and `exact` (the batch's cut at `exact`
                // or deeper gives it exactly, [`Hit::distance_within`]).
                let t_max = p.max_distance;
                let depth = if test_faces && s.faces.counts(i) {
                    s.faces.add(hit.is_some_and(|h| tracer.is_back_face(h, d)));
                    Some(t_max)
                } else if s.z < contact {
                    None
                } else {
                    Some(s.z.min(exact))
                };
                if let Some(c) = &mut s.cap {
                    c.add(receivers.normal[r], d, hit.is_some());
                }
                match hit {
                    Some(h) => {
                        let t = depth.map_or(s.z, |depth| h.distance_within(t_max, depth));
                        s.z = s.z.min(t);
                        sh::accumulate(&mut s.sums.sh, 1.0, d);
                        s.occluded[stratum / 64] |= 1 << (stratum % 64);
                    }
                    None => s.sums.visible += 1,
                }
            }
        };
        for_each_receiver_query::<Closest, Running>(
            tracer,
            &mut running,
            CHUNK,
            emit,
            consume,
            &|_| {},
        );
        from = end;
    }
    let crossings: Vec<u16> = running
        .par_iter()
        .with_min_len(CHUNK)
        .map(|s| {
            let mut occluded = [0u64; STRATA_WORDS];
            occluded[..words].copy_from_slice(s.occluded);
            strata.crossings(&occluded).min(u16::MAX as u32) as u16
        })
        .collect();
    // The validity test goes on past the pre-pass's rays (where it casts
    // fewer than the test's), from the faces its rays saw.
    let inside = match test_faces {
        true => {
            let faces = running.iter().map(|s| s.faces).collect();
            validity::finish_inside(receivers, tracer, p.max_distance, p.seed, o.pre_rays, faces)
        }
        false => vec![false; n],
    };
    let sums = running.iter().map(|s| s.sums).collect();
    let own_z = running.iter().map(|s| s.z).collect();
    drop(running);
    PrePass {
        sums,
        own_z,
        crossings,
        inside,
        cap,
    }
}
