//! Error of a bake against a reference on the same receivers: the figures
//! the benchmark, the tests and reports compare methods by.
//!
//! In: two equally long slices of per-receiver values. Out: an [`ErrorStats`].

/// Error statistics of `values` against `reference`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

#[cfg(test)]
mod tests {
    use super::*;

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
