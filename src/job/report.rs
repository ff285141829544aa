//! The `--report` JSON: what a bake did, stage by stage and page by page.
//!
//! In: the level and what each baked page kept ([`PageDone`]). Out:
//! [`Report`] and its parts ([`level_report`]), serialized by the CLI's
//! `--report`.

use super::across::AcrossReport;
use super::level::Level;
use super::page::{BakePasses, PageOutput};
use super::reuse::ReuseReport;
use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, ShearedStats};
use crate::encode::Encoded;
use crate::gltf::Scene;
use crate::gltf::container::glb_chunks;
use crate::job::settings::{BakeSettings, Method};
use crate::lightmap::BorderReport;
use crate::lightmap::engine_view::{self, EngineView};
use crate::lightmap::seams::SeamReport;
use crate::shard::Shard;
use crate::stage::{StageTime, StageTimer, total};
use serde::Serialize;
use serde_json::Value;
use std::path::Path;

/// A page baked and encoded, and its figures for the report (what a bake
/// keeps of a page once its working set is freed).
#[derive(Clone, Debug)]
pub struct PageDone {
    pub page: u32,
    pub encoded: Encoded,
    pub texels: usize,
    pub texels_inside: usize,
    pub rays: u64,
    pub visibility_rays: Option<u64>,
    pub adaptive: Option<AdaptiveReport>,
    pub sheared: Option<ShearedReport>,
    pub seams: Option<SeamReport>,
    pub border: Option<BorderReport>,
    pub engine_view: Option<EngineView>,
    /// Seconds of the method's passes.
    pub pass_seconds: f64,
    /// A page an edit reaches baked whole: why not texel by texel.
    pub whole: Option<String>,
}

impl PageDone {
    /// What the report keeps of page `page`: its receivers' count, the
    /// method's figures and the encoded images.
    pub fn new(
        page: u32,
        texels: usize,
        inside: &[bool],
        passes: &BakePasses,
        out: &PageOutput,
        s: &BakeSettings,
    ) -> PageDone {
        PageDone {
            page,
            encoded: out.encoded.clone(),
            texels,
            texels_inside: inside.iter().filter(|&&x| x).count(),
            rays: passes.bake.rays,
            visibility_rays: passes.bake.visibility.as_ref().map(|v| v.rays),
            adaptive: passes
                .adaptive_stats
                .as_ref()
                .map(|a| AdaptiveReport::new(&s.adaptive, a)),
            sheared: passes
                .sheared_stats
                .as_ref()
                .map(|f| ShearedReport::new(&s.sheared, f)),
            seams: out.seams,
            border: out.border,
            engine_view: out.engine_view,
            pass_seconds: total(&passes.stages),
            whole: None,
        }
    }
}

/// The `--report` JSON.
#[derive(Clone, Debug, Default, Serialize)]
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
    pub shard: Option<Shard>,
    pub charts: u32,
    pub utilization: f32,
    /// A small page's options as the engine view measured them, and the
    /// one kept (`--ladder view`, where it chose among several).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ladder: Option<super::level::ladder::LadderReport>,
    pub texels: usize,
    /// Texels inside or behind geometry, filled from their nearest valid
    /// texel ([`crate::bake::validity`]).
    pub texels_inside: usize,
    pub baked_primitives: usize,
    pub occluder_triangles: usize,
    /// Monte Carlo rays per texel (the `rays` setting; 0 for the others).
    pub rays_per_texel: u32,
    pub rays_cast: u64,
    /// Rays cast per texel, all passes together.
    pub rays_per_texel_total: f64,
    /// Sheared method only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sheared: Option<ShearedReport>,
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
    /// The border fit (`--border fit`): points fitted, their rays and the
    /// mean AO gap between lookups and traced values before and after, with
    /// one page; per page in `pages`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub border: Option<BorderReport>,
    /// The seams across pages, solved together once every page is encoded
    /// ([`super::across`]; bakes in one process).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_page_seams: Option<AcrossReport>,
    /// The error an engine shows (`--engine-view-points`): bilinear lookups
    /// of the written textures at surface points against a reference, by
    /// texel class, over every baked page; per page in `pages`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub engine_view: Option<EngineView>,
    /// Rays cast over the seconds of the method's passes.
    pub rays_per_second: f64,
    pub max_distance: f64,
    pub seed: u64,
    pub threads: usize,
    /// Where the rays were traced (`--device`): the GPU adapter, if one
    /// answered the ray batches.
    pub backend: super::device::Backend,
    /// Every stage in order, each timed once (`sparse pass` and `filter
    /// pass` for the sheared method, `trace` for Monte Carlo).
    pub stages: Vec<StageTime>,
    /// The stages' seconds added up.
    pub total_seconds: f64,
    pub warnings: Vec<String>,
    /// `--reuse PREV`: whether PREV was taken, and why not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reuse: Option<ReuseReport>,
}

/// One atlas page in the report.
#[derive(Clone, Debug, Default, Serialize)]
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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub border: Option<BorderReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub engine_view: Option<EngineView>,
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

/// The sheared method's figures in the report.
#[derive(Clone, Debug, Serialize)]
pub struct ShearedReport {
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
    /// Fraction of texels in contact filtered along a contact line
    /// (`bake::adaptive::line`).
    pub texels_on_contact_lines: f64,
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
        self.texels_on_contact_lines =
            mean(self.texels_on_contact_lines, other.texels_on_contact_lines);
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
            texels_on_contact_lines: a.contact_lines as f64 / n,
        }
    }
}

impl ShearedReport {
    /// Adds another page's figures: counts add, shares and means are
    /// weighted by texels (`n` here, `n_other` there).
    pub fn merge(&mut self, n: usize, other: &ShearedReport, n_other: usize) {
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

    pub(super) fn new(s: &sheared::ShearedOptions, f: &ShearedStats) -> ShearedReport {
        let texels = f.brute_fraction.len().max(1) as f64;
        ShearedReport {
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

/// The report of a level from its baked pages (`done`: every page, or a
/// shard's).
pub fn level_report(
    level: &Level,
    done: &[PageDone],
    s: &BakeSettings,
    warnings: Vec<String>,
) -> Report {
    let texels: usize = done.iter().map(|d| d.texels).sum();
    let rays: u64 = done.iter().map(|d| d.rays).sum();
    let pass_seconds: f64 = done.iter().map(|d| d.pass_seconds).sum();
    let chart_texels = level.atlas.page_areas();
    let triangles = level.atlas.page_triangles();
    let pages = level
        .atlas
        .pages
        .iter()
        .enumerate()
        .map(|(k, size)| {
            let d = done.iter().find(|d| d.page == k as u32);
            PageReport {
                page: k as u32,
                width: size.width,
                height: size.height,
                chart_texels: chart_texels[k],
                triangles: triangles[k],
                baked: d.is_some(),
                texels: d.map_or(0, |d| d.texels),
                texels_inside: d.map_or(0, |d| d.texels_inside),
                rays_cast: d.map_or(0, |d| d.rays),
                seams: d.and_then(|d| d.seams),
                border: d.and_then(|d| d.border),
                engine_view: d.and_then(|d| d.engine_view),
            }
        })
        .collect();
    let adaptive = merged(
        done.iter()
            .filter_map(|d| Some((d.adaptive.as_ref()?, d.texels))),
        AdaptiveReport::merge,
    );
    let sheared = merged(
        done.iter()
            .filter_map(|d| Some((d.sheared.as_ref()?, d.texels))),
        ShearedReport::merge,
    );
    let visibility_rays: Option<u64> = done.iter().map(|d| d.visibility_rays).sum();
    Report {
        input: String::new(),
        method: s.method,
        atlas_width: level.atlas.width,
        atlas_height: level.atlas.height,
        texel_density: level.texel_density(),
        pages,
        shard: None,
        charts: level.atlas.charts,
        utilization: level.atlas.utilization,
        ladder: level.ladder.clone(),
        texels,
        texels_inside: done.iter().map(|d| d.texels_inside).sum(),
        baked_primitives: level.geometry.receivers.len(),
        occluder_triangles: level.tracer.triangle_count(),
        rays_per_texel: if s.method == Method::Mc { s.rays } else { 0 },
        rays_cast: rays,
        rays_per_texel_total: rays as f64 / texels.max(1) as f64,
        sheared,
        adaptive,
        visibility: visibility_rays.map(|v| VisibilityReport {
            order: s.visibility_order,
            primitives: level.visibility_meshes.iter().filter(|&&m| m).count(),
            rays: v,
            rays_per_texel: v as f64 / texels.max(1) as f64,
        }),
        engine_view: engine_view::merge(
            &done
                .iter()
                .filter_map(|d| d.engine_view)
                .collect::<Vec<_>>(),
        ),
        seams: match done {
            [one] if level.page_count() == 1 => one.seams,
            _ => None,
        },
        border: match done {
            [one] if level.page_count() == 1 => one.border,
            _ => None,
        },
        cross_page_seams: None,
        rays_per_second: if pass_seconds > 0.0 {
            rays as f64 / pass_seconds
        } else {
            0.0
        },
        max_distance: level.max_distance_world,
        seed: s.seed,
        threads: rayon::current_num_threads(),
        backend: level.backend.with_rays(&level.tracer),
        stages: Vec::new(),
        total_seconds: 0.0,
        warnings,
        reuse: None,
    }
}

/// Pages' figures (each with its texels) merged into one by `merge(acc,
/// texels so far, next, its texels)`; `None` without any.
fn merged<'a, T: Clone + 'a>(
    parts: impl Iterator<Item = (&'a T, usize)>,
    merge: impl Fn(&mut T, usize, &T, usize),
) -> Option<T> {
    let mut acc: Option<(T, usize)> = None;
    for (part, n) in parts {
        match &mut acc {
            Some((a, total)) => {
                merge(a, *total, part, n);
                *total += n;
            }
            None => acc = Some((part.clone(), n)),
        }
    }
    acc.map(|(a, _)| a)
}

/// The report of a run that took PREV as its output: the atlas's size
/// and pages as PREV's extension records them, no texel baked.
pub(crate) fn reused_report(
    prev_bytes: &[u8],
    prev: &Path,
    input: &Path,
    scene: &Scene,
    s: &BakeSettings,
    timer: StageTimer,
) -> Report {
    let ext = glb_chunks(prev_bytes)
        .ok()
        .and_then(|(json, _)| serde_json::from_slice::<Value>(json).ok())
        .and_then(|j| j.pointer("/extensions/AOBAKE_lightmap").cloned())
        .unwrap_or_default();
    let size = |v: &Value| -> (u32, u32) {
        let n = |i: usize| v.get(i).and_then(Value::as_u64).unwrap_or(0) as u32;
        (n(0), n(1))
    };
    let (atlas_width, atlas_height) = size(&ext["resolution"]);
    let pages: Vec<(u32, u32)> = match ext.get("pages").and_then(Value::as_array) {
        Some(p) => p.iter().map(size).collect(),
        None => vec![(atlas_width, atlas_height)],
    };
    Report {
        input: input.display().to_string(),
        method: s.method,
        atlas_width,
        atlas_height,
        pages: (pages.iter().enumerate())
            .map(|(k, &(width, height))| PageReport {
                page: k as u32,
                width,
                height,
                ..PageReport::default()
            })
            .collect(),
        max_distance: ext
            .get("maxDistance")
            .and_then(Value::as_f64)
            .unwrap_or(0.0),
        seed: s.seed,
        threads: rayon::current_num_threads(),
        total_seconds: timer.total(),
        stages: timer.into_merged_stages(),
        warnings: scene.warnings.clone(),
        reuse: Some(ReuseReport {
            prev: prev.display().to_string(),
            reused: true,
            carried: false,
            full_bake: None,
            nodes: None,
            texels_baked: 0,
            texels_dirty: 0,
            pages_reused: pages.len(),
            pages_whole: Vec::new(),
        }),
        ..Report::default()
    }
}
