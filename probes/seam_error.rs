//! What stitching costs in accuracy: the written lightmap's texels (after
//! dilation, with and without stitching) against a Monte Carlo reference
//! at each covered texel's receiver, and the seam figures of both.
//!
//!     cargo run --release --example seam_error -- SCENE.glb [RES] [REF_RAYS]
//!
//! Prints AO RMSE and SH RMSE over covered texels not inside geometry: the
//! interior ones (their four neighbours covered, `seams::interior`), all of
//! them, and those the stitch moved, for `--seams off` and `stitch`.

#![allow(clippy::needless_range_loop)]

use aobake::lightmap::seams::SeamMode;
use aobake::stage::StageTimer;
use aobake::{BakeSettings, Method};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = std::path::PathBuf::from(&args[0]);
    let res: u32 = args.get(1).map_or(1024, |v| v.parse().unwrap());
    let refs: u32 = args.get(2).map_or(512, |v| v.parse().unwrap());
    let scene = aobake::gltf::load(&path).expect("load");
    let base = BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(res),
        ..BakeSettings::default()
    };
    let level = aobake::job::Level::new(
        &scene,
        &base,
        &aobake::RunOptions::QUIET,
        &mut StageTimer::new(),
    )
    .expect("prepare");
    let p = level
        .page(0, &scene, &mut StageTimer::new())
        .expect("prepare");
    let passes = p
        .bake(&base, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .expect("bake");
    let reference = {
        let s = BakeSettings {
            method: Method::Mc,
            rays: refs,
            ..base.clone()
        };
        p.bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .expect("reference")
            .bake
    };
    let inside = passes.inside(&p).to_vec();
    let mut outs = Vec::new();
    for seams in [SeamMode::Off, SeamMode::Stitch] {
        let s = BakeSettings {
            seams,
            ..base.clone()
        };
        let mut timer = StageTimer::new();
        let out = p
            .finish(&passes, &s, &aobake::RunOptions::QUIET, &mut timer)
            .expect("output");
        outs.push(out);
    }
    let rc = &p.receivers;
    let moved: Vec<bool> = (0..rc.len())
        .map(|r| {
            let t = rc.texel[r] as usize;
            outs[0].lightmap.ao[t] != outs[1].lightmap.ao[t]
                || outs[0].lightmap.sh[t] != outs[1].lightmap.sh[t]
        })
        .collect();
    println!(
        "{} at {res}, {refs}-ray reference; {} of {} covered texels moved by the stitch",
        path.display(),
        moved.iter().filter(|&&m| m).count(),
        rc.len()
    );
    for (name, out) in ["off", "stitch"].iter().zip(&outs) {
        let lm = &out.lightmap;
        let rmse = |pick: &dyn Fn(usize) -> bool| {
            let (mut ao, mut sh, mut n) = (0.0f64, 0.0f64, 0usize);
            for r in 0..rc.len() {
                if inside.get(r).copied().unwrap_or(false) || !pick(r) {
                    continue;
                }
                let t = rc.texel[r] as usize;
                ao += (lm.ao[t] - reference.ao[r]).powi(2) as f64;
                sh += (0..9)
                    .map(|i| (lm.sh[t][i] - reference.sh[r][i]).powi(2) as f64)
                    .sum::<f64>()
                    / 9.0;
                n += 1;
            }
            ((ao / n.max(1) as f64).sqrt(), (sh / n.max(1) as f64).sqrt())
        };
        let interior = |r: usize| {
            aobake::lightmap::seams::interior(&lm.covered, lm.width, lm.height, rc.texel[r])
        };
        let (i_ao, i_sh) = rmse(&interior);
        let (all_ao, all_sh) = rmse(&|_| true);
        let (m_ao, m_sh) = rmse(&|r| moved[r]);
        println!(
            "{name}: interior texels AO RMSE {i_ao:.5}, SH {i_sh:.5}; all covered AO {all_ao:.5}, SH {all_sh:.5}; texels the stitch moves: AO {m_ao:.5}, SH {m_sh:.5}"
        );
        if let Some(f) = &out.seams {
            println!(
                "  seams {} ({:.1} world units): {:?} -> {:?}",
                f.seams, f.length, f.before, f.after
            );
        }
    }
}
