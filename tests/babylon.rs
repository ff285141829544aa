//! The Babylon.js importer (`babylon/aobake-lightmap.js`) in a real
//! browser: runs `babylon/test` (node:test driving Debian's headless
//! Chromium through the viewer's playwright-core harness) with this
//! build's `aobake`.
//!
//! Needs node, `npm ci --prefix viewer`, `npm ci --prefix babylon` and the
//! `chromium` package (`.ci/run` installs them). Without them the test says
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
        &[
            (
                !root.join("viewer/node_modules/playwright-core").is_dir(),
                "npm ci --prefix viewer",
            ),
            (
                !babylon.join("node_modules/@babylonjs/core").is_dir()
                    || !babylon.join("node_modules/esbuild").is_dir(),
                "npm ci --prefix babylon",
            ),
        ],
        env!("CARGO_BIN_EXE_aobake"),
    );
}
