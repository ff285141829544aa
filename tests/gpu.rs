//! The GPU backend (`trace::gpu`, feature `gpu`) against closed forms and
//! against the CPU backend, on whatever Vulkan adapter the machine has:
//! Mesa's lavapipe where there is no GPU (`.ci/run` installs
//! `mesa-vulkan-drivers`), which runs the same shader on the CPU.
//!
//! Without any Vulkan adapter the tests say so and pass, except under CI
//! (`CI` set) or with `AOBAKE_REQUIRE_TOOLS` set, where they fail.

mod common;

use aobake::trace::gpu::{Adapters, GpuTracer};
use aobake::trace::{RayBatch, Tracer};
use glam::{Vec3, Vec3A};

/// A tracer on any adapter, or `None` (with the note) where there is none.
fn gpu(occluders: &[[Vec3A; 3]]) -> Option<GpuTracer> {
    match GpuTracer::new(occluders, Adapters::Any) {
        Ok(t) => Some(t.expect("triangles given")),
        Err(e) => {
            let missing = format!("a Vulkan adapter (mesa-vulkan-drivers for lavapipe): {e}");
            assert!(!common::tools_present("the GPU tests", &[missing.as_str()]));
            None
        }
    }
}

/// A unit quad in the plane z = h, centred on the z axis.
fn quad(h: f32) -> Vec<[Vec3A; 3]> {
    let p = |x: f32, y: f32| Vec3A::new(x, y, h);
    vec![
        [p(-0.5, -0.5), p(0.5, -0.5), p(0.5, 0.5)],
        [p(-0.5, -0.5), p(0.5, 0.5), p(-0.5, 0.5)],
    ]
}

/// Straight up to a quad at z = 0.2 over |x| < 0.5 from (x, 0.13, 0):
/// occluded exactly where |x| < 0.5 and t_max >= 0.2; blocked rays are
/// occluded, a NaN or negative max distance asks for nothing.
#[test]
fn occlusion_is_what_the_geometry_says() {
    let Some(gpu) = gpu(&quad(0.2)) else { return };
    let mut rays = RayBatch::new();
    let mut expected = Vec::new();
    for k in 0..10_000 {
        let x = -1.0 + 2.0 * (k as f32 + 0.5) / 10_000.0;
        let t_max = if k % 3 == 0 { 0.1 } else { 1.0 };
        // Downwards from above too: the quad's back face occludes.
        let (o, d) = if k % 2 == 0 {
            (Vec3::new(x, 0.13, 0.0), Vec3::Z)
        } else {
            (Vec3::new(x, 0.13, 0.4), -Vec3::Z)
        };
        rays.push(o, d, t_max);
        expected.push(x.abs() < 0.5 && t_max > 0.2);
    }
    rays.push_blocked(-Vec3::Z);
    expected.push(true);
    rays.push(Vec3::ZERO, Vec3::Z, f32::NAN);
    expected.push(false);
    rays.push(Vec3::ZERO, Vec3::Z, -1.0);
    expected.push(false);
    let mut out = Vec::new();
    gpu.occluded_batch(&rays, &mut out).unwrap();
    assert_eq!(out, expected, "on {:?}", gpu.adapter());
}

/// Watertight: from inside a closed octahedron every ray hits, those aimed
/// exactly at its vertices and along its edges included, where a
/// non-watertight test lets rays slip between the triangles.
#[test]
fn no_ray_slips_between_triangles() {
    let v = [
        Vec3A::X,
        -Vec3A::X,
        Vec3A::Y,
        -Vec3A::Y,
        Vec3A::Z,
        -Vec3A::Z,
    ];
    let mut faces = Vec::new();
    for &(a, b) in &[(0, 2), (2, 1), (1, 3), (3, 0)] {
        faces.push([v[a], v[b], v[4]]);
        faces.push([v[b], v[a], v[5]]);
    }
    let scale = 0.3;
    let faces: Vec<[Vec3A; 3]> = faces.iter().map(|f| f.map(|p| p * scale)).collect();
    let Some(gpu) = gpu(&faces) else { return };
    let mut rays = RayBatch::new();
    let origin = Vec3::new(0.0, 0.0, 0.0);
    let mut aims: Vec<Vec3> = v.iter().map(|&p| Vec3::from(p)).collect();
    for (a, b) in [
        (0, 2),
        (2, 1),
        (1, 3),
        (3, 0),
        (0, 4),
        (1, 4),
        (2, 5),
        (3, 5),
    ] {
        aims.push(Vec3::from(v[a] + v[b]).normalize());
    }
    // And a dense sweep across the edge from +X to +Y at z = 0.
    for k in 0..=1000 {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 / 1000.0;
        aims.push(Vec3::new(a.cos(), a.sin(), 0.0));
    }
    for d in &aims {
        rays.push(origin, *d, 1.0);
    }
    let mut out = Vec::new();
    gpu.occluded_batch(&rays, &mut out).unwrap();
    let slipped: Vec<Vec3> = aims
        .iter()
        .zip(&out)
        .filter(|(_, hit)| !**hit)
        .map(|(d, _)| *d)
        .collect();
    assert!(
        slipped.is_empty(),
        "{} rays slipped: {slipped:?}",
        slipped.len()
    );
}

/// A real scene's rays answered as the CPU answers them: rays from points
/// inside the flight helmet's bounds in every direction, at max distances
/// from contact to past the scene; at least 99.99% agree (the rest lie
/// within a hair of a triangle's edge or of the max distance, where the two
/// triangle tests round differently).
#[test]
fn a_scene_occludes_as_on_the_cpu() {
    let scene = common::bundled_scene("flight_helmet.glb");
    let geometry = scene.bake_geometry().unwrap();
    let Some(gpu) = gpu(&geometry.occluders) else {
        return;
    };
    let cpu = Tracer::new(&geometry.occluders);
    let mut rays = RayBatch::new();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = 200_000;
    for _ in 0..n {
        let o = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.6;
        let z = 2.0 * next() - 1.0;
        let phi = std::f32::consts::TAU * next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let t_max = [0.001, 0.01, 0.1, 1.0, 3.0][(next() * 5.0) as usize % 5];
        rays.push(o, d, t_max);
    }
    let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
    gpu.occluded_batch(&rays, &mut on_gpu).unwrap();
    cpu.occluded_batch(&rays, &mut on_cpu);
    let occluded = on_cpu.iter().filter(|&&h| h).count();
    let differ = on_gpu.iter().zip(&on_cpu).filter(|(a, b)| a != b).count();
    eprintln!(
        "{} rays, {occluded} occluded on the CPU, {differ} answered otherwise on {:?}",
        n,
        gpu.adapter()
    );
    // Both answers occur often: the comparison means something.
    assert!(occluded > n / 10 && occluded < n * 9 / 10, "{occluded}");
    assert!(differ * 10_000 <= n, "{differ} of {n} differ");
}

/// Which adapters count: a software one (lavapipe) is no hardware GPU, so
/// where it is all there is, asking for hardware is a clear error.
#[test]
fn a_software_adapter_is_not_a_gpu() {
    let Some(any) = gpu(&quad(0.2)) else { return };
    let hardware = GpuTracer::new(&quad(0.2), Adapters::Hardware);
    if any.adapter().software {
        let e = hardware.err().expect("no hardware adapter to find");
        assert_eq!(e.to_string(), "GPU: no hardware GPU adapter (Vulkan) found");
    } else {
        assert!(!hardware.unwrap().unwrap().adapter().software);
    }
    // No triangles: nothing to trace, no device needed.
    assert!(GpuTracer::new(&[], Adapters::Any).unwrap().is_none());
}

/// Every triangle sits in exactly one leaf, inside its box, and every
/// child's box inside its parent's.
#[test]
fn the_flattened_tree_holds_every_triangle_once_inside_its_boxes() {
    let mut occluders = Vec::new();
    for k in 0..500 {
        let x = (k % 25) as f32 * 0.04 - 0.5;
        let z = (k / 25) as f32 * 0.04 - 0.4;
        let y = ((k * 7919) % 101) as f32 * 0.001;
        occluders.push([
            Vec3A::new(x, y, z),
            Vec3A::new(x + 0.03, y, z),
            Vec3A::new(x, y + 0.02, z + 0.03),
        ]);
    }
    let flat = aobake::trace::gpu::flatten(&occluders).unwrap();
    assert_eq!(flat.tris.len(), occluders.len());
    let mut seen = vec![0; flat.tris.len()];
    let inside = |lo: [f32; 3], hi: [f32; 3], p: [f32; 3]| {
        (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
    };
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        let n = flat.nodes[i];
        if n.count == 0 {
            for c in [n.first as usize, n.first as usize + 1] {
                let m = flat.nodes[c];
                assert!(inside(n.lo, n.hi, m.lo) && inside(n.lo, n.hi, m.hi));
                stack.push(c);
            }
        } else {
            for t in n.first..n.first + n.count {
                seen[t as usize] += 1;
                for v in flat.tris[t as usize].v {
                    assert!(inside(n.lo, n.hi, [v[0], v[1], v[2]]));
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s == 1));
    assert!(flat.depth >= 8 && flat.depth < 64, "{}", flat.depth);
    assert!(aobake::trace::gpu::flatten(&[]).is_none());
}
