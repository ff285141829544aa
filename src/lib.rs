//! aobake: bakes ambient occlusion and 9-coefficient spherical-harmonic
//! directional occlusion into lightmaps and writes them back into glTF.
//!
//! The pipeline has one module per stage, in order:
//! [`load`] -> [`unwrap`] -> [`rasterize`] -> [`trace`] -> [`validity`] ->
//! [`mc`] or [`filter`] (with [`sample`] and [`sh`]) -> [`dilate`] ->
//! [`encode`] -> [`write`](mod@write); [`pipeline`] runs them. [`report`]
//! (with [`metrics`] and [`plot`]) measures error against run time. See the
//! README for the output format.

pub mod dilate;
pub mod encode;
pub mod error;
pub mod filter;
pub mod load;
pub mod mc;
pub mod metrics;
pub mod pipeline;
pub mod plot;
pub mod rasterize;
pub mod report;
pub mod sample;
pub mod sh;
pub mod trace;
pub mod unwrap;
pub mod validity;
pub mod write;

pub use error::{Error, Result};
pub use pipeline::{Method, Report, Settings, UvSource, bake_file, bake_scene, run};
