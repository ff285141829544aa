//! The viewer and its three.js plugin in a real browser: runs
//! `viewer/test` (node:test driving Debian's headless Chromium through
//! playwright-core) with this build's `aobake`.
//!
//! Needs node, `npm ci --prefix viewer` and the `chromium` package (`.ci/run`
//! installs them). Without them the test says so and passes, except under
//! CI (`CI` set) or with `AOBAKE_REQUIRE_BROWSER` set, where it fails.

use std::path::Path;
use std::process::Command;

#[test]
fn viewer_relights_bakes_in_a_real_browser() {
    let viewer = Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".to_string());
    let node = Command::new("node").arg("--version").output();
    let missing: Vec<&str> = [
        (node.is_err(), "node"),
        (
            !viewer.join("node_modules/three").is_dir()
                || !viewer.join("node_modules/playwright-core").is_dir(),
            "npm ci --prefix viewer",
        ),
        (!Path::new(&chromium).is_file(), "the chromium package"),
    ]
    .into_iter()
    .filter_map(|(gone, what)| gone.then_some(what))
    .collect();
    if !missing.is_empty() {
        let required = std::env::var_os("CI").is_some()
            || std::env::var_os("AOBAKE_REQUIRE_BROWSER").is_some();
        assert!(!required, "browser tests need: {}", missing.join(", "));
        eprintln!(
            "note: viewer browser tests skipped, missing: {}",
            missing.join(", ")
        );
        return;
    }
    let out = Command::new("node")
        .args([
            "--test",
            "--test-reporter=tap",
            "test/viewer.test.mjs",
            "test/builtin.test.mjs",
        ])
        .current_dir(&viewer)
        .env("AOBAKE_BIN", env!("CARGO_BIN_EXE_aobake"))
        .env("CHROMIUM", &chromium)
        .output()
        .expect("node runs");
    let tap = String::from_utf8_lossy(&out.stdout);
    // The measured differences, for the log (cargo test --nocapture).
    for line in tap.lines().filter(|l| l.starts_with("# \\#")) {
        eprintln!("{}", &line[4..]);
    }
    assert!(
        out.status.success(),
        "viewer tests failed:\n{tap}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The three.js files built into the binary (`viewer/vendor/three`) are
/// the npm package's pinned in `viewer/package.json`, byte for byte.
#[test]
fn the_vendored_three_js_is_the_pinned_package() {
    let viewer = Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer");
    let installed = viewer.join("node_modules/three");
    if !installed.is_dir() {
        let required = std::env::var_os("CI").is_some()
            || std::env::var_os("AOBAKE_REQUIRE_BROWSER").is_some();
        assert!(!required, "needs npm ci --prefix viewer");
        eprintln!("note: skipped, npm ci --prefix viewer has not run");
        return;
    }
    let pinned: serde_json::Value =
        serde_json::from_slice(&std::fs::read(viewer.join("package.json")).unwrap()).unwrap();
    let version: serde_json::Value =
        serde_json::from_slice(&std::fs::read(installed.join("package.json")).unwrap()).unwrap();
    assert_eq!(pinned["dependencies"]["three"], version["version"]);
    let mut n = 0;
    for (path, bytes) in aobake::view::embedded::FILES {
        if let Some(rel) = path.strip_prefix("vendor/three/") {
            let npm = std::fs::read(installed.join(rel)).unwrap();
            assert!(
                npm == *bytes,
                "{path} differs from node_modules/three/{rel}"
            );
            n += 1;
        }
    }
    assert!(n >= 6, "{n} vendored files");
}
