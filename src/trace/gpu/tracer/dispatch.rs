//! A dispatch's way through the device: rays packed straight into a
//! mapped staging buffer (in parallel, before a set of dispatch buffers is
//! taken), copied to the device, traced, and the answers read back.
//!
//! In: a [`RayBatch`]'s rays from an index on, and what the shader answers
//! ([`Kind`]). Out: the answers' words in the rays' order (two bits a ray
//! for occlusion, a word for a closest hit), and each stage's time in the
//! tracer's [`Timing`](super::Timing).

use super::{GpuTracer, IN_FLIGHT, Kind, RAYS_PER_DISPATCH, Stage, WORKGROUP, one_line};
use crate::error::{Error, Result};
use crate::trace::RayBatch;
use crate::trace::ray::{Hit, shifted_ray};
use rayon::prelude::*;
use std::sync::atomic::Ordering;

/// Bytes of one ray as the shader reads it (`Ray` in traverse.wgsl).
const RAY_BYTES: u64 = 32;
/// Bytes of the largest answer (a closest hit: its triangle and flag).
const ANSWER_BYTES: u64 = 4;

/// How long a dispatch may take before the GPU counts as failed (hung):
/// far beyond what 2^20 rays take even on a software adapter, so only a
/// GPU that stopped answering reaches it, and the bake goes on without it
/// instead of waiting forever.
const DISPATCH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(120);

/// How often a dispatch in flight asks wgpu whether it is done.
const POLL_INTERVAL: std::time::Duration = std::time::Duration::from_micros(50);

/// One dispatch's buffers, for up to `capacity` rays.
pub(super) struct Slots {
    capacity: usize,
    rays: wgpu::Buffer,
    answers: wgpu::Buffer,
    readback: wgpu::Buffer,
    params: wgpu::Buffer,
    group: wgpu::BindGroup,
    /// The kernel's start and end timestamps, and where they resolve.
    queries: Option<(wgpu::QuerySet, wgpu::Buffer)>,
}

/// Bytes of the two timestamps after a dispatch's answers in its read-back.
const TIMESTAMP_BYTES: u64 = 16;

/// A host-visible buffer rays are packed into, for up to `capacity` rays.
pub(super) struct Staging {
    buffer: wgpu::Buffer,
    capacity: usize,
}

impl GpuTracer {
    /// Rays `from..` of `rays` in dispatches of at most
    /// [`RAYS_PER_DISPATCH`], each through a free set of dispatch buffers,
    /// each dispatch's answers' words handed to `read` with the index of
    /// its first ray, in order. Without `wait`,
    /// `Ok(false)` and nothing traced when no set is free at the start.
    ///
    /// Each dispatch's rays are packed (in parallel, into a buffer kept for
    /// the next batch) before a set is taken, and a set is held only for
    /// the upload, the wait and the copy out: a worker holding one never
    /// waits on rayon's other work, which could be a batch waiting for
    /// that set, so waiting for a set cannot deadlock.
    pub(super) fn batch(
        &self,
        rays: &RayBatch,
        from: usize,
        kind: Kind,
        wait: bool,
        read: &mut dyn FnMut(usize, &[u32]),
    ) -> Result<bool> {
        if !wait && !self.exclusive && !self.any_slots_free() {
            return Ok(false);
        }
        let mut start = from;
        while start < rays.len() {
            let end = (start + RAYS_PER_DISPATCH).min(rays.len());
            let packing = std::time::Instant::now();
            let staging = self.staging_for(end - start);
            {
                let bytes = (end - start) as u64 * RAY_BYTES;
                let mut view = staging.buffer.slice(..bytes).get_mapped_range_mut();
                let base = Mapped(view.slice(..).as_raw_element_ptr().as_ptr());
                let firsts: Vec<usize> = (start..end).step_by(PACK_PIECE).collect();
                firsts.into_par_iter().for_each(|first| {
                    let n = (end - first).min(PACK_PIECE);
                    // SAFETY: the pieces are disjoint ranges of the mapping,
                    // which `view` keeps mapped until every piece is written.
                    unsafe { pack_into(rays, first, n, kind, base.at(first - start)) }
                });
            }
            staging.buffer.unmap();
            self.timing.add(Stage::Pack, packing);
            let mut slots = self.take_slots();
            self.dispatch(&mut slots, staging, end - start, kind, &mut |w| {
                read(start, w)
            })?;
            start = end;
        }
        Ok(true)
    }

    /// A staging buffer mapped for writing for at least `rays` rays: a
    /// ready one, else a new one.
    fn staging_for(&self, rays: usize) -> Staging {
        let mut ready = self.staging.lock().unwrap_or_else(|e| e.into_inner());
        // The smallest that holds them.
        let fits = (ready.iter().enumerate())
            .filter(|(_, s)| s.capacity >= rays)
            .min_by_key(|(_, s)| s.capacity)
            .map(|(k, _)| k);
        if let Some(k) = fits {
            return ready.swap_remove(k);
        }
        drop(ready);
        let capacity = rays.next_power_of_two().clamp(1 << 12, RAYS_PER_DISPATCH);
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staging"),
            size: capacity as u64 * RAY_BYTES,
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: true,
        });
        Staging { buffer, capacity }
    }

    /// One dispatch of the `n` rays packed in `staging`: copies them to
    /// the device, runs the shader, hands the answers' words to `read`,
    /// and maps `staging` again for a later batch.
    fn dispatch(
        &self,
        slots: &mut Option<Slots>,
        staging: Staging,
        n: usize,
        kind: Kind,
        read: &mut dyn FnMut(&[u32]),
    ) -> Result<()> {
        if self.lose_after == Some(self.dispatches.fetch_add(1, Ordering::Relaxed)) {
            self.device.destroy();
        }
        self.check()?;
        if slots.as_ref().is_none_or(|s| s.capacity < n) {
            *slots = Some(self.slots(n.next_power_of_two().min(RAYS_PER_DISPATCH)));
        }
        let s = slots.as_ref().expect("made above");
        let uploading = std::time::Instant::now();
        self.timing.dispatched(n);
        let queue = &self.queue;
        queue.write_buffer(&s.params, 0, bytemuck::cast_slice(&[n as u32, 0, 0, 0]));
        let bytes = 4 * kind.answer_words(n) as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&staging.buffer, 0, &s.rays, 0, n as u64 * RAY_BYTES);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: s.queries.as_ref().map(|(set, _)| {
                    wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }
                }),
            });
            pass.set_pipeline(match kind {
                Kind::Occluded => &self.occluded,
                Kind::Closest => &self.closest,
            });
            pass.set_bind_group(0, &s.group, &[]);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP) as u32, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&s.answers, 0, &s.readback, 0, bytes);
        let stamps = s.capacity as u64 * ANSWER_BYTES;
        if let Some((set, resolve)) = &s.queries {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &s.readback, stamps, TIMESTAMP_BYTES);
        }
        let command = encoder.finish();
        self.timing.add(Stage::Upload, uploading);
        let submitting = std::time::Instant::now();
        queue.submit([command]);
        self.timing.add(Stage::Submit, submitting);
        let slice = s.readback.slice(..);
        let (send, receive) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = send.send(r);
        });
        // What wgpu reported on its own (a lost device) says more than
        // the failed call it caused.
        let failed = |e: &dyn std::fmt::Display| match self.check() {
            Err(reported) => reported,
            Ok(()) => Error::Gpu(one_line(&format!("{}: {e}", self.adapter.name))),
        };
        // Polled, not waited on: a blocking wait holds wgpu's fence lock,
        // which every other worker's submission then waits for, and the
        // dispatches in flight would run one at a time.
        let start = std::time::Instant::now();
        let mapped = loop {
            self.device
                .poll(wgpu::PollType::Poll)
                .map_err(|e| failed(&e))?;
            match receive.try_recv() {
                Ok(mapped) => break mapped,
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
                Err(e) => return Err(failed(&e)),
            }
            if start.elapsed() > DISPATCH_TIMEOUT {
                return Err(failed(&format!(
                    "no answer within {} s",
                    DISPATCH_TIMEOUT.as_secs()
                )));
            }
            std::thread::sleep(POLL_INTERVAL);
        };
        self.timing.add(Stage::Wait, start);
        mapped.map_err(|e| failed(&format!("reading the answers back: {e}")))?;
        let reading = std::time::Instant::now();
        {
            let mapped = slice.get_mapped_range();
            let words: &[u32] = bytemuck::cast_slice(&mapped);
            read(&words[..bytes as usize / 4]);
            if let Some(tick_ns) = self.tick_ns.filter(|_| s.queries.is_some()) {
                let at = stamps as usize / 4;
                let stamp =
                    |k: usize| words[at + 2 * k] as u64 | (words[at + 2 * k + 1] as u64) << 32;
                let ticks = stamp(1).saturating_sub(stamp(0));
                self.timing
                    .add_ns(Stage::Kernel, (ticks as f64 * tick_ns) as u64);
            }
        }
        s.readback.unmap();
        // The copy from `staging` is done: mapped again, it goes back for
        // the next batches (dropped if the device is lost meanwhile).
        let ready = self.staging.clone();
        let buffer = staging.buffer.clone();
        staging
            .buffer
            .slice(..)
            .map_async(wgpu::MapMode::Write, move |r| {
                if r.is_ok() {
                    let mut ready = ready.lock().unwrap_or_else(|e| e.into_inner());
                    ready.push(Staging {
                        buffer,
                        capacity: staging.capacity,
                    });
                }
            });
        self.timing.add(Stage::Read, reading);
        self.check()
    }

    /// Whether a set of dispatch buffers is free now (a hint: another
    /// worker may take it first, and the batch then waits for one). A
    /// test's [`GpuTracer::refuse_every`] refuses some attempts as if all
    /// were in flight.
    fn any_slots_free(&self) -> bool {
        if let Some(k) = self.refuse_every
            && (self.attempts.fetch_add(1, Ordering::Relaxed)).is_multiple_of(k)
        {
            return false;
        }
        self.slots.iter().any(|s| s.try_lock().is_ok())
    }

    /// A set of dispatch buffers no other dispatch holds: the first free
    /// one from a rotating start; all in flight, the next in turn once it
    /// is free.
    fn take_slots(&self) -> std::sync::MutexGuard<'_, Option<Slots>> {
        let first = self.next_slot.fetch_add(1, Ordering::Relaxed);
        for k in 0..IN_FLIGHT {
            if let Ok(slots) = self.slots[(first + k) % IN_FLIGHT].try_lock() {
                return slots;
            }
        }
        self.slots[first % IN_FLIGHT]
            .lock()
            .unwrap_or_else(|e| e.into_inner())
    }

    /// Buffers for dispatches of up to `capacity` rays.
    fn slots(&self, capacity: usize) -> Slots {
        let device = &self.device;
        let buffer = |label, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let n = capacity as u64;
        let rays = buffer("rays", n * RAY_BYTES, U::STORAGE | U::COPY_DST);
        let answers = buffer("answers", n * ANSWER_BYTES, U::STORAGE | U::COPY_SRC);
        let readback = buffer(
            "readback",
            n * ANSWER_BYTES + TIMESTAMP_BYTES,
            U::MAP_READ | U::COPY_DST,
        );
        let queries = self.tick_ns.map(|_| {
            let set = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let resolve = buffer("timestamps", 256, U::QUERY_RESOLVE | U::COPY_SRC);
            (set, resolve)
        });
        let params = buffer("params", 16, U::UNIFORM | U::COPY_DST);
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("traverse"),
            layout: &self.layout,
            entries: &[
                entry(0, &self.nodes),
                entry(1, &self.tris),
                entry(2, &rays),
                entry(3, &answers),
                entry(4, &params),
                entry(5, &self.occluder),
            ],
        });
        Slots {
            capacity,
            rays,
            answers,
            readback,
            params,
            group,
            queries,
        }
    }
}

/// Rays packed by one worker at a time.
const PACK_PIECE: usize = 4096;

/// The start of a mapping that workers write disjoint pieces of.
#[derive(Clone, Copy)]
struct Mapped(*mut u8);

// SAFETY: each worker writes its own piece (`pack_into`'s contract).
unsafe impl Send for Mapped {}
unsafe impl Sync for Mapped {}

impl Mapped {
    /// Where ray `k` of the mapping goes.
    fn at(self, k: usize) -> *mut u8 {
        self.0.wrapping_add(k * RAY_BYTES as usize)
    }
}

/// Rays `first..first + n` of `rays` packed at `out` (mapped memory,
/// written once and in order, as write-combining memory prefers).
///
/// # Safety
/// `out` must be valid for `n` rays' bytes, written by no one else.
unsafe fn pack_into(rays: &RayBatch, first: usize, n: usize, kind: Kind, out: *mut u8) {
    const RUN: usize = 256;
    let mut run = [[0f32; 8]; RUN];
    for at in (0..n).step_by(RUN) {
        let m = (n - at).min(RUN);
        for (k, ray) in run[..m].iter_mut().enumerate() {
            *ray = pack(rays, first + at + k, kind);
        }
        let bytes: &[u8] = bytemuck::cast_slice(&run[..m]);
        // SAFETY: within the `n` rays the caller gave.
        unsafe {
            let to = out.add(at * RAY_BYTES as usize);
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), to, bytes.len());
        }
    }
}

/// Ray `i` of `rays` as the shader reads it: the CPU's shifted ray
/// (bvh.rs), rounded here as there, and for a closest hit the cap; a
/// blocked ray keeps its negative end.
fn pack(rays: &RayBatch, i: usize, kind: Kind) -> [f32; 8] {
    if rays.is_blocked(i) {
        return [0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0];
    }
    let t_max = rays.t_max()[i];
    let r = shifted_ray(rays.origins()[i], rays.directions()[i], t_max);
    let cap = match kind {
        Kind::Occluded => 0.0,
        Kind::Closest => Hit::cap(t_max, rays.depths()[i]),
    };
    let (o, d) = (r.origin, r.direction);
    [o.x, o.y, o.z, r.tmax, d.x, d.y, d.z, cap]
}
