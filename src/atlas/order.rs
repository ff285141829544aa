//! Order: the receivers in world-space Morton order of their positions.
//!
//! In: [`Receivers`] (from `super::rasterize`, in texel order). Out: the
//! same receivers permuted so that receivers near each other in the scene
//! are near each other in the list.
//!
//! The tracing passes (the validity test, Monte Carlo, the adaptive
//! pre-pass and second batch) take the receivers in list order, a run of
//! them per thread. In texel order consecutive receivers along an atlas
//! row belong to different charts, often far apart in the scene (the
//! curtains' charts average 28 texels), so each receiver's rays start in
//! BVH nodes and triangles the previous receiver's rays did not bring into
//! the cache. Measured at 1024 (one run each, 2 threads): Monte Carlo's
//! 256-ray trace on the curtains 12.70 -> 12.32 s, the adaptive method's
//! tracing passes 13.41 -> 12.92 s there and 8.64 -> 8.36 s on Sponza.
//!
//! Nothing reads receivers by position in the list: the texel grid, the
//! dilation (sources in texel order, [`crate::lightmap::dilate`]), the encoders and
//! each receiver's ray sequence (seeded by its texel) go through
//! `texel`, so the order changes no output byte.
//!
//! Memory: while permuting, the receivers twice (88 B per texel) and the
//! sort keys (16 B), under the output stages' 160 B per texel that
//! [`crate::job::settings::estimated_bytes`] counts.

use super::Receivers;
use crate::bits::{MORTON3_BITS, morton3};
use glam::Vec3;
use rayon::prelude::*;

const BITS: u32 = MORTON3_BITS;

/// The order (`order[new] = old`) of `positions` along the Morton curve
/// of their bounding cube; ties (and non-finite positions, which go to
/// cell 0) keep their index order, so the order is deterministic.
pub fn world_order(positions: &[Vec3]) -> Vec<u32> {
    let (lo, hi) = positions
        .iter()
        .filter(|p| p.is_finite())
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let extent = (hi - lo).max_element();
    let cells = ((1u32 << BITS) - 1) as f32;
    let scale = if extent > 0.0 && extent.is_finite() {
        cells / extent
    } else {
        0.0
    };
    let mut keyed: Vec<(u64, u32)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            // `as` saturates, and sends NaN to 0.
            let q = ((p - lo) * scale).min(Vec3::splat(cells));
            (morton3(q.x as u32, q.y as u32, q.z as u32), i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// `receivers` in [`world_order`] of their positions.
pub(crate) fn in_world_order(receivers: Receivers) -> Receivers {
    let order = world_order(&receivers.position);
    receivers.permuted(&order)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_codes_interleave_x_y_z() {
        assert_eq!(morton3(0, 0, 0), 0);
        assert_eq!(morton3(1, 0, 0), 1);
        assert_eq!(morton3(0, 1, 0), 2);
        assert_eq!(morton3(0, 0, 1), 4);
        assert_eq!(morton3(3, 0, 0), 0b1001);
        assert_eq!(morton3(0, 2, 1), 0b10100);
        let max = (1 << BITS) - 1;
        assert_eq!(morton3(max, max, max), (1u64 << 63) - 1);
        // Only the low 21 bits count.
        assert_eq!(morton3(1 << BITS | 1, 0, 0), 1);
    }

    #[test]
    fn the_world_order_keeps_clusters_together_and_is_a_permutation() {
        // Two clusters far apart, their points interleaved in the input.
        let positions: Vec<Vec3> = (0..40)
            .map(|i| {
                let base = if i % 2 == 0 {
                    Vec3::ZERO
                } else {
                    Vec3::splat(100.0)
                };
                base + Vec3::new((i / 2) as f32 * 0.01, 0.0, 0.0)
            })
            .collect();
        let order = world_order(&positions);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..40).collect::<Vec<u32>>());
        // One cluster, then the other, each along its line.
        let first: Vec<u32> = order[..20].to_vec();
        assert_eq!(first, (0..20).map(|k| 2 * k).collect::<Vec<u32>>());
        assert_eq!(
            &order[20..],
            &(0..20).map(|k| 2 * k + 1).collect::<Vec<u32>>()[..]
        );
    }

    #[test]
    fn stiff_positions_keep_a_deterministic_permutation() {
        // All equal (extent 0), NaN and infinite, and none.
        let nan = Vec3::new(f32::NAN, 0.0, 1.0);
        let inf = Vec3::new(f32::INFINITY, 0.0, 0.0);
        for positions in [
            vec![Vec3::ONE; 5],
            vec![Vec3::ONE, nan, Vec3::ZERO, inf, Vec3::splat(1e30)],
            vec![nan, nan],
            vec![],
        ] {
            let order = world_order(&positions);
            let mut sorted = order.clone();
            sorted.sort();
            assert_eq!(sorted, (0..positions.len() as u32).collect::<Vec<u32>>());
            assert_eq!(order, world_order(&positions));
        }
        // Equal points keep their index order.
        assert_eq!(world_order(&[Vec3::ONE; 4]), vec![0, 1, 2, 3]);
    }
}
