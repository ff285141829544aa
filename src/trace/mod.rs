//! Trace: the one room where rays meet geometry.
//!
//! In: bake-space occluder triangles, then batches of rays. Out: per ray,
//! whether anything is hit closer than its max distance (occlusion) or
//! the closest hit. Both faces occlude.
//!
//! - `batch`: [`Query`] and [`for_each_receiver`], through which a pass casts its receivers' rays
//!   as batches: each receiver emits its rays in order, the tracer answers
//!   the batch, each receiver reads its answers in the same order. The
//!   tracer decides how a batch is traced, so another backend fits behind
//!   the same calls.
//! - `backend`: the seam, [`Accelerator`]: a device answering whole
//!   batches as the CPU backend does, attached to it ([`Tracer::attach`]).
//! - `ray`: what the backends share: [`RayBatch`] (origins, unit
//!   directions, max distances), the ray the CPU traces for a query
//!   (shifted back), [`Hit`], the trees' inputs.
//! - `bvh`: the CPU backend, [`Tracer`]: one obvhs CWBVH, answering one
//!   ray at a time, which the batches use.
//! - `gpu` (feature `gpu`): the GPU backend, an [`Accelerator`] of wgpu
//!   compute shaders over obvhs's BVH2 answering whole batches (occlusion
//!   and closest hits).
//!
//! Here too: robust ray origins ([`offset_origin`]).

pub(crate) mod backend;
pub(crate) mod batch;
pub(crate) mod bvh;
#[cfg(feature = "gpu")]
pub mod gpu;
pub(crate) mod ray;

pub use backend::{Accelerator, Offer, Settle};
pub use batch::{Closest, Occlusion, Query, for_each_receiver, for_each_receiver_query};
pub use bvh::Tracer;
pub use ray::{Hit, RayBatch};

use glam::Vec3;

/// Origin offset along the geometric normal, in bake units (scene diagonal
/// = 1). Bake space keeps coordinates within [-0.5, 0.5], where an f32 ulp is
/// at most 6e-8, so this is ~30 ulps: above the rounding of interpolated
/// points and of the intersection test, far below any modelled gap.
pub const ORIGIN_OFFSET: f32 = 2e-6;

/// Fraction of the receiver's footprint added to [`ORIGIN_OFFSET`].
pub const ORIGIN_OFFSET_FOOTPRINT: f32 = 1e-3;

/// A ray origin lifted off the surface on the side of the geometric normal.
#[inline]
pub fn offset_origin(p: Vec3, geo_normal: Vec3, footprint: f32) -> Vec3 {
    p + geo_normal * (ORIGIN_OFFSET + ORIGIN_OFFSET_FOOTPRINT * footprint)
}
