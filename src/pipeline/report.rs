//! The `--report` JSON: what a bake did, stage by stage and page by page.
//!
//! In: the figures the pipeline's stages return. Out: [`Report`] and its
//! parts, serialized by the CLI's `--report`.

use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, FilterStats};
use crate::seams::SeamReport;
use crate::settings::Method;
use crate::stage::StageTime;
use serde::Serialize;

/// The `--report` JSON.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub input: String,
    pub method: Method,
    /// The largest page's size (the only page's, with one).
    pub atlas_width: u32,
    pub atlas_height: u32,
    /// Texels per world unit (the asked `--texel-density`, or what the
    /// resolution's densest fit gave).
    pub texel_density: f64,
    /// Every page of the atlas, and what this run baked of it (all pages,
    /// or a shard's).
    pub pages: Vec<PageReport>,
    /// `--shard I/N`: this run baked only shard I's pages.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<crate::shard::Shard>,
    pub charts: u32,
    pub utilization: f32,
    pub texels: usize,
    /// Texels inside or behind geometry, filled from their nearest valid
    /// texel ([`crate::bake::validity`]).
    pub texels_inside: usize,
    pub baked_primitives: usize,
    pub occluder_triangles: usize,
    /// Monte Carlo rays per texel (the `rays` setting; 0 for filtered).
    pub rays_per_texel: u32,
    pub rays_cast: u64,
    /// Rays cast per texel, all passes together.
    pub rays_per_texel_total: f64,
    /// Filtered method only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub filter: Option<FilterReport>,
    /// Adaptive method only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveReport>,
    /// The visibility layer, when baked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub visibility: Option<VisibilityReport>,
    /// Seam count and length, the jumps before and after stitching, and
    /// the solve (`--seams stitch`), with one page; per page in `pages`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<SeamReport>,
    /// Rays cast over the seconds of the method's passes.
    pub rays_per_second: f64,
    pub max_distance: f64,
    pub seed: u64,
    pub threads: usize,
    /// Every stage in order, each timed once (`sparse pass` and `filter
    /// pass` for the filtered method, `trace` for Monte Carlo).
    pub stages: Vec<StageTime>,
    /// The stages' seconds added up.
    pub total_seconds: f64,
    pub warnings: Vec<String>,
}

/// One atlas page in the report.
#[derive(Clone, Debug, Serialize)]
pub struct PageReport {
    pub page: u32,
    pub width: u32,
    pub height: u32,
    /// Texels its charts cover (their UV area), known before baking.
    pub chart_texels: f64,
    /// Triangles on it.
    pub triangles: usize,
    /// Whether this run baked it (false: another shard's).
    pub baked: bool,
    /// Receivers (covered texels); 0 when not baked here.
    pub texels: usize,
    pub texels_inside: usize,
    pub rays_cast: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<SeamReport>,
}

/// The visibility layer's figures in the report.
#[derive(Clone, Debug, Serialize)]
pub struct VisibilityReport {
    /// SH order written (3: 16 coefficients, 2: 9).
    pub order: u32,
    /// Baked primitives that carry the layer.
    pub primitives: usize,
    /// Uniform visibility rays cast (not in `rays_cast`).
    pub rays: u64,
    pub rays_per_texel: f64,
}

/// The filtered method's figures in the report.
#[derive(Clone, Debug, Serialize)]
pub struct FilterReport {
    pub sparse_rays_per_texel: u32,
    pub gather_radius_texels: f32,
    pub omega_v_max: f32,
    pub cell_rays: u32,
    pub sparse_rays: u64,
    pub second_pass_rays: u64,
    /// Fractions of all hemisphere cells (64 per texel).
    pub cells_filtered: f64,
    pub cells_brute_forced: f64,
    /// Of all cells: brute-forced by the paper's bandlimit test (occluder
    /// closer than 2 Omega_v texel footprints).
    pub cells_brute_contact: f64,
    /// Of all cells: brute-forced with no occluder seen in them, because
    /// too few neighbour rays looked through them to trust them open. The
    /// rest of `cells_brute_forced` had hits but too little filter weight.
    pub cells_brute_no_hit: f64,
    pub cells_open: f64,
    /// Fraction of texels whose whole neighbourhood saw no occluder.
    pub texels_open: f64,
    pub mean_neighbours: f64,
}

/// The adaptive method's figures in the report.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    pub pre_rays_per_texel: u32,
    /// The quality setting (Monte Carlo rays whose error it aims at).
    pub quality: u32,
    /// The fixed mean rays setting (0: from quality).
    pub mean_rays_setting: u32,
    /// Mean rays per texel cast.
    pub mean_rays_per_texel: f64,
    pub pre_pass_rays: u64,
    pub adaptive_rays: u64,
    /// (rays per texel, texels) for every count used.
    pub rays_per_texel_histogram: Vec<(u32, usize)>,
    /// Fraction of texels filtered (sigma of at least half a texel).
    pub texels_filtered: f64,
    pub mean_sigma_texels: f64,
}

impl AdaptiveReport {
    /// Adds another page's figures: counts add, means are weighted by
    /// texels (`n` here, `n_other` there).
    pub fn merge(&mut self, n: usize, other: &AdaptiveReport, n_other: usize) {
        let (a, b) = (n as f64, n_other as f64);
        let mean = |x: f64, y: f64| (x * a + y * b) / (a + b).max(1.0);
        self.mean_rays_per_texel = mean(self.mean_rays_per_texel, other.mean_rays_per_texel);
        self.texels_filtered = mean(self.texels_filtered, other.texels_filtered);
        self.mean_sigma_texels = mean(self.mean_sigma_texels, other.mean_sigma_texels);
        self.pre_pass_rays += other.pre_pass_rays;
        self.adaptive_rays += other.adaptive_rays;
        let mut h: std::collections::BTreeMap<u32, usize> =
            self.rays_per_texel_histogram.iter().copied().collect();
        for &(r, c) in &other.rays_per_texel_histogram {
            *h.entry(r).or_default() += c;
        }
        self.rays_per_texel_histogram = h.into_iter().collect();
    }

    pub(super) fn new(o: &adaptive::AdaptiveOptions, a: &AdaptiveStats) -> AdaptiveReport {
        let n = a.rays.len().max(1) as f64;
        let filtered = a.sigma_texels.iter().filter(|&&s| s > 0.0);
        AdaptiveReport {
            pre_rays_per_texel: o.pre_rays,
            quality: o.quality,
            mean_rays_setting: o.mean_rays,
            mean_rays_per_texel: a.rays.iter().map(|&r| r as f64).sum::<f64>() / n,
            pre_pass_rays: a.pre_rays,
            adaptive_rays: a.adaptive_rays,
            rays_per_texel_histogram: a.ray_histogram(),
            texels_filtered: filtered.clone().count() as f64 / n,
            mean_sigma_texels: filtered.map(|&s| s as f64).sum::<f64>() / n,
        }
    }
}

impl FilterReport {
    /// Adds another page's figures: counts add, shares and means are
    /// weighted by texels (`n` here, `n_other` there).
    pub fn merge(&mut self, n: usize, other: &FilterReport, n_other: usize) {
        let (a, b) = (n as f64, n_other as f64);
        let mean = |x: f64, y: f64| (x * a + y * b) / (a + b).max(1.0);
        self.sparse_rays += other.sparse_rays;
        self.second_pass_rays += other.second_pass_rays;
        self.cells_filtered = mean(self.cells_filtered, other.cells_filtered);
        self.cells_brute_forced = mean(self.cells_brute_forced, other.cells_brute_forced);
        self.cells_brute_contact = mean(self.cells_brute_contact, other.cells_brute_contact);
        self.cells_brute_no_hit = mean(self.cells_brute_no_hit, other.cells_brute_no_hit);
        self.cells_open = mean(self.cells_open, other.cells_open);
        self.texels_open = mean(self.texels_open, other.texels_open);
        self.mean_neighbours = mean(self.mean_neighbours, other.mean_neighbours);
    }

    pub(super) fn new(s: &sheared::ShearedOptions, f: &FilterStats) -> FilterReport {
        let texels = f.brute_fraction.len().max(1) as f64;
        FilterReport {
            sparse_rays_per_texel: s.sparse_rays,
            gather_radius_texels: s.gather_radius,
            omega_v_max: s.omega_v_max,
            cell_rays: s.cell_rays,
            sparse_rays: f.sparse_rays,
            second_pass_rays: f.brute_rays,
            cells_filtered: f.cell_share(f.cells_filtered),
            cells_brute_forced: f.cell_share(f.cells_brute),
            cells_brute_contact: f.cell_share(f.cells_contact),
            cells_brute_no_hit: f.cell_share(f.cells_no_hit),
            cells_open: f.cell_share(f.cells_open),
            texels_open: f.receivers_open as f64 / texels,
            mean_neighbours: f.neighbours.iter().map(|&n| n as f64).sum::<f64>() / texels,
        }
    }
}
