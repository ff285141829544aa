//! Where the adaptive method's bias is on a floor beside a wall: AO bias
//! against a 2048-ray reference, binned by distance from the wall, with
//! the filter on and off.
//!
//!     cargo run --release --example adaptive_probe
#[path = "../tests/common/mod.rs"]
mod common;
use common::*;

fn main() {
    let sc = floor_and_wall();
    let raw = |s: aobake::BakeSettings| bake_raw(&sc, s);
    let reference = raw(aobake::BakeSettings {
        seed: 11,
        ..settings(128, 2048, Some(1.0))
    });
    for (reach, mean) in [(0u32, 16u32), (0, 64), (8, 16), (8, 64)] {
        let mut s = settings(128, aobake::job::settings::DEFAULT_RAYS, Some(1.0));
        s.method = aobake::Method::Adaptive;
        s.adaptive.max_reach = reach;
        s.adaptive.mean_rays = mean;
        let a = raw(s);
        let st = a.adaptive_stats.as_ref().unwrap();
        let sp = &a.geometry.space;
        let mut bins = [(0.0f64, 0.0f64, 0usize, 0.0f64, 0.0f64); 8];
        for i in 0..a.receivers.len() {
            let p = sp.to_world(a.receivers.position[i]);
            if p.z.abs() > 1e-4 || p.y.abs() > 0.4 {
                continue;
            }
            let d = (p.x - 0.3).abs();
            let b = ((d / 0.05) as usize).min(7);
            bins[b].0 += (a.bake.ao[i] - reference.bake.ao[i]) as f64;
            bins[b].1 += ((a.bake.ao[i] - reference.bake.ao[i]) as f64).powi(2);
            bins[b].2 += 1;
            bins[b].3 += st.rays[i] as f64;
            bins[b].4 += st.sigma_texels[i] as f64;
        }
        println!("max_reach {reach}, mean rays {mean}:");
        for (k, b) in bins.iter().enumerate() {
            let n = b.2.max(1) as f64;
            println!(
                "  {:.2}-{:.2} from the wall: bias {:+.4} rmse {:.4} rays {:.0} sigma {:.2} texels ({} texels)",
                k as f64 * 0.05,
                (k + 1) as f64 * 0.05,
                b.0 / n,
                (b.1 / n).sqrt(),
                b.3 / n,
                b.4 / n,
                b.2
            );
        }
    }
}
