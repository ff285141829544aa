//! Charts thinner than the bilinear footprint, and what giving them two
//! texels across would cost (issue 38, item 2): from the atlas alone, no
//! ray cast.
//!
//!     cargo run --release --example thin_charts -- SCENE.glb [RESOLUTION 1024] [MIN_WIDTH 2]
//!
//! A chart is a connected set of triangles sharing atlas vertices. Its mean
//! width in texels is 2 A / P (A its UV area, P its UV perimeter: a strip
//! of width w and length L gives w). A chart narrower than MIN_WIDTH texels
//! would need its width scaled by MIN_WIDTH / w, about A (MIN_WIDTH / w - 1)
//! more texels. Prints the thin charts' count, their share of the world
//! area and of the atlas's chart texels, and the extra texels as a share of
//! the charts' texels (the density the same page would have to give up:
//! 1 / sqrt(1 + share)).

use aobake::atlas::AtlasSize;
use aobake::job::{BakeSettings, Level, RunOptions};
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

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let (resolution, min_width) = (arg(2, 1024.0) as u32, arg(3, 2.0));
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(resolution),
        ..BakeSettings::default()
    };
    let level = Level::new(&scene, &s, &RunOptions::QUIET, &mut StageTimer::new()).expect("level");
    let atlas = &level.atlas;
    let (w, h) = (atlas.width as f32, atlas.height as f32);
    // Per chart: UV area (texels^2), UV perimeter (texels), world area.
    let mut charts: Vec<(f64, f64, f64)> = Vec::new();
    for (mesh, charted) in level.geometry.receivers.iter().zip(&atlas.meshes) {
        let n = charted.uv.len() as u32;
        let mut parent: Vec<u32> = (0..n).collect();
        for t in charted.triangles.chunks_exact(3) {
            let r = root(&mut parent, t[0]);
            for &v in &t[1..] {
                let q = root(&mut parent, v);
                parent[q as usize] = r;
            }
        }
        // Boundary edges: UV edges used by one triangle of the chart.
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        let mut of_chart: HashMap<u32, usize> = HashMap::new();
        for t in charted.triangles.chunks_exact(3) {
            let c = *of_chart.entry(root(&mut parent, t[0])).or_insert_with(|| {
                charts.push((0.0, 0.0, 0.0));
                charts.len() - 1
            });
            let uv = |v: u32| {
                let p = charted.uv[v as usize];
                Vec2::new(p[0] * w, p[1] * h)
            };
            let pos = |v: u32| Vec3::from(mesh.positions[charted.xref[v as usize] as usize]);
            let (a, b, d) = (uv(t[0]), uv(t[1]), uv(t[2]));
            charts[c].0 += 0.5 * ((b - a).perp_dot(d - a)).abs() as f64;
            charts[c].2 += 0.5
                * (pos(t[1]) - pos(t[0]))
                    .cross(pos(t[2]) - pos(t[0]))
                    .length() as f64;
            for k in 0..3 {
                let (x, y) = (t[k], t[(k + 1) % 3]);
                *edges.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
        for ((x, y), count) in edges {
            if count == 1 {
                let c = of_chart[&root(&mut parent, x)];
                let (p, q) = (charted.uv[x as usize], charted.uv[y as usize]);
                let len = Vec2::new((q[0] - p[0]) * w, (q[1] - p[1]) * h).length();
                charts[c].1 += len as f64;
            }
        }
    }
    let world: f64 = charts.iter().map(|c| c.2).sum();
    let texels: f64 = charts.iter().map(|c| c.0).sum();
    let thin: Vec<&(f64, f64, f64)> = charts
        .iter()
        .filter(|c| c.1 > 0.0 && 2.0 * c.0 / c.1 < min_width)
        .collect();
    let extra: f64 = thin
        .iter()
        .map(|c| c.0 * (min_width / (2.0 * c.0 / c.1).max(1e-3) - 1.0))
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
        (100.0 * thin.iter().map(|c| c.2).sum::<f64>() / world.max(1e-12)).abs(),
        (100.0 * thin.iter().map(|c| c.0).sum::<f64>() / texels.max(1e-9)).abs(),
        (100.0 * share).abs(),
        1.0 / (1.0 + share).sqrt()
    );
}
