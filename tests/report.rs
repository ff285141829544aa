//! `aobake report`: the figures it prints are computed right, and it works
//! on every bakeable scene.

mod common;
use aobake::report::metrics::error_stats;
use aobake::report::{self, ReportSettings, parse_budgets};
use aobake::stage::StageTimer;
use common::*;
use serde_json::Value;
use std::path::Path;

/// The seconds of `stage` in a JSON list of stage times (0 if absent).
fn seconds_of_stage(stages: &Value, stage: &str) -> f64 {
    (stages.as_array().unwrap().iter())
        .find(|s| s["stage"] == stage)
        .map_or(0.0, |s| s["seconds"].as_f64().unwrap())
}

fn small(budgets: &str, reference_rays: u32, stability_rays: u32) -> ReportSettings {
    ReportSettings {
        resolution: 48,
        reference_rays,
        budgets: parse_budgets(budgets).unwrap(),
        seed: 3,
        max_distance: None,
        stability_rays,
        engine_view_points: 2000,
        include_defaults: true,
        progress: false,
    }
}

#[test]
fn an_open_plane_has_zero_error_in_every_run() {
    let g = glb(
        &[quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true)],
        plain_nodes(1),
    );
    let sweep = report::sweep(
        &scene(&g),
        "plane",
        StageTimer::new(),
        &small("mc:4,filtered:2:4", 32, 4),
    )
    .unwrap();
    let r = &sweep.report;
    // The two runs asked for plus the defaults of each method (Monte
    // Carlo, adaptive, and sheared, which is swept).
    assert_eq!(r.runs.len(), 5);
    for run in &r.runs {
        assert_eq!(run.ao.rmse, 0.0, "{}", run.label);
        assert_eq!(run.ao.bias, 0.0, "{}", run.label);
        assert_eq!(run.ao.max, 0.0, "{}", run.label);
        assert!(
            run.sh_rmse_band.iter().all(|e| e.is_finite()),
            "{}",
            run.label
        );
    }
    // SH of an open hemisphere: every method takes its exact projection
    // (Monte Carlo and adaptive through the control variate).
    for run in &r.runs {
        assert!(run.sh_rmse < 1e-6, "{}: SH RMSE {}", run.label, run.sh_rmse);
    }
    // Where the engine reads, too: the written textures looked up at 2000
    // surface points equal the open hemisphere's AO = 1 and SH, at chart
    // borders as inside.
    for run in &r.runs {
        let e = run.engine_view.expect("measured");
        assert_eq!(e.all.points, 2000, "{}", run.label);
        assert!(e.border.points > 0, "{}", run.label);
        assert!(e.all.ao_rmse < 1e-6, "{}: {e:?}", run.label);
        assert!(e.all.sh_rmse < 1e-5, "{}: {e:?}", run.label);
    }
    // A zero target error: no equal-error comparison, and still a report.
    assert!(r.equal_error.is_none());
    let dir = tempfile::tempdir().unwrap();
    report::write_report(&sweep, dir.path()).unwrap();
    assert!(dir.path().join("error_vs_time.png").exists());
}

#[test]
fn errors_match_an_independent_computation_and_fall_with_rays() {
    // Receiver beside a wall: AO varies over the receiver.
    let recv = quad([0.0; 3], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 0.5, 0.0], true);
    let g = glb(&[recv, wall], plain_nodes(2));
    let sweep = report::sweep(
        &scene(&g),
        "wall",
        StageTimer::new(),
        &small("mc:4,mc:16,mc:64", 1024, 8),
    )
    .unwrap();
    let r = &sweep.report;
    let rmse = |label: &str| r.runs.iter().find(|x| x.label == label).unwrap().ao.rmse;
    // Stratified Monte Carlo error falls at least as 1/sqrt(rays).
    assert!(
        rmse("mc:4") > 1.9 * rmse("mc:16"),
        "{} {}",
        rmse("mc:4"),
        rmse("mc:16")
    );
    assert!(rmse("mc:16") > 1.9 * rmse("mc:64"));
    assert!(rmse("mc:64") > rmse("mc:256"));
    // The default run's RMSE, bias and max, recomputed here by hand over
    // the texels compared: those inside geometry (the wall's foot) hold the
    // reference's value in the maps, a difference of 0, and are not counted.
    let (label, ao) = &sweep.default_ao[0];
    let run = r.runs.iter().find(|x| &x.label == label).unwrap();
    let n = (ao.len() - r.texels_inside) as f64;
    let d: Vec<f64> = ao
        .iter()
        .zip(&sweep.reference_ao)
        .map(|(a, b)| *a as f64 - *b as f64)
        .collect();
    let by_hand = (d.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    assert!(
        (run.ao.rmse - by_hand).abs() < 1e-12,
        "{} against {by_hand}",
        run.ao.rmse
    );
    assert!((run.ao.bias - d.iter().sum::<f64>() / n).abs() < 1e-12);
    assert!((run.ao.max - d.iter().fold(0.0f64, |m, x| m.max(x.abs()))).abs() < 1e-12);
    // The reference against itself has no error; a known offset is its bias.
    let refs = &sweep.reference_ao;
    assert_eq!(error_stats(refs, refs).rmse, 0.0);
    let shifted: Vec<f32> = refs.iter().map(|v| v - 0.25).collect();
    assert!((error_stats(&shifted, refs).bias + 0.25).abs() < 1e-6);
    // Equal-error target: the 256-ray run's own error, reached by MC at its time.
    let e = r.equal_error.as_ref().unwrap();
    assert_eq!(e.target_ao_rmse, rmse("mc:256"));
    // Scale stability: 1e-4 and 1e4 give the same AO within noise.
    assert_eq!(r.stability.len(), 2);
    for row in &r.stability {
        assert!(row.same_within_noise, "{row:?}");
        assert!(row.ao_rmse_difference <= row.monte_carlo_noise_rmse);
    }
}

#[test]
fn cli_writes_every_file_and_refuses_bad_budgets() {
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box.glb");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rep");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
        .args(["report"])
        .arg(&input)
        .arg("--out")
        .arg(&out)
        .args(["--resolution", "48", "--reference-rays", "64"])
        .args([
            "--budgets",
            "mc:4,mc:16,filtered:2:4",
            "--stability-rays",
            "8",
            "-q",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 6);
    assert!(json["cores"].as_u64().unwrap() >= 1);
    assert_eq!(json["reference_rays"], 64);
    assert_eq!(json["stability"].as_array().unwrap().len(), 2);
    // The engine view is measured by default and plotted beside the
    // texel-centre plot.
    assert!(
        json["runs"][0]["engine_view"]["all"]["points"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert!(out.join("engine_view_vs_time.png").exists());
    // Each run pays its own output stages (border fit, seams, encode): its
    // end-to-end time is the shared stages, its passes and them, and the
    // equal-error comparison is made on the engine view too, its target
    // 256-ray Monte Carlo's engine-view error.
    let shared = json["shared_seconds"].as_f64().unwrap();
    for run in json["runs"].as_array().unwrap() {
        let (bake, output) = (
            run["bake_seconds"].as_f64().unwrap(),
            run["output_seconds"].as_f64().unwrap(),
        );
        assert!(output > 0.0, "{run}");
        let sum = shared + bake + output
            - if run["method"] == "adaptive" {
                seconds_of_stage(&json["shared_stages"], "validity")
            } else {
                0.0
            };
        assert!(
            (run["end_to_end_seconds"].as_f64().unwrap() - sum).abs() < 1e-9,
            "{run}"
        );
        let stages: Vec<&str> = (run["passes"].as_array().unwrap().iter())
            .map(|s| s["stage"].as_str().unwrap())
            .collect();
        assert!(
            stages.contains(&"seams") && stages.contains(&"encode"),
            "{stages:?}"
        );
    }
    let mc256 = json["runs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["label"] == "mc:256")
        .unwrap();
    assert_eq!(
        json["equal_engine_view"]["target_ao_rmse"],
        mc256["engine_view"]["all"]["ao_rmse"]
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("**Equal engine-view error**"), "{md}");
    for f in json["files"].as_array().unwrap() {
        assert!(out.join(f.as_str().unwrap()).exists(), "{f}");
    }
    let (w, h) = (
        json["atlas_width"].as_u64().unwrap(),
        json["atlas_height"].as_u64().unwrap(),
    );
    let map = image::open(out.join("error_map_mc_256.png")).unwrap();
    assert_eq!((map.width() as u64, map.height() as u64), (w, h));
    let plot = image::open(out.join("error_vs_time.png")).unwrap();
    assert_eq!((plot.width(), plot.height()), (900, 600));
    let svg = std::fs::read_to_string(out.join("error_vs_time.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("Monte Carlo"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("| mc:256 (default) |") && md.contains("Scale stability"));

    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
        .args(["report"])
        .arg(&input)
        .arg("--out")
        .arg(dir.path().join("bad"))
        .args(["--budgets", "mc:0"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let stderr = String::from_utf8(bad.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("for '--budgets <LIST>': 'mc:0'"),
        "{stderr}"
    );
    assert!(!dir.path().join("bad").exists());
}

/// Every bakeable test scene in `assets/` gets a report (tiny budgets;
/// the scale-stability bakes, which unwrap the scene twice more, only on the
/// scenes whose atlas fits in 256 texels).
#[test]
fn report_works_on_every_bakeable_test_scene() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    // The smallest page each scene's charts fit on as asked (as in
    // tests/assets.rs).
    let scenes = [
        ("boombox_tiny_scale.glb", 256),
        ("cornell_box.glb", 32),
        ("flight_helmet.glb", 512),
        ("foliage_tree_cesium.glb", 256),
        ("generated/cad_instances.glb", 512),
        ("generated/courtyard.glb", 512),
        ("generated/dense_detail.glb", 256),
        ("../tests/data/lantern_quantized.glb", 256),
        ("mixed_lighting_sheen_chair.glb", 512),
        ("negative_scale_floor.glb", 32),
        ("primitive_mode_04_tristrip_nonindexed.glb", 32),
        ("primitive_mode_05_trifan_nonindexed.glb", 32),
        ("primitive_mode_06_triangles_nonindexed.glb", 32),
        ("primitive_mode_11_tristrip_indexed.glb", 32),
        ("primitive_mode_12_trifan_indexed.glb", 32),
        ("primitive_mode_14_triangles_u8_indices.glb", 32),
        ("simple_meshes_shared_mesh.glb", 32),
        ("simple_sparse_accessor.glb", 32),
        ("thin_cloth_curtains_intel_sponza.glb", 1024),
        ("tricky_fern_mask_without_alpha.glb", 512),
    ];
    for (name, resolution) in scenes {
        let start = std::time::Instant::now();
        let scene = aobake::gltf::load(&assets.join(name)).unwrap();
        let s = ReportSettings {
            resolution,
            include_defaults: false,
            stability_rays: if resolution <= 256 { 4 } else { 0 },
            engine_view_points: 500,
            ..small("mc:4,filtered:4:2", 16, 0)
        };
        let sweep = report::sweep(&scene, name, StageTimer::new(), &s)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let dir = tempfile::tempdir().unwrap();
        let r = report::write_report(&sweep, dir.path()).unwrap();
        assert_eq!(r.runs.len(), 2);
        for run in &r.runs {
            assert!(
                run.ao.rmse.is_finite() && run.ao.rmse < 0.5,
                "{name} {}",
                run.label
            );
        }
        for row in &r.stability {
            assert!(row.same_within_noise, "{name}: {row:?}");
        }
        eprintln!("{name}: {:.1} s", start.elapsed().as_secs_f64());
    }
}
