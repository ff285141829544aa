//! glTF in and out: the one GLB reader and writer, accessors, the scene
//! graph, and the lossless write-back of a bake.
//!
//! In (reading): a `.glb`/`.gltf` path. Out: a [`Scene`] (the untouched
//! document, each triangle primitive decoded once, every placement) and,
//! through [`Scene::bake_geometry`], [`crate::geometry::BakeGeometry`] in
//! *bake space*.
//! In (writing): the scene, its atlas and the encoded lightmaps. Out: the
//! output GLB bytes ([`write::build_glb`]).
//!
//! - [`container`]: GLB chunks or JSON, buffers (BIN, `data:`, files), and
//!   GLB serialization;
//! - `decompress`: Draco and meshopt geometry decoded into plain views;
//! - [`accessor`]: typed reads (strides, sparse, normalized, quantized);
//! - [`scene`]: nodes, transforms, primitives, instancing, bake space;
//! - [`write`](mod@write): the document edited as `serde_json::Value`,
//!   images appended to BIN;
//! - `uris`: URIs relocated to the output's directory;
//! - `append`: accessors and bufferViews added to the output's BIN.

pub mod accessor;
mod append;
pub mod container;
pub(crate) mod decompress;
pub mod scene;
#[cfg(feature = "contract-check")]
mod schema_check;
pub(crate) mod uris;
pub mod write;

pub use container::Document;
pub use scene::{
    Instance, MAX_TRIANGLES, PrimitiveGeometry, Scene, load, load_with_bytes, primitive_label,
};
