//! The layout's invariants (ARCHITECTURE.md), read off the source:
//!
//! - the top-level modules import only the layers beneath them (so no
//!   import cycle), in the order [`LAYERS`] gives from the bottom;
//! - within a folder, the files' imports of each other form no cycle;
//! - at most 12 `.rs` files directly in `src/`, no file over 600 lines
//!   but the ones named in [`LONG_FILES`] with their reason.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every top-level module, from the bottom layer up: a module may import
/// only modules before it. ARCHITECTURE.md shows the same order.
const LAYERS: &[&str] = &[
    "error", "bits", "file", "stage", "sample", "sh", "relight", "geometry", "trace", "atlas",
    "bake", "lightmap", "encode", "gltf", "shard", "job", "report", "view",
];

/// Files allowed over 600 lines, and why.
const LONG_FILES: &[(&str, &str)] = &[
    // Algorithm 1 of Egan et al. read line by line as one function with
    // its helpers; splitting it would separate the paper's steps.
    (
        "bake/sheared/receiver.rs",
        "the paper's Algorithm 1 in one place",
    ),
    // The scene graph walk, primitive decoding and bake space: one
    // reading pass over the document.
    ("gltf/scene.rs", "one pass over the document"),
];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The source without comments (line comments, doc comments included).
fn code(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths a file names after `prefix` (`crate::` or `super::`), as
/// their first segments; `use crate::{a, b::c}` names `a` and `b`.
fn named_after(code: &str, prefix: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    for (i, _) in code.match_indices(prefix) {
        let rest = &code[i + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for part in group[..end].split(',') {
                let name = ident(part.trim());
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        } else {
            let name = ident(rest);
            if !name.is_empty() {
                out.insert(name);
            }
        }
    }
    out
}

/// Whether the graph has a cycle; if so, one of its nodes.
fn cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<String> {
    fn visit(
        n: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
    ) -> Option<String> {
        match state.get(n) {
            Some(1) => return Some(n.to_string()),
            Some(2) => return None,
            _ => {}
        }
        state.insert(n.to_string(), 1);
        for m in graph.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, graph, state) {
                return Some(c);
            }
        }
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    graph.keys().find_map(|n| visit(n, graph, &mut state))
}

#[test]
fn modules_import_only_the_layers_beneath_them() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut wrong = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(src()).unwrap();
        let top = rel.iter().next().unwrap().to_string_lossy().to_string();
        let top = top.trim_end_matches(".rs").to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let level = LAYERS.iter().position(|&l| l == top);
        assert!(
            level.is_some(),
            "{top} is not in LAYERS (place it there and in ARCHITECTURE.md)"
        );
        for used in named_after(&code(&std::fs::read_to_string(f).unwrap()), "crate::") {
            if used == top {
                continue;
            }
            let Some(u) = LAYERS.iter().position(|&l| l == used) else {
                continue;
            };
            graph.entry(top.clone()).or_default().insert(used.clone());
            if u > level.unwrap() {
                wrong.push(format!(
                    "{} imports {used}, a layer above {top}",
                    rel.display()
                ));
            }
        }
    }
    assert_eq!(cycle(&graph), None, "an import cycle: {graph:?}");
    assert!(wrong.is_empty(), "{wrong:#?}");
    // Every module of lib.rs is placed.
    let lib = std::fs::read_to_string(src().join("lib.rs")).unwrap();
    for line in lib.lines().filter_map(|l| l.strip_prefix("pub mod ")) {
        let name = line.trim_end_matches(';');
        assert!(LAYERS.contains(&name), "{name} is not in LAYERS");
    }
}

#[test]
fn files_of_a_folder_import_each_other_without_a_cycle() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    // Per folder: file stem -> the siblings it names.
    let mut folders: BTreeMap<PathBuf, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for f in &files {
        let dir = f.parent().unwrap().to_path_buf();
        let stem = f.file_stem().unwrap().to_string_lossy().to_string();
        if stem == "mod" || stem == "lib" || stem == "main" {
            // mod.rs declares its children; their `super::` names reach it.
            continue;
        }
        let text = code(&std::fs::read_to_string(f).unwrap());
        let module_path: Vec<String> = dir
            .strip_prefix(src())
            .unwrap()
            .iter()
            .map(|c| c.to_string_lossy().to_string())
            .collect();
        let mut named = named_after(&text, "super::");
        let own = format!("crate::{}::", module_path.join("::"));
        if !module_path.is_empty() {
            named.extend(named_after(&text, &own));
        }
        folders.entry(dir).or_default().insert(stem, named);
    }
    for (dir, graph) in folders {
        let siblings: BTreeSet<String> = graph.keys().cloned().collect();
        let graph: BTreeMap<String, BTreeSet<String>> = graph
            .into_iter()
            .map(|(k, v)| {
                let v = v
                    .into_iter()
                    .filter(|n| siblings.contains(n) && *n != k)
                    .collect();
                (k, v)
            })
            .collect();
        assert_eq!(cycle(&graph), None, "{}: {graph:?}", dir.display());
    }
}

#[test]
fn the_source_tree_keeps_its_size_limits() {
    let top: Vec<String> = std::fs::read_dir(src())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| p.file_name().unwrap().to_string_lossy().to_string())
        .collect();
    assert!(
        top.len() <= 12,
        "{} files directly in src/: {top:?}",
        top.len()
    );
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    for f in files {
        let rel = f
            .strip_prefix(src())
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let lines = std::fs::read_to_string(&f).unwrap().lines().count();
        if lines > 600 {
            assert!(
                LONG_FILES.iter().any(|(p, _)| *p == rel),
                "{rel} has {lines} lines (over 600; split it or name it in LONG_FILES)"
            );
        }
    }
}

#[test]
fn the_cycle_check_finds_a_cycle() {
    let g = |edges: &[(&str, &str)]| {
        let mut m: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            m.entry(a.to_string()).or_default().insert(b.to_string());
        }
        m
    };
    assert!(cycle(&g(&[("a", "b"), ("b", "c"), ("c", "a")])).is_some());
    assert!(cycle(&g(&[("a", "b"), ("b", "c"), ("a", "c")])).is_none());
    let names = named_after(
        "use crate::{bake::Bake, error::Result};\nlet x = crate::sh::K0;",
        "crate::",
    );
    assert_eq!(
        names.into_iter().collect::<Vec<_>>(),
        vec!["bake", "error", "sh"]
    );
}
