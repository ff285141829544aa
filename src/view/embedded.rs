//! The viewer's files built into the binary, so an installed `aobake view`
//! serves a working page from any directory: the page (`viewer/`) and the
//! three.js modules it imports (`viewer/vendor/three/`, the files of the
//! npm package `three` pinned in `viewer/package.json`, MIT licensed; a
//! test checks they equal the installed package's), and Babylon.js with
//! its importer as one gzip-compressed module (`viewer/vendor/babylon/`,
//! Apache-2.0, built by `babylon/build-viewer.mjs`; a test checks it is
//! what the checkout builds).
//!
//! In: a request path relative to the viewer's root. Out: the file's
//! bytes, if built in.

/// Every built-in file: its path under `viewer/` and its bytes.
pub const FILES: &[(&str, &[u8])] = &[
    ("index.html", include_bytes!("../../viewer/index.html")),
    ("viewer.js", include_bytes!("../../viewer/viewer.js")),
    (
        "aobake-lightmap.js",
        include_bytes!("../../viewer/aobake-lightmap.js"),
    ),
    (
        "aobake-extension.js",
        include_bytes!("../../viewer/aobake-extension.js"),
    ),
    ("aobake-sh.js", include_bytes!("../../viewer/aobake-sh.js")),
    (
        "aobake-glsl.js",
        include_bytes!("../../viewer/aobake-glsl.js"),
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
