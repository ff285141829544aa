//! The whole pipeline (load, unwrap, rasterize, trace, both methods, encode,
//! write) on arbitrary bytes that load, with a tiny atlas and few rays:
//! every input either bakes or returns an error.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let base = std::path::Path::new("/nonexistent-aobake-fuzz");
    let Ok(doc) = aobake::gltf::container::parse(data, base) else {
        return;
    };
    let Ok(scene) = aobake::gltf::Scene::from_document(doc) else {
        return;
    };
    // Keep each run short: small scenes only.
    let triangles: usize = scene.geometries.iter().map(|g| g.triangles.len() / 3).sum();
    if triangles > 2_000 {
        return;
    }
    for method in [aobake::Method::Mc, aobake::Method::Filtered] {
        let settings = aobake::Settings {
            size: aobake::atlas::AtlasSize::Resolution(16),
            method,
            rays: 2,
            progress: false,
            ..Default::default()
        };
        let _ = aobake::bake_scene(&scene, &settings);
    }
});
