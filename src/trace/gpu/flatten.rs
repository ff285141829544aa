//! The BVH as the GPU reads it.
//!
//! In: bake-space occluder triangles. Out: [`FlatBvh`]: obvhs's BVH2 (a
//! binary tree, the layout a compute shader walks with a short stack: the
//! `tray_racing` benchmark's compute traversal uses it) as 32-byte nodes,
//! the triangles in leaf order with their indices among the occluders, and
//! the tree's depth, which bounds the shader's stack.

use crate::trace::ray::{build_params, triangles};
use bytemuck::{Pod, Zeroable};
use glam::Vec3A;
use obvhs::{bvh2::builder::build_bvh2_from_tris, rt_triangle::RtTriangle};
use std::time::Duration;

/// A node as the shader reads it (`Node` in traverse.wgsl): its box, and
/// either its first child (`count` 0; the second is the next node) or its
/// first triangle and triangle count (a leaf).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuNode {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

/// A triangle as the shader reads it (`Tri`): obvhs's `RtTriangle`, the
/// CPU backend's, value for value (its base vertex, edges `v0 - v1` and
/// `v2 - v0`, and their cross product), each padded to 16 bytes, so that
/// the shader's test rounds as the CPU's does.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuTri {
    pub v0: [f32; 4],
    pub e1: [f32; 4],
    pub e2: [f32; 4],
    pub ng: [f32; 4],
}

impl GpuTri {
    /// The triangle's three vertices (`v0`, `v0 - e1`, `v0 + e2`).
    pub fn vertices(&self) -> [[f32; 3]; 3] {
        let (v0, e1, e2) = (self.v0, self.e1, self.e2);
        [
            [v0[0], v0[1], v0[2]],
            [v0[0] - e1[0], v0[1] - e1[1], v0[2] - e1[2]],
            [v0[0] + e2[0], v0[1] + e2[1], v0[2] + e2[2]],
        ]
    }
}

/// The flattened tree.
pub struct FlatBvh {
    pub nodes: Vec<GpuNode>,
    pub tris: Vec<GpuTri>,
    /// Per triangle in leaf order, its index among the occluders given.
    pub primitives: Vec<u32>,
    /// The longest root-to-leaf path, in nodes below the root: the most
    /// entries the traversal's stack holds.
    pub depth: u32,
}

/// How much each box grows, relative to its longest side: twice the
/// shader's barycentric margin (`BARY_MARGIN` in traverse.wgsl). A ray the
/// CPU's test counts as a hit can pass outside the triangle by its
/// rounding, so outside the triangle's exact box (a wall's box is flat);
/// the shader tests triangles with a margin, and its boxes must hold it.
const BOX_MARGIN: f32 = 2e-4;

/// And at least this much (bake units; the scene's diagonal is 1).
const BOX_FLOOR: f32 = 1e-7;

/// Builds obvhs's BVH2 over `occluders` (the same presets as the CPU's
/// CWBVH) and flattens it; `None` without triangles.
pub fn flatten(occluders: &[[Vec3A; 3]]) -> Option<FlatBvh> {
    if occluders.is_empty() {
        return None;
    }
    let tris = triangles(occluders);
    let bvh = build_bvh2_from_tris(&tris, build_params(tris.len()), &mut Duration::default());
    let nodes: Vec<GpuNode> = bvh
        .nodes
        .iter()
        .map(|n| {
            // Grown by the shader's margin around its triangles (see
            // BOX_MARGIN), relative to the box, so a parent's growth holds
            // its children's.
            let (lo, hi) = (n.aabb.min, n.aabb.max);
            let grow = Vec3A::splat(BOX_MARGIN * (hi - lo).max_element() + BOX_FLOOR);
            GpuNode {
                lo: (lo - grow).into(),
                first: n.first_index,
                hi: (hi + grow).into(),
                count: n.prim_count,
            }
        })
        .collect();
    let tris = bvh
        .primitive_indices
        .iter()
        .map(|&i| {
            let t = RtTriangle::from(&tris[i as usize]);
            let p = |v: Vec3A| [v.x, v.y, v.z, 0.0];
            GpuTri {
                v0: p(t.v0),
                e1: p(t.e1),
                e2: p(t.e2),
                ng: p(t.ng),
            }
        })
        .collect();
    let depth = depth(&nodes);
    Some(FlatBvh {
        nodes,
        tris,
        primitives: bvh.primitive_indices,
        depth,
    })
}

/// The tree's depth below the root (0 for a root leaf), walked without
/// recursion.
fn depth(nodes: &[GpuNode]) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, d)) = stack.pop() {
        deepest = deepest.max(d);
        let n = nodes[i];
        if n.count == 0 {
            stack.push((n.first as usize, d + 1));
            stack.push((n.first as usize + 1, d + 1));
        }
    }
    deepest
}
