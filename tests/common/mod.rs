//! Builds small glTF scenes in memory for the tests.
#![allow(dead_code, clippy::needless_range_loop)]

use serde_json::{Value, json};

pub struct MeshSpec {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub indices: Vec<u32>,
}

/// A quad in the plane spanned by axes `u` and `v` through `origin`,
/// facing `u x v`.
pub fn quad(origin: [f32; 3], u: [f32; 3], v: [f32; 3], with_normals: bool) -> MeshSpec {
    let p = |a: f32, b: f32| [0, 1, 2].map(|k| origin[k] + a * u[k] + b * v[k]);
    let n = {
        let c = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        c.map(|x| x / l)
    };
    MeshSpec {
        positions: vec![p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)],
        normals: with_normals.then(|| vec![n; 4]),
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// Merges meshes into one primitive.
pub fn merge(parts: &[MeshSpec]) -> MeshSpec {
    let mut out = MeshSpec {
        positions: vec![],
        normals: Some(vec![]),
        indices: vec![],
    };
    for p in parts {
        let base = out.positions.len() as u32;
        out.positions.extend(&p.positions);
        match (&mut out.normals, &p.normals) {
            (Some(o), Some(n)) => o.extend(n),
            _ => out.normals = None,
        }
        out.indices.extend(p.indices.iter().map(|i| i + base));
    }
    out
}

/// Builds a GLB: `meshes` each one primitive; `nodes` as JSON (with "mesh").
pub fn glb(meshes: &[MeshSpec], nodes: Vec<Value>) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = vec![];
    let mut accessors = vec![];
    let mut json_meshes = vec![];
    let mut push = |bin: &mut Vec<u8>, bytes: &[u8], target: u32| -> usize {
        let off = bin.len();
        bin.extend_from_slice(bytes);
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        views.push(
            json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len(), "target": target}),
        );
        views.len() - 1
    };
    for m in meshes {
        let pos: Vec<u8> = m
            .positions
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let v = push(&mut bin, &pos, 34962);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &m.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        accessors.push(json!({"bufferView": v, "componentType": 5126, "count": m.positions.len(), "type": "VEC3", "min": lo, "max": hi}));
        let mut attrs = json!({"POSITION": accessors.len() - 1});
        if let Some(n) = &m.normals {
            let b: Vec<u8> = n.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
            let v = push(&mut bin, &b, 34962);
            accessors.push(
                json!({"bufferView": v, "componentType": 5126, "count": n.len(), "type": "VEC3"}),
            );
            attrs["NORMAL"] = json!(accessors.len() - 1);
        }
        let ib: Vec<u8> = m.indices.iter().flat_map(|v| v.to_le_bytes()).collect();
        let v = push(&mut bin, &ib, 34963);
        accessors.push(json!({"bufferView": v, "componentType": 5125, "count": m.indices.len(), "type": "SCALAR"}));
        json_meshes
            .push(json!({"primitives": [{"attributes": attrs, "indices": accessors.len() - 1}]}));
    }
    let roots: Vec<usize> = (0..nodes.len()).collect();
    let doc = json!({
        "asset": {"version": "2.0", "generator": "aobake tests"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": json_meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    aobake::gltf::container::glb_bytes(&doc, &bin)
}

/// One node per mesh, untransformed.
pub fn plain_nodes(n: usize) -> Vec<Value> {
    (0..n).map(|i| json!({"mesh": i})).collect()
}

pub fn scene(bytes: &[u8]) -> aobake::gltf::Scene {
    let doc = aobake::gltf::container::parse(bytes, std::path::Path::new(".")).expect("parses");
    aobake::gltf::Scene::from_document(doc).expect("loads")
}

/// Settings for small, quick test bakes.
pub fn settings(resolution: u32, rays: u32, max_distance: Option<f64>) -> aobake::BakeSettings {
    aobake::BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(resolution),
        method: aobake::Method::Mc,
        rays,
        max_distance,
        ..Default::default()
    }
}

/// Splits a GLB into JSON and BIN (the library's GLB reader).
pub fn split(glb: &[u8]) -> (Value, Vec<u8>) {
    let (json, bin) = aobake::gltf::container::glb_chunks(glb).unwrap();
    (
        serde_json::from_slice(json).unwrap(),
        bin.map(<[u8]>::to_vec).unwrap_or_default(),
    )
}

/// A one-page level and what made it: the examples bake its page 0 many
/// times.
pub struct OnePage {
    pub s: aobake::BakeSettings,
    pub scene: aobake::gltf::Scene,
    pub level: aobake::job::Level,
}

impl OnePage {
    /// Page 0, rasterized (deterministic: every call gives the same).
    pub fn page(&self) -> aobake::job::Page<'_> {
        let mut timer = aobake::stage::StageTimer::new();
        self.level.page(0, &self.scene, &mut timer).expect("page")
    }
}

/// For the examples: the scene at `path` prepared at `resolution` without
/// the inside fill (raw values are compared), with the Monte Carlo
/// settings of its `rays`-ray reference.
pub fn prepare_for_reference(path: &std::path::Path, resolution: u32, rays: u32) -> OnePage {
    let scene = aobake::gltf::load(path).expect("load");
    let s = aobake::BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(resolution),
        method: aobake::Method::Mc,
        rays,
        fill_inside: false,
        ..Default::default()
    };
    let mut timer = aobake::stage::StageTimer::new();
    let level = aobake::job::Level::new(&scene, &s, &aobake::RunOptions::QUIET, &mut timer)
        .expect("prepare");
    OnePage { s, scene, level }
}

/// [`prepare_for_reference`] and that reference.
pub fn reference_bake(
    path: &std::path::Path,
    resolution: u32,
    rays: u32,
) -> (OnePage, aobake::bake::Bake) {
    let one = prepare_for_reference(path, resolution, rays);
    let reference = one
        .page()
        .bake(
            &one.s,
            &aobake::RunOptions::QUIET,
            &mut aobake::stage::StageTimer::new(),
        )
        .expect("reference")
        .bake;
    (one, reference)
}

/// The output GLB of a bake run on a pool of `threads` threads.
pub fn glb_on_threads(g: &[u8], s: &aobake::BakeSettings, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| aobake::bake_scene(&scene(g), s).unwrap().glb)
}

/// Appends a float VEC2 accessor holding `uvs` to a split GLB and sets it as
/// `TEXCOORD_1` of the first primitive of each mesh in `meshes`.
pub fn add_texcoord1(json: &mut Value, bin: &mut Vec<u8>, uvs: &[[f32; 2]], meshes: &[usize]) {
    let bytes: Vec<u8> = uvs.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let off = bin.len();
    bin.extend_from_slice(&bytes);
    let views = json["bufferViews"].as_array_mut().unwrap();
    views.push(json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()}));
    let view = views.len() - 1;
    let accessors = json["accessors"].as_array_mut().unwrap();
    accessors.push(
        json!({"bufferView": view, "componentType": 5126, "count": uvs.len(), "type": "VEC2"}),
    );
    let a = accessors.len() - 1;
    for &m in meshes {
        json["meshes"][m]["primitives"][0]["attributes"]["TEXCOORD_1"] = json!(a);
    }
    json["buffers"][0]["byteLength"] = json!(bin.len());
}

/// A floor with a thin double-faced wall standing on it, and a low
/// overhanging slab on one side only: the side under the slab is dark, the
/// other side open. A filter that lends rays across the wall brightens the
/// covered side or darkens the open one.
pub fn thin_wall_scene() -> Vec<u8> {
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    // The wall at x = 0, 2 mm thick, both faces modelled.
    let wall_a = quad([-0.001, 0.0, 0.3], [0.0, 1.0, 0.0], [0.0, 0.0, 0.3], true);
    let wall_b = quad([0.001, 0.0, 0.3], [0.0, 0.0, 0.3], [0.0, 1.0, 0.0], true);
    // A slab over the x < 0 side at height 0.08, facing down.
    let slab = quad([-0.5, 0.0, 0.08], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0], true);
    glb(&[floor, wall_a, wall_b, slab], plain_nodes(4))
}

/// A unit floor with a wall standing on it at x = 0.3 (0.5 high).
pub fn floor_and_wall() -> aobake::gltf::Scene {
    let floor = quad([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], true);
    let wall = quad([0.3, 0.0, 0.5], [0.0, 0.0, 0.5], [0.0, 1.0, 0.0], true);
    scene(&glb(&[floor, wall], plain_nodes(2)))
}

/// A bake without the inside fill (raw values are compared).
pub fn bake_raw(sc: &aobake::gltf::Scene, mut s: aobake::BakeSettings) -> aobake::job::Baked {
    s.fill_inside = false;
    aobake::bake_scene(sc, &s).unwrap()
}

/// The path of the test scene `name` in the repository's `assets/` (real
/// scenes with their credits in `assets/CREDITS.md`; `generated/` holds
/// the scenes `tools/test_scenes.py` writes). Every clone has them: the
/// tests that read them never skip.
pub fn asset_path(name: &str) -> std::path::PathBuf {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name);
    assert!(path.exists(), "{} is missing", path.display());
    path
}

/// The test scene `name` of the repository's `assets/`, loaded.
pub fn bundled_scene(name: &str) -> aobake::gltf::Scene {
    aobake::gltf::load(&asset_path(name)).unwrap()
}

/// A key of the receivers' order (FNV-1a over their texels), for caches
/// of per-receiver results: a cache written in another order is not read.
pub fn order_key(receivers: &aobake::atlas::Receivers) -> u64 {
    receivers
        .texel
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, &t| {
            (h ^ t as u64).wrapping_mul(0x0100_0000_01b3)
        })
}

/// Whether a test part that needs outside tools (a browser, the glTF
/// validator, the checker's Python) can run: `missing` lists what is
/// absent, as what to install. Under CI (`CI` set) or with
/// `AOBAKE_REQUIRE_TOOLS` set, anything missing fails the test; elsewhere
/// the test says what is missing and leaves that part out. Test scenes
/// are never outside tools: they are in `assets/`.
pub fn tools_present(part: &str, missing: &[&str]) -> bool {
    if missing.is_empty() {
        return true;
    }
    let required = ["CI", "AOBAKE_REQUIRE_TOOLS", "AOBAKE_REQUIRE_BROWSER"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    assert!(!required, "{part} needs: {}", missing.join(", "));
    eprintln!("note: {part} not run, missing: {}", missing.join(", "));
    false
}

/// Runs the Khronos validator when node and tools/validator are installed;
/// returns (errors, warnings).
pub fn validate(path: &std::path::Path) -> Option<(u64, u64)> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let installed = root
        .join("tools/validator/node_modules/gltf-validator")
        .exists();
    let missing: &[&str] = if installed {
        &[]
    } else {
        &["gltf-validator (npm install --prefix tools/validator)"]
    };
    if !tools_present("glTF validation", missing) {
        return None;
    }
    let out = std::process::Command::new("node")
        .arg(root.join("tools/validator/validate.mjs"))
        .arg(path)
        .output()
        .ok()?;
    let line: Value = serde_json::from_slice(&out.stdout).expect("validator prints JSON");
    Some((
        line["errors"].as_u64().unwrap(),
        line["warnings"].as_u64().unwrap(),
    ))
}

/// Runs `node --test ARGS` in `dir` (a browser test folder) with the
/// `aobake` binary at `aobake`, after checking what it needs: `needs` lists (missing,
/// what to install). Without them it says so and passes, except under CI
/// (see `tools_present`), where it fails. Prints
/// the measured lines (`# \#`) for the log and fails with the TAP output.
pub fn run_browser_tests(
    dir: &std::path::Path,
    args: &[&str],
    needs: &[(bool, &str)],
    aobake: &str,
) {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".to_string());
    let node = std::process::Command::new("node").arg("--version").output();
    let missing: Vec<&str> = [
        (node.is_err(), "node"),
        (
            !std::path::Path::new(&chromium).is_file(),
            "the chromium package",
        ),
    ]
    .into_iter()
    .chain(needs.iter().copied())
    .filter_map(|(gone, what)| gone.then_some(what))
    .collect();
    if !tools_present("the browser tests", &missing) {
        return;
    }
    let mut node = std::process::Command::new("node");
    node.args(["--test", "--test-reporter=tap"])
        .args(args)
        .current_dir(dir)
        .env("AOBAKE_BIN", aobake)
        .env("CHROMIUM", &chromium);
    // The browser test files (viewer, Babylon.js, both engines) share their
    // bakes: the same binary, input and arguments give the same bytes, and
    // each file bakes the flight helmet. (Integration tests have a
    // target temporary folder; the probes that share this module do not.)
    if let Some(tmp) = option_env!("CARGO_TARGET_TMPDIR") {
        node.env(
            "AOBAKE_BAKE_CACHE",
            std::path::Path::new(tmp).join("browser-bakes"),
        );
    }
    let out = node.output().expect("node runs");
    let tap = String::from_utf8_lossy(&out.stdout);
    // The measured differences, for the log (cargo test --nocapture).
    for line in tap.lines().filter(|l| l.starts_with("# \\#")) {
        eprintln!("{}", &line[4..]);
    }
    assert!(
        out.status.success(),
        "browser tests failed:\n{tap}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
