//! The pipeline: load -> unwrap into pages -> BVH, then page by page
//! rasterize -> validity -> bake -> dilate -> seams -> encode, and last
//! write, each stage timed on one [`StageTimer`] (a stage's laps over the
//! pages added up in the report). The adaptive method has no validity
//! stage: its pre-pass makes the same test on the same rays.
//!
//! In: a loaded [`Scene`] (or a path) and validated [`Settings`]. Out: a
//! [`Baked`] holding the output GLB bytes and page 0's intermediates (for
//! tests and reports), or with [`run`] the output file and its [`Report`].
//! Only one page's working set lives at a time: a page's receivers and
//! arrays are freed once it is encoded ([`level`]).
//!
//! - [`level`]: what every page shares ([`Level`]) and one page prepared
//!   ([`Prepared`]);
//! - [`page`](mod@page): the method's passes, the output stages of a page
//!   and the write-back of all pages;
//! - [`report`](mod@report): the `--report` JSON.
//!
//! [`prepare`], [`bake_prepared`] and [`output`] are the three parts the
//! report (`aobake report`) reuses to bake one page many times.

pub mod level;
pub mod page;
pub mod report;

pub use level::{Level, Prepared, page_seed, prepare, prepare_level};
pub use page::{BakePasses, PageOutput, bake_prepared, output_page, write};
pub use report::{AdaptiveReport, FilterReport, PageReport, Report, VisibilityReport};

use crate::atlas::{Atlas, Receivers};
use crate::bake::Bake;
use crate::bake::adaptive::AdaptiveStats;
use crate::bake::sheared::FilterStats;
use crate::encode::{Encoded, Lightmap};
use crate::error::{Error, Result};
use crate::file;
use crate::geometry::BakeGeometry;
use crate::gltf::{self, Scene};
use crate::seams::SeamReport;
use crate::settings::{Method, Settings};
use crate::stage::{StageTimer, total};
use std::path::Path;
use std::sync::Arc;

/// Every product of a bake: the output and page 0's intermediates (all of
/// a one-page bake).
pub struct Baked {
    pub geometry: Arc<BakeGeometry>,
    /// Every page's charts.
    pub atlas: Atlas,
    pub receivers: Receivers,
    pub bake: Bake,
    /// Filtered method only.
    pub filter_stats: Option<FilterStats>,
    /// Adaptive method only.
    pub adaptive_stats: Option<AdaptiveStats>,
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub report: Report,
}

/// What the output stages produced for a one-page bake.
pub struct Output {
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub warnings: Vec<String>,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
}

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
    pub filter: Option<FilterReport>,
    pub seams: Option<SeamReport>,
    /// Seconds of the method's passes.
    pub pass_seconds: f64,
}

/// Bakes `input` into `output` (written atomically; `input` is never touched).
pub fn run(input: &Path, output: &Path, settings: &Settings) -> Result<Report> {
    check_output(input, output)?;
    let mut timer = StageTimer::new();
    let scene = gltf::load(input)?;
    timer.lap("load");
    let level = prepare_level(&scene, settings, &mut timer)?;
    let pages: Vec<u32> = (0..level.page_count()).collect();
    let done = bake_pages(
        &scene,
        &level,
        &pages,
        settings,
        &mut timer,
        &mut |_, _, _| {},
    )?;
    let encoded: Vec<&Encoded> = done.iter().map(|d| &d.encoded).collect();
    let out_dir = file::parent_dir(output);
    let (glb, warnings) = write(
        &scene,
        &level,
        &encoded,
        settings,
        Some(out_dir),
        &mut timer,
    )?;
    file::write_atomic(output, &glb)?;
    timer.lap("save");
    let mut report = level_report(&level, &done, settings, warnings);
    report.input = input.display().to_string();
    Ok(finish_report(report, timer))
}

/// Refuses an output path that is the input file.
pub fn check_output(input: &Path, output: &Path) -> Result<()> {
    if file::same_file(input, output) {
        return Err(Error::option_conflict(
            "output",
            format!(
                "{} is the input file; choose another path (the input is never overwritten)",
                output.display()
            ),
        ));
    }
    Ok(())
}

/// Loads `input` and bakes it (the output's URIs stay relative to the
/// input's directory).
pub fn bake_file(input: &Path, settings: &Settings) -> Result<Baked> {
    let mut timer = StageTimer::new();
    let scene = gltf::load(input)?;
    timer.lap("load");
    let mut baked = bake_loaded(&scene, settings, &mut timer)?;
    baked.report.input = input.display().to_string();
    baked.report = finish_report(baked.report, timer);
    Ok(baked)
}

/// Bakes a loaded scene into lightmaps and the output GLB bytes.
pub fn bake_scene(scene: &Scene, s: &Settings) -> Result<Baked> {
    let mut timer = StageTimer::new();
    let mut baked = bake_loaded(scene, s, &mut timer)?;
    baked.report = finish_report(baked.report, timer);
    Ok(baked)
}

/// The report with every stage the timer saw (a stage's laps over the
/// pages added up).
pub fn finish_report(mut report: Report, timer: StageTimer) -> Report {
    report.total_seconds = timer.total();
    report.stages = timer.into_merged_stages();
    report
}

fn bake_loaded(scene: &Scene, s: &Settings, timer: &mut StageTimer) -> Result<Baked> {
    let level = prepare_level(scene, s, timer)?;
    let pages: Vec<u32> = (0..level.page_count()).collect();
    let mut first = None;
    let done = bake_pages(scene, &level, &pages, s, timer, &mut |p, passes, out| {
        if p.page == 0 {
            first = Some((p.receivers, passes, out));
        }
    })?;
    let encoded: Vec<&Encoded> = done.iter().map(|d| &d.encoded).collect();
    let (glb, warnings) = write(scene, &level, &encoded, s, None, timer)?;
    let report = level_report(&level, &done, s, warnings);
    let (receivers, passes, out) = first.expect("page 0 is baked");
    Ok(Baked {
        geometry: Arc::clone(&level.geometry),
        atlas: level.atlas,
        receivers,
        bake: passes.bake,
        filter_stats: passes.filter_stats,
        adaptive_stats: passes.adaptive_stats,
        lightmap: out.lightmap,
        encoded: out.encoded,
        glb,
        report,
    })
}

/// Bakes `pages` of the level one after another: each is rasterized,
/// baked, dilated, stitched and encoded, handed to `keep` (which may hold
/// on to its intermediates; the bake's own path drops them), and freed.
pub fn bake_pages(
    scene: &Scene,
    level: &Level,
    pages: &[u32],
    s: &Settings,
    timer: &mut StageTimer,
    keep: &mut dyn FnMut(Prepared, BakePasses, PageOutput),
) -> Result<Vec<PageDone>> {
    let mut done = Vec::with_capacity(pages.len());
    for &page in pages {
        let prepared = level.prepare_page(page, scene, s, timer)?;
        let passes = bake_prepared(&prepared, s, timer)?;
        let out = output_page(&prepared, &passes, s, timer)?;
        let texels = prepared.receivers.len();
        done.push(PageDone {
            page,
            encoded: out.encoded.clone(),
            texels,
            texels_inside: passes.inside(&prepared).iter().filter(|&&x| x).count(),
            rays: passes.bake.rays,
            visibility_rays: passes.bake.visibility.as_ref().map(|v| v.rays),
            adaptive: passes
                .adaptive_stats
                .as_ref()
                .map(|a| AdaptiveReport::new(&s.adaptive, a)),
            filter: passes
                .filter_stats
                .as_ref()
                .map(|f| FilterReport::new(&s.filter, f)),
            seams: out.seams,
            pass_seconds: total(&passes.stages),
        });
        keep(prepared, passes, out);
    }
    Ok(done)
}

/// The report of a level from its baked pages (`done`: every page, or a
/// shard's).
pub fn level_report(
    level: &Level,
    done: &[PageDone],
    s: &Settings,
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
            }
        })
        .collect();
    let adaptive = merged(
        done.iter()
            .filter_map(|d| Some((d.adaptive.as_ref()?, d.texels))),
        AdaptiveReport::merge,
    );
    let filter = merged(
        done.iter()
            .filter_map(|d| Some((d.filter.as_ref()?, d.texels))),
        FilterReport::merge,
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
        texels,
        texels_inside: done.iter().map(|d| d.texels_inside).sum(),
        baked_primitives: level.geometry.receivers.len(),
        occluder_triangles: level.tracer.triangle_count(),
        rays_per_texel: if s.method == Method::Mc { s.rays } else { 0 },
        rays_cast: rays,
        rays_per_texel_total: rays as f64 / texels.max(1) as f64,
        filter,
        adaptive,
        visibility: visibility_rays.map(|v| VisibilityReport {
            order: s.visibility_order,
            primitives: level.visibility_meshes.iter().filter(|&&m| m).count(),
            rays: v,
            rays_per_texel: v as f64 / texels.max(1) as f64,
        }),
        seams: match done {
            [one] if level.page_count() == 1 => one.seams,
            _ => None,
        },
        rays_per_second: if pass_seconds > 0.0 {
            rays as f64 / pass_seconds
        } else {
            0.0
        },
        max_distance: level.max_distance_world,
        seed: s.seed,
        threads: rayon::current_num_threads(),
        stages: Vec::new(),
        total_seconds: 0.0,
        warnings,
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

/// Dilates, stitches and encodes a prepared page and builds the output GLB
/// bytes of a one-page level (as [`prepare`] gives): for the report and
/// tools that bake one page many times.
pub fn output(
    scene: &Scene,
    p: &Prepared,
    passes: &BakePasses,
    s: &Settings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<Output> {
    let PageOutput {
        lightmap,
        encoded,
        seams,
    } = output_page(p, passes, s, timer)?;
    let level = Level {
        geometry: Arc::clone(&p.geometry),
        atlas: p.atlas.clone(),
        tracer: Arc::clone(&p.tracer),
        max_distance_world: p.max_distance_world,
        max_distance: p.max_distance,
        visibility_meshes: p.visibility_meshes.clone(),
        cross_seams: Arc::clone(&p.cross_seams),
    };
    let (glb, warnings) = write(scene, &level, &[&encoded], s, output_dir, timer)?;
    Ok(Output {
        lightmap,
        encoded,
        glb,
        warnings,
        seams,
    })
}
