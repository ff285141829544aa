//! Hemisphere sampling shared by the Monte Carlo baker and the filter.
//!
//! Directions come from a scrambled 2D Sobol (0,2)-sequence in the unit
//! square, mapped through Shirley-Chiu's concentric map onto the disk and
//! lifted to the hemisphere (Malley's method), which makes them
//! cosine-weighted. The map preserves area, so an 8x8 grid of square cells
//! becomes 64 hemisphere *cells* of equal projected solid angle (the paper's
//! Section 5); [`cell_of`] inverts the map to find a direction's cell.

use crate::bits::mix64;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_4, PI};

/// Cells per side of the square domain (the paper uses 8x8).
pub(crate) const CELLS_PER_SIDE: usize = 8;
/// Number of hemisphere cells.
pub const CELL_COUNT: usize = CELLS_PER_SIDE * CELLS_PER_SIDE;

/// Shirley-Chiu concentric map from `[0,1]^2` to the unit disk.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Inverse of [`concentric_disk`]: a disk point back to `[0,1]^2`.
#[inline]
pub(crate) fn concentric_disk_inverse(p: Vec2) -> Vec2 {
    let r = p.length();
    if r == 0.0 {
        return Vec2::splat(0.5);
    }
    let o = if p.x.abs() >= p.y.abs() {
        let a = r.copysign(p.x);
        Vec2::new(a, a * (p.y / p.x).atan() / FRAC_PI_4)
    } else {
        let b = r.copysign(p.y);
        Vec2::new(b * (p.x / p.y).atan() / FRAC_PI_4, b)
    };
    ((o + Vec2::ONE) * 0.5).clamp(Vec2::ZERO, Vec2::ONE)
}

/// Cosine-weighted direction in the local frame (z = normal) for `u` in `[0,1]^2`.
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Uniformly distributed direction (in solid angle) in the local frame (z =
/// normal) for `u` in `[0,1]^2`: z = u.x, azimuth 2 pi u.y (Archimedes'
/// map, area-preserving, so a stratified square gives stratified solid
/// angle). The visibility layer's rays, whose integrand has no cosine.
#[inline]
pub fn uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u.y).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Index of the hemisphere cell holding local direction `d` (z >= 0 side).
#[inline]
pub fn cell_of(d: Vec3) -> usize {
    let u = concentric_disk_inverse(Vec2::new(d.x, d.y));
    let n = CELLS_PER_SIDE as f32;
    let cx = ((u.x * n) as usize).min(CELLS_PER_SIDE - 1);
    let cy = ((u.y * n) as usize).min(CELLS_PER_SIDE - 1);
    cy * CELLS_PER_SIDE + cx
}

/// atan(z) for |z| <= 1, minimax polynomial (|error| < 2e-6 rad).
#[inline]
fn atan_unit(z: f32) -> f32 {
    let z2 = z * z;
    z * (0.999_866 + z2 * (-0.330_299_5 + z2 * (0.180_141 + z2 * (-0.085_133 + z2 * 0.020_835_1))))
}

/// [`cell_of`] with a polynomial arctangent: the filter's hot-loop version.
/// Differs from [`cell_of`] only for directions within ~1e-5 of a cell
/// boundary.
#[inline]
pub(crate) fn cell_of_fast(d: Vec3) -> usize {
    let (x, y) = (d.x, d.y);
    let r = (x * x + y * y).sqrt();
    let (ox, oy) = if r == 0.0 {
        (0.0, 0.0)
    } else if x.abs() >= y.abs() {
        let a = r.copysign(x);
        (a, a * atan_unit(y / x) * (4.0 / std::f32::consts::PI))
    } else {
        let b = r.copysign(y);
        (b * atan_unit(x / y) * (4.0 / std::f32::consts::PI), b)
    };
    let n = CELLS_PER_SIDE as f32 * 0.5;
    let cx = (((ox + 1.0) * n) as usize).min(CELLS_PER_SIDE - 1);
    let cy = (((oy + 1.0) * n) as usize).min(CELLS_PER_SIDE - 1);
    cy * CELLS_PER_SIDE + cx
}

/// The cell of a point `u` of `[0,1)^2` (the square the concentric map
/// takes to the disk): the inverse of [`in_cell`].
#[inline]
pub fn square_cell(u: Vec2) -> usize {
    let n = CELLS_PER_SIDE as f32;
    let cx = ((u.x * n) as usize).min(CELLS_PER_SIDE - 1);
    let cy = ((u.y * n) as usize).min(CELLS_PER_SIDE - 1);
    cy * CELLS_PER_SIDE + cx
}

/// The point of `[0,1]^2` at offset `u` inside cell `cell`.
#[inline]
pub fn in_cell(cell: usize, u: Vec2) -> Vec2 {
    let n = CELLS_PER_SIDE as f32;
    Vec2::new(
        ((cell % CELLS_PER_SIDE) as f32 + u.x) / n,
        ((cell / CELLS_PER_SIDE) as f32 + u.y) / n,
    )
}

/// An orthonormal frame around a unit normal (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub tangent: Vec3,
    pub bitangent: Vec3,
    pub normal: Vec3,
}

impl Frame {
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            tangent: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            bitangent: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            normal: n,
        }
    }
    #[inline]
    pub fn to_world(&self, l: Vec3) -> Vec3 {
        self.tangent * l.x + self.bitangent * l.y + self.normal * l.z
    }
    #[inline]
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        Vec3::new(
            w.dot(self.tangent),
            w.dot(self.bitangent),
            w.dot(self.normal),
        )
    }
}

/// The seed of one receiver's sample stream, independent of thread count.
#[inline]
pub fn receiver_seed(seed: u64, receiver: u64, stream: u64) -> u64 {
    mix64(
        seed ^ mix64(
            receiver
                .wrapping_add(0x9e37_79b9_7f4a_7c15)
                .wrapping_mul(stream | 1)
                ^ stream,
        ),
    )
}

/// Hash-based Owen scrambling of a 32-bit fixed-point value (Laine-Karras,
/// as in pbrt-v4's `FastOwenScrambler`).
#[inline]
fn owen_scramble(v: u32, seed: u32) -> u32 {
    let mut v = v.reverse_bits();
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

/// Point `i` of the Owen-scrambled 2D Sobol (0,2)-sequence for `seed`.
/// Any 2^k consecutive-from-zero points stratify `[0,1]^2` into every
/// elementary interval of area 2^-k.
#[inline]
pub fn sobol_2d(i: u32, seed: u64) -> Vec2 {
    let x = i.reverse_bits();
    let mut y = 0u32;
    let mut v = 1u32 << 31;
    let mut k = i;
    while k != 0 {
        if k & 1 != 0 {
            y ^= v;
        }
        k >>= 1;
        v ^= v >> 1;
    }
    let sx = owen_scramble(x, seed as u32);
    let sy = owen_scramble(y, (seed >> 32) as u32);
    const SCALE: f32 = 1.0 / 4_294_967_296.0;
    // Keep strictly below 1 so cell indices never overflow.
    Vec2::new(
        ((sx >> 8) as f32 * (SCALE * 256.0)).min(1.0 - f32::EPSILON),
        ((sy >> 8) as f32 * (SCALE * 256.0)).min(1.0 - f32::EPSILON),
    )
}

/// Projected solid angle of the hemisphere (= pi); each cell holds 1/64 of it.
pub const HEMISPHERE_PROJECTED: f32 = PI;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_block_of_64_sobol_points_fills_each_cell_once() {
        // The filter's second pass relies on this (0,6,2)-net property of
        // the scrambled sequence: points 64 b..64 (b + 1) put exactly one
        // point in each 8x8 cell, for any seed.
        for seed in [0u64, 1, 0xdead_beef_cafe, u64::MAX] {
            for block in 0..4u32 {
                let mut hits = [0u8; CELL_COUNT];
                for i in 64 * block..64 * (block + 1) {
                    let u = sobol_2d(i, receiver_seed(seed, 7, 1));
                    let c = square_cell(u);
                    hits[c] += 1;
                    // square_cell inverts in_cell.
                    let back = in_cell(c, Vec2::new(0.5, 0.5));
                    assert_eq!(square_cell(back), c);
                }
                assert!(hits.iter().all(|&h| h == 1), "seed {seed} block {block}");
            }
        }
    }

    #[test]
    fn concentric_map_round_trips() {
        for i in 0..=40 {
            for j in 0..=40 {
                let u = Vec2::new(i as f32 / 40.0, j as f32 / 40.0);
                let back = concentric_disk_inverse(concentric_disk(u));
                if (u - Vec2::splat(0.5)).length() > 1e-6 {
                    assert!((back - u).length() < 1e-5, "{u} -> {back}");
                }
            }
        }
    }

    #[test]
    fn concentric_map_preserves_area() {
        // Monte Carlo estimate of each cell's disk area equals pi / 64.
        let n = 1 << 16;
        let mut counts = [0u32; CELL_COUNT];
        for i in 0..n {
            // Uniform points on the disk by rejection from a lattice.
            let p = Vec2::new(
                ((i % 256) as f32 + 0.5) / 128.0 - 1.0,
                ((i / 256) as f32 + 0.5) / 128.0 - 1.0,
            );
            if p.length_squared() < 1.0 {
                let z = (1.0 - p.length_squared()).sqrt();
                counts[cell_of(Vec3::new(p.x, p.y, z))] += 1;
            }
        }
        let total: u32 = counts.iter().sum();
        for c in counts {
            let frac = c as f32 / total as f32;
            assert!((frac * 64.0 - 1.0).abs() < 0.06, "cell fraction {frac}");
        }
    }

    #[test]
    fn fast_cell_lookup_agrees_with_the_exact_inverse() {
        let mut differ = 0;
        let n = 200_000;
        for i in 0..n {
            let d = cosine_hemisphere(sobol_2d(i, 99));
            if cell_of_fast(d) != cell_of(d) {
                differ += 1;
            }
            // Directions generated inside a cell land in it.
            let c = (i as usize * 7) % CELL_COUNT;
            let u = sobol_2d(i, 5) * 0.98 + Vec2::splat(0.01);
            assert_eq!(cell_of_fast(cosine_hemisphere(in_cell(c, u))), c);
        }
        assert!(differ < 20, "{differ} of {n} differ");
    }

    #[test]
    fn sobol_points_stratify_cells() {
        // 64 points hit each of the 64 cells exactly once ((0,2)-sequence).
        for seed in [1u64, 77, 123_456_789] {
            let mut hit = [0u8; CELL_COUNT];
            for i in 0..64 {
                let u = sobol_2d(i, seed);
                let c = ((u.y * 8.0) as usize) * 8 + (u.x * 8.0) as usize;
                hit[c] += 1;
            }
            assert!(hit.iter().all(|&h| h == 1), "{hit:?}");
        }
    }

    #[test]
    fn frame_is_orthonormal_for_any_normal() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(1.0, 2.0, -3.0).normalize(),
            Vec3::new(0.0, -1e-8, -1.0).normalize(),
        ] {
            let f = Frame::from_normal(n);
            assert!((f.tangent.length() - 1.0).abs() < 1e-5);
            assert!((f.bitangent.length() - 1.0).abs() < 1e-5);
            assert!(f.tangent.dot(f.bitangent).abs() < 1e-5);
            assert!(f.tangent.dot(n).abs() < 1e-5 && f.bitangent.dot(n).abs() < 1e-5);
            let w = Vec3::new(0.3, -0.4, 0.5).normalize();
            assert!((f.to_world(f.to_local(w)) - w).length() < 1e-5);
        }
    }

    #[test]
    fn cosine_directions_are_unit_and_upward() {
        for i in 0..256 {
            let d = cosine_hemisphere(sobol_2d(i, 5));
            assert!((d.length() - 1.0).abs() < 1e-5 && d.z >= 0.0);
        }
    }
}
