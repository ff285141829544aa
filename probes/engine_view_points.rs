//! The project's engine view point by point, for a comparison with an
//! independent checker on the same points: bakes page 0 of SCENE with the
//! default settings, spreads N surface points over it as `--engine-view-
//! points` does, and writes one CSV row per point: world position, shading
//! and geometric normal, the origin offset the reference used (world
//! units), lightmap UV, the reference's AO (R rays), the bilinear lookup
//! of the decoded 8-bit textures, the class of its taps and whether it is
//! inside geometry.
//!
//!     cargo run --release --example engine_view_points -- SCENE.glb OUT.csv [N] [R]
use aobake::lightmap::engine_view::{self, TexelClass};
use aobake::stage::StageTimer;
use std::io::Write;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let scene = aobake::gltf::load(std::path::Path::new(&a[1])).expect("load");
    let count: usize = a.get(3).and_then(|v| v.parse().ok()).unwrap_or(20000);
    let rays: u32 = a.get(4).and_then(|v| v.parse().ok()).unwrap_or(512);
    let s = aobake::BakeSettings::default();
    let run = aobake::RunOptions::QUIET;
    let mut timer = StageTimer::new();
    let level = aobake::job::Level::new(&scene, &s, &run, &mut timer).expect("level");
    assert_eq!(level.page_count(), 1, "one page only");
    let page = level.page(0, &scene, &mut timer).expect("page");
    let passes = page.bake(&s, &run, &mut timer).expect("bake");
    let out = page.finish(&passes, &s, &run, &mut timer).expect("finish");
    let probe = page.engine_probe(count, rays, 0x5eed, false);
    let decoded = aobake::encode::decode(&out.encoded).expect("decode");
    let space = level.geometry.space;
    let d = space.diagonal as f32;
    let mut f = std::io::BufWriter::new(std::fs::File::create(&a[2]).expect("out"));
    writeln!(
        f,
        "x,y,z,nx,ny,nz,gx,gy,gz,offset,u,v,ref_ao,lookup_ao,class,inside"
    )
    .unwrap();
    let p = &probe.points;
    for k in 0..p.uv.len() {
        let r = &p.receivers;
        let x = space.to_world(r.position[k]);
        let (n, g) = (r.normal[k], r.geo_normal[k]);
        let offset = (aobake::trace::ORIGIN_OFFSET
            + aobake::trace::ORIGIN_OFFSET_FOOTPRINT * r.footprint[k])
            * d;
        let (ao, _) = engine_view::lookup(&decoded, p.uv[k], aobake::lightmap::Filter::Bilinear);
        let class =
            match engine_view::class_of(p.uv[k], decoded.width, decoded.height, &probe.centers) {
                TexelClass::Interior => 0,
                TexelClass::Border => 1,
                TexelClass::Sliver => 2,
            };
        writeln!(
            f,
            "{},{},{},{},{},{},{},{},{},{:e},{},{},{},{},{},{}",
            x.x,
            x.y,
            x.z,
            n.x,
            n.y,
            n.z,
            g.x,
            g.y,
            g.z,
            offset,
            p.uv[k][0],
            p.uv[k][1],
            probe.reference.ao[k],
            ao,
            class,
            probe.reference.inside[k] as u8
        )
        .unwrap();
    }
    // The same bake's GLB, for the checker's lookups.
    if let Some(glb) = a.get(5) {
        let baked = aobake::bake_scene(&scene, &s).expect("bake");
        std::fs::write(glb, baked.glb).unwrap();
    }
}
