//! Real orthonormal spherical harmonics up to l = 2 (9 coefficients), in the
//! output contract's order (l,m) = (0,0),(1,-1),(1,0),(1,1),(2,-2),(2,-1),
//! (2,0),(2,1),(2,2), without the Condon-Shortley phase.
//!
//! In: a unit world-space direction. Out: the 9 basis values. Also the
//! clamped-cosine band factors A_l used for open hemispheres.
//!
//! The visibility layer continues the basis to l = 3 (16 coefficients,
//! [`basis16`], the contract's i = 9..15 in the same convention) and
//! projects the visibility itself, without a cosine: the open hemisphere
//! ([`open_visibility`]) and the lune below a geometric plane
//! ([`below_plane_visibility`]) exactly.

use glam::Vec3;

/// Number of SH coefficients (order 3, bands 0..=2).
pub const SH_COUNT: usize = 9;

/// Band l of coefficient i.
pub const BAND: [usize; SH_COUNT] = [0, 1, 1, 1, 2, 2, 2, 2, 2];

/// The basis's normalisations: Y_0 = K0, Y_1 = K1 (y, z, x), Y_2 = K2_PRODUCT
/// (xy, yz, xz), K2_ZZ (3 z^2 - 1) and K2_DIFFERENCE (x^2 - y^2). Kept in
/// f64 for [`below_plane`], which integrates the same polynomials.
pub const K0: f64 = 0.282_094_8;
const K1: f64 = 0.488_602_5;
const K2_PRODUCT: f64 = 1.092_548_4;
const K2_ZZ: f64 = 0.315_391_57;
const K2_DIFFERENCE: f64 = 0.546_274_2;

/// The 9 basis functions Y_i(w) for a unit direction w = (x, y, z).
#[inline]
pub fn basis(w: Vec3) -> [f32; SH_COUNT] {
    let (x, y, z) = (w.x, w.y, w.z);
    let (k0, k1, kp, kz, kd) = (
        K0 as f32,
        K1 as f32,
        K2_PRODUCT as f32,
        K2_ZZ as f32,
        K2_DIFFERENCE as f32,
    );
    [
        k0,
        k1 * y,
        k1 * z,
        k1 * x,
        kp * x * y,
        kp * y * z,
        kz * (3.0 * z * z - 1.0),
        kp * x * z,
        kd * (x * x - y * y),
    ]
}

/// Coefficients of the visibility layer at order 3 (bands 0..=3).
pub const VIS_COUNT: usize = 16;

/// Band l of coefficient i of the visibility layer.
pub(crate) const VIS_BAND: [usize; VIS_COUNT] = [0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3];

/// The l = 3 normalisations, in the contract's order i = 9..15 (m = -3..3,
/// no Condon-Shortley phase): sqrt(35/(32 pi)), sqrt(105/(4 pi)),
/// sqrt(21/(32 pi)), sqrt(7/(16 pi)), sqrt(21/(32 pi)), sqrt(105/(16 pi)),
/// sqrt(35/(32 pi)).
const K3_3: f32 = 0.590_043_6;
const K3_2: f32 = 2.890_611_4;
const K3_1: f32 = 0.457_045_8;
const K3_0: f32 = 0.373_176_33;
const K3_2D: f32 = 1.445_305_7;

/// The 16 basis functions of bands 0..=3 for a unit direction w = (x, y,
/// z): [`basis`], then 0.590044 y(3x^2 - y^2), 2.890611 xyz, 0.457046
/// y(5z^2 - 1), 0.373176 z(5z^2 - 3), 0.457046 x(5z^2 - 1), 1.445306
/// z(x^2 - y^2), 0.590044 x(x^2 - 3y^2).
#[inline]
pub fn basis16(w: Vec3) -> [f32; VIS_COUNT] {
    let b = basis(w);
    let (x, y, z) = (w.x, w.y, w.z);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    [
        b[0],
        b[1],
        b[2],
        b[3],
        b[4],
        b[5],
        b[6],
        b[7],
        b[8],
        K3_3 * y * (3.0 * xx - yy),
        K3_2 * x * y * z,
        K3_1 * y * (5.0 * zz - 1.0),
        K3_0 * z * (5.0 * zz - 3.0),
        K3_1 * x * (5.0 * zz - 1.0),
        K3_2D * z * (xx - yy),
        K3_3 * x * (xx - 3.0 * yy),
    ]
}

/// Hemisphere band factors lambda_l = 2 pi Int_0^1 P_l(t) dt (Funk-Hecke
/// for the hemisphere's indicator H(n.w)): 2 pi, pi, 0, -pi/4.
pub(crate) const HEMISPHERE_BAND: [f32; 4] = [
    2.0 * std::f32::consts::PI,
    std::f32::consts::PI,
    0.0,
    -std::f32::consts::FRAC_PI_4,
];

/// The visibility layer of an unoccluded receiver with normal n:
/// v_i = Int H(n.w) Y_i(w) dw = lambda_l Y_i(n) (v_0 = sqrt(pi)).
#[inline]
pub fn open_visibility(n: Vec3) -> [f32; VIS_COUNT] {
    let y = basis16(n);
    std::array::from_fn(|i| HEMISPHERE_BAND[VIS_BAND[i]] * y[i])
}

/// Gauss-Legendre nodes and weights on [-1, 1], 6 points (alpha).
const GAUSS_6: [(f64, f64); 6] = [
    (-0.932_469_514_203_152, 0.171_324_492_379_170_3),
    (-0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
    (-0.238_619_186_083_196_9, 0.467_913_934_572_691),
    (0.238_619_186_083_196_9, 0.467_913_934_572_691),
    (0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
    (0.932_469_514_203_152, 0.171_324_492_379_170_3),
];

/// Gauss-Legendre nodes and weights on [-1, 1], 4 points (phi).
const GAUSS_4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_85),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_85),
];

/// The visibility layer of the lune of n's hemisphere below the geometric
/// plane (normal `geo`): Int over {n.w > 0, geo.w <= 0} of Y_i(w) dw, the
/// directions a tilted shading normal sends into the surface (occluded
/// without tracing). Its first coefficient is Y_0 times the lune's solid
/// angle 2 theta (theta: the angle between n and geo). Zero when the
/// normals agree or for non-finite input; the open hemisphere when they are
/// opposite.
///
/// By quadrature in the lune's own coordinates (w = cos(alpha) a +
/// sin(alpha) (-cos(phi) m + sin(phi) n), alpha in [0, pi], phi in [0,
/// theta], dw = sin(alpha) dalpha dphi; a = n x geo normalised, m = a x
/// n): the integrand is a trigonometric polynomial of degree <= 4 in alpha
/// and <= 3 in phi (over [0, theta]), so 6 x 4 Gauss-Legendre points (6 x
/// 6 past 45 degrees) are exact to f32 (the tests compare with a fine quadrature and the
/// lune's solid angle).
pub fn below_plane_visibility(n: Vec3, geo: Vec3) -> [f32; VIS_COUNT] {
    let (nd, g) = (n.as_dvec3(), geo.as_dvec3());
    let c = nd.dot(g);
    let cross = nd.cross(g);
    let s = cross.length();
    if !(c.is_finite() && s.is_finite()) || (s < 1e-9 && c > 0.0) {
        return [0.0; VIS_COUNT];
    }
    if s < 1e-9 {
        return open_visibility(n);
    }
    let theta = s.atan2(c);
    let a = cross / s;
    let m = a.cross(nd);
    let pi = std::f64::consts::PI;
    let mut acc = [0.0f64; VIS_COUNT];
    // Shading normals tilt by a few degrees; past 45 the phi range needs
    // the longer rule.
    let phi_rule: &[(f64, f64)] = if theta < std::f64::consts::FRAC_PI_4 {
        &GAUSS_4
    } else {
        &GAUSS_6
    };
    for &(xa, wa) in &GAUSS_6 {
        let alpha = (xa + 1.0) * 0.5 * pi;
        let (sa, ca) = alpha.sin_cos();
        for &(xp, wp) in phi_rule {
            let phi = (xp + 1.0) * 0.5 * theta;
            let (sp, cp) = phi.sin_cos();
            let w = a * ca + (m * -cp + nd * sp) * sa;
            let weight = wa * wp * sa * (0.5 * pi) * (0.5 * theta);
            for (o, y) in acc.iter_mut().zip(basis16(w.as_vec3())) {
                *o += weight * y as f64;
            }
        }
    }
    acc.map(|v| v as f32)
}

/// Adds `weight * Y_i(w)` to each coefficient of `acc`.
#[inline]
pub(crate) fn accumulate(acc: &mut [f32; SH_COUNT], weight: f32, w: Vec3) {
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

/// Coefficients of the part of a receiver's clamped-cosine hemisphere
/// (about shading normal `n`) that lies below its geometric plane (normal
/// `geo`): (1/pi) integral over {w.n > 0, w.geo <= 0} of (n.w) Y_i(w), the
/// share a shading normal tilted from the geometric one sends into the
/// surface (occluded without tracing). Its first coefficient is Y_0 times
/// the AO share (1 - n.geo) / 2. Zero when the normals agree, the open
/// hemisphere when they are opposite, zero for non-finite input.
///
/// Exact, from the lune's moments: with a = n x geo (normalised), m = a x n
/// and theta the angle between n and geo, the lune is w = cos(alpha) a +
/// sin(alpha) (-cos(phi) m + sin(phi) n), alpha in [0, pi], phi in [0,
/// theta], and the Y_i are quadratic in w, so the moments of n.w (1, w,
/// w w^T) over it give the coefficients.
pub fn below_plane(n: Vec3, geo: Vec3) -> [f32; SH_COUNT] {
    let (n, g) = (n.as_dvec3(), geo.as_dvec3());
    let c = n.dot(g);
    let cross = n.cross(g);
    let s = cross.length();
    if !(c.is_finite() && s.is_finite()) || (s < 1e-9 && c > 0.0) {
        return [0.0; SH_COUNT];
    }
    if s < 1e-9 {
        return open_hemisphere(n.as_vec3());
    }
    let pi = std::f64::consts::PI;
    let theta = s.atan2(c);
    let a = cross / s;
    let m = a.cross(n);
    // Moments of n.w over the lune, in the frame (a, m, n).
    let m0 = pi / 2.0 * (1.0 - c);
    let first =
        m * (-2.0 / 3.0 * s * s) + n * (4.0 / 3.0 * (theta / 2.0 - (2.0 * theta).sin() / 4.0));
    let (aa, mm, nn, mn) = (
        pi / 8.0 * (1.0 - c),
        pi / 8.0 * (1.0 - c * c * c),
        3.0 * pi / 8.0 * (2.0 / 3.0 - c + c * c * c / 3.0),
        -pi / 8.0 * s * s * s,
    );
    // The second moment matrix, entry (i, j) in world axes.
    let second = |i: usize, j: usize| {
        aa * a[i] * a[j] + mm * m[i] * m[j] + nn * n[i] * n[j] + mn * (m[i] * n[j] + n[i] * m[j])
    };
    let (x, y, z) = (0, 1, 2);
    // The basis polynomials with w w^T and w replaced by their moments.
    let k = [
        K0 * m0,
        K1 * first.y,
        K1 * first.z,
        K1 * first.x,
        K2_PRODUCT * second(x, y),
        K2_PRODUCT * second(y, z),
        K2_ZZ * (3.0 * second(z, z) - m0),
        K2_PRODUCT * second(x, z),
        K2_DIFFERENCE * (second(x, x) - second(y, y)),
    ];
    k.map(|v| (v / pi) as f32)
}

/// The occluded share (less) of a receiver whose open hemisphere projects
/// to `open` ([`open_hemisphere`] of its normal n), from cosine-weighted
/// rays around n, each weighing `per_ray` (1 / rays), whose occluded ones
/// summed `occluded_sum` and all of which summed `all_sum` (sum Y_i(w)),
/// with the
/// open projection as a control variate of weight `visible` (the
/// receiver's visible fraction): at `visible` 1 the occluded rays' share
/// alone (exact for an open receiver), at 0 the visible rays' own sum less
/// the open projection (exact for a closed one: the occluded rays' sum
/// then carries the hemisphere's sampling error, all_sum less the open
/// projection, which a few rays leave large). Add `open` for the
/// coefficients ([`from_sums`]).
#[inline]
pub fn occluded_share<const N: usize>(
    open: &[f32; N],
    occluded_sum: &[f32; N],
    all_sum: &[f32; N],
    per_ray: f32,
    visible: f32,
) -> [f32; N] {
    let w = 1.0 - visible.clamp(0.0, 1.0);
    std::array::from_fn(|i| -occluded_sum[i] * per_ray + w * (all_sum[i] * per_ray - open[i]))
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
    let share = occluded_share(
        &open,
        occluded_sum,
        all_sum,
        1.0 / rays.max(1) as f32,
        visible,
    );
    std::array::from_fn(|i| open[i] + share[i])
}

/// For tests of this crate: every direction of a fine latitude-longitude
/// grid over the sphere (400 x 800 midpoints) with its solid angle.
#[cfg(test)]
pub(crate) fn for_each_direction(mut f: impl FnMut(Vec3, f64)) {
    let (nt, np) = (400, 800);
    let dtheta = std::f64::consts::PI / nt as f64;
    let dphi = 2.0 * std::f64::consts::PI / np as f64;
    for i in 0..nt {
        let theta = (i as f64 + 0.5) * dtheta;
        for j in 0..np {
            let phi = (j as f64 + 0.5) * dphi;
            let w = Vec3::new(
                (theta.sin() * phi.cos()) as f32,
                (theta.sin() * phi.sin()) as f32,
                theta.cos() as f32,
            );
            f(w, theta.sin() * dtheta * dphi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrates f over the sphere by a fine latitude-longitude quadrature.
    fn integrate(f: impl Fn(Vec3) -> f64) -> f64 {
        let mut s = 0.0;
        for_each_direction(|w, da| s += f(w) * da);
        s
    }

    /// Shading normals tilted from `n` by 3, 40, 90 and 150 degrees, about
    /// different axes: (degrees, geometric normal).
    fn tilted_geometric_normals(n: Vec3) -> Vec<(f32, Vec3)> {
        [
            (Vec3::X, 3.0f32),
            (Vec3::new(1.0, 1.0, 0.0), 40.0),
            (Vec3::new(0.0, 1.0, -1.0), 90.0),
            (Vec3::Z, 150.0),
        ]
        .into_iter()
        .map(|(axis, degrees)| {
            let axis = axis.cross(n).normalize();
            (
                degrees,
                glam::Quat::from_axis_angle(axis, degrees.to_radians()) * n,
            )
        })
        .collect()
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
    fn below_plane_matches_numeric_projection() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        for (degrees, geo) in tilted_geometric_normals(n) {
            let c = below_plane(n, geo);
            for (i, &ci) in c.iter().enumerate() {
                let v = integrate(|w| {
                    if n.dot(w) > 0.0 && geo.dot(w) <= 0.0 {
                        (n.dot(w) * basis(w)[i]) as f64
                    } else {
                        0.0
                    }
                }) / std::f64::consts::PI;
                assert!(
                    (v - ci as f64).abs() < 2e-3,
                    "{degrees} deg, c{i}: {v} vs {ci}"
                );
            }
            // The first coefficient is Y_0 times the AO share below.
            let share = (1.0 - n.dot(geo)) / 2.0;
            assert!((c[0] - 0.282_094_8 * share).abs() < 1e-6, "{degrees} deg");
        }
    }

    #[test]
    fn below_plane_ends() {
        let n = Vec3::new(0.0, 0.6, 0.8);
        assert_eq!(below_plane(n, n), [0.0; SH_COUNT]);
        let open = open_hemisphere(n);
        let flipped = below_plane(n, -n);
        assert!((0..SH_COUNT).all(|i| (flipped[i] - open[i]).abs() < 1e-6));
        // Nearly agreeing normals: nearly nothing below, no NaN.
        let tilt = glam::Quat::from_rotation_x(1e-4) * n;
        assert!(below_plane(n, tilt).iter().all(|c| c.abs() < 1e-4));
        assert_eq!(below_plane(Vec3::NAN, n), [0.0; SH_COUNT]);
        assert_eq!(below_plane(n, Vec3::INFINITY), [0.0; SH_COUNT]);
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

    #[test]
    fn order_3_basis_is_orthonormal_and_continues_the_contract() {
        for i in 0..VIS_COUNT {
            for j in i..VIS_COUNT {
                let v = integrate(|w| basis16(w)[i] as f64 * basis16(w)[j] as f64);
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 2e-3, "<Y{i},Y{j}> = {v}");
            }
        }
        // The contract's table, at a direction with no zero component.
        let w = Vec3::new(0.36, -0.48, 0.8);
        let (x, y, z) = (w.x, w.y, w.z);
        let table = [
            0.590044 * y * (3.0 * x * x - y * y),
            2.890611 * x * y * z,
            0.457046 * y * (5.0 * z * z - 1.0),
            0.373176 * z * (5.0 * z * z - 3.0),
            0.457046 * x * (5.0 * z * z - 1.0),
            1.445306 * z * (x * x - y * y),
            0.590044 * x * (x * x - 3.0 * y * y),
        ];
        let b = basis16(w);
        assert_eq!(&b[..SH_COUNT], &basis(w));
        for (k, t) in table.iter().enumerate() {
            assert!(
                (b[9 + k] - t).abs() < 1e-5,
                "Y{}: {} vs {t}",
                9 + k,
                b[9 + k]
            );
        }
    }

    #[test]
    fn open_visibility_matches_numeric_projection() {
        // The closed forms: v_0 = sqrt(pi), and along +z v_2 = 0.488603 pi,
        // v_12 = -0.373176 pi / 2.
        let up = open_visibility(Vec3::Z);
        assert!((up[0] - std::f32::consts::PI.sqrt()).abs() < 1e-5);
        assert!((up[2] - 0.488_603 * std::f32::consts::PI).abs() < 1e-5);
        assert!((up[12] + 0.373_176 * std::f32::consts::FRAC_PI_2).abs() < 1e-5);
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let v = open_visibility(n);
        for (i, &vi) in v.iter().enumerate() {
            let num = integrate(|w| {
                if n.dot(w) > 0.0 {
                    basis16(w)[i] as f64
                } else {
                    0.0
                }
            });
            assert!((num - vi as f64).abs() < 5e-3, "v{i}: {num} vs {vi}");
        }
    }

    #[test]
    fn below_plane_visibility_matches_numeric_projection() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        for (degrees, geo) in tilted_geometric_normals(n) {
            let v = below_plane_visibility(n, geo);
            for (i, &vi) in v.iter().enumerate() {
                let num = integrate(|w| {
                    if n.dot(w) > 0.0 && geo.dot(w) <= 0.0 {
                        basis16(w)[i] as f64
                    } else {
                        0.0
                    }
                });
                assert!(
                    (num - vi as f64).abs() < 5e-3,
                    "{degrees} deg, v{i}: {num} vs {vi}"
                );
            }
            // The lune's solid angle is 2 theta.
            let lune = 2.0 * degrees.to_radians() * 0.282_094_8;
            assert!(
                (v[0] - lune).abs() < 1e-5,
                "{degrees} deg: {} vs {lune}",
                v[0]
            );
        }
        assert_eq!(below_plane_visibility(n, n), [0.0; VIS_COUNT]);
        assert_eq!(below_plane_visibility(Vec3::NAN, n), [0.0; VIS_COUNT]);
        let flipped = below_plane_visibility(n, -n);
        let open = open_visibility(n);
        assert!((0..VIS_COUNT).all(|i| (flipped[i] - open[i]).abs() < 1e-6));
    }
}
