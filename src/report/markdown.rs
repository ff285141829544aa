//! `report.md`: a report as a Markdown page.
//!
//! In: a [`SweepReport`]. Out: the page's text: the runs' table, the
//! equal-error sentence and the scale-stability table.

use super::budget::TARGET_RAYS;
use super::figures::{EqualError, SweepReport};
use crate::stage::seconds_of;

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
        "Reference: {}-ray Monte Carlo (seed {}), {:.2} s. Shared stages (load, unwrap, rasterize, BVH, validity, write): {:.2} s, counted in every end-to-end time but the validity stage's {:.2} s in the adaptive runs' (their pre-pass makes its test on the same rays); each run adds its own passes and output stages (border fit, seams, dilate, encode). Errors are per texel against the reference, over the {} texels not inside geometry ({} inside are filled from their neighbours in the output and left out); AO bias > 0 means too bright.\n",
        r.reference_rays,
        r.reference_seed,
        r.reference_seconds,
        r.shared_seconds,
        seconds_of(&r.shared_stages, "validity"),
        r.texels - r.texels_inside,
        r.texels_inside
    ));
    let busy = |stages: &[crate::stage::StageTime]| -> Vec<String> {
        stages
            .iter()
            .map(|p| {
                format!(
                    "{} {:.2} ({:.0}% busy)",
                    p.stage,
                    p.seconds,
                    100.0 * p.utilisation
                )
            })
            .collect()
    };
    line(format!(
        "Shared stages, seconds and utilisation (CPU time over wall time times {} threads; a serial stage shows 1/threads): {}.\n",
        rayon::current_num_threads(),
        busy(&r.shared_stages).join(", ")
    ));
    if let Some(f) = &r.reference_seams {
        line(format!(
            "Seams (the reference bake's {} smooth seams, {:.1} world units): AO jump mean {:.4} -> {:.4}, p95 {:.4} -> {:.4}, share over 8/255 {:.1}% -> {:.1}%, SH RMS jump {:.4} -> {:.4} after stitching ({} unknowns, {} CG iterations at most, {}).\n",
            f.seams,
            f.length,
            f.before.ao_mean,
            f.after.ao_mean,
            f.before.ao_p95,
            f.after.ao_p95,
            100.0 * f.before.ao_over_8bit,
            100.0 * f.after.ao_over_8bit,
            f.before.sh_rms_mean,
            f.after.sh_rms_mean,
            f.solve.unknowns,
            f.solve.max_iterations,
            if f.solve.converged {
                "converged"
            } else {
                "NOT converged"
            }
        ));
    }
    line("| run | end-to-end s | passes s | rays/texel | AO RMSE | AO bias | AO p99 | AO max | SH RMSE L0 | L1 | L2 | cells brute-forced (contact, no hit) |".into());
    line("|---|---|---|---|---|---|---|---|---|---|---|---|".into());
    for run in &r.runs {
        let passes = busy(&run.passes);
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
    if let Some(first) = r.runs.iter().find_map(|run| run.engine_view) {
        line(String::new());
        line(format!(
            "**Engine view** (what an engine shows: each run's written 8-bit textures read bilinearly at {} surface points spread by area, against a {}-ray reference there; points by their four taps: interior when every tap's centre lies in a triangle, sliver when none does, border otherwise, slivers included; {} points inside geometry left out):\n",
            first.all.points + first.inside,
            first.reference_rays,
            first.inside,
        ));
        line(format!(
            "| run | AO RMSE all | interior | border ({:.1}% of area) | sliver ({:.1}%) | border's share of AO error | border > 0.05 | SH RMSE all | border | relight error interior / border |",
            100.0 * first.border.area_share,
            100.0 * first.sliver.area_share
        ));
        line("|---|---|---|---|---|---|---|---|---|---|".into());
        for run in &r.runs {
            if let Some(e) = &run.engine_view {
                let relight = match (e.interior.relight_error, e.border.relight_error) {
                    (Some(i), Some(b)) => format!("{i:.4} / {b:.4}"),
                    _ => "-".into(),
                };
                line(format!(
                    "| {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.0}% | {:.0}% | {:.4} | {:.4} | {relight} |",
                    run.label,
                    e.all.ao_rmse,
                    e.interior.ao_rmse,
                    e.border.ao_rmse,
                    e.sliver.ao_rmse,
                    100.0 * e.border.ao_error_share,
                    100.0 * e.border.ao_over_005,
                    e.all.sh_rmse,
                    e.border.sh_rmse
                ));
            }
        }
    }
    if let Some(e) = &r.equal_error {
        line(String::new());
        line(equal_error_line("Equal error", "AO RMSE", e));
    }
    if let Some(e) = &r.equal_engine_view {
        line(String::new());
        line(equal_error_line(
            "Equal engine-view error",
            "engine-view AO RMSE (all points)",
            e,
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

/// One equal-error sentence: where Monte Carlo and each method reach
/// 256-ray Monte Carlo's `what`, in end-to-end seconds, and the ratio.
fn equal_error_line(title: &str, what: &str, e: &EqualError) -> String {
    let fmt = |v: Option<f64>| v.map_or("not reached".to_string(), |v| format!("{v:.2} s"));
    let methods: Vec<String> = e
        .methods
        .iter()
        .map(|m| {
            let name = m.method.name();
            match m.speedup {
                Some(x) => format!(
                    "{name} {} ({:.2}x Monte Carlo's time, {x:.2}x as fast)",
                    fmt(m.seconds),
                    1.0 / x
                ),
                None => format!(
                    "{name} not reached (its best {})",
                    m.best_ao_rmse.map_or("-".into(), |v| format!("{v:.4}"))
                ),
            }
        })
        .collect();
    format!(
        "**{title}** at {TARGET_RAYS}-ray Monte Carlo's {what} {:.4}: Monte Carlo {}; {}.",
        e.target_ao_rmse,
        fmt(e.mc_seconds),
        methods.join("; ")
    )
}
