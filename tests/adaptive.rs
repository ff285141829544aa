//! The adaptive method (`--method adaptive`) against closed forms and a
//! high-ray Monte Carlo reference, on scenes built to leak or to blur
//! contact.

mod common;
use aobake::Method;
use aobake::job::settings::DEFAULT_RAYS;
use aobake::report::metrics::error_stats;
use common::*;

fn adaptive(resolution: u32, mean_rays: u32, max_distance: Option<f64>) -> aobake::BakeSettings {
    let mut s = settings(resolution, DEFAULT_RAYS, max_distance);
    s.method = Method::Adaptive;
    s.adaptive.mean_rays = mean_rays;
    s
}

#[test]
fn an_open_plane_is_exactly_open_for_the_pre_pass_alone() {
    let plane = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    // The default quality (not a fixed mean, which spreads its rays over
    // whatever there is).
    let s = adaptive(64, 0, None);
    let b = aobake::bake_scene(&scene(&glb(&[plane], plain_nodes(1))), &s).unwrap();
    let stats = b.adaptive_stats.as_ref().unwrap();
    // Nothing seen: no receiver gets more than the pre-pass.
    assert!(stats.rays.iter().all(|&r| r == 16));
    assert_eq!(stats.adaptive_rays, 0);
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
    // The SH: the open hemisphere's exact projection (no occluded ray).
    let open = aobake::sh::open_hemisphere(glam::Vec3::Z);
    for s in &b.bake.sh {
        for i in 0..9 {
            assert!(
                (s[i] - open[i]).abs() < 1e-5,
                "c{i} {} vs {}",
                s[i],
                open[i]
            );
        }
    }
}

#[test]
fn an_open_plane_with_tilted_shading_normals_is_exact_below_its_plane() {
    // Shading normals tilted 30 degrees from the plane's: (1 - cos 30) / 2
    // of the cosine-weighted hemisphere lies below the plane, occluded
    // without tracing, so the AO is (1 + cos 30) / 2 = 0.9330 and the SH
    // the open hemisphere less the part below. The pre-pass's 16 rays see
    // their own share below (off by up to a ray in 16); the filtered
    // receivers' values carry the exact share instead.
    let tilt = 30f32.to_radians();
    let n = glam::Vec3::new(0.0, tilt.sin(), tilt.cos());
    let mut plane = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    plane.normals = Some(vec![n.to_array(); 4]);
    let s = adaptive(64, 0, None);
    let b = aobake::bake_scene(&scene(&glb(&[plane], plain_nodes(1))), &s).unwrap();
    let want_ao = (1.0 + tilt.cos()) / 2.0;
    let open = aobake::sh::open_hemisphere(n);
    let below = aobake::sh::below_plane(n, glam::Vec3::Z);
    for (ao, sh) in b.bake.ao.iter().zip(&b.bake.sh) {
        assert!((ao - want_ao).abs() < 1e-5, "AO {ao} vs {want_ao}");
        // L0 is Y_0 times the AO.
        assert!((sh[0] - 0.282_094_8 * want_ao).abs() < 1e-5, "L0 {}", sh[0]);
        for i in 0..9 {
            let want = open[i] - below[i];
            assert!((sh[i] - want).abs() < 1e-5, "c{i} {} vs {want}", sh[i]);
        }
    }
}

#[test]
fn no_leak_across_a_thin_wall() {
    let sc = scene(&thin_wall_scene());
    let reference = aobake::bake_scene(&sc, &settings(256, 1024, Some(0.5))).unwrap();
    no_leak_with(&sc, &reference, &adaptive(256, 64, Some(0.5)));
}

fn no_leak_with(
    sc: &aobake::gltf::Scene,
    reference: &aobake::job::Baked,
    settings: &aobake::BakeSettings,
) {
    let a = aobake::bake_scene(sc, settings).unwrap();
    let s = &a.geometry.space;
    let (mut covered, mut open) = (vec![], vec![]);
    for i in 0..a.receivers.len() {
        let p = s.to_world(a.receivers.position[i]);
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
    let raw = |s: aobake::BakeSettings| bake_raw(&sc, s);
    let reference = raw(aobake::BakeSettings {
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
            let p = s.to_world(a.receivers.position[i]);
            p.z.abs() < 1e-4 && (p.x - 0.3).abs() < 0.05 && p.y.abs() < 0.4
        })
        .map(|i| (a.bake.ao[i] - reference.bake.ao[i]) as f64)
        .collect();
    assert!(band.len() > 50);
    let bias = band.iter().sum::<f64>() / band.len() as f64;
    assert!(bias.abs() < 0.01, "contact band bias {bias:+.4}");
}

#[test]
fn contact_lines_cut_the_contact_bands_rays_at_its_error() {
    // The floor beside a wall at the default quality: the floor's texels
    // within a texel of the wall are in contact (not filtered), and with
    // contact lines averaged along the wall. Against a 2048-ray
    // reference, the band's error stays that of the bake without lines
    // for fewer rays, without darkening it.
    let sc = floor_and_wall();
    let reference = bake_raw(
        &sc,
        aobake::BakeSettings {
            seed: 11,
            ..settings(128, 2048, Some(1.0))
        },
    );
    let with = bake_raw(&sc, adaptive(128, 0, Some(1.0)));
    let mut s = adaptive(128, 0, Some(1.0));
    s.adaptive.contact_lines = false;
    let without = bake_raw(&sc, s);
    let space = &with.geometry.space;
    let band: Vec<usize> = (0..with.receivers.len())
        .filter(|&i| {
            let p = space.to_world(with.receivers.position[i]);
            p.z.abs() < 1e-4 && (p.x - 0.3).abs() < 0.02 && p.y.abs() < 0.9
        })
        .collect();
    assert!(band.len() > 100, "{} band texels", band.len());
    let of = |b: &aobake::job::Baked| {
        let stats = b.adaptive_stats.as_ref().unwrap();
        let rays = band.iter().map(|&i| stats.rays[i] as f64).sum::<f64>() / band.len() as f64;
        let d: Vec<f64> = band
            .iter()
            .map(|&i| (b.bake.ao[i] - reference.bake.ao[i]) as f64)
            .collect();
        let rmse = (d.iter().map(|e| e * e).sum::<f64>() / d.len() as f64).sqrt();
        let bias = d.iter().sum::<f64>() / d.len() as f64;
        (stats.contact_lines, rays, rmse, bias)
    };
    let (lines, rays, rmse, bias) = of(&with);
    let (no_lines, rays_0, rmse_0, _) = of(&without);
    assert!(
        lines >= band.len() && no_lines == 0,
        "{lines} lines, {no_lines}"
    );
    assert!(
        rays < 0.6 * rays_0,
        "band rays {rays:.1} against {rays_0:.1}"
    );
    assert!(
        rmse < 1.15 * rmse_0 + 0.002 && bias.abs() < 0.01,
        "band RMSE {rmse:.4} (without lines {rmse_0:.4}), bias {bias:+.4}"
    );
}

#[test]
fn adaptive_output_is_identical_for_any_thread_count() {
    let g = thin_wall_scene();
    let s = adaptive(64, 32, Some(0.5));
    assert_eq!(glb_on_threads(&g, &s, 1), glb_on_threads(&g, &s, 2));
}

/// A box, five faces (no bottom), from `lo` to `hi` ([`quad`] takes a
/// centre and half-axes).
fn open_box(lo: [f32; 3], hi: [f32; 3]) -> Vec<MeshSpec> {
    let [x0, y0, z0] = lo;
    let [x1, y1, z1] = hi;
    let (cx, cy, cz) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0, (z0 + z1) / 2.0);
    let (hx, hy, hz) = ((x1 - x0) / 2.0, (y1 - y0) / 2.0, (z1 - z0) / 2.0);
    vec![
        quad([cx, cy, z1], [hx, 0.0, 0.0], [0.0, hy, 0.0], true),
        quad([x0, cy, cz], [0.0, 0.0, hz], [0.0, hy, 0.0], true),
        quad([x1, cy, cz], [0.0, hy, 0.0], [0.0, 0.0, hz], true),
        quad([cx, y0, cz], [hx, 0.0, 0.0], [0.0, 0.0, hz], true),
        quad([cx, y1, cz], [0.0, 0.0, hz], [hx, 0.0, 0.0], true),
    ]
}

/// A 60 cm floor centred at (0.3, 0.3) with open boxes (lower and upper
/// corners) standing on it, as one mesh.
fn boxes_on_a_floor(boxes: &[([f32; 3], [f32; 3])]) -> aobake::gltf::Scene {
    let mut parts = vec![quad(
        [0.3, 0.3, 0.0],
        [0.3, 0.0, 0.0],
        [0.0, 0.3, 0.0],
        true,
    )];
    for &(lo, hi) in boxes {
        parts.extend(open_box(lo, hi));
    }
    scene(&glb(&[merge(&parts)], plain_nodes(1)))
}

/// Mean AO bias per class of floor texels against a reference.
fn class_bias(
    a: &aobake::job::Baked,
    reference: &aobake::job::Baked,
    class: impl Fn(glam::Vec3) -> Option<usize>,
    classes: usize,
) -> Vec<(f64, usize)> {
    let s = &a.geometry.space;
    let mut acc = vec![(0.0f64, 0usize); classes];
    for i in 0..a.receivers.len() {
        let p = s.to_world(a.receivers.position[i]);
        if let Some(c) = class(p) {
            acc[c].0 += (a.bake.ao[i] - reference.bake.ao[i]) as f64;
            acc[c].1 += 1;
        }
    }
    acc.into_iter()
        .map(|(sum, n)| (sum / n.max(1) as f64, n))
        .collect()
}

#[test]
fn contact_shadows_of_a_box_on_the_floor_and_a_1_cm_crevice_keep_their_depth() {
    // Two 10 cm boxes on a floor, 1 cm apart: the floor beside a box
    // (contact), inside the crevice, and away from both; the default
    // quality against 1024-ray Monte Carlo, bias per class.
    let sc = boxes_on_a_floor(&[
        ([0.2, 0.2, 0.0], [0.3, 0.4, 0.1]),
        ([0.31, 0.2, 0.0], [0.41, 0.4, 0.1]),
    ]);
    let reference = bake_raw(&sc, settings(256, 1024, Some(0.3)));
    // An all-open bake of the same atlas (no occluder within reach) gives
    // each class's depth of shadow: reference minus 1.
    let open_floor = bake_raw(&sc, settings(256, 1, Some(1e-9)));
    let mut s = settings(256, DEFAULT_RAYS, Some(0.3));
    s.method = Method::Adaptive;
    let a = bake_raw(&sc, s);
    let class = |p: glam::Vec3| -> Option<usize> {
        if p.z.abs() > 1e-4 || !(0.22..0.38).contains(&p.y) {
            return None;
        }
        if (0.301..0.309).contains(&p.x) {
            Some(0) // crevice floor
        } else if (0.15..0.199).contains(&p.x) || (0.411..0.46).contains(&p.x) {
            Some(1) // within 5 cm of a box
        } else if p.x < 0.08 || p.x > 0.53 {
            Some(2) // away from both
        } else {
            None
        }
    };
    let bias = class_bias(&a, &reference, class, 3);
    let level = class_bias(&reference, &open_floor, class, 3);
    let mc = bake_raw(&sc, settings(256, 256, Some(0.3)));
    let mc_bias = class_bias(&mc, &reference, class, 3);
    for (k, name) in ["crevice", "contact", "far"].iter().enumerate() {
        let (b, n) = bias[k];
        eprintln!(
            "{name}: {n} texels, AO {:.3}, bias {b:+.4} (256-ray MC {:+.4})",
            1.0 + level[k].0,
            mc_bias[k].0
        );
        assert!(n > 20, "{name}: {n} texels");
        assert!(b.abs() < 0.006, "{name}: AO bias {b:+.4}");
    }
}

#[test]
fn curtains_keep_their_contact_against_monte_carlo() {
    // The thin cloth curtains (bundled in assets/): mean
    // AO bias of the contact texels (not filtered) and of all, against
    // 128-ray Monte Carlo (its noise averages out of a mean bias).
    let sc = bundled_scene("thin_cloth_curtains_intel_sponza.glb");
    // 12072 charts: one page at 512 texels needs no padding.
    let reference = bake_raw(
        &sc,
        aobake::BakeSettings {
            padding: 0,
            ..settings(512, 128, None)
        },
    );
    let mut s = aobake::BakeSettings {
        padding: 0,
        ..settings(512, DEFAULT_RAYS, None)
    };
    s.method = Method::Adaptive;
    let a = bake_raw(&sc, s);
    let st = a.adaptive_stats.as_ref().unwrap();
    let (mut all, mut contact) = ((0.0f64, 0usize), (0.0f64, 0usize));
    for i in 0..a.receivers.len() {
        let d = (a.bake.ao[i] - reference.bake.ao[i]) as f64;
        all = (all.0 + d, all.1 + 1);
        if st.sigma_texels[i] == 0.0 && st.z_min[i].is_finite() {
            contact = (contact.0 + d, contact.1 + 1);
        }
    }
    let (all, contact) = (all.0 / all.1 as f64, contact.0 / contact.1.max(1) as f64);
    eprintln!("curtains: bias all {all:+.4}, contact {contact:+.4}");
    assert!(all.abs() < 0.004, "bias {all:+.4}");
    assert!(contact.abs() < 0.004, "contact bias {contact:+.4}");
}

#[test]
fn scale_1e_minus_4_and_1e4_give_the_same_bake() {
    let sc = floor_and_wall();
    let mut s = settings(96, DEFAULT_RAYS, Some(1.0));
    s.method = Method::Adaptive;
    let base = bake_raw(&sc, s.clone());
    for scale in [1e-4, 1e4] {
        let mut t = s.clone();
        t.max_distance = Some(scale);
        let b = bake_raw(&aobake::report::scaled_scene(&sc, scale), t);
        let e = error_stats(&b.bake.ao, &base.bake.ao);
        assert!(e.rmse < 1e-3 && e.max < 0.05, "scale {scale}: {e:?}");
        assert!(b.bake.ao.iter().all(|v| v.is_finite()));
        assert!(b.bake.sh.iter().flatten().all(|v| v.is_finite()));
    }
}

/// A cheaper bake casts no more border-fit rays: the noise of a lower
/// `--quality` crosses more cells' step span, so the spans grow with it
/// (`border::step_span`). The Cornell box at 256, qualities 256, 64, 16:
/// the fit's rays per texel never rise as the quality drops, and at 16
/// they are fewer than at 256.
#[test]
fn the_border_fit_costs_no_more_as_the_quality_drops() {
    let sc = bundled_scene("cornell_box.glb");
    let rays_per_texel = |quality: u32| {
        let mut s = adaptive(256, 0, None);
        s.adaptive.quality = quality;
        let b = aobake::bake_scene(&sc, &s).unwrap();
        let border = b.report.border.expect("the fit traced points");
        border.rays as f64 / b.report.texels as f64
    };
    let r: Vec<f64> = [256, 64, 16].into_iter().map(rays_per_texel).collect();
    eprintln!("fit rays per texel at quality 256, 64, 16: {r:?}");
    assert!(r[1] <= r[0] && r[2] <= r[1], "{r:?}");
    assert!(r[2] < r[0], "{r:?}");
}

#[test]
fn a_part_of_a_page_bakes_to_the_whole_pages_values_a_halo_inside_it() {
    // The flight helmet at 128 with the visibility layer: the part is the
    // receivers within the halo of a window of the page; every receiver
    // of the window must get the whole page's value bit for bit, and
    // without the halo some must not (the neighbours feed the filter).
    on_layered_page("flight_helmet.glb", |page, s, timer| {
        let quiet = &aobake::RunOptions::QUIET;
        let whole = page.bake(s, quiet, timer).expect("whole");
        // The allocation's scale is the whole page's (PREV's, in a rebake).
        page.carry.scale = whole.adaptive_stats.expect("adaptive").scale;
        let whole = whole.bake;
        let r = &page.receivers;
        let w = r.width as i64;
        let (x0, x1, y0, y1) = (40i64, 72, 30, 70);
        let distance = |t: u32| {
            let (x, y) = (t as i64 % w, t as i64 / w);
            (x0 - x)
                .max(x - (x1 - 1))
                .max(y0 - y)
                .max(y - (y1 - 1))
                .max(0)
        };
        let halo = aobake::bake::adaptive::PageWide::halo(&s.adaptive) as i64;
        let mut differing = |grow: i64| {
            let part: Vec<u32> = (0..r.len() as u32)
                .filter(|&i| distance(r.texel[i as usize]) <= grow)
                .collect();
            let passes = page.bake_part(&part, s, quiet, timer).expect("part");
            let (b, layer) = (&passes.bake, whole.visibility.as_ref().expect("layer"));
            let (mut window, mut differ) = (0, 0);
            for (k, &i) in part.iter().enumerate() {
                if distance(r.texel[i as usize]) > 0 {
                    continue;
                }
                let i = i as usize;
                window += 1;
                let v = &b.visibility.as_ref().expect("layer").v[k];
                let same = b.ao[k].to_bits() == whole.ao[i].to_bits()
                    && b.sh[k].map(f32::to_bits) == whole.sh[i].map(f32::to_bits)
                    && v.map(f32::to_bits) == layer.v[i].map(f32::to_bits);
                differ += !same as usize;
            }
            (window, differ)
        };
        let (window, differ) = differing(halo);
        assert!(window > 300, "{window} receivers in the window");
        assert_eq!(
            differ, 0,
            "{differ} of {window} receivers differ with the halo"
        );
        let (_, differ) = differing(0);
        assert!(differ > 0, "without the halo every receiver matched");
    });
}

#[test]
fn the_lightmap_stage_of_a_part_gives_the_whole_pages_texels_or_nan() {
    // The Cornell box at 128 with the visibility layer, the border fit
    // and the seams' stitch: the lightmap stage of a window's part gives
    // each texel the whole page's value bit for bit, or NaN (not known).
    // (A page of small charts, such as the flight helmet's at 128, is one
    // solve component through its gutters: little of a part is known.)
    on_layered_page("cornell_box.glb", |page, s, timer| {
        let quiet = &aobake::RunOptions::QUIET;
        let whole = page.bake(s, quiet, timer).expect("whole");
        let out = page.finish(&whole, s, quiet, timer).expect("finish");
        let full = out.lightmap;
        // What a rebake carries: the allocation's scale and the solve's range.
        page.carry.scale = whole.adaptive_stats.as_ref().expect("adaptive").scale;
        page.carry.solve_range = out.encoded.solve_range.clone();
        let inside = whole.inside(page).to_vec();
        let r = &page.receivers;
        let w = r.width as i64;
        // The window lies farther than the halo from the page's edges, so
        // that the part's receivers around it are a halo deep.
        let (x0, x1, y0, y1) = (36i64, 84, 36, 84);
        let grow = aobake::bake::adaptive::PageWide::halo(&s.adaptive) as i64 + 6;
        assert!(grow - 6 <= x0.min(y0), "halo {}", grow - 6);
        let part: Vec<u32> = (0..r.len() as u32)
            .filter(|&i| {
                let t = r.texel[i as usize] as i64;
                let (x, y) = (t % w, t / w);
                x >= x0 - grow && x < x1 + grow && y >= y0 - grow && y < y1 + grow
            })
            .collect();
        let passes = page.bake_part(&part, s, quiet, timer).expect("part");
        // An edit that changes a block of texels in the window's middle: every
        // texel it can change is known. One at the part's edge: not.
        let block = |cx: i64, cy: i64| -> Vec<bool> {
            (0..(r.width * r.height) as i64)
                .map(|t| (t % w - cx).abs() <= 3 && (t / w - cy).abs() <= 3)
                .collect()
        };
        let mut lightmap_part = |changed: &[bool]| {
            page.lightmap_part(&part, &passes, &inside, changed, s, timer)
                .expect("lightmap of the part")
        };
        let missing = |built: &aobake::lightmap::Built| {
            let may_change = built.may_change.as_ref().expect("stitched");
            let missing = aobake::lightmap::known::missing(&built.lightmap, may_change);
            missing.iter().filter(|&&m| m).count()
        };
        let edge = lightmap_part(&block(x1 + grow - 2, (y0 + y1) / 2));
        assert!(missing(&edge) > 0);
        let built = lightmap_part(&block((x0 + x1) / 2, (y0 + y1) / 2));
        assert_eq!(missing(&built), 0);
        let lm = &built.lightmap;
        let (full_v, part_v) = (full.visibility.as_ref(), lm.visibility.as_ref());
        let (mut known, mut differ, mut covered_in_window, mut page_known) = (0, 0, 0, 0);
        for t in 0..lm.ao.len() {
            let (x, y) = (t as i64 % w, t as i64 / w);
            let in_window = x >= x0 && x < x1 && y >= y0 && y < y1;
            covered_in_window += (in_window && full.covered[t]) as usize;
            let v = part_v.expect("layer")[t];
            let finite = lm.ao[t].is_finite()
                && lm.sh[t].iter().all(|c| c.is_finite())
                && v.iter().all(|c| c.is_finite());
            if !finite {
                continue;
            }
            known += (in_window && full.covered[t]) as usize;
            page_known += full.covered[t] as usize;
            let same = lm.ao[t].to_bits() == full.ao[t].to_bits()
                && lm.sh[t].map(f32::to_bits) == full.sh[t].map(f32::to_bits)
                && v.map(f32::to_bits) == full_v.expect("layer")[t].map(f32::to_bits);
            differ += !same as usize;
        }
        assert_eq!(
            differ, 0,
            "{differ} known texels differ from the whole page's"
        );
        // Most of the window is known (what is not: texels whose seams or
        // solve components reach out of the part), and the page outside the
        // part is not.
        assert!(
            known * 10 >= covered_in_window * 9,
            "{known} of the window's {covered_in_window} covered texels known"
        );
        let covered = full.covered.iter().filter(|&&c| c).count();
        assert!(page_known * 2 < covered, "{page_known} of {covered} known");
    });
}

/// The bundled scene `name` on one 128 page with the visibility layer,
/// its page handed to `f` with the settings and a timer: what the tests of
/// a bake of part of a page start from.
fn on_layered_page(
    name: &str,
    f: impl FnOnce(&mut aobake::job::Page<'_>, &aobake::BakeSettings, &mut aobake::stage::StageTimer),
) {
    let sc = bundled_scene(name);
    let mut s = adaptive(128, 64, None);
    s.visibility = aobake::job::settings::VisibilityMode::All;
    let mut timer = aobake::stage::StageTimer::new();
    let quiet = &aobake::RunOptions::QUIET;
    let level = aobake::job::Level::new(&sc, &s, quiet, &mut timer).expect("level");
    let mut page = level.page(0, &sc, &mut timer).expect("page");
    f(&mut page, &s, &mut timer);
}

#[test]
fn two_rounds_with_no_receiver_set_bake_as_one_round() {
    // The flight helmet's smooth normals tilt from its faces, so filtered
    // receivers have pre-pass rays below their plane to take out once: a
    // bake whose first round stops every receiver at a fit point's count
    // and whose second continues them all must give the one round's
    // values bit for bit.
    let sc = bundled_scene("flight_helmet.glb");
    let mut s = adaptive(128, 0, None);
    s.fill_inside = true;
    let mut timer = aobake::stage::StageTimer::new();
    let level = aobake::job::Level::new(&sc, &s, &aobake::RunOptions::QUIET, &mut timer).unwrap();
    let page = level.page(0, &sc, &mut timer).unwrap();
    let p = aobake::bake::BakeParams {
        max_distance: level.max_distance,
        seed: 9,
    };
    let run = |sets: Option<&aobake::bake::adaptive::FitSets>| {
        aobake::bake::adaptive::bake(
            &page.receivers,
            &level.tracer,
            true,
            true,
            &s.adaptive,
            aobake::bake::adaptive::PageWide::default(),
            sets,
            &p,
            &mut aobake::stage::StageTimer::new(),
            &|_| {},
        )
    };
    let (one, one_stats) = run(None);
    let none = |ao: &[f32], _: &[bool]| vec![false; ao.len()];
    let (two, two_stats) = run(Some(&none));
    let cap = aobake::bake::adaptive::fit_set_rays(&s.adaptive);
    let continued = one_stats.rays.iter().filter(|&&n| n > cap).count();
    assert!(
        continued > 100,
        "{continued} receivers past the first round"
    );
    assert_eq!(one_stats.rays, two_stats.rays);
    assert_eq!(one.ao, two.ao);
    assert_eq!(one.sh, two.sh);
    assert_eq!(one.visibility.unwrap().v, two.visibility.unwrap().v);
    // Every receiver set: each stops at the first round's count.
    let all = |ao: &[f32], _: &[bool]| vec![true; ao.len()];
    let (_, capped) = run(Some(&all));
    for (a, b) in capped.rays.iter().zip(&one_stats.rays) {
        assert_eq!(*a, (*b).min(cap));
    }
}

#[test]
fn receivers_the_fit_sets_stop_at_a_fit_points_rays_and_the_rest_keep_theirs() {
    // A box on a floor: its contact lines are step cells the border fit
    // sets. The default bake against the same bake with the fit off (one
    // round, nothing set), receiver by receiver: the same allocation, the
    // set receivers stopped at a fit point's count.
    let sc = boxes_on_a_floor(&[([0.2, 0.2, 0.0], [0.3, 0.4, 0.1])]);
    let mut s = settings(256, DEFAULT_RAYS, Some(0.3));
    s.method = Method::Adaptive;
    let fit = bake_raw(&sc, s.clone());
    s.border = aobake::lightmap::border::BorderMode::Off;
    let off = bake_raw(&sc, s.clone());
    let cap = aobake::bake::adaptive::fit_set_rays(&s.adaptive);
    let (a, b) = (
        &fit.adaptive_stats.as_ref().unwrap().rays,
        &off.adaptive_stats.as_ref().unwrap().rays,
    );
    assert_eq!(a.len(), b.len());
    let mut set = 0;
    for (k, (&a, &b)) in a.iter().zip(b).enumerate() {
        assert!(
            a == b || (a == cap && b > cap),
            "receiver {k}: {a} against {b}"
        );
        set += (a < b) as usize;
    }
    let past = a.iter().filter(|&&n| n > cap).count();
    eprintln!("{set} receivers set, {past} past the cap, of {}", a.len());
    assert!(set > 50, "{set}");
    assert!(past > 50, "{past}");
}
