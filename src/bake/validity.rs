//! Validity: receivers inside or behind geometry.
//!
//! In: [`Receivers`], a [`Tracer`] that knows which triangles are
//! single-sided, the max distance. Out: per receiver, whether it is
//! *inside*: most of its hemisphere's closest hits are back faces of
//! single-sided triangles. Such texels (a floor running through a wall, the
//! floor under a box resting on it, geometry intersecting geometry) are
//! never seen, but baked they are black and bilinear filtering bleeds that
//! into visible texels; the output fills them from their nearest valid
//! texel instead (see [`crate::atlas::dilate`]).
//!
//! Each receiver casts up to [`VALIDITY_RAYS`] closest-hit rays (its own
//! scrambled sequence, cosine-weighted); after the first
//! [`VALIDITY_PROBE`] a receiver that saw no back face stops, so texels in
//! the open cost a few rays.

use super::ReceiverRays;
use crate::atlas::Receivers;
use crate::trace::Tracer;
use rayon::prelude::*;

/// Rays per receiver, at most.
pub const VALIDITY_RAYS: u32 = 16;
/// Rays cast before a receiver that saw no back face stops.
pub const VALIDITY_PROBE: u32 = 4;
/// A receiver is inside when at least this fraction of its rays (above its
/// geometric horizon) reach back faces.
pub const INSIDE_FRACTION: f32 = 0.5;

/// Per receiver: inside geometry (see the module doc).
pub fn inside_geometry(receivers: &Receivers, tracer: &Tracer, max_distance: f32) -> Vec<bool> {
    (0..receivers.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|r| receiver_inside(receivers, tracer, max_distance, r))
        .collect()
}

fn receiver_inside(receivers: &Receivers, tracer: &Tracer, max_distance: f32, r: usize) -> bool {
    let rays = ReceiverRays::with_stream(receivers, r, 0x7a11d, 3);
    let (mut traced, mut back) = (0u32, 0u32);
    for i in 0..VALIDITY_RAYS {
        if i == VALIDITY_PROBE && back == 0 {
            return false;
        }
        let d = rays.direction(i);
        if d.dot(rays.geo_normal) <= 0.0 {
            continue;
        }
        traced += 1;
        back += (tracer.back_face_hit(rays.origin, d, max_distance) == Some(true)) as u32;
    }
    traced > 0 && back as f32 >= INSIDE_FRACTION * traced as f32
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
        assert!(inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 1.0)[0]);
        // Outside, looking at the box's front faces, or at nothing.
        assert!(!inside_geometry(&one_receiver(Vec3::new(0.0, 0.0, 0.2)), &tracer, 1.0)[0]);
        assert!(!inside_geometry(&one_receiver(Vec3::new(0.0, 0.0, -0.3)), &tracer, 1.0)[0]);
        // Beyond the max distance nothing counts.
        assert!(!inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 0.05)[0]);
        // Double-sided: back faces are real surfaces.
        let tracer = Tracer::with_sides(&tris, &vec![false; tris.len()]);
        assert!(!inside_geometry(&one_receiver(Vec3::ZERO), &tracer, 1.0)[0]);
    }
}
