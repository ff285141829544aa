//! Charts thinner than the bilinear footprint (issue 38, item 2), from the
//! atlas alone, no ray cast: what giving them a minimum width would cost,
//! and which charts hold the engine view's sliver points.
//!
//!     cargo run --release --example thin_charts -- SCENE.glb [RESOLUTION 1024] [MIN_WIDTH 2]
//!         [ATLAS_MIN_WIDTH the CLI's default] [POINTS 400000]
//!
//! A chart is a connected set of triangles sharing atlas vertices. Its mean
//! width in texels is 2 A / P (A its UV area, P its UV perimeter: a strip
//! of width w and length L gives w). A chart narrower than MIN_WIDTH texels
//! would need its width scaled by MIN_WIDTH / w, about A (MIN_WIDTH / w - 1)
//! more texels. Prints the thin charts' count, their share of the world
//! area and of the atlas's chart texels, and the extra texels as a share of
//! the charts' texels (the density the same page would have to give up:
//! 1 / sqrt(1 + share)).
//!
//! Then, on the atlas unwrapped with `--min-chart-width ATLAS_MIN_WIDTH`:
//! POINTS surface points uniform by world area, classified as the engine
//! view does (sliver: no bilinear tap's centre inside a triangle), and the
//! sliver points grouped by the shape of their chart (bounding box in
//! texels, mean width, elongation P^2 / A), with the charts holding most.

use aobake::atlas::AtlasSize;
use aobake::job::{BakeSettings, Level, RunOptions};
use aobake::lightmap::engine_view::{self, TexelClass};
use aobake::stage::StageTimer;
use glam::{Vec2, Vec3};
use std::collections::HashMap;

fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        parent[i as usize] = parent[parent[i as usize] as usize];
        i = parent[i as usize];
    }
    i
}

#[derive(Default, Clone)]
struct Chart {
    tris: u32,
    uv_area: f64,
    perimeter: f64,
    world: f64,
    min: [f32; 2],
    max: [f32; 2],
    points: u32,
    sliver: u32,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let (resolution, min_width) = (arg(2, 1024.0) as u32, arg(3, 2.0));
    let atlas_width = arg(4, BakeSettings::DEFAULT.min_chart_width as f64) as f32;
    let n = arg(5, 4e5);
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(resolution),
        min_chart_width: atlas_width,
        ..BakeSettings::default()
    };
    let level = Level::new(&scene, &s, &RunOptions::QUIET, &mut StageTimer::new()).expect("level");
    let atlas = &level.atlas;
    let (w, h) = (atlas.width as usize, atlas.height as usize);
    let mut charts: Vec<Chart> = Vec::new();
    // (chart, uv corners in texels, world area)
    let mut tris: Vec<(usize, [Vec2; 3], f64)> = Vec::new();
    for (mesh, charted) in level.geometry.receivers.iter().zip(&atlas.meshes) {
        let nv = charted.uv.len() as u32;
        let mut parent: Vec<u32> = (0..nv).collect();
        for t in charted.triangles.chunks_exact(3) {
            let r = root(&mut parent, t[0]);
            for &v in &t[1..] {
                let q = root(&mut parent, v);
                parent[q as usize] = r;
            }
        }
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        let mut of_chart: HashMap<u32, usize> = HashMap::new();
        let uv = |v: u32| {
            let p = charted.uv[v as usize];
            Vec2::new(p[0] * w as f32, p[1] * h as f32)
        };
        for t in charted.triangles.chunks_exact(3) {
            let c = *of_chart.entry(root(&mut parent, t[0])).or_insert_with(|| {
                charts.push(Chart {
                    min: [f32::MAX; 2],
                    max: [f32::MIN; 2],
                    ..Default::default()
                });
                charts.len() - 1
            });
            let pos = |v: u32| Vec3::from(mesh.positions[charted.xref[v as usize] as usize]);
            let corners = [uv(t[0]), uv(t[1]), uv(t[2])];
            let world = 0.5
                * (pos(t[1]) - pos(t[0]))
                    .cross(pos(t[2]) - pos(t[0]))
                    .length() as f64;
            let ch = &mut charts[c];
            ch.tris += 1;
            ch.uv_area += 0.5
                * (corners[1] - corners[0])
                    .perp_dot(corners[2] - corners[0])
                    .abs() as f64;
            ch.world += world;
            for p in corners {
                ch.min = [ch.min[0].min(p.x), ch.min[1].min(p.y)];
                ch.max = [ch.max[0].max(p.x), ch.max[1].max(p.y)];
            }
            tris.push((c, corners, world));
            for k in 0..3 {
                let (x, y) = (t[k], t[(k + 1) % 3]);
                *edges.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
        for ((x, y), count) in edges {
            if count == 1 {
                let c = of_chart[&root(&mut parent, x)];
                charts[c].perimeter += (uv(y) - uv(x)).length() as f64;
            }
        }
    }
    widening_cost(path, resolution, min_width, &charts);
    // Which texel centres lie inside a triangle: the rasterizer's, as the
    // engine view classifies.
    let page = level.page(0, &scene, &mut StageTimer::new()).expect("page");
    let inside = page.receivers.centers_inside();
    let total: f64 = tris.iter().map(|t| t.2).sum();
    let mut rng = 0x9e3779b97f4a7c15u64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut all, mut sliver) = (0u64, 0u64);
    for (c, t, a) in &tris {
        let expect = a / total * n;
        let mut k = expect.floor() as u32;
        if next() < expect.fract() {
            k += 1;
        }
        for _ in 0..k {
            let (mut r1, mut r2) = (next() as f32, next() as f32);
            if r1 + r2 > 1.0 {
                (r1, r2) = (1.0 - r1, 1.0 - r2);
            }
            let p = t[0] + (t[1] - t[0]) * r1 + (t[2] - t[0]) * r2;
            let uv = [p.x / w as f32, p.y / h as f32];
            all += 1;
            charts[*c].points += 1;
            if engine_view::class_of(uv, w as u32, h as u32, &inside) == TexelClass::Sliver {
                sliver += 1;
                charts[*c].sliver += 1;
            }
        }
    }
    println!(
        "points {all}, sliver {sliver} ({:.3}%), charts {}, density {:.4}, utilization {:.3}",
        100.0 * sliver as f64 / all as f64,
        charts.len(),
        atlas.texels_per_unit,
        atlas.utilization
    );
    // By category.
    let mut cat: HashMap<&str, (u32, u64)> = HashMap::new();
    for c in &charts {
        let (bw, bh) = (c.max[0] - c.min[0], c.max[1] - c.min[1]);
        let mean = 2.0 * c.uv_area / c.perimeter.max(1e-9);
        let elong = c.perimeter * c.perimeter / c.uv_area.max(1e-12);
        let key = if bw.min(bh) < 1.5 {
            "bbox min side < 1.5"
        } else if mean < 1.0 && elong > 50.0 {
            "mean width < 1, P2/A > 50 (strip)"
        } else if mean < 1.0 {
            "mean width < 1, compact"
        } else if mean < 2.0 && elong > 50.0 {
            "mean width 1-2, P2/A > 50 (strip)"
        } else if mean < 2.0 {
            "mean width 1-2, compact"
        } else {
            "mean width >= 2"
        };
        let e = cat.entry(key).or_default();
        e.0 += 1;
        e.1 += c.sliver as u64;
    }
    let mut cats: Vec<_> = cat.into_iter().collect();
    cats.sort_by_key(|c| std::cmp::Reverse(c.1.1));
    for (k, (count, s)) in cats {
        println!(
            "{k}: {count} charts, {s} sliver points ({:.1}%)",
            100.0 * s as f64 / sliver.max(1) as f64
        );
    }
    let mut order: Vec<usize> = (0..charts.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(charts[i].sliver));
    println!("| chart | tris | bbox texels | uv area | mean width | P2/A | points | sliver |");
    for &i in order.iter().take(25) {
        let c = &charts[i];
        println!(
            "| {i} | {} | {:.1} x {:.1} | {:.1} | {:.2} | {:.0} | {} | {} |",
            c.tris,
            c.max[0] - c.min[0],
            c.max[1] - c.min[1],
            c.uv_area,
            2.0 * c.uv_area / c.perimeter.max(1e-9),
            c.perimeter * c.perimeter / c.uv_area.max(1e-12),
            c.points,
            c.sliver
        );
    }
}

/// The table of what widening the charts narrower than `min_width` (mean
/// width) to it would cost.
fn widening_cost(path: &str, resolution: u32, min_width: f64, charts: &[Chart]) {
    let world: f64 = charts.iter().map(|c| c.world).sum();
    let texels: f64 = charts.iter().map(|c| c.uv_area).sum();
    let thin: Vec<&Chart> = charts
        .iter()
        .filter(|c| c.perimeter > 0.0 && 2.0 * c.uv_area / c.perimeter < min_width)
        .collect();
    let extra: f64 = thin
        .iter()
        .map(|c| c.uv_area * (min_width / (2.0 * c.uv_area / c.perimeter).max(1e-3) - 1.0))
        .sum();
    let share = extra / texels.max(1e-9);
    println!(
        "| scene | resolution | charts | thinner than {min_width} texels | their world area | their texels | extra texels to widen them | density to give up |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    println!(
        "| {} | {resolution} | {} | {} | {:.2}% | {:.2}% | {:.1}% of the charts' texels | {:.3}x |",
        std::path::Path::new(path)
            .file_name()
            .unwrap()
            .to_string_lossy(),
        charts.len(),
        thin.len(),
        (100.0 * thin.iter().map(|c| c.world).sum::<f64>() / world.max(1e-12)).abs(),
        (100.0 * thin.iter().map(|c| c.uv_area).sum::<f64>() / texels.max(1e-9)).abs(),
        (100.0 * share).abs(),
        1.0 / (1.0 + share).sqrt()
    );
}
