//! Signal: how finely each receiver mesh's occlusion varies, for
//! `--texel-budget signal` (texels where the signal needs them).
//!
//! In: the [`ReceiverMesh`]es (bake space), the [`Tracer`], the max
//! distance, the texel edge a uniform atlas would have (bake units) and the
//! seed. Out: per mesh a scale of its texel density ([`mesh_scales`]),
//! which the unwrap ([`crate::atlas::unwrap`]) applies to the mesh before
//! packing, so that one page's
//! texels go where the occlusion has detail.
//!
//! Why z_min: occlusion at a point varies over lengths about the distance
//! to its nearest occluder (the adaptive method's bandwidth rests on the
//! same fact, Mehta et al. 2012), so a mesh whose points see occluders
//! close by (a strap lying on a shell, a moulding against a wall) has
//! detail at that scale and a mesh open to the sky has none. With texel
//! edge h on a mesh, a bilinear reconstruction's squared error there grows
//! as (h / z)^2 per unit area (z floored at half a texel: finer detail is
//! one texel's step whatever the density); minimising the sum over meshes
//! of A_m h_m^2 <1/z^2>_m under a fixed count of texels Sum A_m / h_m^2
//! gives h_m proportional to <1/z^2>_m^(-1/4): the mesh's density scale is
//! the fourth root of its area-weighted mean of 1/z^2. Scales are relative
//! (the packer fits the page), kept within [`MAX_RATIO`] of each other's
//! area-weighted geometric mean.
//!
//! The pre-pass: [`RAYS`] cosine-distributed rays from the centroid of
//! each triangle (at most [`MAX_POINTS`] triangles over the scene, evenly
//! strided), each its own sequence, z the nearest hit within the max
//! distance (none: the max distance).

use crate::atlas::Receivers;
use crate::bake::ReceiverRays;
use crate::geometry::ReceiverMesh;
use crate::trace::{Closest, Tracer, for_each_receiver_query};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// How one page's texels are shared among the meshes (`--texel-budget`):
/// `Uniform`, the same texels per world unit everywhere; `Signal`, each
/// mesh's density scaled by how finely its occlusion varies
/// ([`mesh_scales`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum TexelBudget {
    #[default]
    Uniform,
    Signal,
}

impl TexelBudget {
    pub fn is_uniform(&self) -> bool {
        *self == TexelBudget::Uniform
    }
}

/// Points to a batch of rays.
const CHUNK: usize = 256;

/// Rays per pre-pass point.
pub const RAYS: u32 = 16;

/// Most pre-pass points over the scene.
pub const MAX_POINTS: usize = 200_000;

/// Largest density scale against the area-weighted geometric mean, and
/// the inverse of the smallest.
pub const MAX_RATIO: f32 = 2.0;

/// Mixed into the pre-pass's seed.
const SIGNAL_SEED: u64 = 0x5197_a1b0;

/// Per mesh of `meshes`, the scale of its texel density (1: uniform).
/// `texel`: the texel edge (bake units) of a uniform atlas, which floors
/// z; `max_distance`: the occluders' reach (bake units).
pub fn mesh_scales(
    meshes: &[ReceiverMesh],
    tracer: &Tracer,
    max_distance: f32,
    texel: f32,
    seed: u64,
) -> Vec<f32> {
    // Triangles: (mesh, centroid, unit normal, area).
    let mut points: Vec<(u32, Vec3, Vec3, f32)> = Vec::new();
    let total: usize = meshes.iter().map(|m| m.triangles.len() / 3).sum();
    let stride = total.div_ceil(MAX_POINTS).max(1);
    let mut k = 0usize;
    for (mi, m) in meshes.iter().enumerate() {
        for t in m.triangles.chunks_exact(3) {
            k += 1;
            if !k.is_multiple_of(stride) {
                continue;
            }
            let p = [t[0], t[1], t[2]].map(|i| Vec3::from(m.positions[i as usize]));
            let cross = (p[1] - p[0]).cross(p[2] - p[0]);
            let area = 0.5 * cross.length();
            if !(area.is_finite() && area > 0.0) {
                continue;
            }
            // The front face is counter-clockwise, flipped where mirrored.
            let geo = if m.mirrored { -cross } else { cross }.normalize();
            let shading = m.normals.as_ref().map_or(geo, |n| {
                let s: Vec3 = t.iter().map(|&i| Vec3::from(n[i as usize])).sum();
                let s = s.normalize_or_zero();
                if s == Vec3::ZERO { geo } else { s }
            });
            let geo = if geo.dot(shading) < 0.0 { -geo } else { geo };
            points.push((mi as u32, (p[0] + p[1] + p[2]) / 3.0, geo, area));
        }
    }
    let mut r = Receivers::default();
    for (k, &(_, c, n, _)) in points.iter().enumerate() {
        r.texel.push(k as u32);
        r.position.push(c);
        r.normal.push(n);
        r.geo_normal.push(n);
        r.footprint.push(texel);
        r.center_inside.push(true);
    }
    let seed = seed ^ SIGNAL_SEED;
    let floor = 0.5 * texel;
    // Per point, z its nearest hit: each ray traced for its exact closest
    // hit and read as the query cut at the running z would answer
    // ([`crate::trace::Hit::distance_within`]), so the rays go as one batch.
    let mut z = vec![max_distance; points.len()];
    for_each_receiver_query::<Closest, f32>(
        tracer,
        &mut z,
        CHUNK,
        |i, _, batch| {
            let rays = ReceiverRays::new(&r, i, seed);
            for k in 0..RAYS {
                batch.push(rays.origin, rays.direction(k), max_distance);
            }
        },
        |_, z, _, hits| {
            for hit in hits.iter().flatten() {
                *z = z.min(hit.distance_within(max_distance, *z));
            }
        },
        &|_| {},
    );
    // 1 / z^2, z floored at half a texel.
    let inverse: Vec<f32> = z
        .iter()
        .map(|&z| 1.0 / (z.max(floor) * z.max(floor)))
        .collect();
    // Per mesh, the area-weighted mean of 1/z^2, to the fourth root.
    let mut sum = vec![(0.0f64, 0.0f64); meshes.len()];
    for (&(m, _, _, a), &q) in points.iter().zip(&inverse) {
        sum[m as usize].0 += a as f64 * q as f64;
        sum[m as usize].1 += a as f64;
    }
    let raw: Vec<f64> = sum
        .iter()
        .map(|&(q, a)| if a > 0.0 { (q / a).powf(0.25) } else { 0.0 })
        .collect();
    // Relative to the area-weighted geometric mean, within MAX_RATIO.
    let (log_sum, area): (f64, f64) = raw
        .iter()
        .zip(&sum)
        .filter(|(r, _)| **r > 0.0)
        .fold((0.0, 0.0), |(l, a), (r, s)| (l + s.1 * r.ln(), a + s.1));
    if area <= 0.0 {
        return vec![1.0; meshes.len()];
    }
    let mean = (log_sum / area).exp();
    raw.iter()
        .map(|&r| {
            if r > 0.0 {
                ((r / mean) as f32).clamp(1.0 / MAX_RATIO, MAX_RATIO)
            } else {
                1.0
            }
        })
        .collect()
}
