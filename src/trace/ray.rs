//! What every backend shares: batches of rays, the ray the CPU traces for
//! a query, the raw closest-hit answer, and the trees' inputs.
//!
//! In: per ray an origin, a unit direction and a max distance, or a
//! *blocked* ray (a receiver's direction below its own surface, occluded
//! by definition and traced by no backend; it keeps its place so the
//! answers line up with the receiver's sequence); occluder triangles.
//! Out: [`RayBatch`]; obvhs's [`Ray`] shifted back as the CPU backend
//! traces it (and the GPU backend uploads); [`Hit`]; obvhs's triangles and
//! build preset. Neither backend imports the other: both import this.

use glam::{Vec3, Vec3A};
use obvhs::{BvhBuildParams, ray::Ray, triangle::Triangle};

/// A closest-hit answer as traversed: the hit's parameter along the
/// shifted ray (cut at the depth asked, see [`Tracer::trace_closest`](super::Tracer::trace_closest)) and
/// its triangle (in leaf order). Kept raw so that an answer traced with a
/// cut at one depth gives, exactly, what a query cut at any smaller depth
/// would have returned ([`Hit::distance_within`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub(crate) shifted: f32,
    pub(crate) triangle: u32,
}

impl Hit {
    /// Where a ray of max distance `t_max` cut at `depth` is cut, along
    /// the shifted ray. (min/max, not clamp: no panic on a NaN or negative
    /// t_max.)
    #[inline]
    pub(crate) fn cap(t_max: f32, depth: f32) -> f32 {
        depth.min(t_max).max(0.0) + BOX_EPSILON_SHIFT
    }

    /// The hit's distance from the origin when it is below `depth`, else
    /// `depth` (`depth` in [0, t_max]): what a query cut at `depth`
    /// returns, for any `depth` up to the one the ray was traced with.
    #[inline]
    pub fn distance_within(self, t_max: f32, depth: f32) -> f32 {
        if self.shifted >= Hit::cap(t_max, depth) {
            depth.min(t_max).max(0.0)
        } else {
            self.shifted - BOX_EPSILON_SHIFT
        }
    }
}

/// obvhs's CWBVH node test clamps a box's entry distance to an absolute
/// 1e-4 (`EPSILON` in obvhs 0.4 `cwbvh/node.rs`, marked "ray.tmin?"), so it
/// culls every box a ray leaves before t = 1e-4 and loses hits closer than
/// that: 1e-4 of the scene diagonal in bake space, e.g. a box resting 3 mm
/// under a slab in Sponza. Rays therefore start this far behind their origin,
/// with t_min at the same distance: boxes are entered after the clamp, and
/// the triangle test's t_min still excludes everything behind the origin.
pub(crate) const BOX_EPSILON_SHIFT: f32 = 2e-4;

/// How near the ray's start a hit leaves [`Settle::retest`] to the
/// traversal (bake units): origins lying on another surface, hit at
/// distances of 1e-8, which the traversal missed where the test hit
/// (a few rays from border-fit points in Sponza's bake); far below any
/// modelled gap ([`crate::trace::ORIGIN_OFFSET`] is 2e-6).
///
/// [`Settle::retest`]: super::Settle::retest
pub(crate) const AT_START: f32 = 1e-7;

/// The ray the CPU traces for a query from `origin` along `dir` up to
/// `t_max` (the GPU backend traces the same one).
#[inline]
pub(crate) fn shifted_ray(origin: Vec3, dir: Vec3, t_max: f32) -> Ray {
    let dir = positive_zeros(dir);
    Ray::new(
        (origin - dir * BOX_EPSILON_SHIFT).into(),
        dir.into(),
        BOX_EPSILON_SHIFT,
        t_max + BOX_EPSILON_SHIFT,
    )
}

/// The occluders as obvhs's triangles.
pub(crate) fn triangles(occluders: &[[Vec3A; 3]]) -> Vec<Triangle> {
    occluders
        .iter()
        .map(|t| Triangle {
            v0: t[0],
            v1: t[1],
            v2: t[2],
        })
        .collect()
}

/// obvhs's build preset for `count` triangles (both backends' trees):
/// `very_slow` (slower build, faster traversal) pays off at millions of
/// rays, which a scene of this size gets.
pub(crate) fn build_params(count: usize) -> BvhBuildParams {
    if count > 20_000 {
        BvhBuildParams::very_slow_build()
    } else {
        BvhBuildParams::medium_build()
    }
}

/// Turns -0.0 components into +0.0: obvhs picks the traversal octant from
/// the sign bits while its inverse direction treats -0.0 as +0.0, and a
/// ray along -z with -0.0 x and y components then misses everything.
#[inline]
fn positive_zeros(d: Vec3) -> Vec3 {
    d + Vec3::ZERO
}

/// Rays traced together: structure of arrays, a GPU's upload as it is.
#[derive(Clone, Debug, Default)]
pub struct RayBatch {
    pub(crate) origins: Vec<Vec3>,
    pub(crate) directions: Vec<Vec3>,
    /// Max distance per ray; negative: a blocked ray.
    pub(crate) t_max: Vec<f32>,
    /// Per ray, the depth a closest-hit query may cut it at (t_max: none).
    pub(crate) depth: Vec<f32>,
}

impl RayBatch {
    pub fn new() -> RayBatch {
        RayBatch::default()
    }

    /// A ray from `origin` along unit `direction`, asking for hits in
    /// (0, t_max] (a NaN or negative `t_max` asks for none).
    #[inline]
    pub fn push(&mut self, origin: Vec3, direction: Vec3, t_max: f32) {
        self.push_within(origin, direction, t_max, t_max);
    }

    /// A ray whose closest hit is only needed exactly up to `depth` (see
    /// [`Tracer::trace_closest`](super::Tracer::trace_closest)); occlusion queries ignore the depth.
    #[inline]
    pub fn push_within(&mut self, origin: Vec3, direction: Vec3, t_max: f32, depth: f32) {
        self.origins.push(origin);
        self.directions.push(direction);
        self.t_max.push(if t_max >= 0.0 { t_max } else { 0.0 });
        self.depth.push(depth);
    }

    /// A blocked ray: occluded without tracing (a direction at or below
    /// the receiver's geometric plane enters its own surface).
    #[inline]
    pub fn push_blocked(&mut self, direction: Vec3) {
        self.origins.push(Vec3::ZERO);
        self.directions.push(direction);
        self.t_max.push(-1.0);
        self.depth.push(-1.0);
    }

    pub fn len(&self) -> usize {
        self.t_max.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t_max.is_empty()
    }

    pub fn clear(&mut self) {
        self.origins.clear();
        self.directions.clear();
        self.t_max.clear();
        self.depth.clear();
    }

    /// The rays' directions, in the order they were pushed.
    pub fn directions(&self) -> &[Vec3] {
        &self.directions
    }

    pub fn origins(&self) -> &[Vec3] {
        &self.origins
    }

    /// Max distances; negative for a blocked ray.
    pub fn t_max(&self) -> &[f32] {
        &self.t_max
    }

    /// Per ray, the depth a closest-hit query may cut it at.
    pub fn depths(&self) -> &[f32] {
        &self.depth
    }

    /// Whether ray `i` is blocked (occluded without tracing).
    #[inline]
    pub fn is_blocked(&self, i: usize) -> bool {
        self.t_max[i] < 0.0
    }
}
