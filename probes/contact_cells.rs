//! Contact texels per hemisphere cell: how many of a contact texel's 16
//! cells (the 4x4 strata of its sequence's square) hold an occluder
//! within k footprints, and what share of its visibility variance lies
//! in those cells.
//!
//!     cargo run --release --example contact_cells -- SCENE.glb [RES] [RAYS]
#[path = "../tests/common/mod.rs"]
mod common;

use aobake::bake::ReceiverRays;
use aobake::stage::StageTimer;
use rayon::prelude::*;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(&a[1]);
    let res: u32 = a.get(2).and_then(|v| v.parse().ok()).unwrap_or(1024);
    let rays: u32 = a.get(3).and_then(|v| v.parse().ok()).unwrap_or(256);
    let one = common::prepare_for_reference(path, res, 64);
    let p = one.page();
    let s = aobake::BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(res),
        fill_inside: false,
        ..Default::default()
    };
    let out = p
        .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .unwrap();
    let st = out.adaptive_stats.unwrap();
    let rc = &p.receivers;
    let tracer = &p.level.tracer;
    let md = p.level.max_distance;
    let n = rc.len();
    let contact: Vec<usize> = (0..n)
        .filter(|&i| st.sigma_texels[i] <= 0.0 && st.z_min[i].is_finite())
        .collect();
    let all_rays: u64 = st.rays.iter().map(|&r| r as u64).sum();
    let contact_rays: u64 = contact.iter().map(|&i| st.rays[i] as u64).sum();
    println!(
        "texels {n}, contact {} ({:.3}), rays/texel {:.1}, contact rays share {:.3}, mean contact rays {:.1}",
        contact.len(),
        contact.len() as f64 / n as f64,
        all_rays as f64 / n as f64,
        contact_rays as f64 / all_rays as f64,
        contact_rays as f64 / contact.len() as f64
    );
    let ks = [1.0f32, 2.0, 4.0, 8.0, 16.0];
    // Per contact texel: per k, near cells and their variance share.
    let per: Vec<([u32; 5], [f64; 5], f64)> = contact
        .par_iter()
        .map(|&r| {
            let ray = ReceiverRays::new(rc, r, 0);
            let fp = rc.footprint[r];
            let mut near = [f32::INFINITY; 16];
            let mut vis = [0u32; 16];
            let mut cnt = [0u32; 16];
            for i in 0..rays {
                let u = ray.point(i);
                let c = (u.x * 4.0).min(3.0) as usize + 4 * (u.y * 4.0).min(3.0) as usize;
                let d = ray.direction_of(u);
                cnt[c] += 1;
                if d.dot(ray.geo_normal) <= 0.0 {
                    near[c] = 0.0;
                    continue;
                }
                match tracer.trace_closest(ray.origin, d, md, md) {
                    Some(h) => near[c] = near[c].min(h.distance_within(md, md)),
                    None => vis[c] += 1,
                }
            }
            let var: Vec<f64> = (0..16)
                .map(|c| {
                    let q = vis[c] as f64 / cnt[c].max(1) as f64;
                    q * (1.0 - q)
                })
                .collect();
            let total: f64 = var.iter().sum();
            let mut nn = [0u32; 5];
            let mut share = [0f64; 5];
            for (k, &m) in ks.iter().enumerate() {
                for c in 0..16 {
                    if near[c] < m * fp {
                        nn[k] += 1;
                        share[k] += var[c];
                    }
                }
            }
            (nn, share, total)
        })
        .collect();
    let tot: f64 = per.iter().map(|p| p.2).sum();
    for (k, &m) in ks.iter().enumerate() {
        let cells: f64 = per.iter().map(|p| p.0[k] as f64).sum::<f64>() / per.len() as f64;
        let sh: f64 = per.iter().map(|p| p.1[k]).sum::<f64>() / tot;
        println!(
            "near < {m} fp: mean near cells {cells:.2} of 16, variance share in near cells {sh:.3}"
        );
    }
}
