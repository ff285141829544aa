//! Where a bake traces its rays (`--device`).
//!
//! In: the level's tracer (the CPU's, built), its occluders and the
//! [`Device`] asked for. Out: the tracer with the GPU backend attached
//! where the device says so, and the [`Backend`] it traces on (for the
//! report, the shard's fingerprint and the one line saying which).
//!
//! `auto` takes a hardware GPU adapter when the build has the `gpu`
//! feature and the machine has one, else the CPU (a software adapter such
//! as lavapipe is not a GPU for it); `gpu` takes any Vulkan adapter and is
//! an error without one; `cpu` never looks.

use super::settings::Device;
#[cfg(feature = "gpu")]
use crate::error::Error;
use crate::error::Result;
use crate::trace::Tracer;
use glam::Vec3A;
use serde::Serialize;

/// What a bake traces on.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Backend {
    /// The GPU adapter answering the ray batches ("NVIDIA H200",
    /// "llvmpipe (...)"); `None`: the CPU traces every ray.
    pub adapter: Option<String>,
    /// Why `auto` traced on the CPU, if it looked for a GPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_because: Option<String>,
    /// With a GPU, the rays of the ray batches it answered, and those the
    /// CPU answered beside it (every dispatch in flight) or after it
    /// failed; known once the bake has run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rays_on_gpu: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rays_on_cpu: Option<u64>,
}

impl Backend {
    /// The device this bake's rays were traced on, as a shard records it.
    pub fn device(&self) -> Device {
        if self.adapter.is_some() {
            Device::Gpu
        } else {
            Device::Cpu
        }
    }

    /// This backend with `tracer`'s counts of the rays each side answered.
    pub fn with_rays(&self, tracer: &Tracer) -> Backend {
        let (gpu, cpu) = tracer.accelerated_rays().unzip();
        Backend {
            rays_on_gpu: gpu,
            rays_on_cpu: cpu,
            ..self.clone()
        }
    }

    /// One line saying where the rays are traced.
    pub fn line(&self) -> String {
        match (&self.adapter, &self.cpu_because) {
            (Some(a), _) => format!("tracing on the GPU: {a}"),
            (None, Some(why)) => format!("tracing on the CPU ({why})"),
            (None, None) => "tracing on the CPU".into(),
        }
    }
}

/// Attaches the GPU backend to `tracer` as `device` asks.
pub fn attach(tracer: &mut Tracer, occluders: &[[Vec3A; 3]], device: Device) -> Result<Backend> {
    #[cfg(feature = "gpu")]
    {
        use crate::trace::gpu::{AUTO_SOFTWARE_VAR, Adapters, GpuTracer};
        // (A test of `auto`'s fallbacks on a machine with lavapipe only
        // lets it take a software adapter.)
        let software = std::env::var(AUTO_SOFTWARE_VAR).is_ok_and(|v| v == "1");
        let which = match device {
            Device::Cpu => return Ok(Backend::default()),
            Device::Auto if !software => Adapters::Hardware,
            Device::Auto | Device::Gpu => Adapters::Any,
        };
        match GpuTracer::new(occluders, which) {
            Ok(Some(gpu)) => {
                let adapter = gpu.adapter().name.clone();
                gpu.attach_to(tracer);
                Ok(Backend {
                    adapter: Some(adapter),
                    ..Backend::default()
                })
            }
            // No occluder: no ray is ever occluded, nothing to trace.
            Ok(None) => Ok(Backend::default()),
            Err(e) if device == Device::Auto => Ok(Backend {
                cpu_because: Some(match e {
                    Error::Gpu(m) => m,
                    e => e.to_string(),
                }),
                ..Backend::default()
            }),
            Err(e) => Err(e),
        }
    }
    // Without the backend, `gpu` was refused by BakeSettings::validate.
    #[cfg(not(feature = "gpu"))]
    {
        let _ = (tracer, occluders, device);
        Ok(Backend::default())
    }
}
