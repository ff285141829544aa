//! The visibility layer: the visibility itself projected on SH, without
//! the normal's cosine, so an engine can relight a normal-mapped normal or
//! a glossy lobe (the paper's split of occlusion f, precomputed, from the
//! BRDF k, evaluated per pixel).
//!
//! In: [`Receivers`], a [`Tracer`], a ray count per receiver and
//! [`BakeParams`]. Out: per receiver the occluded share above its
//! geometric plane (less, 16 coefficients) from stratified
//! uniform-hemisphere rays around its shading normal n ([`shares`]), which
//! the adaptive method filters like its SH; [`finish`] turns a share into
//! v_i = Int V(w) H(n.w) Y_i(w) dw.
//!
//! The integrand has no cosine, so the rays are uniform in solid angle
//! (weight 2 pi / M each): the bake's cosine-weighted rays with a pi / cos
//! weight have infinite variance at the horizon. The lune of n's
//! hemisphere below the geometric plane (occluded without tracing) is
//! projected exactly ([`sh::below_plane_visibility`]) and its rays are not
//! counted, so none of their sampling error is left; the rest is the open
//! projection less the occluded rays' share, with the open projection as a
//! control variate weighted by the visible fraction, as for the SH
//! ([`sh::occluded_share`]): open and closed receivers are exact at any ray
//! count.

use super::{BakeParams, ReceiverRays};
use crate::atlas::Receivers;
use crate::sample::uniform_hemisphere;
use crate::sh::{self, VIS_COUNT};
use crate::trace::{RayBatch, Tracer, for_each_receiver};
use glam::Vec3;
use rayon::prelude::*;

/// The receiver sequence of the visibility rays (the bake's is stream 0,
/// the sheared method's sparse pass stream 1).
pub(crate) const VISIBILITY_STREAM: u64 = 2;

/// Receivers per batch of rays (and parallel work item).
const CHUNK: usize = 64;

/// The visibility layer of every receiver, and the rays it cost.
#[derive(Clone, Debug, Default)]
pub struct Visibility {
    /// Per receiver: v_0..v_15.
    pub v: Vec<[f32; VIS_COUNT]>,
    pub rays: u64,
}

/// The angle between the shading normal n and the geometric normal, in
/// [0, pi] (0 for non-finite input).
#[inline]
fn tilt(n: Vec3, geo: Vec3) -> f32 {
    let a = n.cross(geo).length().atan2(n.dot(geo));
    if a.is_finite() { a } else { 0.0 }
}

/// Receiver `r`'s `rays` stratified uniform rays around its shading
/// normal, from point `first` of its sequence on, those at or below its
/// geometric plane left out (they add nothing: [`share`] counts the solid
/// angle above).
fn emit_receiver(
    receivers: &Receivers,
    r: usize,
    first: u32,
    rays: u32,
    p: &BakeParams,
    batch: &mut RayBatch,
) {
    let geo = receivers.geo_normal[r];
    let sequence = ReceiverRays::with_stream(receivers, r, p.seed, VISIBILITY_STREAM);
    for i in first..first + rays {
        let dir = sequence
            .frame
            .to_world(uniform_hemisphere(sequence.point(i)))
            .normalize();
        if dir.dot(geo) > 0.0 {
            batch.push(sequence.origin, dir, p.max_distance);
        }
    }
}

/// Receiver `r`'s occluded share above its geometric plane (less), from
/// its rays above the plane ([`emit_receiver`]'s) and whether each is
/// occluded.
pub fn share(
    receivers: &Receivers,
    r: usize,
    directions: &[Vec3],
    occluded_rays: &[bool],
) -> [f32; VIS_COUNT] {
    let (n, geo) = (receivers.normal[r], receivers.geo_normal[r]);
    let (above, mut visible) = (directions.len() as u32, 0u32);
    let mut occluded = [0.0f32; VIS_COUNT];
    let mut all = [0.0f32; VIS_COUNT];
    for (&dir, &hit) in directions.iter().zip(occluded_rays) {
        let y = sh::basis16(dir);
        for (a, y) in all.iter_mut().zip(y) {
            *a += y;
        }
        if !hit {
            visible += 1;
        } else {
            for (o, y) in occluded.iter_mut().zip(y) {
                *o += y;
            }
        }
    }
    let open = sh::open_visibility(n);
    let below = sh::below_plane_visibility(n, geo);
    let open_above: [f32; VIS_COUNT] = std::array::from_fn(|i| open[i] - below[i]);
    // Solid angle above the plane: the hemisphere's 2 pi less the lune's
    // 2 theta, shared by the rays that went there.
    let (per_ray, seen) = if above > 0 {
        let solid = 2.0 * (std::f32::consts::PI - tilt(n, geo));
        (solid / above as f32, visible as f32 / above as f32)
    } else {
        (0.0, 1.0)
    };
    sh::occluded_share(&open_above, &occluded, &all, per_ray, seen)
}

/// Every receiver's [`share`], receiver r with `rays(r)` rays (0: open).
pub fn shares(
    receivers: &Receivers,
    tracer: &Tracer,
    rays: impl Fn(usize) -> u32 + Sync,
    p: &BakeParams,
) -> Vec<[f32; VIS_COUNT]> {
    shares_from(receivers, tracer, |r| (0, rays(r)), p)
}

/// [`shares`] from later points of the receivers' sequences: receiver r
/// with the rays `span(r)` = (first point, count).
pub fn shares_from(
    receivers: &Receivers,
    tracer: &Tracer,
    span: impl Fn(usize) -> (u32, u32) + Sync,
    p: &BakeParams,
) -> Vec<[f32; VIS_COUNT]> {
    let mut out = vec![[0.0f32; VIS_COUNT]; receivers.len()];
    for_each_receiver(
        tracer,
        &mut out,
        CHUNK,
        |r, _, batch| {
            let (first, rays) = span(r);
            emit_receiver(receivers, r, first, rays, p, batch)
        },
        |r, out, directions, occluded| *out = share(receivers, r, directions, occluded),
        &|_| {},
    );
    out
}

/// v = the open hemisphere's projection, less the lune below the
/// geometric plane, plus the (filtered) occluded share above, for each
/// receiver.
pub fn finish(receivers: &Receivers, shares: Vec<[f32; VIS_COUNT]>) -> Vec<[f32; VIS_COUNT]> {
    shares
        .into_par_iter()
        .enumerate()
        .map(|(r, s)| {
            let (n, geo) = (receivers.normal[r], receivers.geo_normal[r]);
            let (open, below) = (sh::open_visibility(n), sh::below_plane_visibility(n, geo));
            std::array::from_fn(|i| open[i] - below[i] + s[i])
        })
        .collect()
}

/// The Monte Carlo layer: `rays` uniform rays per receiver, unfiltered.
pub fn bake(receivers: &Receivers, tracer: &Tracer, rays: u32, p: &BakeParams) -> Visibility {
    let s = shares(receivers, tracer, |_| rays, p);
    Visibility {
        v: finish(receivers, s),
        rays: receivers.len() as u64 * rays as u64,
    }
}
