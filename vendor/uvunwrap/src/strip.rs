//! Bent strips cut into straight pieces (aobake's patch, with
//! `Options::min_chart_width`).
//!
//! In: a parameterized chart, the atlas density and the minimum width in
//! texels. Out: the chart unchanged, or its faces in connected pieces, each
//! finalized as a chart of its own (rotated to its minimum-area rectangle).
//!
//! A strip thinner than a texel that bends (a moulding's band around a
//! pillar, a ring) has a wide bounding rectangle, so the stretch along an
//! axis of that rectangle (`pipeline::widen_thin_charts`) never widens the
//! strip itself, and its bilinear lookups read texels of other charts. Cut
//! into pieces no wider than half the minimum, each piece is nearly
//! straight and the stretch at least doubles the strip's width there.

use crate::geom::{bounds2, convex_hull, min_area_rect_dir, rotate, signed_area, V2};
use crate::param::Chart;
use std::collections::{HashMap, VecDeque};

/// Mean width of a chart, 2 A / P (UV area over boundary length): a strip's
/// width whatever its shape, in the chart's units.
pub(crate) fn mean_width(chart: &Chart) -> f64 {
    let mut area = 0.0;
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &chart.face_local {
        let p = t.map(|v| chart.uvs[v as usize]);
        area += signed_area(p[0], p[1], p[2]).abs();
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let perimeter: f64 = edges
        .iter()
        .filter(|&(_, &n)| n == 1)
        .map(|(&(a, b), _)| {
            let (p, q) = (chart.uvs[a as usize], chart.uvs[b as usize]);
            ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt()
        })
        .sum();
    if perimeter > 0.0 {
        2.0 * area / perimeter
    } else {
        0.0
    }
}

/// The narrow side of the minimum-area rectangle around a convex `hull`.
fn hull_narrow_side(hull: &[V2]) -> f64 {
    let (c, s) = min_area_rect_dir(hull);
    let [lo, hi] = bounds2(hull.iter().map(|&p| rotate(p, c, s)));
    (hi[0] - lo[0]).min(hi[1] - lo[1]).max(0.0)
}

/// Whether the chart is a strip the axis stretch cannot widen: thinner
/// than half the minimum (in texels at `density`) on average, but with a
/// bounding rectangle at least the minimum across.
pub(crate) fn is_bent_strip(chart: &Chart, density: f64, min: f64) -> bool {
    chart.faces.len() > 1
        && chart.size[0].min(chart.size[1]) * density >= min
        && mean_width(chart) * density < 0.5 * min
}

/// `chart`'s faces in connected pieces, each no wider (its minimum-area
/// rectangle's narrow side) than `limit` unless one face alone is: grown
/// face by face in breadth-first order from an end of the strip (the face
/// farthest from the first), each piece taking every neighbour that keeps
/// it narrow. One piece: the chart itself, unchanged. `finish` makes a
/// piece a chart from its mesh faces, welded vertices, local faces and UVs
/// (`param::finalize`).
pub(crate) fn split(
    chart: Chart,
    limit: f64,
    finish: impl Fn(Vec<u32>, Vec<u32>, Vec<[u32; 3]>, Vec<V2>) -> Chart,
) -> Vec<Chart> {
    let n = chart.faces.len();
    let mut by_edge: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (f, t) in chart.face_local.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(f as u32);
        }
    }
    let neighbours: Vec<Vec<u32>> = (0..n)
        .map(|f| {
            let t = chart.face_local[f];
            let mut out: Vec<u32> = (0..3)
                .flat_map(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    by_edge[&(a.min(b), a.max(b))].iter().copied()
                })
                .filter(|&g| g as usize != f)
                .collect();
            out.sort_unstable();
            out.dedup();
            out
        })
        .collect();
    let bfs = |start: usize| -> Vec<u32> {
        let mut seen = vec![false; n];
        let mut order = vec![start as u32];
        seen[start] = true;
        let mut i = 0;
        while i < order.len() {
            for &g in &neighbours[order[i] as usize] {
                if !seen[g as usize] {
                    seen[g as usize] = true;
                    order.push(g);
                }
            }
            i += 1;
        }
        order
    };
    let end = *bfs(0).last().unwrap_or(&0) as usize;
    let mut order = bfs(end);
    // Faces the first search did not reach (a chart in several parts).
    let mut reached = vec![false; n];
    order.iter().for_each(|&f| reached[f as usize] = true);
    order.extend((0..n as u32).filter(|&f| !reached[f as usize]));

    let corners = |f: u32| chart.face_local[f as usize].map(|v| chart.uvs[v as usize]);
    let mut piece_of = vec![u32::MAX; n];
    let mut pieces: Vec<Vec<u32>> = Vec::new();
    for &seed in &order {
        if piece_of[seed as usize] != u32::MAX {
            continue;
        }
        let id = pieces.len() as u32;
        piece_of[seed as usize] = id;
        let mut faces = vec![seed];
        let mut hull = convex_hull(&corners(seed));
        let mut queue = VecDeque::from([seed]);
        while let Some(f) = queue.pop_front() {
            for &g in &neighbours[f as usize] {
                if piece_of[g as usize] != u32::MAX {
                    continue;
                }
                let mut points = hull.clone();
                points.extend_from_slice(&corners(g));
                let grown = convex_hull(&points);
                if hull_narrow_side(&grown) <= limit {
                    piece_of[g as usize] = id;
                    faces.push(g);
                    hull = grown;
                    queue.push_back(g);
                }
            }
        }
        pieces.push(faces);
    }
    if pieces.len() <= 1 {
        return vec![chart];
    }
    pieces
        .into_iter()
        .map(|mut local_faces| {
            local_faces.sort_unstable();
            let mut remap: HashMap<u32, u32> = HashMap::new();
            let (mut verts, mut uvs) = (Vec::new(), Vec::new());
            let mut face_local = Vec::with_capacity(local_faces.len());
            for &f in &local_faces {
                face_local.push(chart.face_local[f as usize].map(|v| {
                    *remap.entry(v).or_insert_with(|| {
                        verts.push(chart.verts[v as usize]);
                        uvs.push(chart.uvs[v as usize]);
                        verts.len() as u32 - 1
                    })
                }));
            }
            let faces = local_faces.iter().map(|&f| chart.faces[f as usize]).collect();
            finish(faces, verts, face_local, uvs)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The narrow side of the minimum-area rectangle around `points`.
    fn narrow_side(points: &[V2]) -> f64 {
        hull_narrow_side(&convex_hull(points))
    }

    /// A strip of quads (two faces each) along a polyline: `width` across,
    /// with the given centre points.
    fn strip(centre: &[V2], width: f64) -> Chart {
        let (mut uvs, mut face_local) = (Vec::new(), Vec::new());
        for (i, &c) in centre.iter().enumerate() {
            let (a, b) = (centre[i.saturating_sub(1)], centre[(i + 1).min(centre.len() - 1)]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let len = (dx * dx + dy * dy).sqrt();
            let nrm = [-dy / len * width / 2.0, dx / len * width / 2.0];
            uvs.push([c[0] - nrm[0], c[1] - nrm[1]]);
            uvs.push([c[0] + nrm[0], c[1] + nrm[1]]);
        }
        for i in 0..centre.len() as u32 - 1 {
            let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            face_local.push([a, c, b]);
            face_local.push([b, c, d]);
        }
        let [lo, hi] = bounds2(uvs.iter().copied());
        Chart {
            faces: (0..face_local.len() as u32).collect(),
            verts: (0..uvs.len() as u32).collect(),
            face_local,
            uvs,
            size: [hi[0] - lo[0], hi[1] - lo[1]],
            area: 0.0,
        }
    }

    #[test]
    fn mean_width_of_a_strip_is_its_width() {
        // 0.5 x 10: 2 A / P = 2 * 5 / 21 (the ends count).
        let c = strip(&[[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]], 0.5);
        assert!((mean_width(&c) - 10.0 / 21.0).abs() < 1e-12);
        assert!((narrow_side(&c.uvs) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_straight_strip_stays_whole_and_a_bent_one_splits_into_straight_pieces() {
        let line: Vec<V2> = (0..=10).map(|i| [i as f64, 0.0]).collect();
        let c = strip(&line, 0.4);
        // Straight: not a bent strip at 1 texel per unit (narrow side 0.4 < 2).
        assert!(!is_bent_strip(&c, 1.0, 2.0));
        // An L: 10 along x, then 10 along y, 0.4 wide.
        let mut l: Vec<V2> = (0..=10).map(|i| [i as f64, 0.0]).collect();
        l.extend((1..=10).map(|i| [10.0, i as f64]));
        let c = strip(&l, 0.4);
        assert!(is_bent_strip(&c, 1.0, 2.0));
        let faces = c.face_local.len();
        let pieces = split(c, 1.0, |faces, verts, face_local, uvs| Chart {
            faces,
            verts,
            face_local,
            uvs,
            size: [0.0; 2],
            area: 0.0,
        });
        // The two legs and at most a corner piece between them.
        assert!((2..=3).contains(&pieces.len()), "{} pieces", pieces.len());
        assert_eq!(pieces.iter().map(|p| p.faces.len()).sum::<usize>(), faces);
        for p in &pieces {
            assert!(narrow_side(&p.uvs) <= 1.0 + 1e-9, "{:?}", p.size);
        }
    }
}
