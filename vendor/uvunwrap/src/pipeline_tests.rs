//! Tests of the pipeline (`pipeline.rs`): the stretch, the automatic
//! density and prepared unwraps.

use super::stretch;

#[test]
fn stretch_brings_thin_axes_to_the_minimum_only() {
    // 0.25 x 10 units at 4 texels per unit: 1 x 40 texels.
    let k = stretch([0.25, 10.0], 4.0, 2.0);
    assert_eq!(k, [2.0, 1.0]);
    // Wide enough, or without extent (a degenerate chart): unchanged.
    assert_eq!(stretch([1.0, 0.0], 4.0, 2.0), [1.0, 1.0]);
    // Both axes thin: each to the minimum.
    let k = stretch([0.1, 0.2], 4.0, 2.0);
    assert!((0.1 * k[0] * 4.0 - 2.0f64).abs() < 1e-12 && (0.2 * k[1] * 4.0 - 2.0f64).abs() < 1e-12);
}

/// Boxes of many sizes (one mesh each): hundreds of charts.
fn boxes() -> Vec<(Vec<[f32; 3]>, Vec<u32>)> {
    (0..60)
        .map(|k| {
            let s = [1.0 + (k % 7) as f32 * 0.6, 0.3 + (k % 5) as f32 * 0.9, 0.5 + (k % 3) as f32];
            let mut p = Vec::new();
            for i in 0..8 {
                p.push([
                    s[0] * (i & 1) as f32 + k as f32 * 10.0,
                    s[1] * ((i >> 1) & 1) as f32,
                    s[2] * ((i >> 2) & 1) as f32,
                ]);
            }
            let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
            let t = quads
                .iter()
                .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
                .collect();
            (p, t)
        })
        .collect()
}

#[test]
fn the_automatic_density_is_the_same_on_any_thread_count_and_fills_the_page() {
    let data = boxes();
    let meshes: Vec<crate::MeshInput> = data.iter().map(|(p, t)| crate::MeshInput::new(p, t)).collect();
    let options = crate::Options {
        density: crate::Density::Auto { page_size: 256 },
        padding: 2,
        min_chart_width: 2.0,
        ..Default::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| crate::generate(&meshes, &options).unwrap())
    };
    let (one, four) = (run(1), run(4));
    assert_eq!(one.texels_per_unit, four.texels_per_unit);
    assert_eq!((one.width, one.height), (four.width, four.height));
    let uv = |a: &crate::Atlas| -> Vec<[f32; 2]> { a.meshes.iter().flat_map(|m| m.vertices.iter().map(|v| v.uv)).collect() };
    assert_eq!(uv(&one), uv(&four));
    // One page, filled: at 1% more density the charts need a second
    // page or a taller one (the search stops within 0.25%).
    assert_eq!(one.page_count, 1);
    assert!(one.width <= 256 && one.height <= 256);
    let denser = crate::Options {
        density: crate::Density::Fixed { texels_per_unit: one.texels_per_unit * 1.01, page_size: Some(256) },
        ..options
    };
    let more = crate::generate(&meshes, &denser).unwrap();
    assert!(more.page_count > 1 || more.height > one.height, "{} pages, {} rows", more.page_count, more.height);
}

#[test]
fn a_prepared_unwrap_packs_as_a_fresh_one_under_any_placement_options() {
    let data = boxes();
    let meshes: Vec<crate::MeshInput> = data.iter().map(|(p, t)| crate::MeshInput::new(p, t)).collect();
    let base = crate::Options {
        density: crate::Density::Auto { page_size: 256 },
        padding: 2,
        min_chart_width: 2.0,
        ..Default::default()
    };
    let prepared = crate::prepare_with_progress(&meshes, &base, |_| true).unwrap();
    let uv = |a: &crate::Atlas| -> Vec<([f32; 2], Option<u32>)> {
        a.meshes.iter().flat_map(|m| m.vertices.iter().map(|v| (v.uv, v.chart))).collect()
    };
    let variants = [
        base,
        crate::Options { padding: 1, min_chart_width: 1.0, lookup_packing: true, ..base },
        crate::Options { padding: 1, min_chart_width: 0.0, packing: crate::Packing::Fast, ..base },
        crate::Options { density: crate::Density::Fixed { texels_per_unit: 3.0, page_size: Some(128) }, ..base },
        // Another segmentation: unwrapped from scratch.
        crate::Options { max_chart_angle: 30.0, ..base },
    ];
    for o in variants {
        let fresh = crate::generate(&meshes, &o).unwrap();
        let again = prepared.generate_with_progress(&meshes, &o, |_| true).unwrap();
        assert_eq!(fresh.texels_per_unit, again.texels_per_unit);
        assert_eq!((fresh.page_count, fresh.chart_count), (again.page_count, again.chart_count));
        assert_eq!(uv(&fresh), uv(&again));
    }
    // The prepared charts are not consumed: packing again gives the same.
    let twice = prepared.generate_with_progress(&meshes, &base, |_| true).unwrap();
    assert_eq!(uv(&twice), uv(&crate::generate(&meshes, &base).unwrap()));
}
