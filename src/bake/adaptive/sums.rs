//! What a receiver's rays add up to, and the values it lends the filter.
//!
//! In: a receiver's rays as the passes count them (visible, below the
//! geometric plane, the SH of the occluded and of all rays). Out: the 10
//! values (AO and the occluded share of the 9 SH) the filter averages
//! ([`below_compensated`]), and the exact share of the hemisphere below
//! the geometric plane ([`below_fraction`]), which the bake adds back per
//! receiver after the filter.

use crate::sh::{self, SH_COUNT};
use glam::Vec3;

/// Receivers per parallel work item of the passes.
pub(crate) const CHUNK: usize = 64;

/// One receiver's running sums over its rays.
#[derive(Clone, Copy, Debug, Default)]
pub struct RaySums {
    pub visible: u32,
    /// Rays below the geometric plane (occluded without tracing).
    pub below: u32,
    /// Sum of Y_i over the occluded rays ([`sh::occluded_share`]); a
    /// filtered receiver's leave out the rays below ([`below_compensated`]).
    pub sh: [f32; SH_COUNT],
    /// Sum of Y_i over all rays (the same).
    pub all: [f32; SH_COUNT],
}

/// The 10 values (AO, then the occluded share of the 9 SH, less) that one
/// receiver lends the filter: estimates of the occlusion above its
/// geometric plane, plus the exact share below it (AO
/// [`below_fraction`] b, SH [`sh::below_plane`] L), which the bake
/// subtracts again per receiver after the filter. Filtering the whole
/// occlusion mixed the neighbours' shares below their planes, which
/// differ on a curved surface with shading normals (and a 16-ray receiver
/// keeps the sampling error of its rays below): the wide filters' error
/// fell by a third on the curtains (`docs/measurements/constants.md`,
/// below_compensated).
///
/// `above_only` (a filtered receiver): `s` holds the rays above the plane
/// only and `s.below` counts the others; the estimate is the exact share
/// below plus (1 - b) times the above rays' (its rays below tell nothing
/// then: none of their sampling error is left). Otherwise (an unfiltered
/// receiver, whose value the filter returns as it is) the usual estimate
/// of all of its rays ([`sh::occluded_share`]) plus (b, L): its own value
/// after the bake subtracts them again. (The exact share as a control
/// variate there measured worse: in contact the rays below and the hits
/// above are one occluded region, and subtracting the exact share from an
/// AO near 0 then clamping biased it bright:
/// `docs/measurements/constants.md`, below_compensated's control variate.)
pub fn below_compensated(
    s: &RaySums,
    rays: u32,
    n: Vec3,
    geo: Vec3,
    above_only: bool,
) -> [f32; 10] {
    let b = below_fraction(n, geo);
    let below_sh = sh::below_plane(n, geo);
    let open = sh::open_hemisphere(n);
    let mut v = [0.0f32; 10];
    if above_only {
        let above = rays.saturating_sub(s.below);
        // Per above ray, its share of the hemisphere's 1 - b; the visible
        // fraction of the above rays (1 when there are none).
        let (per_ray, visible) = if above > 0 {
            ((1.0 - b) / above as f32, s.visible as f32 / above as f32)
        } else {
            (0.0, 1.0)
        };
        let open_above: [f32; SH_COUNT] = std::array::from_fn(|i| open[i] - below_sh[i]);
        let hits = above - s.visible.min(above);
        v[0] = 1.0 - hits as f32 * per_ray;
        let share = sh::occluded_share(&open_above, &s.sh, &s.all, per_ray, visible);
        v[1..].copy_from_slice(&share);
    } else {
        let inv = 1.0 / rays.max(1) as f32;
        v[0] = s.visible as f32 * inv + b;
        let share = sh::occluded_share(&open, &s.sh, &s.all, inv, s.visible as f32 * inv);
        for ((v, s), b) in v[1..].iter_mut().zip(share).zip(below_sh) {
            *v = s + b;
        }
    }
    v
}

/// The share of a receiver's cosine-weighted hemisphere (about shading
/// normal `n`) below its geometric plane (normal `geo`): (1 - n.geo) / 2
/// (the plane cuts the hemisphere's projected unit disc along a half
/// ellipse of semi-axes 1 and n.geo). Those directions are occluded
/// without tracing.
#[inline]
pub fn below_fraction(n: Vec3, geo: Vec3) -> f32 {
    ((1.0 - n.dot(geo)) / 2.0).clamp(0.0, 1.0)
}

/// A receiver's filtered AO `a` finished: less the exact share below its
/// geometric plane ([`below_fraction`]), clamped to [0, 1].
#[inline]
pub fn finish_ao(a: f32, n: Vec3, geo: Vec3) -> f32 {
    (a - below_fraction(n, geo)).clamp(0.0, 1.0)
}

/// Finishes the filtered values of every receiver: the AO less the exact
/// share below its geometric plane ([`below_fraction`], clamped to [0,
/// 1]), the SH plus the open hemisphere's exact projection for its own
/// normal ([`sh::open_hemisphere`]) less the exact share below
/// ([`sh::below_plane`]). The open projection is added after the filter:
/// filtering it with the occluded share mixed the neighbours' normals
/// into the L1 band on curved surfaces, past Monte Carlo's error even at
/// twice the quality (`docs/measurements/constants.md`, finish).
pub fn finish(normal: &[Vec3], geo_normal: &[Vec3], ao: &mut [f32], sh: &mut [[f32; SH_COUNT]]) {
    use rayon::prelude::*;
    ao.par_iter_mut()
        .zip(sh)
        .enumerate()
        .for_each(|(r, (a, s))| {
            let (n, geo) = (normal[r], geo_normal[r]);
            *a = finish_ao(*a, n, geo);
            for ((s, o), b) in
                (s.iter_mut().zip(sh::open_hemisphere(n))).zip(sh::below_plane(n, geo))
            {
                *s += o - b;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::Frame;

    /// The sums of `rays` rays of a receiver with shading normal `n` and
    /// geometric normal Z, visible where `visible(d)` (above the plane),
    /// with or without the rays below in the SH sums.
    fn sums_of(n: Vec3, rays: u32, above_only: bool, visible: impl Fn(Vec3) -> bool) -> RaySums {
        let frame = Frame::from_normal(n);
        let mut s = RaySums::default();
        for i in 0..rays {
            let d = frame
                .to_world(crate::sample::cosine_hemisphere(crate::sample::sobol_2d(
                    i, 3,
                )))
                .normalize();
            if d.z <= 0.0 {
                s.below += 1;
                if above_only {
                    continue;
                }
            } else if visible(d) {
                s.visible += 1;
                sh::accumulate(&mut s.all, 1.0, d);
                continue;
            }
            sh::accumulate(&mut s.all, 1.0, d);
            sh::accumulate(&mut s.sh, 1.0, d);
        }
        s
    }

    /// A receiver's AO and SH from the values it lends the filter, as the
    /// bake finishes them when its filter returns them as they are.
    fn finished(v: [f32; 10], n: Vec3) -> (f32, [f32; SH_COUNT]) {
        let open = sh::open_hemisphere(n);
        let below = sh::below_plane(n, Vec3::Z);
        (
            v[0] - below_fraction(n, Vec3::Z),
            std::array::from_fn(|i| v[1 + i] + open[i] - below[i]),
        )
    }

    #[test]
    fn below_compensated_values_are_exact_for_open_and_closed_receivers() {
        let n = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let b = (1.0 - n.z) / 2.0;
        let (open, below) = (sh::open_hemisphere(n), sh::below_plane(n, Vec3::Z));
        // Everything above the plane visible: 1 - b and the open hemisphere
        // less the part below, exactly (16 rays see 2 or 3 below).
        let s = sums_of(n, 16, true, |_| true);
        assert!(s.below > 0);
        let (ao, c) = finished(below_compensated(&s, 16, n, Vec3::Z, true), n);
        assert!((ao - (1.0 - b)).abs() < 1e-6, "{ao}");
        assert!((0..SH_COUNT).all(|i| (c[i] - (open[i] - below[i])).abs() < 1e-6));
        // Everything occluded: zero.
        let s = sums_of(n, 16, true, |_| false);
        let (ao, c) = finished(below_compensated(&s, 16, n, Vec3::Z, true), n);
        assert!(ao.abs() < 1e-6, "{ao}");
        assert!(c.iter().all(|c| c.abs() < 1e-6), "{c:?}");
    }

    #[test]
    fn below_compensated_values_keep_l0_the_ao_and_unfiltered_ones_monte_carlo() {
        let n = Vec3::new(0.0, -0.6, 0.8);
        // Half of the above rays blocked, by a wall on +x.
        let wall = |d: Vec3| d.x < 0.2;
        for rays in [16, 64, 256] {
            // Filtered: L0 is Y_0 times the AO.
            let s = sums_of(n, rays, true, wall);
            let (ao, c) = finished(below_compensated(&s, rays, n, Vec3::Z, true), n);
            assert!(
                (c[0] - 0.282_094_8 * ao).abs() < 1e-6,
                "{rays}: {} {ao}",
                c[0]
            );
            // Unfiltered: Monte Carlo's estimate of the same rays.
            let s = sums_of(n, rays, false, wall);
            let (ao, c) = finished(below_compensated(&s, rays, n, Vec3::Z, false), n);
            let mc = s.visible as f32 / rays as f32;
            let mc_sh = sh::from_sums(n, &s.sh, &s.all, rays, mc);
            assert!((ao - mc).abs() < 1e-6, "{rays}: {ao} vs {mc}");
            assert!((0..SH_COUNT).all(|i| (c[i] - mc_sh[i]).abs() < 1e-5));
        }
    }

    #[test]
    fn below_fraction_matches_counted_directions() {
        // Cosine-weighted directions about n below a plane tilted by theta:
        // counted over 4096 Sobol points against (1 - cos theta) / 2.
        let n = Vec3::Z;
        for deg in [0.0f32, 10.0, 30.0, 60.0, 90.0] {
            let th = deg.to_radians();
            let geo = Vec3::new(th.sin(), 0.0, th.cos());
            let below = (0..4096u32)
                .filter(|&i| {
                    let d = crate::sample::cosine_hemisphere(crate::sample::sobol_2d(i, 7));
                    d.dot(geo) < 0.0
                })
                .count() as f32
                / 4096.0;
            assert!(
                (below - below_fraction(n, geo)).abs() < 0.005,
                "{deg}: {below}"
            );
        }
        assert_eq!(below_fraction(n, n), 0.0);
    }
}
