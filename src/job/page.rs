//! One page: prepared from the level (rasterized, its receivers inside
//! geometry found), the method's passes, then the lightmap stage and
//! encode.
//!
//! In: a [`Level`], the page's index and the settings. Out: a [`Page`]
//! ([`Level::page`]), [`BakePasses`] (the method's results and figures)
//! and [`PageOutput`] (the page's float lightmap, its encoded images and
//! seam figures; debug maps and EXR files written if the run asks).

use super::carry::PageCarry;
use super::level::{Level, page_seed};
use crate::atlas::{self, Atlas, Receivers};
use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, ShearedStats};
use crate::bake::{Bake, BakeParams, mc, validity, visibility};
use crate::encode::{self, Encoded};
use crate::error::{Error, Result};
use crate::file;
use crate::gltf::Scene;
use crate::job::settings::{BakeSettings, Method, RunOptions, UvSource};
use crate::lightmap::BorderReport;
use crate::lightmap::Filter;
use crate::lightmap::engine_view::{self, EngineView};
use crate::lightmap::seams::SeamReport;
use crate::lightmap::{self, Lightmap, PageBake};
use crate::stage::{StageTime, StageTimer, progress_bar};
use std::path::{Path, PathBuf};

/// One page of a level, prepared: every stage before the first ray. It
/// borrows the level, so what every page shares is never copied.
pub struct Page<'a> {
    pub level: &'a Level,
    /// The page's index in the level's atlas.
    pub page: u32,
    /// This page alone, as a one-page atlas.
    pub atlas: Atlas,
    pub receivers: Receivers,
    /// Per receiver: inside or behind geometry ([`crate::bake::validity`]);
    /// its texel shows its nearest valid receiver instead. All false
    /// without the fill; `None` when the method finds them itself (the
    /// adaptive method, in its pre-pass).
    pub inside: Option<Vec<bool>>,
    /// The border fit traced for this page, kept for runs that bake it
    /// again ([`crate::lightmap::border::FitTargets`]).
    pub fit_cache: crate::lightmap::border::FitCache,
    /// What the page takes from an earlier bake (`--reuse`, [`PageCarry`]);
    /// nothing by default.
    pub carry: PageCarry,
    /// Per receiver: whether the edit since the carried bake can change
    /// it ([`super::carry::dirty`]); `None` without a carry.
    pub dirty: Option<Vec<bool>>,
    /// Rays of each border fit point: [`lightmap::border::FIT_RAYS`], fewer
    /// for the ladder's probe bakes (`job/level/ladder.rs`).
    pub fit_rays: u32,
}

impl Level {
    /// Rasterizes page `page` and finds its receivers inside geometry, by
    /// the level's settings (`scene`: the level's, for names in errors).
    pub fn page(&self, page: u32, scene: &Scene, timer: &mut StageTimer) -> Result<Page<'_>> {
        let (geometry, s) = (&self.geometry, &self.settings());
        let atlas = self.atlas.page(page);
        let receivers = atlas::rasterize(&geometry.receivers, &atlas);
        if let (UvSource::Existing(set), Some((a, b))) = (s.uv, receivers.first_overlap) {
            let name = |k: u32| {
                scene.geometries[scene.instances[geometry.receivers[k as usize].instance].geometry]
                    .label()
            };
            return Err(Error::option_conflict(
                "uv",
                format!(
                    "TEXCOORD_{set} of {} and {} overlap ({} texels): existing UVs must be one shared, non-overlapping lightmap layout; generate them instead",
                    name(a),
                    name(b),
                    receivers.overlapping_texels
                ),
            ));
        }
        if receivers.is_empty() && self.page_count() == 1 {
            return Err(Error::Empty(
                "no texel is covered: every baked triangle is degenerate".into(),
            ));
        }
        // For the tracing passes' caches ([`atlas::order`]); no output changes.
        let receivers = atlas::order::in_world_order(receivers);
        timer.lap("rasterize");
        let inside = if !s.fill_inside {
            Some(vec![false; receivers.len()])
        } else if s.method == Method::Adaptive {
            // Its pre-pass's closest hits make the same test on the same rays.
            None
        } else {
            let seed = page_seed(s.seed, page);
            let inside =
                validity::inside_geometry(&receivers, &self.tracer, self.max_distance, seed);
            timer.lap("validity");
            Some(inside)
        };
        Ok(Page {
            level: self,
            page,
            atlas,
            receivers,
            inside,
            fit_cache: Default::default(),
            carry: PageCarry::default(),
            dirty: None,
            fit_rays: lightmap::border::FIT_RAYS,
        })
    }
}

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
    /// Runs the method's passes over the page's receivers under `s`: the
    /// level's settings ([`Level::settings`], as a job bakes), or the same
    /// with another method or budget (validated), as `aobake report`'s
    /// sweep bakes one page many times.
    pub fn bake(
        &self,
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<BakePasses> {
        let page = adaptive::PageWide {
            scale: self.carry.scale,
            depths: None,
        };
        self.bake_receivers(&self.receivers, page, s, run, timer)
    }

    /// [`Page::bake`] of the receivers `part` (indices into the page's,
    /// ascending) alone, for the texels an edit reaches (`--reuse`): each
    /// of them at least [`adaptive::PageWide::halo`] texels inside the
    /// part gets the value the whole page's bake gives it (in `part`'s
    /// order). Monte Carlo's receivers are their own rays alone; the
    /// sheared filter's cells are page-wide (an error).
    pub fn bake_part(
        &self,
        part: &[u32],
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<BakePasses> {
        if s.method == Method::Sheared {
            return Err(Error::option_conflict(
                "method",
                "the sheared filter bakes whole pages only",
            ));
        }
        let receivers = self.receivers.permuted(part);
        let page = adaptive::PageWide {
            scale: self.carry.scale,
            depths: Some(adaptive::Depths::of(
                &self.receivers.footprint,
                &s.adaptive,
                self.level.max_distance,
            )),
        };
        self.bake_receivers(&receivers, page, s, run, timer)
    }

    fn bake_receivers(
        &self,
        receivers: &Receivers,
        page: adaptive::PageWide,
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<BakePasses> {
        let tracer = &self.level.tracer;
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
                // The receivers the border fit will set, found as the
                // lightmap stage finds its fitted texels, at the first
                // round's noise.
                let (reach, noise) = (s.filter.reach(), s.first_round_noise_rays());
                let sets = |ao: &[f32], inside: &[bool]| {
                    lightmap::border::fit_sets(receivers, ao, inside, reach, s.border, noise)
                };
                let sets: Option<&adaptive::FitSets> =
                    (s.border != lightmap::border::BorderMode::Off).then_some(&sets);
                let (b, stats) = adaptive::bake(
                    receivers,
                    tracer,
                    s.fill_inside,
                    layer,
                    &s.adaptive,
                    page,
                    sets,
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
            let mut maps = maps;
            if let Some(dirty) = &self.dirty {
                maps.push(("dirty", dirty.iter().map(|&d| d as u8 as f32).collect()));
            }
            if !maps.is_empty() {
                encode::write_grey_maps(dir, &self.receivers, &maps)?;
            }
        }
        let sigma = passes.adaptive_stats.as_ref().map(|a| &a.sigma_texels[..]);
        let mut page_bake = self.page_bake(&passes.bake, passes.inside(self), sigma, s);
        page_bake.fit_cache = Some(&self.fit_cache);
        let built = lightmap::build(
            &page_bake,
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
        let mut encoded =
            encode::encode_in(&lightmap, s.visibility_order, self.carry.ranges.as_ref())?;
        encoded.scale = passes.adaptive_stats.as_ref().and_then(|a| a.scale);
        encoded.solve_range = built.solve_range;
        encoded.inside = Some(super::carry::inside_runs(
            &self.receivers.texel,
            passes.inside(self),
        ));
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

    /// What the lightmap stage reads of the page baked as `bake`.
    fn page_bake<'b>(
        &'b self,
        bake: &'b crate::bake::Bake,
        inside: &'b [bool],
        sigma_texels: Option<&'b [f32]>,
        s: &BakeSettings,
    ) -> PageBake<'b> {
        let level = self.level;
        PageBake {
            page: self.page,
            pages: &level.atlas.pages,
            meshes: &level.geometry.receivers,
            atlas: &self.atlas,
            receivers: &self.receivers,
            bake,
            inside,
            cross_seams: &level.cross_seams,
            tracer: &level.tracer,
            max_distance: level.max_distance,
            seed: s.seed,
            diagonal: level.geometry.space.diagonal,
            fit_cache: None,
            solve_range: self.carry.solve_range.as_ref(),
            known: None,
            changed: None,
            noise_rays: s.noise_rays(),
            fit_rays: self.fit_rays,
            sigma_texels,
        }
    }

    /// The lightmap stage of a bake of part of the page (`part` and its
    /// `passes`, [`Page::bake_part`]), with `inside` the page's marks per
    /// receiver (PREV's, and the part's own over them): the page's float
    /// lightmap, each texel the value [`Page::finish`] gives it on a bake
    /// of the whole page, or NaN where that depends on a receiver less
    /// than [`adaptive::PageWide::halo`] texels inside the part
    /// ([`lightmap::build`] says how NaN travels), and per texel whether
    /// the edit (`changed`: the texels whose inputs it changed) can change
    /// it ([`lightmap::known::missing`] reads it). Bilinear pages only.
    pub fn lightmap_part(
        &self,
        part: &[u32],
        passes: &BakePasses,
        inside: &[bool],
        changed: &[bool],
        s: &BakeSettings,
        timer: &mut StageTimer,
    ) -> Result<lightmap::Built> {
        if s.filter != Filter::Bilinear {
            return Err(Error::option_conflict(
                "filter",
                "a bake of part of a page is bilinear only",
            ));
        }
        let r = &self.receivers;
        let known = deep_in_part(r, part, adaptive::PageWide::halo(&s.adaptive));
        let n = r.len();
        let b = &passes.bake;
        let mut bake = crate::bake::Bake {
            ao: vec![0.0; n],
            sh: vec![[0.0; crate::sh::SH_COUNT]; n],
            rays: b.rays,
            visibility: (b.visibility.as_ref()).map(|v| crate::bake::visibility::Visibility {
                v: vec![[0.0; crate::sh::VIS_COUNT]; n],
                rays: v.rays,
            }),
        };
        let mut sigma = vec![0.0f32; n];
        let part_sigma = passes.adaptive_stats.as_ref().map(|a| &a.sigma_texels);
        for (k, &j) in part.iter().enumerate() {
            let j = j as usize;
            bake.ao[j] = b.ao[k];
            bake.sh[j] = b.sh[k];
            if let (Some(to), Some(from)) = (&mut bake.visibility, &b.visibility) {
                to.v[j] = from.v[k];
            }
            sigma[j] = part_sigma.map_or(0.0, |p| p[k]);
        }
        let sigma = part_sigma.map(|_| &sigma[..]);
        let mut page_bake = self.page_bake(&bake, inside, sigma, s);
        page_bake.known = Some(&known);
        page_bake.changed = Some(changed);
        lightmap::build(&page_bake, s.seams, s.border, s.filter, false, timer)
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

/// Per receiver of `r`: whether it is in `part` (indices into `r`) with
/// no receiver outside it within `halo` texels (Chebyshev).
fn deep_in_part(r: &Receivers, part: &[u32], halo: u32) -> Vec<bool> {
    let mut inside_part = vec![false; r.len()];
    for &j in part {
        inside_part[j as usize] = true;
    }
    // Texels of receivers outside the part, grown by `halo`.
    let mut outside = vec![false; (r.width * r.height) as usize];
    for (j, &t) in r.texel.iter().enumerate() {
        outside[t as usize] |= !inside_part[j];
    }
    let near = lightmap::seams::reach(&outside, r.width, r.height, halo);
    (r.texel.iter().zip(&inside_part))
        .map(|(&t, &p)| p && !near[t as usize])
        .collect()
}
