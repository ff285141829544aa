//! The CPU backend: one BVH over every occluder triangle.
//!
//! In: bake-space triangles. Out: a [`Tracer`] answering one ray at a time:
//! occlusion (any hit closer than `t_max`) and closest-hit queries. Both
//! faces occlude. Built with obvhs as a compressed wide BVH (CWBVH) with
//! triangles stored in leaf order, so traversal has no indirection. The
//! passes reach it through [`super::batch`], which offers whole batches to
//! an attached accelerator ([`super::backend`]) first.

use super::backend::{Accelerator, Settle};
use super::ray::{AT_START, BOX_EPSILON_SHIFT, Hit, build_params, shifted_ray, triangles};
use glam::{Vec3, Vec3A};
use obvhs::{
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::RayHit,
    rt_triangle::RtTriangle,
};
use std::time::Duration;

/// Ray-tracing acceleration structure over the scene's occluders.
pub struct Tracer {
    bvh: Option<CwBvh>,
    tris: Vec<RtTriangle>,
    /// Per triangle in leaf order: single-sided (its back face is "inside").
    single_sided: Vec<bool>,
    /// The device answering the batches, if one is attached.
    accelerator: Option<Box<dyn Accelerator>>,
}

impl Tracer {
    /// Builds the BVH (`very_slow` preset: slower build, faster traversal,
    /// which pays off at millions of rays).
    pub fn new(occluders: &[[Vec3A; 3]]) -> Tracer {
        Tracer::with_sides(occluders, &[])
    }

    /// [`Tracer::new`] that also knows which triangles are single-sided
    /// (`single_sided[i]` for `occluders[i]`; missing entries are
    /// double-sided), for [`Tracer::is_back_face`].
    pub fn with_sides(occluders: &[[Vec3A; 3]], single_sided: &[bool]) -> Tracer {
        if occluders.is_empty() {
            return Tracer {
                bvh: None,
                tris: Vec::new(),
                single_sided: Vec::new(),
                accelerator: None,
            };
        }
        let tris = triangles(occluders);
        let bvh = build_cwbvh_from_tris(&tris, build_params(tris.len()), &mut Duration::default());
        let rt = bvh
            .primitive_indices
            .iter()
            .map(|&i| RtTriangle::from(&tris[i as usize]))
            .collect();
        let sides = bvh
            .primitive_indices
            .iter()
            .map(|&i| single_sided.get(i as usize).copied().unwrap_or(false))
            .collect();
        Tracer {
            bvh: Some(bvh),
            tris: rt,
            single_sided: sides,
            accelerator: None,
        }
    }

    /// Hands the batches ([`Tracer::trace_batch`]: occlusion and closest
    /// hits) to `accelerator`, which holds the same occluders; the per-ray
    /// queries stay here.
    pub fn attach(&mut self, accelerator: Box<dyn Accelerator>) {
        self.accelerator = Some(accelerator);
    }

    /// The attached accelerator, if any.
    pub fn accelerator(&self) -> Option<&dyn Accelerator> {
        self.accelerator.as_deref()
    }

    /// Per triangle in this tracer's leaf order (as [`Hit`]s and
    /// [`Settle::retest`](super::Settle::retest) name them), its index among the occluders given.
    pub fn leaf_order(&self) -> &[u32] {
        self.bvh.as_ref().map_or(&[][..], |b| &b.primitive_indices)
    }

    /// The name of the device answering the batches, if one is attached.
    pub fn accelerator_name(&self) -> Option<&str> {
        self.accelerator().map(|a| a.name())
    }

    /// With an accelerator attached, the rays of the batches it answered
    /// and those the CPU answered instead (the device busy, or failed).
    pub fn accelerated_rays(&self) -> Option<(u64, u64)> {
        self.accelerator().map(|a| a.rays())
    }

    /// Why the accelerator stopped answering, if a batch failed (the rest
    /// were traced here).
    pub fn accelerator_failure(&self) -> Option<&str> {
        self.accelerator().and_then(|a| a.failure())
    }

    /// Whether any occluder triangle is single-sided: without one, no
    /// closest hit is ever a back face ([`Tracer::is_back_face`]), so the
    /// validity test has nothing to find.
    pub fn has_single_sided(&self) -> bool {
        self.single_sided.iter().any(|&s| s)
    }

    /// Number of occluder triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Whether a ray from `origin` along unit `dir` hits anything in (0, t_max].
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        let Some(bvh) = &self.bvh else { return false };
        let ray = shifted_ray(origin, dir, t_max);
        !bvh.ray_traverse_miss(ray, |r, id| self.tris[id].intersect(r))
    }

    /// Whether a receiver sees past `t_max` along unit `dir`, from `origin`
    /// (already lifted by `offset_origin`) on a surface with unit
    /// geometric normal `geo_normal`. A direction at or below the geometric
    /// tangent plane enters the surface itself, so it is occluded without
    /// tracing (shading normals send ~8% of Sponza's cosine-weighted rays
    /// there).
    #[inline]
    pub fn receiver_visible(&self, origin: Vec3, geo_normal: Vec3, dir: Vec3, t_max: f32) -> bool {
        dir.dot(geo_normal) > 0.0 && !self.occluded(origin, dir, t_max)
    }

    /// The one traversal the closest-hit queries share: the closest hit in
    /// (0, t_max], cut at `depth` ([`Hit`]). A hit found beyond `depth` is
    /// taken as a hit at `depth`, which shortens the ray there, so the rest
    /// of the traversal looks for closer hits only (then the triangle is
    /// the hit that cut the ray there). At `depth = t_max` nothing is cut:
    /// the ray ends there anyway.
    #[inline]
    pub fn trace_closest(&self, origin: Vec3, dir: Vec3, t_max: f32, depth: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let ray = shifted_ray(origin, dir, t_max);
        let cap = Hit::cap(t_max, depth);
        let mut hit = RayHit::none();
        bvh.ray_traverse(ray, &mut hit, |r, id| {
            // A miss is infinite; a hit beyond the cap becomes one at it.
            let t = self.tris[id].intersect(r);
            if t.is_finite() { t.min(cap) } else { t }
        })
        .then_some(Hit {
            shifted: hit.t,
            triangle: hit.primitive_id,
        })
    }

    /// Whether `hit`, of a ray along `dir` traced without a cut (depth =
    /// t_max), is the back face of a single-sided triangle. Front faces are
    /// counter-clockwise; obvhs stores `ng = (v0 - v1) x (v2 - v0)`, the
    /// negated front normal, so a back face has `ng . dir < 0`.
    #[inline]
    pub fn is_back_face(&self, hit: Hit, dir: Vec3) -> bool {
        let id = hit.triangle as usize;
        self.single_sided[id] && Vec3::from(self.tris[id].ng).dot(dir) < 0.0
    }

    /// The unit geometric normal of `hit`'s triangle (either side).
    #[inline]
    pub fn hit_normal(&self, hit: Hit) -> Vec3 {
        Vec3::from(self.tris[hit.triangle as usize].ng).normalize_or_zero()
    }

    /// Distance to the closest hit in (0, t_max], if any.
    #[inline]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<f32> {
        self.trace_closest(origin, dir, t_max, t_max)
            .map(|hit| hit.distance_within(t_max, t_max))
    }
}

impl Settle for Tracer {
    /// The hit [`Tracer::trace_closest`] returns when `triangle` (in leaf
    /// order) is the closest: its test on the same ray, cut at `depth`
    /// (for an accelerator settling what its device left open);
    /// `None` where the test misses it, or hits it at the ray's very start
    /// (within `AT_START` (1e-7) of it: an origin on another surface), where this
    /// tracer's traversal, whose boxes are entered from the start on, may
    /// not reach what its test would hit: the caller then asks the
    /// traversal.
    fn retest(
        &self,
        triangle: u32,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        depth: f32,
    ) -> Option<Hit> {
        let ray = shifted_ray(origin, dir, t_max);
        let t = self.tris.get(triangle as usize)?.intersect(&ray);
        if t <= BOX_EPSILON_SHIFT + AT_START {
            return None;
        }
        // The traversal's rules: a miss is infinite, a hit beyond the cap
        // one at it, and a hit counts below the ray's end only.
        let t = t.is_finite().then(|| t.min(Hit::cap(t_max, depth)))?;
        (t < ray.tmax).then_some(Hit {
            shifted: t,
            triangle,
        })
    }

    fn occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        Tracer::occluded(self, origin, dir, t_max)
    }

    fn trace_closest(&self, origin: Vec3, dir: Vec3, t_max: f32, depth: f32) -> Option<Hit> {
        Tracer::trace_closest(self, origin, dir, t_max, depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f32, half: f32) -> Vec<[Vec3A; 3]> {
        let p = |x: f32, y: f32| Vec3A::new(x, y, z);
        vec![
            [p(-half, -half), p(half, -half), p(half, half)],
            [p(-half, -half), p(half, half), p(-half, half)],
        ]
    }

    #[test]
    fn hits_both_faces_and_respects_t_max() {
        let t = Tracer::new(&quad(0.1, 0.2));
        // Off the quad's diagonal: obvhs's Moller-Trumbore test is not
        // watertight exactly on shared edges (measure zero for a baker).
        let o = Vec3::new(0.05, -0.03, 0.0);
        assert!(t.occluded(o, Vec3::Z, 1.0));
        assert!(t.occluded(o + Vec3::new(0.0, 0.0, 0.2), -Vec3::Z, 1.0));
        assert!(!t.occluded(o, Vec3::Z, 0.05));
        assert!(!t.occluded(o, -Vec3::Z, 1.0));
        let d = t.closest_hit(o, Vec3::Z, 1.0).unwrap();
        assert!((d - 0.1).abs() < 1e-6);
    }

    #[test]
    fn offset_origin_escapes_own_surface_at_grazing_angles() {
        use crate::trace::offset_origin;
        let t = Tracer::new(&quad(0.0, 0.5));
        for k in 1..200 {
            let x = 0.49 * (k as f32 / 200.0 - 0.5) * 2.0;
            let p = Vec3::new(x, x * 0.37, 0.0);
            let o = offset_origin(p, Vec3::Z, 1e-3);
            let dir = Vec3::new(1.0, 0.3, 1e-4).normalize();
            assert!(!t.occluded(o, dir, 2.0), "self-hit at {p}");
        }
    }

    #[test]
    fn directions_below_the_geometric_plane_are_occluded() {
        let t = Tracer::new(&[]);
        let n = Vec3::Z;
        assert!(t.receiver_visible(Vec3::ZERO, n, Vec3::new(0.0, 0.6, 0.8), 1.0));
        assert!(!t.receiver_visible(Vec3::ZERO, n, Vec3::new(0.0, 0.8, -0.6), 1.0));
        assert!(!t.receiver_visible(Vec3::ZERO, n, Vec3::Y, 1.0));
    }

    #[test]
    fn occluders_closer_than_the_bvh_epsilon_are_found() {
        // A slab 3e-5 above the origin, inside a scene of unit diagonal
        // (the BVH needs several levels: many small triangles).
        let mut tris = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (x, y) = (i as f32 / 40.0 - 0.5, j as f32 / 40.0 - 0.5);
                let p = |a: f32, b: f32| Vec3A::new(x + a / 40.0, y + b / 40.0, 3e-5);
                tris.push([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)]);
                tris.push([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
            }
        }
        let t = Tracer::new(&tris);
        for k in 0..100 {
            let o = Vec3::new(k as f32 * 0.0071 - 0.35, 0.1234 - k as f32 * 0.003, 0.0);
            let d = Vec3::new(0.3, -0.2, 1.0).normalize();
            assert!(t.occluded(o, d, 1.0), "ray {k} missed a slab 3e-5 away");
            let hit = t.closest_hit(o, d, 1.0).unwrap();
            assert!((hit - 3e-5 / d.z).abs() < 2e-6, "t = {hit}");
        }
    }

    /// A query cut at `depth`: the closest hit's distance below it, else
    /// `depth`.
    fn hit_depth_within(t: &Tracer, o: Vec3, d: Vec3, t_max: f32, depth: f32) -> Option<f32> {
        t.trace_closest(o, d, t_max, depth)
            .map(|hit| hit.distance_within(t_max, depth))
    }

    #[test]
    fn hit_depth_is_exact_below_the_asked_depth_and_the_depth_beyond() {
        // Two parallel quads at 0.1 and 0.3 above the origin.
        let mut tris = quad(0.1, 0.2);
        tris.extend(quad(0.3, 0.2));
        let t = &Tracer::new(&tris);
        let o = Vec3::new(0.05, -0.03, 0.0);
        let d = Vec3::new(0.1, 0.2, 1.0).normalize();
        let first = 0.1 / d.z;
        assert!((t.closest_hit(o, d, 1.0).unwrap() - first).abs() < 1e-6);
        // Below the depth: the closest hit, whatever the depth.
        for depth in [0.2f32, 0.5, 1.0, 7.0] {
            let h = hit_depth_within(t, o, d, 1.0, depth).unwrap();
            assert!((h - first).abs() < 1e-6, "depth {depth}: {h}");
        }
        // Beyond it: exactly the depth (a hit, its distance not asked).
        assert_eq!(hit_depth_within(t, o, d, 1.0, 0.05), Some(0.05));
        assert_eq!(hit_depth_within(t, o, d, 1.0, 0.0), Some(0.0));
        // Nothing within t_max: no hit, whatever the depth.
        assert_eq!(hit_depth_within(t, o, d, 0.09, 0.05), None);
        assert_eq!(hit_depth_within(t, o, -d, 1.0, 0.05), None);
        // Only the far quad in range from above the near one.
        let above = o + Vec3::new(0.0, 0.0, 0.2);
        let h = hit_depth_within(t, above, d, 1.0, 0.5).unwrap();
        assert!((h - 0.1 / d.z).abs() < 1e-6);
        assert_eq!(hit_depth_within(&Tracer::new(&[]), o, d, 1.0, 0.5), None);
        // A hit traced with a cut at one depth reads, at any shallower
        // depth, exactly what a query cut there returns (the batches trace
        // once at the deepest depth a pass may need).
        for from in [o, above] {
            let deep = t.trace_closest(from, d, 1.0, 0.5).unwrap();
            for depth in [0.0f32, 0.05, 0.1 / d.z, 0.2, 0.3, 0.5] {
                let read = deep.distance_within(1.0, depth);
                assert_eq!(
                    Some(read),
                    hit_depth_within(t, from, d, 1.0, depth),
                    "{depth}"
                );
            }
        }
    }

    #[test]
    fn knows_whether_any_triangle_is_single_sided() {
        let tris = quad(0.1, 0.2);
        assert!(!Tracer::new(&tris).has_single_sided());
        assert!(!Tracer::with_sides(&tris, &[false, false]).has_single_sided());
        assert!(Tracer::with_sides(&tris, &[false, true]).has_single_sided());
        assert!(!Tracer::with_sides(&[], &[true]).has_single_sided());
    }

    #[test]
    fn empty_scene_never_occludes() {
        let t = Tracer::new(&[]);
        assert!(!t.occluded(Vec3::ZERO, Vec3::Z, 1.0));
        assert!(t.closest_hit(Vec3::ZERO, Vec3::Z, 1.0).is_none());
    }
}
