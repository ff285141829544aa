//! Atlas: the lightmap page and its texels.
//!
//! In: the [`crate::geometry::ReceiverMesh`]es in bake space. Out: an
//! [`Atlas`] (one page, a chart layout per receiver mesh), its
//! [`Receivers`] (one point per covered texel, the paper's receivers).
//!
//! - [`unwrap`](mod@unwrap): charts and packing (`uvunwrap`), or an
//!   existing UV set; `pages` crops the last page;
//! - [`rasterize`](mod@rasterize): covered texels into receivers,
//!   conservative at chart edges;
//! - [`order`]: the receivers in world-space Morton order, for the tracing
//!   passes' caches.

pub mod order;
pub(crate) mod pages;
pub mod rasterize;
pub mod unwrap;

pub use rasterize::{Receivers, rasterize};
pub use unwrap::{
    Atlas, AtlasSize, ChartTooLarge, Ladder, MAX_ATLAS_EDGE, Packing, PageSize, UnwrapOptions,
};
