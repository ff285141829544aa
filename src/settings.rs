//! Settings: everything a bake can be told, checked once.
//!
//! In: the caller's choices (the CLI's flags, or a library caller's
//! fields). Out: [`Settings`], whose [`Settings::validate`] runs before
//! any stage, and [`estimated_bytes`], the memory check made once the
//! atlas size is known. Defaults live here only; the CLI takes its
//! defaults from [`Settings::default`].
//!
//! Errors name a setting by its field here (`sparse_rays`); the command
//! line shows the flag instead (`--sparse-rays`).

use crate::atlas::{AtlasSize, Packing};
use crate::bake::adaptive::AdaptiveOptions;
use crate::bake::sheared::ShearedOptions;
use crate::error::{Error, Result};
use crate::gltf::write::OcclusionMode;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Memory a bake may use (checked against [`estimated_bytes`] before the
/// per-texel arrays are allocated): the 24 GiB build machines keep room for
/// the loaded scene and the BVH.
pub const MAX_BAKE_BYTES: u64 = 16 << 30;

/// Per atlas texel, an upper bound of what the output stages hold at once:
/// receiver (texel, position, two normals, footprint, centre inside: 45 B), results (AO
/// and 9 SH: 40 B), the float lightmap with its coverage (41 B), the
/// dilation map (4 B), BFS queue and encoded image rows (~24 B).
const BYTES_PER_TEXEL: u64 = 160;

/// Per atlas texel, what every method holds while it bakes: the receiver
/// (45 B) and its results (40 B). A method's working arrays come on top of
/// these, and are freed before the output stages.
const BAKE_BYTES_PER_TEXEL: u64 = 45 + 40;

/// Default atlas page edge in texels.
pub const DEFAULT_RESOLUTION: u32 = 1024;

/// Default largest page edge of a `--texel-density` bake (a common engine
/// and GPU texture limit).
pub const DEFAULT_PAGE_SIZE: u32 = 4096;

/// Default Monte Carlo rays per texel.
pub const DEFAULT_RAYS: u32 = 256;

/// Default max occluder distance as a fraction of the scene's bounding-box diagonal.
pub const DEFAULT_MAX_DISTANCE_FRACTION: f64 = 0.1;

/// Baking method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Sparse rays shared between texels by the sheared filter of Egan et
    /// al. 2011 ([`crate::bake::sheared`]). Named `filtered` before the
    /// adaptive method; that name is still accepted.
    Sheared,
    /// Brute-force Monte Carlo ([`crate::bake::mc`]).
    Mc,
    /// Adaptive ray counts and an axis-aligned filter
    /// ([`crate::bake::adaptive`]).
    Adaptive,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Sheared => "sheared",
            Method::Mc => "mc",
            Method::Adaptive => "adaptive",
        }
    }
}

/// Which primitives get the visibility layer (`--visibility`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VisibilityMode {
    /// Where the primitive's material can use it
    /// (`gltf::Scene::material_reads_visibility`: a normal map or a glossy
    /// lobe); a scene with none bakes no layer.
    #[default]
    Auto,
    /// Every baked primitive.
    All,
    /// None.
    Off,
}

/// What happens at smooth seams (`--seams`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SeamMode {
    /// Least-squares stitching of both sides ([`crate::seams`]).
    #[default]
    Stitch,
    /// Each side keeps its own baked and dilated texels.
    Off,
}

/// Where the lightmap UVs come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum UvSource {
    /// Unwrap every baked placement into a new atlas (new TEXCOORD_n).
    #[default]
    Generate,
    /// Reuse `TEXCOORD_<set>` as it is.
    Existing(usize),
}

/// Everything a bake can be told.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Settings {
    pub size: AtlasSize,
    pub padding: u32,
    pub packing: Packing,
    pub uv: UvSource,
    pub method: Method,
    /// Rays per texel of the Monte Carlo method.
    pub rays: u32,
    /// Options of the filtered method.
    pub filter: ShearedOptions,
    /// Options of the adaptive method.
    pub adaptive: AdaptiveOptions,
    /// Write diagnostic PNG maps here.
    pub debug_dir: Option<PathBuf>,
    /// World units; `None`: [`DEFAULT_MAX_DISTANCE_FRACTION`] of the diagonal.
    pub max_distance: Option<f64>,
    pub seed: u64,
    pub occlusion: OcclusionMode,
    pub exr_dir: Option<PathBuf>,
    /// Show progress bars (only drawn when stderr is a terminal).
    pub progress: bool,
    /// Fill texels inside or behind geometry from their nearest valid
    /// texel ([`crate::bake::validity`]); `false` bakes them as they are.
    pub fill_inside: bool,
    /// Which primitives get the visibility layer.
    pub visibility: VisibilityMode,
    /// SH order of the visibility layer written: 3 (16 coefficients) or
    /// 2 (9).
    pub visibility_order: u32,
    pub seams: SeamMode,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            size: AtlasSize::Resolution(DEFAULT_RESOLUTION),
            padding: 2,
            packing: Packing::Fast,
            uv: UvSource::Generate,
            // Adaptive: measured against 256-ray Monte Carlo on five scenes
            // in the comparison table of `docs/method-adaptive.md`.
            method: Method::Adaptive,
            rays: DEFAULT_RAYS,
            filter: ShearedOptions::default(),
            adaptive: AdaptiveOptions::default(),
            debug_dir: None,
            max_distance: None,
            seed: 0,
            occlusion: OcclusionMode::Keep,
            exr_dir: None,
            progress: true,
            fill_inside: true,
            visibility: VisibilityMode::Auto,
            visibility_order: 3,
            seams: SeamMode::Stitch,
        }
    }
}

impl Settings {
    /// Checks every setting that can be checked without the scene: the
    /// pipeline calls it before any stage, so a bad option fails at once.
    pub fn validate(&self) -> Result<()> {
        // Refused whichever method reads it.
        if self.rays == 0 {
            return Err(Error::option("rays", "must be at least 1"));
        }
        match self.method {
            Method::Mc => {}
            Method::Sheared => self.filter.validate()?,
            Method::Adaptive => self.adaptive.validate()?,
        }
        if !matches!(self.visibility_order, 2 | 3) {
            return Err(Error::option(
                "visibility_order",
                format!("{} must be 2 or 3", self.visibility_order),
            ));
        }
        if self.visibility == VisibilityMode::All && self.method == Method::Sheared {
            return Err(Error::option_conflict(
                "visibility",
                "the sheared method does not bake the visibility layer; use --method adaptive or mc, or --visibility off",
            ));
        }
        crate::atlas::unwrap::check_size(self.size)?;
        if let Some(d) = self.max_distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(Error::option(
                "max_distance",
                format!("{d} must be finite and > 0"),
            ));
        }
        if let (UvSource::Existing(_), AtlasSize::TexelDensity { .. }) = (self.uv, self.size) {
            return Err(Error::option_conflict(
                "texel_density",
                "needs generated UVs; give a resolution with existing UVs",
            ));
        }
        Ok(())
    }
}

/// Memory estimate of baking a `width` x `height` atlas with settings `s`
/// (every texel counted as covered: the worst case): the larger of the bake
/// stage (receivers, results and the method's working arrays) and the
/// output stages (with what the method keeps for the report and debug
/// maps). Measured peak RSS, Cornell box at 4096 x 3594, 16 rays: 2.09 GB
/// (`mc`) and 2.24 GB (`adaptive`), under this estimate's 2.36 and 2.71 GB.
pub fn estimated_bytes(width: u32, height: u32, s: &Settings) -> u64 {
    estimated_bytes_with(width, height, s, s.visibility == VisibilityMode::All)
}

/// Per atlas texel, what the visibility layer adds to either stage: its
/// result (16 floats) and, in the bake, the filter's row pass and shares
/// (2 x 68 B); in the output stages, the float layer (64 B) beside it.
pub const VISIBILITY_BYTES_PER_TEXEL: u64 = 64 + 2 * 68;

/// [`estimated_bytes`], knowing whether the scene bakes the visibility
/// layer (`--visibility auto` decides from its materials).
pub fn estimated_bytes_with(width: u32, height: u32, s: &Settings, layer: bool) -> u64 {
    let texels = width as u64 * height as u64;
    let layer = if layer { VISIBILITY_BYTES_PER_TEXEL } else { 0 };
    let (working, kept) = match s.method {
        Method::Mc => (0, 0),
        // Counted as held throughout (not measured).
        Method::Sheared => (s.filter.bytes_per_texel(), s.filter.bytes_per_texel()),
        Method::Adaptive => (
            s.adaptive.bytes_per_texel(),
            AdaptiveOptions::KEPT_BYTES_PER_TEXEL,
        ),
    };
    texels * ((BAKE_BYTES_PER_TEXEL + working).max(BYTES_PER_TEXEL + kept) + layer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_default_fits_an_8192_page() {
        for method in [Method::Mc, Method::Adaptive] {
            let s = Settings {
                method,
                ..Settings::default()
            };
            let need = estimated_bytes(8192, 8192, &s);
            assert!(need <= MAX_BAKE_BYTES, "{method:?}: {need}");
            // ... and 16000^2 does not.
            assert!(estimated_bytes(16000, 16000, &s) > MAX_BAKE_BYTES);
        }
    }

    #[test]
    fn the_estimate_is_the_larger_stage_not_their_sum() {
        let mc = Settings {
            method: Method::Mc,
            ..Settings::default()
        };
        let adaptive = Settings {
            method: Method::Adaptive,
            ..Settings::default()
        };
        let per_texel = |s: &Settings| estimated_bytes(1000, 1000, s) / 1_000_000;
        assert_eq!(per_texel(&mc), BYTES_PER_TEXEL);
        let working = adaptive.adaptive.bytes_per_texel();
        assert_eq!(
            per_texel(&adaptive),
            (BAKE_BYTES_PER_TEXEL + working)
                .max(BYTES_PER_TEXEL + AdaptiveOptions::KEPT_BYTES_PER_TEXEL)
        );
        assert!(per_texel(&adaptive) < BYTES_PER_TEXEL + working);
    }
}
