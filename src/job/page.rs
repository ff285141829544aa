//! One page: the method's passes, then the lightmap stage and encode; and
//! the write-back of every page's images into one GLB.
//!
//! In: a [`Page`] and the settings. Out: [`BakePasses`] (the method's
//! results and figures), [`PageOutput`] (the page's float lightmap, its
//! encoded images and seam figures; debug maps and EXR files written if
//! the run asks), and from the encoded pages of a whole level the output
//! GLB bytes ([`write`](fn@write)).

use super::level::{Level, Page, page_seed};
use crate::atlas::AtlasSize;
use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, ShearedStats};
use crate::bake::{Bake, BakeParams, mc, visibility};
use crate::encode::{self, Encoded};
use crate::error::{Error, Result};
use crate::file;
use crate::gltf::Scene;
use crate::gltf::write::{self, BakeRecord, OutputOptions};
use crate::job::settings::{BakeSettings, Method, RunOptions, UvSource};
use crate::lightmap::BorderReport;
use crate::lightmap::Filter;
use crate::lightmap::engine_view::{self, EngineView};
use crate::lightmap::seams::SeamReport;
use crate::lightmap::{self, Lightmap, PageBake};
use crate::stage::{StageTime, StageTimer, progress_bar};
use std::path::{Path, PathBuf};

/// What a method's passes over a page's receivers produced.
pub struct BakePasses {
    pub bake: Bake,
    /// Sheared method only.
    pub sheared_stats: Option<ShearedStats>,
    /// Adaptive method only.
    pub adaptive_stats: Option<AdaptiveStats>,
    /// The method's own passes: `trace` (Monte Carlo), or `sparse pass` and
    /// `filter pass` (sheared).
    pub stages: Vec<StageTime>,
}

impl BakePasses {
    /// Per receiver: inside geometry, from the validity stage or, when
    /// the method found them itself, from its passes.
    pub fn inside<'a>(&'a self, p: &'a Page) -> &'a [bool] {
        match (&p.inside, &self.adaptive_stats) {
            (Some(inside), _) => inside,
            (None, Some(stats)) => &stats.inside,
            (None, None) => &[],
        }
    }
}

/// What the lightmap stage and encode made of one page.
pub struct PageOutput {
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
    /// The border fit's figures (`--border fit`).
    pub border: Option<BorderReport>,
    /// The engine-view error (`--engine-view-points`).
    pub engine_view: Option<EngineView>,
}

/// Mixed into the seed of the engine-view points and reference rays.
const ENGINE_VIEW_SEED: u64 = 0xe9_61_2e_71_e3_00_00_01;

/// Page 0's files go into `dir` itself, page k's into `dir/page-k`.
fn page_dir(dir: &Path, page: u32) -> PathBuf {
    if page == 0 {
        dir.to_path_buf()
    } else {
        dir.join(format!("page-{page}"))
    }
}

impl Page<'_> {
    /// Runs the method's passes over the page's receivers (`s` validated,
    /// as by [`Level::new`]).
    pub fn bake(
        &self,
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<BakePasses> {
        let (receivers, tracer) = (&self.receivers, &self.level.tracer);
        let params = BakeParams {
            max_distance: self.level.max_distance,
            seed: page_seed(s.seed, self.page),
        };
        let layer = self.level.bakes_visibility();
        let first = timer.stages().len();
        timer.restart();
        let pb = progress_bar(run.progress, receivers.len() as u64, "baking");
        let progress = |n| pb.inc(n);
        let (bake, sheared_stats, adaptive_stats) = match s.method {
            Method::Mc => {
                let mut b = mc::bake(receivers, tracer, s.rays, &params, &progress);
                timer.lap("trace");
                if layer {
                    b.visibility = Some(visibility::bake(receivers, tracer, s.rays, &params));
                    timer.lap("visibility pass");
                }
                (b, None, None)
            }
            Method::Sheared => {
                let (b, stats) =
                    sheared::bake(receivers, tracer, &s.sheared, &params, timer, &progress)?;
                (b, Some(stats), None)
            }
            Method::Adaptive => {
                let (b, stats) = adaptive::bake(
                    receivers,
                    tracer,
                    s.fill_inside,
                    layer,
                    &s.adaptive,
                    &params,
                    timer,
                    &progress,
                );
                (b, None, Some(stats))
            }
        };
        pb.finish_and_clear();
        Ok(BakePasses {
            bake,
            sheared_stats,
            adaptive_stats,
            stages: timer.since(first).to_vec(),
        })
    }

    /// The lightmap stage ([`lightmap::build`]) and encode of the page's
    /// bake; writes its debug maps and EXR if the run asks (page 0's into
    /// the directories given, page k's into their `page-k` subdirectories).
    pub fn finish(
        &self,
        passes: &BakePasses,
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<PageOutput> {
        let level = self.level;
        let debug_dir = run.debug_dir.as_ref().map(|d| page_dir(d, self.page));
        if let Some(dir) = &debug_dir {
            let maps = match (&passes.sheared_stats, &passes.adaptive_stats) {
                (Some(stats), _) => stats.debug_maps(level.max_distance),
                (_, Some(stats)) => stats.debug_maps(level.max_distance),
                _ => Vec::new(),
            };
            if !maps.is_empty() {
                encode::write_grey_maps(dir, &self.receivers, &maps)?;
            }
        }
        let built = lightmap::build(
            &PageBake {
                page: self.page,
                pages: &level.atlas.pages,
                meshes: &level.geometry.receivers,
                atlas: &self.atlas,
                receivers: &self.receivers,
                bake: &passes.bake,
                inside: passes.inside(self),
                cross_seams: &level.cross_seams,
                tracer: &level.tracer,
                max_distance: level.max_distance,
                seed: s.seed,
                diagonal: level.geometry.space.diagonal,
                fit_cache: Some(&self.fit_cache),
                noise_rays: (s.method == Method::Mc).then_some(s.rays),
                sigma_texels: passes.adaptive_stats.as_ref().map(|a| &a.sigma_texels[..]),
            },
            s.seams,
            s.border,
            s.filter,
            debug_dir.is_some(),
            timer,
        )?;
        let lightmap = built.lightmap;
        if let (Some(dir), Some(maps)) = (&debug_dir, built.seam_maps) {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            for (name, img) in ["seams_before", "seams_after"].into_iter().zip(maps) {
                let png = encode::png(
                    lightmap.width,
                    lightmap.height,
                    &img,
                    image::ExtendedColorType::L8,
                )?;
                file::write_atomic(&dir.join(format!("{name}.png")), &png)?;
            }
        }
        timer.restart();
        let encoded = encode::encode(&lightmap, s.visibility_order)?;
        if let Some(dir) = &run.exr_dir {
            let dir = page_dir(dir, self.page);
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            encode::write_exr(&lightmap, &dir.join("lightmap.exr"))?;
        }
        timer.lap("encode");
        let engine_view = self.engine_view(&encoded, s, run)?;
        if engine_view.is_some() {
            timer.lap("engine view");
        }
        Ok(PageOutput {
            lightmap,
            encoded,
            seams: built.seams,
            border: built.border,
            engine_view,
        })
    }

    /// The engine-view error of the page's encoded images, with this
    /// page's share (by area) of `run.engine_view_points` points; `None`
    /// when the run does not ask for it.
    pub fn engine_view(
        &self,
        encoded: &Encoded,
        s: &BakeSettings,
        run: &RunOptions,
    ) -> Result<Option<EngineView>> {
        if run.engine_view_points == 0 {
            return Ok(None);
        }
        if run.engine_view_rays == 0 {
            return Err(Error::option("engine_view_rays", "must be at least 1"));
        }
        let areas = self.level.page_surface_areas();
        let total: f64 = areas.iter().sum();
        let share = areas[self.page as usize] / total.max(f64::MIN_POSITIVE);
        let count = (run.engine_view_points as f64 * share).round() as usize;
        // Its own streams: never the bake's rays.
        let seed = page_seed(s.seed ^ ENGINE_VIEW_SEED, self.page);
        let probe = self.engine_probe(
            count,
            run.engine_view_rays,
            seed,
            encoded.visibility.is_some(),
        );
        self.engine_view_against(&probe, encoded, s.filter)
            .map(Some)
    }

    /// `count` surface points of this page uniform by area and their
    /// `rays`-ray reference (with the visibility layer's when `layer`):
    /// what the engine view measures the page's textures against (once per
    /// page in a bake, once for all runs in `aobake report`).
    pub fn engine_probe(&self, count: usize, rays: u32, seed: u64, layer: bool) -> EngineProbe {
        let level = self.level;
        let tris =
            crate::atlas::rasterize::surface_triangles(&level.geometry.receivers, &self.atlas);
        let points =
            engine_view::surface_points(&tris, self.atlas.width, self.atlas.height, count, seed);
        let reference = engine_view::reference(
            &points,
            &level.tracer,
            level.max_distance,
            rays,
            seed,
            layer,
        );
        EngineProbe {
            points,
            reference,
            centers: self.receivers.centers_inside(),
        }
    }

    /// The engine-view error of `encoded` (this page's written textures,
    /// decoded as a GPU reads them through `filter`) against `probe`.
    pub fn engine_view_against(
        &self,
        probe: &EngineProbe,
        encoded: &Encoded,
        filter: Filter,
    ) -> Result<EngineView> {
        let decoded = crate::encode::decode(encoded)?;
        Ok(engine_view::measure(
            &probe.points,
            &decoded,
            filter,
            &probe.reference,
            &probe.centers,
            &self.level.visibility_meshes,
            encoded.visibility.as_ref().map_or(0, |v| v.scale.len()),
        ))
    }
}

/// A page's surface points and their reference, and which of its texel
/// centres lie inside a triangle ([`Page::engine_probe`]).
pub struct EngineProbe {
    pub points: engine_view::SurfacePoints,
    pub reference: engine_view::PointReference,
    pub centers: Vec<bool>,
}

/// The output GLB of a level from every page's encoded images (`pages[k]`
/// is page k's), with the scene's warnings and the writer's. `output_dir`:
/// where the GLB will be written, so external URIs resolve from there.
pub fn write(
    scene: &Scene,
    level: &Level,
    pages: &[&Encoded],
    s: &BakeSettings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<(Vec<u8>, Vec<String>)> {
    timer.restart();
    let options = OutputOptions {
        record: BakeRecord {
            method: s.method.name().to_string(),
            rays: match s.method {
                Method::Mc => s.rays,
                Method::Sheared => s.sheared.sparse_rays,
                Method::Adaptive => s.adaptive.quality,
            },
            seed: s.seed,
            max_distance: level.max_distance_world,
            width: level.atlas.width,
            height: level.atlas.height,
            filter: s.filter,
        },
        occlusion: s.occlusion,
        visibility_meshes: level.visibility_meshes.clone(),
        existing_uv: match s.uv {
            UvSource::Existing(set) => Some(set),
            UvSource::Generate => None,
        },
        output_dir: output_dir.map(Path::to_path_buf),
    };
    let mut warnings = scene.warnings.clone();
    if let (Some(relaxed), AtlasSize::Resolution(r)) = (level.atlas.relaxed, s.size) {
        let why = match relaxed.starved {
            true => format!(
                "with padding {} and minimum chart width {} the charts would cover under {:.0}% of one {r}x{r} page",
                s.padding,
                s.min_chart_width,
                100.0 * crate::atlas::unwrap::STARVED_UTILIZATION
            ),
            false => format!(
                "the {} charts do not fit one {r}x{r} page with padding {} and minimum chart width {}",
                level.atlas.charts, s.padding, s.min_chart_width
            ),
        };
        warnings.push(format!(
            "{why}: packed with padding {} and minimum chart width {}{} (raise --resolution for the requested ones)",
            relaxed.padding,
            relaxed.min_chart_width,
            if relaxed.padding == 0 {
                ", so lookups at chart edges blend neighbouring charts"
            } else {
                ""
            },
        ));
    }
    let glb = write::build_glb(
        scene,
        &level.geometry,
        &level.atlas,
        pages,
        &options,
        &mut warnings,
    )?;
    timer.lap("write");
    Ok((glb, warnings))
}
