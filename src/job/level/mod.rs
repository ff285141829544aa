//! The level: what every page of a bake shares, built once.
//!
//! In: a loaded [`Scene`] and validated [`BakeSettings`]. Out: a [`Level`]
//! (bake-space geometry, the atlas of every page, the BVH, which meshes
//! get the visibility layer). Each page (`job/page.rs`) borrows it and
//! owns only what is the page's, freed once the page is encoded: peak
//! memory is the level plus one page, and the memory limit is checked per
//! page.

pub mod ladder;

use super::device::{self, Backend};
use crate::atlas::{self, Atlas, AtlasSize, Ladder, UnwrapOptions};
use crate::bake::signal::{self, TexelBudget};
use crate::error::{Error, Result};
use crate::geometry::{BakeGeometry, BakeSpace};
use crate::gltf::Scene;
use crate::job::settings::{
    BakeSettings, DEFAULT_MAX_DISTANCE_FRACTION, MAX_BAKE_BYTES, Method, RunOptions, UvSource,
    VisibilityMode, estimated_bytes_with,
};
use crate::lightmap::seams::find::cross_page_seams;
use crate::lightmap::seams::{CrossSeam, FLAT_DEGREES, SMOOTH_DEGREES, SeamMode};
use crate::stage::{StageTimer, progress_bar};
use crate::trace::Tracer;
use ladder::LadderReport;

/// The share of a page a uniform atlas's charts cover, for the texel edge
/// the signal's pre-pass floors distances at (the packer's utilisation on
/// the shared assets lies near it).
const UNIFORM_UTILIZATION: f64 = 0.5;

/// What every page of a bake shares: everything before the first texel.
pub struct Level {
    pub geometry: BakeGeometry,
    /// Every page's charts.
    pub atlas: Atlas,
    pub tracer: Tracer,
    /// Max occluder distance in world units.
    pub max_distance_world: f64,
    /// The same in bake units.
    pub max_distance: f32,
    /// Per receiver mesh: it gets the visibility layer (`--visibility`,
    /// `auto` from its material).
    pub visibility_meshes: Vec<bool>,
    /// Smooth seams whose sides lie on two pages (`--seams stitch`).
    pub cross_seams: Vec<CrossSeam>,
    /// Where the rays are traced (`--device`).
    pub backend: Backend,
    /// The settings the level was built with (validated): its pages are
    /// rasterized and tested for receivers inside geometry by them.
    settings: BakeSettings,
    /// Per page, the bake-space area of its triangles, computed when first
    /// asked for ([`Level::page_surface_areas`]).
    surface_areas: std::sync::OnceLock<Vec<f64>>,
    /// A small page's options as the engine view measured them
    /// (`--ladder view`), where it chose among several.
    pub ladder: Option<LadderReport>,
}

impl Level {
    /// The settings the level was built with ([`Level::new`] validated
    /// them).
    pub fn settings(&self) -> &BakeSettings {
        &self.settings
    }

    /// Whether the bake makes the visibility layer.
    pub fn bakes_visibility(&self) -> bool {
        self.visibility_meshes.iter().any(|&v| v)
    }
}

/// The seed of page `page`'s rays: the bake's own for page 0 (so a
/// one-page bake is unchanged), a different stream for every other page.
pub fn page_seed(seed: u64, page: u32) -> u64 {
    if page == 0 {
        seed
    } else {
        seed ^ (page as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
    }
}

impl Level {
    /// Unwraps into pages and builds the BVH (at the same time: the
    /// report's stage `unwrap + bvh`). Validates `s` first and keeps them
    /// for the pages.
    pub fn new(
        scene: &Scene,
        s: &BakeSettings,
        run: &RunOptions,
        timer: &mut StageTimer,
    ) -> Result<Level> {
        s.validate()?;
        Level::build(scene, s, run, None, timer)
    }

    /// [`Level::new`] for settings validated already: [`crate::bake()`] and
    /// [`crate::job::bake_shard`] validate before they read the input, so a bad
    /// option fails before any I/O, and once.
    /// `space`: the bake space to use instead of the scene's (an earlier
    /// bake's, `--reuse`).
    pub(crate) fn build(
        scene: &Scene,
        s: &BakeSettings,
        run: &RunOptions,
        space: Option<BakeSpace>,
        timer: &mut StageTimer,
    ) -> Result<Level> {
        Level::build_with(scene, s, run, space, None, timer)
    }

    /// [`Level::build`] with the ladder's choice already made
    /// (`chosen`: what the shards' level chose, which the merge takes
    /// instead of baking the options again: it casts no ray).
    pub(crate) fn build_with(
        scene: &Scene,
        s: &BakeSettings,
        run: &RunOptions,
        space: Option<BakeSpace>,
        chosen: Option<LadderReport>,
        timer: &mut StageTimer,
    ) -> Result<Level> {
        if scene.baked_count() == 0 {
            return Err(Error::Empty(if scene.instances.is_empty() {
                "the default scene has no triangle primitive (points and lines are not baked)"
                    .into()
            } else {
                "every triangle mesh of the default scene is skinned, morphed or GPU-instanced (they only occlude)".into()
            }));
        }
        let geometry = scene.bake_geometry_in(space)?;
        let diagonal = geometry.space.diagonal;
        let max_distance_world = s
            .max_distance
            .unwrap_or(DEFAULT_MAX_DISTANCE_FRACTION * diagonal);
        timer.lap("prepare");
        // Texels where the signal needs them: each mesh's density from a
        // pre-pass over its triangles, traced before the unwrap (the
        // uniform atlas's texel edge, bake units, floors the occluders'
        // distance).
        let signal =
            (s.texel_budget == TexelBudget::Signal && s.uv == UvSource::Generate).then(|| {
                let mut tracer =
                    Tracer::with_sides(&geometry.occluders, &geometry.occluder_single_sided);
                let backend = device::attach(&mut tracer, &geometry.occluders, s.device)?;
                let texel = match s.size {
                    AtlasSize::Resolution(r) => {
                        let area: f64 = (geometry.receivers.iter()).map(|m| m.surface_area()).sum();
                        (area / (UNIFORM_UTILIZATION * r as f64 * r as f64)).sqrt()
                    }
                    AtlasSize::TexelDensity { density, .. } => 1.0 / (density * diagonal),
                };
                let d = (max_distance_world / diagonal).min(f32::MAX as f64) as f32;
                let scales =
                    signal::mesh_scales(&geometry.receivers, &tracer, d, texel as f32, s.seed);
                Ok::<_, Error>(((tracer, backend), scales))
            });
        let signal = signal.transpose()?;
        if signal.is_some() {
            timer.lap("signal pre-pass");
        }
        let (early_tracer, scales) = signal.unzip();
        // The BVH (and the GPU's device, where one is used) is built while
        // the unwrap runs: neither needs the other, and the unwrap's chart
        // packing is mostly serial, so the build's parallel work fills the
        // idle threads. (With the signal pre-pass it was built before.)
        let (atlases, traced) = rayon::join(
            || unwrap_atlas(scene, &geometry, s, run, scales.as_deref()),
            || match early_tracer {
                Some(early) => Ok(early),
                None => {
                    let mut tracer =
                        Tracer::with_sides(&geometry.occluders, &geometry.occluder_single_sided);
                    let backend = device::attach(&mut tracer, &geometry.occluders, s.device)?;
                    Ok((tracer, backend))
                }
            },
        );
        let mut atlases = atlases?;
        let atlas = atlases.remove(0);
        timer.lap("unwrap + bvh");
        let visibility_meshes: Vec<bool> = geometry
            .receivers
            .iter()
            .map(|m| match (s.visibility, s.method) {
                (VisibilityMode::Off, _) | (VisibilityMode::Auto, Method::Sheared) => false,
                (VisibilityMode::All, _) => true,
                (VisibilityMode::Auto, _) => {
                    scene.material_reads_visibility(scene.instances[m.instance].geometry)
                }
            })
            .collect();
        let layer = visibility_meshes.iter().any(|&v| v);
        // Pages are baked one at a time: the limit is per page.
        let page = atlas
            .pages
            .iter()
            .max_by_key(|p| p.width as u64 * p.height as u64);
        let page = page.copied().unwrap_or(atlas::PageSize {
            width: atlas.width,
            height: atlas.height,
        });
        let need = estimated_bytes_with(page.width, page.height, s, layer);
        if need > MAX_BAKE_BYTES {
            return Err(Error::Limit(format!(
                "a {}x{} atlas page needs about {:.1} GiB of memory to bake, more than the {} GiB limit; lower the resolution or the page size",
                page.width,
                page.height,
                need as f64 / (1u64 << 30) as f64,
                MAX_BAKE_BYTES >> 30
            )));
        }
        let (tracer, backend) = traced?;
        if run.progress {
            eprintln!("aobake: {}", backend.line());
        }
        let max_distance = (max_distance_world / diagonal).min(f32::MAX as f64) as f32;
        let cross_seams = if s.seams == SeamMode::Stitch && atlas.pages.len() > 1 {
            cross_page_seams(&geometry.receivers, &atlas, SMOOTH_DEGREES, FLAT_DEGREES)
        } else {
            Vec::new()
        };
        let mut level = Level {
            geometry,
            atlas,
            tracer,
            max_distance_world,
            max_distance,
            visibility_meshes,
            cross_seams,
            backend,
            settings: s.clone(),
            surface_areas: std::sync::OnceLock::new(),
            ladder: None,
        };
        match (atlases.is_empty(), chosen) {
            (true, None) => {}
            (false, None) => {
                level.ladder = Some(ladder::choose(&mut level, atlases, scene, s)?);
                level.surface_areas = std::sync::OnceLock::new();
                timer.lap("ladder");
            }
            (_, Some(report)) => {
                let options = 1 + atlases.len();
                if report.rungs.len() != options || report.chosen >= options {
                    return Err(Error::Merge(format!(
                        "the shards' level chose among {} atlas options, but the input offers {options}",
                        report.rungs.len()
                    )));
                }
                if report.chosen > 0 {
                    level.atlas = atlases.swap_remove(report.chosen - 1);
                }
                level.ladder = Some(report);
            }
        }
        Ok(level)
    }

    /// How many pages the atlas has.
    pub fn page_count(&self) -> u32 {
        self.atlas.pages.len() as u32
    }

    /// Per page, the bake-space area of the triangles on it (computed once
    /// per level, however many pages ask).
    pub fn page_surface_areas(&self) -> &[f64] {
        self.surface_areas.get_or_init(|| self.surface_areas_now())
    }

    fn surface_areas_now(&self) -> Vec<f64> {
        let mut area = vec![0.0; self.atlas.pages.len()];
        for (m, c) in self.geometry.receivers.iter().zip(&self.atlas.meshes) {
            for (t, &p) in c.triangles.chunks_exact(3).zip(&c.triangle_page) {
                let [a, b, d] = [0, 1, 2]
                    .map(|k| glam::Vec3::from(m.positions[c.xref[t[k] as usize] as usize]));
                let a2 = (b - a).cross(d - a).length() as f64;
                if a2.is_finite() {
                    area[p as usize] += 0.5 * a2;
                }
            }
        }
        area
    }

    /// Texels per world unit.
    pub fn texel_density(&self) -> f64 {
        self.atlas.texels_per_unit / self.geometry.space.diagonal
    }
}

/// The atlas of every page: the UVs asked for (`--uv existing`) or an
/// unwrap; a chart that fits no page is an error naming its mesh. With
/// `--ladder view`, a tight small page's other options follow it
/// ([`crate::atlas::unwrap::ladder_applies`]).
fn unwrap_atlas(
    scene: &Scene,
    geometry: &BakeGeometry,
    s: &BakeSettings,
    run: &RunOptions,
    scales: Option<&[f32]>,
) -> Result<Vec<Atlas>> {
    let diagonal = geometry.space.diagonal;
    let label = |k: usize| {
        scene.geometries[scene.instances[geometry.receivers[k].instance].geometry].label()
    };
    Ok(match (s.uv, s.size) {
        (UvSource::Existing(set), AtlasSize::Resolution(r)) => {
            let uvs = scene.lightmap_uvs(&geometry.receivers, set)?;
            vec![atlas::unwrap::existing(&geometry.receivers, uvs, r)]
        }
        (_, size) => {
            let options = UnwrapOptions {
                size,
                padding: s.padding,
                packing: s.packing,
                min_chart_width: s.min_chart_width,
            };
            let pb = progress_bar(run.progress, 0, "unwrap");
            let report = |stage: &'static str, done: usize, total: Option<usize>| {
                pb.set_message(stage);
                pb.set_length(total.unwrap_or(done + 1) as u64);
                pb.set_position(done as u64);
            };
            let atlas = atlas::unwrap::unwrap_with_progress(
                &geometry.receivers,
                &options,
                diagonal,
                scales,
                s.ladder == Ladder::View,
                &report,
            );
            pb.finish_and_clear();
            match atlas? {
                Ok(atlases) => atlases,
                Err(c) => {
                    let page = match size {
                        AtlasSize::TexelDensity { page_size, .. } => page_size,
                        AtlasSize::Resolution(r) => r,
                    };
                    return Err(Error::Limit(format!(
                        "{}: a chart of {}x{} texels does not fit a {page}x{page} page; --texel-density {:.4} or less fits it (or raise --page-size)",
                        label(c.mesh),
                        c.width,
                        c.height,
                        c.fitting_density
                    )));
                }
            }
        }
    })
}
