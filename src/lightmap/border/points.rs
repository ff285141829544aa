//! The border fit's surface points: where they lie on a page and which
//! run of which sequence traces each.
//!
//! In: a page's triangles, which texels are free, which texel centres lie
//! inside a triangle, the page's seed. Out: [`FitPoint`]s ([`points`]): a
//! jittered grid of [`GRID`]^2 points per texel of UV area in the cells
//! with a free tap, [`SLIVER_SUB`]^2 times as dense in a sliver's cells,
//! the centroid of a triangle too small for the grid; each with the key of
//! its block's sequence and its slot in it ([`block_of`]).

use crate::atlas::rasterize::{SurfaceTri, closest_point_barycentric, inside};
use crate::bits::{mix64, unit};
use crate::lightmap::filter::bilinear_taps as taps;
use glam::Vec2;
use rayon::prelude::*;

/// Quadrature points per texel edge: GRID^2 points per texel of UV area.
pub const GRID: u32 = 2;

/// A surface point of the fit: its UV in texels and where it lies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitPoint {
    /// Lightmap position in texel units of the page.
    pub uv: Vec2,
    /// Its triangle (index into the page's triangles) and barycentrics.
    pub tri: u32,
    pub bary: [f32; 3],
    /// The sequence its rays come from (the key of its block of points)
    /// and its share of it: the points of one block take successive runs
    /// of one sequence (`block_of`).
    pub block: u32,
    pub slot: u32,
}

/// The block of grid cell (`gx`, `gy`) at `per` points per block edge:
/// its key (from the block's place on the page and `salt`) and the cell's
/// slot in it. The points of a block, a texel's area of the grid (or a
/// sliver's grid cell of its dense points), trace successive runs of one
/// scrambled Sobol sequence, so that together they hold a stratified set
/// of `per`^2 times the rays: where they share most of the hemisphere's
/// visibility, the fit, which averages them, sees the error of the
/// larger stratified set.
fn block_of(gx: i64, gy: i64, per: i64, salt: u64) -> (u32, u32) {
    let (bx, by) = (gx.div_euclid(per), gy.div_euclid(per));
    let slot = gx.rem_euclid(per) + per * gy.rem_euclid(per);
    let key = mix64(salt ^ mix64((bx as u64) << 32 ^ (by as u64 & 0xffff_ffff)));
    (key as u32, slot as u32)
}

/// The four texels (indices into a `width` x `height` page) of the
/// bilinear cell of a lookup at `uv` (texel units): the engine view's
/// [`taps`], so the fit and the metric agree on every cell.
pub(crate) fn cell_taps(uv: Vec2, width: u32, height: u32) -> [usize; 4] {
    taps([uv.x / width as f32, uv.y / height as f32], width, height).map(|(t, _)| t as usize)
}

/// Whether the bilinear cell of a lookup at `uv` (texel units) has a
/// free tap (`free` per texel of a `width` x `height` page).
pub(crate) fn cell_has_free(uv: Vec2, width: u32, height: u32, free: &[bool]) -> bool {
    cell_taps(uv, width, height).iter().any(|&t| free[t])
}

/// Whether no tap of the bilinear cell at `uv` (texel units) has its
/// centre inside a triangle: a sliver's cell, as the engine view
/// classifies its lookups.
fn is_sliver_cell(uv: Vec2, width: u32, height: u32, center_inside: &[bool]) -> bool {
    !cell_taps(uv, width, height)
        .iter()
        .any(|&t| center_inside[t])
}

/// The grid point of global grid cell (`gx`, `gy`): jittered in its cell
/// of 1 / [`GRID`] texels, the same wherever it is asked for.
fn grid_point(gx: i64, gy: i64, seed: u64) -> Vec2 {
    let key = mix64(seed ^ mix64((gx as u64) << 32 ^ (gy as u64 & 0xffff_ffff)));
    let g = GRID as f32;
    Vec2::new(
        (gx as f32 + unit(key)) / g,
        (gy as f32 + unit(key ^ 0x5bd1_e995)) / g,
    )
}

/// The fit's points on `tris` (one page's, `width` x `height`): every
/// grid point inside a triangle whose cell has a free tap, and the
/// centroid of a triangle holding none such but whose centroid's cell
/// has one. In a sliver cell (no tap's centre inside a triangle,
/// `center_inside` per texel) each grid cell holds [`SLIVER_SUB`]^2 points
/// instead of one. In triangle order, deterministic for `seed`.
pub fn points(
    tris: &[SurfaceTri],
    width: u32,
    height: u32,
    free: &[bool],
    center_inside: &[bool],
    seed: u64,
) -> Vec<FitPoint> {
    let g = GRID as f32;
    let per_tri: Vec<Vec<FitPoint>> = tris
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let mut out = Vec::new();
            let lo = t.uv.iter().fold(Vec2::INFINITY, |a, &p| a.min(p));
            let hi = t.uv.iter().fold(Vec2::NEG_INFINITY, |a, &p| a.max(p));
            if !(lo.is_finite() && hi.is_finite()) {
                return out;
            }
            let (gx0, gy0) = ((lo.x * g).floor() as i64, (lo.y * g).floor() as i64);
            let (gx1, gy1) = ((hi.x * g).floor() as i64, (hi.y * g).floor() as i64);
            // Whether any grid point falls inside the triangle.
            let mut any = false;
            let mut push = |p: Vec2, (block, slot): (u32, u32), out: &mut Vec<FitPoint>| {
                if !inside(p, &t.uv) {
                    return;
                }
                any = true;
                if cell_has_free(p, width, height, free) {
                    let (bary, _) = closest_point_barycentric(p, t.uv[0], t.uv[1], t.uv[2]);
                    out.push(FitPoint {
                        uv: p,
                        tri: i as u32,
                        bary,
                        block,
                        slot,
                    });
                }
            };
            for gy in gy0..=gy1 {
                for gx in gx0..=gx1 {
                    let centre = Vec2::new(gx as f32 + 0.5, gy as f32 + 0.5) / g;
                    if is_sliver_cell(centre, width, height, center_inside) {
                        let s = SLIVER_SUB as i64;
                        for sy in 0..s {
                            for sx in 0..s {
                                let (fx, fy) = (gx * s + sx, gy * s + sy);
                                let f = grid_point(fx, fy, seed ^ SLIVER_SEED);
                                let block = block_of(fx, fy, s, SLIVER_SEED);
                                push(f / SLIVER_SUB as f32, block, &mut out);
                            }
                        }
                    } else {
                        let block = block_of(gx, gy, GRID as i64, 0);
                        push(grid_point(gx, gy, seed), block, &mut out);
                    }
                }
            }
            let centroid = (t.uv[0] + t.uv[1] + t.uv[2]) / 3.0;
            if !any && cell_has_free(centroid, width, height, free) {
                let third = 1.0 / 3.0;
                out.push(FitPoint {
                    uv: centroid,
                    tri: i as u32,
                    bary: [third; 3],
                    block: point_key(centroid),
                    slot: 0,
                });
            }
            out
        })
        .collect();
    per_tri.into_iter().flatten().collect()
}

/// The key of a fit point's rays (its receiver's `texel`, which seeds its
/// sequence): a hash of its UV's bits. Points are placed by the global
/// grid, so a point keeps its key whatever else is on the page.
fn point_key(uv: Vec2) -> u32 {
    mix64(u64::from(uv.x.to_bits()) << 32 | u64::from(uv.y.to_bits())) as u32
}

/// Points per grid cell edge in a sliver's cell: SLIVER_SUB^2 points where
/// the grid has one, each a full fit row. A chart's acute tip or a strip
/// thinner than the grid spacing gets a grid point only here and there, and
/// its few rows lose to the texels' data terms, so its lookups keep the
/// edge receivers' values. Full rows matter: weighted by their share of
/// the cell they did worse than none; 8 per edge does no better than 4
/// for far more points (`docs/measurements/constants.md`, SLIVER_SUB).
pub const SLIVER_SUB: u32 = 4;

const SLIVER_SEED: u64 = 0x51f1_7e55;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec3;

    pub(crate) fn square(w: f32) -> Vec<SurfaceTri> {
        // A w x w texel square at (2, 2), as two triangles.
        let c = [
            Vec2::new(2.0, 2.0),
            Vec2::new(2.0 + w, 2.0),
            Vec2::new(2.0 + w, 2.0 + w),
            Vec2::new(2.0, 2.0 + w),
        ];
        let p = c.map(|c| Vec3::new(c.x, c.y, 0.0));
        [[0, 1, 2], [0, 2, 3]]
            .iter()
            .map(|i| SurfaceTri {
                mesh: 0,
                uv: i.map(|k| c[k]),
                pos: i.map(|k| p[k]),
                nrm: None,
                geo: Vec3::Z,
                footprint: 1.0,
            })
            .collect()
    }

    #[test]
    fn a_texels_grid_points_share_its_block_in_distinct_slots() {
        // A 6 x 6 texel square at (2, 2), every texel free: the points of
        // one texel's area share a block key, one in each of its GRID^2
        // slots; points of different texels do not share a key.
        let tris = square(6.0);
        let all = vec![true; 100];
        let pts = points(&tris, 10, 10, &all, &all, 3);
        let mut blocks: std::collections::BTreeMap<u32, Vec<(u32, [i64; 2])>> = Default::default();
        for p in &pts {
            let texel = [p.uv.x.floor() as i64, p.uv.y.floor() as i64];
            blocks.entry(p.block).or_default().push((p.slot, texel));
        }
        let per = (GRID * GRID) as usize;
        let mut full = 0;
        for (key, members) in &blocks {
            let texel = members[0].1;
            assert!(members.iter().all(|m| m.1 == texel), "{key}: {members:?}");
            let mut slots: Vec<u32> = members.iter().map(|m| m.0).collect();
            slots.sort();
            slots.dedup();
            assert_eq!(slots.len(), members.len(), "{key}: {members:?}");
            assert!(slots.iter().all(|&s| (s as usize) < per));
            full += (slots.len() == per) as usize;
        }
        // The square's 36 texels, a block each (the two triangles' points
        // of one texel in one block).
        assert_eq!(blocks.len(), 36);
        assert_eq!(full, 36);
    }

    #[test]
    fn grid_points_are_the_same_from_either_triangle() {
        assert_eq!(grid_point(7, -3, 11), grid_point(7, -3, 11));
        let p = grid_point(7, -3, 11);
        assert!(p.x >= 3.5 && p.x < 4.0 && p.y >= -1.5 && p.y < -1.0, "{p}");
    }

    #[test]
    fn points_cover_the_cells_with_a_free_tap_at_the_grid_density() {
        // A 6 x 6 texel square on a 10 x 10 page, every texel free: its
        // area times GRID^2 points, each once.
        let tris = square(6.0);
        let all = vec![true; 100];
        let pts = points(&tris, 10, 10, &all, &all, 3);
        let expected = 36.0 * (GRID * GRID) as f32;
        assert!((pts.len() as f32 - expected).abs() <= 2.0, "{}", pts.len());
        // No texel free: no point.
        assert!(points(&tris, 10, 10, &[false; 100], &all, 3).is_empty());
        // Only texel (2, 2) free: points only in the four cells around its
        // centre (2.5, 2.5), i.e. within one texel of it.
        let mut one = vec![false; 100];
        one[2 * 10 + 2] = true;
        let pts = points(&tris, 10, 10, &one, &all, 3);
        assert!(!pts.is_empty());
        for p in &pts {
            assert!(
                (p.uv - Vec2::splat(2.5)).abs().max_element() <= 1.0,
                "{p:?}"
            );
        }
    }

    #[test]
    fn a_triangle_smaller_than_the_grid_gets_its_centroid() {
        let tris = square(0.05);
        let all = vec![true; 100];
        let pts = points(&tris, 10, 10, &all, &all, 3);
        assert_eq!(pts.len(), 2, "{pts:?}");
        for p in &pts {
            assert_eq!(p.bary, [1.0 / 3.0; 3]);
        }
    }

    #[test]
    fn a_slivers_cells_hold_the_dense_points() {
        // A strip 0.3 x 6 texels at (2, 2) on a 10 x 10 page, every texel
        // free. With no texel centre inside a triangle every cell is a
        // sliver's: SLIVER_SUB^2 times the grid's points per area.
        let mut tris = square(6.0);
        for t in &mut tris {
            for p in &mut t.uv {
                p.y = 2.0 + (p.y - 2.0) * 0.05;
            }
        }
        let all = vec![true; 100];
        let none = vec![false; 100];
        let area = 6.0 * 0.3;
        let grid = points(&tris, 10, 10, &all, &all, 3).len() as f32;
        let dense = points(&tris, 10, 10, &all, &none, 3).len() as f32;
        let per = (GRID * GRID) as f32;
        let sub = (SLIVER_SUB * SLIVER_SUB) as f32;
        assert!((grid - area * per).abs() <= 4.0, "{grid}");
        assert!(
            (dense - area * per * sub).abs() <= 0.15 * area * per * sub,
            "{dense}"
        );
        // Deterministic, and every point inside the strip.
        let again = points(&tris, 10, 10, &all, &none, 3);
        assert_eq!(again, points(&tris, 10, 10, &all, &none, 3));
        for p in &again {
            assert!(
                p.uv.y >= 2.0 && p.uv.y <= 2.3 && p.uv.x >= 2.0 && p.uv.x <= 8.0,
                "{p:?}"
            );
        }
    }
}
