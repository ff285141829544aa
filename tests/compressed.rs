//! Compressed inputs: Draco (`KHR_draco_mesh_compression`) and meshopt
//! (`EXT_meshopt_compression`, `KHR_meshopt_compression`) geometry is
//! decoded on input, bakes, and is written uncompressed with the
//! extensions no longer listed.
//!
//! The expectations are independent of the decoders: the same Khronos
//! Lantern stored three ways (`tests/data/`: Draco from the Khronos
//! sample, meshopt made from the quantized one by `gltfpack -cc -vpf` and
//! `gltfpack -cc -ce khr`, which exercise the octahedral and exponential
//! filters and the triangle index codec) against the quantized lantern
//! read by the plain accessor path: triangle count, world area and
//! bounding box, positions within the bounds the Draco encoder recorded,
//! and the baked AO, averaged by world area over bilinear lookups, within
//! Monte Carlo noise of the uncompressed lantern's.

mod common;
use aobake::gltf::Scene;
use glam::{DVec3, Vec3};
use serde_json::Value;
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// World-space facts of a scene's placed triangles.
struct Surface {
    triangles: usize,
    area: f64,
    lo: DVec3,
    hi: DVec3,
}

fn surface(scene: &Scene) -> Surface {
    let mut s = Surface {
        triangles: 0,
        area: 0.0,
        lo: DVec3::INFINITY,
        hi: DVec3::NEG_INFINITY,
    };
    for inst in &scene.instances {
        let g = &scene.geometries[inst.geometry];
        let world = |i: u32| {
            inst.transform
                .transform_point3(Vec3::from(g.positions[i as usize]).as_dvec3())
        };
        for t in g.triangles.chunks_exact(3) {
            let [a, b, c] = [world(t[0]), world(t[1]), world(t[2])];
            s.triangles += 1;
            s.area += 0.5 * (b - a).cross(c - a).length();
            for p in [a, b, c] {
                s.lo = s.lo.min(p);
                s.hi = s.hi.max(p);
            }
        }
    }
    s
}

/// `a` matches `b` (the quantized lantern) in area and bounds within `tol`
/// (relative to the area and to the box's diagonal).
fn same_surface(name: &str, a: &Surface, b: &Surface, tol: f64) {
    let extent = (b.hi - b.lo).length();
    assert!(
        (a.area - b.area).abs() <= tol * b.area,
        "{name}: area {} against {}",
        a.area,
        b.area
    );
    let off = (a.lo - b.lo).abs().max((a.hi - b.hi).abs()).max_element();
    assert!(
        off <= tol * extent,
        "{name}: bounds off by {off} of {extent}"
    );
}

#[test]
fn decoded_geometry_is_the_lantern() {
    let quantized = surface(&aobake::gltf::load(&data("lantern_quantized.glb")).unwrap());
    assert_eq!(quantized.triangles, 5394);

    // Draco: every triangle, within the bounds its encoder recorded
    // (accessor min/max of the uncompressed positions, in mesh space).
    let draco = aobake::gltf::load(&data("lantern_draco.glb")).unwrap();
    let input: Value = {
        let bytes = std::fs::read(data("lantern_draco.glb")).unwrap();
        common::split(&bytes).0
    };
    for g in &draco.geometries {
        let prim = &input["meshes"][g.mesh]["primitives"][g.primitive];
        let acc = &input["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
        let bound = |k: &str, i: usize| acc[k][i].as_f64().unwrap();
        let extent = (0..3)
            .map(|i| bound("max", i) - bound("min", i))
            .fold(0.0, f64::max);
        for p in &g.positions {
            for (i, &v) in p.iter().enumerate() {
                let v = v as f64;
                assert!(
                    v >= bound("min", i) - 1e-4 * extent && v <= bound("max", i) + 1e-4 * extent,
                    "{}: {v} outside the encoder's bounds",
                    g.label()
                );
            }
        }
    }
    let d = surface(&draco);
    assert_eq!(d.triangles, 5394);
    same_surface("draco", &d, &quantized, 0.005);
    assert!(
        draco
            .warnings
            .iter()
            .any(|w| w.contains("KHR_draco_mesh_compression"))
    );

    // Meshopt, EXT and KHR: gltfpack drops the 14 degenerate triangles.
    for name in ["lantern_meshopt.glb", "lantern_meshopt_khr.glb"] {
        let scene = aobake::gltf::load(&data(name)).unwrap();
        let m = surface(&scene);
        assert!(
            (5380..=5394).contains(&m.triangles),
            "{name}: {}",
            m.triangles
        );
        same_surface(name, &m, &quantized, 0.005);
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.contains("meshopt_compression"))
        );
    }
}

/// Area-weighted mean of the baked AO as an engine reads it: bilinear
/// lookups (clamp to edge) in the written 8-bit texture at 7 points of
/// every baked triangle.
fn mean_ao(out: &Path) -> f64 {
    let scene = aobake::gltf::load(out).unwrap();
    let json = &scene.doc.json;
    let bin = &scene.doc.buffers[0];
    let image_of = |texture: u64| {
        let image = &json["images"][json["textures"][texture as usize]["source"]
            .as_u64()
            .unwrap() as usize];
        let view = &json["bufferViews"][image["bufferView"].as_u64().unwrap() as usize];
        let o = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let png = &bin[o..o + view["byteLength"].as_u64().unwrap() as usize];
        image::load_from_memory(png).unwrap().into_luma8()
    };
    let (mut sum, mut area) = (0.0, 0.0);
    for inst in scene.instances.iter().filter(|i| i.baked) {
        let g = &scene.geometries[inst.geometry];
        let prim = &json["meshes"][g.mesh]["primitives"][g.primitive];
        let ext = &prim["extensions"]["AOBAKE_lightmap"];
        let ao = image_of(ext["occlusion"]["index"].as_u64().unwrap());
        let set = ext["texCoord"].as_u64().unwrap();
        let uv_acc = prim["attributes"][format!("TEXCOORD_{set}")]
            .as_u64()
            .unwrap();
        let uvs = aobake::gltf::accessor::read(&scene.doc, uv_acc as usize)
            .unwrap()
            .to_f32::<2>("uv")
            .unwrap();
        let (w, h) = (ao.width() as f64, ao.height() as f64);
        let texel = |x: i64, y: i64| {
            let x = x.clamp(0, w as i64 - 1) as u32;
            let y = y.clamp(0, h as i64 - 1) as u32;
            ao.get_pixel(x, y).0[0] as f64 / 255.0
        };
        let lookup = |u: f64, v: f64| {
            let (x, y) = (u * w - 0.5, v * h - 0.5);
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            (1.0 - fy) * ((1.0 - fx) * texel(x0, y0) + fx * texel(x0 + 1, y0))
                + fy * ((1.0 - fx) * texel(x0, y0 + 1) + fx * texel(x0 + 1, y0 + 1))
        };
        let world = |i: u32| {
            inst.transform
                .transform_point3(Vec3::from(g.positions[i as usize]).as_dvec3())
        };
        const BARY: [[f64; 3]; 7] = [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            [0.6, 0.2, 0.2],
            [0.2, 0.6, 0.2],
            [0.2, 0.2, 0.6],
            [0.1, 0.45, 0.45],
            [0.45, 0.1, 0.45],
            [0.45, 0.45, 0.1],
        ];
        for t in g.triangles.chunks_exact(3) {
            let a = 0.5
                * (world(t[1]) - world(t[0]))
                    .cross(world(t[2]) - world(t[0]))
                    .length();
            let uv = |k: usize| uvs[t[k] as usize];
            for b in BARY {
                let u = (0..3).map(|k| b[k] * uv(k)[0] as f64).sum::<f64>();
                let v = (0..3).map(|k| b[k] * uv(k)[1] as f64).sum::<f64>();
                sum += a / 7.0 * lookup(u, v);
            }
            area += a;
        }
    }
    sum / area
}

#[test]
fn compressed_lanterns_bake_like_the_uncompressed_one() {
    let dir = tempfile::tempdir().unwrap();
    let settings = common::settings(256, 64, None);
    let mut means = Vec::new();
    for name in [
        "lantern_quantized.glb",
        "lantern_draco.glb",
        "lantern_meshopt.glb",
        "lantern_meshopt_khr.glb",
    ] {
        let input = data(name);
        let before = std::fs::read(&input).unwrap();
        let out = dir.path().join(name);
        let report = aobake::bake(&input, &out, &settings, &aobake::RunOptions::QUIET)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(std::fs::read(&input).unwrap(), before, "input touched");
        let (ij, _) = common::split(&before);
        let (oj, _) = common::split(&std::fs::read(&out).unwrap());
        // The compression extensions are gone from the output, everywhere.
        let text = oj.to_string();
        for ext in [
            "KHR_draco_mesh_compression",
            "EXT_meshopt_compression",
            "KHR_meshopt_compression",
        ] {
            assert!(!text.contains(ext), "{name}: the output still names {ext}");
            if ij.to_string().contains(ext) {
                assert!(
                    report.warnings.iter().any(|w| w.contains(ext)),
                    "{name}: no warning names {ext}: {:?}",
                    report.warnings
                );
            }
        }
        // What the decode does not touch is kept.
        // (materials gain the baked occlusionTexture, nodes may point at a
        // copied mesh).
        for key in ["asset", "scenes", "scene"] {
            assert_eq!(ij.get(key), oj.get(key), "{name}: {key} changed");
        }
        for key in ["materials", "nodes"] {
            for (i, object) in ij[key].as_array().unwrap().iter().enumerate() {
                for (k, v) in object.as_object().unwrap() {
                    if k != "mesh" {
                        assert_eq!(&oj[key][i][k], v, "{name}: {key}[{i}].{k}");
                    }
                }
            }
        }
        // Every accessor of the output reads real data.
        for (i, acc) in oj["accessors"].as_array().unwrap().iter().enumerate() {
            assert!(
                acc.get("bufferView").is_some(),
                "{name}: accessors[{i}] has no data"
            );
        }
        aobake::gltf::load(&out).unwrap();
        if let Some((errors, _)) = common::validate(&out) {
            assert_eq!(errors, 0, "{name}: validator errors");
        }
        means.push((name, mean_ao(&out)));
    }
    eprintln!("area-weighted mean AO: {means:?}");
    let reference = means[0].1;
    assert!(reference > 0.3 && reference < 0.99, "{means:?}");
    for &(name, m) in &means[1..] {
        assert!(
            (m - reference).abs() < 0.01,
            "{name}: mean AO {m} against {reference}"
        );
    }
}
