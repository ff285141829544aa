//! aobake: bakes ambient occlusion and 9-coefficient spherical-harmonic
//! directional occlusion into lightmaps and writes them back into glTF.
//!
//! The folders are the pipeline, in order ([`pipeline`] runs them):
//!
//! | stage | module | in -> out |
//! |---|---|---|
//! | load | [`gltf`] | a `.glb`/`.gltf` -> [`gltf::Scene`], then [`geometry::BakeGeometry`] |
//! | atlas | [`atlas`] | receiver meshes -> [`atlas::Atlas`] and [`atlas::Receivers`] |
//! | trace | [`trace`] | occluder triangles -> a BVH ([`trace::Tracer`]) |
//! | bake | [`bake`] | receivers + tracer -> [`bake::Bake`] (AO and SH per receiver) |
//! | seams | [`seams`] | dilated images -> the same, stitched at smooth seams |
//! | encode | [`encode`] | bake + dilation map -> lightmap PNGs (and EXR) |
//! | write | [`gltf::write`] | scene + atlas + PNGs -> the output GLB |
//! | shard | [`shard`] | one shard's pages -> a partial; a complete set -> the output GLB |
//! | report | [`report`] | a scene -> error against time for each method |
//! | view | [`view`] | a baked GLB -> the relighting viewer on 127.0.0.1 |
//!
//! Beneath them, used by the stages and using none: [`geometry`] (the
//! bake-space scene the atlas reads, no glTF syntax), [`sample`] (Sobol
//! points, cells, frames), [`sh`] (the SH basis, to order 3 for the
//! visibility layer), [`relight`] (what an engine does with a bake), [`stage`] (timer and
//! progress bars), [`file`] (atomic writes), [`error`]. [`settings`] is
//! what a bake is told. See the README for the output format.

pub mod atlas;
pub mod bake;
pub mod encode;
pub mod error;
pub mod file;
pub mod geometry;
pub mod gltf;
pub mod pipeline;
pub mod relight;
pub mod report;
pub mod sample;
pub mod seams;
pub mod settings;
pub mod sh;
pub mod shard;
pub mod stage;
pub mod trace;
pub mod view;

pub use error::{Error, Result};
pub use pipeline::{Report, bake_file, bake_scene, run};
pub use settings::{Method, Settings, UvSource};
