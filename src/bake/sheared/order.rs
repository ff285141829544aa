//! Locality: the receivers in Morton order of their texels for the
//! passes, and the results back in the receivers' own order.
//!
//! In: [`Receivers`]. Out: an order (`order[new] = old`) for
//! [`Receivers::permuted`], and a [`Bake`] and [`ShearedStats`] unpermuted.

use super::types::ShearedStats;
use crate::atlas::Receivers;
use crate::bake::Bake;
use crate::bits::morton2;

/// An order of the receivers in which texels near each other in the atlas
/// are near each other in memory (Morton order of their texel
/// coordinates), so a receiver's world-space neighbours, which are mostly
/// its atlas neighbours, and their samples share cache lines.
pub fn locality_order(receivers: &Receivers) -> Vec<u32> {
    let w = receivers.width.max(1);
    let mut order: Vec<u32> = (0..receivers.len() as u32).collect();
    order.sort_by_key(|&i| {
        let t = receivers.texel[i as usize];
        morton2(t % w, t / w)
    });
    order
}

/// A bake and its per-receiver statistics, from `order` back to the
/// receivers' own order.
pub fn unpermuted(bake: Bake, stats: ShearedStats, order: &[u32]) -> (Bake, ShearedStats) {
    fn back<T: Copy + Default>(v: &[T], order: &[u32]) -> Vec<T> {
        let mut out = vec![T::default(); v.len()];
        for (new, &old) in order.iter().enumerate() {
            out[old as usize] = v[new];
        }
        out
    }
    (
        Bake {
            ao: back(&bake.ao, order),
            sh: back(&bake.sh, order),
            rays: bake.rays,
            visibility: None,
        },
        ShearedStats {
            brute_fraction: back(&stats.brute_fraction, order),
            z_min: back(&stats.z_min, order),
            neighbours: back(&stats.neighbours, order),
            sparse_ao: back(&stats.sparse_ao, order),
            ..stats
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::SH_COUNT;
    use glam::Vec3;

    #[test]
    fn locality_order_is_a_morton_permutation_and_round_trips() {
        // A 4x4 atlas with two texels uncovered.
        let texels: Vec<u32> = (0..16).filter(|&t| t != 5 && t != 10).collect();
        let receivers = Receivers {
            width: 4,
            height: 4,
            position: texels.iter().map(|&t| Vec3::splat(t as f32)).collect(),
            normal: vec![Vec3::Z; texels.len()],
            geo_normal: vec![Vec3::Z; texels.len()],
            footprint: texels.iter().map(|&t| t as f32).collect(),
            center_inside: vec![true; texels.len()],
            texel: texels,
            ..Default::default()
        };
        let order = locality_order(&receivers);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..14).collect::<Vec<u32>>());
        // Z order: (0,0) (1,0) (0,1) (1,1) (2,0) ...: texels 0 1 4 (5 missing) 2 3 6 7.
        let local = receivers.permuted(&order);
        assert_eq!(&local.texel[..7], &[0, 1, 4, 2, 3, 6, 7]);
        assert_eq!(local.footprint[2], 4.0);
        assert_eq!((local.width, local.height), (4, 4));
        // Results computed in that order come back to each receiver.
        let bake = Bake {
            ao: local.footprint.clone(),
            sh: local.footprint.iter().map(|&f| [f; SH_COUNT]).collect(),
            rays: 7,
            visibility: None,
        };
        let stats = ShearedStats {
            z_min: local.footprint.clone(),
            neighbours: local.texel.clone(),
            brute_fraction: local.footprint.clone(),
            sparse_ao: local.footprint.clone(),
            brute_rays: 3,
            ..Default::default()
        };
        let (bake, stats) = unpermuted(bake, stats, &order);
        assert_eq!(bake.ao, receivers.footprint);
        assert_eq!(bake.sh[3], [receivers.footprint[3]; SH_COUNT]);
        assert_eq!(stats.neighbours, receivers.texel);
        assert_eq!(stats.z_min, receivers.footprint);
        assert_eq!((bake.rays, stats.brute_rays), (7, 3));
    }
}
