//! The receivers' order (the pipeline's world-space Morton order, for the
//! tracing passes' caches) changes no result: every method gives each
//! texel the same values as with the receivers in texel order.
mod common;

use aobake::Method;
use aobake::job::Level;
use aobake::stage::StageTimer;

#[test]
fn every_method_bakes_the_same_texels_in_world_and_texel_order() {
    // Single-sided walls: the inside test runs too.
    let scene = common::scene(&common::thin_wall_scene());
    for method in [Method::Mc, Method::Adaptive, Method::Sheared] {
        let s = aobake::BakeSettings {
            method,
            ..common::settings(64, 32, None)
        };
        let run = aobake::RunOptions::QUIET;
        let level = Level::new(&scene, &s, &run, &mut StageTimer::new()).unwrap();
        let world = level.page(0, &scene, &mut StageTimer::new()).unwrap();
        let n = world.receivers.len();
        // The pipeline's order is not the texel order (or this proves nothing).
        assert!(world.receivers.texel.windows(2).any(|w| w[0] > w[1]));
        let mut by_texel = level.page(0, &scene, &mut StageTimer::new()).unwrap();
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by_key(|&i| by_texel.receivers.texel[i as usize]);
        by_texel.receivers = by_texel.receivers.permuted(&order);
        by_texel.inside = by_texel
            .inside
            .map(|v| order.iter().map(|&i| v[i as usize]).collect());
        let a = world
            .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
        let b = by_texel
            .bake(&s, &aobake::RunOptions::QUIET, &mut StageTimer::new())
            .unwrap();
        let mut inside = 0;
        for (k, &i) in order.iter().enumerate() {
            let i = i as usize;
            assert_eq!(a.bake.ao[i].to_bits(), b.bake.ao[k].to_bits(), "{method:?}");
            assert_eq!(a.bake.sh[i], b.bake.sh[k], "{method:?}");
            if let Some(st) = &a.adaptive_stats {
                let sb = b.adaptive_stats.as_ref().unwrap();
                assert_eq!(st.rays[i], sb.rays[k]);
                assert_eq!(st.inside[i], sb.inside[k]);
                inside += st.inside[i] as usize;
            }
        }
        if method == Method::Adaptive {
            // The slab's underside and the wall's inner faces: the inside
            // test found receivers, in both orders alike.
            assert!(inside > 0, "no receiver inside");
        }
    }
}
