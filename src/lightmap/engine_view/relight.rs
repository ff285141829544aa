//! The relight error of the engine view: what an engine's normal-mapped
//! diffuse makes of the visibility layer's lookups.
//!
//! In: a point's normal, the looked-up c and v and the reference's. Out:
//! |E(n') from the lookups - E(n') from the reference| / unoccluded E(n'),
//! the anchored diffuse of [`crate::relight`] at n' tilted
//! [`RELIGHT_TILT_DEGREES`] from n (azimuth from a key), averaged over
//! [`environments`].

use crate::bits::{mix64, unit};
use crate::relight::{Environment, anchored_diffuse};
use crate::sample::Frame;
use crate::sh::{self, SH_COUNT, VIS_COUNT};
use glam::{Quat, Vec3};

/// The tilt of the normal-mapped normal n' from n in the relight error.
pub const RELIGHT_TILT_DEGREES: f32 = 30.0;
/// Environments of the relight error.
pub const RELIGHT_ENVIRONMENTS: usize = 8;

/// The relight error's environments: two near-directional (a lobe of
/// weight 2 over a dim ambient) and six of an ambient and three lobes,
/// fixed by a seed.
pub fn environments() -> Vec<Environment> {
    let mut state = 0x5eed_e17eu64;
    let mut next = move || {
        state = mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..RELIGHT_ENVIRONMENTS)
        .map(|k| {
            let directional = k < 2;
            let mut l = [0.0f32; SH_COUNT];
            let (ambient, lobes) = if directional {
                (0.05, 1)
            } else {
                (0.2 + next(), 3)
            };
            l[0] = ambient * (4.0 * std::f32::consts::PI).sqrt();
            for _ in 0..lobes {
                let z = 2.0 * next() - 1.0;
                let phi = 2.0 * std::f32::consts::PI * next();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let w = if directional { 2.0 } else { next() };
                let y = sh::basis(d);
                for i in 0..SH_COUNT {
                    l[i] += w * sh::CLAMPED_COSINE_BAND[sh::BAND[i]] * y[i];
                }
            }
            Environment::new(l)
        })
        .collect()
}

/// The mean relight error at one point (see the module doc): the engine's
/// lookups (`c`, `v`) against the reference's (`rc`, `rv`), n' tilted in an
/// azimuth from `key`.
#[allow(clippy::too_many_arguments)]
pub fn relight_error(
    envs: &[Environment],
    n: Vec3,
    key: u64,
    c: &[f32; SH_COUNT],
    v: &[f32; VIS_COUNT],
    rc: &[f32; SH_COUNT],
    rv: &[f32; VIS_COUNT],
) -> f64 {
    let frame = Frame::from_normal(n);
    let phi = 2.0 * std::f32::consts::PI * unit(key);
    let axis = frame.tangent * phi.cos() + frame.bitangent * phi.sin();
    let tilted = Quat::from_axis_angle(
        axis.cross(n).normalize_or(frame.tangent),
        RELIGHT_TILT_DEGREES.to_radians(),
    ) * n;
    let mut sum = 0.0f64;
    for env in envs {
        let open = env.open_diffuse(tilted).abs().max(1e-6);
        let est = anchored_diffuse(env, c, v, n, tilted);
        let truth = anchored_diffuse(env, rc, rv, n, tilted);
        sum += ((est - truth) / open).abs() as f64;
    }
    sum / envs.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_relight_error_vanishes_for_equal_coefficients_and_follows_a_difference() {
        let envs = environments();
        assert_eq!(envs.len(), RELIGHT_ENVIRONMENTS);
        let n = Vec3::new(0.3, -0.2, 0.93).normalize();
        // An open receiver's exact coefficients (the layer's open
        // projection: lambda_l Y_i(n)).
        let y = sh::basis(n);
        let c: [f32; SH_COUNT] = std::array::from_fn(|i| {
            sh::CLAMPED_COSINE_BAND[sh::BAND[i]] / std::f32::consts::PI * y[i]
        });
        let lambda = [2.0 * std::f32::consts::PI, std::f32::consts::PI, 0.0];
        let mut v = [0.0f32; VIS_COUNT];
        for i in 0..SH_COUNT {
            v[i] = lambda[sh::BAND[i]] * y[i];
        }
        assert_eq!(relight_error(&envs, n, 7, &c, &v, &c, &v), 0.0);
        // A visibility coefficient off by d moves E(n') by d x (a tilt's
        // worth of it): some error, and twice the error for twice d.
        let mut v1 = v;
        v1[1] += 0.05;
        let mut v2 = v;
        v2[1] += 0.10;
        let e1 = relight_error(&envs, n, 7, &c, &v1, &c, &v);
        let e2 = relight_error(&envs, n, 7, &c, &v2, &c, &v);
        assert!(e1 > 1e-4, "{e1}");
        assert!((e2 / e1 - 2.0).abs() < 1e-3, "{e1} {e2}");
        // c off by d at n' = n would be c.L off; tilted, the anchor keeps
        // it: the error of a changed c0 is |d L0| / open(n').
        let mut c1 = c;
        c1[0] += 0.01;
        assert!(relight_error(&envs, n, 7, &c1, &v, &c, &v) > 0.0);
    }
}
