//! Do the two sides of a smooth seam agree at the seam itself? For points
//! along every in-page smooth seam, each side's texel that is covered only
//! conservatively (its receiver on the chart's edge) nearest the point:
//! the world distance between the two sides' receivers (in texel
//! footprints), the angle between their geometric normals, and the
//! difference of their baked AO, binned.
//!
//!     cargo run --release --example seam_sides -- SCENE.glb [RES 1024]

use aobake::atlas::AtlasSize;
use aobake::job::settings::BakeSettings;
use aobake::job::{Job, RunOptions};
use aobake::lightmap::seams::SeamMode;
use aobake::lightmap::seams::find::smooth_seams;
use aobake::lightmap::seams::metric::samples;
use aobake::stage::StageTimer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let res = args.get(2).map_or(1024, |a| a.parse().unwrap());
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(res),
        seams: SeamMode::Off,
        ..BakeSettings::default()
    };
    let run = RunOptions::QUIET;
    let mut job = Job::new(&scene, &s, &run, StageTimer::new());
    let level = job.level().expect("prepare");
    job.pages(&level, &[0], &mut |p, passes, _out| {
        let r = &p.receivers;
        let (w, h) = (r.width, r.height);
        let mut edge_of = vec![u32::MAX; (w * h) as usize];
        for (i, &t) in r.texel.iter().enumerate() {
            if !r.center_inside[i] {
                edge_of[t as usize] = i as u32;
            }
        }
        let seams = smooth_seams(&level.geometry.receivers, &p.atlas, 10.0, 180.0);
        // Nearest edge receiver to a UV on one side: (receiver, texel distance).
        let nearest = |uv: [f32; 2]| -> Option<(usize, f32)> {
            let (x, y) = (uv[0] * w as f32, uv[1] * h as f32);
            let mut best = None;
            for ty in (y as i64 - 2)..=(y as i64 + 2) {
                for tx in (x as i64 - 2)..=(x as i64 + 2) {
                    if tx < 0 || ty < 0 || tx >= w as i64 || ty >= h as i64 {
                        continue;
                    }
                    let i = edge_of[(ty * w as i64 + tx) as usize];
                    if i == u32::MAX {
                        continue;
                    }
                    let d = ((tx as f32 + 0.5 - x).powi(2) + (ty as f32 + 0.5 - y).powi(2)).sqrt();
                    if best.is_none_or(|(_, b)| d < b) {
                        best = Some((i as usize, d));
                    }
                }
            }
            best
        };
        // Bins by distance between the two receivers (footprints) and by
        // the geometric normals' angle: (count, sum |dAO|).
        let mut bins: std::collections::BTreeMap<(u32, u32), (usize, f64)> = Default::default();
        // Pairs on the same point (< 0.25 footprints apart), for the reference.
        let mut pairs: Vec<(u32, u32, u32)> = Vec::new();
        for seam in &seams {
            for t in samples(seam, w, h, 1.0) {
                let (ua, ub) = seam.at(t);
                let (Some((a, _)), Some((b, _))) = (nearest(ua), nearest(ub)) else {
                    continue;
                };
                let dist = (r.position[a] - r.position[b]).length() / r.footprint[a];
                let angle = r.geo_normal[a].dot(r.geo_normal[b]).clamp(-1.0, 1.0).acos().to_degrees();
                let dao = (passes.bake.ao[a] - passes.bake.ao[b]).abs() as f64;
                let db = if dist < 0.25 { 0 } else if dist < 1.0 { 1 } else { 2 };
                let ab = if angle < 1.0 { 0 } else if angle < 10.0 { 1 } else if angle < 45.0 { 2 } else { 3 };
                if db == 0 && pairs.len() < 200_000 {
                    pairs.push((a as u32, b as u32, ab));
                }
                let e = bins.entry((db, ab)).or_default();
                e.0 += 1;
                e.1 += dao;
            }
        }
        println!("| receivers apart (footprints) | geometric normals | points | mean |AO A - AO B| |");
        println!("|---|---|---|---|");
        for ((db, ab), (n, sum)) in bins {
            let d = ["< 0.25", "0.25-1", ">= 1"][db as usize];
            let a = ["< 1 deg", "1-10 deg", "10-45 deg", ">= 45 deg"][ab as usize];
            println!("| {d} | {a} | {n} | {:.4} |", sum / n as f64);
        }
        // The contract's AO at both receivers of a pair (512 rays each,
        // on streams of their own): does the reference itself jump?
        let pick: Vec<(u32, u32, u32)> = pairs.iter().copied().step_by(8).collect();
        let ids: Vec<u32> = pick.iter().flat_map(|&(a, b, _)| [a, b]).collect();
        let sub = r.permuted(&ids);
        let params = aobake::bake::BakeParams {
            max_distance: p.level.max_distance,
            seed: 0x5eed_5eed,
        };
        let reference = aobake::bake::mc::bake(&sub, &p.level.tracer, 512, &params, &|_| {});
        let mut ref_bins = [(0usize, 0.0f64); 4];
        for (k, &(_, _, ab)) in pick.iter().enumerate() {
            let e = &mut ref_bins[ab as usize];
            e.0 += 1;
            e.1 += (reference.ao[2 * k] - reference.ao[2 * k + 1]).abs() as f64;
        }
        println!("\n| geometric normals | pairs on one point | reference's mean |AO A - AO B| (512 rays) |");
        println!("|---|---|---|");
        for (ab, (n, sum)) in ref_bins.iter().enumerate() {
            let a = ["< 1 deg", "1-10 deg", "10-45 deg", ">= 45 deg"][ab];
            println!("| {a} | {n} | {:.4} |", sum / (*n).max(1) as f64);
        }
    })
    .expect("bake");
}
