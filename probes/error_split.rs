//! Where a bake's error comes from: bias against variance. Bakes one
//! method with several seeds on the same atlas and splits each texel's
//! mean squared error against a high-ray Monte Carlo reference into the
//! squared bias of the seeds' mean (less its own variance share) and the
//! variance across seeds, over all texels and binned by the fraction of
//! cells the filter brute-forced.
//!
//!     cargo run --release --example error_split -- SCENE.glb [RES] [RUN] [SEEDS] [REF_RAYS]
//!
//! RUN is `mc:N` or `filtered:K:R[:C]` (defaults `filtered:8:4`).
#[path = "../tests/common/mod.rs"]
mod common;

use aobake::stage::StageTimer;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(&a[1]);
    let res: u32 = a.get(2).and_then(|v| v.parse().ok()).unwrap_or(512);
    let run = a.get(3).cloned().unwrap_or("filtered:8:4".into());
    let seeds: u64 = a.get(4).and_then(|v| v.parse().ok()).unwrap_or(6);
    let refs: u32 = a.get(5).and_then(|v| v.parse().ok()).unwrap_or(2048);
    let (one, reference) = common::reference_bake(path, res, refs);
    let (s, p) = (one.s.clone(), one.page());
    let budget = aobake::report::parse_budgets(&run).expect("RUN")[0];
    let mut f = budget.settings(&s, 0);
    let n = p.receivers.len();
    let mut sum = vec![0.0f64; n];
    let mut sum2 = vec![0.0f64; n];
    let mut brute = vec![0.0f64; n];
    for seed in 0..seeds {
        f.seed = 0x5eed_0000 + seed * 7919;
        let out = p
            .bake(&f, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
        for i in 0..n {
            let e = (out.bake.ao[i] - reference.ao[i]) as f64;
            sum[i] += e;
            sum2[i] += e * e;
        }
        if let Some(st) = &out.sheared_stats {
            for (b, f) in brute.iter_mut().zip(&st.brute_fraction) {
                *b += *f as f64 / seeds as f64;
            }
        }
    }
    let sn = seeds as f64;
    let bins: [(&str, f64, f64); 4] = [
        ("all", -1.0, 2.0),
        ("brute 0 (all filtered or open)", -1.0, 1e-9),
        ("brute (0, 1)", 1e-9, 1.0 - 1e-9),
        ("brute 1", 1.0 - 1e-9, 2.0),
    ];
    println!(
        "{run} on {} at {res}, {seeds} seeds, reference {refs} rays",
        path.display()
    );
    println!("| texels | share | RMSE | bias RMS | noise RMS | mean bias |");
    println!("|---|---|---|---|---|---|");
    for (name, lo, hi) in bins {
        let (mut mse, mut b2, mut var, mut mb, mut cnt) = (0.0, 0.0, 0.0, 0.0, 0usize);
        for i in 0..n {
            if brute[i] < lo || brute[i] > hi {
                continue;
            }
            let m = sum[i] / sn;
            let v = (sum2[i] / sn - m * m).max(0.0) * sn / (sn - 1.0);
            mse += sum2[i] / sn;
            var += v;
            b2 += m * m - v / sn;
            mb += m;
            cnt += 1;
        }
        if cnt == 0 {
            continue;
        }
        let c = cnt as f64;
        println!(
            "| {name} | {:.1}% | {:.4} | {:.4} | {:.4} | {:+.4} |",
            100.0 * c / n as f64,
            (mse / c).sqrt(),
            (b2 / c).max(0.0).sqrt(),
            (var / c).sqrt(),
            mb / c
        );
    }
}
