//! The seam between the passes' batches and the devices that answer them.
//!
//! In: a batch of rays ([`RayBatch`]) and the rays of it still to answer.
//! Out: an [`Accelerator`]'s answers for them, one per ray, exactly the
//! CPU backend's, or an [`Offer`] saying it answered none.
//!
//! The CPU backend (`bvh.rs`) answers every query itself; an accelerator
//! attached to it (`Tracer::attach`) is offered whole batches first
//! (`batch.rs`), and settles what its device leaves open through the CPU
//! backend's [`Settle`]. This module imports neither backend.
//! The GPU backend (`gpu/`, feature `gpu`) is one; another device or a
//! remote tracer is one more implementation of [`Accelerator`], with no
//! change here or in the passes. `job/device.rs` picks which.

use super::ray::{Hit, RayBatch};
use glam::Vec3;

/// What became of rays offered to an accelerator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Offer {
    /// Answered, as the CPU answers them.
    Answered,
    /// The device was busy: nothing answered, for the CPU to start on.
    Busy,
    /// The device has failed (now or before): the CPU answers every ray.
    Failed,
}

/// The CPU backend as an accelerator sees it: its own test and traversal,
/// to settle the rays its device leaves open. Triangles are named in the
/// CPU backend's leaf order.
pub trait Settle: Sync {
    /// The CPU test's hit on `triangle` as a closest-hit query cut at
    /// `depth` returns it; `None` where the test misses it or hits it at
    /// the ray's very start (where the traversal decides).
    fn retest(&self, triangle: u32, origin: Vec3, dir: Vec3, t_max: f32, depth: f32)
    -> Option<Hit>;
    /// The CPU's occlusion answer, traced.
    fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool;
    /// The CPU's closest hit, traced.
    fn trace_closest(&self, origin: Vec3, dir: Vec3, t_max: f32, depth: f32) -> Option<Hit>;
}

/// A device that answers batches as the CPU backend does. `cpu` is the
/// CPU backend it is attached to, which holds the same occluders.
pub trait Accelerator: Send + Sync {
    /// The device's name, for reports ("NVIDIA H200").
    fn name(&self) -> &str;

    /// The occlusion of rays `from..` of `rays` into `out` (one answer a
    /// ray from `from`), if the device takes them.
    fn occluded_from(
        &self,
        cpu: &dyn Settle,
        rays: &RayBatch,
        from: usize,
        out: &mut [bool],
    ) -> Offer;

    /// The closest hits of rays `from..` of `rays` into `out`, if the
    /// device takes them.
    fn closest_from(
        &self,
        cpu: &dyn Settle,
        rays: &RayBatch,
        from: usize,
        out: &mut [Option<Hit>],
    ) -> Offer;

    /// Counts `rays` of a batch answered by the CPU instead.
    fn answered_on_cpu(&self, rays: usize);

    /// Rays of the batches so far answered by the device and by the CPU.
    fn rays(&self) -> (u64, u64);

    /// Why the device stopped answering, if it failed.
    fn failure(&self) -> Option<&str>;

    /// The accelerator itself, for probes that read a backend's own
    /// measurements.
    fn as_any(&self) -> &dyn std::any::Any;
}
