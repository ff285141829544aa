//! The device side: a [`GpuTracer`] holds the occluders' tree in GPU
//! memory and answers batches of rays with the shaders of `traverse.wgsl`.
//!
//! In: bake-space occluder triangles, an adapter choice, then
//! [`RayBatch`]es. Out: per ray, candidates (traverse.wgsl's margin test):
//! a triangle that may occlude it, or the nearest candidate hit's triangle
//! in the tree's leaf order ([`GpuTracer::primitives`] maps it back to the
//! occluders) and a near tie's. Every triangle the CPU's test hits is a candidate; the caller
//! settles them with that test ([`super::Attached`]).
//!
//! A batch goes in dispatches of at most [`RAYS_PER_DISPATCH`] rays, at
//! most [`IN_FLIGHT`] at a time, each through a set of buffers kept from
//! one dispatch to the next (grown to the largest dispatch seen, never past
//! that bound): the GPU memory a bake takes is the tree plus those sets,
//! whatever the batches' sizes. Workers' dispatches overlap each other's
//! uploads and read-backs, and while the GPU traces, the other workers
//! build and read their batches on the CPU.

use super::{
    AdapterName, Adapters, RAYS_PER_DISPATCH, STACK_DEPTH, WORKGROUP, flatten, order, pick_adapter,
};
use crate::error::{Error, Result};
use crate::trace::RayBatch;
use crate::trace::bvh::{Hit, shifted_ray};
use glam::Vec3A;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use wgpu::util::DeviceExt;

/// Bytes of one ray as the shader reads it (`Ray` in traverse.wgsl).
const RAY_BYTES: u64 = 32;
/// Bytes of the largest answer (a closest hit: its triangle and a tie's).
const ANSWER_BYTES: u64 = 8;

/// How long a dispatch may take before the GPU counts as failed (hung):
/// far beyond what 2^20 rays take even on a software adapter, so only a
/// GPU that stopped answering reaches it, and the bake goes on without it
/// instead of waiting forever.
const DISPATCH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(120);

/// Dispatches in flight at once, each with its own buffers: while one
/// worker's rays are uploaded or its answers read back, others' run.
const IN_FLIGHT: usize = 4;

/// How often a dispatch in flight asks wgpu whether it is done.
const POLL_INTERVAL: std::time::Duration = std::time::Duration::from_micros(50);

/// No triangle (`NONE` in traverse.wgsl).
const NONE: u32 = u32::MAX;

/// The nearest candidate hit the GPU found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuHit {
    /// The triangle, in the tree's leaf order ([`GpuTracer::primitives`]).
    pub triangle: u32,
    /// Another occluder's candidate within rounding of its distance,
    /// below the cut: which one is "the" hit is then rounding's or the
    /// traversal order's choice.
    pub tie: Option<u32>,
}

/// For tests of a device lost mid-bake: the tracer destroys its own
/// device after this many dispatches, which wgpu reports as a lost device.
pub const LOSE_AFTER_VAR: &str = "AOBAKE_GPU_LOSE_AFTER";

/// For tests of `--device auto` on a machine without a hardware GPU (the
/// CI's): set to 1, `auto` takes a software adapter too.
pub const AUTO_SOFTWARE_VAR: &str = "AOBAKE_GPU_AUTO_SOFTWARE";

/// For tests of batches shared with the CPU: every how many attempts to
/// start a batch find the GPU busy ([`GpuTracer::refuse_every`]).
pub const SHARE_VAR: &str = "AOBAKE_GPU_BUSY_EVERY";

/// The occluders on the GPU, and what traces rays against them.
pub struct GpuTracer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    occluded: wgpu::ComputePipeline,
    closest: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    nodes: wgpu::Buffer,
    tris: wgpu::Buffer,
    /// Per triangle in leaf order, its occluder (`occluder` in the shader).
    occluder: wgpu::Buffer,
    /// Per triangle in leaf order, its index among the occluders.
    primitives: Vec<u32>,
    adapter: AdapterName,
    /// The dispatch buffers, [`IN_FLIGHT`] sets: a dispatch holds one set's
    /// lock from its upload to its read-back.
    slots: Vec<Mutex<Option<Slots>>>,
    /// The set the next dispatch tries first.
    next_slot: std::sync::atomic::AtomicUsize,
    /// The first error wgpu reported outside a call's result (a refused
    /// shader, a validation error), instead of its default of panicking.
    errors: Arc<Mutex<Option<String>>>,
    /// Why the device was lost, if it was: the cause of every error after.
    lost: Arc<Mutex<Option<String>>>,
    dispatches: AtomicU64,
    lose_after: Option<u64>,
    /// Attempts to start a batch without waiting, and every how many of
    /// them a test has refused ([`GpuTracer::refuse_every`]).
    attempts: AtomicU64,
    refuse_every: Option<u64>,
    /// Every batch waits for a dispatch ([`GpuTracer::exclusive`]).
    exclusive: bool,
    /// Rays go to the GPU by direction ([`GpuTracer::order_by_direction`]).
    by_direction: bool,
}

/// One dispatch's buffers, for up to `capacity` rays.
struct Slots {
    capacity: usize,
    rays: wgpu::Buffer,
    answers: wgpu::Buffer,
    readback: wgpu::Buffer,
    params: wgpu::Buffer,
    group: wgpu::BindGroup,
}

/// Which shader a dispatch runs.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Occluded,
    Closest,
}

impl Kind {
    fn answer_words(self) -> usize {
        match self {
            Kind::Occluded => 1,
            Kind::Closest => 2,
        }
    }
}

impl GpuTracer {
    /// Uploads `occluders` (bake space) to the first adapter `which`
    /// admits; `Ok(None)` without triangles (nothing to trace: no ray is
    /// ever occluded).
    pub fn new(occluders: &[[Vec3A; 3]], which: Adapters) -> Result<Option<GpuTracer>> {
        let Some(flat) = flatten(occluders) else {
            return Ok(None);
        };
        if flat.depth > STACK_DEPTH {
            return Err(Error::Gpu(format!(
                "the BVH is {} levels deep, past the shader's stack of {STACK_DEPTH}",
                flat.depth
            )));
        }
        let (adapter, name) = pick_adapter(which)?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("aobake"),
            required_limits: wgpu::Limits {
                max_storage_buffer_binding_size: adapter.limits().max_storage_buffer_binding_size,
                max_buffer_size: adapter.limits().max_buffer_size,
                // Five storage buffers (Vulkan promises four; drivers give
                // eight and more).
                max_storage_buffers_per_shader_stage: 5,
                ..wgpu::Limits::downlevel_defaults()
            },
            ..Default::default()
        }))
        .map_err(|e| Error::Gpu(one_line(&format!("{}: no device: {e}", name.name))))?;
        let errors = Arc::new(Mutex::new(None));
        let first = |sink: &Arc<Mutex<Option<String>>>, what: String| {
            let mut slot = sink.lock().unwrap_or_else(|e| e.into_inner());
            slot.get_or_insert_with(|| one_line(&what));
        };
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| first(&sink, e.to_string())));
        let lost = Arc::new(Mutex::new(None));
        let sink = lost.clone();
        device.set_device_lost_callback(move |reason, message| {
            let why = if message.is_empty() {
                String::new()
            } else {
                format!(": {message}")
            };
            first(&sink, format!("device lost ({reason:?}){why}"))
        });
        let limit = device.limits().max_storage_buffer_binding_size as usize;
        let node_bytes = std::mem::size_of_val(flat.nodes.as_slice());
        let tri_bytes = std::mem::size_of_val(flat.tris.as_slice());
        if node_bytes.max(tri_bytes) > limit {
            return Err(Error::Gpu(format!(
                "{}: the scene's BVH ({node_bytes} bytes of nodes, {tri_bytes} of triangles) is past its storage binding limit of {limit}",
                name.name
            )));
        }
        let upload = |label, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let nodes = upload("nodes", bytemuck::cast_slice(&flat.nodes));
        let tris = upload("triangles", bytemuck::cast_slice(&flat.tris));
        let occluder = upload("occluders", bytemuck::cast_slice(&flat.primitives));
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("traverse.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("traverse.wgsl").into()),
        });
        let buffer = |binding: u32, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("traverse"),
            entries: &[
                buffer(0, storage(true)),
                buffer(1, storage(true)),
                buffer(2, storage(true)),
                buffer(3, storage(false)),
                buffer(4, wgpu::BufferBindingType::Uniform),
                buffer(5, storage(true)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("traverse"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let (occluded, closest) = (pipeline("occluded"), pipeline("closest"));
        let var = |name| std::env::var(name).ok().and_then(|v| v.parse().ok());
        let (lose_after, refuse_every) = (var(LOSE_AFTER_VAR), var(SHARE_VAR));
        let tracer = GpuTracer {
            device,
            queue,
            occluded,
            closest,
            layout,
            nodes,
            tris,
            occluder,
            primitives: flat.primitives,
            adapter: name,
            slots: (0..IN_FLIGHT).map(|_| Mutex::new(None)).collect(),
            next_slot: Default::default(),
            errors,
            lost,
            dispatches: AtomicU64::new(0),
            lose_after,
            attempts: AtomicU64::new(0),
            refuse_every: refuse_every.map(|k: u64| k.max(1)),
            exclusive: false,
            by_direction: false,
        };
        tracer.check()?;
        Ok(Some(tracer))
    }

    /// The first error wgpu reported, if any, as this tracer's failure.
    /// A lost device is named before the errors it caused (wgpu reports
    /// the loss when polled, often after the first call it failed).
    fn check(&self) -> Result<()> {
        let read =
            |slot: &Mutex<Option<String>>| slot.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if read(&self.errors).is_some() {
            // wgpu reports a lost device once its queue has drained.
            let _ = self.device.poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: Some(std::time::Duration::from_secs(2)),
            });
        }
        match read(&self.lost).or_else(|| read(&self.errors)) {
            Some(e) => Err(Error::Gpu(format!("{}: {e}", self.adapter.name))),
            None => Ok(()),
        }
    }

    /// For tests of a lost device: the tracer destroys its own device
    /// before its dispatch number `dispatches` (from 0), as
    /// [`LOSE_AFTER_VAR`] asks from the environment.
    #[doc(hidden)]
    pub fn lose_device_after(&mut self, dispatches: u64) {
        self.lose_after = Some(dispatches);
    }

    /// The adapter this tracer runs on.
    pub fn adapter(&self) -> &AdapterName {
        &self.adapter
    }

    /// Per triangle in the tree's leaf order (as the candidates name
    /// them), its index among the occluders given.
    pub fn primitives(&self) -> &[u32] {
        &self.primitives
    }

    /// Per ray of `rays`, a triangle (leaf order) that may occlude it in
    /// (0, t_max], `None` where none does (a blocked ray: `None`, the
    /// caller answers it), into `out` (cleared first), in the batch's order.
    /// Waits for a set of dispatch buffers when all are in flight.
    pub fn occlusion_candidates(&self, rays: &RayBatch, out: &mut Vec<Option<u32>>) -> Result<()> {
        out.clear();
        self.occlusion_candidates_from(rays, 0, true, out)
            .map(|_| ())
    }

    /// [`GpuTracer::occlusion_candidates`] of rays `from..` of `rays`,
    /// appended to `out`; without `wait`, `Ok(false)` (nothing traced)
    /// when every set of dispatch buffers is in flight.
    pub fn occlusion_candidates_from(
        &self,
        rays: &RayBatch,
        from: usize,
        wait: bool,
        out: &mut Vec<Option<u32>>,
    ) -> Result<bool> {
        out.reserve(rays.len().saturating_sub(from));
        self.batch(rays, from, Kind::Occluded, wait, |answers| {
            out.extend(answers.iter().map(|&a| (a != NONE).then_some(a)))
        })
    }

    /// Per ray of `rays`, the nearest candidate hit in (0, t_max] cut at
    /// its depth ([`crate::trace::Tracer::trace_closest`]), `None` where no
    /// triangle is hit (a blocked ray: `None`), into `out` (cleared first).
    /// Waits for a set of dispatch buffers when all are in flight.
    pub fn closest_candidates(&self, rays: &RayBatch, out: &mut Vec<Option<GpuHit>>) -> Result<()> {
        out.clear();
        self.closest_candidates_from(rays, 0, true, out).map(|_| ())
    }

    /// [`GpuTracer::closest_candidates`] of rays `from..` of `rays`,
    /// appended to `out`; without `wait`, `Ok(false)` (nothing traced)
    /// when every set of dispatch buffers is in flight.
    pub fn closest_candidates_from(
        &self,
        rays: &RayBatch,
        from: usize,
        wait: bool,
        out: &mut Vec<Option<GpuHit>>,
    ) -> Result<bool> {
        out.reserve(rays.len().saturating_sub(from));
        self.batch(rays, from, Kind::Closest, wait, |answers| {
            out.extend(answers.chunks_exact(2).map(|a| {
                (a[0] != NONE).then(|| GpuHit {
                    triangle: a[0],
                    tie: (a[1] != NONE).then_some(a[1]),
                })
            }))
        })
    }

    /// Rays `from..` of `rays` in dispatches of at most
    /// [`RAYS_PER_DISPATCH`] through one set of dispatch buffers, each
    /// dispatch's answers handed to `read` in order. Without `wait`,
    /// `Ok(false)` and nothing traced when no set is free.
    fn batch(
        &self,
        rays: &RayBatch,
        from: usize,
        kind: Kind,
        wait: bool,
        mut read: impl FnMut(&[u32]),
    ) -> Result<bool> {
        let Some(mut slots) = self.free_slots(wait) else {
            return Ok(false);
        };
        let most = rays.len().saturating_sub(from).min(RAYS_PER_DISPATCH);
        let mut packed: Vec<[f32; 8]> = Vec::with_capacity(most);
        let (mut order, mut answers) = (Vec::new(), Vec::new());
        let words = kind.answer_words();
        let mut start = from;
        while start < rays.len() {
            let end = (start + RAYS_PER_DISPATCH).min(rays.len());
            packed.clear();
            if !self.by_direction {
                packed.par_extend((start..end).into_par_iter().map(|i| pack(rays, i, kind)));
                self.dispatch(&mut slots, &packed, kind, &mut read)?;
            } else {
                // By direction on the GPU (order.rs), the answers put back
                // in the batch's order.
                order::by_direction(rays, start, end, &mut order);
                packed.par_extend(order.par_iter().map(|&i| pack(rays, i as usize, kind)));
                self.dispatch(&mut slots, &packed, kind, &mut |sorted: &[u32]| {
                    order::put_back(&order, start, words, sorted, &mut answers);
                    read(&answers)
                })?;
            }
            start = end;
        }
        Ok(true)
    }

    /// One dispatch: uploads the rays, runs the shader, reads the answers
    /// back into `read`.
    fn dispatch(
        &self,
        slots: &mut Option<Slots>,
        rays: &[[f32; 8]],
        kind: Kind,
        read: &mut impl FnMut(&[u32]),
    ) -> Result<()> {
        if self.lose_after == Some(self.dispatches.fetch_add(1, Ordering::Relaxed)) {
            self.device.destroy();
        }
        self.check()?;
        let n = rays.len();
        if slots.as_ref().is_none_or(|s| s.capacity < n) {
            *slots = Some(self.slots(n.next_power_of_two().min(RAYS_PER_DISPATCH)));
        }
        let s = slots.as_ref().expect("made above");
        let queue = &self.queue;
        queue.write_buffer(&s.rays, 0, bytemuck::cast_slice(rays));
        queue.write_buffer(&s.params, 0, bytemuck::cast_slice(&[n as u32, 0, 0, 0]));
        let bytes = (n * kind.answer_words() * 4) as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(match kind {
                Kind::Occluded => &self.occluded,
                Kind::Closest => &self.closest,
            });
            pass.set_bind_group(0, &s.group, &[]);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP) as u32, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&s.answers, 0, &s.readback, 0, bytes);
        queue.submit([encoder.finish()]);
        let slice = s.readback.slice(..bytes);
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
        mapped.map_err(|e| failed(&format!("reading the answers back: {e}")))?;
        read(bytemuck::cast_slice(&slice.get_mapped_range()));
        s.readback.unmap();
        self.check()
    }

    /// A set of dispatch buffers no other dispatch holds: the first free
    /// one from a rotating start; all in flight, the next in turn once it
    /// is free (`wait`) or none. (A test's [`GpuTracer::refuse_every`]
    /// refuses some attempts as if all were in flight.)
    fn free_slots(&self, wait: bool) -> Option<std::sync::MutexGuard<'_, Option<Slots>>> {
        let wait = wait || self.exclusive;
        let first = self.next_slot.fetch_add(1, Ordering::Relaxed);
        if !wait
            && let Some(k) = self.refuse_every
            && self
                .attempts
                .fetch_add(1, Ordering::Relaxed)
                .is_multiple_of(k)
        {
            return None;
        }
        for k in 0..IN_FLIGHT {
            if let Ok(slots) = self.slots[(first + k) % IN_FLIGHT].try_lock() {
                return Some(slots);
            }
        }
        wait.then(|| {
            self.slots[first % IN_FLIGHT]
                .lock()
                .unwrap_or_else(|e| e.into_inner())
        })
    }

    /// For measurements of the GPU alone: every batch waits for a dispatch
    /// instead of being shared with the CPU while all are in flight.
    #[doc(hidden)]
    pub fn exclusive(&mut self) {
        self.exclusive = true;
    }

    /// For measurements of the rays' order on a GPU (`probes/gpu_rays`):
    /// rays go to the GPU by direction (`order.rs`) instead of in the
    /// batch's order. Not a bake's: on lavapipe it changed nothing
    /// (Sponza's 10.7M rays: 2.23 against 2.24 Mrays/s), and no hardware
    /// GPU has measured it yet.
    #[doc(hidden)]
    pub fn order_by_direction(&mut self) {
        self.by_direction = true;
    }

    /// For tests of batches shared with the CPU: of the attempts to start
    /// a batch without waiting, the 1st, (k+1)th, (2k+1)th, ... find every
    /// set of dispatch buffers in flight, as [`SHARE_VAR`] asks from the
    /// environment.
    #[doc(hidden)]
    pub fn refuse_every(&mut self, k: u64) {
        self.refuse_every = Some(k.max(1));
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
        let readback = buffer("readback", n * ANSWER_BYTES, U::MAP_READ | U::COPY_DST);
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
        }
    }
}

/// `message` on one line (wgpu's span several).
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
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
