//! The Babylon.js importer (the package `packages/aobake-babylon`) in a
//! real browser: runs `babylon/test` (node:test driving Debian's headless
//! Chromium through the viewer's playwright-core harness) with this
//! build's `aobake`.
//!
//! Needs node, `npm ci` in the repository's root and the `chromium`
//! package (`.ci/run` installs them). Without them the test says
//! so and passes, except under CI (`CI` set) or with
//! `AOBAKE_REQUIRE_TOOLS` set, where it fails.

mod common;

use std::path::Path;

#[test]
fn babylon_relights_bakes_in_a_real_browser() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let babylon = root.join("babylon");
    common::run_browser_tests(
        &babylon,
        &[
            "--test-concurrency=1",
            "test/babylon.test.mjs",
            "test/engines.test.mjs",
        ],
        &[(
            [
                "playwright-core",
                "@babylonjs/core",
                "esbuild",
                "aobake-babylon",
            ]
            .iter()
            .any(|m| !root.join("node_modules").join(m).is_dir()),
            "npm ci",
        )],
        env!("CARGO_BIN_EXE_aobake"),
    );
}
