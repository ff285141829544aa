//! Dilate: fill gutter texels from their nearest covered texel, so bilinear
//! filtering and mipmaps never pull background into a chart.
//!
//! In: atlas size and the covered texels. Out: for every texel of the image,
//! the receiver whose value it shows (itself where covered), found by a
//! multi-source breadth-first search over 8-connected texels (nearest in
//! Chebyshev distance; ties go to the receiver reached first from sources
//! taken in texel order, whatever the receivers' order, so the result is
//! deterministic).

use rayon::prelude::*;

/// Marker for "no receiver" (only when there are no receivers at all).
pub(crate) const NONE: u32 = u32::MAX;

/// The 8 neighbours, in the order the search visits them.
const NEIGHBOURS: [(isize, isize); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (-1, -1),
    (1, -1),
    (-1, 1),
];

/// For each texel, the index of the receiver that fills it.
///
/// The breadth-first search runs one ring (Chebyshev distance) at a time,
/// each ring in parallel, and gives every texel the owner a queue-order
/// search would: of the previous ring's texels next to it, the first in
/// that ring's order (by neighbour order within one texel), and the new
/// ring is ordered the way that search would have queued it.
pub fn nearest_receiver(width: u32, height: u32, receiver_texels: &[u32]) -> Vec<u32> {
    let (w, h) = (width as usize, height as usize);
    let mut owner = vec![NONE; w * h];
    for (r, &t) in receiver_texels.iter().enumerate() {
        owner[t as usize] = r as u32;
    }
    // Sources in texel order whatever the receivers' order.
    let mut ring: Vec<u32> = (0..(w * h) as u32)
        .into_par_iter()
        .filter(|&t| owner[t as usize] != NONE)
        .collect();
    while !ring.is_empty() {
        // (texel, queue key = position in the ring * 8 + neighbour), in key
        // order: the first entry of a texel is the one a queue would take.
        let mut found: Vec<(u32, u64)> = ring
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, &t)| {
                let (x, y) = ((t as usize % w) as isize, (t as usize / w) as isize);
                let owner = &owner;
                NEIGHBOURS
                    .iter()
                    .enumerate()
                    .filter_map(move |(d, &(dx, dy))| {
                        let (nx, ny) = (x + dx, y + dy);
                        if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                            return None;
                        }
                        let n = ny as usize * w + nx as usize;
                        (owner[n] == NONE).then_some((n as u32, i as u64 * 8 + d as u64))
                    })
            })
            .collect();
        found.par_sort_unstable();
        found.dedup_by_key(|&mut (n, _)| n);
        found.par_sort_unstable_by_key(|&(_, key)| key);
        for &(n, key) in &found {
            owner[n as usize] = owner[ring[(key / 8) as usize] as usize];
        }
        ring = found.into_iter().map(|(n, _)| n).collect();
    }
    owner
}

/// The queue-order search [`nearest_receiver`] reproduces ring by ring
/// (the reference its test compares with).
#[cfg(test)]
fn nearest_receiver_queue(width: u32, height: u32, receiver_texels: &[u32]) -> Vec<u32> {
    let (w, h) = (width as usize, height as usize);
    let mut owner = vec![NONE; w * h];
    let mut queue = std::collections::VecDeque::new();
    for (r, &t) in receiver_texels.iter().enumerate() {
        owner[t as usize] = r as u32;
    }
    queue.extend((0..w * h).filter(|&t| owner[t] != NONE));
    while let Some(t) = queue.pop_front() {
        let (x, y) = ((t % w) as isize, (t / w) as isize);
        for (dx, dy) in NEIGHBOURS {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                continue;
            }
            let n = ny as usize * w + nx as usize;
            if owner[n] == NONE {
                owner[n] = owner[t];
                queue.push_back(n);
            }
        }
    }
    owner
}

/// [`nearest_receiver`] where receivers marked `inside` (inside geometry,
/// see [`crate::bake::validity`]) are filled like gutter texels, from the nearest
/// valid receiver. If no receiver is valid, every receiver shows itself.
pub fn fill_map(width: u32, height: u32, receiver_texels: &[u32], inside: &[bool]) -> Vec<u32> {
    let valid: Vec<u32> = (0..receiver_texels.len() as u32)
        .filter(|&r| !inside.get(r as usize).copied().unwrap_or(false))
        .collect();
    if valid.len() == receiver_texels.len() || valid.is_empty() {
        return nearest_receiver(width, height, receiver_texels);
    }
    let texels: Vec<u32> = valid.iter().map(|&r| receiver_texels[r as usize]).collect();
    nearest_receiver(width, height, &texels)
        .into_iter()
        .map(|k| if k == NONE { NONE } else { valid[k as usize] })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inside_receivers_show_their_nearest_valid_one() {
        // 5x1: receivers at x = 0, 1, 2, 3; r1 and r2 inside.
        let o = fill_map(5, 1, &[0, 1, 2, 3], &[false, true, true, false]);
        assert_eq!(o, vec![0, 0, 3, 3, 3]);
        // All inside: each shows itself.
        let o = fill_map(3, 1, &[0, 2], &[true, true]);
        assert_eq!(o, vec![0, 0, 1]);
    }

    #[test]
    fn fills_every_texel_from_the_nearest() {
        // 5x1 image, receivers at x=0 (r0) and x=4 (r1).
        let o = nearest_receiver(5, 1, &[0, 4]);
        assert_eq!(o, vec![0, 0, 0, 1, 1]);
        let o = nearest_receiver(3, 3, &[4]);
        assert!(o.iter().all(|&r| r == 0));
        assert!(nearest_receiver(2, 2, &[]).iter().all(|&r| r == NONE));
    }

    #[test]
    fn ties_go_to_the_first_source_in_texel_order_whatever_the_receivers_order() {
        // Texel 2 is as near x = 0 as x = 4: it shows the receiver at x = 0
        // whether that is listed first or second.
        assert_eq!(nearest_receiver(5, 1, &[0, 4]), vec![0, 0, 0, 1, 1]);
        assert_eq!(nearest_receiver(5, 1, &[4, 0]), vec![1, 1, 1, 0, 0]);
    }

    #[test]
    fn rings_in_parallel_give_the_queue_order_search_exactly() {
        // Scattered receivers in random order on a page with wide gaps,
        // where ties between sources are common.
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        for (w, h, n) in [(37, 23, 9), (64, 64, 200), (101, 7, 30), (5, 5, 1)] {
            let mut texels: Vec<u32> = (0..n).map(|_| next() % (w * h)).collect();
            texels.sort_unstable();
            texels.dedup();
            let k = texels.len();
            for i in 0..k {
                texels.swap(i, (next() as usize) % k);
            }
            assert_eq!(
                nearest_receiver(w, h, &texels),
                nearest_receiver_queue(w, h, &texels),
                "{w}x{h}, {k} receivers"
            );
        }
    }
}
