//! aobake: bakes ambient occlusion and 9-coefficient spherical-harmonic
//! directional occlusion into lightmaps and writes them back into glTF.
//!
//! [`job`] runs the stages in order: [`gltf`] (load) -> [`atlas`] (unwrap,
//! rasterize) and [`trace`] (BVH) -> `bake` (the methods) ->
//! [`lightmap`] (dilate, spread, seams) -> [`encode`] -> [`gltf::write`].
//! [`shard`] is the sharded bake's partial files; with the `cli` feature
//! (the binary's, on by default), `report` is the `aobake report` sweep and
//! `view` the relighting viewer's server. Beneath them,
//! used by the stages and using none: [`geometry`], [`sample`], [`sh`],
//! [`relight`], [`bits`], [`stage`], `file`, [`error`].
//!
//! Figures quoted in the code's comments (a scene's error or time behind
//! a default or a departure from the paper) were measured in November
//! 2026 on the project's 2-core build machine, one run each, unless the
//! comment says otherwise; `docs/measurements/` holds the tables they come
//! from.
//!
//! `ARCHITECTURE.md` is the code map: every stage with its In and Out, the
//! invariants (no import cycle, stages import only downwards), and where to
//! add a stage or a command-line option. The README holds the output
//! format.

pub mod atlas;
pub mod bake;
pub mod bits;
pub mod encode;
pub mod error;
pub mod file;
pub mod geometry;
pub mod gltf;
pub mod job;
pub mod lightmap;
pub mod relight;
#[cfg(feature = "cli")]
pub mod report;
pub mod sample;
pub mod sh;
pub mod shard;
pub mod stage;
pub mod trace;
#[cfg(feature = "cli")]
pub mod view;

pub use error::{Error, Result};
pub use job::{
    BakeSettings, Device, Method, Report, RunOptions, UvSource, bake, bake_file, bake_scene,
};
