//! The viewer and its three.js plugin in a real browser: runs
//! `viewer/test` (node:test driving Debian's headless Chromium through
//! playwright-core) with this build's `aobake`.
//!
//! Needs node, `npm ci` in the repository's root and the `chromium` package
//! (`.ci/run` installs them). Without them the test says so and passes, except under
//! CI (`CI` set) or with `AOBAKE_REQUIRE_TOOLS` set, where it fails.

mod common;

use std::path::Path;

#[test]
fn viewer_relights_bakes_in_a_real_browser() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let installed = root.join("node_modules/three").is_dir()
        && root.join("node_modules/playwright-core").is_dir()
        && root.join("node_modules/aobake-three").is_dir();
    common::run_browser_tests(
        &root.join("viewer"),
        &["test/viewer.test.mjs", "test/builtin.test.mjs"],
        &[(!installed, "npm ci")],
        env!("CARGO_BIN_EXE_aobake"),
    );
}

/// The three.js files built into the binary (`viewer/vendor/three`) are
/// the npm package's pinned in the repository's `package.json`, byte for
/// byte.
#[test]
fn the_vendored_three_js_is_the_pinned_package() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let installed = root.join("node_modules/three");
    if !installed.is_dir()
        && !common::tools_present("the check of the vendored three.js", &["npm ci"])
    {
        return;
    }
    let pinned: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join("package.json")).unwrap()).unwrap();
    let version: serde_json::Value =
        serde_json::from_slice(&std::fs::read(installed.join("package.json")).unwrap()).unwrap();
    assert_eq!(pinned["devDependencies"]["three"], version["version"]);
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
