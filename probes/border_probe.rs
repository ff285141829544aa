//! Where the border band's engine-view error comes from: the bake at the
//! border receivers against a reference at the same points, and the
//! engine-view error of border-class points split by what their four
//! bilinear taps hold (a receiver whose centre is inside a triangle, a
//! conservative receiver on the chart's edge, or a dilated gutter copy).
//!
//!     cargo run --release --example border_probe -- SCENE.glb [RES 1024]
//!         [MIN_CHART_WIDTH 2] [SEAMS off|stitch] [POINTS 20000]

use aobake::atlas::AtlasSize;
use aobake::bake::{BakeParams, mc};
use aobake::job::settings::BakeSettings;
use aobake::job::{Job, RunOptions};
use aobake::lightmap::bilinear_taps as taps;
use aobake::lightmap::engine_view::{TexelClass, class_of, lookup};
use aobake::lightmap::seams::SeamMode;
use aobake::stage::StageTimer;

fn rmse(v: &[f64]) -> f64 {
    (v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let res = arg(2, 1024.0) as u32;
    let width = arg(3, 2.0) as f32;
    let seams = match args.get(4).map(String::as_str) {
        Some("stitch") => SeamMode::Stitch,
        _ => SeamMode::Off,
    };
    let count = arg(5, 20000.0) as usize;
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(res),
        min_chart_width: width,
        seams,
        ..BakeSettings::default()
    };
    let run = RunOptions::QUIET;
    let mut job = Job::new(&scene, &s, &run, StageTimer::new());
    let level = job.level().expect("prepare");
    job.pages(&level, &[0], &mut |p, passes, out| {
        let r = &p.receivers;
        let inside = passes.inside(&p).to_vec();
        // 1. The bake at its own receivers: centre-inside vs edge receivers.
        for (name, want) in [("centre inside", true), ("on the chart's edge", false)] {
            let pick: Vec<u32> = (0..r.len() as u32)
                .filter(|&i| r.center_inside[i as usize] == want && !inside[i as usize])
                .step_by(37)
                .take(4000)
                .collect();
            let sub = r.permuted(&pick);
            let params = BakeParams {
                max_distance: p.level.max_distance,
                seed: 0x5eed,
            };
            let reference = mc::bake(&sub, &p.level.tracer, 512, &params, &|_| {});
            let raw: Vec<f64> = pick
                .iter()
                .enumerate()
                .map(|(k, &i)| (passes.bake.ao[i as usize] - reference.ao[k]) as f64)
                .collect();
            let bias = raw.iter().sum::<f64>() / raw.len().max(1) as f64;
            println!(
                "receivers {name}: {} compared, bake - reference AO RMSE {:.4}, mean {:+.4}",
                pick.len(),
                rmse(&raw),
                bias
            );
        }
        // 2. Border-class points by what their taps hold.
        let (w, h) = (out.lightmap.width, out.lightmap.height);
        let mut kind = vec![0u8; (w * h) as usize]; // 0 gutter, 1 edge receiver, 2 centre inside
        for (i, &t) in r.texel.iter().enumerate() {
            kind[t as usize] = if r.center_inside[i] { 2 } else { 1 };
        }
        let probe = p.engine_probe(count, 512, 0xabc, false);
        let decoded = aobake::encode::decode(&out.encoded).expect("decode");
        let centers = &probe.centers;
        // Key: (taps inside, edge taps, gutter taps) weighted by weight.
        let mut groups: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
        let mut weight_groups: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
        for k in 0..probe.points.uv.len() {
            if probe.reference.inside[k] {
                continue;
            }
            let uv = probe.points.uv[k];
            let class = class_of(uv, w, h, centers);
            if class == TexelClass::Interior {
                continue;
            }
            let err = (lookup(&decoded, uv, aobake::lightmap::Filter::Bilinear).0
                - probe.reference.ao[k]) as f64;
            let tp = taps(uv, w, h);
            let mut wk = [0.0f32; 3];
            for &(t, wt) in &tp {
                wk[kind[t as usize] as usize] += wt;
            }
            let n = |c: u8| tp.iter().filter(|&&(t, _)| kind[t as usize] == c).count();
            let key = format!("{} inside, {} edge, {} gutter", n(2), n(1), n(0));
            groups.entry(key).or_default().push(err);
            let bucket = if wk[0] > 0.25 {
                "gutter weight > 0.25"
            } else if wk[1] > 0.5 {
                "edge-receiver weight > 0.5"
            } else {
                "inside weight >= 0.5 or mixed"
            };
            weight_groups.entry(bucket.into()).or_default().push(err);
        }
        println!("\n| border-class taps | points | AO RMSE | mean error |");
        println!("|---|---|---|---|");
        for (g, e) in groups.iter().chain(weight_groups.iter()) {
            println!(
                "| {g} | {} | {:.4} | {:+.4} |",
                e.len(),
                rmse(e),
                e.iter().sum::<f64>() / e.len() as f64
            );
        }
    })
    .expect("bake");
}
