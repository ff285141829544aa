//! The adaptive method (`--method adaptive`) against closed forms and a
//! high-ray Monte Carlo reference, on scenes built to leak or to blur
//! contact.

mod common;
use aobake::Method;
use aobake::report::metrics::error_stats;
use common::*;

fn adaptive(resolution: u32, mean_rays: u32, max_distance: Option<f64>) -> aobake::Settings {
    let mut s = settings(resolution, 0, max_distance);
    s.method = Method::Adaptive;
    s.adaptive.mean_rays = mean_rays;
    s
}

#[test]
fn an_open_plane_is_exactly_open_for_the_pre_pass_alone() {
    let plane = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let b = aobake::bake_scene(
        &scene(&glb(&[plane], plain_nodes(1))),
        &adaptive(64, 64, None),
    )
    .unwrap();
    let stats = b.adaptive_stats.as_ref().unwrap();
    // Nothing seen: no receiver gets more than the pre-pass, none is filtered.
    assert!(stats.rays.iter().all(|&r| r == 16));
    assert_eq!(stats.adaptive_rays, 0);
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
    // The SH of 16 stratified rays: close to the open hemisphere's.
    let open = aobake::sh::open_hemisphere(glam::Vec3::Z);
    for s in &b.bake.sh {
        for i in 0..9 {
            assert!(
                (s[i] - open[i]).abs() < 0.05,
                "c{i} {} vs {}",
                s[i],
                open[i]
            );
        }
    }
}

#[test]
fn no_leak_across_a_thin_wall() {
    let sc = scene(&thin_wall_scene());
    let reference = aobake::bake_scene(&sc, &settings(256, 1024, Some(0.5))).unwrap();
    let a = aobake::bake_scene(&sc, &adaptive(256, 64, Some(0.5))).unwrap();
    let s = &a.geometry.space;
    let (mut covered, mut open) = (vec![], vec![]);
    for i in 0..a.receivers.len() {
        let p = s.center.as_vec3() + a.receivers.position[i] * s.diagonal as f32;
        let d = (a.bake.ao[i] - reference.bake.ao[i]) as f64;
        if p.z.abs() < 1e-4 && p.y.abs() < 0.8 {
            if (-0.1..-0.01).contains(&p.x) {
                covered.push(d);
            } else if (0.01..0.1).contains(&p.x) {
                open.push(d);
            }
        }
    }
    for (name, v) in [("covered floor", &covered), ("open floor", &open)] {
        assert!(v.len() > 30, "{name}: {} texels", v.len());
        let bias = v.iter().sum::<f64>() / v.len() as f64;
        // A leak moves these bands by 0.1 or more.
        assert!(bias.abs() < 0.01, "{name}: bias {bias:+.4}");
    }
}

#[test]
fn floor_beside_a_wall_beats_64_ray_monte_carlo_without_darkening_the_contact() {
    let sc = floor_and_wall();
    let raw = |s: aobake::Settings| bake_raw(&sc, s);
    let reference = raw(aobake::Settings {
        seed: 11,
        ..settings(128, 2048, Some(1.0))
    });
    let mc = raw(settings(128, 64, Some(1.0)));
    let a = raw(adaptive(128, 64, Some(1.0)));
    let e_mc = error_stats(&mc.bake.ao, &reference.bake.ao);
    let e_a = error_stats(&a.bake.ao, &reference.bake.ao);
    let stats = a.adaptive_stats.as_ref().unwrap();
    let mean_rays = stats.rays.iter().map(|&r| r as f64).sum::<f64>() / stats.rays.len() as f64;
    assert!(mean_rays < 72.0, "mean rays {mean_rays}");
    assert!(
        e_a.rmse < e_mc.rmse && e_a.bias.abs() < 0.004,
        "adaptive RMSE {:.4} bias {:+.4}, 64-ray Monte Carlo RMSE {:.4}",
        e_a.rmse,
        e_a.bias,
        e_mc.rmse
    );
    // The contact band (floor within 0.05 of the wall): no blur-darkening.
    let s = &a.geometry.space;
    let band: Vec<f64> = (0..a.receivers.len())
        .filter(|&i| {
            let p = s.center.as_vec3() + a.receivers.position[i] * s.diagonal as f32;
            p.z.abs() < 1e-4 && (p.x - 0.3).abs() < 0.05 && p.y.abs() < 0.4
        })
        .map(|i| (a.bake.ao[i] - reference.bake.ao[i]) as f64)
        .collect();
    assert!(band.len() > 50);
    let bias = band.iter().sum::<f64>() / band.len() as f64;
    assert!(bias.abs() < 0.01, "contact band bias {bias:+.4}");
}

#[test]
fn adaptive_output_is_identical_for_any_thread_count() {
    let g = thin_wall_scene();
    let s = adaptive(64, 32, Some(0.5));
    assert_eq!(glb_on_threads(&g, &s, 1), glb_on_threads(&g, &s, 2));
}
