//! The bake-space scene: what the atlas, the tracer and the bake see of a
//! loaded file, with no glTF syntax left (the layer below the atlas; the
//! glTF reader builds it, the writer reads it back).
//!
//! In: built by `gltf::Scene::bake_geometry`. Out: [`BakeGeometry`]: the
//! [`BakeSpace`] map (world recentred on the scene's bounding box and divided
//! by its diagonal, so everything below works at unit scale whatever the
//! file's units), every occluder triangle, and one [`ReceiverMesh`] per baked
//! placement.

use glam::{DVec3, Vec3, Vec3A};

/// The uniform map from world space to bake space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BakeSpace {
    pub center: DVec3,
    /// World length of the scene's bounding-box diagonal; bake-space unit.
    pub diagonal: f64,
}

impl BakeSpace {
    pub fn to_bake(&self, p: DVec3) -> Vec3 {
        ((p - self.center) / self.diagonal).as_vec3()
    }

    /// The world position of bake-space `p` (the inverse of [`Self::to_bake`],
    /// in single precision, as receivers are stored).
    pub fn to_world(&self, p: Vec3) -> Vec3 {
        self.center.as_vec3() + p * self.diagonal as f32
    }

    /// `[centre x, y, z, unit]`: how an output's fingerprint and a shard's
    /// partial record it ([`Self::from_array`] reads it back).
    pub fn to_array(&self) -> [f64; 4] {
        let c = self.center;
        [c.x, c.y, c.z, self.diagonal]
    }

    pub fn from_array([x, y, z, diagonal]: [f64; 4]) -> BakeSpace {
        BakeSpace {
            center: DVec3::new(x, y, z),
            diagonal,
        }
    }
}

/// A baked placement in bake space, ready to unwrap and rasterize.
#[derive(Debug, Clone)]
pub struct ReceiverMesh {
    /// Index of the placement it comes from (the loader's `Scene::instances`).
    pub instance: usize,
    /// Positions in bake space.
    pub positions: Vec<[f32; 3]>,
    /// The same without the placement's translation (its linear part
    /// applied to the mesh's positions, over the bake unit): what the
    /// unwrap reads, so that a mesh moved by a translation unwraps into
    /// the same charts to the bit (`--reuse`).
    pub shape: Vec<[f32; 3]>,
    /// Unit world-space normals, if the primitive has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Triangle list indexing `positions` (same as the primitive's).
    pub triangles: Vec<u32>,
    /// The transform mirrors (negative determinant): winding is flipped.
    pub mirrored: bool,
}

impl ReceiverMesh {
    /// Its triangles' total area (bake units; non-finite ones left out).
    pub fn surface_area(&self) -> f64 {
        (self.triangles.chunks_exact(3))
            .map(|t| {
                let p = [t[0], t[1], t[2]].map(|i| glam::Vec3::from(self.positions[i as usize]));
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64
            })
            .filter(|a: &f64| a.is_finite())
            .sum()
    }
}

/// All geometry of a scene in bake space.
#[derive(Debug, Clone)]
pub struct BakeGeometry {
    pub space: BakeSpace,
    /// Every non-degenerate triangle of every instance (occluders), wound
    /// so that its front face is counter-clockwise in bake space (mirroring
    /// placements are flipped back).
    pub occluders: Vec<[Vec3A; 3]>,
    /// Per occluder: its material is single-sided, so a ray reaching its
    /// back face comes from inside or behind geometry.
    pub occluder_single_sided: Vec<bool>,
    pub receivers: Vec<ReceiverMesh>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bake_space_round_trips() {
        let s = BakeSpace {
            center: DVec3::new(10.0, -2.0, 3.5),
            diagonal: 40.0,
        };
        let w = DVec3::new(12.0, 0.5, -1.0);
        let back = s.to_world(s.to_bake(w));
        assert!((back.as_dvec3() - w).length() < 1e-5, "{back}");
        assert_eq!(s.to_world(Vec3::ZERO), s.center.as_vec3());
    }
}
