//! The device side: a [`GpuTracer`] holds the occluders' tree in GPU
//! memory and answers batches of rays with the shaders of `traverse.wgsl`.
//!
//! In: bake-space occluder triangles, an adapter choice, then
//! [`RayBatch`]es. Out: per ray, an occlusion answer ([`GpuAnswer`]: a
//! sure hit, no candidate, or unsure) or the nearest candidate hit
//! ([`GpuHit`]: its triangle in the tree's leaf order, which
//! [`GpuTracer::primitives`] maps back to the occluders, and whether it is
//! sure). The caller traces the rays the GPU is unsure of on the CPU and
//! retests closest hits there for the CPU's distance ([`super::Attached`]).
//!
//! A batch goes in dispatches of at most [`RAYS_PER_DISPATCH`] rays
//! (`dispatch`), at most [`IN_FLIGHT`] at a time, each through a set of
//! buffers kept from one dispatch to the next (grown to the largest
//! dispatch seen, never past that bound): the GPU memory a bake takes is
//! the tree plus those sets, whatever the batches' sizes. Workers'
//! dispatches overlap each other's uploads and read-backs, and while the
//! GPU traces, the other workers build and read their batches on the CPU.

use super::timing::{DispatchTimes, Stage, Timing};
use super::{
    AdapterName, Adapters, RAYS_PER_DISPATCH, STACK_DEPTH, WORKGROUP, flatten, pick_adapter,
};
use crate::error::{Error, Result};
use crate::trace::RayBatch;
use glam::Vec3A;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};
use wgpu::util::DeviceExt;

mod dispatch;

use dispatch::{Slots, Staging};

/// Dispatches in flight at once, each with its own buffers: while one
/// worker's rays are uploaded or its answers read back, others' run.
const IN_FLIGHT: usize = 4;

/// No triangle (`NONE` in traverse.wgsl).
const NONE: u32 = u32::MAX;

/// The nearest candidate hit the GPU found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuHit {
    /// The triangle, in the tree's leaf order ([`GpuTracer::primitives`]).
    pub triangle: u32,
    /// Whether it is the CPU's hit: the CPU's test surely hits it, no
    /// other occluder's candidate is within rounding of its distance below
    /// the cut (which one is "the" hit is then rounding's or the traversal
    /// order's choice), and the walk was whole. The host retests it for
    /// the CPU's distance.
    pub sure: bool,
}

/// An occlusion answer from the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuAnswer {
    /// No triangle is a candidate: the CPU finds the ray unoccluded.
    Miss,
    /// A triangle the CPU's test surely hits: occluded.
    Hit,
    /// A candidate only within rounding of the test: the CPU decides.
    Unsure,
}

/// The closest hit's answer flag (`UNSURE_BIT` in traverse.wgsl).
const UNSURE_BIT: u32 = 1 << 31;

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
    /// Host-visible buffers mapped for writing, which dispatches' rays
    /// are packed straight into (no copy on the host): a buffer goes back
    /// here, mapped again, once its dispatch is done.
    staging: Arc<Mutex<Vec<Staging>>>,
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
    /// Where the time goes, per stage.
    pub(crate) timing: Timing,
    /// Nanoseconds per timestamp tick, where the adapter has timestamp
    /// queries (each dispatch's kernel is then timed on the device).
    tick_ns: Option<f64>,
}

/// Which shader a dispatch runs.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Occluded,
    Closest,
}

impl Kind {
    /// Words of the answers of `rays` rays: two bits a ray for
    /// occlusion, a word a ray for a closest hit.
    fn answer_words(self, rays: usize) -> usize {
        match self {
            Kind::Occluded => rays.div_ceil(16),
            Kind::Closest => rays,
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
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("aobake"),
            required_features: if timestamps {
                wgpu::Features::TIMESTAMP_QUERY
            } else {
                wgpu::Features::empty()
            },
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
            staging: Arc::new(Mutex::new(Vec::new())),
            errors,
            lost,
            dispatches: AtomicU64::new(0),
            lose_after,
            attempts: AtomicU64::new(0),
            refuse_every: refuse_every.map(|k: u64| k.max(1)),
            exclusive: false,
            timing: Timing::default(),
            tick_ns: timestamps.then(|| queue.get_timestamp_period() as f64),
            queue,
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

    /// Per ray of `rays`, whether anything is hit in (0, t_max] as the
    /// CPU's test decides it ([`GpuAnswer`]; a blocked ray: `Miss`, the
    /// caller answers it), into `out` (cleared first), in the batch's
    /// order. Waits for a set of dispatch buffers when all are in flight.
    pub fn occlusion(&self, rays: &RayBatch, out: &mut Vec<GpuAnswer>) -> Result<()> {
        out.clear();
        self.occlusion_from(rays, 0, true, out).map(|_| ())
    }

    /// [`GpuTracer::occlusion`] of rays `from..` of `rays`, appended to
    /// `out`; without `wait`, `Ok(false)` (nothing traced) when every set
    /// of dispatch buffers is in flight.
    pub fn occlusion_from(
        &self,
        rays: &RayBatch,
        from: usize,
        wait: bool,
        out: &mut Vec<GpuAnswer>,
    ) -> Result<bool> {
        let n = rays.len().saturating_sub(from);
        let first = out.len();
        out.resize(first + n, GpuAnswer::Miss);
        let traced = self.batch(rays, from, Kind::Occluded, wait, &mut |start, words| {
            let out = &mut out[first + start - from..];
            let count = out.len().min(RAYS_PER_DISPATCH);
            for (i, out) in out[..count].iter_mut().enumerate() {
                *out = match (words[i / 16] >> (2 * (i % 16))) & 3 {
                    0 => GpuAnswer::Miss,
                    1 => GpuAnswer::Hit,
                    _ => GpuAnswer::Unsure,
                };
            }
        })?;
        if !traced {
            out.truncate(first);
        }
        Ok(traced)
    }

    /// Per ray of `rays`, the nearest candidate hit in (0, t_max] cut at
    /// its depth ([`crate::trace::Tracer::trace_closest`]), `None` where no
    /// triangle is hit (a blocked ray: `None`), into `out` (cleared first).
    /// Waits for a set of dispatch buffers when all are in flight.
    pub fn closest(&self, rays: &RayBatch, out: &mut Vec<Option<GpuHit>>) -> Result<()> {
        out.clear();
        self.closest_from(rays, 0, true, out).map(|_| ())
    }

    /// [`GpuTracer::closest`] of rays `from..` of `rays`, appended to
    /// `out`; without `wait`, `Ok(false)` (nothing traced) when every set
    /// of dispatch buffers is in flight.
    pub fn closest_from(
        &self,
        rays: &RayBatch,
        from: usize,
        wait: bool,
        out: &mut Vec<Option<GpuHit>>,
    ) -> Result<bool> {
        out.reserve(rays.len().saturating_sub(from));
        self.batch(rays, from, Kind::Closest, wait, &mut |_, words| {
            out.extend(words.iter().map(|&a| {
                (a != NONE).then_some(GpuHit {
                    triangle: a & !UNSURE_BIT,
                    sure: a & UNSURE_BIT == 0,
                })
            }))
        })
    }

    /// For measurements of the GPU alone: every batch waits for a dispatch
    /// instead of being shared with the CPU while all are in flight.
    #[doc(hidden)]
    pub fn exclusive(&mut self) {
        self.exclusive = true;
    }

    /// For tests of batches shared with the CPU: of the attempts to start
    /// a batch without waiting, the 1st, (k+1)th, (2k+1)th, ... find every
    /// set of dispatch buffers in flight, as [`SHARE_VAR`] asks from the
    /// environment.
    #[doc(hidden)]
    pub fn refuse_every(&mut self, k: u64) {
        self.refuse_every = Some(k.max(1));
    }

    /// Where this tracer's time went, summed over its dispatches.
    pub fn dispatch_times(&self) -> DispatchTimes {
        self.timing.read()
    }

    /// Starts the sums of [`GpuTracer::dispatch_times`] afresh.
    pub fn reset_dispatch_times(&self) {
        self.timing.reset()
    }
}

/// `message` on one line (wgpu's span several).
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}
