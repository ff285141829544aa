//! The worst texels of a filtered bake against a Monte Carlo reference,
//! with the filter's per-receiver diagnostics: where a large error is.
//!
//!     cargo run --release --example worst_texels -- SCENE.glb [RES] [K] [R] [REF_RAYS]
#[path = "../tests/common/mod.rs"]
mod common;

use aobake::Method;
use aobake::bake::sheared::ShearedOptions;
use aobake::stage::StageTimer;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let path = std::path::Path::new(&a[1]);
    let arg = |i: usize, d: f64| a.get(i).and_then(|v| v.parse().ok()).unwrap_or(d);
    let (res, k, r, refs) = (arg(2, 512.0), arg(3, 8.0), arg(4, 4.0), arg(5, 256.0));
    let (one, reference) = common::reference_bake(path, res as u32, refs as u32);
    let (s, p) = (one.s.clone(), one.page());
    let mut f = s.clone();
    f.method = Method::Sheared;
    f.sheared = ShearedOptions {
        sparse_rays: k as u32,
        gather_radius: r as f32,
        ..ShearedOptions::default()
    };
    let out = p
        .bake(&f, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .unwrap();
    let st = out.sheared_stats.unwrap();
    let mut idx: Vec<usize> = (0..p.receivers.len()).collect();
    idx.sort_by(|&i, &j| {
        let e = |i: usize| (out.bake.ao[i] - reference.ao[i]).abs();
        e(j).total_cmp(&e(i))
    });
    let space = &p.level.geometry.space;
    let params = aobake::bake::BakeParams {
        max_distance: p.level.max_distance,
        seed: s.seed,
    };
    let samples =
        aobake::bake::sheared::sparse_pass(&p.receivers, &p.level.tracer, &f.sheared, &params);
    let kk = k as usize;
    for &i in idx.iter().take(12) {
        let fp = p.receivers.footprint[i];
        println!(
            "texel {:7} at {:?}: filtered {:.3} reference {:.3} | brute {:.2} z_min {:.1} fp neighbours {} sparse AO {:.2} n {:?} geo {:?}",
            p.receivers.texel[i],
            (space.to_world(p.receivers.position[i])).to_array(),
            out.bake.ao[i],
            reference.ao[i],
            st.brute_fraction[i],
            st.z_min[i] / fp,
            st.neighbours[i],
            st.sparse_ao[i],
            p.receivers.normal[i].to_array(),
            p.receivers.geo_normal[i].to_array(),
        );
        let ts: Vec<String> = (i * kk..(i + 1) * kk)
            .map(|q| {
                format!(
                    "t {:.2e} d.geo {:.3}",
                    samples.t[q],
                    samples.dir[q].dot(p.receivers.geo_normal[i])
                )
            })
            .collect();
        if std::env::var("CELLS").is_ok() {
            let cells = aobake::bake::sheared::cell_estimates(
                &p.receivers,
                &samples,
                &p.level.tracer,
                &f.sheared,
                &params,
                i,
            );
            let nz: Vec<String> = cells
                .iter()
                .enumerate()
                .filter(|(_, c)| c.0 > 0.0 || c.2)
                .map(|(c, v)| format!("{c}:{:.1}/{:.1}/{}", v.0, v.1, v.2 as u8))
                .collect();
            println!("   cells: {}", nz.join(" "));
        }
        println!(
            "   own rays: {} (max distance {:.2e}, footprint {:.2e})",
            ts.join(", "),
            p.level.max_distance,
            fp
        );
    }
}
