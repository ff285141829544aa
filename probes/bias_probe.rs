//! Filter bias probe: the filtered method against a 2048-ray Monte Carlo
//! bake on the same receivers, on small scenes with known structure (a
//! floor under a plane, a floor beside a wall), with the bias binned by
//! distance to the wall. `CELLS=1 [X=-0.1] [K=32]` instead prints, per
//! hemisphere cell, the filter's occlusion minus a 256-ray-per-cell
//! reference, averaged over floor receivers at x = X (cells the filter
//! serves only): where in the hemisphere a bias comes from.
//!
//!     cargo run --release --example bias_probe
#[path = "../tests/common/mod.rs"]
mod common;
use aobake::Method;
use aobake::bake::sheared::ShearedOptions;
use aobake::stage::StageTimer;
use common::*;

fn probe(
    name: &str,
    g: &[u8],
    res: u32,
    d: f64,
    runs: &[(u32, f32, u32)],
    keep: &dyn Fn(glam::Vec3) -> bool,
) {
    let sc = scene(g);
    let mut s = settings(res, 2048, Some(d));
    s.fill_inside = false;
    let level =
        aobake::job::Level::new(&sc, &s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
    let p = level.page(0, &sc, &mut StageTimer::new()).unwrap();
    let reference = p
        .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .unwrap()
        .bake;
    let space = &p.level.geometry.space;
    let sel: Vec<usize> = (0..p.receivers.len())
        .filter(|&i| keep(space.to_world(p.receivers.position[i])))
        .collect();
    for &(k, r, c) in runs {
        let mut f = s.clone();
        f.method = Method::Sheared;
        f.sheared = ShearedOptions {
            sparse_rays: k,
            gather_radius: r,
            cell_rays: c,
            ..ShearedOptions::default()
        };
        let out = p
            .bake(&f, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
        let st = out.sheared_stats.unwrap();
        let (mut bias, mut sq, mut bf) = (0.0f64, 0.0f64, 0.0f64);
        for &i in &sel {
            let e = (out.bake.ao[i] - reference.ao[i]) as f64;
            bias += e;
            sq += e * e;
            bf += st.brute_fraction[i] as f64;
        }
        let n = sel.len() as f64;
        if name.starts_with("wall") {
            let mut bins = [(0.0f64, 0.0f64, 0usize); 8];
            for &i in &sel {
                let q = space.to_world(p.receivers.position[i]);
                let b = (((0.3 - q.x) / 0.08) as usize).min(7);
                bins[b].0 += (out.bake.ao[i] - reference.ao[i]) as f64;
                bins[b].1 += st.brute_fraction[i] as f64;
                bins[b].2 += 1;
            }
            for (b, (e, bf, c)) in bins.iter().enumerate() {
                println!(
                    "   dist {:.2}-{:.2}: bias {:+.4} brute {:.3} n {c}",
                    b as f32 * 0.08,
                    (b + 1) as f32 * 0.08,
                    e / *c as f64,
                    bf / *c as f64
                );
            }
        }
        let mc = {
            let mut m = s.clone();
            m.rays = 64;
            m.seed = 7;
            let b = p
                .bake(&m, &aobake::RunOptions::QUIET, &mut StageTimer::new())
                .unwrap()
                .bake;
            (sel.iter()
                .map(|&i| ((b.ao[i] - reference.ao[i]) as f64).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
        };
        println!(
            "{name:10} K{k:2} R{r:2} C{c}: n {n:6} bias {:+.4} rmse {:.4} brute {:.3} rays/texel {:.1} (mc64 rmse {mc:.4}) ref mean {:.3}",
            bias / n,
            (sq / n).sqrt(),
            bf / n,
            out.bake.rays as f64 / p.receivers.len() as f64,
            sel.iter().map(|&i| reference.ao[i] as f64).sum::<f64>() / n,
        );
    }
}

fn main() {
    if std::env::var("CELLS").is_ok() {
        return cells_main();
    }
    let runs = [(8, 4.0, 2), (8, 8.0, 2), (32, 8.0, 2)];
    // Floor under a parallel plane at height 1, max distance 2.
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let roof = quad([0.0, 0.0, 1.0], [0.0, 3.0, 0.0], [3.0, 0.0, 0.0], true);
    let g = glb(&[floor, roof], plain_nodes(2));
    probe("plane", &g, 256, 2.0, &runs, &|p| {
        p.z.abs() < 1e-3 && p.x.abs() < 0.8 && p.y.abs() < 0.8
    });
    let runs = [(8, 8.0, 2), (32, 8.0, 2)];
    for (name, half_h, d) in [
        ("wall_h1_d10", 0.5f32, 10.0),
        ("wall_h20_d1", 10.0, 1.0),
        ("wall_h1_d1", 0.5, 1.0),
    ] {
        let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
        let wall = quad(
            [0.3, 0.0, half_h],
            [0.0, 0.0, half_h],
            [0.0, 1.0, 0.0],
            true,
        );
        let g = glb(&[floor, wall], plain_nodes(2));
        probe(name, &g, 256, d, &runs, &|p| {
            p.z.abs() < 1e-3 && p.x < 0.29 && p.y.abs() < 0.5
        });
    }
}

fn cells_main() {
    use aobake::bake::sheared as filter;
    use aobake::sample::{CELL_COUNT, Frame, cosine_hemisphere, in_cell, sobol_2d};
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 1.0, 0.0], true);
    let g = glb(&[floor, wall], plain_nodes(2));
    let sc = scene(&g);
    let mut s = settings(256, 64, Some(10.0));
    s.fill_inside = false;
    let level =
        aobake::job::Level::new(&sc, &s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
    let p = level.page(0, &sc, &mut StageTimer::new()).unwrap();
    let space = &p.level.geometry.space;
    let world = |i: usize| space.to_world(p.receivers.position[i]);
    let k_env: u32 = std::env::var("K")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(32);
    let target_x: f32 = std::env::var("X")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(-0.1);
    let fs = filter::ShearedOptions {
        sparse_rays: k_env,
        gather_radius: 8.0,
        ..Default::default()
    };
    let params = aobake::bake::BakeParams {
        max_distance: p.level.max_distance,
        seed: 0,
    };
    let samples = filter::sparse_pass(&p.receivers, &p.level.tracer, &fs, &params);
    // Average over receivers near (target_x, y in [-0.3, 0.3]).
    let rs: Vec<usize> = (0..p.receivers.len())
        .filter(|&i| {
            let q = world(i);
            q.z.abs() < 1e-3 && (q.x - target_x).abs() < 0.01 && q.y.abs() < 0.3
        })
        .collect();
    let mut est = vec![0.0f64; CELL_COUNT];
    let mut refv = vec![0.0f64; CELL_COUNT];
    let mut wsum = vec![0.0f64; CELL_COUNT];
    let mut nb = vec![0usize; CELL_COUNT];
    for &r in &rs {
        let cells =
            filter::cell_estimates(&p.receivers, &samples, &p.level.tracer, &fs, &params, r);
        let frame = Frame::from_normal(p.receivers.normal[r]);
        let geo = p.receivers.geo_normal[r];
        let origin =
            aobake::trace::offset_origin(p.receivers.position[r], geo, p.receivers.footprint[r]);
        for c in 0..CELL_COUNT {
            let (w, o, b) = cells[c];
            if b || w <= 0.0 {
                nb[c] += 1;
                continue;
            }
            est[c] += (o / w) as f64;
            wsum[c] += w as f64;
            let m = 256;
            let mut occ = 0;
            for q in 0..m {
                let d = frame
                    .to_world(cosine_hemisphere(in_cell(c, sobol_2d(q, 99 + c as u64))))
                    .normalize();
                if !p
                    .level
                    .tracer
                    .receiver_visible(origin, geo, d, p.level.max_distance)
                {
                    occ += 1;
                }
            }
            refv[c] += occ as f64 / m as f64;
        }
    }
    let n = rs.len() as f64;
    println!("receivers {}", rs.len());
    let mut tot = 0.0;
    for cy in (0..8).rev() {
        let mut line = String::new();
        for cx in 0..8 {
            let c = cy * 8 + cx;
            let k = n - nb[c] as f64;
            let e = if k > 0.0 {
                (est[c] - refv[c]) / k
            } else {
                f64::NAN
            };
            if k > 0.0 {
                tot += e;
            }
            line += &format!(
                "{:+.3}/{:.2}/{:4.0} ",
                e,
                refv[c] / k.max(1.0),
                wsum[c] / k.max(1.0)
            );
        }
        println!("{line}");
    }
    println!("sum of per-cell bias / 64 = {:+.4}", tot / 64.0);
}
