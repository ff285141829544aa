//! Real orthonormal spherical harmonics up to l = 2 (9 coefficients), in the
//! output contract's order (l,m) = (0,0),(1,-1),(1,0),(1,1),(2,-2),(2,-1),
//! (2,0),(2,1),(2,2), without the Condon-Shortley phase.
//!
//! In: a unit world-space direction. Out: the 9 basis values. Also the
//! clamped-cosine band factors A_l used for open hemispheres.

use glam::Vec3;

/// Number of SH coefficients (order 3, bands 0..=2).
pub const SH_COUNT: usize = 9;

/// Band l of coefficient i.
pub const BAND: [usize; SH_COUNT] = [0, 1, 1, 1, 2, 2, 2, 2, 2];

/// The 9 basis functions Y_i(w) for a unit direction w = (x, y, z).
#[inline]
pub fn basis(w: Vec3) -> [f32; SH_COUNT] {
    let (x, y, z) = (w.x, w.y, w.z);
    [
        0.282_094_8,
        0.488_602_5 * y,
        0.488_602_5 * z,
        0.488_602_5 * x,
        1.092_548_4 * x * y,
        1.092_548_4 * y * z,
        0.315_391_57 * (3.0 * z * z - 1.0),
        1.092_548_4 * x * z,
        0.546_274_2 * (x * x - y * y),
    ]
}

/// Adds `weight * Y_i(w)` to each coefficient of `acc`.
#[inline]
pub fn accumulate(acc: &mut [f32; SH_COUNT], weight: f32, w: Vec3) {
    for (a, y) in acc.iter_mut().zip(basis(w)) {
        *a += weight * y;
    }
}

/// Clamped-cosine convolution factors A_l (Ramamoorthi-Hanrahan):
/// A_0 = pi, A_1 = 2pi/3, A_2 = pi/4.
pub const CLAMPED_COSINE_BAND: [f32; 3] = [
    std::f32::consts::PI,
    2.0 * std::f32::consts::PI / 3.0,
    std::f32::consts::FRAC_PI_4,
];

/// Coefficients of an unoccluded receiver with normal n:
/// c_i = (A_l / pi) Y_i(n).
#[inline]
pub fn open_hemisphere(n: Vec3) -> [f32; SH_COUNT] {
    let y = basis(n);
    std::array::from_fn(|i| CLAMPED_COSINE_BAND[BAND[i]] / std::f32::consts::PI * y[i])
}

/// The occluded share (less) of a receiver whose open hemisphere projects
/// to `open` ([`open_hemisphere`] of its normal n), from `rays`
/// cosine-weighted rays around n whose occluded ones summed
/// `occluded_sum` and all of which summed `all_sum` (sum Y_i(w)), with the
/// open projection as a control variate of weight `visible` (the
/// receiver's visible fraction): at `visible` 1 the occluded rays' share
/// alone (exact for an open receiver), at 0 the visible rays' own sum less
/// the open projection (exact for a closed one: the occluded rays' sum
/// then carries the hemisphere's sampling error, all_sum less the open
/// projection, which a few rays leave large). Add `open` for the
/// coefficients ([`from_sums`]).
#[inline]
pub fn occluded_share(
    open: &[f32; SH_COUNT],
    occluded_sum: &[f32; SH_COUNT],
    all_sum: &[f32; SH_COUNT],
    rays: u32,
    visible: f32,
) -> [f32; SH_COUNT] {
    let inv = 1.0 / rays.max(1) as f32;
    let w = 1.0 - visible.clamp(0.0, 1.0);
    std::array::from_fn(|i| -occluded_sum[i] * inv + w * (all_sum[i] * inv - open[i]))
}

/// Coefficients of a receiver with normal n from its rays' sums (see
/// [`occluded_share`]): the open hemisphere's exact projection plus the
/// occluded share (less).
#[inline]
pub fn from_sums(
    n: Vec3,
    occluded_sum: &[f32; SH_COUNT],
    all_sum: &[f32; SH_COUNT],
    rays: u32,
    visible: f32,
) -> [f32; SH_COUNT] {
    let open = open_hemisphere(n);
    let share = occluded_share(&open, occluded_sum, all_sum, rays, visible);
    std::array::from_fn(|i| open[i] + share[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrates f over the sphere by a fine latitude-longitude quadrature.
    fn integrate(f: impl Fn(Vec3) -> f64) -> f64 {
        let (nt, np) = (400, 800);
        let mut s = 0.0;
        for i in 0..nt {
            let theta = (i as f64 + 0.5) / nt as f64 * std::f64::consts::PI;
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                let w = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                s += f(w) * theta.sin();
            }
        }
        s * (std::f64::consts::PI / nt as f64) * (2.0 * std::f64::consts::PI / np as f64)
    }

    #[test]
    fn basis_is_orthonormal() {
        for i in 0..SH_COUNT {
            for j in 0..SH_COUNT {
                let v = integrate(|w| basis(w)[i] as f64 * basis(w)[j] as f64);
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 2e-3, "<Y{i},Y{j}> = {v}");
            }
        }
    }

    #[test]
    fn open_hemisphere_matches_numeric_projection() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let c = open_hemisphere(n);
        for (i, &ci) in c.iter().enumerate() {
            let v = integrate(|w| (n.dot(w).max(0.0) * basis(w)[i]) as f64) / std::f64::consts::PI;
            assert!((v - ci as f64).abs() < 2e-3, "c{i}: {v} vs {ci}");
        }
    }

    #[test]
    fn occluded_share_is_exact_for_closed_and_open_receivers() {
        // 16 cosine-weighted rays of a scrambled sequence around n: their
        // sum of Y is not the open projection (sampling error).
        let n = Vec3::new(0.2, 0.4, 0.9).normalize();
        let frame = crate::sample::Frame::from_normal(n);
        let mut all = [0.0f32; SH_COUNT];
        for i in 0..16 {
            let u = crate::sample::sobol_2d(i, 7);
            accumulate(
                &mut all,
                1.0,
                frame.to_world(crate::sample::cosine_hemisphere(u)),
            );
        }
        let open = open_hemisphere(n);
        let error: f32 = (0..SH_COUNT).map(|i| (all[i] / 16.0 - open[i]).abs()).sum();
        assert!(error > 1e-3, "the rays' sum should differ: {error}");
        let none = [0.0f32; SH_COUNT];
        let coefficients =
            |occ: &[f32; SH_COUNT], visible: f32| from_sums(n, occ, &all, 16, visible);
        // Every ray occluded, weight 0: zero, whatever the sampling error;
        // weight 1 (the open projection less the occluded rays' mean): the
        // sampling error remains.
        assert!(coefficients(&all, 0.0).iter().all(|c| c.abs() < 1e-6));
        let old: Vec<f32> = (0..SH_COUNT).map(|i| open[i] - all[i] / 16.0).collect();
        let blended = coefficients(&all, 1.0);
        assert!((0..SH_COUNT).all(|i| (old[i] - blended[i]).abs() < 1e-6));
        // None occluded, weight 1: the open projection exactly.
        let open_again = coefficients(&none, 1.0);
        assert!((0..SH_COUNT).all(|i| (open_again[i] - open[i]).abs() < 1e-6));
        // In between, a linear blend of two estimators of the same value.
        let half: Vec<f32> = all.iter().map(|a| 0.5 * a).collect();
        let half: [f32; SH_COUNT] = half.try_into().unwrap();
        let (a, b, m) = (
            coefficients(&half, 0.0),
            coefficients(&half, 1.0),
            coefficients(&half, 0.25),
        );
        assert!((0..SH_COUNT).all(|i| (m[i] - (0.75 * a[i] + 0.25 * b[i])).abs() < 1e-6));
    }
}
