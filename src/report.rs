//! Report (`aobake report`): what quality each second buys, for one scene.
//!
//! In: a loaded [`Scene`] and [`ReportSettings`]. Out: a [`SweepReport`]
//! and, with [`write_report`], a directory of `report.json`, `report.md`,
//! `error_vs_time.svg`/`.png`, AO error maps of each method's default
//! settings and the filter's brute-force fraction map.
//!
//! The scene is unwrapped, rasterized and its BVH built once
//! ([`pipeline::prepare`]); a high-ray Monte Carlo *reference* and every
//! run of the sweep bake those same receivers, so errors compare texel by
//! texel. A run's end-to-end time is the shared stages (measured once,
//! including encode and write of the reference) plus its own passes.
//! The reference uses a different seed from the runs, so a run is never
//! correlated with it.

use crate::error::{Error, Result};
use crate::load::Scene;
use crate::metrics::{ErrorStats, cost_at_error, error_stats, loglog_at, sh_band_rmse};
use crate::pipeline::{self, FilterOptions, Method, Prepared, Settings, StageTime};
use crate::rasterize::Receivers;
use crate::unwrap::AtlasSize;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The sweep used when `--budgets` is not given.
pub const DEFAULT_BUDGETS: &str = "mc:8,mc:16,mc:32,mc:64,mc:128,mc:256,mc:512,\
filtered:4:4,filtered:8:4,filtered:16:4,filtered:8:8,filtered:16:8";

/// Monte Carlo rays whose error is the equal-error target (the `--rays`
/// default).
pub const TARGET_RAYS: u32 = 256;

/// One run of the sweep: a method and its budget.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    pub method: Method,
    /// Monte Carlo rays per texel (Monte Carlo only).
    pub rays: u32,
    pub filter: FilterOptions,
}

impl Budget {
    /// `mc:N` or `filtered:K:R[:C[:O[:W]]]` (sparse rays, gather radius,
    /// rays per brute-forced cell, Omega_v, min weight).
    pub fn label(&self) -> String {
        match self.method {
            Method::Mc => format!("mc:{}", self.rays),
            Method::Filtered => {
                let f = &self.filter;
                let d = FilterOptions::default();
                let mut s = format!("filtered:{}:{}", f.sparse_rays, f.gather_radius);
                if (f.cell_rays, f.omega_v_max, f.min_weight)
                    != (d.cell_rays, d.omega_v_max, d.min_weight)
                {
                    s += &format!(":{}:{}:{}", f.cell_rays, f.omega_v_max, f.min_weight);
                }
                s
            }
        }
    }

    fn is_default(&self) -> bool {
        match self.method {
            Method::Mc => self.rays == TARGET_RAYS,
            Method::Filtered => self.filter == FilterOptions::default(),
        }
    }
}

/// Parses a comma-separated budget list (see [`Budget::label`]).
pub fn parse_budgets(text: &str) -> Result<Vec<Budget>> {
    let bad = |item: &str, why: &str| Error::Option(format!("--budgets: '{item}': {why}"));
    let mut out = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let parts: Vec<&str> = item.split(':').collect();
        let num = |i: usize| -> Result<Option<f64>> {
            match parts.get(i) {
                None => Ok(None),
                Some(p) => match p.parse::<f64>() {
                    Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
                    _ => Err(bad(item, "numbers must be finite and > 0")),
                },
            }
        };
        let budget = match parts[0] {
            "mc" => {
                if parts.len() != 2 {
                    return Err(bad(item, "expected mc:RAYS"));
                }
                let rays = num(1)?.unwrap_or(0.0);
                if rays.fract() != 0.0 || rays > 1e6 {
                    return Err(bad(item, "rays must be a whole number up to 1000000"));
                }
                Budget {
                    method: Method::Mc,
                    rays: rays as u32,
                    filter: FilterOptions::default(),
                }
            }
            "filtered" => {
                if parts.len() > 6 {
                    return Err(bad(item, "expected filtered:K:R[:C[:O[:W]]]"));
                }
                let mut f = FilterOptions::default();
                if let Some(k) = num(1)? {
                    if k.fract() != 0.0 || k > 1024.0 {
                        return Err(bad(item, "sparse rays must be a whole number up to 1024"));
                    }
                    f.sparse_rays = k as u32;
                }
                if let Some(r) = num(2)? {
                    f.gather_radius = r as f32;
                }
                if let Some(c) = num(3)? {
                    if c.fract() != 0.0 || c > 1024.0 {
                        return Err(bad(item, "cell rays must be a whole number up to 1024"));
                    }
                    f.cell_rays = c as u32;
                }
                if let Some(o) = num(4)? {
                    f.omega_v_max = o as f32;
                }
                if let Some(w) = num(5)? {
                    f.min_weight = w as f32;
                }
                Budget {
                    method: Method::Filtered,
                    rays: 0,
                    filter: f,
                }
            }
            other => {
                return Err(bad(
                    item,
                    &format!("unknown method '{other}' (mc or filtered)"),
                ));
            }
        };
        out.push(budget);
    }
    if out.is_empty() {
        return Err(Error::Option("--budgets is empty".into()));
    }
    Ok(out)
}

/// What `aobake report` is told.
#[derive(Clone, Debug)]
pub struct ReportSettings {
    /// Atlas page edge in texels.
    pub resolution: u32,
    pub reference_rays: u32,
    pub budgets: Vec<Budget>,
    /// Seed of the runs (the reference uses another one).
    pub seed: u64,
    /// World units; `None`: the pipeline's default.
    pub max_distance: Option<f64>,
    /// Monte Carlo rays of the scale-stability bakes; 0 skips them.
    pub stability_rays: u32,
    /// Also run each method's default settings if `budgets` lacks them
    /// (their error maps are drawn and 256-ray Monte Carlo sets the
    /// equal-error target).
    pub include_defaults: bool,
    pub progress: bool,
}

impl Default for ReportSettings {
    fn default() -> Self {
        ReportSettings {
            resolution: 512,
            reference_rays: 2048,
            budgets: parse_budgets(DEFAULT_BUDGETS).expect("default budgets parse"),
            seed: 0,
            max_distance: None,
            stability_rays: 64,
            include_defaults: true,
            progress: true,
        }
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
    /// Shared stages plus this run's passes.
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
}

/// The equal-error comparison at the error of 256-ray Monte Carlo.
#[derive(Clone, Debug, Serialize)]
pub struct EqualError {
    /// AO RMSE of 256-ray Monte Carlo (measured, or interpolated in log-log
    /// between the nearest Monte Carlo runs).
    pub target_ao_rmse: f64,
    /// End-to-end seconds at which each method's best runs reach it.
    pub mc_seconds: Option<f64>,
    pub filtered_seconds: Option<f64>,
    /// mc_seconds / filtered_seconds (> 1: filtered is faster).
    pub speedup: Option<f64>,
    /// Smallest AO RMSE any filtered run reached.
    pub best_filtered_ao_rmse: Option<f64>,
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
    pub charts: u32,
    pub occluder_triangles: usize,
    pub max_distance_world: f64,
    pub seed: u64,
    pub reference_rays: u32,
    pub reference_seed: u64,
    pub reference_seconds: f64,
    /// Stages every run shares (load, unwrap, rasterize, BVH, dilate,
    /// encode, write), measured once.
    pub shared_stages: Vec<StageTime>,
    pub shared_seconds: f64,
    pub runs: Vec<RunFigures>,
    pub equal_error: Option<EqualError>,
    pub stability: Vec<StabilityRow>,
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

/// Seed of the reference: never one a run uses.
fn reference_seed(seed: u64) -> u64 {
    seed ^ 0x5eed_0f2e_f02e_2ce5
}

fn settings_for(base: &Settings, b: &Budget, seed: u64) -> Settings {
    Settings {
        method: b.method,
        rays: b.rays,
        filter: b.filter,
        seed,
        ..base.clone()
    }
}

/// Runs the sweep on a loaded scene. `load_seconds` joins the shared stages.
pub fn sweep(scene: &Scene, input: &str, load_seconds: f64, rs: &ReportSettings) -> Result<Sweep> {
    if rs.reference_rays == 0 {
        return Err(Error::Option("--reference-rays must be at least 1".into()));
    }
    let mut budgets = rs.budgets.clone();
    // Each method's default settings are always measured (their error maps
    // are drawn and the equal-error target is 256-ray Monte Carlo).
    for d in [
        Budget {
            method: Method::Mc,
            rays: TARGET_RAYS,
            filter: FilterOptions::default(),
        },
        Budget {
            method: Method::Filtered,
            rays: 0,
            filter: FilterOptions::default(),
        },
    ] {
        if rs.include_defaults
            && !budgets
                .iter()
                .any(|b| b.method == d.method && b.is_default())
        {
            budgets.push(d);
        }
    }
    let base = Settings {
        size: AtlasSize::Resolution(rs.resolution),
        max_distance: rs.max_distance,
        progress: false,
        ..Default::default()
    };
    let total_steps = 1 + budgets.len() as u64 + if rs.stability_rays > 0 { 3 } else { 0 };
    let pb = pipeline::bar(rs.progress, total_steps, "report");
    pb.set_message("prepare");
    let prepared = pipeline::prepare(scene, &base)?;
    let texels = prepared.receivers.len();

    // The reference, through the whole pipeline once to time the shared
    // output stages.
    pb.set_message(format!("reference (mc:{})", rs.reference_rays));
    let ref_budget = Budget {
        method: Method::Mc,
        rays: rs.reference_rays,
        filter: FilterOptions::default(),
    };
    let ref_settings = settings_for(&base, &ref_budget, reference_seed(rs.seed));
    let t = Instant::now();
    let reference = pipeline::bake_prepared(&prepared, &ref_settings)?;
    let reference_seconds = t.elapsed().as_secs_f64();
    let out_stages = pipeline::output(scene, &prepared, &reference, &ref_settings)?.stages;
    pb.inc(1);
    let mut shared_stages = vec![StageTime {
        stage: "load",
        seconds: load_seconds,
    }];
    shared_stages.extend(prepared.stages.iter().cloned());
    shared_stages.extend(out_stages);
    let shared_seconds: f64 = shared_stages.iter().map(|s| s.seconds).sum();
    let ref_ao = &reference.bake.ao;
    let ref_sh = &reference.bake.sh;
    let ref_sh_flat: Vec<f32> = ref_sh.iter().flatten().copied().collect();

    let mut runs = Vec::new();
    let mut default_ao = Vec::new();
    let mut brute_fraction = None;
    for b in &budgets {
        let label = b.label();
        pb.set_message(label.clone());
        let s = settings_for(&base, b, rs.seed);
        let t = Instant::now();
        let passes = pipeline::bake_prepared(&prepared, &s)?;
        let bake_seconds = t.elapsed().as_secs_f64();
        let ao = error_stats(&passes.bake.ao, ref_ao);
        let sh_flat: Vec<f32> = passes.bake.sh.iter().flatten().copied().collect();
        let fs = passes.filter_stats.as_ref();
        let default_settings = b.is_default();
        if default_settings && !default_ao.iter().any(|(l, _)| *l == label) {
            default_ao.push((label.clone(), passes.bake.ao.clone()));
            if let Some(f) = fs {
                brute_fraction = Some(f.brute_fraction.clone());
            }
        }
        runs.push(RunFigures {
            label,
            method: b.method,
            default_settings,
            passes: passes.stages.clone(),
            bake_seconds,
            end_to_end_seconds: shared_seconds + bake_seconds,
            rays_cast: passes.bake.rays,
            rays_per_texel: passes.bake.rays as f64 / texels.max(1) as f64,
            ao,
            sh_rmse_band: sh_band_rmse(&passes.bake.sh, ref_sh),
            sh_rmse: error_stats(&sh_flat, &ref_sh_flat).rmse,
            cells_filtered: fs.map(|f| f.cell_share(f.cells_filtered)),
            cells_brute_forced: fs.map(|f| f.cell_share(f.cells_brute)),
            cells_brute_contact: fs.map(|f| f.cell_share(f.cells_contact)),
            cells_brute_no_hit: fs.map(|f| f.cell_share(f.cells_no_hit)),
        });
        pb.inc(1);
    }
    let equal_error = equal_error(&runs);

    let stability = if rs.stability_rays > 0 {
        pb.set_message("scale stability");
        let r = stability(scene, &base, &prepared, rs, ref_ao)?;
        pb.inc(3);
        r
    } else {
        Vec::new()
    };
    pb.finish_and_clear();

    let report = SweepReport {
        aobake_version: env!("CARGO_PKG_VERSION"),
        input: input.to_string(),
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        threads: rayon::current_num_threads(),
        resolution: rs.resolution,
        atlas_width: prepared.atlas.width,
        atlas_height: prepared.atlas.height,
        texels,
        charts: prepared.atlas.charts,
        occluder_triangles: prepared.tracer.triangle_count(),
        max_distance_world: prepared.max_distance_world,
        seed: rs.seed,
        reference_rays: rs.reference_rays,
        reference_seed: reference_seed(rs.seed),
        reference_seconds,
        shared_stages,
        shared_seconds,
        runs,
        equal_error,
        stability,
        files: Vec::new(),
    };
    Ok(Sweep {
        report,
        reference_ao: reference.bake.ao,
        receivers: prepared.receivers,
        default_ao,
        brute_fraction,
    })
}

/// The equal-error comparison of a sweep's runs (see [`EqualError`]).
pub fn equal_error(runs: &[RunFigures]) -> Option<EqualError> {
    let curve = |m: Method| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r.method == m)
            .map(|r| (r.end_to_end_seconds, r.ao.rmse))
            .collect()
    };
    let mc_by_rays: Vec<(f64, f64)> = runs
        .iter()
        .filter(|r| r.method == Method::Mc)
        .map(|r| (r.rays_per_texel, r.ao.rmse))
        .collect();
    let target = loglog_at(&mc_by_rays, TARGET_RAYS as f64)?;
    let mc_seconds = cost_at_error(&curve(Method::Mc), target);
    let filtered = curve(Method::Filtered);
    let filtered_seconds = cost_at_error(&filtered, target);
    Some(EqualError {
        target_ao_rmse: target,
        mc_seconds,
        filtered_seconds,
        speedup: match (mc_seconds, filtered_seconds) {
            (Some(m), Some(f)) if f > 0.0 => Some(m / f),
            _ => None,
        },
        best_filtered_ao_rmse: filtered.iter().map(|p| p.1).min_by(f64::total_cmp),
    })
}

/// The scene uniformly scaled by `scale` (every placement's transform).
pub fn scaled_scene(scene: &Scene, scale: f64) -> Scene {
    let mut s = scene.clone();
    let m = glam::DMat4::from_scale(glam::DVec3::splat(scale));
    for inst in &mut s.instances {
        inst.transform = m * inst.transform;
    }
    s
}

/// Bakes the scene at 1, 1e-4 and 1e4 scale with the max distance scaled
/// alike and compares the AO texel by texel.
fn stability(
    scene: &Scene,
    base: &Settings,
    prepared: &Prepared,
    rs: &ReportSettings,
    reference_ao: &[f32],
) -> Result<Vec<StabilityRow>> {
    let budget = Budget {
        method: Method::Mc,
        rays: rs.stability_rays,
        filter: FilterOptions::default(),
    };
    let s = settings_for(base, &budget, rs.seed);
    let unscaled = pipeline::bake_prepared(prepared, &s)?.bake.ao;
    let noise = error_stats(&unscaled, reference_ao).rmse;
    let mut rows = Vec::new();
    for scale in [1e-4, 1e4] {
        let scaled = scaled_scene(scene, scale);
        let max_distance_world = prepared.max_distance_world * scale;
        let ss = Settings {
            max_distance: Some(max_distance_world),
            // Raw AO is compared, the inside fill is not: skip its pass.
            fill_inside: false,
            ..s.clone()
        };
        let p = pipeline::prepare(&scaled, &ss)?;
        if p.receivers.texel != prepared.receivers.texel {
            return Err(Error::Limit(format!(
                "the scene scaled by {scale:e} unwrapped to different texels; the stability table needs the same atlas"
            )));
        }
        let ao = pipeline::bake_prepared(&p, &ss)?.bake.ao;
        let d = error_stats(&ao, &unscaled);
        rows.push(StabilityRow {
            scale,
            max_distance_world,
            ao_rmse_difference: d.rmse,
            ao_max_difference: d.max,
            monte_carlo_noise_rmse: noise,
            same_within_noise: d.rmse <= noise,
        });
    }
    Ok(rows)
}

/// AO error map: red where `values` are darker than `reference`, green
/// where brighter (the paper's Figure 7), full intensity at `full_scale`
/// error; texels no receiver covers are dark grey.
pub fn error_map_rgb(
    receivers: &Receivers,
    values: &[f32],
    reference: &[f32],
    full_scale: f32,
) -> Vec<u8> {
    let (w, h) = (receivers.width as usize, receivers.height as usize);
    let mut img = vec![32u8; w * h * 3];
    for (r, &t) in receivers.texel.iter().enumerate() {
        let e = values[r] - reference[r];
        let v = if e.is_finite() {
            ((e.abs() / full_scale).min(1.0) * 255.0).round() as u8
        } else {
            255
        };
        let px = &mut img[t as usize * 3..t as usize * 3 + 3];
        px.copy_from_slice(&if e < 0.0 { [v, 0, 0] } else { [0, v, 0] });
    }
    img
}

/// Full intensity of the error maps: this much AO error.
pub const ERROR_MAP_FULL_SCALE: f32 = 0.1;

/// Writes the report files into `dir` and returns the report with their names.
pub fn write_report(sweep: &Sweep, dir: &Path) -> Result<SweepReport> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let write = |name: &str, bytes: &[u8]| -> Result<()> {
        crate::write::write_atomic(&dir.join(name), bytes)
    };
    let mut report = sweep.report.clone();
    let mut files = Vec::new();
    let (w, h) = (sweep.receivers.width, sweep.receivers.height);
    for (label, ao) in &sweep.default_ao {
        let name = format!("error_map_{}.png", label.replace(':', "_"));
        let img = error_map_rgb(
            &sweep.receivers,
            ao,
            &sweep.reference_ao,
            ERROR_MAP_FULL_SCALE,
        );
        write(
            &name,
            &crate::encode::png(w, h, &img, image::ExtendedColorType::Rgb8)?,
        )?;
        files.push(name);
    }
    if let Some(bf) = &sweep.brute_fraction {
        let name = "brute_force_fraction.png".to_string();
        write(
            &name,
            &crate::encode::grey_map(&sweep.receivers, |r| bf[r])?,
        )?;
        files.push(name);
    }
    let (svg, png) = crate::plot::error_vs_time(&report)?;
    write("error_vs_time.svg", svg.as_bytes())?;
    write("error_vs_time.png", &png)?;
    files.push("error_vs_time.svg".into());
    files.push("error_vs_time.png".into());
    files.push("report.md".into());
    files.push("report.json".into());
    report.files = files;
    write("report.md", markdown(&report).as_bytes())?;
    let json = serde_json::to_vec_pretty(&report)
        .map_err(|e| Error::Limit(format!("cannot serialize the report: {e}")))?;
    write("report.json", &json)?;
    Ok(report)
}

/// The report as a Markdown page.
pub fn markdown(r: &SweepReport) -> String {
    let mut s = String::new();
    let mut line = |t: String| {
        s.push_str(&t);
        s.push('\n');
    };
    line(format!("# aobake report: {}\n", r.input));
    line(format!(
        "aobake {}, {} cores ({} threads). Atlas {}x{} ({} texels, {} charts), {} occluder triangles, max distance {:.4} (world units).\n",
        r.aobake_version,
        r.cores,
        r.threads,
        r.atlas_width,
        r.atlas_height,
        r.texels,
        r.charts,
        r.occluder_triangles,
        r.max_distance_world
    ));
    line(format!(
        "Reference: {}-ray Monte Carlo (seed {}), {:.2} s. Shared stages (load, unwrap, rasterize, BVH, dilate, encode, write): {:.2} s, counted in every end-to-end time. Errors are per texel against the reference; AO bias > 0 means too bright.\n",
        r.reference_rays, r.reference_seed, r.reference_seconds, r.shared_seconds
    ));
    line("| run | end-to-end s | passes s | rays/texel | AO RMSE | AO bias | AO p99 | AO max | SH RMSE L0 | L1 | L2 | cells brute-forced (contact, no hit) |".into());
    line("|---|---|---|---|---|---|---|---|---|---|---|---|".into());
    for run in &r.runs {
        let passes: Vec<String> = run
            .passes
            .iter()
            .map(|p| format!("{} {:.2}", p.stage, p.seconds))
            .collect();
        line(format!(
            "| {}{} | {:.2} | {} | {:.1} | {:.4} | {:+.4} | {:.3} | {:.3} | {:.4} | {:.4} | {:.4} | {} |",
            run.label,
            if run.default_settings {
                " (default)"
            } else {
                ""
            },
            run.end_to_end_seconds,
            passes.join(", "),
            run.rays_per_texel,
            run.ao.rmse,
            run.ao.bias,
            run.ao.p99,
            run.ao.max,
            run.sh_rmse_band[0],
            run.sh_rmse_band[1],
            run.sh_rmse_band[2],
            match (
                run.cells_brute_forced,
                run.cells_brute_contact,
                run.cells_brute_no_hit,
            ) {
                (Some(b), Some(c), Some(u)) =>
                    format!("{:.1}% ({:.1}%, {:.1}%)", 100.0 * b, 100.0 * c, 100.0 * u),
                _ => "-".into(),
            }
        ));
    }
    if let Some(e) = &r.equal_error {
        line(String::new());
        let fmt = |v: Option<f64>| v.map_or("not reached".to_string(), |v| format!("{v:.2} s"));
        line(format!(
            "**Equal error** at {}-ray Monte Carlo's AO RMSE {:.4}: Monte Carlo {}, filtered {}; {}",
            TARGET_RAYS,
            e.target_ao_rmse,
            fmt(e.mc_seconds),
            fmt(e.filtered_seconds),
            match e.speedup {
                Some(x) => format!("filtered is {x:.2}x as fast."),
                None => format!(
                    "no filtered run reached it (best filtered AO RMSE {}).",
                    e.best_filtered_ao_rmse
                        .map_or("-".into(), |v| format!("{v:.4}"))
                ),
            }
        ));
    }
    if !r.stability.is_empty() {
        line(String::new());
        line("**Scale stability** (the scene scaled uniformly, max distance alike; AO against the unscaled bake with the same rays and seed):\n".into());
        line("| scale | max distance (world) | AO RMSE difference | AO max difference | Monte Carlo noise (RMSE vs reference) | same within noise |".into());
        line("|---|---|---|---|---|---|".into());
        for row in &r.stability {
            line(format!(
                "| {:e} | {:.4e} | {:.2e} | {:.2e} | {:.4} | {} |",
                row.scale,
                row.max_distance_world,
                row.ao_rmse_difference,
                row.ao_max_difference,
                row.monte_carlo_noise_rmse,
                if row.same_within_noise { "yes" } else { "no" }
            ));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_parse_and_refuse() {
        let b = parse_budgets("mc:8, filtered:16:6, filtered:8:4:3:1.5:2").unwrap();
        assert_eq!(b.len(), 3);
        assert_eq!((b[0].method, b[0].rays), (Method::Mc, 8));
        assert_eq!(b[1].filter.sparse_rays, 16);
        assert_eq!(b[1].filter.gather_radius, 6.0);
        assert_eq!(b[2].filter.cell_rays, 3);
        assert_eq!(b[2].filter.omega_v_max, 1.5);
        assert_eq!(b[2].filter.min_weight, 2.0);
        assert_eq!(b[0].label(), "mc:8");
        assert_eq!(b[1].label(), "filtered:16:6");
        assert_eq!(b[2].label(), "filtered:8:4:3:1.5:2");
        for bad in [
            "",
            "mc",
            "mc:0",
            "mc:-4",
            "mc:1.5",
            "mc:nan",
            "pt:4",
            "filtered:a",
            "mc:8:9",
        ] {
            assert!(parse_budgets(bad).is_err(), "{bad}");
        }
        assert!(parse_budgets(DEFAULT_BUDGETS).unwrap().len() >= 10);
    }

    fn run(method: Method, seconds: f64, rays: f64, rmse: f64) -> RunFigures {
        RunFigures {
            label: String::new(),
            method,
            default_settings: false,
            passes: Vec::new(),
            bake_seconds: seconds,
            end_to_end_seconds: seconds,
            rays_cast: 0,
            rays_per_texel: rays,
            ao: ErrorStats {
                rmse,
                ..Default::default()
            },
            sh_rmse_band: [0.0; 3],
            sh_rmse: 0.0,
            cells_filtered: None,
            cells_brute_forced: None,
            cells_brute_contact: None,
            cells_brute_no_hit: None,
        }
    }

    #[test]
    fn equal_error_speedup() {
        // MC: error 0.16/sqrt(rays), time = rays / 64 s; error at 256 rays
        // is 0.01, reached at 4 s. Filtered reaches 0.01 at 1 s: 4x.
        let mut runs: Vec<RunFigures> = [16.0, 64.0, 1024.0]
            .iter()
            .map(|&n: &f64| run(Method::Mc, n / 64.0, n, 0.16 / n.sqrt()))
            .collect();
        runs.push(run(Method::Filtered, 0.5, 10.0, 0.02));
        runs.push(run(Method::Filtered, 2.0, 40.0, 0.005));
        let e = equal_error(&runs).unwrap();
        assert!((e.target_ao_rmse - 0.01).abs() < 1e-12);
        assert!((e.mc_seconds.unwrap() - 4.0).abs() < 1e-9);
        assert!((e.filtered_seconds.unwrap() - 1.0).abs() < 1e-9);
        assert!((e.speedup.unwrap() - 4.0).abs() < 1e-9);
        // No filtered run good enough: no speed-up, best error reported.
        runs.truncate(4);
        let e = equal_error(&runs).unwrap();
        assert_eq!(e.speedup, None);
        assert_eq!(e.best_filtered_ao_rmse, Some(0.02));
    }

    #[test]
    fn error_map_colours() {
        let receivers = Receivers {
            width: 3,
            height: 1,
            texel: vec![0, 2],
            ..Default::default()
        };
        let img = error_map_rgb(&receivers, &[0.45, 0.6], &[0.5, 0.5], 0.1);
        // Too dark by 0.05: half red. Too bright by 0.1: full green.
        assert_eq!(&img[0..3], &[128, 0, 0]);
        assert_eq!(&img[3..6], &[32, 32, 32]);
        assert_eq!(&img[6..9], &[0, 255, 0]);
    }
}
