//! Where a GPU tracer's time goes, per stage of its dispatches, for
//! measurements (`probes/gpu_rays`, `docs/gpu.md`).
//!
//! In: the stages' durations as the tracer's threads spend them (packing
//! rays, uploading and submitting, waiting for the device, reading the
//! answers, settling them on the host; the submission apart, which a
//! software adapter may spend running the kernel) and, where the adapter has
//! timestamp queries, the kernel's own time on the device. Out:
//! [`DispatchTimes`], their sums since the tracer started (or was reset).
//! Sums of threads' time: with dispatches in flight on several threads
//! they may add to more than the wall time.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// The stages timed.
#[derive(Clone, Copy)]
pub(crate) enum Stage {
    /// Rays packed as the shader reads them.
    Pack,
    /// The rays written to the device's staging memory, the commands
    /// encoded.
    Upload,
    /// The commands submitted (a software adapter may run them there).
    Submit,
    /// From the submission until the answers are mapped.
    Wait,
    /// The mapped answers read into the caller's.
    Read,
    /// The answers settled on the host (retests, rays traced on the CPU).
    Settle,
    /// The kernel on the device (timestamp queries).
    Kernel,
}

const STAGES: usize = 7;

/// Sums over a tracer's dispatches.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DispatchTimes {
    pub dispatches: u64,
    /// Rays sent to the device.
    pub rays: u64,
    /// Rays the host traced again on the CPU (the GPU unsure of them).
    pub retraced: u64,
    /// Seconds per stage, summed over the threads that spent them.
    pub pack_s: f64,
    pub upload_s: f64,
    pub submit_s: f64,
    pub wait_s: f64,
    pub read_s: f64,
    pub settle_s: f64,
    /// The kernels' time on the device, where the adapter has timestamp
    /// queries.
    pub kernel_s: Option<f64>,
}

/// The tracer's counters.
#[derive(Default)]
pub(crate) struct Timing {
    ns: [AtomicU64; STAGES],
    dispatches: AtomicU64,
    rays: AtomicU64,
    retraced: AtomicU64,
    kernels: AtomicU64,
}

impl Timing {
    /// Adds the time since `since` to `stage`.
    pub(crate) fn add(&self, stage: Stage, since: Instant) {
        self.add_ns(stage, since.elapsed().as_nanos() as u64);
    }

    pub(crate) fn add_ns(&self, stage: Stage, ns: u64) {
        self.ns[stage as usize].fetch_add(ns, Ordering::Relaxed);
        if let Stage::Kernel = stage {
            self.kernels.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Counts a dispatch of `rays`.
    pub(crate) fn dispatched(&self, rays: usize) {
        self.dispatches.fetch_add(1, Ordering::Relaxed);
        self.rays.fetch_add(rays as u64, Ordering::Relaxed);
    }

    /// Counts `rays` traced again on the CPU.
    pub(crate) fn retraced(&self, rays: usize) {
        self.retraced.fetch_add(rays as u64, Ordering::Relaxed);
    }

    pub(crate) fn read(&self) -> DispatchTimes {
        let s = |stage: Stage| self.ns[stage as usize].load(Ordering::Relaxed) as f64 * 1e-9;
        let dispatches = self.dispatches.load(Ordering::Relaxed);
        DispatchTimes {
            dispatches,
            rays: self.rays.load(Ordering::Relaxed),
            retraced: self.retraced.load(Ordering::Relaxed),
            pack_s: s(Stage::Pack),
            upload_s: s(Stage::Upload),
            submit_s: s(Stage::Submit),
            wait_s: s(Stage::Wait),
            read_s: s(Stage::Read),
            settle_s: s(Stage::Settle),
            // Only where every dispatch was timed on the device.
            kernel_s: (dispatches > 0 && self.kernels.load(Ordering::Relaxed) == dispatches)
                .then(|| s(Stage::Kernel)),
        }
    }

    pub(crate) fn reset(&self) {
        for c in self
            .ns
            .iter()
            .chain([&self.dispatches, &self.rays, &self.retraced, &self.kernels])
        {
            c.store(0, Ordering::Relaxed);
        }
    }
}
