//! The brute-force Monte Carlo baker (`--method mc`): the reference method.
//!
//! In: [`Receivers`], a [`Tracer`], ray count, max distance, seed. Out: a
//! [`Bake`]: per receiver AO = (1/pi) Int V max(0, n.w) dw and the 9 SH
//! coefficients (1/pi) Int V max(0, n.w) Y_i(w) dw, estimated with
//! stratified cosine-weighted directions (so each ray contributes V and
//! V Y_i(w) with equal weight). Every receiver draws from its own scrambled
//! sequence, so results do not depend on thread count.

use crate::rasterize::Receivers;
use crate::sample::{Frame, cosine_hemisphere, receiver_seed, sobol_2d};
use crate::sh::{self, SH_COUNT};
use crate::trace::{Tracer, offset_origin};
use glam::Vec3;
use rayon::prelude::*;

/// Per-receiver bake result.
#[derive(Clone, Debug, Default)]
pub struct Bake {
    pub ao: Vec<f32>,
    pub sh: Vec<[f32; SH_COUNT]>,
    /// Rays cast.
    pub rays: u64,
}

/// Monte Carlo settings.
#[derive(Clone, Copy, Debug)]
pub struct McSettings {
    pub rays: u32,
    /// Max occluder distance, bake units.
    pub max_distance: f32,
    pub seed: u64,
}

/// Receivers per parallel work item.
const CHUNK: usize = 64;

/// Bakes every receiver by Monte Carlo. `progress` is called with the
/// number of receivers finished since its last call.
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    s: &McSettings,
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
                let (a, coeffs) = integrate_receiver(receivers, r, tracer, s);
                ao[k] = a;
                shv[k] = coeffs;
            }
            progress(ao.len() as u64);
        });
    Bake {
        ao,
        sh: shv,
        rays: n as u64 * s.rays as u64,
    }
}

/// The Monte Carlo rays of one receiver: a lifted origin and, for each ray
/// index, a direction from the receiver's own scrambled sequence.
#[derive(Clone, Copy, Debug)]
pub struct ReceiverRays {
    pub origin: Vec3,
    pub geo_normal: Vec3,
    frame: Frame,
    seed: u64,
}

impl ReceiverRays {
    /// The rays of receiver `r` for bake seed `seed`.
    pub fn new(receivers: &Receivers, r: usize, seed: u64) -> ReceiverRays {
        ReceiverRays::with_stream(receivers, r, seed, 0)
    }

    /// The same from another of the receiver's sequences (`stream`), for
    /// passes whose rays must not repeat the bake's.
    pub fn with_stream(receivers: &Receivers, r: usize, seed: u64, stream: u64) -> ReceiverRays {
        let geo_normal = receivers.geo_normal[r];
        ReceiverRays {
            origin: offset_origin(receivers.position[r], geo_normal, receivers.footprint[r]),
            geo_normal,
            frame: Frame::from_normal(receivers.normal[r]),
            seed: receiver_seed(seed, receivers.texel[r] as u64, stream),
        }
    }

    /// Direction of ray `i` (cosine-weighted around the shading normal).
    #[inline]
    pub fn direction(&self, i: u32) -> Vec3 {
        self.frame
            .to_world(cosine_hemisphere(sobol_2d(i, self.seed)))
            .normalize()
    }
}

/// Estimates AO and SH of receiver `r` with `s.rays` rays.
pub fn integrate_receiver(
    receivers: &Receivers,
    r: usize,
    tracer: &Tracer,
    s: &McSettings,
) -> (f32, [f32; SH_COUNT]) {
    let rays = ReceiverRays::new(receivers, r, s.seed);
    let mut visible = 0u32;
    let mut acc = [0.0f32; SH_COUNT];
    for i in 0..s.rays {
        let dir = rays.direction(i);
        if tracer.receiver_visible(rays.origin, rays.geo_normal, dir, s.max_distance) {
            visible += 1;
            sh::accumulate(&mut acc, 1.0, dir);
        }
    }
    let inv = 1.0 / s.rays.max(1) as f32;
    (visible as f32 * inv, acc.map(|v| v * inv))
}
