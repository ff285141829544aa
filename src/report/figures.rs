//! What a sweep is told and what it measured: the types every other file
//! of the report reads.
//!
//! In: nothing (the bottom of the folder). Out: [`ReportSettings`],
//! [`RunFigures`], [`EqualError`], [`StabilityRow`], [`SweepReport`] (the
//! `report.json`) and [`Sweep`].

use super::budget::{Budget, DEFAULT_BUDGETS, parse_budgets};
use super::metrics::ErrorStats;
use crate::atlas::Receivers;
use crate::error::{Error, Result};
use crate::job::Method;
use crate::stage::StageTime;
use serde::Serialize;

/// What `aobake report` is told. Each flag's doc comment is its `--help`
/// line.
#[derive(Clone, Debug, clap::Args)]
pub struct ReportSettings {
    /// Atlas page edge in texels
    #[arg(long, value_name = "N", default_value_t = 512)]
    pub resolution: u32,
    /// Rays per texel of the Monte Carlo reference
    #[arg(long, value_name = "N", default_value_t = 2048)]
    pub reference_rays: u32,
    /// The runs (`--budgets`: [`Budget::label`]s, comma-separated).
    #[arg(
        long,
        value_name = "LIST",
        default_value = DEFAULT_BUDGETS,
        value_parser = budget_list,
        help = "Runs, comma-separated: mc:RAYS, adaptive:QUALITY[:PRE_RAYS:MAX_RAYS], \
                adaptive-mean:MEAN_RAYS[:PRE_RAYS:MAX_RAYS] and \
                sheared:SPARSE_RAYS:GATHER_RADIUS[:CELL_RAYS[:OMEGA_V[:MIN_WEIGHT]]]"
    )]
    pub budgets: ::std::vec::Vec<Budget>,
    /// Seed of the runs (the reference uses another one)
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub seed: u64,
    /// Occluders farther than this (world units) do not count [default: 0.1
    /// x the scene's bounding-box diagonal]
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Monte Carlo rays of the 1e-4 and 1e4 scale-stability bakes (0: skip
    /// them)
    #[arg(long, value_name = "N", default_value_t = 64)]
    pub stability_rays: u32,
    /// Surface points of the engine-view error (bilinear lookups of each
    /// run's written textures against a --reference-rays reference there,
    /// by texel class; 0: skip it)
    #[arg(long, value_name = "N", default_value_t = 20000)]
    pub engine_view_points: usize,
    /// Also run each method's default settings if `budgets` lacks them
    /// (their error maps are drawn and 256-ray Monte Carlo sets the
    /// equal-error target).
    #[arg(skip = true)]
    pub include_defaults: bool,
    /// No progress bar and no summary
    #[arg(short = 'q', long = "quiet", action = clap::ArgAction::SetFalse)]
    pub progress: bool,
}

/// `--budgets` as the command line parses it: the list, or why an item is
/// wrong.
fn budget_list(text: &str) -> std::result::Result<Vec<Budget>, String> {
    parse_budgets(text).map_err(|e| match e {
        Error::Option { detail, .. } => detail.trim_start_matches(": ").to_string(),
        e => e.to_string(),
    })
}

impl Default for ReportSettings {
    /// The command line's defaults (written once, on the fields above).
    fn default() -> Self {
        #[derive(clap::Parser)]
        struct Flags {
            #[command(flatten)]
            settings: ReportSettings,
        }
        <Flags as clap::Parser>::parse_from(["aobake report"]).settings
    }
}

impl ReportSettings {
    /// Checks the report's own settings (each run's bake settings are
    /// checked by [`crate::job::BakeSettings::validate`]).
    pub fn validate(&self) -> Result<()> {
        if self.reference_rays == 0 {
            return Err(Error::option("reference_rays", "must be at least 1"));
        }
        Ok(())
    }
}

/// The figures of one run against the reference.
#[derive(Clone, Debug, Serialize)]
pub struct RunFigures {
    pub label: String,
    pub method: Method,
    /// Whether these are the method's default settings (error maps drawn).
    pub default_settings: bool,
    /// Wall time of each of the run's own passes.
    pub passes: Vec<StageTime>,
    pub bake_seconds: f64,
    /// This run's output stages (border fit, seams, dilate, encode), whose
    /// stages follow its passes' in `passes`.
    pub output_seconds: f64,
    /// Shared stages plus this run's passes and output stages.
    pub end_to_end_seconds: f64,
    pub rays_cast: u64,
    pub rays_per_texel: f64,
    pub ao: ErrorStats,
    /// RMSE of the SH coefficients per band L0, L1, L2, and over all nine.
    pub sh_rmse_band: [f64; 3],
    pub sh_rmse: f64,
    /// Filtered only: fractions of all hemisphere cells.
    pub cells_filtered: Option<f64>,
    pub cells_brute_forced: Option<f64>,
    pub cells_brute_contact: Option<f64>,
    /// Of all cells: brute-forced because no neighbour ray hit in them and
    /// too few looked through them to trust them open.
    pub cells_brute_no_hit: Option<f64>,
    /// The error an engine shows: the run's written textures looked up
    /// bilinearly at surface points against the points' reference, by
    /// texel class (`--engine-view-points`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub engine_view: Option<crate::lightmap::engine_view::EngineView>,
}

/// The equal-error comparison at the error of 256-ray Monte Carlo.
#[derive(Clone, Debug, Serialize)]
pub struct EqualError {
    /// AO RMSE of 256-ray Monte Carlo (measured, or interpolated in log-log
    /// between the nearest Monte Carlo runs).
    pub target_ao_rmse: f64,
    /// End-to-end seconds at which Monte Carlo's runs reach it.
    pub mc_seconds: Option<f64>,
    /// The same for each other method swept (sheared, adaptive).
    pub methods: Vec<MethodAtError>,
}

/// Where one method's runs reach the equal-error target.
#[derive(Clone, Debug, Serialize)]
pub struct MethodAtError {
    pub method: Method,
    /// End-to-end seconds at the target (log-log between its runs).
    pub seconds: Option<f64>,
    /// mc_seconds / seconds (> 1: faster than Monte Carlo).
    pub speedup: Option<f64>,
    /// Smallest AO RMSE any of its runs reached.
    pub best_ao_rmse: Option<f64>,
}

impl EqualError {
    /// The entry of `method`, if it was swept.
    pub fn of(&self, method: Method) -> Option<&MethodAtError> {
        self.methods.iter().find(|m| m.method == method)
    }

    /// End-to-end seconds at which `method`'s runs reach the target
    /// (Monte Carlo's own, or a swept method's), where a plot crosses its
    /// curve.
    pub fn crossing(&self, method: Method) -> Option<f64> {
        match method {
            Method::Mc => self.mc_seconds,
            m => self.of(m).and_then(|m| m.seconds),
        }
    }
}

/// One row of the scale-stability table.
#[derive(Clone, Debug, Serialize)]
pub struct StabilityRow {
    pub scale: f64,
    pub max_distance_world: f64,
    /// AO of the scaled scene against the unscaled one (same settings and seed).
    pub ao_rmse_difference: f64,
    pub ao_max_difference: f64,
    /// AO RMSE of the unscaled bake against the reference: its Monte Carlo noise.
    pub monte_carlo_noise_rmse: f64,
    pub same_within_noise: bool,
}

/// Everything `aobake report` measured.
#[derive(Clone, Debug, Serialize)]
pub struct SweepReport {
    pub aobake_version: &'static str,
    pub input: String,
    pub cores: usize,
    pub threads: usize,
    pub resolution: u32,
    pub atlas_width: u32,
    pub atlas_height: u32,
    pub texels: usize,
    /// Texels inside or behind geometry: the output fills them from their
    /// nearest valid texel, so no run's error counts them.
    pub texels_inside: usize,
    pub charts: u32,
    pub occluder_triangles: usize,
    pub max_distance_world: f64,
    pub seed: u64,
    pub reference_rays: u32,
    pub reference_seed: u64,
    pub reference_seconds: f64,
    /// Stages every run shares (load, unwrap, rasterize, BVH, validity,
    /// the write of the reference's file), measured once.
    pub shared_stages: Vec<StageTime>,
    pub shared_seconds: f64,
    pub runs: Vec<RunFigures>,
    pub equal_error: Option<EqualError>,
    /// The same comparison on the engine view's AO RMSE over all surface
    /// points (with `--engine-view-points`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub equal_engine_view: Option<EqualError>,
    pub stability: Vec<StabilityRow>,
    /// The reference bake's smooth seams before and after stitching (the
    /// output stages' `seams`; each run times its own).
    pub reference_seams: Option<crate::lightmap::seams::SeamReport>,
    /// Files written next to report.json.
    pub files: Vec<String>,
}

/// Everything a sweep produced: the figures and the per-texel values the
/// maps are drawn from.
pub struct Sweep {
    pub report: SweepReport,
    pub receivers: Receivers,
    pub reference_ao: Vec<f32>,
    /// (label, AO) of each method's default run.
    pub default_ao: Vec<(String, Vec<f32>)>,
    /// Brute-force fraction per receiver of the default filtered run.
    pub brute_fraction: Option<Vec<f32>>,
}
