//! The order a dispatch's rays go to the GPU in.
//!
//! In: rays `start..end` of a [`RayBatch`] (receiver by receiver, each
//! receiver's directions spread over its hemisphere). Out: a permutation
//! of them (position on the GPU -> ray), by direction first: rays of
//! neighbouring receivers along nearly one direction side by side, so
//! that the invocations of a subgroup, which run in lockstep, walk the
//! same part of the tree and fetch the same nodes. In receiver order a
//! subgroup holds one receiver's rays fanned over the hemisphere, and
//! every one of them waits for the longest walk among them.
//!
//! The key is the direction's cell on an octahedral map ([`CELLS`] a
//! side); rays of one cell keep the batch's order (a counting sort), and
//! the batch's receivers lie in texel order, near each other in space.
//! The answers do not depend on the order: the host puts them back.

use crate::trace::RayBatch;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Cells a side of the octahedral map: 256 directions' cells, about 16
/// degrees across.
pub const CELLS: u32 = 16;

/// The octahedral map's cell of unit direction `d`.
fn cell(d: Vec3) -> u32 {
    let n = d / (d.x.abs() + d.y.abs() + d.z.abs());
    let mut p = Vec2::new(n.x, n.y);
    if n.z < 0.0 {
        let sign = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        p = Vec2::new((1.0 - n.y.abs()) * sign(n.x), (1.0 - n.x.abs()) * sign(n.y));
    }
    // (A NaN direction casts to cell 0.)
    let q = ((p * 0.5 + 0.5) * CELLS as f32)
        .as_uvec2()
        .min(glam::UVec2::splat(CELLS - 1));
    q.y * CELLS + q.x
}

/// Into `order`, rays `start..end` of `rays` by their direction's cell,
/// each cell's in the batch's order (blocked rays first, in cell 0).
pub fn by_direction(rays: &RayBatch, start: usize, end: usize, order: &mut Vec<u32>) {
    let keys: Vec<u16> = (start..end)
        .into_par_iter()
        .map(|i| {
            if rays.is_blocked(i) {
                0
            } else {
                cell(rays.directions()[i]) as u16
            }
        })
        .collect();
    let mut first = vec![0u32; (CELLS * CELLS) as usize + 1];
    for &k in &keys {
        first[k as usize + 1] += 1;
    }
    for c in 1..first.len() {
        first[c] += first[c - 1];
    }
    order.clear();
    order.resize(keys.len(), 0);
    for (i, &k) in (start as u32..).zip(&keys) {
        let slot = &mut first[k as usize];
        order[*slot as usize] = i;
        *slot += 1;
    }
}

/// Into `answers`, in the batch's order, the `words` words a ray of
/// `sorted`, the answers to the rays `order` (from `by_direction`, rays
/// from `start`) in that order.
pub fn put_back(order: &[u32], start: usize, words: usize, sorted: &[u32], answers: &mut Vec<u32>) {
    answers.clear();
    answers.resize(sorted.len(), 0);
    for (&i, a) in order.iter().zip(sorted.chunks_exact(words)) {
        let at = (i as usize - start) * words;
        answers[at..at + words].copy_from_slice(a);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_cover_the_sphere_each_a_small_cone() {
        // A Fibonacci sphere.
        let n = 200_000;
        let dirs: Vec<Vec3> = (0..n)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f32 + 0.5) / n as f32;
                let phi = k as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        let cells = (CELLS * CELLS) as usize;
        let (mut seen, mut sum) = (vec![0u32; cells], vec![Vec3::ZERO; cells]);
        for &d in &dirs {
            let c = cell(d) as usize;
            seen[c] += 1;
            sum[c] += d;
        }
        // Every cell holds directions, none many more than its share.
        let share = n as f32 / cells as f32;
        assert!(
            seen.iter()
                .all(|&s| s as f32 > 0.2 * share && (s as f32) < 3.0 * share),
            "{seen:?}"
        );
        // Each cell's directions lie within 25 degrees of their mean.
        for &d in &dirs {
            let mean = sum[cell(d) as usize].normalize();
            assert!(d.dot(mean) > 25f32.to_radians().cos(), "{d}");
        }
        assert_eq!(cell(Vec3::new(f32::NAN, 0.0, 1.0)), 0);
    }

    #[test]
    fn the_order_is_a_permutation_by_cell_stable_within_one() {
        let mut rays = RayBatch::new();
        let dirs = [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::Z, Vec3::X];
        for (k, d) in dirs.iter().enumerate() {
            rays.push(Vec3::new(k as f32, 0.0, 0.0), *d, 1.0);
        }
        rays.push_blocked(-Vec3::Y);
        let mut order = Vec::new();
        by_direction(&rays, 1, 6, &mut order);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, vec![1, 2, 3, 4, 5]);
        assert_eq!(order[0], 5, "the blocked ray first");
        let key = |i: u32| if i == 5 { 0 } else { cell(dirs[i as usize]) };
        assert!(
            order
                .windows(2)
                .all(|w| key(w[0]) < key(w[1]) || (key(w[0]) == key(w[1]) && w[0] < w[1]))
        );
        // Rays 2 and 4 (+X), 3 (+Z) keep their order within their cells.
        let at = |i: u32| order.iter().position(|&j| j == i).unwrap();
        assert!(at(2) < at(4));
        // Answers of two words a ray, in that order, put back in the batch's.
        let sorted: Vec<u32> = order.iter().flat_map(|&i| [i, 10 * i]).collect();
        let mut answers = Vec::new();
        put_back(&order, 1, 2, &sorted, &mut answers);
        assert_eq!(answers, vec![1, 10, 2, 20, 3, 30, 4, 40, 5, 50]);
    }
}
