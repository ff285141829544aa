//! Where the adaptive method's error goes, per texel class, beside Monte
//! Carlo on the same atlas. Classes come from the adaptive run's own
//! bounds: nothing hit (z_min infinite), contact (not filtered, sigma <
//! half a texel), filtered narrow (sigma < 2 texels) and filtered wide. Each
//! row gives the class's share of texels, RMSE, mean bias, share of the
//! total squared error and mean rays.
//!
//!     cargo run --release --example adaptive_classes -- SCENE.glb [RES] [REF_RAYS] [RUNS]
//!
//! RUNS: comma-separated `aobake report` budgets (default
//! `mc:64,mc:256,adaptive:64`); the first adaptive run gives the classes.
//! Every run also prints, per ray count, its share of texels, RMSE and
//! how many texels lie above the first Monte Carlo run's AO p99, and each
//! class's share of those (where the tail goes).
//! The reference is cached under the system temp directory.
#[path = "../tests/common/mod.rs"]
mod common;

use aobake::stage::StageTimer;
use std::time::Instant;

fn cached_reference(
    path: &std::path::Path,
    res: u32,
    refs: u32,
) -> (common::OnePage, Vec<f32>, Vec<[f32; 9]>) {
    let one = common::prepare_for_reference(path, res, refs);
    let (s, p) = (&one.s, one.page());
    let name = path.file_stem().unwrap().to_string_lossy();
    let cache = std::env::temp_dir().join(format!(
        "aobake-ref-{name}-{res}-{refs}-{:016x}.bin",
        common::order_key(&p.receivers)
    ));
    let n = p.receivers.len();
    if let Ok(b) = std::fs::read(&cache)
        && b.len() == n * 40
    {
        let f: Vec<f32> = b
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        let ao = (0..n).map(|i| f[i * 10]).collect();
        let sh = (0..n)
            .map(|i| std::array::from_fn(|k| f[i * 10 + 1 + k]))
            .collect();
        drop(p);
        return (one, ao, sh);
    }
    let r = p
        .bake(s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .expect("reference")
        .bake;
    let mut b = Vec::with_capacity(n * 40);
    for i in 0..n {
        b.extend_from_slice(&r.ao[i].to_le_bytes());
        for v in r.sh[i] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&cache, b).ok();
    drop(p);
    (one, r.ao, r.sh)
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(&a[1]);
    let res: u32 = a.get(2).and_then(|v| v.parse().ok()).unwrap_or(1024);
    let refs: u32 = a.get(3).and_then(|v| v.parse().ok()).unwrap_or(2048);
    let runs = a
        .get(4)
        .cloned()
        .unwrap_or("mc:64,mc:256,adaptive:64".into());
    let (one, ref_ao, ref_sh) = cached_reference(path, res, refs);
    let p = one.page();
    let base = aobake::BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(res),
        fill_inside: false,
        ..Default::default()
    };
    let n = p.receivers.len();
    let inside: &[bool] = p.inside.as_deref().unwrap_or_default();
    let mut class: Option<Vec<usize>> = None;
    // The first run's AO p99: later runs count their texels above it per
    // ray count (where the tail goes).
    let mut tail: Option<f64> = None;
    const NAMES: [&str; 4] = ["nothing hit", "contact", "narrow (<2 texels)", "wide"];
    let mut outs = Vec::new();
    for budget in aobake::report::parse_budgets(&runs).expect("RUNS") {
        let mut s = budget.settings(&base, 0);
        if let Ok(v) = std::env::var("AOBAKE_MU") {
            s.adaptive.mu = v.parse().unwrap();
        }
        if let Ok(v) = std::env::var("AOBAKE_REACH") {
            s.adaptive.max_reach = v.parse().unwrap();
        }
        if let Ok(v) = std::env::var("AOBAKE_PRE") {
            s.adaptive.pre_rays = v.parse().unwrap();
        }
        let t = Instant::now();
        let out = p
            .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
        let secs = t.elapsed().as_secs_f64();
        let rays: Vec<f64> = match &out.adaptive_stats {
            Some(st) => st.rays.iter().map(|&r| r as f64).collect(),
            None => vec![s.rays as f64; n],
        };
        if class.is_none()
            && let Some(st) = &out.adaptive_stats
        {
            class = Some(
                (0..n)
                    .map(|i| {
                        if st.z_min[i].is_infinite() {
                            0
                        } else if st.sigma_texels[i] <= 0.0 {
                            1
                        } else if st.sigma_texels[i] < 2.0 {
                            2
                        } else {
                            3
                        }
                    })
                    .collect(),
            );
        }
        // The tail threshold: the first Monte Carlo run's AO p99.
        if tail.is_none() && out.adaptive_stats.is_none() {
            let mut e: Vec<f64> = (0..n)
                .filter(|&i| !inside[i])
                .map(|i| (out.bake.ao[i] - ref_ao[i]).abs() as f64)
                .collect();
            e.sort_by(|a, b| a.partial_cmp(b).unwrap());
            tail = Some(e[(e.len() as f64 * 0.99) as usize]);
        }
        outs.push((budget, out, secs, rays));
    }
    for (budget, out, secs, rays) in outs {
        let cls = class.clone().unwrap_or(vec![1; n]);
        let mut acc = [[0.0f64; 6]; 4]; // count, sum e, sum e2, rays, sh l2 e2, above the tail
        let mut total = 0.0;
        let mut errs = Vec::new();
        // The texels compared: SH of the run and of the reference.
        let (mut run_sh, mut kept_ref_sh) = (Vec::new(), Vec::new());
        for i in 0..n {
            if inside[i] {
                continue;
            }
            let e = (out.bake.ao[i] - ref_ao[i]) as f64;
            let c = &mut acc[cls[i]];
            c[0] += 1.0;
            c[1] += e;
            c[2] += e * e;
            c[3] += rays[i];
            for (a, b) in out.bake.sh[i][4..].iter().zip(&ref_sh[i][4..]) {
                c[4] += ((a - b) as f64).powi(2) / 5.0;
            }
            c[5] += (e.abs() > tail.unwrap_or(0.05)) as u8 as f64;
            run_sh.push(out.bake.sh[i]);
            kept_ref_sh.push(ref_sh[i]);
            total += e * e;
            errs.push(e.abs());
        }
        // AOBAKE_WORST=N: the N texels with the largest AO error.
        if let Some(k) = std::env::var("AOBAKE_WORST")
            .ok()
            .and_then(|v| v.parse().ok())
        {
            let mut order: Vec<usize> = (0..n).filter(|&i| !inside[i]).collect();
            let err = |i: usize| (out.bake.ao[i] - ref_ao[i]).abs();
            order.sort_by(|&a, &b| err(b).total_cmp(&err(a)));
            let rc = &p.receivers;
            for &i in order.iter().take(k) {
                let t = rc.texel[i];
                let (z, sg) = out
                    .adaptive_stats
                    .as_ref()
                    .map_or((0.0, 0.0), |st| (st.z_min[i], st.sigma_texels[i]));
                println!(
                    "  texel ({},{}) ao {:.3} ref {:.3} rays {} z_min {:.4} sigma {:.2} fp {:.4} p {:.3} n {:.2}",
                    t % rc.width,
                    t / rc.width,
                    out.bake.ao[i],
                    ref_ao[i],
                    rays[i],
                    z,
                    sg,
                    rc.footprint[i],
                    rc.position[i],
                    rc.normal[i]
                );
            }
        }
        if let Some(t) = tail {
            // Per ray count: texels, RMSE, and how many lie above the first
            // run's p99 (1% of texels there).
            let mut by: std::collections::BTreeMap<u64, [f64; 3]> = Default::default();
            for i in (0..n).filter(|&i| !inside[i]) {
                let e = (out.bake.ao[i] - ref_ao[i]) as f64;
                let c = by.entry(rays[i] as u64).or_default();
                c[0] += 1.0;
                c[1] += e * e;
                c[2] += (e.abs() > t) as u8 as f64;
            }
            let m = errs.len() as f64;
            for (k, c) in by {
                println!(
                    "  rays {k:5}  {:5.1}% of texels  rmse {:.4}  above MC's p99: {:.2}% of all texels ({:.2}% of these)",
                    100.0 * c[0] / m,
                    (c[1] / c[0]).sqrt(),
                    100.0 * c[2] / m,
                    100.0 * c[2] / c[0]
                );
            }
        }
        errs.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let m: f64 = acc.iter().map(|c| c[0]).sum();
        let bands = aobake::report::metrics::sh_band_rmse(&run_sh, &kept_ref_sh);
        println!(
            "{} ({secs:.2} s): AO RMSE {:.5}, p99 {:.5}, SH RMSE L0/L1/L2 {:.5}/{:.5}/{:.5}, rays {:.1}",
            budget.label(),
            (total / m).sqrt(),
            errs[(errs.len() as f64 * 0.99) as usize],
            bands[0],
            bands[1],
            bands[2],
            acc.iter().map(|c| c[3]).sum::<f64>() / m
        );
        for (k, c) in acc.iter().enumerate() {
            if c[0] == 0.0 {
                continue;
            }
            println!(
                "  {:<20} {:5.1}%  rmse {:.4}  bias {:+.4}  err share {:5.1}%  rays {:6.1}  L2 rmse {:.4}  above tail: {:.2}% of all",
                NAMES[k],
                100.0 * c[0] / m,
                (c[2] / c[0]).sqrt(),
                c[1] / c[0],
                100.0 * c[2] / total,
                c[3] / c[0],
                (c[4] / c[0]).sqrt(),
                100.0 * c[5] / m
            );
        }
    }
}
