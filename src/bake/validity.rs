//! Validity: receivers inside or behind geometry.
//!
//! In: [`Receivers`], a [`Tracer`] that knows which triangles are
//! single-sided, the max distance. Out: per receiver, whether it is
//! *inside*: most of its hemisphere's closest hits are back faces of
//! single-sided triangles. Such texels (a floor running through a wall, the
//! floor under a box resting on it, geometry intersecting geometry) are
//! never seen, but baked they are black and bilinear filtering bleeds that
//! into visible texels; the output fills them from their nearest valid
//! texel instead (see `crate::atlas::dilate`).
//!
//! Each receiver casts up to [`VALIDITY_RAYS`] closest-hit rays, the
//! first of the bake's own sequence (seed and stream of the bake, so the
//! adaptive method's pre-pass, which casts the same closest-hit rays,
//! finds the same receivers inside without this stage: see
//! [`BackFaces`]); after the first [`VALIDITY_PROBE`] a receiver that saw
//! no back face stops, so texels in the open cost a few rays. A scene
//! without single-sided triangles has no back faces to find and casts none.

use super::ReceiverRays;
use crate::atlas::Receivers;
use crate::trace::{Closest, Tracer, for_each_receiver_query};

/// Rays per receiver, at most.
pub const VALIDITY_RAYS: u32 = 16;
/// Rays cast before a receiver that saw no back face stops.
pub const VALIDITY_PROBE: u32 = 4;
/// A receiver is inside when at least this fraction of its rays (above its
/// geometric horizon) reach back faces.
pub const INSIDE_FRACTION: f32 = 0.5;

/// The inside test's running count over a receiver's rays in sequence
/// order: the rays traced (above the geometric plane) and those whose
/// closest hit is a back face.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BackFaces {
    traced: u32,
    back: u32,
}

impl BackFaces {
    /// Whether ray `i` of the sequence is part of the test: one of the
    /// first [`VALIDITY_RAYS`], past the probe only if the probe saw a
    /// back face.
    #[inline]
    pub fn counts(&self, i: u32) -> bool {
        i < VALIDITY_RAYS && (i < VALIDITY_PROBE || self.back > 0)
    }

    /// Counts a traced ray; `back`: its closest hit is a back face.
    #[inline]
    pub fn add(&mut self, back: bool) {
        self.traced += 1;
        self.back += back as u32;
    }

    /// Inside: at least [`INSIDE_FRACTION`] of the traced rays reached back
    /// faces (none traced: not inside).
    #[inline]
    pub fn inside(&self) -> bool {
        self.traced > 0 && self.back as f32 >= INSIDE_FRACTION * self.traced as f32
    }
}

/// Per receiver: inside geometry (see the module doc), from the bake's
/// sequences for `seed`.
pub(crate) fn inside_geometry(
    receivers: &Receivers,
    tracer: &Tracer,
    max_distance: f32,
    seed: u64,
) -> Vec<bool> {
    if !tracer.has_single_sided() {
        return vec![false; receivers.len()];
    }
    let counts = vec![BackFaces::default(); receivers.len()];
    finish_inside(receivers, tracer, max_distance, seed, 0, counts)
}

/// Per receiver: inside geometry, its test continued from ray `from` of
/// the bake's sequence with `counts[r]` the count of receiver r's rays
/// before it (the adaptive pre-pass's, when it casts fewer than
/// [`VALIDITY_RAYS`]). Traced in two rounds of batches: the probe, then the
/// rest of the test where the probe saw a back face (the rays
/// [`BackFaces::counts`]).
pub(crate) fn finish_inside(
    receivers: &Receivers,
    tracer: &Tracer,
    max_distance: f32,
    seed: u64,
    from: u32,
    mut counts: Vec<BackFaces>,
) -> Vec<bool> {
    for (start, end) in [(0, VALIDITY_PROBE), (VALIDITY_PROBE, VALIDITY_RAYS)] {
        let start = start.max(from);
        if start >= end {
            continue;
        }
        for_each_receiver_query::<Closest, BackFaces>(
            tracer,
            &mut counts,
            256,
            |r, count, batch| {
                let rays = ReceiverRays::new(receivers, r, seed);
                for i in (start..end).take_while(|&i| count.counts(i)) {
                    let d = rays.direction(i);
                    if d.dot(rays.geo_normal) > 0.0 {
                        batch.push(rays.origin, d, max_distance);
                    }
                }
            },
            |_, count, directions, hits| {
                for (&d, hit) in directions.iter().zip(hits) {
                    count.add(hit.is_some_and(|h| tracer.is_back_face(h, d)));
                }
            },
            &|_| {},
        );
    }
    counts.iter().map(BackFaces::inside).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec3, Vec3A};

    /// An axis-aligned box with outward (counter-clockwise) faces.
    fn closed_box(lo: Vec3, hi: Vec3) -> Vec<[Vec3A; 3]> {
        let c = |x: usize, y: usize, z: usize| {
            Vec3A::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
        };
        let quads = [
            [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -z
            [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +z
            [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -y
            [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +y
            [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -x
            [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +x
        ];
        quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect()
    }

    fn one_receiver(p: Vec3) -> Receivers {
        Receivers {
            width: 1,
            height: 1,
            texel: vec![0],
            position: vec![p],
            normal: vec![Vec3::Z],
            geo_normal: vec![Vec3::Z],
            footprint: vec![1e-3],
            ..Default::default()
        }
    }

    #[test]
    fn box_faces_point_outward() {
        for t in closed_box(Vec3::ZERO, Vec3::ONE) {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            let centre = (t[0] + t[1] + t[2]) / 3.0 - Vec3A::splat(0.5);
            assert!(n.dot(centre) > 0.0);
        }
    }

    #[test]
    fn inside_a_single_sided_box_but_not_outside_or_double_sided() {
        let tris = closed_box(Vec3::new(-0.1, -0.1, -0.1), Vec3::new(0.1, 0.1, 0.1));
        let single = vec![true; tris.len()];
        let tracer = Tracer::with_sides(&tris, &single);
        // Inside: every ray reaches a back face.
        assert!(inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 1.0, 0)[0]);
        // Outside, looking at the box's front faces, or at nothing.
        assert!(!inside_geometry(&one_receiver(Vec3::new(0.0, 0.0, 0.2)), &tracer, 1.0, 0)[0]);
        assert!(!inside_geometry(&one_receiver(Vec3::new(0.0, 0.0, -0.3)), &tracer, 1.0, 0)[0]);
        // Beyond the max distance nothing counts.
        assert!(!inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 0.05, 0)[0]);
        // Double-sided: back faces are real surfaces.
        let tracer = Tracer::with_sides(&tris, &vec![false; tris.len()]);
        assert!(!inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 1.0, 0)[0]);
    }
}
