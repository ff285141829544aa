//! Bake: per-receiver AO and SH from rays, by one of the methods.
//!
//! In: [`Receivers`] (from [`crate::atlas`]), a `Tracer`, [`BakeParams`]
//! and the method's own options. Out: a [`Bake`], the result every method
//! produces: per receiver AO = (1/pi) Int V max(0, n.w) dw and the 9 SH
//! coefficients (1/pi) Int V max(0, n.w) Y_i(w) dw.
//!
//! - [`mc`]: brute-force Monte Carlo, the reference method;
//! - [`adaptive`]: adaptive ray counts and an axis-aligned filter of the
//!   integrated values (the default);
//! - [`sheared`]: the sheared filter of Egan et al. 2011 (`--method
//!   sheared`), sparse rays shared between neighbouring receivers;
//! - `visibility`: the visibility layer v (16 SH coefficients of V
//!   itself), for `mc` (uniform rays) and (filtered) `adaptive` (the
//!   bake's own rays in the cap, uniform rays in the band at the horizon);
//! - [`validity`]: which receivers lie inside or behind geometry (their
//!   texels are filled, not shown): a stage before Monte Carlo and the
//!   sheared method, made by the adaptive method's pre-pass on the same
//!   rays.
//!
//! Here, shared by all of them: [`Bake`], [`BakeParams`] and
//! [`ReceiverRays`], the rays of one receiver (lifted origin, frame and
//! its own scrambled Sobol sequence), so every pass of every method draws
//! from the same sequences and results do not depend on thread count.

pub mod adaptive;
pub mod mc;
pub mod sheared;
pub mod signal;
pub mod validity;
pub(crate) mod visibility;

use crate::atlas::Receivers;
use crate::sample::{Frame, cosine_hemisphere, receiver_seed, sobol_2d};
use crate::sh::SH_COUNT;
use crate::trace::offset_origin;
use glam::{Vec2, Vec3};

/// Per-receiver bake result.
#[derive(Clone, Debug, Default)]
pub struct Bake {
    pub ao: Vec<f32>,
    pub sh: Vec<[f32; SH_COUNT]>,
    /// Rays cast (the visibility layer's not counted).
    pub rays: u64,
    /// The visibility layer, when asked for (`visibility`).
    pub visibility: Option<visibility::Visibility>,
}

/// What every method is told besides its own options.
#[derive(Clone, Copy, Debug)]
pub struct BakeParams {
    /// Max occluder distance, bake units.
    pub max_distance: f32,
    pub seed: u64,
}

/// The rays of one receiver: a lifted origin and, for each ray index, a
/// direction from the receiver's own scrambled sequence.
#[derive(Clone, Copy, Debug)]
pub struct ReceiverRays {
    pub origin: Vec3,
    pub geo_normal: Vec3,
    pub frame: Frame,
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

    /// Point `i` of the receiver's sequence in the unit square (its cell
    /// is [`crate::sample::square_cell`] of it).
    #[inline]
    pub fn point(&self, i: u32) -> Vec2 {
        sobol_2d(i, self.seed)
    }

    /// The world direction of a point of the square (cosine-weighted
    /// around the shading normal).
    #[inline]
    pub fn direction_of(&self, u: Vec2) -> Vec3 {
        self.frame.to_world(cosine_hemisphere(u)).normalize()
    }

    /// Direction of ray `i`.
    #[inline]
    pub fn direction(&self, i: u32) -> Vec3 {
        self.direction_of(self.point(i))
    }
}
