//! The pipeline: load -> unwrap -> rasterize -> trace -> bake -> dilate ->
//! encode -> write, with per-stage wall times and progress bars.
//!
//! In: a loaded [`Scene`] and [`Settings`]. Out: a [`Baked`] holding every
//! intermediate (for tests and reports) and the output GLB bytes.

use crate::dilate;
use crate::encode::{self, Encoded, Lightmap};
use crate::error::{Error, Result};
use crate::filter;
use crate::load::{self, BakeGeometry, Scene};
use crate::mc::{self, Bake, McSettings};
use crate::rasterize::{self, Receivers};
use crate::trace::Tracer;
use crate::unwrap::{self, Atlas, AtlasSize, Packing, UnwrapOptions};
use crate::write::{self, BakeRecord, OcclusionMode, OutputOptions};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Memory a bake may use (checked against [`estimated_bytes`] before the
/// per-texel arrays are allocated): the 24 GiB build machines keep room for
/// the loaded scene and the BVH.
pub const MAX_BAKE_BYTES: u64 = 16 << 30;

/// Per atlas texel, an upper bound of what a bake holds at once: receiver
/// (texel, position, two normals, footprint: 44 B), results (AO and 9 SH:
/// 40 B), the float lightmap with its coverage (41 B), the dilation map
/// (4 B), BFS queue and encoded image rows (~24 B).
const BYTES_PER_TEXEL: u64 = 160;

/// Memory estimate of baking a `width` x `height` atlas with settings `s`
/// (every texel counted as covered: the worst case).
pub fn estimated_bytes(width: u32, height: u32, s: &Settings) -> u64 {
    let texels = width as u64 * height as u64;
    let mut bytes = texels * BYTES_PER_TEXEL;
    if s.method == Method::Filtered {
        // Sparse samples (direction, distance, cell, hit normal: 29 B each),
        // the k-d tree's points, per-receiver filter statistics (~40 B) and
        // the receivers reordered for locality (44 B).
        bytes += texels * (s.filter.sparse_rays as u64 * 29 + 12 + 40 + 44);
    }
    bytes
}

/// Largest `--gather-radius` in texels: every receiver visits the
/// neighbours within it, so the filter's cost grows with its square.
pub const MAX_GATHER_RADIUS: f32 = 64.0;
/// Largest `--sparse-rays` and `--cell-rays`.
pub const MAX_FILTER_RAYS: u32 = 1024;

fn filter_settings(s: &Settings, max_distance: f32) -> filter::FilterSettings {
    filter::FilterSettings {
        sparse_rays: s.filter.sparse_rays,
        gather_radius: s.filter.gather_radius,
        omega_v_max: s.filter.omega_v_max,
        cell_rays: s.filter.cell_rays,
        min_weight: s.filter.min_weight,
        max_distance,
        seed: s.seed,
    }
}

fn check_filter_options(fs: &FilterOptions) -> Result<()> {
    if !(1..=MAX_FILTER_RAYS).contains(&fs.sparse_rays) {
        return Err(Error::Option(format!(
            "--sparse-rays {} is outside 1..={MAX_FILTER_RAYS}",
            fs.sparse_rays
        )));
    }
    if !(1..=MAX_FILTER_RAYS).contains(&fs.cell_rays) {
        return Err(Error::Option(format!(
            "--cell-rays {} is outside 1..={MAX_FILTER_RAYS}",
            fs.cell_rays
        )));
    }
    if !(0.0..=MAX_GATHER_RADIUS).contains(&fs.gather_radius) {
        return Err(Error::Option(format!(
            "--gather-radius {} is outside 0..={MAX_GATHER_RADIUS} texels",
            fs.gather_radius
        )));
    }
    if !(fs.omega_v_max > 0.0 && fs.omega_v_max.is_finite()) {
        return Err(Error::Option(format!(
            "--omega-v {} must be finite and > 0",
            fs.omega_v_max
        )));
    }
    if !(fs.min_weight >= 0.0 && fs.min_weight.is_finite()) {
        return Err(Error::Option(format!(
            "--min-weight {} must be finite and >= 0",
            fs.min_weight
        )));
    }
    Ok(())
}

/// Default max occluder distance as a fraction of the scene's bounding-box diagonal.
pub const DEFAULT_MAX_DISTANCE_FRACTION: f64 = 0.1;

/// Baking method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Sparse rays shared between texels by the filter of Egan et al. 2011.
    Filtered,
    /// Brute-force Monte Carlo.
    Mc,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Filtered => "filtered",
            Method::Mc => "mc",
        }
    }
}

/// Options of the filtered method (see [`crate::filter`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterOptions {
    pub sparse_rays: u32,
    /// Gather radius in texels.
    pub gather_radius: f32,
    pub omega_v_max: f32,
    pub cell_rays: u32,
    /// Cells with less filter weight are brute-forced (about that many samples).
    pub min_weight: f32,
}

impl Default for FilterOptions {
    fn default() -> Self {
        let d = filter::FilterSettings::default();
        FilterOptions {
            sparse_rays: d.sparse_rays,
            gather_radius: d.gather_radius,
            omega_v_max: d.omega_v_max,
            cell_rays: d.cell_rays,
            min_weight: d.min_weight,
        }
    }
}

/// Where the lightmap UVs come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum UvSource {
    /// Unwrap every baked placement into a new atlas (new TEXCOORD_n).
    #[default]
    Generate,
    /// Reuse `TEXCOORD_<set>` as it is.
    Existing(usize),
}

/// Everything a bake can be told.
#[derive(Clone, Debug)]
pub struct Settings {
    pub size: AtlasSize,
    pub padding: u32,
    pub packing: Packing,
    pub uv: UvSource,
    pub method: Method,
    /// Rays per texel of the Monte Carlo method.
    pub rays: u32,
    pub filter: FilterOptions,
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
    /// texel ([`crate::validity`]); `false` bakes them as they are.
    pub fill_inside: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            size: AtlasSize::Resolution(1024),
            padding: 2,
            packing: Packing::Fast,
            uv: UvSource::Generate,
            method: Method::Mc,
            rays: 256,
            filter: FilterOptions::default(),
            debug_dir: None,
            max_distance: None,
            seed: 0,
            occlusion: OcclusionMode::Keep,
            exr_dir: None,
            progress: true,
            fill_inside: true,
        }
    }
}

/// Wall time of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
}

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
    /// texel ([`crate::validity`]).
    pub texels_inside: usize,
    pub baked_primitives: usize,
    pub occluder_triangles: usize,
    /// Monte Carlo rays per texel (the `--rays` setting; 0 for filtered).
    pub rays_per_texel: u32,
    pub rays_cast: u64,
    /// Rays cast per texel, all passes together.
    pub rays_per_texel_total: f64,
    /// Filtered method only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub filter: Option<FilterReport>,
    pub rays_per_second: f64,
    pub max_distance: f64,
    pub seed: u64,
    pub threads: usize,
    pub stages: Vec<StageTime>,
    pub total_seconds: f64,
    pub warnings: Vec<String>,
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
    pub sparse_pass_seconds: f64,
    /// Filtering with the second pass's brute-force rays (interleaved per texel).
    pub filter_pass_seconds: f64,
    pub mean_neighbours: f64,
}

/// Every product of a bake.
pub struct Baked {
    pub geometry: BakeGeometry,
    pub atlas: Atlas,
    pub receivers: Receivers,
    pub bake: Bake,
    /// Filtered method only.
    pub filter_stats: Option<filter::FilterStats>,
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub report: Report,
}

struct Timer {
    stages: Vec<StageTime>,
    last: Instant,
    start: Instant,
}

impl Timer {
    fn new() -> Timer {
        let now = Instant::now();
        Timer {
            stages: Vec::new(),
            last: now,
            start: now,
        }
    }
    fn lap(&mut self, stage: &'static str) {
        let now = Instant::now();
        self.stages.push(StageTime {
            stage,
            seconds: (now - self.last).as_secs_f64(),
        });
        self.last = now;
    }
    fn seconds(&self, stage: &str) -> f64 {
        self.stages
            .iter()
            .filter(|s| s.stage == stage)
            .map(|s| s.seconds)
            .sum()
    }
}

pub(crate) fn bar(show: bool, len: u64, msg: &'static str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(len),
        if show && std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    pb.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len}, {per_sec}, eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    pb.set_message(msg);
    pb
}

/// Loads `input` and bakes it.
pub fn bake_file(input: &Path, settings: &Settings) -> Result<Baked> {
    let start = Instant::now();
    let scene = load::load(input)?;
    let load_seconds = start.elapsed().as_secs_f64();
    let mut baked = bake_scene(&scene, settings)?;
    baked.report.input = input.display().to_string();
    baked.report.stages.insert(
        0,
        StageTime {
            stage: "load",
            seconds: load_seconds,
        },
    );
    baked.report.total_seconds += load_seconds;
    Ok(baked)
}

/// Bakes a loaded scene into lightmaps and the output GLB bytes.
pub fn bake_scene(scene: &Scene, s: &Settings) -> Result<Baked> {
    let start = Instant::now();
    let prepared = prepare(scene, s)?;
    let passes = bake_prepared(&prepared, s)?;
    let Output {
        lightmap,
        encoded,
        glb,
        warnings,
        stages: output_stages,
    } = output(scene, &prepared, &passes, s)?;
    let BakePasses {
        bake,
        filter_stats,
        stages: pass_stages,
    } = passes;
    let Prepared {
        geometry,
        atlas,
        receivers,
        tracer,
        max_distance_world,
        inside,
        stages,
        ..
    } = prepared;
    let mut t = Timer::new();
    t.start = start;
    t.stages = stages;
    t.stages.extend(pass_stages);
    t.stages.extend(output_stages);
    let trace_s = t.seconds("trace") + t.seconds("sparse pass") + t.seconds("filter pass");
    let filter_report = filter_stats.as_ref().map(|f| FilterReport {
        sparse_rays_per_texel: s.filter.sparse_rays,
        gather_radius_texels: s.filter.gather_radius,
        omega_v_max: s.filter.omega_v_max,
        cell_rays: s.filter.cell_rays,
        sparse_rays: f.sparse_rays,
        second_pass_rays: f.brute_rays,
        cells_filtered: f.cell_share(f.cells_filtered),
        cells_brute_forced: f.cell_share(f.cells_brute),
        cells_brute_contact: f.cell_share(f.cells_contact),
        cells_brute_no_hit: f.cell_share(f.cells_no_hit),
        cells_open: f.cell_share(f.cells_open),
        texels_open: f.receivers_open as f64 / receivers.len() as f64,
        sparse_pass_seconds: t.seconds("sparse pass"),
        filter_pass_seconds: t.seconds("filter pass"),
        mean_neighbours: f.neighbours.iter().map(|&n| n as f64).sum::<f64>()
            / receivers.len() as f64,
    });
    let report = Report {
        input: String::new(),
        method: s.method,
        atlas_width: atlas.width,
        atlas_height: atlas.height,
        charts: atlas.charts,
        utilization: atlas.utilization,
        texels: receivers.len(),
        texels_inside: inside.iter().filter(|&&x| x).count(),
        baked_primitives: geometry.receivers.len(),
        occluder_triangles: tracer.triangle_count(),
        rays_per_texel: if s.method == Method::Mc { s.rays } else { 0 },
        rays_cast: bake.rays,
        rays_per_texel_total: bake.rays as f64 / receivers.len() as f64,
        filter: filter_report,
        rays_per_second: if trace_s > 0.0 {
            bake.rays as f64 / trace_s
        } else {
            0.0
        },
        max_distance: max_distance_world,
        seed: s.seed,
        threads: rayon::current_num_threads(),
        total_seconds: t.start.elapsed().as_secs_f64(),
        stages: t.stages,
        warnings,
    };
    Ok(Baked {
        geometry,
        atlas,
        receivers,
        bake,
        filter_stats,
        lightmap,
        encoded,
        glb,
        report,
    })
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
    /// Per receiver: inside or behind geometry ([`crate::validity`]); its
    /// texel shows its nearest valid receiver instead.
    pub inside: Vec<bool>,
    /// Wall times of the stages so far.
    pub stages: Vec<StageTime>,
}

/// What a method's passes over prepared receivers produced.
pub struct BakePasses {
    pub bake: Bake,
    /// Filtered method only.
    pub filter_stats: Option<filter::FilterStats>,
    /// `trace` (Monte Carlo), or `sparse pass` and `filter pass` (filtered).
    pub stages: Vec<StageTime>,
}

/// What the output stages produced.
pub struct Output {
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub warnings: Vec<String>,
    /// `dilate`, `encode`, `write`.
    pub stages: Vec<StageTime>,
}

/// Dilates and encodes the bake and builds the output GLB bytes (and writes
/// the debug maps and EXR if asked).
pub fn output(scene: &Scene, p: &Prepared, passes: &BakePasses, s: &Settings) -> Result<Output> {
    let mut t = Timer::new();
    let receivers = &p.receivers;
    if let (Some(dir), Some(stats)) = (&s.debug_dir, &passes.filter_stats) {
        crate::encode::write_debug_maps(dir, receivers, stats, p.max_distance)?;
    }
    let fill = dilate::fill_map(
        receivers.width,
        receivers.height,
        &receivers.texel,
        &p.inside,
    );
    let lightmap = encode::lightmap(receivers, &passes.bake, &fill)?;
    t.lap("dilate");
    let encoded = encode::encode(&lightmap)?;
    if let Some(dir) = &s.exr_dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        encode::write_exr(&lightmap, &dir.join("lightmap.exr"))?;
    }
    t.lap("encode");
    let options = OutputOptions {
        record: BakeRecord {
            method: s.method.name().to_string(),
            rays: match s.method {
                Method::Mc => s.rays,
                Method::Filtered => s.filter.sparse_rays,
            },
            seed: s.seed,
            max_distance: p.max_distance_world,
            width: p.atlas.width,
            height: p.atlas.height,
        },
        occlusion: s.occlusion,
        existing_uv: match s.uv {
            UvSource::Existing(set) => Some(set),
            UvSource::Generate => None,
        },
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
    t.lap("write");
    Ok(Output {
        lightmap,
        encoded,
        glb,
        warnings,
        stages: t.stages,
    })
}

/// Unwraps, rasterizes and builds the BVH: everything before the first ray.
pub fn prepare(scene: &Scene, s: &Settings) -> Result<Prepared> {
    if s.method == Method::Filtered {
        // Before the unwrap, so a bad option fails at once.
        check_filter_options(&s.filter)?;
    }
    if s.method == Method::Mc && s.rays == 0 {
        return Err(Error::Option("--rays must be at least 1".into()));
    }
    if scene.baked_count() == 0 {
        return Err(Error::Empty(if scene.instances.is_empty() {
            "the default scene has no triangle primitive (points and lines are not baked)".into()
        } else {
            "every triangle mesh of the default scene is skinned, morphed or GPU-instanced (they only occlude)".into()
        }));
    }
    let mut t = Timer::new();
    let geometry = scene.bake_geometry()?;
    let diagonal = geometry.space.diagonal;
    let max_distance_world = match s.max_distance {
        Some(d) if d.is_finite() && d > 0.0 => d,
        Some(d) => {
            return Err(Error::Option(format!(
                "--max-distance {d} must be finite and > 0"
            )));
        }
        None => DEFAULT_MAX_DISTANCE_FRACTION * diagonal,
    };
    t.lap("prepare");
    let atlas = match (s.uv, s.size) {
        (UvSource::Generate, size) => {
            let options = UnwrapOptions {
                size,
                padding: s.padding,
                packing: s.packing,
            };
            let pb = bar(s.progress, 0, "unwrap");
            let report = |stage: &'static str, done: usize, total: Option<usize>| {
                pb.set_message(stage);
                pb.set_length(total.unwrap_or(done + 1) as u64);
                pb.set_position(done as u64);
            };
            let atlas =
                unwrap::unwrap_with_progress(&geometry.receivers, &options, diagonal, &report);
            pb.finish_and_clear();
            atlas?
        }
        (UvSource::Existing(set), AtlasSize::Resolution(r)) => {
            unwrap::existing(scene, &geometry.receivers, set, r)?
        }
        (UvSource::Existing(_), AtlasSize::TexelDensity(_)) => {
            return Err(Error::Option(
                "--texel-density needs generated UVs; give --resolution with --uv existing".into(),
            ));
        }
    };
    t.lap("unwrap");
    let need = estimated_bytes(atlas.width, atlas.height, s);
    if need > MAX_BAKE_BYTES {
        return Err(Error::Limit(format!(
            "a {}x{} atlas needs about {:.1} GiB of memory to bake, more than the {} GiB limit; lower --resolution or --texel-density",
            atlas.width,
            atlas.height,
            need as f64 / (1u64 << 30) as f64,
            MAX_BAKE_BYTES >> 30
        )));
    }
    let receivers = rasterize::rasterize(&geometry.receivers, &atlas);
    if let (UvSource::Existing(set), Some((a, b))) = (s.uv, receivers.first_overlap) {
        let name = |k: u32| {
            let g = &scene.geometries
                [scene.instances[geometry.receivers[k as usize].instance].geometry];
            format!("meshes[{}].primitives[{}]", g.mesh, g.primitive)
        };
        return Err(Error::Option(format!(
            "TEXCOORD_{set} of {} and {} overlap ({} texels): --uv existing needs one shared, non-overlapping lightmap layout; use --uv generate",
            name(a),
            name(b),
            receivers.overlapping_texels
        )));
    }
    if receivers.is_empty() {
        return Err(Error::Empty(
            "no texel is covered: every baked triangle is degenerate".into(),
        ));
    }
    t.lap("rasterize");
    let tracer = Tracer::with_sides(&geometry.occluders, &geometry.occluder_single_sided);
    t.lap("bvh");
    let max_distance = (max_distance_world / diagonal).min(f32::MAX as f64) as f32;
    let inside = if s.fill_inside {
        crate::validity::inside_geometry(&receivers, &tracer, max_distance)
    } else {
        vec![false; receivers.len()]
    };
    t.lap("validity");
    Ok(Prepared {
        geometry,
        atlas,
        receivers,
        tracer,
        max_distance_world,
        max_distance,
        inside,
        stages: t.stages,
    })
}

/// Runs the method's passes (Monte Carlo, or sparse and filter passes) over
/// prepared receivers.
pub fn bake_prepared(p: &Prepared, s: &Settings) -> Result<BakePasses> {
    let (receivers, tracer) = (&p.receivers, &p.tracer);
    let mut t = Timer::new();
    let mc_settings = McSettings {
        rays: s.rays,
        max_distance: p.max_distance,
        seed: s.seed,
    };
    let pb = bar(s.progress, receivers.len() as u64, "baking");
    let (bake, filter_stats) = match s.method {
        Method::Mc => {
            let b = mc::bake(receivers, tracer, &mc_settings, &|n| pb.inc(n));
            t.lap("trace");
            (b, None)
        }
        Method::Filtered => {
            check_filter_options(&s.filter)?;
            let fs = filter_settings(s, mc_settings.max_distance);
            let order = filter::locality_order(receivers);
            let local = filter::permuted(receivers, &order);
            let samples = filter::sparse_pass(&local, tracer, &fs);
            t.lap("sparse pass");
            let (b, stats) = filter::filter_pass(&local, &samples, tracer, &fs, &|n| pb.inc(n))?;
            let (b, stats) = filter::unpermuted(b, stats, &order);
            t.lap("filter pass");
            (b, Some(stats))
        }
    };
    pb.finish_and_clear();
    Ok(BakePasses {
        bake,
        filter_stats,
        stages: t.stages,
    })
}

/// Whether two paths name the same file (the second may not exist yet).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// Bakes `input` into `output` (written atomically; `input` is never touched).
pub fn run(input: &Path, output: &Path, settings: &Settings) -> Result<Report> {
    if same_file(input, output) {
        return Err(Error::Option(format!(
            "output {} is the input file; choose another path (the input is never overwritten)",
            output.display()
        )));
    }
    let baked = bake_file(input, settings)?;
    let t = Instant::now();
    let out_dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let in_dir = match input.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if same_file(in_dir, out_dir) {
        write::write_atomic(output, &baked.glb)?;
    } else {
        // Relative URIs of external buffers and images must resolve from the output.
        let (mut json, bin) = write::split_glb(&baked.glb);
        write::relocate_uris(&mut json, in_dir, out_dir)?;
        write::write_atomic(output, &write::glb_bytes(&json, &bin))?;
    }
    let mut report = baked.report;
    let secs = t.elapsed().as_secs_f64();
    report.stages.push(StageTime {
        stage: "save",
        seconds: secs,
    });
    report.total_seconds += secs;
    Ok(report)
}
