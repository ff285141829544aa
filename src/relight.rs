//! Relighting: what an engine does with a bake, on the CPU. The reference
//! for the README's GLSL and the viewer's shader, and what the tests and
//! `probes/visibility_error` measure the layer with.
//!
//! In: an environment's radiance as L2 SH (9 coefficients per colour
//! channel, the contract's basis), a texel's c (9) and v (16 or 9), a
//! vertex normal n and a shading normal n'. Out: the diffuse
//! irradiance over pi at n' ([`anchored_diffuse`]) and the specular
//! occlusion of a glossy lobe ([`specular_occlusion`]).
//!
//! Per environment, [`Environment::new`] forms P_ik = Sum_j Gamma_ijk L_j
//! (Gamma: the SH triple product, [`gaunt`]); per pixel, the visible
//! radiance u = P^T v (u_k = the projection of V(w) H(n.w) L(w)), whose
//! irradiance at any unit normal m is E_C(m)/pi = (1/pi) Sum_{k<9} A_l u_k
//! Y_k(m). The baked c gives the exact value at n; the layer gives the
//! change from n to n': E(n')/pi = c.L + E_C(n')/pi - E_C(n)/pi.

use crate::sh::{self, CLAMPED_COSINE_BAND, SH_COUNT, VIS_BAND, VIS_COUNT};
use glam::Vec3;
use std::sync::OnceLock;

/// The SH triple product Gamma_ijk = Int Y_i Y_j Y_k dw for i, k < 16
/// (the layer and the visible radiance to order 3) and j < 9 (the L2
/// environment): `gaunt()[i][j][k]`. By quadrature, exact for these
/// degrees (the integrand is a polynomial of degree <= 8 in w: 16
/// Gauss-Legendre points in z times 32 uniform in azimuth).
pub fn gaunt() -> &'static [[[f32; VIS_COUNT]; SH_COUNT]; VIS_COUNT] {
    static TABLE: OnceLock<Box<[[[f32; VIS_COUNT]; SH_COUNT]; VIS_COUNT]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let (nodes, weights) = gauss_legendre(16);
        let azimuths = 32;
        let mut g = [[[0.0f64; VIS_COUNT]; SH_COUNT]; VIS_COUNT];
        for (&z, &wz) in nodes.iter().zip(&weights) {
            let r = (1.0 - z * z).max(0.0).sqrt();
            for a in 0..azimuths {
                let phi = (a as f64 + 0.5) / azimuths as f64 * 2.0 * std::f64::consts::PI;
                let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                let y = sh::basis16(w).map(f64::from);
                let weight = wz * 2.0 * std::f64::consts::PI / azimuths as f64;
                for i in 0..VIS_COUNT {
                    for j in 0..SH_COUNT {
                        let yij = weight * y[i] * y[j];
                        for k in 0..VIS_COUNT {
                            g[i][j][k] += yij * y[k];
                        }
                    }
                }
            }
        }
        Box::new(g.map(|a| a.map(|b| b.map(|x| x as f32))))
    })
}

/// P_n(t) and its derivative, by the three-term recurrence.
fn legendre(n: usize, t: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, t);
    for k in 2..=n {
        let p2 = ((2 * k - 1) as f64 * t * p1 - (k - 1) as f64 * p0) / k as f64;
        p0 = p1;
        p1 = p2;
    }
    (p1, n as f64 * (t * p1 - p0) / (t * t - 1.0))
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n).
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut w) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..n {
        let mut t = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        for _ in 0..100 {
            let (p, dp) = legendre(n, t);
            let step = p / dp;
            t -= step;
            if step.abs() < 1e-15 {
                let (_, d) = legendre(n, t);
                x[i] = t;
                w[i] = 2.0 / ((1.0 - t * t) * d * d);
                break;
            }
        }
    }
    (x, w)
}

/// One environment (one colour channel) made ready for relighting: P_ik.
#[derive(Clone, Debug)]
pub struct Environment {
    /// The radiance's L2 coefficients.
    pub l: [f32; SH_COUNT],
    /// P_ik = Sum_j Gamma_ijk L_j.
    pub p: [[f32; VIS_COUNT]; VIS_COUNT],
}

impl Environment {
    pub fn new(l: [f32; SH_COUNT]) -> Environment {
        let g = gaunt();
        let mut p = [[0.0f32; VIS_COUNT]; VIS_COUNT];
        for (i, row) in p.iter_mut().enumerate() {
            for (k, pik) in row.iter_mut().enumerate() {
                *pik = (0..SH_COUNT).map(|j| g[i][j][k] * l[j]).sum();
            }
        }
        Environment { l, p }
    }

    /// The visible radiance u = P^T v (`v`: 16 coefficients, or 9 with the
    /// rest zero), all 16 bands.
    pub fn visible_radiance(&self, v: &[f32]) -> [f32; VIS_COUNT] {
        let mut u = [0.0f32; VIS_COUNT];
        for (vi, row) in v.iter().zip(&self.p) {
            for (uk, pik) in u.iter_mut().zip(row) {
                *uk += vi * pik;
            }
        }
        u
    }

    /// c.L: the baked diffuse irradiance over pi at the vertex normal.
    pub fn baked_diffuse(&self, c: &[f32; SH_COUNT]) -> f32 {
        c.iter().zip(&self.l).map(|(c, l)| c * l).sum()
    }

    /// The unoccluded irradiance over pi at unit normal m.
    pub fn open_diffuse(&self, m: Vec3) -> f32 {
        let y = sh::basis(m);
        (0..SH_COUNT)
            .map(|k| CLAMPED_COSINE_BAND[sh::BAND[k]] / std::f32::consts::PI * self.l[k] * y[k])
            .sum()
    }
}

/// E_C(m)/pi: the irradiance over pi at unit normal m of the visible
/// radiance u (bands 0..2; A_3 = 0).
pub fn irradiance(u: &[f32; VIS_COUNT], m: Vec3) -> f32 {
    let y = sh::basis(m);
    (0..SH_COUNT)
        .map(|k| CLAMPED_COSINE_BAND[sh::BAND[k]] / std::f32::consts::PI * u[k] * y[k])
        .sum()
}

/// The anchored diffuse: E(n')/pi = c.L + E_C(n')/pi - E_C(n)/pi, exactly
/// c.L at n' = n.
pub fn anchored_diffuse(
    env: &Environment,
    c: &[f32; SH_COUNT],
    v: &[f32],
    n: Vec3,
    shading: Vec3,
) -> f32 {
    let u = env.visible_radiance(v);
    env.baked_diffuse(c) + irradiance(&u, shading) - irradiance(&u, n)
}

/// Zonal factors of a normalised glossy lobe of GGX roughness `roughness`
/// (perceptual, alpha = roughness^2), approximated by a Phong lobe of
/// exponent s = 2 / alpha^2 - 2: Lambda_l = exp(-l^2 / (2 s))
/// (Ramamoorthi and Hanrahan 2001), Lambda_0 = 1.
pub fn lobe_bands(roughness: f32) -> [f32; 4] {
    let alpha = (roughness * roughness).clamp(1e-3, 1.0);
    let s = (2.0 / (alpha * alpha) - 2.0).max(1e-3);
    std::array::from_fn(|l| (-((l * l) as f32) / (2.0 * s)).exp())
}

/// Specular occlusion of a glossy lobe about unit direction `r` (the
/// reflected view direction): the lobe-filtered visible radiance over the
/// lobe-filtered radiance of an unoccluded receiver with the same normal,
/// from u to order 3, clamped to [0, 1] (1 where the environment is dark
/// in the lobe).
pub fn specular_occlusion(env: &Environment, v: &[f32], n: Vec3, r: Vec3, roughness: f32) -> f32 {
    let lambda = lobe_bands(roughness);
    let y = sh::basis16(r);
    let filtered = |u: &[f32; VIS_COUNT]| -> f32 {
        (0..VIS_COUNT)
            .map(|k| lambda[VIS_BAND[k]] * u[k] * y[k])
            .sum()
    };
    let open = filtered(&env.visible_radiance(&sh::open_visibility(n)));
    let seen = filtered(&env.visible_radiance(v));
    if open > 1e-6 {
        (seen / open).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn gaunt_is_symmetric_and_its_first_row_is_y0() {
        let g = gaunt();
        for j in 0..SH_COUNT {
            for k in 0..VIS_COUNT {
                let want = if j == k { 0.282_094_8 } else { 0.0 };
                assert!(
                    (g[0][j][k] - want).abs() < 1e-5,
                    "G0{j}{k} = {}",
                    g[0][j][k]
                );
            }
        }
        for i in 0..SH_COUNT {
            for j in 0..SH_COUNT {
                for k in 0..SH_COUNT {
                    assert!((g[i][j][k] - g[j][i][k]).abs() < 1e-5);
                    assert!((g[i][j][k] - g[k][j][i]).abs() < 1e-5);
                }
            }
        }
    }

    /// Brute force over a fine grid of directions: Int V H(n.w) max(0,
    /// m.w) L(w) dw / pi for a visibility V given as a function.
    fn brute(l: &[f32; SH_COUNT], n: Vec3, m: Vec3, vis: impl Fn(Vec3) -> bool) -> f64 {
        let mut s = 0.0;
        sh::for_each_direction(|w, da| {
            if n.dot(w) > 0.0 && vis(w) {
                let lw: f32 = sh::basis(w).iter().zip(l).map(|(y, l)| y * l).sum();
                s += (m.dot(w).max(0.0) * lw) as f64 * da;
            }
        });
        s / std::f64::consts::PI
    }

    /// v and c of a receiver with normal n and visibility `vis`, projected
    /// on the same grid.
    fn project(n: Vec3, vis: impl Fn(Vec3) -> bool) -> ([f32; SH_COUNT], [f32; VIS_COUNT]) {
        let (mut c, mut v) = ([0.0f64; SH_COUNT], [0.0f64; VIS_COUNT]);
        sh::for_each_direction(|w, da| {
            if n.dot(w) > 0.0 && vis(w) {
                let y = sh::basis16(w);
                for k in 0..VIS_COUNT {
                    v[k] += y[k] as f64 * da;
                }
                for k in 0..SH_COUNT {
                    c[k] += (n.dot(w) * y[k]) as f64 * da / std::f64::consts::PI;
                }
            }
        });
        (c.map(|x| x as f32), v.map(|x| x as f32))
    }

    #[test]
    fn an_open_receiver_relights_any_normal_exactly() {
        // Open: V = 1, so E(n') is the environment's irradiance restricted
        // to n's hemisphere; at n' = n the formula is c.L exactly.
        let l = [0.9, 0.2, 0.5, -0.1, 0.05, 0.1, 0.15, -0.05, 0.02];
        let env = Environment::new(l);
        let n = Vec3::new(0.1, 0.3, 0.95).normalize();
        let (c, v) = (sh::open_hemisphere(n), sh::open_visibility(n));
        let at_n = anchored_diffuse(&env, &c, &v, n, n);
        assert!((at_n - env.baked_diffuse(&c)).abs() < 1e-6);
        assert!((at_n - env.open_diffuse(n)).abs() < 1e-4);
        for degrees in [15.0f32, 45.0, 89.0] {
            let tilted = glam::Quat::from_rotation_x(degrees.to_radians()) * n;
            let got = anchored_diffuse(&env, &c, &v, n, tilted) as f64;
            let want = brute(&l, n, tilted, |_| true);
            // Order-3 truncation of H: a few percent at grazing tilts.
            let scale = env.open_diffuse(tilted).abs().max(0.1) as f64;
            assert!(
                ((got - want) / scale).abs() < 0.03,
                "{degrees} deg: {got} vs {want}"
            );
            assert!(got.is_finite());
        }
    }

    #[test]
    fn a_receiver_beside_a_wall_relights_tilted_normals_like_brute_force() {
        // A wall blocks every direction with x > 0.3 (a groove side): the
        // layer relights tilts towards and away from it.
        let n = Vec3::Z;
        let vis = |w: Vec3| w.x < 0.3;
        let (c, v) = project(n, vis);
        let l = [1.0, 0.1, 0.6, 0.4, 0.0, 0.1, 0.2, 0.3, 0.1];
        let env = Environment::new(l);
        // At n' = n: c.L is the brute force's value.
        let at_n = env.baked_diffuse(&c) as f64;
        assert!((at_n - brute(&l, n, n, vis)).abs() < 2e-3);
        let (mut layer, mut ignored) = (0.0, 0.0);
        for (axis, degrees) in [
            (Vec3::Y, 30.0f32),
            (Vec3::Y, -30.0),
            (Vec3::X, 45.0),
            (Vec3::Y, 60.0),
        ] {
            let tilted = glam::Quat::from_axis_angle(axis, degrees.to_radians()) * n;
            let got = anchored_diffuse(&env, &c, &v, n, tilted) as f64;
            let want = brute(&l, n, tilted, vis);
            let fallback = env.baked_diffuse(&c) as f64;
            let scale = env.open_diffuse(tilted).abs() as f64;
            let (err, old) = ((got - want) / scale, (fallback - want) / scale);
            assert!(
                err.abs() < 0.03,
                "{degrees} deg about {axis}: {got} vs {want}"
            );
            layer += err.abs();
            ignored += old.abs();
        }
        // Far better than ignoring the normal map, over the tilts (a tilt
        // away from the wall sees what n sees: there both are close).
        assert!(layer < 0.3 * ignored, "{layer} vs {ignored}");
    }

    #[test]
    fn specular_occlusion_is_one_when_open_and_falls_towards_a_wall() {
        let l = [1.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let env = Environment::new(l);
        let n = Vec3::Z;
        let open = specular_occlusion(&env, &sh::open_visibility(n), n, n, 0.3);
        assert!((open - 1.0).abs() < 1e-5);
        let (_, v) = project(n, |w| w.x < 0.0);
        let towards = Vec3::new(0.8, 0.0, 0.6);
        let away = Vec3::new(-0.8, 0.0, 0.6);
        let (a, b) = (
            specular_occlusion(&env, &v, n, towards, 0.3),
            specular_occlusion(&env, &v, n, away, 0.3),
        );
        assert!(a < 0.4 && b > 0.8, "towards {a}, away {b}");
        for r in [0.0f32, 1.0, f32::NAN] {
            let s = specular_occlusion(&env, &v, n, towards, r);
            assert!((0.0..=1.0).contains(&s), "{r}: {s}");
        }
    }
}
