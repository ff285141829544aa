//! The viewer's files built into the binary, so an installed `aobake view`
//! serves a working page from any directory: the page (`viewer/`), the
//! engine importer packages it imports as a user of the npm packages would
//! (`packages/aobake-contract` and `packages/aobake-three`, named in the
//! page's import map and served under `packages/`), the three.js modules
//! (`viewer/vendor/three/`, the files of the npm package `three` pinned in
//! the repository's `package.json`, MIT licensed; a test checks they equal
//! the installed package's), and Babylon.js with the `aobake-babylon`
//! package as one gzip-compressed module (`viewer/vendor/babylon/`,
//! Apache-2.0, built by `babylon/build-viewer.mjs`; a test checks it is
//! what the checkout builds).
//!
//! In: a request path relative to the viewer's root. Out: the file's
//! bytes, if built in.

/// Every built-in file: its path as served (under `viewer/`, or under
/// `packages/` for the importer packages) and its bytes.
pub const FILES: &[(&str, &[u8])] = &[
    ("index.html", include_bytes!("../../viewer/index.html")),
    ("viewer.js", include_bytes!("../../viewer/viewer.js")),
    (
        "packages/aobake-three/aobake-lightmap.js",
        include_bytes!("../../packages/aobake-three/aobake-lightmap.js"),
    ),
    (
        "packages/aobake-contract/index.js",
        include_bytes!("../../packages/aobake-contract/index.js"),
    ),
    (
        "packages/aobake-contract/extension.js",
        include_bytes!("../../packages/aobake-contract/extension.js"),
    ),
    (
        "packages/aobake-contract/sh.js",
        include_bytes!("../../packages/aobake-contract/sh.js"),
    ),
    (
        "packages/aobake-contract/glsl.js",
        include_bytes!("../../packages/aobake-contract/glsl.js"),
    ),
    ("bar.js", include_bytes!("../../viewer/bar.js")),
    (
        "babylon-viewer.js",
        include_bytes!("../../viewer/babylon-viewer.js"),
    ),
    ("compare.js", include_bytes!("../../viewer/compare.js")),
    (
        "environments.js",
        include_bytes!("../../viewer/environments.js"),
    ),
    (
        "vendor/three/LICENSE",
        include_bytes!("../../viewer/vendor/three/LICENSE"),
    ),
    (
        "vendor/three/build/three.module.js",
        include_bytes!("../../viewer/vendor/three/build/three.module.js"),
    ),
    (
        "vendor/three/build/three.core.js",
        include_bytes!("../../viewer/vendor/three/build/three.core.js"),
    ),
    (
        "vendor/three/examples/jsm/loaders/GLTFLoader.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    ),
    (
        "vendor/three/examples/jsm/controls/OrbitControls.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/controls/OrbitControls.js"),
    ),
    (
        "vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    ),
    (
        "vendor/three/examples/jsm/utils/SkeletonUtils.js",
        include_bytes!("../../viewer/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    ),
    (
        "vendor/babylon/LICENSE",
        include_bytes!("../../viewer/vendor/babylon/LICENSE"),
    ),
    (
        "vendor/babylon/aobake-babylon.js.gz",
        include_bytes!("../../viewer/vendor/babylon/aobake-babylon.js.gz"),
    ),
];

/// The built-in file at `path` (relative, `/`-separated).
pub fn file(path: &str) -> Option<&'static [u8]> {
    FILES.iter().find(|(p, _)| *p == path).map(|(_, b)| *b)
}
