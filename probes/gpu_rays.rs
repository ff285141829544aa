//! The GPU backend against the CPU's on a scene's own rays: the Monte
//! Carlo rays its bake casts (16 per texel at every k-th texel of page 0,
//! seed 1, up to 2M), answered as occlusion and as closest hits by the CPU
//! tracer on all threads and by the GPU (feature `gpu`), in batches of
//! 2^17 rays traced in parallel as a bake's workers cast them, timed after
//! a warm-up. The GPU's rate is its own (every batch waits for a dispatch
//! of its own); a bake's rate, the GPU with the CPU's threads tracing
//! beside it while every dispatch is in flight, is printed as "shared";
//! and the GPU's occlusion rate with the rays by direction instead of in
//! the batch's order (trace/gpu/order.rs), an order yet to be measured on
//! a GPU.
//!
//!     cargo run --release --features gpu --example gpu_rays -- SCENE.glb
//!         [--resolution 1024] [--rays 2000000] [--hardware]
//!
//! Prints the adapter, both rates (Mrays/s) and how many answers differ;
//! `--hardware` fails unless the adapter is a hardware GPU (not lavapipe).
//! Rays exactly on a triangle's edge or at the max distance may round
//! otherwise; the rest agree.

use aobake::atlas::AtlasSize;
use aobake::bake::ReceiverRays;
use aobake::job::{Level, RunOptions};
use aobake::stage::StageTimer;
use aobake::trace::gpu::{Adapters, GpuTracer};
use aobake::trace::{Closest, Hit, Occlusion, Query, RayBatch, Tracer};
use aobake::{BakeSettings, Device};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// Rays per texel, as a Monte Carlo bake's first ones.
const PER_TEXEL: u32 = 16;

/// Rays to a batch, as a bake's workers cast them (a few thousand
/// receivers' rays each), the batches traced in parallel.
const BATCH: usize = 1 << 17;

/// Seconds of `tracer` answering `rays` as `Q` in batches of [`BATCH`]
/// traced in parallel (the second of two runs), and the answers in order.
fn timed<Q: Query>(tracer: &Tracer, rays: &RayBatch) -> (f64, Vec<Q::Answer>) {
    let batches: Vec<RayBatch> = (0..rays.len())
        .step_by(BATCH)
        .map(|start| {
            let mut batch = RayBatch::new();
            for i in start..(start + BATCH).min(rays.len()) {
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
    let t = Instant::now();
    let answers = trace();
    (t.elapsed().as_secs_f64(), answers.concat())
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
    on_gpu.attach_gpu(gpu);
    let mut shared = Tracer::with_sides(occluders, sides);
    shared.attach_gpu(start());
    // The GPU alone with the rays by direction rather than in the batch's
    // order (receiver by receiver): trace/gpu/order.rs.
    let mut by_direction = Tracer::with_sides(occluders, sides);
    let mut gpu = start();
    gpu.exclusive();
    gpu.order_by_direction();
    by_direction.attach_gpu(gpu);
    let n = rays.len();
    println!(
        "{path}: {} triangles, {n} rays ({} blocked) from {} of {} texels; GPU adapter {:?}{}; CPU {} threads",
        occluders.len(),
        (0..n).filter(|&i| rays.is_blocked(i)).count(),
        receivers.len().div_ceil(stride),
        receivers.len(),
        adapter.name,
        if adapter.software { " (software)" } else { "" },
        rayon::current_num_threads()
    );
    let rate = |secs: f64| n as f64 / secs / 1e6;
    let (cpu_s, cpu_occluded) = timed::<Occlusion>(&cpu, &rays);
    let (gpu_s, gpu_occluded) = timed::<Occlusion>(&on_gpu, &rays);
    let (shared_s, shared_occluded) = timed::<Occlusion>(&shared, &rays);
    let (by_direction_s, by_direction_occluded) = timed::<Occlusion>(&by_direction, &rays);
    let in_order_s = gpu_s;
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
    let (cpu_s, cpu_hits) = timed::<Closest>(&cpu, &rays);
    let (gpu_s, gpu_hits) = timed::<Closest>(&on_gpu, &rays);
    let (shared_s, shared_hits) = timed::<Closest>(&shared, &rays);
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
    println!(
        "occlusion on the GPU with the rays by direction: {:.2} Mrays/s ({:.2}x the rate in the batch's order); {} differ",
        rate(by_direction_s),
        in_order_s / by_direction_s,
        differing_occluded(&by_direction_occluded)
    );
    if let Some((gpu, cpu)) = shared.gpu_rays() {
        println!(
            "shared: {:.1}% of the rays traced on the GPU",
            100.0 * gpu as f64 / (gpu + cpu).max(1) as f64
        );
    }
    let failed = [&on_gpu, &shared, &by_direction]
        .into_iter()
        .find_map(|t| t.gpu_failure());
    if let Some(failure) = failed {
        eprintln!("the GPU failed, the CPU answered the rest: {failure}");
        std::process::exit(1);
    }
    if args.iter().any(|a| a == "--hardware") && adapter.software {
        eprintln!("{} is a software adapter, not a GPU", adapter.name);
        std::process::exit(1);
    }
}
