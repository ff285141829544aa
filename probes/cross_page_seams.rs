//! The jump at seams whose two sides lie on different atlas pages, as a
//! viewer sees it: each side's bilinear AO lookup on its own page's float
//! lightmap (before encoding), at 3 points per texel, with `--seams off`
//! and with stitching (both sides pulled to the shared target); then, for
//! the stitched bake, the 8-bit images before and after the pass that
//! solves both sides together (`job::across`, run by the write).
//!
//!     cargo run --release --example cross_page_seams -- SCENE.glb [DENSITY 28] [PAGE 1024]

use aobake::atlas::AtlasSize;
use aobake::job::BakeSettings;
use aobake::job::{Job, RunOptions};
use aobake::lightmap::seams::SeamMode;
use aobake::lightmap::seams::anchor::cross_page_jumps;
use aobake::lightmap::seams::find::cross_page_seams;
use aobake::lightmap::seams::{FLAT_DEGREES, SMOOTH_DEGREES};
use aobake::stage::StageTimer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("SCENE.glb");
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let (density, page) = (arg(2, 28.0), arg(3, 1024.0) as u32);
    let scene = aobake::gltf::load(std::path::Path::new(path)).expect("load");
    println!("| seams | cross-page seams | points | AO jump mean | p95 | over 8/255 | seconds |");
    println!("|---|---|---|---|---|---|---|");
    for mode in [SeamMode::Off, SeamMode::Stitch] {
        let s = BakeSettings {
            size: AtlasSize::TexelDensity {
                density,
                page_size: page,
            },
            seams: mode,
            ..BakeSettings::default()
        };
        let run = RunOptions::QUIET;
        let mut job = Job::new(&scene, &s, &run, StageTimer::new());
        let level = job.level().expect("prepare");
        let pages: Vec<u32> = (0..level.page_count()).collect();
        let mut ao: Vec<(u32, u32, Vec<f32>)> = vec![(0, 0, Vec::new()); pages.len()];
        let done = job
            .pages(&level, &pages, &mut |p, _, out| {
                let lm = out.lightmap;
                ao[p.page as usize] = (lm.width, lm.height, lm.ao);
            })
            .expect("bake");
        let encoded: Vec<_> = done.iter().map(|d| &d.encoded).collect();
        job.write(&level, &encoded, None).expect("write");
        let across = job.across;
        let seams = cross_page_seams(
            &level.geometry.receivers,
            &level.atlas,
            SMOOTH_DEGREES,
            FLAT_DEGREES,
        );
        let mut jumps = cross_page_jumps(&seams, &level.atlas.pages, |p| {
            let (w, h, img) = &ao[p as usize];
            (*w, *h, img.as_slice())
        });
        jumps.sort_by(f64::total_cmp);
        let n = jumps.len().max(1) as f64;
        let mean = jumps.iter().sum::<f64>() / n;
        let p95 = jumps.get((0.95 * n) as usize).copied().unwrap_or(0.0);
        let over = jumps.iter().filter(|&&j| j > 8.0 / 255.0).count() as f64 / n;
        let stages = job.timer.into_merged_stages();
        let seconds_of = |stage: &str| -> f64 {
            (stages.iter())
                .filter(|st| st.stage == stage)
                .map(|st| st.seconds)
                .sum()
        };
        let seconds = seconds_of("seams");
        println!(
            "| {mode:?} | {} | {} | {mean:.4} | {p95:.4} | {:.1}% | {seconds:.2} |",
            seams.len(),
            jumps.len(),
            100.0 * over
        );
        if let Some(a) = across {
            let pass = seconds_of("cross-page seams");
            println!(
                "| {mode:?}, 8-bit, before the pass across pages | {} | {} | {:.4} | {:.4} | | |",
                a.seams, a.points, a.ao_before, a.p95_before
            );
            println!(
                "| {mode:?}, 8-bit, after it | {} | {} | {:.4} | {:.4} | | {pass:.2} ({} pages re-encoded, {} unknowns) |",
                a.seams, a.points, a.ao_after, a.p95_after, a.pages_changed, a.solve.unknowns
            );
        }
    }
}
