//! Bit helpers shared by the stages: a 64-bit mix and Morton codes.
//!
//! In: integers. Out: their mix ([`mix64`], for seeds and hashes; [`unit()`]
//! as a number in [0, 1)) and
//! interleaved bits ([`morton2`] for atlas texels, [`morton3`] for world
//! cells).

/// A 64-bit mix (the SplitMix64 finalizer), for per-texel seeds and the
/// shards' hashes.
#[inline]
pub fn mix64(mut x: u64) -> u64 {
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A uniform number in [0, 1) from a key: the top 24 bits of its mix.
#[inline]
pub fn unit(key: u64) -> f32 {
    (mix64(key) >> 40) as f32 / (1u64 << 24) as f32
}

/// The bits of `v` spread one apart (bit i to bit 2i).
#[inline]
fn spread_by_one(v: u32) -> u64 {
    let mut x = v as u64;
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// Bits per axis of [`morton3`].
pub const MORTON3_BITS: u32 = 21;

/// The low [`MORTON3_BITS`] bits of `v` spread two apart (bit i to bit 3i).
#[inline]
fn spread_by_two(v: u32) -> u64 {
    let mut x = v as u64 & ((1 << MORTON3_BITS) - 1);
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    (x | (x << 2)) & 0x1249_2492_4924_9249
}

/// The Morton code of a 2D cell: the bits of x and y interleaved (x
/// lowest).
#[inline]
pub fn morton2(x: u32, y: u32) -> u64 {
    spread_by_one(x) | (spread_by_one(y) << 1)
}

/// The Morton code of a cell of a 2^21 grid: the bits of x, y and z
/// interleaved (x lowest). Coordinates beyond 21 bits keep their low bits.
#[inline]
pub fn morton3(x: u32, y: u32, z: u32) -> u64 {
    spread_by_two(x) | (spread_by_two(y) << 1) | (spread_by_two(z) << 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Interleaving bit by bit, the definition.
    fn interleaved(coords: &[u32], bits: u32) -> u64 {
        let mut out = 0u64;
        for i in 0..bits {
            for (axis, &c) in coords.iter().enumerate() {
                out |= (((c >> i) & 1) as u64) << (i as usize * coords.len() + axis);
            }
        }
        out
    }

    #[test]
    fn morton_codes_interleave_bit_by_bit() {
        let mut x = 0x1234_5678u64;
        for _ in 0..1000 {
            x = mix64(x);
            let (a, b, c) = (x as u32, (x >> 32) as u32, (x >> 11) as u32);
            assert_eq!(morton2(a, b), interleaved(&[a, b], 32));
            assert_eq!(morton3(a, b, c), interleaved(&[a, b, c], MORTON3_BITS));
        }
    }

    #[test]
    fn the_mix_is_splitmix64s_finalizer() {
        // SplitMix64 from state 0: the first output is mix64(0x9e37...).
        assert_eq!(mix64(0x9e37_79b9_7f4a_7c15), 0xe220_a839_7b1d_cdaf);
    }
}
