//! The GPU backend against the CPU's on a scene's own rays: the Monte
//! Carlo rays its bake casts (16 per texel at every k-th texel of page 0,
//! seed 1, up to 2M), answered as occlusion and as closest hits by the CPU
//! tracer on all threads and by the GPU (feature `gpu`), in batches of
//! 2^17 rays traced in parallel as a bake's workers cast them, timed after
//! a warm-up. The GPU's rate is its own (every batch waits for a dispatch
//! of its own); a bake's rate, the GPU with the CPU's threads tracing
//! beside it while every dispatch is in flight, is printed as "shared".
//! Per GPU run it prints where the time went per dispatch: the host's
//! stages (pack, upload and submit, wait, read, settle), the kernel's own
//! time on the device where the adapter has timestamp queries, and the
//! share of rays the GPU was unsure of (traced again on the CPU).
//!
//!     cargo run --release --features gpu --example gpu_rays -- SCENE.glb
//!         [--resolution 1024] [--rays 2000000] [--batch 131072] [--hardware]
//!
//! Prints the adapter, the rates (Mrays/s) and how many answers differ;
//! `--hardware` fails unless the adapter is a hardware GPU (not lavapipe).
//! Rays exactly on a triangle's edge or at the max distance may round
//! otherwise; the rest agree.

use aobake::atlas::AtlasSize;
use aobake::bake::ReceiverRays;
use aobake::job::{Level, RunOptions};
use aobake::stage::StageTimer;
use aobake::trace::gpu::{Adapters, Attached, GpuTracer};
use aobake::trace::{Closest, Hit, Occlusion, Query, RayBatch, Tracer};
use aobake::{BakeSettings, Device};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// Rays per texel, as a Monte Carlo bake's first ones.
const PER_TEXEL: u32 = 16;

/// Rays to a batch by default, as a bake's workers cast them (a few
/// thousand receivers' rays each), the batches traced in parallel.
const BATCH: usize = 1 << 17;

/// Seconds of `tracer` answering `rays` as `Q` in batches of `size`
/// traced in parallel (the second of two runs), and the answers in order.
fn timed<Q: Query>(tracer: &Tracer, rays: &RayBatch, size: usize) -> (f64, Vec<Q::Answer>) {
    let batches: Vec<RayBatch> = (0..rays.len())
        .step_by(size)
        .map(|start| {
            let mut batch = RayBatch::new();
            for i in start..(start + size).min(rays.len()) {
                if rays.is_blocked(i) {
                    batch.push_blocked(rays.directions()[i]);
                } else {
                    let (o, d) = (rays.origins()[i], rays.directions()[i]);
                    batch.push_within(o, d, rays.t_max()[i], rays.depths()[i]);
                }
            }
            batch
        })
        .collect();
    let trace = || -> Vec<Vec<Q::Answer>> {
        (batches.par_iter())
            .map(|b| {
                let mut out = Vec::new();
                tracer.trace_batch::<Q>(b, &mut out);
                out
            })
            .collect()
    };
    let _ = trace();
    if let Some(gpu) = gpu_of(tracer) {
        gpu.reset_dispatch_times();
    }
    let t = Instant::now();
    let answers = trace();
    (t.elapsed().as_secs_f64(), answers.concat())
}

/// The GPU backend attached to `tracer`, if it is one.
fn gpu_of(tracer: &Tracer) -> Option<&Attached> {
    tracer.accelerator()?.as_any().downcast_ref::<Attached>()
}

/// Where `tracer`'s GPU time went in its last timed run, per dispatch
/// and per ray: the host's stages (pack, upload, submit, wait, read,
/// settle), the kernel on the device where timestamps are there, and the
/// share of rays traced again on the CPU. The host's own time per ray is
/// pack, upload, read and settle: the submission and the wait are the
/// device's (a software adapter runs the kernel in the submission).
fn print_stages(what: &str, tracer: &Tracer) {
    let Some(t) = gpu_of(tracer).map(|g| g.dispatch_times()) else {
        return;
    };
    let rays = t.rays.max(1) as f64;
    let per_ray = |s: f64| s * 1e9 / rays;
    let per_dispatch = |s: f64| s * 1e3 / t.dispatches.max(1) as f64;
    let host = t.pack_s + t.upload_s + t.read_s + t.settle_s;
    let kernel = t.kernel_s.map_or("no timestamps".into(), |k| {
        format!(
            "{:.3} ms, {:.2} ns/ray ({:.0} Mrays/s on the device)",
            per_dispatch(k),
            per_ray(k),
            rays / k / 1e6
        )
    });
    println!(
        "{what}: {} dispatches of {:.0} rays; per dispatch (ms) pack {:.3}, upload {:.3}, submit {:.3}, wait {:.3}, read {:.3}, settle {:.3}; kernel {kernel}; host {:.2} ns per GPU-answered ray (pack {:.2}, upload {:.2}, read {:.2}, settle {:.2}); {} rays ({:.4}%) traced again on the CPU",
        t.dispatches,
        rays / t.dispatches.max(1) as f64,
        per_dispatch(t.pack_s),
        per_dispatch(t.upload_s),
        per_dispatch(t.submit_s),
        per_dispatch(t.wait_s),
        per_dispatch(t.read_s),
        per_dispatch(t.settle_s),
        per_ray(host),
        per_ray(t.pack_s),
        per_ray(t.upload_s),
        per_ray(t.read_s),
        per_ray(t.settle_s),
        t.retraced,
        100.0 * t.retraced as f64 / rays
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str, default: usize| -> usize {
        (args.iter().position(|a| a == name))
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().expect("a number"))
    };
    let path = args.first().expect("SCENE.glb");
    let (resolution, most) = (flag("--resolution", 1024), flag("--rays", 2_000_000));
    let size = flag("--batch", BATCH).max(1);
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(resolution as u32),
        device: Device::Cpu,
        ..BakeSettings::DEFAULT
    };
    let mut timer = StageTimer::new();
    let level = Level::new(&scene, &s, &RunOptions::QUIET, &mut timer).expect("prepare");
    let page = level.page(0, &scene, &mut timer).expect("page");
    let receivers = &page.receivers;
    let stride = (receivers.len() * PER_TEXEL as usize).div_ceil(most).max(1);
    let mut rays = RayBatch::new();
    for i in (0..receivers.len()).step_by(stride) {
        let r = ReceiverRays::new(receivers, i, 1);
        for k in 0..PER_TEXEL {
            let d = r.direction(k);
            if d.dot(r.geo_normal) <= 0.0 {
                rays.push_blocked(d);
            } else {
                rays.push(r.origin, d, level.max_distance);
            }
        }
    }
    let geometry = &level.geometry;
    let (occluders, sides) = (&geometry.occluders, &geometry.occluder_single_sided);
    let start = || {
        GpuTracer::new(occluders, Adapters::Any)
            .expect("a Vulkan adapter")
            .expect("occluders")
    };
    let mut gpu = start();
    gpu.exclusive();
    let adapter = gpu.adapter().clone();
    let cpu = Tracer::with_sides(occluders, sides);
    let mut on_gpu = Tracer::with_sides(occluders, sides);
    gpu.attach_to(&mut on_gpu);
    let mut shared = Tracer::with_sides(occluders, sides);
    start().attach_to(&mut shared);
    let n = rays.len();
    // The rays the GPU is unsure of (traced again on the CPU), by where
    // the CPU's closest hit lies: none (a candidate only within the
    // margins), or at the ray's very start (an origin on another surface).
    {
        let gpu = start();
        let mut answers = Vec::new();
        gpu.occlusion(&rays, &mut answers).expect("GPU");
        let mut bins = [0usize; 6];
        for i in (0..n).filter(|&i| answers[i] == aobake::trace::gpu::GpuAnswer::Unsure) {
            let (o, d, t) = (rays.origins()[i], rays.directions()[i], rays.t_max()[i]);
            let bin = match cpu.closest_hit(o, d, t) {
                None => 0,
                Some(h) if h < 1e-7 => 1,
                Some(h) if h < 1e-5 => 2,
                Some(h) if h < 1e-3 => 3,
                Some(h) if h < 1e-1 => 4,
                Some(_) => 5,
            };
            bins[bin] += 1;
        }
        println!(
            "occlusion rays the GPU is unsure of, by the CPU's closest hit: none {}, below 1e-7 {}, 1e-7..1e-5 {}, 1e-5..1e-3 {}, 1e-3..0.1 {}, beyond {}",
            bins[0], bins[1], bins[2], bins[3], bins[4], bins[5]
        );
    }
    println!(
        "{path}: {} triangles, {n} rays ({} blocked) from {} of {} texels, batches of {size}; GPU adapter {:?}{}; CPU {} threads",
        occluders.len(),
        (0..n).filter(|&i| rays.is_blocked(i)).count(),
        receivers.len().div_ceil(stride),
        receivers.len(),
        adapter.name,
        if adapter.software { " (software)" } else { "" },
        rayon::current_num_threads()
    );
    let rate = |secs: f64| n as f64 / secs / 1e6;
    let (cpu_s, cpu_occluded) = timed::<Occlusion>(&cpu, &rays, size);
    let (gpu_s, gpu_occluded) = timed::<Occlusion>(&on_gpu, &rays, size);
    print_stages("occlusion, GPU alone", &on_gpu);
    let (shared_s, shared_occluded) = timed::<Occlusion>(&shared, &rays, size);
    let differing_occluded = |answers: &[bool]| {
        (cpu_occluded.iter().zip(answers))
            .filter(|(a, b)| a != b)
            .count()
    };
    let differ = differing_occluded(&gpu_occluded);
    let occluded = cpu_occluded.iter().filter(|&&o| o).count();
    let only_gpu = (cpu_occluded.iter().zip(&gpu_occluded))
        .filter(|(a, b)| !**a && **b)
        .count();
    println!(
        "occlusion: CPU {:.2} Mrays/s, GPU {:.2} Mrays/s ({:.2}x), shared {:.2} Mrays/s ({:.2}x); {occluded} occluded; {differ} of {n} differ ({:.4}%), {only_gpu} occluded on the GPU only; shared: {} differ",
        rate(cpu_s),
        rate(gpu_s),
        cpu_s / gpu_s,
        rate(shared_s),
        cpu_s / shared_s,
        100.0 * differ as f64 / n as f64,
        differing_occluded(&shared_occluded)
    );
    let (cpu_s, cpu_hits) = timed::<Closest>(&cpu, &rays, size);
    let (gpu_s, gpu_hits) = timed::<Closest>(&on_gpu, &rays, size);
    print_stages("closest hits, GPU alone", &on_gpu);
    let (shared_s, shared_hits) = timed::<Closest>(&shared, &rays, size);
    // Compared as a pass reads them: the distance, the triangle's normal
    // and face (a triangle split into several leaves has several indices).
    let t_max = level.max_distance;
    let read = |h: &Option<Hit>, d: Vec3| {
        h.map(|h| {
            (
                h.distance_within(t_max, t_max),
                cpu.hit_normal(h),
                cpu.is_back_face(h, d),
            )
        })
    };
    let dirs = rays.directions();
    let differing = |hits: &[Option<Hit>]| {
        (0..n)
            .filter(|&i| read(&cpu_hits[i], dirs[i]) != read(&hits[i], dirs[i]))
            .count()
    };
    let differ = differing(&gpu_hits);
    let (mut presence, mut distance, mut face) = (0, 0, 0);
    for i in 0..n {
        match (read(&cpu_hits[i], dirs[i]), read(&gpu_hits[i], dirs[i])) {
            (Some(a), Some(b)) if a.0 != b.0 => distance += 1,
            (Some(a), Some(b)) if a != b => face += 1,
            (a, b) if a.is_some() != b.is_some() => presence += 1,
            _ => {}
        }
    }
    println!(
        "closest hits that differ: {presence} hit or miss, {distance} in distance, {face} in the triangle's normal or face"
    );
    let hit = cpu_hits.iter().filter(|h| h.is_some()).count();
    println!(
        "closest hits: CPU {:.2} Mrays/s, GPU {:.2} Mrays/s ({:.2}x), shared {:.2} Mrays/s ({:.2}x); {hit} hit; {differ} of {n} differ ({:.4}%); shared: {} differ",
        rate(cpu_s),
        rate(gpu_s),
        cpu_s / gpu_s,
        rate(shared_s),
        cpu_s / shared_s,
        100.0 * differ as f64 / n as f64,
        differing(&shared_hits)
    );
    if let Some((gpu, cpu)) = shared.accelerated_rays() {
        println!(
            "shared: {:.1}% of the rays traced on the GPU",
            100.0 * gpu as f64 / (gpu + cpu).max(1) as f64
        );
    }
    let failed = [&on_gpu, &shared]
        .into_iter()
        .find_map(|t| t.accelerator_failure());
    if let Some(failure) = failed {
        eprintln!("the GPU failed, the CPU answered the rest: {failure}");
        std::process::exit(1);
    }
    if args.iter().any(|a| a == "--hardware") && adapter.software {
        eprintln!("{} is a software adapter, not a GPU", adapter.name);
        std::process::exit(1);
    }
}
