use aobake::pipeline::{self, Method, Settings};
use aobake::unwrap::AtlasSize;
fn main() {
    let path = std::path::Path::new("../shared/assets/sponza_dabrovic.glb");
    let base = Settings {
        size: AtlasSize::Resolution(512),
        progress: false,
        ..Default::default()
    };
    let m = pipeline::bake_file(
        path,
        &Settings {
            method: Method::Mc,
            rays: 256,
            ..base.clone()
        },
    )
    .unwrap();
    let f = pipeline::bake_file(
        path,
        &Settings {
            method: Method::Filtered,
            ..base.clone()
        },
    )
    .unwrap();
    let st = f.filter_stats.as_ref().unwrap();
    let r = &f.receivers;
    let mut shown = 0;
    let mut count = 0;
    for i in 0..r.len() {
        if f.bake.ao[i] - m.bake.ao[i] > 0.3 {
            count += 1;
            if shown < 12 && i % 7 == 0 {
                shown += 1;
                println!(
                    "texel ({},{}) mc {:.3} filt {:.3} sparse {:.3} nbrs {} zmin {:.5} brute {:.2} fp {:.6} n {:.3?} g {:.3?} p {:.3?}",
                    r.texel[i] % r.width,
                    r.texel[i] / r.width,
                    m.bake.ao[i],
                    f.bake.ao[i],
                    st.sparse_ao[i],
                    st.neighbours[i],
                    st.z_min[i],
                    st.brute_fraction[i],
                    r.footprint[i],
                    r.normal[i],
                    r.geo_normal[i],
                    r.position[i]
                );
            }
        }
    }
    println!("{count} texels > 0.3 too bright of {}", r.len());
}
