//! Benchmark: stage times, ray throughput, and Monte Carlo error against a
//! high-ray reference on one atlas.
//!
//!     cargo run --release --example bench -- [SCENE.glb] [--resolution 1024] [--reference 2048] [--rays 16,64,256]
//!
//! Prints a markdown table. All figures come from one run on one machine.

use aobake::load;
use aobake::mc::{self, McSettings};
use aobake::pipeline::DEFAULT_MAX_DISTANCE_FRACTION;
use aobake::rasterize::{self, Receivers};
use aobake::sample::{Frame, cosine_hemisphere, receiver_seed, sobol_2d};
use aobake::trace::{Tracer, offset_origin};
use aobake::unwrap::{self, AtlasSize, Packing, UnwrapOptions};
use rayon::prelude::*;
use std::io::Write;
use std::time::Instant;

fn rmse(a: &[f32], b: &[f32]) -> f64 {
    (a.iter()
        .zip(b)
        .map(|(x, y)| ((x - y) as f64).powi(2))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt()
}

/// The first `per` rays of every `stride`-th receiver, as the MC baker casts
/// them: [ox, oy, oz, dx, dy, dz, t_max] in bake space.
fn sample_rays(r: &Receivers, per: u32, stride: usize, t_max: f32) -> Vec<[f32; 10]> {
    (0..r.len())
        .step_by(stride)
        .flat_map(|i| {
            let frame = Frame::from_normal(r.normal[i]);
            let o = offset_origin(r.position[i], r.geo_normal[i], r.footprint[i]);
            let g = r.geo_normal[i];
            let seed = receiver_seed(1, r.texel[i] as u64, 0);
            (0..per).map(move |k| {
                let d = frame
                    .to_world(cosine_hemisphere(sobol_2d(k, seed)))
                    .normalize();
                [o.x, o.y, o.z, d.x, d.y, d.z, t_max, g.x, g.y, g.z]
            })
        })
        .collect()
}

fn write_f32(path: &std::path::Path, data: &[f32]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for v in data {
        f.write_all(&v.to_le_bytes()).unwrap();
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str, default: &str| -> String {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
            .unwrap_or(default.to_string())
    };
    let scene_path = args
        .first()
        .filter(|a| !a.starts_with("--"))
        .cloned()
        .unwrap_or("../shared/assets/sponza_dabrovic.glb".into());
    let resolution: u32 = flag("--resolution", "1024").parse().unwrap();
    let reference: u32 = flag("--reference", "2048").parse().unwrap();
    let ladder: Vec<u32> = flag("--rays", "16,64,256")
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect();

    let t = Instant::now();
    let scene = load::load(std::path::Path::new(&scene_path)).expect("load");
    let t_load = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let geometry = scene.bake_geometry().expect("geometry");
    let t_prep = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let opts = UnwrapOptions {
        size: AtlasSize::Resolution(resolution),
        padding: 2,
        packing: Packing::Fast,
    };
    let atlas =
        unwrap::unwrap(&geometry.receivers, &opts, geometry.space.diagonal).expect("unwrap");
    let t_unwrap = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let receivers = rasterize::rasterize(&geometry.receivers, &atlas);
    let t_raster = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let tracer = Tracer::new(&geometry.occluders);
    let t_bvh = t.elapsed().as_secs_f64();

    println!("scene: {scene_path}");
    println!(
        "atlas {}x{}, {} charts, {} texels (receivers), {} occluder triangles, {} threads, max distance {} x diagonal\n",
        atlas.width,
        atlas.height,
        atlas.charts,
        receivers.len(),
        tracer.triangle_count(),
        rayon::current_num_threads(),
        DEFAULT_MAX_DISTANCE_FRACTION
    );
    println!("| stage | seconds |\n|---|---|");
    for (s, v) in [
        ("load", t_load),
        ("bake-space geometry", t_prep),
        ("unwrap", t_unwrap),
        ("rasterize", t_raster),
        ("BVH build", t_bvh),
    ] {
        println!("| {s} | {v:.3} |");
    }

    if let Some(dir) = args
        .iter()
        .position(|a| a == "--dump-rays")
        .and_then(|i| args.get(i + 1))
    {
        // 2M of the bake's own rays, for tools/embree_compare.py.
        let dir = std::path::Path::new(dir);
        std::fs::create_dir_all(dir).unwrap();
        let stride = (receivers.len() * 16 / 2_000_000).max(1);
        let rays = sample_rays(&receivers, 16, stride, DEFAULT_MAX_DISTANCE_FRACTION as f32);
        let tris: Vec<f32> = geometry
            .occluders
            .iter()
            .flat_map(|t| t.iter().flat_map(|v| v.to_array()))
            .collect();
        write_f32(&dir.join("tris.f32"), &tris);
        write_f32(
            &dir.join("rays.f32"),
            &rays.iter().flatten().copied().collect::<Vec<_>>(),
        );
        let trace = |rays: &[[f32; 10]]| {
            let t = Instant::now();
            let hits: usize = rays
                .par_chunks(4096)
                .map(|c| {
                    c.iter()
                        .filter(|r| {
                            tracer.occluded(
                                glam::Vec3::new(r[0], r[1], r[2]),
                                glam::Vec3::new(r[3], r[4], r[5]),
                                r[6],
                            )
                        })
                        .count()
                })
                .sum();
            (t.elapsed().as_secs_f64(), hits)
        };
        let v3 = |r: &[f32]| glam::Vec3::new(r[0], r[1], r[2]);
        let mask: Vec<u8> = rays
            .iter()
            .map(|r| {
                !tracer.receiver_visible(v3(&r[0..3]), v3(&r[7..10]), v3(&r[3..6]), r[6]) as u8
            })
            .collect();
        println!(
            "occluded with the horizon rule (as baked): {} of {}",
            mask.iter().map(|&m| m as usize).sum::<usize>(),
            rays.len()
        );
        std::fs::write(dir.join("occluded_obvhs.u8"), &mask).unwrap();
        let _ = trace(&rays); // warm caches
        let (secs, hits) = trace(&rays);
        println!(
            "\nobvhs on the dumped rays: {} rays, {hits} occluded, {:.3} s, {:.2} Mrays/s ({} threads)\n",
            rays.len(),
            secs,
            rays.len() as f64 / secs / 1e6,
            rayon::current_num_threads()
        );
    }

    let settings = |rays| McSettings {
        rays,
        max_distance: DEFAULT_MAX_DISTANCE_FRACTION as f32,
        seed: 1,
    };
    let t = Instant::now();
    let reference_bake = mc::bake(&receivers, &tracer, &settings(reference), &|_| {});
    let t_ref = t.elapsed().as_secs_f64();
    println!("| trace, reference {reference} rays | {t_ref:.3} |\n");
    println!(
        "| rays/texel | trace s | Mrays/s | AO RMSE | AO max err | SH RMSE (all 9) |\n|---|---|---|---|---|---|"
    );
    for &rays in &ladder {
        let t = Instant::now();
        let b = mc::bake(
            &receivers,
            &tracer,
            &McSettings {
                seed: 7,
                ..settings(rays)
            },
            &|_| {},
        );
        let secs = t.elapsed().as_secs_f64();
        let ao_rmse = rmse(&b.ao, &reference_bake.ao);
        let ao_max =
            b.ao.iter()
                .zip(&reference_bake.ao)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max);
        let flat = |v: &[[f32; 9]]| v.iter().flatten().copied().collect::<Vec<f32>>();
        let sh_rmse = rmse(&flat(&b.sh), &flat(&reference_bake.sh));
        println!(
            "| {rays} | {secs:.2} | {:.2} | {ao_rmse:.4} | {ao_max:.3} | {sh_rmse:.4} |",
            b.rays as f64 / secs / 1e6
        );
    }
    println!(
        "| {reference} (reference) | {t_ref:.2} | {:.2} | 0 | 0 | 0 |",
        reference_bake.rays as f64 / t_ref / 1e6
    );
}
