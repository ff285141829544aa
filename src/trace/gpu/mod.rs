//! The GPU backend: occlusion and closest-hit batches answered by wgpu
//! compute shaders.
//!
//! In: bake-space occluder triangles, then [`RayBatch`]es. Out: per ray,
//! in the batch's order, what [`super::Tracer::trace_batch`] answers on the
//! CPU: whether anything (either face) is hit in (0, t_max] ([`Occlusion`]),
//! or the closest hit cut at the ray's depth ([`Closest`]), the same
//! parameter and triangle as the CPU's traversal finds.
//!
//! - `flatten`: obvhs's BVH2 as the shader's nodes and triangles.
//! - `tracer`: [`GpuTracer`], the device, its pipelines and the buffers
//!   of the dispatches in flight.
//! - `timing`: where a tracer's time goes, per stage of its dispatches.
//! - `traverse.wgsl`: the traversal (a short stack, the nearer child first)
//!   and the CPU's triangle test.
//!
//! The adapter is Vulkan's (wgpu's Vulkan backend only): a hardware GPU,
//! or with [`Adapters::Any`] also a software one such as Mesa's lavapipe,
//! which runs the same shader on the CPU (the tests use it). Every failure
//! (no adapter, a device lost mid-batch, a shader the driver refuses) is
//! an [`Error::Gpu`] naming what failed, for the caller to fall back or
//! stop on; nothing here panics on a GPU's answer.
//!
//! [`Occlusion`]: super::Occlusion
//! [`Closest`]: super::Closest

mod flatten;
mod timing;
mod tracer;

pub use flatten::{FlatBvh, GpuNode, GpuTri, flatten};
pub use timing::DispatchTimes;
pub use tracer::{AUTO_SOFTWARE_VAR, GpuAnswer, GpuHit, GpuTracer, LOSE_AFTER_VAR, SHARE_VAR};

use super::{Accelerator, Hit, Offer, RayBatch, Settle, Tracer};
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Rays per dispatch: bounds the GPU memory a dispatch takes (32 bytes
/// of ray, at most 4 of answer and 4 of its copy to read back each:
/// 40 MiB) whatever the batch's size.
pub const RAYS_PER_DISPATCH: usize = 1 << 20;

/// Threads per workgroup (`@workgroup_size` in traverse.wgsl).
const WORKGROUP: usize = 64;

/// The stack the shader walks with (`STACK` in traverse.wgsl): a tree
/// deeper than this is refused.
pub const STACK_DEPTH: u32 = 64;

/// Which adapters [`GpuTracer::new`] may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Adapters {
    /// A hardware GPU only (integrated, discrete or virtual).
    Hardware,
    /// Any, software rasterizers included (lavapipe), a hardware one first.
    Any,
}

/// The adapter a tracer runs on, for reports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterName {
    /// The driver's name for it ("NVIDIA H200", "llvmpipe (LLVM 15.0.6, 256 bits)").
    pub name: String,
    /// Whether it is a software adapter (runs on the CPU).
    pub software: bool,
}

/// A [`GpuTracer`] behind a CPU tracer ([`GpuTracer::attach_to`]), as
/// its [`Accelerator`]:
/// answers its batches until one fails, then leaves every later
/// batch to the CPU and keeps the first failure for the job to report.
/// It shares the batches with the CPU: a batch offered while every
/// dispatch of the GPU's is in flight is answered by the CPU a piece at a
/// time, the rest offered again between pieces ([`super::Tracer::trace_batch`]).
pub struct Attached {
    tracer: GpuTracer,
    /// Per GPU triangle (the BVH2's leaf order), the CPU's (the CWBVH's),
    /// which a [`Hit`] names.
    to_cpu: Vec<u32>,
    failure: std::sync::OnceLock<String>,
    /// Rays of the batches answered here, and by the CPU instead.
    on_gpu: AtomicU64,
    on_cpu: AtomicU64,
}

impl GpuTracer {
    /// Attaches this tracer to `cpu` (which holds the same occluders) as
    /// its accelerator: `cpu`'s batches go here first.
    pub fn attach_to(self, cpu: &mut Tracer) {
        let attached = Attached::new(self, cpu.leaf_order());
        cpu.attach(Box::new(attached));
    }
}

impl Attached {
    /// `tracer` behind a CPU tracer whose triangle in leaf order `k` is
    /// occluder `cpu_order[k]`. (A triangle the builders split sits in
    /// several leaves, each the same triangle: any one names it.)
    pub(crate) fn new(tracer: GpuTracer, cpu_order: &[u32]) -> Attached {
        let count = cpu_order
            .iter()
            .chain(tracer.primitives())
            .max()
            .map_or(0, |&i| i as usize + 1);
        let mut cpu_of = vec![0; count];
        for (k, &i) in cpu_order.iter().enumerate().rev() {
            cpu_of[i as usize] = k as u32;
        }
        let to_cpu = tracer
            .primitives()
            .iter()
            .map(|&i| cpu_of[i as usize])
            .collect();
        Attached {
            tracer,
            to_cpu,
            failure: std::sync::OnceLock::new(),
            on_gpu: AtomicU64::new(0),
            on_cpu: AtomicU64::new(0),
        }
    }

    pub fn adapter(&self) -> &AdapterName {
        self.tracer.adapter()
    }

    /// The GPU tracer's [`DispatchTimes`] so far.
    pub fn dispatch_times(&self) -> DispatchTimes {
        self.tracer.dispatch_times()
    }

    /// Starts its sums afresh.
    pub fn reset_dispatch_times(&self) {
        self.tracer.reset_dispatch_times()
    }

    /// The GPU's answers `found` to rays `from..` settled into `out`, in
    /// parallel pieces: `settle(i, answer, retraced)` gives ray `i`'s
    /// answer and counts in `retraced` the rays it traced again on the CPU.
    /// The stage's time and the count go to the tracer's timing.
    fn settle<F: Sync, T: Send>(
        &self,
        from: usize,
        found: &[F],
        out: &mut [T],
        settle: impl Fn(usize, &F, &mut usize) -> T + Sync,
    ) {
        let settling = std::time::Instant::now();
        let retraced: usize = (out.par_chunks_mut(SETTLE_PIECE))
            .zip(found.par_chunks(SETTLE_PIECE))
            .enumerate()
            .map(|(k, (out, found))| {
                let mut retraced = 0;
                let first = from + k * SETTLE_PIECE;
                for ((i, answer), out) in (first..).zip(found).zip(out) {
                    *out = settle(i, answer, &mut retraced);
                }
                retraced
            })
            .sum();
        self.tracer.timing.retraced(retraced);
        self.tracer.timing.add(timing::Stage::Settle, settling);
    }

    /// What became of `rays` offered to `answer`: `Failed` once a batch
    /// has failed (this one's failure kept), when the CPU must answer.
    fn offer(&self, rays: usize, answer: impl FnOnce() -> Result<bool>) -> Offer {
        if self.failure.get().is_some() {
            return Offer::Failed;
        }
        match answer() {
            Ok(true) => {
                self.on_gpu.fetch_add(rays as u64, Ordering::Relaxed);
                Offer::Answered
            }
            Ok(false) => Offer::Busy,
            Err(e) => {
                let _ = self.failure.set(match e {
                    Error::Gpu(m) => m,
                    e => e.to_string(),
                });
                Offer::Failed
            }
        }
    }
}

impl Accelerator for Attached {
    fn name(&self) -> &str {
        &self.tracer.adapter().name
    }

    fn failure(&self) -> Option<&str> {
        self.failure.get().map(String::as_str)
    }

    fn rays(&self) -> (u64, u64) {
        (
            self.on_gpu.load(Ordering::Relaxed),
            self.on_cpu.load(Ordering::Relaxed),
        )
    }

    fn answered_on_cpu(&self, rays: usize) {
        self.on_cpu.fetch_add(rays as u64, Ordering::Relaxed);
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    /// Answers the occlusion of rays `from..` of `rays` into `out` (one
    /// answer a ray from `from`) as `cpu` (the tracer this is attached to)
    /// answers it, if the GPU has a dispatch free and has not failed. The
    /// GPU's sure answers stand; the rays it is unsure of (a candidate
    /// within rounding of the test) are traced here, in parallel.
    fn occluded_from(
        &self,
        cpu: &dyn Settle,
        rays: &RayBatch,
        from: usize,
        out: &mut [bool],
    ) -> Offer {
        self.offer(out.len(), || {
            let mut found = Vec::new();
            if !self.tracer.occlusion_from(rays, from, false, &mut found)? {
                return Ok(false);
            }
            self.settle(from, &found, out, |i, &answer, retraced| {
                rays.is_blocked(i)
                    || match answer {
                        GpuAnswer::Miss => false,
                        GpuAnswer::Hit => true,
                        GpuAnswer::Unsure => {
                            *retraced += 1;
                            let (o, d) = (rays.origins()[i], rays.directions()[i]);
                            cpu.occluded(o, d, rays.t_max()[i])
                        }
                    }
            });
            Ok(true)
        })
    }

    /// Answers the closest hits of rays `from..` of `rays` into `out` as
    /// `cpu` (the tracer this is attached to) answers them, if the GPU has
    /// a dispatch free and has not failed. A ray without a candidate hits
    /// nothing; a sure nearest candidate is the hit, its distance the CPU
    /// test's (retested here); the rest (a near tie, which rounding or the
    /// CPU's traversal order decides, or a candidate within rounding of the
    /// test) are traced here. Settled in parallel.
    fn closest_from(
        &self,
        cpu: &dyn Settle,
        rays: &RayBatch,
        from: usize,
        out: &mut [Option<Hit>],
    ) -> Offer {
        self.offer(out.len(), || {
            let mut found = Vec::new();
            if !self.tracer.closest_from(rays, from, false, &mut found)? {
                return Ok(false);
            }
            self.settle(from, &found, out, |i, hit, retraced| {
                hit.and_then(|hit| {
                    let (o, d) = (rays.origins()[i], rays.directions()[i]);
                    let (t_max, depth) = (rays.t_max()[i], rays.depths()[i]);
                    let triangle = self.to_cpu[hit.triangle as usize];
                    match cpu.retest(triangle, o, d, t_max, depth) {
                        Some(found) if hit.sure => Some(found),
                        _ => {
                            *retraced += 1;
                            cpu.trace_closest(o, d, t_max, depth)
                        }
                    }
                })
            });
            Ok(true)
        })
    }
}

/// Rays a worker settles at a time: a batch's answers are settled in
/// parallel pieces of this many.
const SETTLE_PIECE: usize = 8192;

/// The first adapter `which` admits: hardware ones before software ones.
fn pick_adapter(which: Adapters) -> Result<(wgpu::Adapter, AdapterName)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
    let mut named: Vec<(wgpu::Adapter, AdapterName)> = adapters
        .into_iter()
        .map(|a| {
            let info = a.get_info();
            let software = info.device_type == wgpu::DeviceType::Cpu;
            (
                a,
                AdapterName {
                    name: info.name,
                    software,
                },
            )
        })
        .filter(|(_, n)| which == Adapters::Any || !n.software)
        .collect();
    // Hardware first, then discrete before integrated (stable otherwise).
    named.sort_by_key(|(a, n)| {
        (
            n.software,
            a.get_info().device_type != wgpu::DeviceType::DiscreteGpu,
        )
    });
    named.into_iter().next().ok_or_else(|| {
        Error::Gpu(match which {
            Adapters::Hardware => "no hardware GPU adapter (Vulkan) found".into(),
            Adapters::Any => "no Vulkan adapter found, not even a software one".into(),
        })
    })
}
