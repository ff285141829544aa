//! The filtered method against closed forms and brute force, on scenes
//! built to leak, and on degenerate input.

mod common;
use aobake::{Method, sh};
use common::*;
use glam::Vec3;

fn filtered(resolution: u32, max_distance: Option<f64>) -> aobake::BakeSettings {
    aobake::BakeSettings {
        method: Method::Sheared,
        ..settings(
            resolution,
            aobake::job::settings::DEFAULT_RAYS,
            max_distance,
        )
    }
}

#[test]
fn open_plane_is_exactly_open() {
    let g = glb(
        &[quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)],
        plain_nodes(1),
    );
    let b = aobake::bake_scene(&scene(&g), &filtered(64, None)).unwrap();
    let want = sh::open_hemisphere(Vec3::Z);
    let stats = b.sheared_stats.as_ref().unwrap();
    assert_eq!(
        stats.receivers_open as usize,
        b.receivers.len(),
        "every texel takes the open early-out"
    );
    assert_eq!(
        stats.brute_rays, 0,
        "no second pass where nothing is marked"
    );
    for i in 0..b.receivers.len() {
        assert_eq!(b.bake.ao[i], 1.0);
        assert_eq!(b.bake.sh[i], want);
    }
}

#[test]
fn too_few_rays_on_an_open_plane_brute_force_every_cell_as_no_hit() {
    // One sparse ray per texel and a one-texel gather: far fewer than one
    // ray per cell reaches each receiver, so no receiver takes the open
    // early-out and every cell, having seen no occluder but fewer than
    // MIN_CELL_SAMPLES misses, is brute-forced and counted as no-hit (none
    // as contact). The brute-force rays find the plane open.
    let g = glb(
        &[quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)],
        plain_nodes(1),
    );
    let mut s = filtered(32, None);
    s.sheared.sparse_rays = 1;
    s.sheared.gather_radius = 1.0;
    let b = aobake::bake_scene(&scene(&g), &s).unwrap();
    let stats = b.sheared_stats.as_ref().unwrap();
    let cells = 64 * b.receivers.len() as u64;
    assert_eq!(stats.receivers_open, 0);
    assert_eq!(stats.cells_brute, cells);
    assert_eq!(stats.cells_no_hit, cells);
    assert_eq!(stats.cells_contact, 0);
    assert!(b.bake.ao.iter().all(|&a| a == 1.0));
}

#[test]
fn parallel_plane_matches_closed_form() {
    // As in tests/analytic.rs: AO = (h/D)^2 for a receiver under a plane.
    let recv = quad([0.0; 3], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0], true);
    let occ = quad([0.0, 0.0, 1.0], [0.0, 2.2, 0.0], [2.2, 0.0, 0.0], true);
    let g = glb(&[recv, occ], plain_nodes(2));
    let b = aobake::bake_scene(&scene(&g), &filtered(256, Some(2.0))).unwrap();
    let s = &b.geometry.space;
    let mut sum = 0.0f64;
    let mut n = 0;
    for i in 0..b.receivers.len() {
        let p = s.to_world(b.receivers.position[i]);
        if p.z.abs() < 1e-3 && p.x.abs() < 0.2 && p.y.abs() < 0.2 {
            sum += b.bake.ao[i] as f64;
            n += 1;
        }
    }
    assert!(n > 50, "{n}");
    let mean = sum / n as f64;
    assert!((mean - 0.25).abs() < 0.03, "filtered AO {mean} vs 0.25");
}

#[test]
fn no_leak_across_a_thin_wall() {
    let g = thin_wall_scene();
    let sc = scene(&g);
    let mc = aobake::bake_scene(&sc, &settings(256, 512, Some(0.5))).unwrap();
    let f = aobake::bake_scene(&sc, &filtered(256, Some(0.5))).unwrap();
    assert_eq!(mc.receivers.texel, f.receivers.texel);
    let s = &f.geometry.space;
    // Floor texels within 0.1 of the wall on each side, and the wall faces.
    let (mut covered, mut open, mut faces) = (vec![], vec![], vec![]);
    for i in 0..f.receivers.len() {
        let p = s.to_world(f.receivers.position[i]);
        let d = (f.bake.ao[i] - mc.bake.ao[i]) as f64;
        if p.z.abs() < 1e-4 && p.y.abs() < 0.8 {
            if (-0.1..-0.01).contains(&p.x) {
                covered.push(d);
            } else if (0.01..0.1).contains(&p.x) {
                open.push(d);
            }
        } else if p.x.abs() < 0.002 && p.z > 0.01 && p.z < 0.07 {
            faces.push(d);
        }
    }
    for (name, v) in [
        ("covered floor", &covered),
        ("open floor", &open),
        ("wall faces below the slab", &faces),
    ] {
        assert!(v.len() > 30, "{name}: {} texels", v.len());
        let bias = v.iter().sum::<f64>() / v.len() as f64;
        let mean_abs = v.iter().map(|d| d.abs()).sum::<f64>() / v.len() as f64;
        assert!(
            bias.abs() < 0.03 && mean_abs < 0.05,
            "{name}: bias {bias:+.4}, mean |err| {mean_abs:.4}"
        );
    }
}

#[test]
fn curtains_match_brute_force() {
    let sc = bundled_scene("thin_cloth_curtains_intel_sponza.glb");
    let mc = aobake::bake_scene(&sc, &settings(1024, 64, None)).unwrap();
    let f = aobake::bake_scene(&sc, &filtered(1024, None)).unwrap();
    let e = aobake::report::metrics::error_stats(&f.bake.ao, &mc.bake.ao);
    let (bias, rmse) = (e.bias, e.rmse);
    // A leak through the cloth shows as a large bright bias.
    assert!(
        bias.abs() < 0.01 && rmse < 0.05,
        "curtains: bias {bias:+.4}, RMSE {rmse:.4}"
    );
}

#[test]
fn degenerate_and_sliver_triangles_never_give_nan() {
    // A sliver, a zero-area triangle, a triangle with zero UV area after
    // unwrapping (collinear), next to a normal quad, under a close plane.
    let mut parts = vec![quad([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], false)];
    parts.push(MeshSpec {
        positions: vec![
            [0.0, 0.0, 0.001],
            [1.0, 0.0, 0.001],
            [0.5, 1e-7, 0.001],
            [0.2, 0.2, 0.0],
            [0.2, 0.2, 0.0],
            [0.2, 0.2, 0.0],
        ],
        normals: None,
        indices: vec![0, 1, 2, 3, 4, 5],
    });
    parts.push(quad(
        [0.0, 0.0, 1e-4],
        [0.0, 0.3, 0.0],
        [0.3, 0.0, 0.0],
        true,
    ));
    let g = glb(&parts, plain_nodes(3));
    let b = aobake::bake_scene(&scene(&g), &filtered(64, None)).unwrap();
    assert!(
        b.bake
            .ao
            .iter()
            .all(|a| a.is_finite() && (0.0..=1.0).contains(a))
    );
    assert!(b.bake.sh.iter().flatten().all(|c| c.is_finite()));
    let covered = b.bake.ao.iter().filter(|&&a| a < 0.5).count();
    let mc = aobake::bake_scene(&scene(&g), &settings(64, 64, None)).unwrap();
    let covered_mc = mc.bake.ao.iter().filter(|&&a| a < 0.5).count();
    assert!(
        covered > 0,
        "the plane 1e-4 above must darken part of the quad: filtered {covered}, mc {covered_mc}, of {}",
        b.bake.ao.len()
    );
}

#[test]
fn filtered_output_is_identical_for_any_thread_count() {
    let g = thin_wall_scene();
    let run = |threads| glb_on_threads(&g, &filtered(64, Some(0.5)), threads);
    assert!(run(1) == run(2));
}

#[test]
fn tilted_shading_normals_match_brute_force() {
    // A plane whose shading normals lean 60 degrees off its geometric
    // normal: the part of the shading hemisphere below the surface is
    // occluded by the surface itself (AO well below 1, as Monte Carlo says).
    let mut q = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let (s, c) = (60f32.to_radians().sin(), 60f32.to_radians().cos());
    q.normals = Some(vec![[0.0, s, c]; 4]);
    let g = glb(&[q], plain_nodes(1));
    let sc = scene(&g);
    let mc = aobake::bake_scene(&sc, &settings(64, 256, None)).unwrap();
    let f = aobake::bake_scene(&sc, &filtered(64, None)).unwrap();
    let mean = |v: &[f32]| v.iter().map(|&a| a as f64).sum::<f64>() / v.len() as f64;
    assert!(
        mean(&mc.bake.ao) < 0.9,
        "the surface occludes part of the hemisphere: {}",
        mean(&mc.bake.ao)
    );
    assert!(
        (mean(&f.bake.ao) - mean(&mc.bake.ao)).abs() < 0.02,
        "filtered {} vs mc {}",
        mean(&f.bake.ao),
        mean(&mc.bake.ao)
    );
}

#[test]
fn floor_beside_a_wall_beats_64_ray_monte_carlo() {
    // A floor with a wall standing on it, filtered with a wide gather
    // (K 8, radius 8, where most cells are filtered, not brute-forced), against
    // a 1024-ray Monte Carlo reference on the same receivers: the filter
    // must be unbiased within 0.005 and closer to the reference than an
    // independent 64-ray Monte Carlo bake is.
    let sc = floor_and_wall();
    let bake = |s: aobake::BakeSettings| bake_raw(&sc, s);
    let reference = bake(aobake::BakeSettings {
        seed: 11,
        ..settings(128, 1024, Some(1.0))
    });
    let mc = bake(settings(128, 64, Some(1.0)));
    let mut f = filtered(128, Some(1.0));
    f.sheared.sparse_rays = 8;
    f.sheared.gather_radius = 8.0;
    let f = bake(f);
    let stats = f.sheared_stats.as_ref().unwrap();
    assert!(
        stats.cell_share(stats.cells_brute) < 0.2,
        "most cells filtered: {}",
        stats.cell_share(stats.cells_brute)
    );
    // Floor receivers in front of the wall.
    let s = &reference.geometry.space;
    let sel: Vec<usize> = (0..reference.receivers.len())
        .filter(|&i| {
            let p = s.to_world(reference.receivers.position[i]);
            p.z.abs() < 1e-3 && p.x < 0.29 && p.y.abs() < 0.6
        })
        .collect();
    assert!(sel.len() > 1000, "{}", sel.len());
    let err = |b: &aobake::job::Baked| {
        let (mut bias, mut sq) = (0.0f64, 0.0f64);
        for &i in &sel {
            let e = (b.bake.ao[i] - reference.bake.ao[i]) as f64;
            bias += e;
            sq += e * e;
        }
        (bias / sel.len() as f64, (sq / sel.len() as f64).sqrt())
    };
    let (f_bias, f_rmse) = err(&f);
    let (_, mc_rmse) = err(&mc);
    eprintln!("filtered bias {f_bias} rmse {f_rmse}, mc64 {mc_rmse}");
    assert!(f_bias.abs() < 0.005, "filtered bias {f_bias}");
    assert!(
        f_rmse < mc_rmse,
        "filtered RMSE {f_rmse} vs 64-ray Monte Carlo {mc_rmse}"
    );
}

#[test]
fn a_sheet_just_above_a_floor_lends_it_no_rays() {
    // A single-sided square 0.005 above a floor (a quarter of a texel), like
    // the Cornell box's light quad under its ceiling: the floor under it
    // sees the square's back at 0.005 and is dark. The square's own texels
    // are parallel, nearly coplanar neighbours that see the open sky; if
    // they lent their rays, the hidden floor would come out bright.
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let sheet = quad([0.0, 0.0, 0.005], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0], true);
    // A roof off to one side gives the sheet's texels occluders at 0.2-0.4,
    // so cells of the hidden floor get a z_min far from contact and would
    // be filtered with the sheet's open rays.
    let roof = quad([0.4, 0.0, 0.2], [0.0, 0.6, 0.0], [0.3, 0.0, 0.0], true);
    let sc = scene(&glb(&[floor, sheet, roof], plain_nodes(3)));
    let bake = |s: aobake::BakeSettings| {
        let mut s = s;
        s.fill_inside = false;
        aobake::bake_scene(&sc, &s).unwrap()
    };
    let mc = bake(settings(128, 256, Some(0.5)));
    let f = bake(filtered(128, Some(0.5)));
    let s = &mc.geometry.space;
    let under: Vec<usize> = (0..mc.receivers.len())
        .filter(|&i| {
            let p = s.to_world(mc.receivers.position[i]);
            p.z.abs() < 1e-4 && p.x.abs() < 0.2 && p.y.abs() < 0.2
        })
        .collect();
    assert!(under.len() > 100, "{}", under.len());
    let mean = |b: &aobake::job::Baked| {
        under.iter().map(|&i| b.bake.ao[i] as f64).sum::<f64>() / under.len() as f64
    };
    eprintln!("hidden floor: mc {} filtered {}", mean(&mc), mean(&f));
    assert!(mean(&mc) < 0.05, "hidden floor is dark: {}", mean(&mc));
    assert!(
        // Measured: 0.016 too bright when the sheet lent its rays, 0 now.
        (mean(&f) - mean(&mc)).abs() < 0.005,
        "filtered {} vs Monte Carlo {}",
        mean(&f),
        mean(&mc)
    );
}

#[test]
fn a_wall_top_edge_does_not_darken_the_floor() {
    // The wall's top edge crosses hemisphere cells of the floor receivers in
    // front of it. With dense sparse rays (K = 32) and a wide gather, nearly
    // every cell is filtered, so the mean error over the floor band 0.1-0.5
    // from the wall is the filter's bias. Misses from neighbours must be
    // re-aimed consistently on both sides of a cell boundary; re-aiming
    // an open cell's misses at infinity while its occluded neighbour re-aims
    // at the mid depth loses open rays from the edge's cells and biased this
    // band dark by 0.006 (now 0.0009).
    let sc = floor_and_wall();
    let bake = |s: aobake::BakeSettings| bake_raw(&sc, s);
    let reference = bake(aobake::BakeSettings {
        seed: 11,
        ..settings(192, 2048, Some(1.0))
    });
    let mut f = filtered(192, Some(1.0));
    f.sheared.gather_radius = 8.0;
    f.sheared.sparse_rays = 32;
    let f = bake(f);
    let stats = f.sheared_stats.as_ref().unwrap();
    let brute = stats.cell_share(stats.cells_brute);
    assert!(brute < 0.1, "brute-forced {brute}");
    let s = &reference.geometry.space;
    let sel: Vec<usize> = (0..reference.receivers.len())
        .filter(|&i| {
            let p = s.to_world(reference.receivers.position[i]);
            p.z.abs() < 1e-3 && (-0.2..0.2).contains(&p.x) && p.y.abs() < 0.6
        })
        .collect();
    assert!(sel.len() > 1000, "{}", sel.len());
    let bias = sel
        .iter()
        .map(|&i| (f.bake.ao[i] - reference.bake.ao[i]) as f64)
        .sum::<f64>()
        / sel.len() as f64;
    eprintln!("bias {bias} over {} receivers", sel.len());
    assert!(bias.abs() < 0.002, "filtered bias {bias}");
}

#[test]
fn second_pass_continues_the_sparse_sequence() {
    // Every cell brute-forced (min weight out of reach): the second pass is
    // then Monte Carlo over the whole hemisphere with cell_rays = 2, 128
    // points of the receiver's sparse Sobol sequence, of which the 8 sparse
    // rays are reused, not traced again. Against the closed form of a
    // receiver beside a wall it must be as accurate as 128-ray Monte Carlo
    // (same sequence type, another seed); m rays drawn per cell
    // independently lose the sequence's stratification across cells.
    let (a, d) = (0.5f32, 1.0f64);
    let recv = quad([0.0; 3], [0.25, 0.0, 0.0], [0.0, 0.25, 0.0], true);
    let wall = quad([a, 0.0, 1.2], [0.0, 0.0, 1.2], [0.0, 1.2, 0.0], true);
    let sc = scene(&glb(&[recv, wall], plain_nodes(2)));
    let mut f = filtered(256, Some(d));
    f.sheared.sparse_rays = 8;
    f.sheared.min_weight = 1e9;
    let f = aobake::bake_scene(&sc, &f).unwrap();
    let mc = aobake::bake_scene(&sc, &settings(256, 128, Some(d))).unwrap();
    let s = &f.geometry.space;
    let rmse = |b: &aobake::job::Baked| {
        let (mut sq, mut n) = (0.0f64, 0usize);
        for i in 0..b.receivers.len() {
            let p = s.to_world(b.receivers.position[i]);
            if p.z.abs() > 1e-4 || p.x.abs() > 0.24 || p.y.abs() > 0.24 {
                continue;
            }
            // Closed form (tests/analytic.rs): s = distance to the wall / D.
            let sw = (a - p.x) as f64 / d;
            let want = 1.0 - (sw.acos() - sw * (1.0 - sw * sw).sqrt()) / std::f64::consts::PI;
            sq += (b.bake.ao[i] as f64 - want).powi(2);
            n += 1;
        }
        assert!(n > 1000, "{n}");
        (sq / n as f64).sqrt()
    };
    let (f_rmse, mc_rmse) = (rmse(&f), rmse(&mc));
    eprintln!("all-brute filtered {f_rmse}, mc128 {mc_rmse}");
    let stats = f.sheared_stats.as_ref().unwrap();
    assert_eq!(stats.cells_filtered, 0);
    // Receivers that saw an occluder: 120 new rays each (128 less the 8
    // reused), fewer only for rays below the geometric horizon.
    let receivers = f.receivers.len() as u64 - stats.receivers_open;
    let per = stats.brute_rays as f64 / receivers as f64;
    assert!((115.0..=120.0).contains(&per), "{per} rays per receiver");
    assert!(f_rmse < 1.1 * mc_rmse, "{f_rmse} vs {mc_rmse}");
}
