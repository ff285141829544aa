//! The loader over arbitrary bytes: container, JSON, accessors, scene graph
//! and bake-space geometry must return an error, never panic or allocate
//! without bound.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // External URIs resolve against a directory that does not exist.
    let base = std::path::Path::new("/nonexistent-aobake-fuzz");
    if let Ok(doc) = aobake::gltf::container::parse(data, base)
        && let Ok(scene) = aobake::gltf::Scene::from_document(doc)
    {
        let _ = scene.bake_geometry();
    }
});
