//! Writes a PNG of which texels the validity pass marks inside geometry
//! (white) over the baked AO (grey), for checking a scene by eye.
//!
//!     cargo run --release --example inside_map -- SCENE.glb OUT.png [--resolution 512]

use aobake::BakeSettings;
use aobake::atlas::AtlasSize;
use aobake::stage::StageTimer;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let resolution: u32 = args
        .iter()
        .position(|a| a == "--resolution")
        .and_then(|i| args.get(i + 1))
        .map_or(512, |v| v.parse().unwrap());
    let scene = aobake::gltf::load(std::path::Path::new(&args[0])).expect("load");
    let s = BakeSettings {
        size: AtlasSize::Resolution(resolution),
        method: aobake::Method::Mc,
        rays: 16,
        ..Default::default()
    };
    let level = aobake::job::Level::new(
        &scene,
        &s,
        &aobake::RunOptions::QUIET,
        &mut StageTimer::new(),
    )
    .expect("prepare");
    let p = level
        .page(0, &scene, &mut StageTimer::new())
        .expect("prepare");
    let passes = p
        .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
        .expect("bake");
    let r = &p.receivers;
    let inside = passes.inside(&p);
    let mut img = vec![0u8; (r.width * r.height * 3) as usize];
    for (i, &inside) in inside.iter().enumerate() {
        let t = r.texel[i] as usize * 3;
        let px = if inside {
            [255, 0, 255]
        } else {
            let g = (passes.bake.ao[i] * 200.0) as u8;
            [g, g, g]
        };
        img[t..t + 3].copy_from_slice(&px);
    }
    let png = aobake::encode::png(r.width, r.height, &img, image::ExtendedColorType::Rgb8).unwrap();
    std::fs::write(&args[1], png).unwrap();
    println!(
        "{} of {} texels inside",
        inside.iter().filter(|&&x| x).count(),
        r.len()
    );
}
