//! The pre-pass's strata: the grid of the sample square whose every cell
//! holds one pre-pass ray, and how many pairs of neighbouring cells a
//! visibility boundary crosses.
//!
//! In: `pre_rays`, points of the square, the occluded strata's bits. Out:
//! a stratum's index, and the crossings the allocation reads
//! ([`super::allocation::boundary_variance`]).

use super::options::MAX_ADAPTIVE_RAYS;
use glam::Vec2;

/// The pre-pass's strata: the `cols` x `rows` grid of the sample square
/// (2^ceil(m/2) x 2^floor(m/2) for `pre_rays` = 2^m) whose every cell holds
/// exactly one of the first `pre_rays` points of a receiver's (Owen
/// scrambled) Sobol sequence, a (0,m,2)-net.
#[derive(Clone, Copy, Debug)]
pub struct Strata {
    pub cols: u32,
    pub rows: u32,
}

/// Pre-pass rays at most (the largest `pre_rays`), in 64-bit words.
pub(crate) const STRATA_WORDS: usize = MAX_ADAPTIVE_RAYS as usize / 64;

impl Strata {
    pub fn of(pre_rays: u32) -> Strata {
        let m = exponent_at_most(pre_rays);
        Strata {
            cols: 1 << m.div_ceil(2),
            rows: 1 << (m / 2),
        }
    }

    /// The stratum of a point of the square.
    #[inline]
    pub fn index(&self, u: Vec2) -> usize {
        let x = ((u.x * self.cols as f32) as u32).min(self.cols - 1);
        let y = ((u.y * self.rows as f32) as u32).min(self.rows - 1);
        (y * self.cols + x) as usize
    }

    /// Pairs of strata sharing an edge.
    pub fn pairs(&self) -> u32 {
        (self.cols - 1) * self.rows + self.cols * (self.rows - 1)
    }

    /// The crossings of a straight boundary halving the square: `rows`
    /// along a column, `cols` along a row, their geometric mean (4 of the
    /// 4x4 grid's 24 pairs).
    pub fn halving(&self) -> f32 {
        ((self.cols * self.rows) as f32).sqrt()
    }

    /// Pairs of edge-sharing strata whose rays disagree (one occluded, one
    /// not), from the occluded strata's bits (`occluded[i / 64] >> i % 64`).
    pub fn crossings(&self, occluded: &[u64; STRATA_WORDS]) -> u32 {
        let bit = |i: u32| (occluded[(i / 64) as usize] >> (i % 64)) & 1;
        let mut n = 0;
        for y in 0..self.rows {
            for x in 0..self.cols {
                let i = y * self.cols + x;
                if x + 1 < self.cols {
                    n += (bit(i) ^ bit(i + 1)) as u32;
                }
                if y + 1 < self.rows {
                    n += (bit(i) ^ bit(i + self.cols)) as u32;
                }
            }
        }
        n
    }
}

/// The exponent of the smallest power of two at least `n` (n >= 1).
pub(crate) fn exponent_at_least(n: u32) -> u32 {
    n.max(1).next_power_of_two().trailing_zeros()
}

/// The exponent of the largest power of two at most `n` (n >= 1).
pub(crate) fn exponent_at_most(n: u32) -> u32 {
    31 - n.max(1).leading_zeros()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_pre_pass_stratum_holds_one_point() {
        for m in 0..=12 {
            let pre = 1u32 << m;
            let strata = Strata::of(pre);
            assert_eq!(strata.cols * strata.rows, pre);
            assert!(strata.cols == strata.rows || strata.cols == 2 * strata.rows);
            for seed in [0u64, 7, 0xdead_beef] {
                let mut seen = vec![false; pre as usize];
                for i in 0..pre {
                    let k = strata.index(crate::sample::sobol_2d(i, seed));
                    assert!(!seen[k], "two of {pre} points in stratum {k}");
                    seen[k] = true;
                }
            }
        }
        assert_eq!(Strata::of(16).pairs(), 24);
        assert_eq!(Strata::of(1).pairs(), 0);
        // Points on the square's far edges stay in the grid.
        assert_eq!(Strata::of(16).index(Vec2::ONE), 15);
    }

    #[test]
    fn crossings_count_the_boundary_between_strata() {
        let strata = Strata::of(16);
        let bits = |f: &dyn Fn(u32, u32) -> bool| {
            let mut b = [0u64; STRATA_WORDS];
            for y in 0..4 {
                for x in 0..4 {
                    if f(x, y) {
                        b[0] |= 1 << (y * 4 + x);
                    }
                }
            }
            b
        };
        assert_eq!(strata.crossings(&bits(&|_, _| false)), 0);
        assert_eq!(strata.crossings(&bits(&|_, _| true)), 0);
        // A straight wall over half of the square: one crossing per row.
        assert_eq!(strata.crossings(&bits(&|x, _| x < 2)), 4);
        // A lattice: every pair.
        assert_eq!(strata.crossings(&bits(&|x, y| (x + y) % 2 == 0)), 24);
        // Past the first word (64 strata of 128 rays: 16 x 8).
        let strata = Strata::of(128);
        let mut b = [0u64; STRATA_WORDS];
        for i in 64..128 {
            b[1] |= 1 << (i - 64);
        }
        assert_eq!(strata.crossings(&b), 16);
    }
}
