//! The files of a report directory: AO error maps in the atlas layout,
//! the brute-force map, the error-vs-time plots (texel centres, and the
//! engine view where measured), `report.md` and `report.json`.
//!
//! In: a [`Sweep`]. Out: the files, each written atomically, and the
//! report with their names.

use super::budget::TARGET_RAYS;
use super::figures::{RunFigures, Sweep, SweepReport};
use super::markdown::markdown;
use super::plot::{self, Curve, Plot, Target};
use crate::atlas::Receivers;
use crate::error::{Error, Result};
use crate::job::Method;
use std::path::Path;

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
        crate::file::write_atomic(&dir.join(name), bytes)
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
    let (svg, png) = plot::error_vs_time(&error_vs_time(&report))?;
    write("error_vs_time.svg", svg.as_bytes())?;
    write("error_vs_time.png", &png)?;
    files.push("error_vs_time.svg".into());
    files.push("error_vs_time.png".into());
    if let Some(p) = engine_view_vs_time(&report) {
        let (svg, png) = plot::error_vs_time(&p)?;
        write("engine_view_vs_time.svg", svg.as_bytes())?;
        write("engine_view_vs_time.png", &png)?;
        files.push("engine_view_vs_time.svg".into());
        files.push("engine_view_vs_time.png".into());
    }
    files.push("report.md".into());
    files.push("report.json".into());
    report.files = files;
    write("report.md", markdown(&report).as_bytes())?;
    let json = serde_json::to_vec_pretty(&report)
        .map_err(|e| Error::Limit(format!("cannot serialize the report: {e}")))?;
    write("report.json", &json)?;
    Ok(report)
}

/// The error-vs-time plot of a report: one curve per method (point labels
/// without the method's prefix), the equal-error target dashed, and where
/// each method reaches it crossed.
pub fn error_vs_time(r: &SweepReport) -> Plot {
    let e = r.equal_error.as_ref();
    Plot {
        title: format!(
            "{}: AO error vs end-to-end time ({} texels, {} cores)",
            file_name(r),
            r.texels,
            r.cores
        ),
        x_desc: "end-to-end seconds (log)".into(),
        y_desc: format!("AO RMSE vs {}-ray reference (log)", r.reference_rays),
        curves: method_curves(r, |x| Some(x.ao.rmse), |m| e.and_then(|e| e.crossing(m))),
        target: e.map(|e| Target {
            error: e.target_ao_rmse,
            legend: format!(
                "MC-{TARGET_RAYS} error {:.4}: {}",
                e.target_ao_rmse,
                e.methods
                    .iter()
                    .map(|m| match m.speedup {
                        Some(x) => format!("{} {x:.2}x as fast", m.method.name()),
                        None => format!("{} not reached", m.method.name()),
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }),
    }
}

/// The input's file name.
fn file_name(r: &SweepReport) -> String {
    std::path::Path::new(&r.input)
        .file_name()
        .map_or(r.input.clone(), |n| n.to_string_lossy().into_owned())
}

/// One curve per method of `error` against end-to-end time (runs without
/// the error left out; point labels without the method's prefix), each
/// crossed where `crossing` says.
fn method_curves(
    r: &SweepReport,
    error: impl Fn(&RunFigures) -> Option<f64>,
    crossing: impl Fn(Method) -> Option<f64>,
) -> Vec<Curve> {
    [
        (Method::Mc, "Monte Carlo (rays per texel)"),
        (Method::Sheared, "sheared (sparse rays : gather radius)"),
        (Method::Adaptive, "adaptive (mean rays per texel)"),
    ]
    .into_iter()
    .map(|(m, legend)| Curve {
        legend: legend.to_string(),
        points: (r.runs.iter())
            .filter(|x| x.method == m)
            .filter_map(|x| {
                let prefix = format!("{}:", m.name());
                let short = x.label.strip_prefix(&prefix).unwrap_or(&x.label);
                Some((x.end_to_end_seconds, error(x)?, short.to_string()))
            })
            .collect(),
        crossing: crossing(m),
    })
    .collect()
}

/// The engine-view plot: each run's AO RMSE over the surface points (the
/// written textures read bilinearly) against end-to-end time, with 256-ray
/// Monte Carlo's as the dashed level and where each method reaches it
/// crossed (the report's `equal_engine_view`), so the time ratio at equal
/// engine-view error reads from the chart; `None` without engine-view
/// figures.
pub fn engine_view_vs_time(r: &SweepReport) -> Option<Plot> {
    let first = r.runs.iter().find_map(|x| x.engine_view)?;
    let mc = (r.runs.iter())
        .find(|x| x.method == Method::Mc && x.default_settings)
        .and_then(|x| x.engine_view);
    let e = r.equal_engine_view.as_ref();
    Some(Plot {
        title: format!(
            "{}: engine-view AO error vs end-to-end time ({} points)",
            file_name(r),
            first.all.points + first.inside
        ),
        x_desc: "end-to-end seconds (log)".into(),
        y_desc: format!(
            "AO RMSE at surface points, bilinear, vs {}-ray reference (log)",
            first.reference_rays
        ),
        curves: method_curves(
            r,
            |x| x.engine_view.map(|e| e.all.ao_rmse),
            |m| e.and_then(|e| e.crossing(m)),
        ),
        target: e.map(|e| Target {
            error: e.target_ao_rmse,
            legend: format!(
                "MC-{TARGET_RAYS} {:.4}{}: {}",
                e.target_ao_rmse,
                mc.map_or(String::new(), |v| format!(
                    " (interior {:.4}, border {:.4})",
                    v.interior.ao_rmse, v.border.ao_rmse
                )),
                e.methods
                    .iter()
                    .map(|m| match m.speedup {
                        Some(x) => format!("{} at {:.2}x its time", m.method.name(), 1.0 / x),
                        None => format!("{} not reached", m.method.name()),
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
