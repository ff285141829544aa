//! Log-log plots of error against time: one curve per method, the best
//! error reached at each cost, with an equal-error target marked.
//!
//! In: a [`Plot`] of plain curves (seconds, error, label), knowing nothing
//! of methods or reports. Out: the plot as SVG text and as PNG bytes
//! (plotters; the PNG's text uses the embedded DejaVu Sans, so no system
//! font is needed).

use crate::error::{Error, Result};
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

/// A log axis's range holding a power of ten inside it (plotters labels a
/// log axis only then): `lo` lowered below the decade under `hi` if need be.
fn with_decade(lo: f64, hi: f64) -> (f64, f64) {
    let decade = 10f64.powf(hi.log10().floor());
    (if decade > lo { lo } else { decade / 1.2 }, hi)
}

fn plot_error<E: std::fmt::Debug>(e: E) -> Error {
    Error::Limit(format!("cannot draw the plot: {e:?}"))
}

/// One method's runs.
#[derive(Clone, Debug)]
pub struct Curve {
    pub legend: String,
    /// (seconds, error, label) of each run.
    pub points: Vec<(f64, f64, String)>,
    /// Seconds at which the curve reaches the target, if it does.
    pub crossing: Option<f64>,
}

/// An error level every curve is compared at, drawn dashed.
#[derive(Clone, Debug)]
pub(crate) struct Target {
    pub error: f64,
    pub legend: String,
}

/// What is drawn.
#[derive(Clone, Debug)]
pub struct Plot {
    pub title: String,
    pub x_desc: String,
    pub y_desc: String,
    /// Coloured in order from [`PALETTE`].
    pub curves: Vec<Curve>,
    pub target: Option<Target>,
}

/// Curve colours, in order.
pub const PALETTE: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// A curve's finite points, cheapest first.
fn points(c: &Curve) -> Vec<(f64, f64, String)> {
    let mut p: Vec<(f64, f64, String)> = c
        .points
        .iter()
        .filter(|x| x.0.is_finite() && x.1.is_finite())
        // Log axes: an exact run (open scenes) sits on the floor.
        .map(|x| (x.0.max(MIN_PLOTTED), x.1.max(MIN_PLOTTED), x.2.clone()))
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

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, plot: &Plot) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(plot_error)?;
    let curves: Vec<Vec<(f64, f64, String)>> = plot.curves.iter().map(points).collect();
    let all: Vec<&(f64, f64, String)> = curves.iter().flatten().collect();
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
    if let Some(target) = &plot.target {
        e0 = e0.min(target.error.max(MIN_PLOTTED));
        e1 = e1.max(target.error);
    }
    let (t0, t1) = with_decade(t0 / 1.3, t1 * 1.3);
    let (e0, e1) = with_decade(e0 / 1.3, e1 * 1.3);
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, (FONT, 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc(&plot.x_desc)
        .y_desc(&plot.y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .x_labels(10)
        .y_labels(10)
        .y_label_formatter(&|v| format!("{v:.4}"))
        .x_label_formatter(&|v| format!("{v:.1}"))
        .draw()
        .map_err(plot_error)?;
    for ((curve, pts), &colour) in plot.curves.iter().zip(&curves).zip(PALETTE.iter().cycle()) {
        if pts.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(envelope(pts), colour.stroke_width(2)))
            .map_err(plot_error)?
            .label(&curve.legend)
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
                EmptyElement::at((*t, *e))
                    + Text::new(l.clone(), (6, 4), (FONT, 12).into_font().color(&colour))
            }))
            .map_err(plot_error)?;
    }
    if let Some(target) = &plot.target {
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(DashedLineSeries::new(
                [(t0, target.error), (t1, target.error)],
                6,
                4,
                grey.stroke_width(1),
            ))
            .map_err(plot_error)?
            .label(&target.legend)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
        for (curve, &colour) in plot.curves.iter().zip(PALETTE.iter().cycle()) {
            if let Some(t) = curve.crossing {
                chart
                    .draw_series(std::iter::once(Cross::new(
                        (t, target.error),
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

/// The plot as SVG text and PNG bytes.
pub fn error_vs_time(r: &Plot) -> Result<(String, Vec<u8>)> {
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
