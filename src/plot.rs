//! Plots of a [`SweepReport`]: AO error against end-to-end seconds, log-log,
//! one curve per method, with the equal-error comparison marked.
//!
//! In: a [`SweepReport`]. Out: the plot as SVG text and as PNG bytes
//! (plotters; the PNG's text uses the embedded DejaVu Sans, so no system
//! font is needed).

use crate::error::{Error, Result};
use crate::pipeline::Method;
use crate::report::{SweepReport, TARGET_RAYS};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::Once;

/// Plot size in pixels.
const SIZE: (u32, u32) = (900, 600);
const FONT: &str = "sans-serif";
/// Smallest time or error drawn (log axes cannot show 0).
const MIN_PLOTTED: f64 = 1e-6;

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The embedded font is valid; a failure would only drop the text.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

fn plot_error<E: std::fmt::Debug>(e: E) -> Error {
    Error::Limit(format!("cannot draw the plot: {e:?}"))
}

/// (seconds, AO RMSE, label) of a method's runs, cheapest first.
fn points(r: &SweepReport, m: Method) -> Vec<(f64, f64, String)> {
    let mut p: Vec<(f64, f64, String)> = r
        .runs
        .iter()
        .filter(|x| x.method == m && x.end_to_end_seconds.is_finite() && x.ao.rmse.is_finite())
        // Log axes: an exact run (open scenes) sits on the floor.
        .map(|x| {
            (
                x.end_to_end_seconds.max(MIN_PLOTTED),
                x.ao.rmse.max(MIN_PLOTTED),
                x.label.clone(),
            )
        })
        .collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    p
}

/// Best error reached at each cost or less: the curve a user can buy.
fn envelope(p: &[(f64, f64, String)]) -> Vec<(f64, f64)> {
    let mut best = f64::INFINITY;
    let mut out = Vec::new();
    for (t, e, _) in p {
        if *e < best {
            best = *e;
            out.push((*t, *e));
        }
    }
    out
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, r: &SweepReport) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(plot_error)?;
    let mc = points(r, Method::Mc);
    let filtered = points(r, Method::Filtered);
    let all: Vec<&(f64, f64, String)> = mc.iter().chain(&filtered).collect();
    if all.is_empty() {
        return Err(Error::Limit(
            "no run with positive time and error to plot".into(),
        ));
    }
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0.0f64, f64::MAX, 0.0f64);
    for p in &all {
        t0 = t0.min(p.0);
        t1 = t1.max(p.0);
        e0 = e0.min(p.1);
        e1 = e1.max(p.1);
    }
    if let Some(e) = &r.equal_error {
        e0 = e0.min(e.target_ao_rmse.max(MIN_PLOTTED));
        e1 = e1.max(e.target_ao_rmse);
    }
    let (t0, t1, e0, e1) = (t0 / 1.3, t1 * 1.3, e0 / 1.3, e1 * 1.3);
    let name = std::path::Path::new(&r.input)
        .file_name()
        .map_or(r.input.clone(), |n| n.to_string_lossy().into_owned());
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{name}: AO error vs end-to-end time ({} texels, {} cores)",
                r.texels, r.cores
            ),
            (FONT, 20),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc("end-to-end seconds (log)")
        .y_desc(format!(
            "AO RMSE vs {}-ray reference (log)",
            r.reference_rays
        ))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .y_label_formatter(&|v| format!("{v:.4}"))
        .x_label_formatter(&|v| format!("{v:.1}"))
        .draw()
        .map_err(plot_error)?;
    let blue = RGBColor(31, 119, 180);
    let orange = RGBColor(214, 39, 40);
    for (pts, colour, label) in [
        (&mc, blue, "Monte Carlo (rays per texel)"),
        (&filtered, orange, "filtered (sparse rays : gather radius)"),
    ] {
        if pts.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(envelope(pts), colour.stroke_width(2)))
            .map_err(plot_error)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(
                pts.iter()
                    .map(|(t, e, _)| Circle::new((*t, *e), 4, colour.filled())),
            )
            .map_err(plot_error)?;
        chart
            .draw_series(pts.iter().map(|(t, e, l)| {
                let short = l.trim_start_matches("mc:").trim_start_matches("filtered:");
                EmptyElement::at((*t, *e))
                    + Text::new(
                        short.to_string(),
                        (6, 4),
                        (FONT, 12).into_font().color(&colour),
                    )
            }))
            .map_err(plot_error)?;
    }
    if let Some(e) = &r.equal_error {
        let grey = RGBColor(90, 90, 90);
        let label = match e.speedup {
            Some(x) => format!(
                "MC-{TARGET_RAYS} error {:.4}: filtered {x:.2}x as fast",
                e.target_ao_rmse
            ),
            None => format!(
                "MC-{TARGET_RAYS} error {:.4}: not reached by filtered",
                e.target_ao_rmse
            ),
        };
        chart
            .draw_series(DashedLineSeries::new(
                [(t0, e.target_ao_rmse), (t1, e.target_ao_rmse)],
                6,
                4,
                grey.stroke_width(1),
            ))
            .map_err(plot_error)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
        for (secs, colour) in [(e.mc_seconds, blue), (e.filtered_seconds, orange)] {
            if let Some(t) = secs {
                chart
                    .draw_series(std::iter::once(Cross::new(
                        (t, e.target_ao_rmse),
                        8,
                        colour.stroke_width(3),
                    )))
                    .map_err(plot_error)?;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(plot_error)?;
    root.present().map_err(plot_error)?;
    Ok(())
}

/// The error-vs-time plot as SVG text and PNG bytes.
pub fn error_vs_time(r: &SweepReport) -> Result<(String, Vec<u8>)> {
    register_font();
    let mut svg = String::new();
    draw(
        SVGBackend::with_string(&mut svg, SIZE).into_drawing_area(),
        r,
    )?;
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(),
        r,
    )?;
    let png = crate::encode::png(SIZE.0, SIZE.1, &rgb, image::ExtendedColorType::Rgb8)?;
    Ok((svg, png))
}
