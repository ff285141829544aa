//! The engine importers as npm packages (`packages/`): runs
//! `packages/test/pack.test.mjs`, which packs each package with `npm pack`,
//! installs the tarballs into a clean temporary project with their engines
//! as peer dependencies, and imports them there (node and a bundler),
//! checking the contract's numbers against closed forms.
//!
//! Needs node, npm (with the registry or npm's cache, for the engines) and
//! `npm ci` in the repository's root (`.ci/run` does it). Without them the
//! test says so and passes, except under CI (`CI` set) or with
//! `AOBAKE_REQUIRE_TOOLS` set, where it fails.

mod common;

use std::path::Path;
use std::process::Command;

#[test]
fn the_packed_importers_install_and_load_in_a_clean_project() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let runs = |tool: &str| Command::new(tool).arg("--version").output().is_ok();
    let missing: Vec<&str> = [
        (!runs("node"), "node"),
        (!runs("npm"), "npm"),
        (!root.join("node_modules/esbuild").is_dir(), "npm ci"),
    ]
    .into_iter()
    .filter_map(|(gone, what)| gone.then_some(what))
    .collect();
    if !common::tools_present("the npm package test", &missing) {
        return;
    }
    let out = Command::new("node")
        .args([
            "--test",
            "--test-reporter=tap",
            "packages/test/pack.test.mjs",
        ])
        .current_dir(root)
        .output()
        .expect("node runs");
    assert!(
        out.status.success(),
        "package tests failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
