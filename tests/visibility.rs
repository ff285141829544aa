//! The visibility layer v_i = Int V(w) H(n.w) Y_i(w) dw against closed
//! forms, a dense uniform reference traced independently at the texel, and
//! the relit value of tilted normals against brute force; and the layer in
//! the file (fields, decoding, `auto`).

mod common;
use aobake::job::settings::VisibilityMode;
use aobake::relight::{Environment, anchored_diffuse};
use aobake::sample::{Frame, receiver_seed, sobol_2d, uniform_hemisphere};
use aobake::sh::{self, VIS_COUNT};
use aobake::trace::offset_origin;
use common::*;
use glam::{Quat, Vec3};
use serde_json::{Value, json};

const PI: f64 = std::f64::consts::PI;

fn with_layer(mut s: aobake::BakeSettings, method: aobake::Method) -> aobake::BakeSettings {
    s.method = method;
    s.visibility = VisibilityMode::All;
    if method == aobake::Method::Adaptive {
        s.adaptive.mean_rays = 64;
    }
    s
}

/// Uniform midpoint quadrature over the upper hemisphere of +z (uniform in
/// z is uniform in solid angle): Int V(w) f(w) dw.
fn uniform_reference(visible: impl Fn(Vec3) -> bool, f: impl Fn(Vec3) -> f64) -> f64 {
    let (nz, np) = (600, 600);
    let mut s = 0.0;
    for i in 0..nz {
        let z = (i as f64 + 0.5) / nz as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            if visible(w) {
                s += f(w);
            }
        }
    }
    s * 2.0 * PI / (nz * np) as f64
}

/// The layer of receivers on the plane z = 0 near the origin (world units).
fn layer_near_origin(b: &aobake::job::Baked, half: f32) -> Vec<[f32; VIS_COUNT]> {
    let v = &b.bake.visibility.as_ref().expect("a layer").v;
    (0..b.receivers.len())
        .filter(|&i| {
            let p = b.geometry.space.to_world(b.receivers.position[i]);
            p.z.abs() < 1e-3 && p.x.abs() < half && p.y.abs() < half
        })
        .map(|i| v[i])
        .collect()
}

fn mean(v: &[[f32; VIS_COUNT]], k: usize) -> f64 {
    v.iter().map(|c| c[k] as f64).sum::<f64>() / v.len() as f64
}

#[test]
fn an_open_plane_has_the_open_hemisphere_exactly() {
    let plane = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let sc = scene(&glb(&[plane], plain_nodes(1)));
    for method in [aobake::Method::Mc, aobake::Method::Adaptive] {
        let b = aobake::bake_scene(&sc, &with_layer(settings(32, 16, None), method)).unwrap();
        let v = &b.bake.visibility.as_ref().unwrap().v;
        let open = sh::open_visibility(Vec3::Z);
        assert!((open[0] - PI.sqrt() as f32).abs() < 1e-5);
        for c in v {
            for k in 0..VIS_COUNT {
                assert!((c[k] - open[k]).abs() < 1e-5, "{method:?} v{k}: {}", c[k]);
            }
        }
    }
}

#[test]
fn a_receiver_under_a_parallel_plane_matches_the_closed_form() {
    // Occluded iff cos(theta) > c = h / D: the band 0 < z < c is seen.
    let (h, d) = (1.0f32, 2.0f64);
    let recv = quad([0.0; 3], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], true);
    let occ = quad([0.0, 0.0, h], [0.0, 2.2, 0.0], [2.2, 0.0, 0.0], true);
    let sc = scene(&glb(&[recv, occ], plain_nodes(2)));
    let c = h as f64 / d;
    // Zonal closed forms: 2 pi K_l Int_0^c P(z) dz.
    let want = [
        (0, 2.0 * PI * 0.282_094_8 * c),
        (2, PI * 0.488_602_5 * c * c),
        (6, 2.0 * PI * 0.315_391_57 * (c.powi(3) - c)),
        (
            12,
            2.0 * PI * 0.373_176_33 * (1.25 * c.powi(4) - 1.5 * c * c),
        ),
    ];
    for method in [aobake::Method::Mc, aobake::Method::Adaptive] {
        let b = aobake::bake_scene(&sc, &with_layer(settings(256, 256, Some(d)), method)).unwrap();
        let v = layer_near_origin(&b, 0.15);
        assert!(v.len() > 20, "{}", v.len());
        for (k, w) in want {
            assert!(
                (mean(&v, k) - w).abs() < 0.01,
                "{method:?} v{k}: {} vs {w}",
                mean(&v, k)
            );
        }
        for k in [1, 3, 4, 5, 7, 8, 9, 10, 11, 13, 14, 15] {
            assert!(mean(&v, k).abs() < 0.01, "{method:?} v{k}: {}", mean(&v, k));
        }
    }
}

#[test]
fn a_receiver_beside_a_wall_matches_quadrature_and_sign() {
    let (a, d) = (0.5f32, 1.0f64);
    let recv = quad([0.0; 3], [0.05, 0.0, 0.0], [0.0, 0.05, 0.0], true);
    let wall = quad([a, 0.0, 1.2], [0.0, 0.0, 1.2], [0.0, 1.2, 0.0], true);
    let sc = scene(&glb(&[recv, wall], plain_nodes(2)));
    let s = a as f64 / d;
    // A direction hits iff its distance to the wall plane, a / w_x, is
    // within D: w_x >= a / D.
    let vis = |w: Vec3| (w.x as f64) < s;
    for method in [aobake::Method::Mc, aobake::Method::Adaptive] {
        let b = aobake::bake_scene(&sc, &with_layer(settings(512, 256, Some(d)), method)).unwrap();
        let v = layer_near_origin(&b, 0.02);
        assert!(v.len() > 10, "{}", v.len());
        for k in 0..VIS_COUNT {
            let want = uniform_reference(vis, |w| sh::basis16(w)[k] as f64);
            assert!(
                (mean(&v, k) - want).abs() < 0.012,
                "{method:?} v{k}: {} vs {want}",
                mean(&v, k)
            );
        }
        // The wall is towards +x: the x coefficient drops below the open
        // value 0.
        assert!(mean(&v, 3) < -0.1, "v3 {}", mean(&v, 3));
    }
}

/// A floor with a wall and a low slab: contact, narrow and wide occlusion.
fn groove() -> aobake::gltf::Scene {
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 1.0, 0.0], true);
    let slab = quad([-0.5, 0.0, 0.1], [0.0, 1.0, 0.0], [0.4, 0.0, 0.0], true);
    scene(&glb(&[floor, wall, slab], plain_nodes(3)))
}

#[test]
fn the_baked_layer_relights_tilted_normals_like_brute_force_at_the_texel() {
    let sc = groove();
    let mut s = with_layer(settings(96, 256, Some(0.6)), aobake::Method::Adaptive);
    s.adaptive.mean_rays = 0;
    s.fill_inside = false;
    // The receivers' own values are compared: with the border fit on,
    // those the fit sets stop at a fit point's rays, as their texels take
    // the fit's values (`bake::adaptive::FitSets`).
    s.border = aobake::lightmap::border::BorderMode::Off;
    let b = aobake::bake_scene(&sc, &s).unwrap();
    let level_prepared = aobake::job::Level::new(
        &sc,
        &s,
        &aobake::RunOptions::QUIET,
        &mut aobake::stage::StageTimer::new(),
    )
    .unwrap();
    let prepared = level_prepared
        .page(0, &sc, &mut aobake::stage::StageTimer::new())
        .unwrap();
    let (rc, tracer) = (&b.receivers, &prepared.level.tracer);
    assert_eq!(rc.texel, prepared.receivers.texel);
    let v = &b.bake.visibility.as_ref().unwrap().v;
    let max_distance = (0.6 / b.geometry.space.diagonal) as f32;
    let envs = [
        Environment::new([1.0, 0.2, 0.6, 0.3, 0.1, 0.0, 0.2, 0.1, 0.0]),
        Environment::new([0.6, -0.3, 0.4, -0.4, 0.0, 0.1, 0.1, -0.1, 0.2]),
    ];
    let (mut layer, mut ignored, mut count) = (0.0f64, 0.0f64, 0);
    let mut v_error = 0.0f64;
    // Every 7th receiver: a dense uniform reference on its own stream.
    for r in (0..rc.len()).step_by(7) {
        let (n, geo) = (rc.normal[r], rc.geo_normal[r]);
        let origin = offset_origin(rc.position[r], geo, rc.footprint[r]);
        let frame = Frame::from_normal(n);
        let seed = receiver_seed(99, rc.texel[r] as u64, 9);
        let rays = 2048;
        let dirs: Vec<(Vec3, bool)> = (0..rays)
            .map(|i| {
                let d = frame
                    .to_world(uniform_hemisphere(sobol_2d(i, seed)))
                    .normalize();
                (d, tracer.receiver_visible(origin, geo, d, max_distance))
            })
            .collect();
        let reference_v0 =
            dirs.iter().filter(|d| d.1).count() as f64 * 2.0 * PI / rays as f64 * 0.282_094_8;
        v_error += (v[r][0] as f64 - reference_v0).powi(2);
        for env in &envs {
            for (k, tilt) in [20.0f32, 45.0, 70.0, 89.9].into_iter().enumerate() {
                let axis = frame.tangent * (k as f32).cos() + frame.bitangent * (k as f32).sin();
                let shading = Quat::from_axis_angle(axis, tilt.to_radians()) * n;
                let truth: f64 = dirs
                    .iter()
                    .filter(|d| d.1)
                    .map(|&(d, _)| {
                        let l: f32 = sh::basis(d).iter().zip(&env.l).map(|(y, l)| y * l).sum();
                        (shading.dot(d).max(0.0) * l) as f64
                    })
                    .sum::<f64>()
                    * 2.0
                    / rays as f64;
                let got = anchored_diffuse(env, &b.bake.sh[r], &v[r], n, shading) as f64;
                assert!(got.is_finite(), "NaN at {tilt} degrees");
                let scale = env.open_diffuse(shading).abs().max(0.05) as f64;
                layer += ((got - truth) / scale).abs();
                ignored += ((env.baked_diffuse(&b.bake.sh[r]) as f64 - truth) / scale).abs();
                count += 1;
            }
        }
        // At n' = n the formula is c.L exactly.
        for env in &envs {
            let at_n = anchored_diffuse(env, &b.bake.sh[r], &v[r], n, n);
            assert!((at_n - env.baked_diffuse(&b.bake.sh[r])).abs() < 1e-5);
        }
    }
    let (layer, ignored) = (layer / count as f64, ignored / count as f64);
    let v_rmse = (v_error / (count / 8) as f64).sqrt();
    eprintln!(
        "{count} relit values: layer {layer:.4}, normal map ignored {ignored:.4}; v0 RMSE {v_rmse:.4}"
    );
    assert!(v_rmse < 0.03, "v0 RMSE {v_rmse}");
    assert!(layer < 0.03, "layer {layer}");
    assert!(layer < 0.25 * ignored, "layer {layer} vs ignored {ignored}");
}

/// A floor and a box-like wall; the wall's material is glossy.
fn glossy_wall_file() -> Vec<u8> {
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 1.0, 0.0], true);
    let (mut json, bin) = split(&glb(&[floor, wall], plain_nodes(2)));
    json["materials"] = json!([{"pbrMetallicRoughness": {"roughnessFactor": 0.2}}]);
    json["meshes"][1]["primitives"][0]["material"] = json!(0);
    aobake::gltf::container::glb_bytes(&json, &bin)
}

fn primitive_ext(json: &Value, mesh: usize) -> &Value {
    &json["meshes"][mesh]["primitives"][0]["extensions"]["AOBAKE_lightmap"]
}

#[test]
fn the_file_carries_the_layer_where_a_material_reads_it() {
    let g = glossy_wall_file();
    let sc = scene(&g);
    let s = aobake::BakeSettings {
        method: aobake::Method::Adaptive,
        // The write path: every texel holds its receiver's values (the
        // border fit moves the border band's: tests/border_fit.rs).
        border: aobake::lightmap::BorderMode::Off,
        ..settings(64, 64, Some(0.5))
    };
    // auto: the glossy wall gets the layer, the rough floor does not.
    let b = aobake::bake_scene(&sc, &s).unwrap();
    let (json, bin) = split(&b.glb);
    assert!(primitive_ext(&json, 0).get("visibility").is_none());
    let ext = primitive_ext(&json, 1);
    assert_eq!(ext["visibility"].as_array().unwrap().len(), 4);
    assert_eq!(ext["visibilityScale"].as_array().unwrap().len(), 16);
    assert_eq!(ext["visibilityOffset"].as_array().unwrap().len(), 16);
    assert_eq!(json["extensions"]["AOBAKE_lightmap"]["visibilityOrder"], 3);
    assert_eq!(json["extensions"]["AOBAKE_lightmap"]["version"], 1);
    // Decoding texel values reproduces the float layer within 8 bits.
    let v = &b.bake.visibility.as_ref().unwrap().v;
    let scale: Vec<f32> = serde_json::from_value(ext["visibilityScale"].clone()).unwrap();
    let offset: Vec<f32> = serde_json::from_value(ext["visibilityOffset"].clone()).unwrap();
    let image = |tex: &Value| {
        let t = tex["index"].as_u64().unwrap() as usize;
        let img = json["textures"][t]["source"].as_u64().unwrap() as usize;
        let view =
            &json["bufferViews"][json["images"][img]["bufferView"].as_u64().unwrap() as usize];
        let off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = view["byteLength"].as_u64().unwrap() as usize;
        image::load_from_memory(&bin[off..off + len])
            .unwrap()
            .to_rgba8()
    };
    let pages: Vec<_> = ext["visibility"]
        .as_array()
        .unwrap()
        .iter()
        .map(image)
        .collect();
    let w = b.receivers.width;
    for r in (0..b.receivers.len()).step_by(13) {
        let t = b.receivers.texel[r];
        for k in 0..VIS_COUNT {
            let ch = pages[k / 4].get_pixel(t % w, t / w)[k % 4] as f32 / 255.0;
            let decoded = scale[k] * ch + offset[k];
            assert!(
                (decoded - v[r][k]).abs() <= scale[k] / 255.0 * 0.51 + 1e-6,
                "v{k}"
            );
        }
    }
    // Order 2: 3 textures, 9 coefficients, v8 in the third's red.
    let b2 = aobake::bake_scene(
        &sc,
        &aobake::BakeSettings {
            visibility_order: 2,
            ..s.clone()
        },
    )
    .unwrap();
    let (json2, _) = split(&b2.glb);
    let ext2 = primitive_ext(&json2, 1);
    assert_eq!(ext2["visibility"].as_array().unwrap().len(), 3);
    assert_eq!(ext2["visibilityScale"].as_array().unwrap().len(), 9);
    // off, and auto on a scene without such materials: no layer, the same
    // bytes.
    let off = aobake::bake_scene(
        &sc,
        &aobake::BakeSettings {
            visibility: VisibilityMode::Off,
            ..s.clone()
        },
    )
    .unwrap();
    assert!(off.bake.visibility.is_none());
    let plain = scene(&glb(
        &[
            quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true),
            quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 1.0, 0.0], true),
        ],
        plain_nodes(2),
    ));
    let auto = aobake::bake_scene(&plain, &s).unwrap();
    let none = aobake::bake_scene(
        &plain,
        &aobake::BakeSettings {
            visibility: VisibilityMode::Off,
            ..s.clone()
        },
    )
    .unwrap();
    assert!(auto.bake.visibility.is_none());
    assert_eq!(auto.glb, none.glb);
}

#[test]
fn the_sheared_method_refuses_the_layer_and_a_bad_order_is_refused() {
    let sc = scene(&glossy_wall_file());
    let s = aobake::BakeSettings {
        method: aobake::Method::Sheared,
        visibility: VisibilityMode::All,
        ..settings(32, 16, None)
    };
    let e = aobake::bake_scene(&sc, &s).err().unwrap().to_string();
    assert!(
        e.contains("sheared method does not bake the visibility layer"),
        "{e}"
    );
    let s = aobake::BakeSettings {
        visibility_order: 4,
        ..settings(32, 16, None)
    };
    let e = aobake::bake_scene(&sc, &s).err().unwrap().to_string();
    assert!(e.contains("visibility_order 4 must be 2 or 3"), "{e}");
}
