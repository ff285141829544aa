//! Error of a bake against a reference on the same receivers: the figures
//! the benchmark, the tests and reports compare methods by.
//!
//! In: two equally long slices of per-receiver values. Out: an [`ErrorStats`].

use crate::sh::{BAND, SH_COUNT};
use serde::Serialize;

/// Error statistics of `values` against `reference`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    pub rmse: f64,
    /// Mean signed error (positive: too bright / too large).
    pub bias: f64,
    /// 99th percentile of the absolute error.
    pub p99: f64,
    pub max: f64,
}

/// Compares `values` with `reference` element by element.
pub fn error_stats(values: &[f32], reference: &[f32]) -> ErrorStats {
    assert_eq!(
        values.len(),
        reference.len(),
        "compared bakes differ in size"
    );
    if values.is_empty() {
        return ErrorStats::default();
    }
    let n = values.len() as f64;
    let mut abs: Vec<f64> = Vec::with_capacity(values.len());
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for (&v, &r) in values.iter().zip(reference) {
        let d = v as f64 - r as f64;
        sum += d;
        sum2 += d * d;
        abs.push(d.abs());
    }
    abs.sort_by(f64::total_cmp);
    ErrorStats {
        rmse: (sum2 / n).sqrt(),
        bias: sum / n,
        p99: abs[((n * 0.99) as usize).min(abs.len() - 1)],
        max: abs[abs.len() - 1],
    }
}

/// RMSE of SH coefficients per band (L0: c0; L1: c1..c3; L2: c4..c8),
/// over every receiver and every coefficient of the band.
pub fn sh_band_rmse(values: &[[f32; SH_COUNT]], reference: &[[f32; SH_COUNT]]) -> [f64; 3] {
    assert_eq!(
        values.len(),
        reference.len(),
        "compared bakes differ in size"
    );
    let mut sum2 = [0.0f64; 3];
    let mut count = [0usize; 3];
    for (v, r) in values.iter().zip(reference) {
        for i in 0..SH_COUNT {
            let d = v[i] as f64 - r[i] as f64;
            sum2[BAND[i]] += d * d;
            count[BAND[i]] += 1;
        }
    }
    std::array::from_fn(|b| {
        if count[b] == 0 {
            0.0
        } else {
            (sum2[b] / count[b] as f64).sqrt()
        }
    })
}

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// The points with both coordinates positive and finite (log axes), by x.
fn positive_sorted(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|&(a, b)| positive(a) && positive(b))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

/// Where a decreasing cost/error curve first reaches `target` error:
/// `points` are (cost, error) pairs in any order; the curve is their lower
/// envelope in cost order (the best error any run at that cost or less
/// reached), interpolated linearly in log-log between runs. `None` if no run
/// reaches the target or an input is not positive and finite. When even the
/// cheapest run is at or below the target, its cost is returned (an upper
/// bound).
pub(crate) fn cost_at_error(points: &[(f64, f64)], target: f64) -> Option<f64> {
    if !positive(target) {
        return None;
    }
    let mut prev: Option<(f64, f64)> = None;
    for (c, e) in positive_sorted(points) {
        let e = prev.map_or(e, |(_, pe)| e.min(pe));
        if e <= target {
            return Some(match prev {
                None => c,
                Some((pc, pe)) if pe > e && c > pc => {
                    let f = (target.ln() - pe.ln()) / (e.ln() - pe.ln());
                    (pc.ln() + f * (c.ln() - pc.ln())).exp()
                }
                Some(_) => c,
            });
        }
        prev = Some((c, e));
    }
    None
}

/// The value of a curve at `x`, interpolated linearly in log-log between
/// the two nearest points (`points` sorted or not; `None` outside their
/// range or for non-positive input).
pub(crate) fn loglog_at(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let pts = positive_sorted(points);
    if let Some(&(_, y)) = pts.iter().find(|p| p.0 == x) {
        return Some(y);
    }
    let i = pts.iter().position(|p| p.0 > x)?;
    if i == 0 {
        return None;
    }
    let ((x0, y0), (x1, y1)) = (pts[i - 1], pts[i]);
    let f = (x.ln() - x0.ln()) / (x1.ln() - x0.ln());
    Some((y0.ln() + f * (y1.ln() - y0.ln())).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sh_band_rmse_separates_bands() {
        let r = vec![[0.1f32; SH_COUNT]; 50];
        assert_eq!(sh_band_rmse(&r, &r), [0.0; 3]);
        // Offset only c2 (band 1) by 0.3: band-1 RMSE = sqrt(0.09 / 3).
        let mut v = r.clone();
        for c in &mut v {
            c[2] += 0.3;
        }
        let e = sh_band_rmse(&v, &r);
        assert_eq!(e[0], 0.0);
        assert!((e[1] - (0.09f64 / 3.0).sqrt()).abs() < 1e-6);
        assert_eq!(e[2], 0.0);
    }

    #[test]
    fn cost_at_error_on_power_laws() {
        // error = 1 / sqrt(cost): error 0.1 at cost 100 exactly.
        let curve: Vec<(f64, f64)> = [1.0, 10.0, 1000.0, 10000.0]
            .iter()
            .map(|&c: &f64| (c, 1.0 / c.sqrt()))
            .collect();
        assert!((cost_at_error(&curve, 0.1).unwrap() - 100.0).abs() < 1e-9);
        // Half the error at every cost: reaches 0.1 at cost 25 (4x cheaper).
        let better: Vec<(f64, f64)> = curve.iter().map(|&(c, e)| (c, e / 2.0)).collect();
        assert!((cost_at_error(&better, 0.1).unwrap() - 25.0).abs() < 1e-9);
        // Never reached; a run worse than a cheaper one does not count.
        assert_eq!(cost_at_error(&curve, 1e-3), None);
        let bumpy = [(1.0, 0.5), (2.0, 0.9), (4.0, 0.05)];
        let c = cost_at_error(&bumpy, 0.1).unwrap();
        assert!(c > 2.0 && c < 4.0, "{c}");
        // Already below the target at the cheapest run; bad input.
        assert_eq!(cost_at_error(&[(3.0, 0.01)], 0.1), Some(3.0));
        assert_eq!(cost_at_error(&[(f64::NAN, 0.01)], 0.1), None);
        assert_eq!(cost_at_error(&curve, 0.0), None);
    }

    #[test]
    fn loglog_interpolation() {
        let curve = [(64.0, 0.02), (16.0, 0.04), (256.0, 0.01)];
        assert_eq!(loglog_at(&curve, 64.0), Some(0.02));
        assert!((loglog_at(&curve, 128.0).unwrap() - 0.02 / 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(loglog_at(&curve, 512.0), None);
        assert_eq!(loglog_at(&curve, 8.0), None);
    }

    #[test]
    fn a_bake_against_itself_has_no_error_and_an_offset_shows_as_bias() {
        let r: Vec<f32> = (0..1000)
            .map(|i| (i as f32 * 0.37).sin() * 0.5 + 0.5)
            .collect();
        assert_eq!(error_stats(&r, &r), ErrorStats::default());
        let shifted: Vec<f32> = r.iter().map(|v| v + 0.125).collect();
        let e = error_stats(&shifted, &r);
        assert!((e.bias - 0.125).abs() < 1e-6 && (e.rmse - 0.125).abs() < 1e-6);
        assert!((e.p99 - 0.125).abs() < 1e-6 && (e.max - 0.125).abs() < 1e-6);
        let mut one = r.clone();
        one[10] += 0.5;
        let e = error_stats(&one, &r);
        assert!((e.max - 0.5).abs() < 1e-6 && e.p99 < 1e-6);
        assert!((e.rmse - (0.25f64 / 1000.0).sqrt()).abs() < 1e-6);
    }
}
