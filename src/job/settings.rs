//! Settings: what a bake is ([`BakeSettings`]) and how this run of it goes
//! ([`RunOptions`]), each checked once.
//!
//! In: the caller's choices (the command line's flags, derived from these
//! very fields with `clap`, or a library caller's fields). Out:
//! [`BakeSettings`], whose [`BakeSettings::validate`] runs before any stage
//! and whose JSON is a shard's fingerprint (everything in it decides the
//! output bytes, nothing else does), [`RunOptions`] (progress bars and
//! diagnostic files, which change no output byte), and [`estimated_bytes`],
//! the memory check made once the atlas size is known. Defaults live here
//! only ([`BakeSettings::DEFAULT`]); the command line shows them.
//!
//! Each field's doc comment is its `--help` line, so the help cannot drift
//! from the code. Errors name a setting by its field here (`sparse_rays`);
//! the command line shows the flag instead (`--sparse-rays`).

use crate::atlas::{AtlasSize, Ladder, Packing};
use crate::bake::adaptive::AdaptiveOptions;
use crate::bake::sheared::ShearedOptions;
use crate::bake::signal::TexelBudget;
use crate::error::{Error, Result};
use crate::gltf::write::OcclusionMode;
use crate::lightmap::seams::SeamMode;
use crate::lightmap::{BorderMode, Filter};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Memory a bake may use (checked against [`estimated_bytes`] before the
/// per-texel arrays are allocated): the 24 GiB build machines keep room for
/// the loaded scene and the BVH.
pub(crate) const MAX_BAKE_BYTES: u64 = 16 << 30;

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
pub(crate) const DEFAULT_MAX_DISTANCE_FRACTION: f64 = 0.1;

/// Baking method: `Adaptive` (ray counts per texel from the occluders'
/// depth and an axis-aligned filter of the integrated values,
/// [`crate::bake::adaptive`]), `Mc` (brute-force Monte Carlo,
/// [`crate::bake::mc`]) or `Sheared` (sparse rays shared between texels by
/// the sheared filter of Egan et al. 2011, [`crate::bake::sheared`]; named
/// `filtered` before the adaptive method, which the command line still
/// accepts).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Method {
    #[cfg_attr(feature = "cli", value(alias = "filtered"))]
    Sheared,
    Mc,
    #[default]
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

/// Which primitives get the visibility layer (`--visibility`): `Auto`,
/// where the primitive's material can use it
/// (`gltf::Scene::material_reads_visibility`: a normal map, a roughness
/// below [`crate::gltf::scene::GLOSSY_ROUGHNESS`] or a clearcoat; a scene
/// with none bakes no layer), `All` baked primitives, or `Off`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum VisibilityMode {
    #[default]
    Auto,
    All,
    Off,
}

/// Where the lightmap UVs come from (`--uv`, `--uv-set`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[non_exhaustive]
pub enum UvSource {
    /// Unwrap every baked placement into a new atlas (new TEXCOORD_n).
    #[default]
    Generate,
    /// Reuse `TEXCOORD_<set>` as it is.
    Existing(usize),
}

/// What a bake is: every setting that decides the output's bytes. Two
/// bakes of one input with equal `BakeSettings` write the same file (a
/// shard's fingerprint is this struct's JSON).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct BakeSettings {
    #[cfg_attr(feature = "cli", command(flatten))]
    pub size: AtlasSize,
    /// Empty texels around each chart
    #[cfg_attr(feature = "cli", arg(long, value_name = "P", default_value_t = Self::DEFAULT.padding))]
    pub padding: u32,
    /// Smallest chart width in texels: a generated chart narrower than this
    /// across its bounding rectangle is stretched to it (a strip that bends
    /// is first cut into straight pieces), so that bilinear lookups on it
    /// read texels of its own (0: charts keep their shape)
    #[cfg_attr(feature = "cli", arg(long, value_name = "W", default_value_t = Self::DEFAULT.min_chart_width))]
    #[serde(default)]
    pub min_chart_width: f32,
    /// Chart packing
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.packing))]
    pub packing: Packing,
    /// A --resolution page of at most 512 texels that the asked padding
    /// and chart width fill to under 35%: view also packs it with a texel
    /// of padding and charts a texel wide (and a page relaxed to no
    /// padding with a texel of padding), bakes each at a low budget and
    /// keeps the one whose lookups read the least error at surface points;
    /// rule keeps the asked options wherever they fit unstarved
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.ladder))]
    #[serde(default, skip_serializing_if = "Ladder::is_view")]
    pub ladder: Ladder,
    #[cfg_attr(feature = "cli", command(flatten))]
    pub uv: UvSource,
    /// Baking method: adaptive (ray counts per texel from the occluders'
    /// depth, an axis-aligned filter of the integrated values), mc
    /// (brute-force Monte Carlo) or sheared (also `filtered`: the sheared
    /// filter of Egan et al. 2011)
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.method))]
    pub method: Method,
    /// Monte Carlo (mc): rays per texel
    #[cfg_attr(feature = "cli", arg(long, value_name = "N", default_value_t = Self::DEFAULT.rays))]
    pub rays: u32,
    /// Options of the sheared method.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub sheared: ShearedOptions,
    /// Options of the adaptive method.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub adaptive: AdaptiveOptions,
    /// Occluders farther than this (world units) do not count [default: 0.1
    /// x the scene's bounding-box diagonal]
    #[cfg_attr(feature = "cli", arg(long, value_name = "D"))]
    pub max_distance: Option<f64>,
    /// Random seed: the same seed gives the same output on any thread count
    #[cfg_attr(feature = "cli", arg(long, value_name = "S", default_value_t = Self::DEFAULT.seed))]
    pub seed: u64,
    /// A material's existing occlusionTexture is kept or replaced by the
    /// baked AO
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.occlusion))]
    pub occlusion: OcclusionMode,
    /// Bake texels inside or behind single-sided geometry as they are
    /// instead of filling them from their nearest valid texel
    #[cfg_attr(feature = "cli", arg(long = "no-inside-fill", action = clap::ArgAction::SetFalse))]
    pub fill_inside: bool,
    /// The visibility layer (SH of the visibility itself), for normal maps
    /// and glossy lobes: auto bakes it for primitives whose material has a
    /// normalTexture, a roughnessFactor below 0.4 or a clearcoat
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.visibility))]
    pub visibility: VisibilityMode,
    /// SH order of the visibility layer: 3 (16 coefficients) or 2 (9)
    #[cfg_attr(feature = "cli", arg(long, value_name = "2|3", default_value_t = Self::DEFAULT.visibility_order))]
    pub visibility_order: u32,
    /// Smooth seams (vertex normals within 10 degrees, faces within 20
    /// degrees): stitched by least squares, or left as baked
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.seams))]
    pub seams: SeamMode,
    /// Texels fitted by least squares so that bilinear lookups at the
    /// chart's surface points match values traced there: fit, the border
    /// band (texels next to a chart's edge, and its gutter) and the cells
    /// inside charts the signal steps across; band, the border band alone;
    /// off, none (border texels hold their edge receivers' values)
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.border))]
    #[serde(default)]
    pub border: BorderMode,
    /// The lookup the texels are fitted for and the file records: bilinear
    /// (what a GPU's texture unit does), or bicubic (the cubic B-spline of
    /// Godot's, Bevy's and Unity's bicubic lightmap sampling), whose texels
    /// are fitted by least squares over the whole chart
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.filter))]
    #[serde(default, skip_serializing_if = "Filter::is_bilinear")]
    pub filter: Filter,
    /// How one page's texels are shared: uniform (the same texels per
    /// world unit everywhere), or signal (a pre-pass of 16 rays per
    /// triangle finds how close each mesh's occluders are, and meshes
    /// whose occlusion varies finely get up to 2x the density, open ones
    /// down to half)
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.texel_budget))]
    #[serde(default, skip_serializing_if = "TexelBudget::is_uniform")]
    pub texel_budget: TexelBudget,
    /// Where rays are traced: auto (a hardware GPU when one is found, else
    /// the CPU; a software Vulkan adapter such as lavapipe does not count),
    /// cpu, or gpu (any Vulkan adapter, software ones included; an error
    /// without one). The CPU's own triangle test settles the GPU's
    /// candidate hits, so the GPU answers the rays as the CPU does, and
    /// the CPU's threads trace beside it while it is busy
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Self::DEFAULT.device))]
    #[serde(default, skip_serializing_if = "Device::traces_on_cpu")]
    pub device: Device,
}

/// Where rays are traced (`--device`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Device {
    #[default]
    Auto,
    Cpu,
    Gpu,
}

impl Device {
    /// Whether a shard's fingerprint leaves it out: a bake recorded with
    /// `gpu` traced there (a shard records where it traced, see
    /// `job/shard.rs`), one without on the CPU.
    pub fn traces_on_cpu(&self) -> bool {
        *self != Device::Gpu
    }
}

/// Largest `--min-chart-width`: wider than the bilinear footprint (2
/// texels) plus the padding on each side buys nothing.
pub(crate) const MAX_MIN_CHART_WIDTH: f32 = 16.0;

impl BakeSettings {
    /// Every setting's default.
    pub const DEFAULT: BakeSettings = BakeSettings {
        size: AtlasSize::Resolution(DEFAULT_RESOLUTION),
        padding: 2,
        min_chart_width: 2.0,
        packing: Packing::Fast,
        ladder: Ladder::View,
        uv: UvSource::Generate,
        // Adaptive: measured against 256-ray Monte Carlo on five scenes
        // in the comparison table of `docs/method-adaptive.md`.
        method: Method::Adaptive,
        rays: DEFAULT_RAYS,
        sheared: ShearedOptions::DEFAULT,
        adaptive: AdaptiveOptions::DEFAULT,
        max_distance: None,
        seed: 0,
        occlusion: OcclusionMode::Keep,
        fill_inside: true,
        visibility: VisibilityMode::Auto,
        visibility_order: 3,
        seams: SeamMode::Stitch,
        border: BorderMode::Fit,
        filter: Filter::Bilinear,
        texel_budget: TexelBudget::Uniform,
        device: Device::Auto,
    };
}

impl Default for BakeSettings {
    fn default() -> Self {
        BakeSettings::DEFAULT
    }
}

/// How this run of a bake goes: nothing here changes an output byte.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct RunOptions {
    /// No progress bars and no warnings
    #[cfg_attr(feature = "cli", arg(short = 'q', long = "quiet", action = clap::ArgAction::SetFalse))]
    pub progress: bool,
    /// Write diagnostic PNG maps here: seams_before/after (AO jump at
    /// seams); adaptive: z_min, rays_per_texel, filter_sigma; sheared:
    /// brute_force_fraction, z_min, neighbours, sparse_ao (page k's in
    /// DIR/page-k)
    #[cfg_attr(feature = "cli", arg(long, value_name = "DIR"))]
    pub debug_dir: Option<PathBuf>,
    /// Also write DIR/lightmap.exr (float ao, sh0..sh8, v0..v15; page k's in
    /// DIR/page-k)
    #[cfg_attr(feature = "cli", arg(long = "exr", value_name = "DIR"))]
    pub exr_dir: Option<PathBuf>,
    /// Measure the engine-view error into --report: bilinear lookups of the
    /// written 8-bit textures at N surface points (spread over the pages by
    /// area) against a Monte Carlo reference there, by texel class (0: off)
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "N", default_value_t = 0, hide_default_value = true)
    )]
    pub engine_view_points: usize,
    /// Rays per point of the engine-view reference
    #[cfg_attr(feature = "cli", arg(long, value_name = "N", default_value_t = 512))]
    pub engine_view_rays: u32,
}

impl RunOptions {
    /// No progress bars, no files besides the output (tests and tools).
    pub const QUIET: RunOptions = RunOptions {
        progress: false,
        debug_dir: None,
        exr_dir: None,
        engine_view_points: 0,
        engine_view_rays: 512,
    };
}

impl Default for RunOptions {
    /// Progress bars (drawn only when stderr is a terminal), no diagnostic
    /// files.
    fn default() -> Self {
        RunOptions {
            progress: true,
            ..RunOptions::QUIET
        }
    }
}

/// How many texels' rays the adaptive method's filter averages into a
/// texel's value, as the border fit counts its noise: its mean filter width
/// is about a texel (Sponza 1024: 1.1), a footprint of about four texels.
/// Counted as `--quality` alone, a bake at 16 would fit no step cell and
/// lose its contact lines (Sponza 1024, engine view all 0.0162 -> 0.0227);
/// as four times it, the default keeps its step cells as they were.
pub const ADAPTIVE_NOISE_SHARE: u32 = 4;

impl BakeSettings {
    /// The Monte Carlo ray count whose noise the baked values carry, as
    /// the border fit reads it ([`crate::lightmap::border::step_span`]):
    /// `--method mc`'s rays; for the adaptive method, its `--quality` (or
    /// `--mean-rays` when set) times [`ADAPTIVE_NOISE_SHARE`], the texels
    /// its filter averages; `None` for the sheared filter.
    pub fn noise_rays(&self) -> Option<u32> {
        let adaptive = |rays: u32| Some(rays.saturating_mul(ADAPTIVE_NOISE_SHARE));
        match self.method {
            Method::Mc => Some(self.rays),
            Method::Adaptive if self.adaptive.mean_rays > 0 => adaptive(self.adaptive.mean_rays),
            Method::Adaptive => adaptive(self.adaptive.quality),
            Method::Sheared => None,
        }
    }

    /// The noise [`Self::noise_rays`] counts in the adaptive bake's first
    /// round, from which it finds the receivers the border fit sets
    /// ([`crate::bake::adaptive::FitSets`]): at most
    /// [`crate::bake::adaptive::fit_set_rays`] times
    /// [`ADAPTIVE_NOISE_SHARE`]. Read at the final values' noise instead,
    /// the first round's noise crossed more cells and the fit set more
    /// receivers than the final values fit (Sponza 1024: 41.0M rays
    /// against 50.4M, engine view all 0.0142 against 0.0140).
    pub fn first_round_noise_rays(&self) -> Option<u32> {
        let first = crate::bake::adaptive::fit_set_rays(&self.adaptive);
        let first = first.saturating_mul(ADAPTIVE_NOISE_SHARE);
        self.noise_rays().map(|n| n.min(first))
    }

    /// Checks every setting that can be checked without the scene, once
    /// per bake: [`crate::bake()`] and [`crate::job::bake_shard`] call it before
    /// they read the input, so a bad option fails at once;
    /// [`crate::job::Level::new`] calls it for a level built directly.
    pub fn validate(&self) -> Result<()> {
        if self.device == Device::Gpu && !cfg!(feature = "gpu") {
            return Err(Error::option(
                "device",
                "gpu: this build has no GPU backend (build with --features gpu)",
            ));
        }
        // Refused whichever method reads it.
        if self.rays == 0 {
            return Err(Error::option("rays", "must be at least 1"));
        }
        match self.method {
            Method::Mc => {}
            Method::Sheared => self.sheared.validate()?,
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
        if !(self.min_chart_width.is_finite()
            && (0.0..=MAX_MIN_CHART_WIDTH).contains(&self.min_chart_width))
        {
            return Err(Error::option(
                "min_chart_width",
                format!(
                    "{} is outside 0..={MAX_MIN_CHART_WIDTH}",
                    self.min_chart_width
                ),
            ));
        }
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

#[cfg(feature = "cli")]
mod flags;

/// Memory estimate of baking a `width` x `height` atlas with settings `s`
/// (every texel counted as covered: the worst case): the larger of the bake
/// stage (receivers, results and the method's working arrays) and the
/// output stages (with what the method keeps for the report and debug
/// maps). Measured peak RSS, Cornell box at 4096 x 3594, 16 rays: 2.09 GB
/// (`mc`) and 2.24 GB (`adaptive`), under this estimate's 2.36 and 2.71 GB.
pub fn estimated_bytes(width: u32, height: u32, s: &BakeSettings) -> u64 {
    estimated_bytes_with(width, height, s, s.visibility == VisibilityMode::All)
}

/// Per atlas texel, what the visibility layer adds to either stage: its
/// result (16 floats) and, in the bake, the filter's row pass and shares
/// (2 x 68 B); in the output stages, the float layer (64 B) beside it.
pub(crate) const VISIBILITY_BYTES_PER_TEXEL: u64 = 64 + 2 * 68;

/// [`estimated_bytes`], knowing whether the scene bakes the visibility
/// layer (`--visibility auto` decides from its materials).
pub(crate) fn estimated_bytes_with(width: u32, height: u32, s: &BakeSettings, layer: bool) -> u64 {
    let texels = width as u64 * height as u64;
    let layer = if layer { VISIBILITY_BYTES_PER_TEXEL } else { 0 };
    let (working, kept) = match s.method {
        Method::Mc => (0, 0),
        // Counted as held throughout (not measured).
        Method::Sheared => (s.sheared.bytes_per_texel(), s.sheared.bytes_per_texel()),
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
            let s = BakeSettings {
                method,
                ..BakeSettings::default()
            };
            let need = estimated_bytes(8192, 8192, &s);
            assert!(need <= MAX_BAKE_BYTES, "{method:?}: {need}");
            // ... and 16000^2 does not.
            assert!(estimated_bytes(16000, 16000, &s) > MAX_BAKE_BYTES);
        }
    }

    #[test]
    fn the_estimate_is_the_larger_stage_not_their_sum() {
        let mc = BakeSettings {
            method: Method::Mc,
            ..BakeSettings::default()
        };
        let adaptive = BakeSettings {
            method: Method::Adaptive,
            ..BakeSettings::default()
        };
        let per_texel = |s: &BakeSettings| estimated_bytes(1000, 1000, s) / 1_000_000;
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
