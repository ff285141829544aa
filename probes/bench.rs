//! Benchmark: end-to-end bakes of one scene by several methods on the same
//! atlas (the unwrap is deterministic), each compared texel by texel with a
//! high-ray Monte Carlo reference.
//!
//!     cargo run --release --example bench -- [SCENE.glb] [--resolution 1024]
//!         [--reference 2048] [--runs adaptive,sheared,mc:16,mc:64,mc:256]
//!         [--dump-rays DIR]
//!
//! The scene defaults to the bundled courtyard (`assets/generated/`). The
//! runs are `aobake report`'s budgets: `adaptive` is the default bake
//! (`adaptive:QUALITY[:PRE[:MAX]]`, `adaptive-mean:MEAN`), `sheared` the
//! paper's filter (`sheared:K:R[:C[:O[:W]]]`: sparse rays, gather radius,
//! rays per brute-forced cell, Omega_v, min weight), `mc:N` Monte Carlo.
//! Prints markdown tables; all figures come from one run on one machine.
//! `--dump-rays DIR` also writes 2M of the bake's Monte Carlo rays for
//! `tools/embree_compare.py` and times obvhs on them.

use aobake::atlas::AtlasSize;
use aobake::atlas::Receivers;
use aobake::bake::ReceiverRays;
use aobake::job::Baked;
use aobake::report::metrics::error_stats;
use aobake::trace::{RayBatch, Tracer};
use aobake::{BakeSettings, Method};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// The first `per` rays of every `stride`-th receiver, exactly as the MC
/// baker (seed 1) casts them: [ox, oy, oz, dx, dy, dz, t_max, geometric
/// normal] in bake space.
fn sample_rays(r: &Receivers, per: u32, stride: usize, t_max: f32) -> Vec<[f32; 10]> {
    (0..r.len())
        .step_by(stride)
        .flat_map(|i| {
            let rays = ReceiverRays::new(r, i, 1);
            let (o, g) = (rays.origin, rays.geo_normal);
            (0..per).map(move |k| {
                let d = rays.direction(k);
                [o.x, o.y, o.z, d.x, d.y, d.z, t_max, g.x, g.y, g.z]
            })
        })
        .collect()
}

fn write_f32(path: &Path, data: &[f32]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for v in data {
        f.write_all(&v.to_le_bytes()).unwrap();
    }
}

fn dump_rays(dir: &Path, reference: &Baked) {
    std::fs::create_dir_all(dir).unwrap();
    let receivers = &reference.receivers;
    let tracer = Tracer::new(&reference.geometry.occluders);
    let t_max = (reference.report.max_distance / reference.geometry.space.diagonal) as f32;
    let stride = (receivers.len() * 16 / 2_000_000).max(1);
    let rays = sample_rays(receivers, 16, stride, t_max);
    let tris: Vec<f32> = reference
        .geometry
        .occluders
        .iter()
        .flat_map(|t| t.iter().flat_map(|v| v.to_array()))
        .collect();
    write_f32(&dir.join("tris.f32"), &tris);
    write_f32(
        &dir.join("rays.f32"),
        &rays.iter().flatten().copied().collect::<Vec<_>>(),
    );
    let v3 = |r: &[f32]| glam::Vec3::new(r[0], r[1], r[2]);
    let mask: Vec<u8> = rays
        .iter()
        .map(|r| !tracer.receiver_visible(v3(&r[0..3]), v3(&r[7..10]), v3(&r[3..6]), r[6]) as u8)
        .collect();
    std::fs::write(dir.join("occluded_obvhs.u8"), &mask).unwrap();
    // The same rays as one batch through the tracer's batch interface (the
    // passes' way), the horizon rule left to the comparison.
    let mut batch = RayBatch::new();
    for r in &rays {
        batch.push(v3(&r[0..3]), v3(&r[3..6]), r[6]);
    }
    let mut answers = Vec::new();
    let mut trace = || {
        let t = Instant::now();
        tracer.occluded_batch(&batch, &mut answers);
        (
            t.elapsed().as_secs_f64(),
            answers.iter().filter(|&&a| a).count(),
        )
    };
    let _ = trace();
    let (secs, hits) = trace();
    println!(
        "\nobvhs on {} dumped rays (one batch): {hits} occluded (plain), {} with the horizon rule, {secs:.3} s, {:.2} Mrays/s ({} threads)",
        rays.len(),
        mask.iter().map(|&m| m as usize).sum::<usize>(),
        rays.len() as f64 / secs / 1e6,
        rayon::current_num_threads()
    );
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
    let scene = args
        .first()
        .filter(|a| !a.starts_with("--"))
        .cloned()
        .unwrap_or("assets/generated/courtyard.glb".into());
    let resolution: u32 = flag("--resolution", "1024").parse().unwrap();
    let reference_rays: u32 = flag("--reference", "2048").parse().unwrap();
    let runs = flag("--runs", "adaptive,sheared,mc:16,mc:64,mc:256");
    let base = BakeSettings {
        size: AtlasSize::Resolution(resolution),
        ..Default::default()
    };
    let mc = |rays, seed| BakeSettings {
        method: Method::Mc,
        rays,
        seed,
        ..base.clone()
    };
    let path = Path::new(&scene);

    let reference = aobake::bake_file(path, &mc(reference_rays, 1)).expect("reference bake");
    let r = &reference.report;
    println!("scene: {scene}");
    println!(
        "atlas {}x{}, {} charts, {} texels, {} occluder triangles, {} threads, max distance {:.4} (world)\n",
        r.atlas_width,
        r.atlas_height,
        r.charts,
        r.texels,
        r.occluder_triangles,
        r.threads,
        r.max_distance
    );
    println!("reference ({reference_rays}-ray MC) stage times:\n\n| stage | seconds |\n|---|---|");
    for st in &r.stages {
        println!("| {} | {:.3} |", st.stage, st.seconds);
    }
    println!("| total | {:.3} |\n", r.total_seconds);
    if let Some(dir) = args
        .iter()
        .position(|a| a == "--dump-rays")
        .and_then(|i| args.get(i + 1))
    {
        dump_rays(Path::new(dir), &reference);
    }

    println!(
        "\n| run | total s | trace/filter s | rays/texel | Mrays/s | AO RMSE | AO bias | AO p99 err | SH RMSE | brute-forced cells |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let flat = |v: &[[f32; 9]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    let ref_sh = flat(&reference.bake.sh);
    for budget in aobake::report::parse_budgets(&runs).expect("--runs") {
        let run = budget.label();
        let settings = budget.settings(&base, 7);
        let t = Instant::now();
        let b = aobake::bake_file(path, &settings).expect("bake");
        let total = t.elapsed().as_secs_f64();
        assert_eq!(
            b.receivers.texel, reference.receivers.texel,
            "same atlas and receivers"
        );
        let rep = &b.report;
        let work: f64 = rep
            .stages
            .iter()
            .filter(|s| {
                [
                    "trace",
                    "sparse pass",
                    "filter pass",
                    "pre-pass",
                    "adaptive pass",
                    "filter",
                ]
                .contains(&s.stage)
            })
            .map(|s| s.seconds)
            .sum();
        let ao = error_stats(&b.bake.ao, &reference.bake.ao);
        let sh = error_stats(&flat(&b.bake.sh), &ref_sh);
        println!(
            "| {run} | {total:.2} | {work:.2} | {:.1} | {:.2} | {:.4} | {:+.4} | {:.3} | {:.4} | {} |",
            rep.rays_per_texel_total,
            rep.rays_cast as f64 / work / 1e6,
            ao.rmse,
            ao.bias,
            ao.p99,
            sh.rmse,
            rep.sheared.as_ref().map_or("-".into(), |f| format!(
                "{:.1}% ({:.1}% contact, {:.1}% no hit)",
                100.0 * f.cells_brute_forced,
                100.0 * f.cells_brute_contact,
                100.0 * f.cells_brute_no_hit
            )),
        );
        if args.iter().any(|a| a == "--breakdown") {
            // What the texture shows: texels inside geometry hold their
            // nearest valid texel's value in both bakes.
            let shown = |l: &aobake::lightmap::Lightmap| -> Vec<f32> {
                b.receivers
                    .texel
                    .iter()
                    .map(|&t| l.ao[t as usize])
                    .collect()
            };
            let tex = error_stats(&shown(&b.lightmap), &shown(&reference.lightmap));
            println!(
                "  texture (after the inside fill, {} texels inside): AO RMSE {:.4}, bias {:+.4}",
                b.report.texels_inside, tex.rmse, tex.bias
            );
        }
        if args.iter().any(|a| a == "--breakdown")
            && let Some(fs) = &b.sheared_stats
        {
            breakdown(fs, &b.bake.ao, &reference.bake.ao);
            // Nearest occluder and max distance in texel footprints: the
            // filter's spatial radius is at most z_min / Omega_v.
            let d_max = (rep.max_distance / b.geometry.space.diagonal) as f32;
            let mut z: Vec<f32> = fs
                .z_min
                .iter()
                .zip(&b.receivers.footprint)
                .map(|(z, f)| z.min(d_max) / f.max(1e-12))
                .collect();
            z.sort_by(f32::total_cmp);
            let mut dm: Vec<f32> = b
                .receivers
                .footprint
                .iter()
                .map(|f| d_max / f.max(1e-12))
                .collect();
            dm.sort_by(f32::total_cmp);
            let q = |v: &[f32], p: f64| v[((v.len() - 1) as f64 * p) as usize];
            println!(
                "\nnearest occluder, texel footprints: p10 {:.1}, median {:.1}, p90 {:.1}; max distance: median {:.1} footprints; mean neighbours {:.1}",
                q(&z, 0.1),
                q(&z, 0.5),
                q(&z, 0.9),
                q(&dm, 0.5),
                fs.neighbours.iter().map(|&n| n as f64).sum::<f64>() / fs.neighbours.len() as f64
            );
        }
    }
}

/// Where a filtered bake's AO error comes from: texels binned by their
/// fraction of brute-forced cells, each bin's share of the squared error.
fn breakdown(fs: &aobake::bake::sheared::ShearedStats, ao: &[f32], reference: &[f32]) {
    const BINS: usize = 5;
    let mut count = [0usize; BINS];
    let mut sq = [0f64; BINS];
    let mut bias = [0f64; BINS];
    for i in 0..ao.len() {
        let b = ((fs.brute_fraction[i] * BINS as f32) as usize).min(BINS - 1);
        let e = (ao[i] - reference[i]) as f64;
        count[b] += 1;
        sq[b] += e * e;
        bias[b] += e;
    }
    let total: f64 = sq.iter().sum();
    println!(
        "\n| brute fraction | texels | RMSE | bias | share of squared error |\n|---|---|---|---|---|"
    );
    for b in 0..BINS {
        let n = count[b].max(1) as f64;
        println!(
            "| {:.1}-{:.1} | {} | {:.4} | {:+.4} | {:.1}% |",
            b as f32 / BINS as f32,
            (b + 1) as f32 / BINS as f32,
            count[b],
            (sq[b] / n).sqrt(),
            bias[b] / n,
            100.0 * sq[b] / total.max(1e-30)
        );
    }
}
