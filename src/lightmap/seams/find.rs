//! Find: the smooth seams of an atlas, where two triangles share an edge in
//! world space but map it to different lightmap UVs.
//!
//! In: the [`ReceiverMesh`]es (bake space) and their [`Atlas`] charts.
//! Out: one [`Seam`] per shared world edge whose two sides' vertex normals
//! agree within a given angle at both ends (a smooth surface the unwrapper
//! cut, or a mesh split by material or mirrored) and whose two faces'
//! geometric normals agree within another; creases keep their jump, shaded
//! smooth or not (see [`super::FLAT_DEGREES`]). Edges shared by more than
//! two triangles (non-manifold) and zero-length edges are left out.

use crate::atlas::Atlas;
use crate::geometry::ReceiverMesh;
use glam::Vec3;
use std::collections::HashMap;

/// One smooth seam: the same world edge seen through two UV mappings.
/// `a[e]` and `b[e]` are the UVs (glTF convention, in [0, 1]) of endpoint
/// e on each side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seam {
    pub a: [[f32; 2]; 2],
    pub b: [[f32; 2]; 2],
    /// Length in bake units.
    pub length: f32,
}

impl Seam {
    /// The longer side's length in texels of a `width` x `height` page.
    pub fn texels(&self, width: u32, height: u32) -> f32 {
        let len = |uv: &[[f32; 2]; 2]| {
            let d = [
                (uv[1][0] - uv[0][0]) * width as f32,
                (uv[1][1] - uv[0][1]) * height as f32,
            ];
            (d[0] * d[0] + d[1] * d[1]).sqrt()
        };
        len(&self.a).max(len(&self.b))
    }

    /// The UVs of the point at `t` in [0, 1] along the edge, on each side.
    #[inline]
    pub fn at(&self, t: f32) -> ([f32; 2], [f32; 2]) {
        let lerp = |uv: &[[f32; 2]; 2]| {
            [
                uv[0][0] + (uv[1][0] - uv[0][0]) * t,
                uv[0][1] + (uv[1][1] - uv[0][1]) * t,
            ]
        };
        (lerp(&self.a), lerp(&self.b))
    }
}

/// One triangle's view of an edge, endpoints in the key's order.
#[derive(Clone, Copy)]
struct Side {
    uv: [[f32; 2]; 2],
    normal: [Vec3; 2],
    length: f32,
    page: u32,
    ends: [Vec3; 2],
    face: Vec3,
}

/// A smooth seam whose two sides lie on different atlas pages: what both
/// pages need to agree on it without the other's images. Side 0 is the
/// first page's (`page[0] < page[1]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrossSeam {
    pub page: [u32; 2],
    /// `uv[side][end]`, in that side's page.
    pub uv: [[[f32; 2]; 2]; 2],
    /// Bake-space endpoints.
    pub ends: [Vec3; 2],
    /// Unit vertex normals at the ends, the two sides' averaged.
    pub normal: [Vec3; 2],
    /// Unit face normal, the two sides' averaged.
    pub face: Vec3,
    /// Length in bake units.
    pub length: f32,
}

impl CrossSeam {
    /// The UV of the point at `t` in [0, 1] along the edge on side
    /// `side`, in that side's page.
    #[inline]
    pub fn at(&self, side: usize, t: f32) -> [f32; 2] {
        let uv = &self.uv[side];
        [
            uv[0][0] + (uv[1][0] - uv[0][0]) * t,
            uv[0][1] + (uv[1][1] - uv[0][1]) * t,
        ]
    }
}

/// Position key: bake-space coordinates on a 2^-24 grid (bake space spans
/// about 1, so vertices that a file places at the same point share a key).
fn key(p: [f32; 3]) -> [i64; 3] {
    p.map(|c| (c as f64 * (1u64 << 24) as f64).round() as i64)
}

/// Every shared world edge and the triangles' views of it.
fn edge_sides(meshes: &[ReceiverMesh], atlas: &Atlas) -> HashMap<([i64; 3], [i64; 3]), Vec<Side>> {
    let mut edges: HashMap<([i64; 3], [i64; 3]), Vec<Side>> = HashMap::new();
    for (m, charted) in meshes.iter().zip(&atlas.meshes) {
        for (tri, &page) in charted
            .triangles
            .chunks_exact(3)
            .zip(&charted.triangle_page)
        {
            let corner = |i: u32| {
                let input = charted.xref[i as usize] as usize;
                (m.positions[input], charted.uv[i as usize], input)
            };
            let c = [corner(tri[0]), corner(tri[1]), corner(tri[2])];
            let p = c.map(|(p, _, _)| Vec3::from(p));
            let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            if face == Vec3::ZERO {
                continue;
            }
            for e in 0..3 {
                let (mut s, mut t) = (c[e], c[(e + 1) % 3]);
                let (mut ks, mut kt) = (key(s.0), key(t.0));
                if ks == kt {
                    continue;
                }
                if kt < ks {
                    std::mem::swap(&mut s, &mut t);
                    std::mem::swap(&mut ks, &mut kt);
                }
                let normal = |input: usize| {
                    m.normals
                        .as_ref()
                        .map_or(face, |n| Vec3::from(n[input]).normalize_or_zero())
                };
                let ends = [Vec3::from(s.0), Vec3::from(t.0)];
                edges.entry((ks, kt)).or_default().push(Side {
                    uv: [s.1, t.1],
                    normal: [normal(s.2), normal(t.2)],
                    length: (ends[1] - ends[0]).length(),
                    page,
                    ends,
                    face: if m.mirrored { -face } else { face },
                });
            }
        }
    }
    edges
}

/// When two sides of an edge are one smooth surface: the cosines of the
/// largest angles between their vertex normals (at both ends) and between
/// their faces' normals.
#[derive(Clone, Copy)]
struct Smooth {
    normal_cos: f32,
    face_cos: f32,
}

impl Smooth {
    fn new(normal_degrees: f32, face_degrees: f32) -> Smooth {
        Smooth {
            normal_cos: normal_degrees.to_radians().cos(),
            face_cos: face_degrees.to_radians().cos(),
        }
    }

    fn holds(self, a: &Side, b: &Side) -> bool {
        (0..2).all(|e| a.normal[e].dot(b.normal[e]) >= self.normal_cos)
            && a.face.dot(b.face) >= self.face_cos
    }
}

/// The smooth seams of `atlas` (see the module doc): vertex normals within
/// `normal_degrees` at both ends, faces within `face_degrees`, both sides
/// on one page (every seam of a one-page atlas).
pub fn smooth_seams(
    meshes: &[ReceiverMesh],
    atlas: &Atlas,
    normal_degrees: f32,
    face_degrees: f32,
) -> Vec<Seam> {
    let smooth = Smooth::new(normal_degrees, face_degrees);
    let edges = edge_sides(meshes, atlas);
    let mut seams: Vec<Seam> = edges
        .into_values()
        .filter_map(|sides| {
            let [a, b] = sides.as_slice() else {
                return None;
            };
            let same_uv = (0..2).all(|e| {
                (a.uv[e][0] - b.uv[e][0]).abs() < 1e-7 && (a.uv[e][1] - b.uv[e][1]).abs() < 1e-7
            });
            (!same_uv && smooth.holds(a, b) && a.page == b.page).then_some(Seam {
                a: a.uv,
                b: b.uv,
                length: a.length,
            })
        })
        .collect();
    // Deterministic order whatever the hash map's.
    seams.sort_by(|x, y| {
        let k = |s: &Seam| {
            [
                s.a[0][0], s.a[0][1], s.a[1][0], s.a[1][1], s.b[0][0], s.b[0][1],
            ]
        };
        k(x).partial_cmp(&k(y)).unwrap_or(std::cmp::Ordering::Equal)
    });
    seams
}

/// The smooth seams of a multi-page `atlas` whose two sides lie on
/// different pages, in a deterministic order.
pub fn cross_page_seams(
    meshes: &[ReceiverMesh],
    atlas: &Atlas,
    normal_degrees: f32,
    face_degrees: f32,
) -> Vec<CrossSeam> {
    let smooth = Smooth::new(normal_degrees, face_degrees);
    let mut seams: Vec<CrossSeam> = edge_sides(meshes, atlas)
        .into_values()
        .filter_map(|sides| {
            let [a, b] = sides.as_slice() else {
                return None;
            };
            if !smooth.holds(a, b) || a.page == b.page {
                return None;
            }
            let (a, b) = if a.page < b.page { (a, b) } else { (b, a) };
            let average = |x: Vec3, y: Vec3| (x + y).normalize_or(x);
            Some(CrossSeam {
                page: [a.page, b.page],
                uv: [a.uv, b.uv],
                ends: a.ends,
                normal: [
                    average(a.normal[0], b.normal[0]),
                    average(a.normal[1], b.normal[1]),
                ],
                face: average(a.face, b.face),
                length: a.length,
            })
        })
        .collect();
    seams.sort_by(|x, y| {
        let k = |s: &CrossSeam| [s.ends[0].to_array(), s.ends[1].to_array()];
        k(x).partial_cmp(&k(y)).unwrap_or(std::cmp::Ordering::Equal)
    });
    seams
}
