//! The pipeline: load -> unwrap -> rasterize -> BVH -> validity -> bake
//! -> dilate -> encode -> write, each stage timed once on one
//! [`StageTimer`]. The adaptive method has no validity stage: its
//! pre-pass makes the same test on the same rays.
//!
//! In: a loaded [`Scene`] (or a path) and validated [`Settings`]. Out: a
//! [`Baked`] holding every intermediate (for tests and reports) and the
//! output GLB bytes, or with [`run`] the output file and its [`Report`].
//! [`prepare`], [`bake_prepared`] and [`output`] are the three parts the
//! report (`aobake report`) reuses to bake one atlas many times.

use crate::atlas::{self, Atlas, AtlasSize, Receivers, UnwrapOptions, dilate};
use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, FilterStats};
use crate::bake::{Bake, BakeParams, mc, validity, visibility};
use crate::encode::{self, Encoded, Lightmap};
use crate::error::{Error, Result};
use crate::file;
use crate::geometry::BakeGeometry;
use crate::gltf::write::{self, BakeRecord, OutputOptions};
use crate::gltf::{self, Scene};
use crate::seams::{self, SMOOTH_DEGREES, SeamReport};
use crate::settings::{
    DEFAULT_MAX_DISTANCE_FRACTION, MAX_BAKE_BYTES, Method, SeamMode, Settings, UvSource,
    VisibilityMode, estimated_bytes_with,
};
use crate::stage::{StageTime, StageTimer, progress_bar, total};
use crate::trace::Tracer;
use serde::Serialize;
use std::path::Path;

/// The `--report` JSON.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub input: String,
    pub method: Method,
    pub atlas_width: u32,
    pub atlas_height: u32,
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
    /// the solve (`--seams stitch`).
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
    fn new(o: &adaptive::AdaptiveOptions, a: &AdaptiveStats) -> AdaptiveReport {
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
    fn new(s: &sheared::ShearedOptions, f: &FilterStats) -> FilterReport {
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

/// Every product of a bake.
pub struct Baked {
    pub geometry: BakeGeometry,
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

/// What every bake of one scene shares: geometry in bake space, the atlas,
/// its receivers and the BVH (every stage before the first ray).
pub struct Prepared {
    pub geometry: BakeGeometry,
    pub atlas: Atlas,
    pub receivers: Receivers,
    pub tracer: Tracer,
    /// Max occluder distance in world units.
    pub max_distance_world: f64,
    /// The same in bake units.
    pub max_distance: f32,
    /// Per receiver: inside or behind geometry ([`crate::bake::validity`]);
    /// its texel shows its nearest valid receiver instead. All false
    /// without the fill; `None` when the method finds them itself (the
    /// adaptive method, in its pre-pass: [`BakePasses::inside`]).
    pub inside: Option<Vec<bool>>,
    /// Per receiver mesh: it gets the visibility layer (`--visibility`,
    /// `auto` from its material). The layer is baked when any does.
    pub visibility_meshes: Vec<bool>,
}

impl Prepared {
    /// Whether the bake makes the visibility layer.
    pub fn bakes_visibility(&self) -> bool {
        self.visibility_meshes.iter().any(|&v| v)
    }
}

/// What a method's passes over prepared receivers produced.
pub struct BakePasses {
    pub bake: Bake,
    /// Filtered method only.
    pub filter_stats: Option<FilterStats>,
    /// Adaptive method only.
    pub adaptive_stats: Option<AdaptiveStats>,
    /// The method's own passes: `trace` (Monte Carlo), or `sparse pass` and
    /// `filter pass` (filtered).
    pub stages: Vec<StageTime>,
}

impl BakePasses {
    /// Per receiver: inside geometry, from the validity stage or, when
    /// the method found them itself, from its passes.
    pub fn inside<'a>(&'a self, p: &'a Prepared) -> &'a [bool] {
        match (&p.inside, &self.adaptive_stats) {
            (Some(inside), _) => inside,
            (None, Some(stats)) => &stats.inside,
            (None, None) => &[],
        }
    }
}

/// What the output stages produced.
pub struct Output {
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub warnings: Vec<String>,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
}

/// Bakes `input` into `output` (written atomically; `input` is never touched).
pub fn run(input: &Path, output: &Path, settings: &Settings) -> Result<Report> {
    if file::same_file(input, output) {
        return Err(Error::option_conflict(
            "output",
            format!(
                "{} is the input file; choose another path (the input is never overwritten)",
                output.display()
            ),
        ));
    }
    let mut timer = StageTimer::new();
    let baked = bake_to(input, settings, Some(file::parent_dir(output)), &mut timer)?;
    file::write_atomic(output, &baked.glb)?;
    timer.lap("save");
    Ok(finish_report(baked.report, timer))
}

/// Loads `input` and bakes it (the output's URIs stay relative to the
/// input's directory).
pub fn bake_file(input: &Path, settings: &Settings) -> Result<Baked> {
    let mut timer = StageTimer::new();
    let mut baked = bake_to(input, settings, None, &mut timer)?;
    baked.report = finish_report(baked.report, timer);
    Ok(baked)
}

/// Bakes a loaded scene into lightmaps and the output GLB bytes.
pub fn bake_scene(scene: &Scene, s: &Settings) -> Result<Baked> {
    let mut timer = StageTimer::new();
    let mut baked = bake_loaded(scene, s, None, &mut timer)?;
    baked.report = finish_report(baked.report, timer);
    Ok(baked)
}

fn bake_to(
    input: &Path,
    s: &Settings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<Baked> {
    let scene = gltf::load(input)?;
    timer.lap("load");
    let mut baked = bake_loaded(&scene, s, output_dir, timer)?;
    baked.report.input = input.display().to_string();
    Ok(baked)
}

/// The report with every stage the timer saw.
fn finish_report(mut report: Report, timer: StageTimer) -> Report {
    report.total_seconds = timer.total();
    report.stages = timer.into_stages();
    report
}

fn bake_loaded(
    scene: &Scene,
    s: &Settings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<Baked> {
    let prepared = prepare(scene, s, timer)?;
    let passes = bake_prepared(&prepared, s, timer)?;
    let Output {
        lightmap,
        encoded,
        glb,
        warnings,
        seams: seam_report,
    } = output(scene, &prepared, &passes, s, output_dir, timer)?;
    let texels_inside = passes.inside(&prepared).iter().filter(|&&x| x).count();
    let visibility_report = passes.bake.visibility.as_ref().map(|v| VisibilityReport {
        order: s.visibility_order,
        primitives: prepared.visibility_meshes.iter().filter(|&&m| m).count(),
        rays: v.rays,
        rays_per_texel: v.rays as f64 / prepared.receivers.len().max(1) as f64,
    });
    let BakePasses {
        bake,
        filter_stats,
        adaptive_stats,
        stages: pass_stages,
    } = passes;
    let Prepared {
        geometry,
        atlas,
        receivers,
        tracer,
        max_distance_world,
        ..
    } = prepared;
    let pass_seconds = total(&pass_stages);
    let report = Report {
        input: String::new(),
        method: s.method,
        atlas_width: atlas.width,
        atlas_height: atlas.height,
        charts: atlas.charts,
        utilization: atlas.utilization,
        texels: receivers.len(),
        texels_inside,
        baked_primitives: geometry.receivers.len(),
        occluder_triangles: tracer.triangle_count(),
        rays_per_texel: if s.method == Method::Mc { s.rays } else { 0 },
        rays_cast: bake.rays,
        rays_per_texel_total: bake.rays as f64 / receivers.len() as f64,
        filter: filter_stats
            .as_ref()
            .map(|f| FilterReport::new(&s.filter, f)),
        adaptive: adaptive_stats
            .as_ref()
            .map(|a| AdaptiveReport::new(&s.adaptive, a)),
        visibility: visibility_report,
        seams: seam_report,
        rays_per_second: if pass_seconds > 0.0 {
            bake.rays as f64 / pass_seconds
        } else {
            0.0
        },
        max_distance: max_distance_world,
        seed: s.seed,
        threads: rayon::current_num_threads(),
        stages: Vec::new(),
        total_seconds: 0.0,
        warnings,
    };
    Ok(Baked {
        geometry,
        atlas,
        receivers,
        bake,
        filter_stats,
        adaptive_stats,
        lightmap,
        encoded,
        glb,
        report,
    })
}

/// Unwraps, rasterizes, builds the BVH and finds the receivers inside
/// geometry: everything before the first ray. Validates `s` first.
pub fn prepare(scene: &Scene, s: &Settings, timer: &mut StageTimer) -> Result<Prepared> {
    s.validate()?;
    if scene.baked_count() == 0 {
        return Err(Error::Empty(if scene.instances.is_empty() {
            "the default scene has no triangle primitive (points and lines are not baked)".into()
        } else {
            "every triangle mesh of the default scene is skinned, morphed or GPU-instanced (they only occlude)".into()
        }));
    }
    let geometry = scene.bake_geometry()?;
    let diagonal = geometry.space.diagonal;
    let max_distance_world = s
        .max_distance
        .unwrap_or(DEFAULT_MAX_DISTANCE_FRACTION * diagonal);
    timer.lap("prepare");
    let atlas = match (s.uv, s.size) {
        (UvSource::Existing(set), AtlasSize::Resolution(r)) => {
            let uvs = scene.lightmap_uvs(&geometry.receivers, set)?;
            atlas::unwrap::existing(&geometry.receivers, uvs, r)
        }
        (_, size) => {
            let options = UnwrapOptions {
                size,
                padding: s.padding,
                packing: s.packing,
            };
            let pb = progress_bar(s.progress, 0, "unwrap");
            let report = |stage: &'static str, done: usize, total: Option<usize>| {
                pb.set_message(stage);
                pb.set_length(total.unwrap_or(done + 1) as u64);
                pb.set_position(done as u64);
            };
            let atlas = atlas::unwrap::unwrap_with_progress(
                &geometry.receivers,
                &options,
                diagonal,
                &report,
            );
            pb.finish_and_clear();
            atlas?
        }
    };
    timer.lap("unwrap");
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
    let need = estimated_bytes_with(atlas.width, atlas.height, s, layer);
    if need > MAX_BAKE_BYTES {
        return Err(Error::Limit(format!(
            "a {}x{} atlas needs about {:.1} GiB of memory to bake, more than the {} GiB limit; lower the resolution or texel density",
            atlas.width,
            atlas.height,
            need as f64 / (1u64 << 30) as f64,
            MAX_BAKE_BYTES >> 30
        )));
    }
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
    if receivers.is_empty() {
        return Err(Error::Empty(
            "no texel is covered: every baked triangle is degenerate".into(),
        ));
    }
    // For the tracing passes' caches ([`atlas::order`]); no output changes.
    let receivers = atlas::order::in_world_order(receivers);
    timer.lap("rasterize");
    let tracer = Tracer::with_sides(&geometry.occluders, &geometry.occluder_single_sided);
    timer.lap("bvh");
    let max_distance = (max_distance_world / diagonal).min(f32::MAX as f64) as f32;
    let inside = if !s.fill_inside {
        Some(vec![false; receivers.len()])
    } else if s.method == Method::Adaptive {
        // Its pre-pass's closest hits make the same test on the same rays.
        None
    } else {
        let inside = validity::inside_geometry(&receivers, &tracer, max_distance, s.seed);
        timer.lap("validity");
        Some(inside)
    };
    Ok(Prepared {
        geometry,
        atlas,
        receivers,
        tracer,
        max_distance_world,
        max_distance,
        inside,
        visibility_meshes,
    })
}

/// Runs the method's passes over prepared receivers (`s` validated, as by
/// [`prepare`]).
pub fn bake_prepared(p: &Prepared, s: &Settings, timer: &mut StageTimer) -> Result<BakePasses> {
    let (receivers, tracer) = (&p.receivers, &p.tracer);
    let params = BakeParams {
        max_distance: p.max_distance,
        seed: s.seed,
    };
    let first = timer.stages().len();
    timer.restart();
    let pb = progress_bar(s.progress, receivers.len() as u64, "baking");
    let progress = |n| pb.inc(n);
    let (bake, filter_stats, adaptive_stats) = match s.method {
        Method::Mc => {
            let mut b = mc::bake(receivers, tracer, s.rays, &params, &progress);
            timer.lap("trace");
            if p.bakes_visibility() {
                b.visibility = Some(visibility::bake(receivers, tracer, s.rays, &params));
                timer.lap("visibility pass");
            }
            (b, None, None)
        }
        Method::Sheared => {
            let (b, stats) =
                sheared::bake(receivers, tracer, &s.filter, &params, timer, &progress)?;
            (b, Some(stats), None)
        }
        Method::Adaptive => {
            let (b, stats) = adaptive::bake(
                receivers,
                tracer,
                s.fill_inside,
                p.bakes_visibility(),
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
        filter_stats,
        adaptive_stats,
        stages: timer.since(first).to_vec(),
    })
}

/// Dilates and encodes the bake and builds the output GLB bytes (and writes
/// the debug maps and EXR if asked). `output_dir`: where the GLB will be
/// written, so external URIs resolve from there.
pub fn output(
    scene: &Scene,
    p: &Prepared,
    passes: &BakePasses,
    s: &Settings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<Output> {
    timer.restart();
    let receivers = &p.receivers;
    if let Some(dir) = &s.debug_dir {
        if let Some(stats) = &passes.filter_stats {
            encode::write_grey_maps(dir, receivers, &stats.debug_maps(p.max_distance))?;
        }
        if let Some(stats) = &passes.adaptive_stats {
            encode::write_grey_maps(dir, receivers, &stats.debug_maps(p.max_distance))?;
        }
    }
    let fill = dilate::fill_map(
        receivers.width,
        receivers.height,
        &receivers.texel,
        passes.inside(p),
    );
    let mut lightmap = encode::lightmap(receivers, &passes.bake, &fill)?;
    timer.lap("dilate");
    let seams = (s.seams == SeamMode::Stitch).then(|| {
        let found = seams::find::smooth_seams(&p.geometry.receivers, &p.atlas, SMOOTH_DEGREES);
        let (w, h) = (lightmap.width, lightmap.height);
        let map = |lm: &Lightmap| {
            let points = seams::metric::points(&found, w, h, &lm.ao, &lm.sh);
            seams::jump_map(&points, w, h)
        };
        let before = s.debug_dir.as_ref().map(|_| map(&lightmap));
        let report = seams::stitch_page(
            &found,
            p.geometry.space.diagonal,
            w,
            h,
            &lightmap.covered,
            &mut lightmap.ao,
            &mut lightmap.sh,
            lightmap.visibility.as_deref_mut(),
        );
        let maps = before.map(|b| (b, map(&lightmap)));
        (report, maps)
    });
    let seams = match seams {
        Some((report, maps)) => {
            if let (Some(dir), Some((before, after))) = (&s.debug_dir, maps) {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
                for (name, img) in [("seams_before", before), ("seams_after", after)] {
                    let png = encode::png(
                        lightmap.width,
                        lightmap.height,
                        &img,
                        image::ExtendedColorType::L8,
                    )?;
                    file::write_atomic(&dir.join(format!("{name}.png")), &png)?;
                }
            }
            timer.lap("seams");
            Some(report)
        }
        None => None,
    };
    let encoded = encode::encode(&lightmap, s.visibility_order)?;
    if let Some(dir) = &s.exr_dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        encode::write_exr(&lightmap, &dir.join("lightmap.exr"))?;
    }
    timer.lap("encode");
    let options = OutputOptions {
        record: BakeRecord {
            method: s.method.name().to_string(),
            rays: match s.method {
                Method::Mc => s.rays,
                Method::Sheared => s.filter.sparse_rays,
                Method::Adaptive => s.adaptive.quality,
            },
            seed: s.seed,
            max_distance: p.max_distance_world,
            width: p.atlas.width,
            height: p.atlas.height,
        },
        occlusion: s.occlusion,
        visibility_meshes: p.visibility_meshes.clone(),
        existing_uv: match s.uv {
            UvSource::Existing(set) => Some(set),
            UvSource::Generate => None,
        },
        output_dir: output_dir.map(Path::to_path_buf),
    };
    let mut warnings = scene.warnings.clone();
    let glb = write::build_glb(
        scene,
        &p.geometry,
        &p.atlas,
        &encoded,
        &options,
        &mut warnings,
    )?;
    timer.lap("write");
    Ok(Output {
        lightmap,
        encoded,
        glb,
        warnings,
        seams,
    })
}
