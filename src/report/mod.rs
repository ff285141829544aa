//! Report (`aobake report`): what quality each second buys, for one scene.
//!
//! In: a loaded [`Scene`] and [`ReportSettings`]. Out: a [`SweepReport`]
//! and, with [`write_report`], a directory of `report.json`, `report.md`,
//! `error_vs_time.svg`/`.png`, AO error maps of each method's default
//! settings and the filter's brute-force fraction map.
//!
//! - `mod.rs`: the sweep and the equal-error comparison;
//! - `budget`: the runs (`--budgets`);
//! - `figures`: what a sweep measured ([`SweepReport`]) and is told;
//! - [`metrics`]: error statistics and log-log interpolation;
//! - `plot`: log-log curves of plain points (plotters);
//! - `files`: the error maps and the files of a report directory;
//! - [`markdown`](mod@markdown): `report.md`.
//!
//! The scene is unwrapped, rasterized and its BVH built once (one
//! [`Level`] and its [`Page`] 0, through the job's API); a high-ray Monte Carlo *reference* and every
//! run of the sweep bake those same receivers, so errors compare texel by
//! texel. A run's end-to-end time is the shared stages (measured once:
//! load, unwrap, rasterize, BVH, the write of the reference's file) plus
//! its own passes and its own output stages (border fit, seams, dilate,
//! encode: their cost follows the run's noise and method, so each run
//! pays its own), as a bake from the command line would.
//! The reference uses a different seed from the runs, so a run is never
//! correlated with it.

pub(crate) mod budget;
pub(crate) mod figures;
pub(crate) mod files;
pub mod markdown;
pub mod metrics;
pub(crate) mod plot;

pub use budget::{Budget, DEFAULT_BUDGETS, TARGET_RAYS, parse_budgets};
pub use figures::{
    EqualError, MethodAtError, ReportSettings, RunFigures, StabilityRow, Sweep, SweepReport,
};
pub use files::{ERROR_MAP_FULL_SCALE, error_map_rgb, write_report};
pub use markdown::markdown;

use crate::atlas::AtlasSize;
use crate::error::{Error, Result};
use crate::gltf::Scene;
use crate::job::{BakeSettings, Level, Method, Page, RunOptions};
use crate::stage::{StageTimer, progress_bar, seconds_of};
use metrics::{cost_at_error, error_stats, loglog_at, sh_band_rmse};

/// Seed of the reference: never one a run uses.
fn reference_seed(seed: u64) -> u64 {
    seed ^ 0x5eed_0f2e_f02e_2ce5
}

/// The values of `v` at the texels `indices`, in their order.
fn picked<T: Copy>(v: &[T], indices: &[usize]) -> Vec<T> {
    indices.iter().map(|&i| v[i]).collect()
}

/// Runs the sweep on a loaded scene. `timer` holds the stages so far (the
/// load); they join the shared stages.
pub fn sweep(
    scene: &Scene,
    input: &str,
    mut timer: StageTimer,
    rs: &ReportSettings,
) -> Result<Sweep> {
    rs.validate()?;
    let mut budgets = rs.budgets.clone();
    // Monte Carlo's and the adaptive method's default settings are always
    // measured, the sheared method's when it is swept (their error maps are
    // drawn and the equal-error target is 256-ray Monte Carlo).
    let sheared = budgets.iter().any(|b| b.method == Method::Sheared);
    let defaults = [
        Some(Budget::mc(TARGET_RAYS)),
        Some(Budget::adaptive_default()),
        sheared.then(Budget::sheared_default),
    ];
    for d in defaults.into_iter().flatten() {
        if rs.include_defaults
            && !budgets
                .iter()
                .any(|b| b.method == d.method && b.is_default())
        {
            budgets.push(d);
        }
    }
    let base = BakeSettings {
        size: AtlasSize::Resolution(rs.resolution),
        max_distance: rs.max_distance,
        ..Default::default()
    };
    let run = RunOptions::QUIET;
    // Every run's settings, before the first stage.
    let ref_settings = Budget::mc(rs.reference_rays).settings(&base, reference_seed(rs.seed));
    ref_settings.validate()?;
    for b in &budgets {
        b.settings(&base, rs.seed).validate()?;
    }
    let total_steps = 1 + budgets.len() as u64 + if rs.stability_rays > 0 { 3 } else { 0 };
    let pb = progress_bar(rs.progress, total_steps, "report");
    pb.set_message("prepare");
    // The validity stage is shared (its inside texels are left out of every
    // comparison), with the runs' seed: the adaptive method makes the same
    // test on the same rays in its pre-pass and is not charged for it.
    let with_validity = BakeSettings {
        method: Method::Mc,
        seed: rs.seed,
        ..base.clone()
    };
    let level = Level::new(scene, &with_validity, &run, &mut timer)?;
    let prepared = level.page(0, scene, &mut timer)?;
    let inside: &[bool] = prepared.inside.as_deref().unwrap_or_default();
    let texels = prepared.receivers.len();

    // The reference, through the whole pipeline once to time the shared
    // output stages.
    pb.set_message(format!("reference (mc:{})", rs.reference_rays));
    let mut ref_timer = StageTimer::new();
    let reference = prepared.bake(&ref_settings, &run, &mut ref_timer)?;
    let reference_seconds = ref_timer.total();
    // The reference's output stages are its own, not shared.
    let out = prepared.finish(&reference, &ref_settings, &run, &mut StageTimer::new())?;
    crate::job::write(
        scene,
        &level,
        &[&out.encoded],
        &ref_settings,
        None,
        None,
        &mut timer,
    )?;
    let reference_seams = out.seams;
    pb.inc(1);
    let shared_seconds = timer.total();
    let shared_stages = timer.into_stages();
    let validity_seconds = seconds_of(&shared_stages, "validity");
    // Texels inside geometry never reach the output (the fill replaces
    // them with their nearest valid texel's value), and the adaptive method
    // spends only its pre-pass on them: every run is compared on the others.
    let compared: Vec<usize> = (0..texels).filter(|&i| !inside[i]).collect();
    let ref_ao = &picked(&reference.bake.ao, &compared);
    let ref_sh = &picked(&reference.bake.sh, &compared);
    let ref_sh_flat: Vec<f32> = ref_sh.iter().flatten().copied().collect();

    // The engine view's points and their reference, once.
    // A run with the visibility layer is measured against this reference's
    // layer (`--visibility auto` bakes one only where a material reads it).
    let probe = (rs.engine_view_points > 0).then(|| {
        pb.set_message("engine-view reference");
        prepared.engine_probe(
            rs.engine_view_points,
            rs.reference_rays,
            reference_seed(rs.seed) ^ 0xe9,
            level.bakes_visibility(),
        )
    });

    let mut runs = Vec::new();
    let mut default_ao = Vec::new();
    let mut brute_fraction = None;
    for b in &budgets {
        let label = b.label();
        pb.set_message(label.clone());
        let s = b.settings(&base, rs.seed);
        let mut run_timer = StageTimer::new();
        let passes = prepared.bake(&s, &run, &mut run_timer)?;
        let bake_seconds = run_timer.total();
        let ao = error_stats(&picked(&passes.bake.ao, &compared), ref_ao);
        let run_sh = picked(&passes.bake.sh, &compared);
        let sh_flat: Vec<f32> = run_sh.iter().flatten().copied().collect();
        let fs = passes.sheared_stats.as_ref();
        // The run's output stages, timed into its end-to-end seconds; what
        // the engine reads is their textures, looked up at the points.
        let mut output_timer = StageTimer::new();
        let out = prepared.finish(&passes, &s, &run, &mut output_timer)?;
        let output_seconds = output_timer.total();
        let engine_view = match &probe {
            Some(probe) => Some(prepared.engine_view_against(probe, &out.encoded, s.filter)?),
            None => None,
        };
        let mut stages = passes.stages.clone();
        stages.extend(output_timer.into_stages());
        let default_settings = b.is_default();
        if default_settings && !default_ao.iter().any(|(l, _)| *l == label) {
            // The maps show texels inside geometry as the reference's (not
            // compared: filled in the output).
            let mut ao = passes.bake.ao.clone();
            for (i, a) in ao.iter_mut().enumerate() {
                if inside[i] {
                    *a = reference.bake.ao[i];
                }
            }
            default_ao.push((label.clone(), ao));
            if let Some(f) = fs {
                brute_fraction = Some(f.brute_fraction.clone());
            }
        }
        runs.push(RunFigures {
            label,
            method: b.method,
            default_settings,
            passes: stages,
            bake_seconds,
            output_seconds,
            end_to_end_seconds: shared_seconds + bake_seconds + output_seconds
                - if b.method == Method::Adaptive {
                    validity_seconds
                } else {
                    0.0
                },
            rays_cast: passes.bake.rays,
            rays_per_texel: passes.bake.rays as f64 / texels.max(1) as f64,
            ao,
            sh_rmse_band: sh_band_rmse(&run_sh, ref_sh),
            sh_rmse: error_stats(&sh_flat, &ref_sh_flat).rmse,
            cells_filtered: fs.map(|f| f.cell_share(f.cells_filtered)),
            cells_brute_forced: fs.map(|f| f.cell_share(f.cells_brute)),
            cells_brute_contact: fs.map(|f| f.cell_share(f.cells_contact)),
            cells_brute_no_hit: fs.map(|f| f.cell_share(f.cells_no_hit)),
            engine_view,
        });
        pb.inc(1);
    }
    let equal_engine_view =
        equal_error(&runs, |r: &RunFigures| r.engine_view.map(|e| e.all.ao_rmse));
    let equal_error = equal_error(&runs, |r| Some(r.ao.rmse));

    let stability = if rs.stability_rays > 0 {
        pb.set_message("scale stability");
        let r = stability(scene, &base, &prepared, rs, &reference.bake.ao)?;
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
        texels_inside: texels - compared.len(),
        charts: prepared.atlas.charts,
        occluder_triangles: level.tracer.triangle_count(),
        max_distance_world: level.max_distance_world,
        seed: rs.seed,
        reference_rays: rs.reference_rays,
        reference_seed: reference_seed(rs.seed),
        reference_seconds,
        shared_stages,
        shared_seconds,
        runs,
        equal_error,
        equal_engine_view,
        stability,
        reference_seams,
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

/// The equal-error comparison of a sweep's runs (see [`EqualError`]) on
/// the error `error` reads from a run (the AO RMSE at texel centres, or
/// the engine view's over surface points); runs without it are left out.
pub fn equal_error(
    runs: &[RunFigures],
    error: impl Fn(&RunFigures) -> Option<f64>,
) -> Option<EqualError> {
    let curve = |m: Method| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r.method == m)
            .filter_map(|r| Some((r.end_to_end_seconds, error(r)?)))
            .collect()
    };
    let mc_by_rays: Vec<(f64, f64)> = runs
        .iter()
        .filter(|r| r.method == Method::Mc)
        .filter_map(|r| Some((r.rays_per_texel, error(r)?)))
        .collect();
    let target = loglog_at(&mc_by_rays, TARGET_RAYS as f64)?;
    let mc_seconds = cost_at_error(&curve(Method::Mc), target);
    let methods = [Method::Sheared, Method::Adaptive]
        .into_iter()
        .filter(|&m| runs.iter().any(|r| r.method == m && error(r).is_some()))
        .map(|method| {
            let points = curve(method);
            let seconds = cost_at_error(&points, target);
            MethodAtError {
                method,
                seconds,
                speedup: match (mc_seconds, seconds) {
                    (Some(m), Some(f)) if f > 0.0 => Some(m / f),
                    _ => None,
                },
                best_ao_rmse: points.iter().map(|p| p.1).min_by(f64::total_cmp),
            }
        })
        .collect();
    Some(EqualError {
        target_ao_rmse: target,
        mc_seconds,
        methods,
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
    base: &BakeSettings,
    prepared: &Page,
    rs: &ReportSettings,
    reference_ao: &[f32],
) -> Result<Vec<StabilityRow>> {
    let s = Budget::mc(rs.stability_rays).settings(base, rs.seed);
    let run = RunOptions::QUIET;
    let unscaled = prepared.bake(&s, &run, &mut StageTimer::new())?.bake.ao;
    let noise = error_stats(&unscaled, reference_ao).rmse;
    let mut rows = Vec::new();
    for scale in [1e-4, 1e4] {
        let scaled = scaled_scene(scene, scale);
        let max_distance_world = prepared.level.max_distance_world * scale;
        let ss = BakeSettings {
            max_distance: Some(max_distance_world),
            // Raw AO is compared, the inside fill is not: skip its pass.
            fill_inside: false,
            ..s.clone()
        };
        let mut timer = StageTimer::new();
        let level = Level::new(&scaled, &ss, &run, &mut timer)?;
        let p = level.page(0, &scaled, &mut timer)?;
        if p.receivers.texel != prepared.receivers.texel {
            return Err(Error::Limit(format!(
                "the scene scaled by {scale:e} unwrapped to different texels; the stability table needs the same atlas"
            )));
        }
        let ao = p.bake(&ss, &run, &mut timer)?.bake.ao;
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

#[cfg(test)]
mod tests {
    use super::*;
    use metrics::ErrorStats;

    fn run(method: Method, seconds: f64, rays: f64, rmse: f64) -> RunFigures {
        RunFigures {
            label: String::new(),
            method,
            default_settings: false,
            passes: Vec::new(),
            bake_seconds: seconds,
            output_seconds: 0.0,
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
            engine_view: None,
        }
    }

    fn ao(r: &RunFigures) -> Option<f64> {
        Some(r.ao.rmse)
    }

    /// Monte Carlo at 16, 64 and 1024 rays: error 0.16/sqrt(rays), time
    /// rays / 64 s (error 0.01 at 256 rays, reached at 4 s).
    fn mc_ladder() -> Vec<RunFigures> {
        [16.0, 64.0, 1024.0]
            .iter()
            .map(|&n: &f64| run(Method::Mc, n / 64.0, n, 0.16 / n.sqrt()))
            .collect()
    }

    #[test]
    fn equal_error_speedup() {
        // MC: error 0.16/sqrt(rays), time = rays / 64 s; error at 256 rays
        // is 0.01, reached at 4 s. Filtered reaches 0.01 at 1 s: 4x.
        let mut runs = mc_ladder();
        runs.push(run(Method::Sheared, 0.5, 10.0, 0.02));
        runs.push(run(Method::Sheared, 2.0, 40.0, 0.005));
        let e = equal_error(&runs, ao).unwrap();
        assert!((e.target_ao_rmse - 0.01).abs() < 1e-12);
        assert!((e.mc_seconds.unwrap() - 4.0).abs() < 1e-9);
        let s = e.of(Method::Sheared).unwrap();
        assert!((s.seconds.unwrap() - 1.0).abs() < 1e-9);
        assert!((s.speedup.unwrap() - 4.0).abs() < 1e-9);
        // A method not swept has no entry.
        assert!(e.of(Method::Adaptive).is_none());
        // No sheared run good enough: no speed-up, best error reported.
        runs.truncate(4);
        let e = equal_error(&runs, ao).unwrap();
        let s = e.of(Method::Sheared).unwrap();
        assert_eq!(s.speedup, None);
        assert_eq!(s.best_ao_rmse, Some(0.02));
    }

    #[test]
    fn runs_without_the_error_are_left_out_of_the_comparison() {
        // The engine view's comparison: only the runs that measured it. MC
        // at 16 and 1024 rays measured 0.04 and 0.005, so MC-256's is
        // interpolated in log-log: 0.01 at 4 s; a 64-ray MC run without the
        // error (its 0.03 at texel centres) must not move it, and a sheared
        // method without any is not compared.
        let mut runs = mc_ladder();
        runs[1].ao.rmse = 0.03;
        runs.push(run(Method::Adaptive, 1.0, 10.0, 0.01));
        runs.push(run(Method::Sheared, 1.0, 10.0, 0.001));
        let measured = |r: &RunFigures| {
            (r.method != Method::Sheared && r.rays_per_texel != 64.0).then_some(r.ao.rmse)
        };
        let e = equal_error(&runs, measured).unwrap();
        assert!((e.target_ao_rmse - 0.01).abs() < 1e-12);
        assert!((e.mc_seconds.unwrap() - 4.0).abs() < 1e-9);
        assert!((e.of(Method::Adaptive).unwrap().speedup.unwrap() - 4.0).abs() < 1e-9);
        assert!(e.of(Method::Sheared).is_none());
        // No Monte Carlo run measured it: no comparison.
        assert!(equal_error(&runs, |r| (r.method != Method::Mc).then_some(r.ao.rmse)).is_none());
    }
}
