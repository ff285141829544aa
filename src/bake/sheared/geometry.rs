//! Per-pair math of the sheared filter, each a small pure function tested
//! in isolation: the leak rule, the paper's Eq. 8 (spatial radius), Eq. 9
//! (mid depth), the bandlimit test, Figure 6's reprojection and tangent
//! offset, the filter weight and the reprojection Jacobian.
//!
//! In: positions, directions, normals, depths (bake units). Out: numbers
//! and yes/no answers; no state.

use crate::sample::CELL_COUNT;
use glam::Vec3;

/// Normal agreement of the leak rule: cos 25 degrees.
const NORMAL_AGREEMENT: f32 = 0.906;

/// Largest tangent-plane distance of a neighbour, as a fraction of its
/// distance (plus one footprint): keeps neighbours on the same sheet.
const TANGENT_SLOPE: f32 = 0.25;

/// Geometric normals this close (cos 0.5 degrees) are parallel planes.
const PARALLEL_AGREEMENT: f32 = 0.99996;

/// Largest offset along the normal, in footprints, of a neighbour on a
/// parallel plane: anything farther is another sheet.
const SHEET_OFFSET: f32 = 0.01;

/// The leak rule: whether a neighbour at `rel` from the receiver (shading
/// and geometric normals `n`, `geo`; the neighbour's `n_j`, `geo_j`) may
/// lend its rays. Both normals within 25 degrees, and the neighbour near
/// the receiver's geometric tangent plane: within a slope of 0.25 plus a
/// footprint on curved surfaces, and on the plane itself (0.01 footprint,
/// plus the 0.5-degree tilt) when the planes are parallel, so a second
/// sheet in front of or behind a flat surface (a light quad under a
/// ceiling, a decal, a coplanar duplicate pushed out) never lends rays
/// that its own surface does not see.
#[inline]
pub fn lends_rays(rel: Vec3, n: Vec3, geo: Vec3, n_j: Vec3, geo_j: Vec3, footprint: f32) -> bool {
    let agree = geo_j.dot(geo);
    if n_j.dot(n) < NORMAL_AGREEMENT || agree < NORMAL_AGREEMENT {
        return false;
    }
    let offset = rel.dot(geo).abs();
    let dist = rel.length();
    if agree >= PARALLEL_AGREEMENT {
        offset <= SHEET_OFFSET * footprint + 0.01 * dist + 1e-6
    } else {
        offset <= TANGENT_SLOPE * dist + footprint
    }
}

/// Spatial radius of Eq. 8 (times the shading diameter): the filter's reach
/// for a cell whose occluders lie in [z_min, z_max]. Infinite when
/// z_min = z_max (the shear is exact) or no occluder was seen.
#[inline]
pub(crate) fn spatial_radius(z_min: f32, z_max: f32, omega_v_max: f32) -> f32 {
    let inv_diff = 1.0 / z_min - 1.0 / z_max;
    if inv_diff > 0.0 && inv_diff.is_finite() {
        1.0 / (omega_v_max * inv_diff)
    } else if z_min > 0.0 {
        f32::INFINITY
    } else {
        0.0
    }
}

/// Mid depth of Eq. 9: the harmonic mean of z_min and z_max.
#[inline]
pub(crate) fn mid_depth(z_min: f32, z_max: f32) -> f32 {
    let s = 1.0 / z_min + 1.0 / z_max;
    if s > 0.0 { 2.0 / s } else { f32::INFINITY }
}

/// Depth at which each cell's unoccluded sample rays are re-aimed: the
/// cell's mid depth (Eq. 9), and for a cell without hits (mid depth
/// infinite) the farthest mid depth among the cells around it in the 8x8
/// grid, infinite only when none of them saw an occluder.
///
/// Re-aiming shifts a miss's effective direction by about the neighbour's
/// offset over the aim depth. Where an occluder's silhouette runs along a
/// cell boundary, an open cell re-aimed at infinity shifts nothing across
/// the boundary while the occluded cell's misses shift out of it, so the
/// silhouette cell loses open rays and comes out too dark (floor beside a
/// wall: -0.006). With one depth on both sides the shifts cancel. The
/// farthest neighbour is the one that shifts least.
pub fn miss_depths(mid: &[f32; CELL_COUNT], aim: &mut [f32; CELL_COUNT]) {
    let side = crate::sample::CELLS_PER_SIDE as i32;
    for c in 0..CELL_COUNT {
        aim[c] = mid[c];
        if mid[c].is_finite() {
            continue;
        }
        let (cx, cy) = (c as i32 % side, c as i32 / side);
        let mut farthest = 0.0f32;
        for y in (cy - 1).max(0)..=(cy + 1).min(side - 1) {
            for x in (cx - 1).max(0)..=(cx + 1).min(side - 1) {
                let m = mid[(y * side + x) as usize];
                if m.is_finite() {
                    farthest = farthest.max(m);
                }
            }
        }
        if farthest > 0.0 {
            aim[c] = farthest;
        }
    }
}

/// Whether the paper's bandlimit test sends a cell to brute force:
/// Omega_v^max / z_min > Omega_pix with Omega_pix = 0.5 / shading diameter.
#[inline]
pub(crate) fn needs_brute_force(z_min: f32, omega_v_max: f32, footprint: f32) -> bool {
    // Written so that a NaN z_min also sends the cell to brute force.
    z_min.is_nan() || z_min < omega_v_max * footprint * 2.0
}

/// Filter weight for a tangent offset x over a spatial radius (biweight,
/// 1 at x = 0, 0 from x = radius on).
#[inline]
pub fn weight(x: f32, radius: f32) -> f32 {
    let q = x / radius;
    if q < 1.0 {
        (1.0 - q * q) * (1.0 - q * q)
    } else {
        0.0
    }
}

/// [`weight`] from the squared offset (no square root in the hot loop).
#[inline]
pub(crate) fn weight_sq(x2: f32, radius: f32) -> f32 {
    let q2 = x2.max(0.0) / (radius * radius);
    if q2 < 1.0 {
        (1.0 - q2) * (1.0 - q2)
    } else {
        0.0
    }
}

/// Effective direction and tangent offset of a sample ray (origin `o`,
/// direction `d`) re-aimed from `receiver` at `target` (Figure 6). `None`
/// if the target is the receiver or the ray runs parallel to the plane.
#[inline]
pub fn reproject(receiver: Vec3, o: Vec3, d: Vec3, target: Vec3) -> Option<(Vec3, f32, f32)> {
    let v = target - receiver;
    let dist = v.length();
    if dist.is_nan() || dist <= 0.0 {
        return None;
    }
    let e = v / dist;
    let de = d.dot(e);
    if de.abs() < 1e-6 {
        return None;
    }
    let rel = o - receiver;
    let u = -rel.dot(e) / de;
    Some((e, (rel + d * u).length(), dist))
}

/// Where a neighbour's hit lies relative to the receiver: the neighbour at
/// `rel` from the receiver, its ray `d` hitting at distance `t`. Summed
/// from the offset, not from absolute positions: `pj + d t - p` rounds a
/// hit closer than an ulp of the coordinates (a surface through the
/// receiver, ~1e-8 of the scene) to exactly the receiver, which then
/// looked open (two-cylinder engine at 1024: a texel of AO 0.5 came out 1).
#[inline]
pub(crate) fn hit_offset(rel: Vec3, d: Vec3, t: f32) -> Vec3 {
    rel + d * t
}

/// Squared tangent offset x^2 of a sample ray (origin at `rel` from the
/// receiver, direction `d`) re-aimed along the effective direction `e`:
/// where the ray crosses the plane through the receiver perpendicular to
/// `e` ([`reproject`] with the target already known). `None` if the ray
/// runs parallel to that plane.
#[inline]
pub(crate) fn tangent_offset_sq(rel: Vec3, d: Vec3, e: Vec3) -> Option<f32> {
    let de = d.dot(e);
    if de.abs() < 1e-6 {
        return None;
    }
    let u = -rel.dot(e) / de;
    Some((rel + d * u).length_squared())
}

/// Largest reprojection Jacobian a sample may carry: grazing targets
/// (a hit seen edge-on from the neighbour) would otherwise dominate a cell.
pub const MAX_JACOBIAN: f32 = 4.0;

/// Weight correcting a re-aimed sample for the change of density between
/// the neighbour's cosine-distributed directions and the receiver's: the
/// ratio of projected solid angles of the target patch seen from the
/// receiver and from the neighbour,
/// (cos theta_r |cos alpha_r| / dist_r^2) / (cos theta_n |cos alpha_n| / dist_n^2),
/// with theta against each one's normal and alpha against the target's
/// surface normal (the same Jacobian as spatial reuse in ReSTIR). 1 for a
/// target at infinity seen from the same plane. Clamped to
/// [0, MAX_JACOBIAN]; 0 for targets behind either point.
#[inline]
pub fn reprojection_jacobian(
    cos_receiver: f32,
    cos_neighbour: f32,
    cos_target_receiver: f32,
    cos_target_neighbour: f32,
    dist_receiver: f32,
    dist_neighbour: f32,
) -> f32 {
    let num = cos_receiver * cos_target_receiver.abs() * dist_neighbour * dist_neighbour;
    let den = cos_neighbour * cos_target_neighbour.abs() * dist_receiver * dist_receiver;
    // Written so that NaN inputs also give 0.
    if cos_receiver <= 0.0 || den.is_nan() || den <= 0.0 {
        return 0.0;
    }
    let j = num / den;
    if j.is_nan() { 0.0 } else { j.min(MAX_JACOBIAN) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hit_at_distance_near_zero_keeps_its_distance() {
        let p = Vec3::new(0.31, -0.27, 0.4);
        let d = Vec3::new(0.6, 0.0, 0.8);
        // The receiver's own ray (rel = 0) hitting at 1.5e-9.
        let v = hit_offset(p - p, d, 1.5e-9);
        assert!((v.length() - 1.5e-9).abs() < 1e-15, "{}", v.length());
        assert!((v / v.length() - d).length() < 1e-6);
        // The absolute form loses it entirely.
        assert_eq!((p + d * 1.5e-9 - p).length(), 0.0);
        // A neighbour's hit: the same point as the absolute form.
        let pj = p + Vec3::new(0.01, 0.002, 0.0);
        let v = hit_offset(pj - p, d, 0.2);
        assert!((v - (pj + d * 0.2 - p)).length() < 1e-7);
    }

    #[test]
    fn misses_of_open_cells_aim_at_the_farthest_occluded_neighbour_cell() {
        let inf = f32::INFINITY;
        let mut mid = [inf; CELL_COUNT];
        // Cell (2, 2) and (3, 3) saw occluders.
        mid[2 * 8 + 2] = 0.5;
        mid[3 * 8 + 3] = 0.8;
        let mut aim = [0.0; CELL_COUNT];
        miss_depths(&mid, &mut aim);
        // Cells with hits keep their own mid depth.
        assert_eq!(aim[2 * 8 + 2], 0.5);
        assert_eq!(aim[3 * 8 + 3], 0.8);
        // Open cells touching only (2, 2); touching both: the farther.
        assert_eq!(aim[8 + 1], 0.5);
        assert_eq!(aim[2 * 8 + 3], 0.8);
        assert_eq!(aim[4 * 8 + 4], 0.8);
        // Open cells two cells away from any occluder stay at infinity,
        // and the grid does not wrap around.
        assert_eq!(aim[0], inf);
        assert_eq!(aim[5 * 8 + 5], inf);
        assert_eq!(aim[2 * 8 + 7], inf);
        // Nothing seen anywhere: everything at infinity; a zero mid depth
        // (contact) is not a depth to aim at.
        mid = [inf; CELL_COUNT];
        mid[9] = 0.0;
        miss_depths(&mid, &mut aim);
        assert!(
            aim.iter()
                .enumerate()
                .all(|(c, &a)| a == if c == 9 { 0.0 } else { inf })
        );
    }

    #[test]
    fn spatial_radius_stiff_cases() {
        // z_max -> infinity: radius = z_min / Omega_v.
        assert!((spatial_radius(0.5, f32::INFINITY, 2.0) - 0.25).abs() < 1e-7);
        // z_min = z_max: the shear is exact, no bound on the radius.
        assert_eq!(spatial_radius(0.3, 0.3, 2.0), f32::INFINITY);
        // Contact (z_min -> 0): radius -> 0, never NaN.
        assert_eq!(spatial_radius(0.0, 1.0, 2.0), 0.0);
        assert!(spatial_radius(1e-30, 1.0, 2.0) < 1e-29);
        // Omega_v at its extremes.
        assert_eq!(spatial_radius(0.5, 1.0, f32::INFINITY), 0.0);
        assert_eq!(spatial_radius(0.5, 1.0, 0.0), f32::INFINITY);
        assert!(!spatial_radius(0.5, 1.0, 1e-30).is_nan());
        // General case matches Eq. 8 times the shading diameter.
        let (zmin, zmax, ov, d) = (0.2f32, 0.7f32, 2.0f32, 0.01f32);
        let primal_scale = (2.0 * (0.5 / d) / ov) / (1.0 / zmin - 1.0 / zmax);
        assert!((spatial_radius(zmin, zmax, ov) - d * primal_scale).abs() < 1e-5);
    }

    #[test]
    fn mid_depth_is_the_harmonic_mean() {
        assert!((mid_depth(1.0, 3.0) - 1.5).abs() < 1e-6);
        assert!((mid_depth(0.4, 0.4) - 0.4).abs() < 1e-7);
        assert!((mid_depth(1.0, f32::INFINITY) - 2.0).abs() < 1e-6);
        assert_eq!(mid_depth(0.0, 1.0), 0.0);
        assert_eq!(mid_depth(f32::INFINITY, f32::INFINITY), f32::INFINITY);
    }

    #[test]
    fn bandlimit_test_matches_the_paper() {
        // Omega_v / z_min > 0.5 / d  <=>  z_min < 2 Omega_v d.
        assert!(needs_brute_force(0.039, 2.0, 0.01));
        assert!(!needs_brute_force(0.041, 2.0, 0.01));
        assert!(needs_brute_force(0.0, 2.0, 0.01));
        assert!(needs_brute_force(f32::NAN, 2.0, 0.01));
        // Zero footprint (degenerate UVs): nothing forces brute force but contact.
        assert!(!needs_brute_force(1e-9, 2.0, 0.0));
    }

    #[test]
    fn weight_is_one_at_zero_and_vanishes_at_the_radius() {
        assert_eq!(weight(0.0, 1.0), 1.0);
        assert_eq!(weight(1.0, 1.0), 0.0);
        assert_eq!(weight(2.0, 1.0), 0.0);
        assert_eq!(weight(0.3, f32::INFINITY), 1.0);
        assert_eq!(weight(0.3, 0.0), 0.0);
        assert!(weight(0.5, 1.0) > weight(0.6, 1.0));
        for x in [0.0f32, 0.3, 0.99, 1.5] {
            assert!((weight_sq(x * x, 1.3) - weight(x, 1.3)).abs() < 1e-6);
        }
        assert_eq!(weight_sq(-1e-9, 1.0), 1.0);
    }

    #[test]
    fn reprojection_of_figure_6() {
        // Receiver at origin; a neighbour at (1,0,0) whose ray goes straight
        // up and hits at (1,0,1): effective direction toward the hit, tangent
        // offset = distance from receiver to where the ray crosses the plane
        // through the receiver perpendicular to that direction.
        let (e, x, dist) =
            reproject(Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)).unwrap();
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((e - Vec3::new(s, 0.0, s)).length() < 1e-6);
        assert!((dist - 2f32.sqrt()).abs() < 1e-6);
        // The ray (1,0,u) meets x + z = 0 at u = -1: offset |(1,0,-1)| = sqrt 2.
        assert!((x - 2f32.sqrt()).abs() < 1e-6);
        // A ray aimed at the receiver's own target from the receiver: x = 0.
        let (_, x, _) =
            reproject(Vec3::ZERO, Vec3::ZERO, Vec3::Z, Vec3::new(0.0, 0.0, 2.0)).unwrap();
        assert!(x.abs() < 1e-7);
        // Degenerate target (the receiver itself) and parallel rays.
        assert!(reproject(Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::ZERO).is_none());
        assert!(reproject(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.0, 0.0, 1.0)).is_none());
    }

    #[test]
    fn jacobian_turns_reprojected_samples_into_the_receivers_cosine_measure() {
        // Cosine rays from a neighbour at (0.3, 0, 0) hit the plane z = 1
        // (normal +z) and are re-aimed from the receiver at the origin. With
        // the Jacobian as weight, the weight per cell must be the cosine
        // measure of the cell (1/64 each); without it, it is not.
        use crate::sample::{cell_of, cosine_hemisphere, sobol_2d};
        let (pn, h) = (Vec3::new(0.3, 0.0, 0.0), 1.0f32);
        let mut weighted = [0.0f64; CELL_COUNT];
        let mut plain = [0.0f64; CELL_COUNT];
        let (mut total_w, mut total) = (0.0f64, 0.0f64);
        for i in 0..1 << 18 {
            let d = cosine_hemisphere(sobol_2d(i, 7));
            if d.z < 1e-3 {
                continue;
            }
            let t = h / d.z;
            let target = pn + d * t;
            let dist = target.length();
            let e = target / dist;
            let j = reprojection_jacobian(e.z, d.z, e.z, d.z, dist, t);
            let c = cell_of(e);
            weighted[c] += j as f64;
            plain[c] += 1.0;
            total_w += j as f64;
            total += 1.0;
        }
        // Inner cells only: toward the horizon the clamp (MAX_JACOBIAN) and
        // the finite sample count dominate.
        let inner = |c: usize| {
            let (x, y) = ((c % 8) as i32, (c / 8) as i32);
            (2..6).contains(&x) && (2..6).contains(&y)
        };
        let (mut worst_w, mut worst_plain) = (0.0f64, 0.0f64);
        for c in (0..CELL_COUNT).filter(|&c| inner(c)) {
            let want = 1.0 / CELL_COUNT as f64;
            worst_w = worst_w.max((weighted[c] / total_w - want).abs() / want);
            worst_plain = worst_plain.max((plain[c] / total - want).abs() / want);
        }
        assert!(worst_w < 0.03, "weighted cells off by {worst_w}");
        assert!(
            worst_plain > 0.1,
            "the test must need the Jacobian: {worst_plain}"
        );
        // Same point, same normal: weight 1. Behind the receiver: 0.
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.7, 2.0, 2.0), 1.0);
        assert_eq!(reprojection_jacobian(-0.1, 0.5, 0.7, 0.7, 2.0, 2.0), 0.0);
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.0, 2.0, 2.0), 0.0);
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.7, 0.0, 2.0), 0.0);
        assert_eq!(
            reprojection_jacobian(0.9, 0.1, 0.9, 0.1, 1.0, 9.0),
            MAX_JACOBIAN
        );
        assert_eq!(
            reprojection_jacobian(f32::NAN, 0.5, 0.7, 0.7, 2.0, 2.0),
            0.0
        );
    }

    #[test]
    fn leak_rule() {
        let (n, f) = (Vec3::Z, 0.01f32);
        let lends = |rel: Vec3, nj: Vec3| lends_rays(rel, n, n, nj, nj, f);
        // Same plane, any distance: lends.
        assert!(lends(Vec3::new(0.04, 0.0, 0.0), Vec3::Z));
        // A parallel sheet 0.3 footprints in front (a light quad under a
        // ceiling) or behind: does not.
        assert!(!lends(Vec3::new(0.02, 0.0, 0.003), Vec3::Z));
        assert!(!lends(Vec3::new(0.02, 0.0, -0.003), Vec3::Z));
        // Facing the other way, or 40 degrees off: does not.
        assert!(!lends(Vec3::new(0.02, 0.0, 0.0), -Vec3::Z));
        let tilted = Vec3::new(40f32.to_radians().sin(), 0.0, 40f32.to_radians().cos());
        assert!(!lends(Vec3::new(0.02, 0.0, 0.0), tilted));
        // A curved surface (10 degrees off) rising along the slope: lends;
        // far above the tangent plane: does not.
        let bent = Vec3::new(10f32.to_radians().sin(), 0.0, 10f32.to_radians().cos());
        assert!(lends(Vec3::new(0.04, 0.0, 0.004), bent));
        assert!(!lends(Vec3::new(0.04, 0.0, 0.03), bent));
        // The other face of a thin wall (opposite normals): does not.
        assert!(!lends_rays(Vec3::new(0.0, 0.0, -0.002), n, n, -n, -n, f));
    }

    #[test]
    fn tangent_offset_matches_reprojection() {
        // Figure 6's example: x = sqrt 2.
        let e = Vec3::new(1.0, 0.0, 1.0).normalize();
        let x2 = tangent_offset_sq(Vec3::X, Vec3::Z, e).unwrap();
        assert!((x2 - 2.0).abs() < 1e-5);
        // Against reproject for skewed rays and targets.
        let receiver = Vec3::new(0.3, -0.2, 0.1);
        for (o, d, target) in [
            (
                Vec3::new(0.5, 0.1, 0.1),
                Vec3::new(0.2, 0.3, 0.9),
                Vec3::new(0.4, 0.7, 1.3),
            ),
            (
                Vec3::new(-0.1, -0.4, 0.12),
                Vec3::new(-0.6, 0.1, 0.5),
                Vec3::new(-1.0, 0.0, 0.9),
            ),
        ] {
            let d = d.normalize();
            let (e, x, _) = reproject(receiver, o, d, target).unwrap();
            let x2 = tangent_offset_sq(o - receiver, d, e).unwrap();
            assert!((x2.sqrt() - x).abs() < 1e-5, "{x2} {x}");
        }
        // Parallel to the plane: no offset.
        assert!(tangent_offset_sq(Vec3::X, Vec3::X, Vec3::Z).is_none());
    }
}
