//! One page against several: the same scene at the same texel density baked
//! on one page and on pages of at most E texels, each page's output (the
//! float lightmap after dilation and seam stitching, as encoded) compared
//! with a Monte Carlo reference of its own receivers (another seed) at
//! every k-th texel that is not inside geometry.
//!
//!     cargo run --release --example page_error -- SCENE.glb [DENSITY 28] [PAGE 1024]
//!         [STRIDE 64] [REFERENCE_RAYS 2048]
//!
//! Prints, per layout, the pages, the texels compared and the AO and SH
//! RMSE over all of them and over interior texels (3x3 neighbourhood
//! covered: never moved by stitching).

use aobake::atlas::AtlasSize;
use aobake::bake::{BakeParams, mc};
use aobake::job::settings::BakeSettings;
use aobake::job::{Job, RunOptions};
use aobake::lightmap::seams::interior;
use aobake::stage::StageTimer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let (density, page) = (arg(2, 28.0), arg(3, 1024.0) as u32);
    let (stride, ref_rays) = (arg(4, 64.0) as usize, arg(5, 2048.0) as u32);
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    println!(
        "| layout | pages | texels compared | AO RMSE | SH RMSE | interior AO | interior SH |"
    );
    println!("|---|---|---|---|---|---|---|");
    for page_size in [4096, page] {
        let s = BakeSettings {
            size: AtlasSize::TexelDensity { density, page_size },
            ..BakeSettings::default()
        };
        let run = RunOptions::QUIET;
        let mut job = Job::new(&scene, &s, &run, StageTimer::new());
        let level = job.level().expect("prepare");
        let pages: Vec<u32> = (0..level.page_count()).collect();
        // (sum AO^2, sum SH^2 / 9, n) over all compared texels, then interior.
        let mut sums = [[0.0f64; 3]; 2];
        job.pages(&level, &pages, &mut |p, passes, out| {
            let inside = passes.inside(&p).to_vec();
            let pick: Vec<u32> = (0..p.receivers.len() as u32)
                .step_by(stride)
                .filter(|&r| !inside.get(r as usize).copied().unwrap_or(false))
                .collect();
            let sub = p.receivers.permuted(&pick);
            let params = BakeParams {
                max_distance: p.level.max_distance,
                seed: 0x5eed_0000 + p.page as u64,
            };
            let reference = mc::bake(&sub, &p.level.tracer, ref_rays, &params, &|_| {});
            let lm = &out.lightmap;
            for (k, &t) in sub.texel.iter().enumerate() {
                let t = t as usize;
                let ao = (lm.ao[t] - reference.ao[k]) as f64;
                let sh: f64 = (0..9)
                    .map(|i| ((lm.sh[t][i] - reference.sh[k][i]) as f64).powi(2))
                    .sum::<f64>()
                    / 9.0;
                let classes = [true, interior(&lm.covered, lm.width, lm.height, t as u32)];
                for (c, &inn) in classes.iter().enumerate() {
                    if inn {
                        sums[c][0] += ao * ao;
                        sums[c][1] += sh;
                        sums[c][2] += 1.0;
                    }
                }
            }
        })
        .expect("bake");
        let rmse = |c: usize, i: usize| (sums[c][i] / sums[c][2].max(1.0)).sqrt();
        println!(
            "| page {page_size} | {} | {} | {:.5} | {:.5} | {:.5} | {:.5} |",
            level.page_count(),
            sums[0][2],
            rmse(0, 0),
            rmse(0, 1),
            rmse(1, 0),
            rmse(1, 1)
        );
    }
}
