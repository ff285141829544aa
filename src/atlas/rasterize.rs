//! Rasterize: atlas texels into receiver points.
//!
//! In: the [`ReceiverMesh`]es and their [`Atlas`] charts. Out: [`Receivers`],
//! one per covered texel, in row-major texel order (SoA): bake-space
//! position, shading normal, geometric normal, footprint (the world size of a
//! texel there, the paper's shading diameter, in bake units).
//!
//! Coverage is conservative: a texel whose centre lies in no triangle but
//! whose square touches one (centre within half a texel diagonal) still gets
//! a point, the closest point of that triangle, so chart edges never go
//! black. A texel whose centre lies inside a triangle always takes that one.

use super::unwrap::Atlas;
use crate::geometry::ReceiverMesh;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Half the diagonal of a texel: the reach of conservative coverage.
const CONSERVATIVE_REACH: f32 = std::f32::consts::FRAC_1_SQRT_2 + 1e-4;
/// Rows per band of the binned rasterizer.
const BAND_ROWS: u32 = 8;

/// Receiver points, one per covered texel (structure of arrays), in any
/// order: every stage finds a receiver's texel through `texel` (the
/// pipeline puts them in [`super::order`]'s world order).
#[derive(Clone, Debug, Default)]
pub struct Receivers {
    pub width: u32,
    pub height: u32,
    /// Texel index `y * width + x`.
    pub texel: Vec<u32>,
    pub position: Vec<Vec3>,
    /// Unit shading normal n (interpolated, or geometric if absent).
    pub normal: Vec<Vec3>,
    /// Unit geometric normal, on the side of `normal`.
    pub geo_normal: Vec<Vec3>,
    /// Texel edge length at the receiver, bake units.
    pub footprint: Vec<f32>,
    /// The texel's centre lies inside a triangle (false: covered only
    /// conservatively, the receiver on the chart's edge).
    pub center_inside: Vec<bool>,
    /// Texels whose centre lies inside triangles of two different receiver
    /// meshes (overlapping UVs; always 0 for generated atlases), and the
    /// first such pair of receiver-mesh indices.
    pub overlapping_texels: usize,
    pub first_overlap: Option<(u32, u32)>,
}

impl Receivers {
    /// The atlas size and overlap diagnostics, with no receivers.
    pub fn clone_header(&self) -> Receivers {
        Receivers {
            width: self.width,
            height: self.height,
            overlapping_texels: self.overlapping_texels,
            first_overlap: self.first_overlap,
            ..Default::default()
        }
    }
    pub fn len(&self) -> usize {
        self.texel.len()
    }
    pub fn is_empty(&self) -> bool {
        self.texel.is_empty()
    }

    /// Per texel of the page: whether its centre lies inside a triangle.
    pub fn centers_inside(&self) -> Vec<bool> {
        let mut map = vec![false; (self.width * self.height) as usize];
        for (&t, &c) in self.texel.iter().zip(&self.center_inside) {
            map[t as usize] |= c;
        }
        map
    }

    /// Appends the receiver at barycentrics `b` of triangle `t` (its
    /// position, normals and footprint), keyed `texel`.
    pub fn push_surface_point(
        &mut self,
        texel: u32,
        t: &SurfaceTri,
        b: [f32; 3],
        center_inside: bool,
    ) {
        let (pos, n, geo) = t.at(b);
        self.texel.push(texel);
        self.position.push(pos);
        self.normal.push(n);
        self.geo_normal.push(geo);
        self.footprint.push(t.footprint);
        self.center_inside.push(center_inside);
    }

    /// The receivers in `order` (`order[new] = old`, a permutation).
    pub fn permuted(&self, order: &[u32]) -> Receivers {
        fn pick<T: Copy + Send + Sync>(v: &[T], order: &[u32]) -> Vec<T> {
            order.par_iter().map(|&i| v[i as usize]).collect()
        }
        Receivers {
            texel: pick(&self.texel, order),
            position: pick(&self.position, order),
            normal: pick(&self.normal, order),
            geo_normal: pick(&self.geo_normal, order),
            footprint: pick(&self.footprint, order),
            center_inside: pick(&self.center_inside, order),
            ..self.clone_header()
        }
    }
}

/// A triangle of a page, ready to rasterize or sample: its corners in
/// texels and in bake space.
#[derive(Clone, Debug)]
pub struct SurfaceTri {
    /// Receiver mesh index.
    pub mesh: u32,
    /// Corners in texel units of the page.
    pub uv: [Vec2; 3],
    pub pos: [Vec3; 3],
    pub nrm: Option<[Vec3; 3]>,
    /// Unit geometric normal (front face, mirroring undone).
    pub geo: Vec3,
    /// World size of a texel on it, bake units.
    pub footprint: f32,
}

impl SurfaceTri {
    /// The surface at barycentrics `b`: position, unit shading normal
    /// (interpolated, or geometric where the normals are missing or
    /// cancel) and the geometric normal on its side.
    pub fn at(&self, b: [f32; 3]) -> (Vec3, Vec3, Vec3) {
        let pos = self.pos[0] * b[0] + self.pos[1] * b[1] + self.pos[2] * b[2];
        let n = self
            .nrm
            .map(|n| (n[0] * b[0] + n[1] * b[1] + n[2] * b[2]).normalize_or_zero())
            .filter(|n| n.length_squared() > 0.5)
            .unwrap_or(self.geo);
        let geo = if self.geo.dot(n) < 0.0 {
            -self.geo
        } else {
            self.geo
        };
        (pos, n, geo)
    }

    /// Bake-space area.
    pub fn area(&self) -> f32 {
        0.5 * (self.pos[1] - self.pos[0])
            .cross(self.pos[2] - self.pos[0])
            .length()
    }
}

/// Closest point of triangle abc to p in 2D: (barycentrics, squared distance).
pub fn closest_point_barycentric(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> ([f32; 3], f32) {
    // Ericson, Real-Time Collision Detection, 5.1.5.
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    let bary = if d1 <= 0.0 && d2 <= 0.0 {
        [1.0, 0.0, 0.0]
    } else {
        let bp = p - b;
        let d3 = ab.dot(bp);
        let d4 = ac.dot(bp);
        if d3 >= 0.0 && d4 <= d3 {
            [0.0, 1.0, 0.0]
        } else {
            let vc = d1 * d4 - d3 * d2;
            if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
                let v = d1 / (d1 - d3);
                [1.0 - v, v, 0.0]
            } else {
                let cp = p - c;
                let d5 = ab.dot(cp);
                let d6 = ac.dot(cp);
                if d6 >= 0.0 && d5 <= d6 {
                    [0.0, 0.0, 1.0]
                } else {
                    let vb = d5 * d2 - d1 * d6;
                    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
                        let w = d2 / (d2 - d6);
                        [1.0 - w, 0.0, w]
                    } else {
                        let va = d3 * d6 - d5 * d4;
                        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
                            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                            [0.0, 1.0 - w, w]
                        } else {
                            let denom = 1.0 / (va + vb + vc);
                            let v = vb * denom;
                            let w = vc * denom;
                            [1.0 - v - w, v, w]
                        }
                    }
                }
            }
        }
    };
    let q = a * bary[0] + b * bary[1] + c * bary[2];
    (bary, (q - p).length_squared())
}

/// Whether p is inside (or on) triangle abc, by edge functions of either winding.
/// Whether `p` is inside triangle `t` (either winding; edges included).
pub fn inside(p: Vec2, t: &[Vec2; 3]) -> bool {
    let e = |a: Vec2, b: Vec2| (b - a).perp_dot(p - a);
    let (e0, e1, e2) = (e(t[0], t[1]), e(t[1], t[2]), e(t[2], t[0]));
    (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
}

/// The non-degenerate triangles of `atlas`'s charts (one page's atlas:
/// [`Atlas::page`]), in mesh and triangle order.
pub fn surface_triangles(meshes: &[ReceiverMesh], atlas: &Atlas) -> Vec<SurfaceTri> {
    let (w, h) = (atlas.width as f32, atlas.height as f32);
    let mut tris = Vec::new();
    for (mi, (m, c)) in meshes.iter().zip(&atlas.meshes).enumerate() {
        for t in c.triangles.chunks_exact(3) {
            let uv = [0, 1, 2].map(|k| {
                let u = c.uv[t[k] as usize];
                Vec2::new(u[0] * w, u[1] * h)
            });
            let src = [0, 1, 2].map(|k| c.xref[t[k] as usize] as usize);
            let pos = src.map(|i| Vec3::from(m.positions[i]));
            let cross = (pos[1] - pos[0]).cross(pos[2] - pos[0]);
            let area3 = 0.5 * cross.length();
            let area_uv = 0.5 * (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
            // Zero-area triangles (in space or in UV) cover nothing.
            if !(area3 > 0.0 && area_uv > 1e-12 && area3.is_finite()) {
                continue;
            }
            let mut geo = cross / (2.0 * area3);
            if m.mirrored {
                geo = -geo;
            }
            let nrm = m.normals.as_ref().map(|n| src.map(|i| Vec3::from(n[i])));
            tris.push(SurfaceTri {
                mesh: mi as u32,
                uv,
                pos,
                nrm,
                geo,
                footprint: (area3 / area_uv).sqrt(),
            });
        }
    }
    tris
}

/// Finds the receiver points of every covered texel.
pub fn rasterize(meshes: &[ReceiverMesh], atlas: &Atlas) -> Receivers {
    let tris = surface_triangles(meshes, atlas);
    let (w, h) = (atlas.width, atlas.height);
    let bands = h.div_ceil(BAND_ROWS) as usize;
    // Bin triangles by band of rows (ascending triangle order inside a band).
    let mut binned: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, t) in tris.iter().enumerate() {
        let lo = t.uv.iter().fold(f32::INFINITY, |a, p| a.min(p.y)) - CONSERVATIVE_REACH;
        let hi = t.uv.iter().fold(f32::NEG_INFINITY, |a, p| a.max(p.y)) + CONSERVATIVE_REACH;
        let y0 = (lo.floor().max(0.0) as u32).min(h - 1);
        let y1 = (hi.ceil().max(0.0) as u32).min(h - 1);
        for b in (y0 / BAND_ROWS)..=(y1 / BAND_ROWS) {
            binned[b as usize].push(i as u32);
        }
    }
    let per_band: Vec<Receivers> = binned
        .par_iter()
        .enumerate()
        .map(|(b, list)| rasterize_band(&tris, list, b as u32, w, h))
        .collect();
    let mut out = Receivers {
        width: w,
        height: h,
        ..Default::default()
    };
    for r in per_band {
        out.overlapping_texels += r.overlapping_texels;
        out.first_overlap = out.first_overlap.or(r.first_overlap);
        out.texel.extend(r.texel);
        out.position.extend(r.position);
        out.normal.extend(r.normal);
        out.geo_normal.extend(r.geo_normal);
        out.footprint.extend(r.footprint);
        out.center_inside.extend(r.center_inside);
    }
    out
}

/// The texels whose centres may lie within [`CONSERVATIVE_REACH`] of a
/// triangle with UVs `uv` (texels), on a `w` x `h` page: x and y ranges,
/// inclusive.
fn reach_box(uv: &[Vec2; 3], w: u32, h: u32) -> ([u32; 2], [u32; 2]) {
    let lo = uv.iter().fold(Vec2::INFINITY, |a, &p| a.min(p)) - CONSERVATIVE_REACH;
    let hi = uv.iter().fold(Vec2::NEG_INFINITY, |a, &p| a.max(p)) + CONSERVATIVE_REACH;
    let x = [lo.x, hi.x.ceil()].map(|v| (v.floor().max(0.0) as u32).min(w - 1));
    let y = [lo.y, hi.y.ceil()].map(|v| (v.floor().max(0.0) as u32).min(h - 1));
    (x, y)
}

/// The barycentrics of the point of triangle `t` nearest `p` and the
/// squared distance to it (0 inside, edges included).
fn nearest(p: Vec2, t: &[Vec2; 3]) -> ([f32; 3], f32) {
    if inside(p, t) {
        (closest_point_barycentric(p, t[0], t[1], t[2]).0, 0.0)
    } else {
        closest_point_barycentric(p, t[0], t[1], t[2])
    }
}

/// Which texels of `atlas` (one page's) are covered, the texels
/// [`rasterize`] gives a receiver (a centre within its conservative reach
/// of a triangle), decided only where `needed` is true (false elsewhere):
/// the coverage of a few texels without making every receiver.
pub fn covered(meshes: &[ReceiverMesh], atlas: &Atlas, needed: &[bool]) -> Vec<bool> {
    let (w, h) = (atlas.width, atlas.height);
    let mut out = vec![false; needed.len()];
    let reach2 = CONSERVATIVE_REACH * CONSERVATIVE_REACH;
    for t in surface_triangles(meshes, atlas) {
        let ([xa, xb], [ya, yb]) = reach_box(&t.uv, w, h);
        for y in ya..=yb {
            for x in xa..=xb {
                let i = (y * w + x) as usize;
                if !needed[i] || out[i] {
                    continue;
                }
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                out[i] = nearest(p, &t.uv).1 <= reach2;
            }
        }
    }
    out
}

fn rasterize_band(tris: &[SurfaceTri], list: &[u32], band: u32, w: u32, h: u32) -> Receivers {
    let y0 = band * BAND_ROWS;
    let y1 = (y0 + BAND_ROWS).min(h);
    let rows = (y1 - y0) as usize;
    // Best candidate per texel of the band: (squared distance, triangle, barycentrics).
    let mut best: Vec<(f32, u32, [f32; 3])> =
        vec![(f32::INFINITY, u32::MAX, [0.0; 3]); rows * w as usize];
    let reach2 = CONSERVATIVE_REACH * CONSERVATIVE_REACH;
    let mut out = Receivers::default();
    for &ti in list {
        let t = &tris[ti as usize];
        let ([xa, xb], y) = reach_box(&t.uv, w, h);
        let [ya, yb] = y.map(|y| y.clamp(y0, y1 - 1));
        for y in ya..=yb {
            for x in xa..=xb {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let (bary, d2) = nearest(p, &t.uv);
                let slot = &mut best[(y - y0) as usize * w as usize + x as usize];
                if d2 == 0.0 && slot.0 == 0.0 && tris[slot.1 as usize].mesh != t.mesh {
                    out.overlapping_texels += 1;
                    out.first_overlap
                        .get_or_insert((tris[slot.1 as usize].mesh, t.mesh));
                }
                if d2 <= reach2 && d2 < slot.0 {
                    *slot = (d2, ti, bary);
                }
            }
        }
    }
    for (i, &(d2, ti, b)) in best.iter().enumerate() {
        if !d2.is_finite() {
            continue;
        }
        let (x, y) = (i % w as usize, i / w as usize + y0 as usize);
        let texel = (y * w as usize + x) as u32;
        out.push_surface_point(texel, &tris[ti as usize], b, d2 == 0.0);
    }
    out
}

/// The UV (texel units) of the receiver [`rasterize`] gives each texel
/// that `needed` marks: the covered point nearest its centre.
pub(crate) fn receiver_uvs(
    tris: &[SurfaceTri],
    w: u32,
    h: u32,
    needed: &[bool],
) -> Vec<Option<Vec2>> {
    let reach2 = CONSERVATIVE_REACH * CONSERVATIVE_REACH;
    // Every triangle's candidates (texel, distance^2, triangle, point), in
    // parallel; then per texel the nearest, the first triangle on a tie:
    // what a loop over the triangles in order keeps.
    let candidates: Vec<(usize, f32, usize, Vec2)> = tris
        .par_iter()
        .enumerate()
        .flat_map_iter(|(k, t)| {
            let ([xa, xb], [ya, yb]) = reach_box(&t.uv, w, h);
            (ya..=yb).flat_map(move |y| {
                (xa..=xb).filter_map(move |x| {
                    let i = (y * w + x) as usize;
                    if !needed[i] {
                        return None;
                    }
                    let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let (b, d2) = nearest(p, &t.uv);
                    (d2 <= reach2)
                        .then(|| (i, d2, k, t.uv[0] * b[0] + t.uv[1] * b[1] + t.uv[2] * b[2]))
                })
            })
        })
        .collect();
    let mut best: Vec<(f32, usize, Option<Vec2>)> =
        vec![(f32::INFINITY, usize::MAX, None); needed.len()];
    for (i, d2, k, uv) in candidates {
        let b = &mut best[i];
        if d2 < b.0 || (d2 == b.0 && k < b.1) {
            *b = (d2, k, Some(uv));
        }
    }
    best.into_iter().map(|b| b.2).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_inside_edge_and_vertex() {
        let (a, b, c) = (Vec2::ZERO, Vec2::new(4.0, 0.0), Vec2::new(0.0, 4.0));
        let (bary, d2) = closest_point_barycentric(Vec2::new(1.0, 1.0), a, b, c);
        assert!(d2 < 1e-12);
        assert!((bary[1] - 0.25).abs() < 1e-6 && (bary[2] - 0.25).abs() < 1e-6);
        let (bary, d2) = closest_point_barycentric(Vec2::new(2.0, -1.0), a, b, c);
        assert!((d2 - 1.0).abs() < 1e-6 && (bary[1] - 0.5).abs() < 1e-6);
        let (bary, d2) = closest_point_barycentric(Vec2::new(-1.0, -1.0), a, b, c);
        assert!((d2 - 2.0).abs() < 1e-6 && bary == [1.0, 0.0, 0.0]);
        let (_, d2) = closest_point_barycentric(Vec2::new(3.0, 3.0), a, b, c);
        assert!((d2 - 2.0).abs() < 1e-5);
    }
}
