//! The GPU backend (`trace::gpu`, feature `gpu`) against closed forms and
//! against the CPU backend, on whatever Vulkan adapter the machine has:
//! Mesa's lavapipe where there is no GPU (`.ci/run` installs
//! `mesa-vulkan-drivers`), which runs the same shader on the CPU.
//!
//! Without any Vulkan adapter the tests say so and pass, except under CI
//! (`CI` set) or with `AOBAKE_REQUIRE_TOOLS` set, where they fail.

mod common;

use aobake::trace::gpu::{Adapters, GpuAnswer, GpuTracer};
use aobake::trace::{Closest, Hit, RayBatch, Tracer};
use glam::{Vec3, Vec3A};

/// A tracer on any adapter, or `None` (with the note) where there is none;
/// any other failure (a shader or a limit the driver refuses) fails.
fn gpu(occluders: &[[Vec3A; 3]]) -> Option<GpuTracer> {
    match GpuTracer::new(occluders, Adapters::Any) {
        Ok(t) => Some(t.expect("triangles given")),
        Err(e) if !e.to_string().contains("no Vulkan adapter found") => {
            panic!("the GPU backend failed to start: {e}")
        }
        Err(e) => {
            let missing = format!("a Vulkan adapter (mesa-vulkan-drivers for lavapipe): {e}");
            assert!(!common::tools_present("the GPU tests", &[missing.as_str()]));
            None
        }
    }
}

/// A CPU tracer with `gpu` attached: the bake's way to the GPU, whose
/// candidates it settles with the CPU's triangle test.
fn attached(occluders: &[[Vec3A; 3]], gpu: GpuTracer) -> Tracer {
    let mut tracer = Tracer::new(occluders);
    gpu.attach_to(&mut tracer);
    tracer
}

/// Whether the GPU's occlusion answers are the CPU's where it is sure:
/// every ray `cpu` finds occluded is a hit or unsure (the margins cover
/// the GPU's rounding), and every sure hit is occluded on the CPU (the
/// rounding bound holds). The count of unsure rays (traced on the CPU).
fn answers_cover(gpu: &GpuTracer, cpu: &Tracer, rays: &RayBatch) -> usize {
    let (mut answers, mut on_cpu) = (Vec::new(), Vec::new());
    gpu.occlusion(rays, &mut answers).unwrap();
    cpu.occluded_batch(rays, &mut on_cpu);
    for i in (0..rays.len()).filter(|&i| !rays.is_blocked(i)) {
        assert!(
            !on_cpu[i] || answers[i] != GpuAnswer::Miss,
            "ray {i} is occluded on the CPU and a sure miss on the GPU"
        );
        assert!(
            on_cpu[i] || answers[i] != GpuAnswer::Hit,
            "ray {i} is a sure hit on the GPU and not occluded on the CPU"
        );
    }
    (0..rays.len())
        .filter(|&i| !rays.is_blocked(i) && answers[i] == GpuAnswer::Unsure)
        .count()
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
    let adapter = gpu.adapter().clone();
    let tracer = attached(&quad(0.2), gpu);
    let mut out = Vec::new();
    tracer.occluded_batch(&rays, &mut out);
    assert_eq!(tracer.accelerator_failure(), None);
    assert_eq!(out, expected, "on {adapter:?}");
}

/// Rays along triangle edges and through vertices, where the triangle
/// test decides by rounding: from inside a closed octahedron, aimed at its
/// vertices, its edges' midpoints and swept along an edge, every answer is
/// the CPU's. (Both use obvhs's test, which is not watertight: a ray
/// exactly along a shared edge can miss both triangles, as most of these
/// do. A GPU rounds its products otherwise where it fuses a multiply and
/// an add, which decided 2 of these rays before its hits became candidates
/// that the host retests with the CPU's test; Woop's watertight test there
/// disagreed with the CPU on 7% of the Cornell box's bake rays, the ones
/// from texels on the edge between two walls.) Every ray the CPU finds
/// occluded has a candidate.
#[test]
fn edge_and_vertex_rays_are_answered_as_on_the_cpu() {
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
    let faces: Vec<[Vec3A; 3]> = faces.iter().map(|f| f.map(|p| p * 0.3)).collect();
    let Some(gpu) = gpu(&faces) else { return };
    let cpu = Tracer::new(&faces);
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
    for k in 0..=1000 {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 / 1000.0;
        aims.push(Vec3::new(a.cos(), a.sin(), 0.0));
        // Off the edge by a little: every one hits.
        aims.push(Vec3::new(a.cos(), a.sin(), 1e-3).normalize());
    }
    let mut rays = RayBatch::new();
    for d in &aims {
        rays.push(Vec3::ZERO, *d, 1.0);
    }
    let unsure = answers_cover(&gpu, &cpu, &rays);
    let tracer = attached(&faces, gpu);
    let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
    tracer.occluded_batch(&rays, &mut on_gpu);
    cpu.occluded_batch(&rays, &mut on_cpu);
    assert_eq!(tracer.accelerator_failure(), None);
    eprintln!("{unsure} rays the GPU is unsure of");
    // Off the edges every answer agrees (and hits); exactly on an edge or
    // a vertex the CPU's rounding decides, which the candidates' retest
    // on the host reproduces. (The sweep's ends, along x = 0 or y = 0, lie
    // on edges too.)
    let off_edge: Vec<usize> = (1..1000).map(|k| 14 + 2 * k + 1).collect();
    assert!(off_edge.iter().all(|&i| on_gpu[i] && on_cpu[i]));
    let differ: Vec<(Vec3, bool)> = (0..aims.len())
        .filter(|&i| on_gpu[i] != on_cpu[i])
        .map(|i| (aims[i], on_cpu[i]))
        .collect();
    eprintln!(
        "{} of {} edge and vertex rays differ: {differ:?}",
        differ.len(),
        aims.len() - off_edge.len()
    );
    assert!(differ.is_empty(), "{differ:?}");
}

/// Random rays in the flight helmet: from points inside its bounds in
/// every direction, at max distances from contact to past the scene, each
/// with a depth to cut a closest hit at (the max distance, none, or in
/// between).
fn helmet_rays(n: usize) -> (Vec<[Vec3A; 3]>, RayBatch) {
    let scene = common::bundled_scene("flight_helmet.glb");
    let geometry = scene.bake_geometry().unwrap();
    let mut rays = RayBatch::new();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    for _ in 0..n {
        let o = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 0.6;
        let z = 2.0 * next() - 1.0;
        let phi = std::f32::consts::TAU * next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let t_max = [0.001, 0.01, 0.1, 1.0, 3.0][(next() * 5.0) as usize % 5];
        let depth = [t_max, 0.0, t_max * next()][(next() * 3.0) as usize % 3];
        rays.push_within(o, d, t_max, depth);
    }
    (geometry.occluders, rays)
}

/// A real scene's rays answered as the CPU answers them: at least 99.99%
/// agree (the rest lie within a hair of a triangle's edge or of the max
/// distance, where the two triangle tests round differently).
#[test]
fn a_scene_occludes_as_on_the_cpu() {
    let (occluders, rays) = helmet_rays(200_000);
    let Some(gpu) = gpu(&occluders) else {
        return;
    };
    let cpu = Tracer::new(&occluders);
    let n = rays.len();
    let unsure = answers_cover(&gpu, &cpu, &rays);
    let adapter = gpu.adapter().clone();
    let tracer = attached(&occluders, gpu);
    let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
    tracer.occluded_batch(&rays, &mut on_gpu);
    cpu.occluded_batch(&rays, &mut on_cpu);
    assert_eq!(tracer.accelerator_failure(), None);
    // One worker, a dispatch always free: the GPU traced every ray.
    assert_eq!(tracer.accelerated_rays(), Some((n as u64, 0)));
    let occluded = on_cpu.iter().filter(|&&h| h).count();
    let differ = on_gpu.iter().zip(&on_cpu).filter(|(a, b)| a != b).count();
    eprintln!(
        "{n} rays, {occluded} occluded on the CPU, {differ} answered otherwise, {unsure} unsure, on {adapter:?}"
    );
    // Rays the GPU is unsure of (then traced on the CPU) stay rare.
    assert!(unsure * 1000 <= n, "{unsure}");
    // Both answers occur often: the comparison means something.
    assert!(occluded > n / 10 && occluded < n * 9 / 10, "{occluded}");
    assert!(differ * 10_000 <= n, "{differ} of {n} differ");
}

/// Rays that end exactly where they hit, as the passes cast them (a max
/// distance read from an earlier closest hit): the CPU's test counts a hit
/// at the ray's end and its traversal does not, so an occlusion answer
/// settled by the test alone would differ there. From random helmet rays,
/// each cast again up to its own hit's distance and up to a hair beyond:
/// the GPU answers all of them as the CPU does, and the comparison is not
/// vacuous (both answers occur).
#[test]
fn rays_ending_at_their_hit_are_answered_as_on_the_cpu() {
    let (occluders, probe) = helmet_rays(40_000);
    let Some(gpu) = gpu(&occluders) else {
        return;
    };
    let cpu = Tracer::new(&occluders);
    let mut rays = RayBatch::new();
    for i in 0..probe.len() {
        let (o, d, t_max) = (probe.origins()[i], probe.directions()[i], probe.t_max()[i]);
        if let Some(t) = cpu.closest_hit(o, d, t_max) {
            for end in [t, t.next_up(), t.next_down()] {
                rays.push(o, d, end);
            }
        }
    }
    let tracer = attached(&occluders, gpu);
    let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
    tracer.occluded_batch(&rays, &mut on_gpu);
    cpu.occluded_batch(&rays, &mut on_cpu);
    assert_eq!(tracer.accelerator_failure(), None);
    let n = rays.len();
    let occluded = on_cpu.iter().filter(|&&h| h).count();
    let differ = on_gpu.iter().zip(&on_cpu).filter(|(a, b)| a != b).count();
    eprintln!(
        "{n} rays ending at their hit, {occluded} occluded on the CPU, {differ} answered otherwise"
    );
    assert!(
        occluded > n / 10 && occluded < n * 9 / 10,
        "{occluded} of {n}"
    );
    assert_eq!(differ, 0, "{differ} of {n} differ");
}

/// How many of two answers to `rays`' closest hits (each naming `cpu`'s
/// triangles) differ where a pass reads them: the distance cut at the
/// ray's depth, and for a ray traced uncut the triangle's normal and
/// whether its back face was hit. (Not the triangle's index: the tree
/// builder splits large triangles into several leaves, and beyond a cut
/// the triangle is whichever the traversal met first, on either.)
fn differing(cpu: &Tracer, rays: &RayBatch, a: &[Option<Hit>], b: &[Option<Hit>]) -> usize {
    let (t_max, depth, dirs) = (rays.t_max(), rays.depths(), rays.directions());
    (0..rays.len())
        .filter(|&i| {
            let read = |h: &Option<Hit>| h.map(|h| h.distance_within(t_max[i], depth[i]));
            let face =
                |h: &Option<Hit>| h.map(|h| (cpu.hit_normal(h), cpu.is_back_face(h, dirs[i])));
            read(&a[i]) != read(&b[i]) || (depth[i] >= t_max[i] && face(&a[i]) != face(&b[i]))
        })
        .count()
}

/// Closest hits through a tracer with the GPU attached, as the passes ask
/// for them: the same hit as the CPU's (parameter and triangle, so the
/// same distance at every depth, back face and normal) on at least 99.99%
/// of the helmet's rays, cut at their depths; and on two parallel quads
/// the closed form: the nearer quad's distance below the depth, the depth
/// beyond it.
#[test]
fn closest_hits_are_the_cpus() {
    let mut quads = quad(0.1);
    quads.extend(quad(0.3));
    let Some(on_quads) = gpu(&quads) else { return };
    let mut tracer = Tracer::new(&quads);
    on_quads.attach_to(&mut tracer);
    let mut rays = RayBatch::new();
    let d = Vec3::new(0.1, 0.2, 1.0).normalize();
    let o = Vec3::new(0.05, -0.03, 0.0);
    for depth in [1.0, 0.5, 0.05, 0.0] {
        rays.push_within(o, d, 1.0, depth);
    }
    rays.push_within(o, d, 0.09, 0.05);
    rays.push_within(o, -d, 1.0, 1.0);
    rays.push_blocked(-d);
    let mut hits = Vec::new();
    tracer.trace_batch::<Closest>(&rays, &mut hits);
    assert_eq!(tracer.accelerator_failure(), None);
    let near = 0.1 / d.z;
    let read: Vec<Option<f32>> = (hits.iter().zip(rays.depths()).zip(rays.t_max()))
        .map(|((h, &depth), &t_max)| h.map(|h| h.distance_within(t_max, depth)))
        .collect();
    for (got, want) in read
        .iter()
        .zip([Some(near), Some(near), Some(0.05), Some(0.0)])
    {
        let (got, want) = (got.unwrap(), want.unwrap());
        assert!((got - want).abs() < 1e-6, "{got} for {want}");
    }
    assert_eq!(&read[4..], &[None, None, None]);

    let (occluders, rays) = helmet_rays(100_000);
    let Some(on_helmet) = gpu(&occluders) else {
        return;
    };
    let cpu = Tracer::with_sides(&occluders, &vec![true; occluders.len()]);
    let mut tracer = Tracer::with_sides(&occluders, &vec![true; occluders.len()]);
    on_helmet.attach_to(&mut tracer);
    let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
    tracer.trace_batch::<Closest>(&rays, &mut on_gpu);
    cpu.trace_batch::<Closest>(&rays, &mut on_cpu);
    assert_eq!(tracer.accelerator_failure(), None);
    let n = rays.len();
    let hit = on_cpu.iter().filter(|h| h.is_some()).count();
    let back = (on_cpu.iter().zip(rays.directions()))
        .filter(|(h, d)| h.is_some_and(|h| cpu.is_back_face(h, **d)))
        .count();
    let differ = differing(&cpu, &rays, &on_gpu, &on_cpu);
    eprintln!("{n} rays, {hit} hit ({back} back faces), {differ} answered otherwise");
    assert!(hit > n / 10 && hit < n * 9 / 10, "{hit}");
    assert!(back > n / 100, "{back}");
    assert!(differ * 10_000 <= n, "{differ} of {n} differ");
}

/// A device lost mid-bake: the batch it failed on and every later one are
/// answered by the CPU (the answers as if it never failed), and the tracer
/// says why.
#[test]
fn a_lost_device_leaves_the_rest_to_the_cpu() {
    let (occluders, rays) = helmet_rays(20_000);
    let Some(mut lost) = gpu(&occluders) else {
        return;
    };
    lost.lose_device_after(2);
    let cpu = Tracer::new(&occluders);
    let mut tracer = Tracer::new(&occluders);
    lost.attach_to(&mut tracer);
    for round in 0..5 {
        let (mut on_gpu, mut on_cpu) = (Vec::new(), Vec::new());
        tracer.occluded_batch(&rays, &mut on_gpu);
        cpu.occluded_batch(&rays, &mut on_cpu);
        let differ = on_gpu.iter().zip(&on_cpu).filter(|(a, b)| a != b).count();
        assert!(differ * 10_000 <= rays.len(), "round {round}: {differ}");
        let (mut closest_gpu, mut closest_cpu) = (Vec::new(), Vec::new());
        tracer.trace_batch::<Closest>(&rays, &mut closest_gpu);
        cpu.trace_batch::<Closest>(&rays, &mut closest_cpu);
        let differ = differing(&cpu, &rays, &closest_gpu, &closest_cpu);
        assert!(differ * 10_000 <= rays.len(), "round {round}: {differ}");
        assert_eq!(
            tracer.accelerator_failure().is_some(),
            round >= 1,
            "round {round}"
        );
    }
    let why = tracer.accelerator_failure().unwrap();
    assert!(why.contains("lost") || why.contains("Lost"), "{why}");
}

/// A batch offered while every dispatch of the GPU's is in flight: the
/// worker answers a piece of it on the CPU and offers the rest again, so
/// the answers are the same whoever traced which rays. Refusing every
/// attempt leaves whole batches to the CPU; refusing every other one, the
/// first piece (4096 rays) of each batch and the GPU the rest.
#[test]
fn a_busy_gpu_shares_its_batches_with_the_cpu() {
    let (occluders, rays) = helmet_rays(20_000);
    let n = rays.len() as u64;
    let cpu = Tracer::new(&occluders);
    let (mut occluded, mut closest) = (Vec::new(), Vec::new());
    cpu.occluded_batch(&rays, &mut occluded);
    cpu.trace_batch::<Closest>(&rays, &mut closest);
    for (every, on_cpu) in [(1, 2 * n), (2, 2 * 4096)] {
        let Some(mut busy) = gpu(&occluders) else {
            return;
        };
        busy.refuse_every(every);
        let tracer = attached(&occluders, busy);
        let (mut o, mut c) = (Vec::new(), Vec::new());
        tracer.occluded_batch(&rays, &mut o);
        tracer.trace_batch::<Closest>(&rays, &mut c);
        assert_eq!(
            tracer.accelerated_rays(),
            Some((2 * n - on_cpu, on_cpu)),
            "every {every}"
        );
        assert_eq!(tracer.accelerator_failure(), None);
        // The CPU's pieces are the CPU's answers; the GPU's agree.
        if on_cpu > 0 {
            assert_eq!(o[..4096], occluded[..4096], "every {every}");
            assert_eq!(c[..4096], closest[..4096], "every {every}");
        }
        let differ = o.iter().zip(&occluded).filter(|(a, b)| a != b).count();
        assert!(differ * 10_000 <= rays.len(), "every {every}: {differ}");
        let differ = differing(&cpu, &rays, &c, &closest);
        assert!(differ * 10_000 <= rays.len(), "every {every}: {differ}");
    }
}

/// The Cornell box baked by the command line into `dir` (files named by
/// `device`) with `--device device`, `args` and the environment `env`; it
/// must exit 0. Its output's bytes, its report and its stderr.
fn cli_bake(
    dir: &std::path::Path,
    device: &str,
    args: &[&str],
    env: &[(&str, &str)],
) -> (Vec<u8>, serde_json::Value, String) {
    let out = dir.join(format!("{device}.glb"));
    let report = dir.join(format!("{device}.json"));
    let mut run = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"));
    run.arg(common::asset_path("cornell_box.glb")).arg(&out);
    run.arg("--report").arg(&report).args(["--device", device]);
    run.args(args).envs(env.iter().copied());
    let done = run.output().unwrap();
    let err = String::from_utf8_lossy(&done.stderr).into_owned();
    assert_eq!(done.status.code(), Some(0), "{err}");
    let report = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    (std::fs::read(&out).unwrap(), report, err)
}

/// A bake whose GPU is busy half the time (the CPU tracing pieces beside
/// it) is the CPU's bake, and its report says who traced how many rays.
#[test]
fn a_bake_shared_with_the_cpu_is_the_cpu_bake() {
    let Some(probe) = gpu(&quad(0.2)) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let args = ["--resolution", "96", "-q"];
    let (cpu, cpu_report, _) = cli_bake(dir.path(), "cpu", &args, &[]);
    let busy = [(aobake::trace::gpu::SHARE_VAR, "2")];
    let (shared, report, _) = cli_bake(dir.path(), "gpu", &args, &busy);
    let backend = &report["backend"];
    let count = |k: &str| backend[k].as_u64().unwrap_or_else(|| panic!("{backend}"));
    let (on_gpu, on_cpu) = (count("rays_on_gpu"), count("rays_on_cpu"));
    assert!(on_gpu > 0 && on_cpu > 0, "{backend}");
    // Every ray the passes cast went through a batch (blocked ones too).
    assert!(on_gpu + on_cpu >= cpu_report["rays_cast"].as_u64().unwrap());
    assert!(cpu_report["backend"].get("rays_on_gpu").is_none());
    // On a software adapter the GPU's answers are the CPU's to the bit
    // (hardware: within the agreement a_gpu_bake_is_the_cpu_bake checks).
    if probe.adapter().software {
        assert!(
            cpu == shared,
            "the shared bake's bytes differ from the CPU's"
        );
    }
}

/// `--device gpu` whose device is lost mid-bake stops with a one-line
/// error and writes nothing (the input untouched).
#[test]
fn a_gpu_bake_whose_device_is_lost_writes_nothing() {
    if gpu(&quad(0.2)).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = common::asset_path("cornell_box.glb");
    let before = std::fs::read(&input).unwrap();
    let out = dir.path().join("out.glb");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
        .arg(&input)
        .arg(&out)
        .args([
            "--resolution",
            "64",
            "--rays",
            "16",
            "--device",
            "gpu",
            "-q",
        ])
        .env(aobake::trace::gpu::LOSE_AFTER_VAR, "1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{err}");
    // aobake's own lines (the Vulkan loader may add its own).
    let ours: Vec<&str> = err.lines().filter(|l| l.starts_with("aobake")).collect();
    assert_eq!(ours.len(), 1, "{err}");
    let err = ours[0];
    assert!(
        err.contains("lost") && err.contains("nothing written"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    assert_eq!(std::fs::read(&input).unwrap(), before);
}

/// `--device auto` whose device is lost mid-bake: the CPU traces the rest,
/// the bake writes its output, exits 0 and warns in one line; the output is
/// the CPU bake's (bytes, on a software adapter). (`auto` is let take
/// lavapipe here, as CI has no hardware GPU.)
#[test]
fn an_auto_bake_whose_device_is_lost_finishes_on_the_cpu() {
    let Some(probe) = gpu(&quad(0.2)) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let args = ["--resolution", "64", "--rays", "16"];
    let (cpu, _, _) = cli_bake(dir.path(), "cpu", &args, &[]);
    let lose = [
        (aobake::trace::gpu::AUTO_SOFTWARE_VAR, "1"),
        (aobake::trace::gpu::LOSE_AFTER_VAR, "1"),
    ];
    let (auto, report, err) = cli_bake(dir.path(), "auto", &args, &lose);
    let warned: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("aobake: warning: the GPU failed mid-bake"))
        .collect();
    assert_eq!(warned.len(), 1, "{err}");
    assert!(warned[0].contains("lost"), "{}", warned[0]);
    assert!(
        warned[0].ends_with("the rest was traced on the CPU"),
        "{}",
        warned[0]
    );
    let backend = &report["backend"];
    assert!(backend["adapter"].is_string(), "{backend}");
    assert!(backend["rays_on_cpu"].as_u64().unwrap() > 0, "{backend}");
    assert_eq!(report["warnings"].as_array().unwrap().len(), 1);
    if probe.adapter().software {
        assert!(
            cpu == auto,
            "the bake finished on the CPU differs from the CPU's"
        );
    }
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
    let inside =
        |lo: [f32; 3], hi: [f32; 3], p: [f32; 3]| (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k]);
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
                // Rebuilt from the edges: within rounding of the box.
                for v in flat.tris[t as usize].vertices() {
                    let grown = |b: [f32; 3], s: f32| b.map(|x| x + s * 1e-6);
                    assert!(inside(grown(n.lo, -1.0), grown(n.hi, 1.0), v));
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s == 1));
    assert!(flat.depth >= 8 && flat.depth < 64, "{}", flat.depth);
    assert!(aobake::trace::gpu::flatten(&[]).is_none());
}

/// A whole bake with `--device gpu` against `--device cpu`: every batch
/// (occlusion and closest hits) on lavapipe. The adaptive method's and
/// Monte Carlo's AO and 9 SH within 1/255 of the CPU bake's on at least
/// 99.9% of texels, and the report names the adapter; `auto` takes no
/// software adapter.
#[test]
fn a_gpu_bake_is_the_cpu_bake() {
    let scene = common::bundled_scene("cornell_box.glb");
    if gpu(&quad(0.2)).is_none() {
        return;
    }
    for method in [aobake::Method::Adaptive, aobake::Method::Mc] {
        let settings = |device| aobake::BakeSettings {
            size: aobake::atlas::AtlasSize::Resolution(128),
            method,
            rays: 64,
            device,
            ..aobake::BakeSettings::DEFAULT
        };
        let cpu = aobake::bake_scene(&scene, &settings(aobake::Device::Cpu)).unwrap();
        let on_gpu = aobake::bake_scene(&scene, &settings(aobake::Device::Gpu)).unwrap();
        let adapter = on_gpu.report.backend.adapter.clone();
        assert!(adapter.is_some(), "{:?}", on_gpu.report.backend);
        // Traced there to the end (no batch left to the CPU).
        assert!(
            on_gpu.report.warnings.is_empty(),
            "{:?}",
            on_gpu.report.warnings
        );
        assert_eq!(cpu.report.backend.adapter, None);
        let (a, b) = (&cpu.lightmap, &on_gpu.lightmap);
        assert_eq!((a.width, a.height), (b.width, b.height));
        let texels = a.ao.len();
        let far = (0..texels)
            .filter(|&t| {
                let ao = (a.ao[t] - b.ao[t]).abs();
                let sh = (0..9).map(|i| (a.sh[t][i] - b.sh[t][i]).abs());
                ao.max(sh.fold(0.0, f32::max)) > 1.0 / 255.0
            })
            .count();
        eprintln!("{method:?}: {far} of {texels} texels past 1/255 on {adapter:?}");
        assert!(
            far * 1000 <= texels,
            "{method:?}: {far} of {texels} texels past 1/255"
        );
        // Not vacuous: the box occludes.
        assert!(a.ao.iter().any(|&v| v < 0.5));
    }
    // auto: a software adapter is not a GPU.
    let auto = aobake::bake_scene(
        &scene,
        &aobake::BakeSettings {
            size: aobake::atlas::AtlasSize::Resolution(64),
            ..aobake::BakeSettings::DEFAULT
        },
    )
    .unwrap();
    let software_only = GpuTracer::new(&quad(0.2), Adapters::Hardware).is_err();
    assert_eq!(auto.report.backend.adapter.is_none(), software_only);
    if software_only {
        let why = auto.report.backend.cpu_because.unwrap();
        assert!(why.contains("no hardware GPU adapter"), "{why}");
    }
}

/// Shards record where they traced: a level whose shards traced on the GPU
/// and on the CPU is refused at the merge, one traced on one device merges.
#[test]
fn shards_of_one_level_share_their_device() {
    if gpu(&quad(0.2)).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = common::asset_path("generated/courtyard.glb");
    let out = dir.path().join("level.glb");
    let shard = |i: u32, device: &str| {
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
            .arg(&input)
            .arg(&out)
            .args(["--texel-density", "4", "--page-size", "128", "--rays", "16"])
            .args(["--method", "mc", "--device", device, "-q"])
            .args(["--shard", &format!("{i}/2")])
            .status()
            .unwrap();
        assert!(status.success(), "shard {i} on {device}");
    };
    let merge = || {
        std::process::Command::new(env!("CARGO_BIN_EXE_aobake"))
            .args(["merge", "-q"])
            .arg(&out)
            .output()
            .unwrap()
    };
    shard(0, "gpu");
    shard(1, "cpu");
    let mixed = merge();
    let err = String::from_utf8_lossy(&mixed.stderr);
    assert_eq!(mixed.status.code(), Some(1), "{err}");
    assert!(
        err.contains("merge refused") && err.contains("baked with other settings"),
        "{err}"
    );
    assert!(!out.exists());
    shard(1, "gpu");
    let merged = merge();
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    assert!(out.exists());
}
