//! The GPU backend: occlusion rays answered by a wgpu compute shader.
//!
//! In: bake-space occluder triangles, then [`RayBatch`]es. Out: per ray
//! whether anything (either face) is hit in (0, t_max], as
//! [`super::Tracer::occluded_batch`] answers, in the batch's order.
//!
//! - `flatten`: obvhs's BVH2 as the shader's nodes and triangles.
//! - `occlusion.wgsl`: the traversal (a short stack, any hit ends it) and
//!   the watertight triangle test.
//!
//! The adapter is Vulkan's (wgpu's Vulkan backend only): a hardware GPU,
//! or with [`Adapters::Any`] also a software one such as Mesa's lavapipe,
//! which runs the same shader on the CPU (the tests use it). Every failure
//! (no adapter, a device lost mid-batch, a shader the driver refuses) is
//! an [`Error::Gpu`] naming what failed, for the caller to fall back or
//! stop on; nothing here panics on a GPU's answer.

mod flatten;

pub use flatten::{FlatBvh, GpuNode, GpuTri, flatten};

use super::RayBatch;
use super::bvh::shifted_ray;
use crate::error::{Error, Result};
use glam::Vec3A;
use std::sync::{Arc, Mutex};
use wgpu::util::DeviceExt;

/// Rays per dispatch: bounds the GPU memory a batch takes (32 bytes of
/// ray and 4 of answer each: 36 MiB) whatever the batch's size.
pub const RAYS_PER_DISPATCH: usize = 1 << 20;

/// Threads per workgroup (`@workgroup_size` in occlusion.wgsl).
const WORKGROUP: usize = 64;

/// The stack the shader walks with (`STACK` in occlusion.wgsl): a tree
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

/// A [`GpuTracer`] behind a CPU tracer ([`super::Tracer::attach_gpu`]):
/// answers its occlusion batches until one fails, then leaves every later
/// batch to the CPU and keeps the first failure for the job to report.
pub struct Attached {
    tracer: GpuTracer,
    failure: std::sync::OnceLock<String>,
}

impl Attached {
    pub fn new(tracer: GpuTracer) -> Attached {
        Attached {
            tracer,
            failure: std::sync::OnceLock::new(),
        }
    }

    pub fn adapter(&self) -> &AdapterName {
        self.tracer.adapter()
    }

    /// The first failure, if a batch failed.
    pub fn failure(&self) -> Option<&str> {
        self.failure.get().map(String::as_str)
    }

    /// Answers `rays` into `out` on the GPU: false (nothing answered) once
    /// a batch has failed.
    pub fn occluded_batch(&self, rays: &RayBatch, out: &mut Vec<bool>) -> bool {
        if self.failure.get().is_some() {
            return false;
        }
        match self.tracer.occluded_batch(rays, out) {
            Ok(()) => true,
            Err(e) => {
                let _ = self.failure.set(e.to_string());
                false
            }
        }
    }
}

/// The occluders on the GPU, and what traces rays against them.
pub struct GpuTracer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    nodes: wgpu::Buffer,
    tris: wgpu::Buffer,
    adapter: AdapterName,
    /// One dispatch at a time: GPU memory holds one dispatch's buffers.
    busy: Mutex<()>,
    /// The first error wgpu reported outside a call's result (a refused
    /// shader, a validation error, a lost device), instead of its default
    /// of panicking.
    errors: Arc<Mutex<Option<String>>>,
}

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
                ..wgpu::Limits::downlevel_defaults()
            },
            ..Default::default()
        }))
        .map_err(|e| Error::Gpu(format!("{}: no device: {e}", name.name)))?;
        let errors = Arc::new(Mutex::new(None));
        let first = |sink: &Arc<Mutex<Option<String>>>, what: String| {
            let mut slot = sink.lock().unwrap_or_else(|e| e.into_inner());
            slot.get_or_insert(what);
        };
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| first(&sink, e.to_string())));
        let sink = errors.clone();
        device.set_device_lost_callback(move |reason, message| {
            first(&sink, format!("device lost ({reason:?}): {message}"))
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
        let nodes = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("nodes"),
            contents: bytemuck::cast_slice(&flat.nodes),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let tris = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("triangles"),
            contents: bytemuck::cast_slice(&flat.tris),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("occlusion.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("occlusion.wgsl").into()),
        });
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("occlusion"),
            entries: &[
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("occlusion"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("occlusion"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("occluded"),
            compilation_options: Default::default(),
            cache: None,
        });
        let tracer = GpuTracer {
            device,
            queue,
            pipeline,
            layout,
            nodes,
            tris,
            adapter: name,
            busy: Mutex::new(()),
            errors,
        };
        tracer.check()?;
        Ok(Some(tracer))
    }

    /// The first error wgpu reported, if any, as this tracer's failure.
    fn check(&self) -> Result<()> {
        let slot = self.errors.lock().unwrap_or_else(|e| e.into_inner());
        match &*slot {
            Some(e) => Err(Error::Gpu(format!("{}: {e}", self.adapter.name))),
            None => Ok(()),
        }
    }

    /// The adapter this tracer runs on.
    pub fn adapter(&self) -> &AdapterName {
        &self.adapter
    }

    /// Per ray of `rays`, whether anything is hit in (0, t_max] (a blocked
    /// ray: true), into `out` (cleared first), in the batch's order, in
    /// dispatches of at most [`RAYS_PER_DISPATCH`] rays.
    pub fn occluded_batch(&self, rays: &RayBatch, out: &mut Vec<bool>) -> Result<()> {
        out.clear();
        out.reserve(rays.len());
        let mut packed: Vec<[f32; 8]> = Vec::with_capacity(rays.len().min(RAYS_PER_DISPATCH));
        let (origins, directions, t_max) = (rays.origins(), rays.directions(), rays.t_max());
        let mut start = 0;
        while start < rays.len() {
            let end = (start + RAYS_PER_DISPATCH).min(rays.len());
            packed.clear();
            // The CPU's shifted ray (bvh.rs), rounded here as there; a
            // blocked ray keeps its negative end.
            packed.extend((start..end).map(|i| {
                if rays.is_blocked(i) {
                    return [0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0];
                }
                let r = shifted_ray(origins[i], directions[i], t_max[i]);
                let (o, d) = (r.origin, r.direction);
                [o.x, o.y, o.z, r.tmax, d.x, d.y, d.z, 0.0]
            }));
            let answers = self.dispatch(&packed)?;
            out.extend(answers.iter().map(|&a| a != 0));
            start = end;
        }
        Ok(())
    }

    /// One dispatch: uploads the rays, runs the shader, reads the answers
    /// back.
    fn dispatch(&self, rays: &[[f32; 8]]) -> Result<Vec<u32>> {
        let _one = self.busy.lock().unwrap_or_else(|e| e.into_inner());
        self.check()?;
        let n = rays.len();
        let device = &self.device;
        let ray_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("rays"),
            contents: bytemuck::cast_slice(rays),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let bytes = (n * 4) as u64;
        let hits = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::cast_slice(&[n as u32, 0, 0, 0]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("occlusion"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.nodes.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.tris.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ray_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: hits.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP) as u32, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&hits, 0, &readback, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let slice = readback.slice(..);
        let (send, receive) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = send.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("{}: {e}", self.adapter.name)))?;
        receive
            .recv()
            .map_err(|e| Error::Gpu(format!("{}: {e}", self.adapter.name)))?
            .map_err(|e| {
                Error::Gpu(format!(
                    "{}: reading the answers back: {e}",
                    self.adapter.name
                ))
            })?;
        let answers = bytemuck::cast_slice(&slice.get_mapped_range()).to_vec();
        readback.unmap();
        self.check()?;
        Ok(answers)
    }
}
