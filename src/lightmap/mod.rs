//! The lightmap stage: a page's baked receivers into the texel values the
//! engine's bilinear lookups will read.
//!
//! In: a baked page ([`PageBake`]: its receivers, their [`Bake`], which of
//! them lie inside geometry, the page's charts and what its seams need).
//! Out: the page's float [`Lightmap`] (every texel's AO, SH and visibility
//! layer), which [`crate::encode`] only quantizes and writes, and the seam
//! figures ([`Built`]).
//!
//! Every post-bake stage lives here, in order:
//!
//! 1. [`dilate`]: the receiver each texel shows (gutters, and texels inside
//!    geometry filled from their nearest valid receiver);
//! 2. [`spread`](mod@spread): receiver results over the page through that
//!    map;
//! 3. [`seams`]: the two sides of every smooth seam stitched to agree
//!    (within the page, and to a shared target across pages).
//!
//! A new post-bake stage goes into [`build`], between these, reading and
//! writing the [`Lightmap`]. [`engine_view`] measures the result where an
//! engine reads it (bilinear lookups at surface points).

pub mod dilate;
pub mod engine_view;
pub mod seams;
pub mod spread;

pub use spread::spread;

use crate::atlas::{Atlas, PageSize, Receivers};
use crate::bake::Bake;
use crate::error::Result;
use crate::geometry::ReceiverMesh;
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::stage::StageTimer;
use crate::trace::Tracer;
use seams::{CrossSeam, FLAT_DEGREES, SMOOTH_DEGREES, SeamMode, SeamReport};

/// Float lightmap images, row-major, row 0 at the top (glTF v = 0).
#[derive(Clone, Debug)]
pub struct Lightmap {
    pub width: u32,
    pub height: u32,
    pub ao: Vec<f32>,
    pub sh: Vec<[f32; SH_COUNT]>,
    /// Whether each texel holds a receiver of its own (not dilated).
    pub covered: Vec<bool>,
    /// The visibility layer v_0..v_15, when baked.
    pub visibility: Option<Vec<[f32; VIS_COUNT]>>,
}

/// What the lightmap stage reads of one baked page.
pub struct PageBake<'a> {
    /// The page's index among the level's pages.
    pub page: u32,
    /// Every page's size (the cross-page seams' sides are measured on them).
    pub pages: &'a [PageSize],
    /// The receiver meshes of the level (bake space).
    pub meshes: &'a [ReceiverMesh],
    /// This page alone, as a one-page atlas.
    pub atlas: &'a Atlas,
    pub receivers: &'a Receivers,
    pub bake: &'a Bake,
    /// Per receiver: inside or behind geometry (its texel shows its nearest
    /// valid receiver instead); empty: none is.
    pub inside: &'a [bool],
    /// The level's seams whose sides lie on two pages.
    pub cross_seams: &'a [CrossSeam],
    /// For the cross-page seams' targets: the occluders, their max distance
    /// (bake units) and the bake's seed.
    pub tracer: &'a Tracer,
    pub max_distance: f32,
    pub seed: u64,
    /// The scene's bounding-box diagonal (bake units to world units).
    pub diagonal: f64,
}

/// What the lightmap stage made of a page.
pub struct Built {
    pub lightmap: Lightmap,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
    /// With `seam_maps`: the AO jump at the seams before and after
    /// stitching, one grey byte per texel ([`seams::jump_map`]).
    pub seam_maps: Option<[Vec<u8>; 2]>,
}

/// Runs the post-bake stages on one page: dilate, spread, stitch. Fails
/// if a baked value is NaN or infinite (it must never reach a texture).
pub fn build(
    p: &PageBake,
    seam_mode: SeamMode,
    seam_maps: bool,
    timer: &mut StageTimer,
) -> Result<Built> {
    timer.restart();
    let r = p.receivers;
    let fill = dilate::fill_map(r.width, r.height, &r.texel, p.inside);
    let mut lightmap = spread(r, p.bake, &fill)?;
    timer.lap("dilate");
    if seam_mode == SeamMode::Off {
        return Ok(Built {
            lightmap,
            seams: None,
            seam_maps: None,
        });
    }
    let found = seams::find::smooth_seams(p.meshes, p.atlas, SMOOTH_DEGREES, FLAT_DEGREES);
    let (w, h) = (lightmap.width, lightmap.height);
    let map = |lm: &Lightmap| {
        let points = seams::metric::points(&found, w, h, &lm.ao, &lm.sh);
        seams::jump_map(&points, w, h)
    };
    let before = seam_maps.then(|| map(&lightmap));
    // Seams to other pages: this side meets the target both compute.
    let anchors = seams::anchor::anchors(
        p.cross_seams,
        p.page,
        p.pages,
        p.tracer,
        p.max_distance,
        p.seed,
        lightmap.visibility.is_some(),
    );
    let report = seams::stitch_page(
        &found,
        &anchors,
        p.diagonal,
        w,
        h,
        &lightmap.covered,
        &mut lightmap.ao,
        &mut lightmap.sh,
        lightmap.visibility.as_deref_mut(),
    );
    let seam_maps = before.map(|b| [b, map(&lightmap)]);
    timer.lap("seams");
    Ok(Built {
        lightmap,
        seams: Some(report),
        seam_maps,
    })
}
