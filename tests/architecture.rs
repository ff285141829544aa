//! The layout's invariants (ARCHITECTURE.md), read off the source:
//!
//! - the top-level modules import only the layers beneath them (so no
//!   import cycle), in the order [`LAYERS`] gives from the bottom;
//! - within a folder, at any depth, its modules (files and subfolders,
//!   counting every file inside a subfolder) import each other without a
//!   cycle;
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

/// A use tree after `crate::` or `super::`, as the paths it names (each a
/// list of segments): `{a::B, c::{d, e as f}}` names `a::B`, `c::d` and
/// `c::e`, with the alias `f` for the last. Returns the paths, each with the
/// name it is known by, and how far it read.
fn use_tree(s: &str) -> (Vec<(Vec<String>, String)>, usize) {
    let bytes = s.as_bytes();
    let mut i = 0;
    let skip_ws = |i: &mut usize| {
        while *i < bytes.len() && (bytes[*i] as char).is_whitespace() {
            *i += 1;
        }
    };
    skip_ws(&mut i);
    if i < bytes.len() && bytes[i] == b'{' {
        i += 1;
        let mut out = Vec::new();
        loop {
            skip_ws(&mut i);
            if i >= bytes.len() || bytes[i] == b'}' {
                return (out, (i + 1).min(bytes.len()));
            }
            let (paths, used) = use_tree(&s[i..]);
            out.extend(paths);
            i += used.max(1);
            skip_ws(&mut i);
            if i < bytes.len() && bytes[i] == b',' {
                i += 1;
            }
        }
    }
    let start = i;
    while i < bytes.len() && ((bytes[i] as char).is_alphanumeric() || bytes[i] == b'_') {
        i += 1;
    }
    let name = s[start..i].to_string();
    if name.is_empty() {
        return (Vec::new(), i);
    }
    if s[i..].starts_with("::") {
        let (rest, used) = use_tree(&s[i + 2..]);
        let rest = rest
            .into_iter()
            .map(|(mut p, alias)| {
                p.insert(0, name.clone());
                (p, alias)
            })
            .collect::<Vec<_>>();
        if rest.is_empty() {
            return (vec![(vec![name.clone()], name)], i + 2 + used);
        }
        return (rest, i + 2 + used);
    }
    let mut alias = name.clone();
    let after = &s[i..];
    let trimmed = after.trim_start();
    if let Some(a) = trimmed.strip_prefix("as ") {
        let a = a.trim_start();
        let len = a
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(a.len());
        alias = a[..len].to_string();
        // `a` is a suffix of `after`: the alias ends `len` past its start.
        i += after.len() - a.len() + len;
    }
    (vec![(vec![name], alias)], i)
}

/// A source file as the module graph sees it: its module path (`src/a/b.rs`
/// and `src/a/b/mod.rs` are both `a::b`), whether it is a `mod.rs`, and its
/// code without comments.
struct Module {
    path: Vec<String>,
    is_mod_rs: bool,
    code: String,
}

fn modules() -> Vec<Module> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files
        .iter()
        .filter_map(|f| {
            let rel = f.strip_prefix(src()).unwrap();
            let mut path: Vec<String> = rel
                .iter()
                .map(|c| c.to_string_lossy().trim_end_matches(".rs").to_string())
                .collect();
            let is_mod_rs = path.last().is_some_and(|l| l == "mod");
            if is_mod_rs {
                path.pop();
            }
            if path == ["lib"] || path == ["main"] {
                return None;
            }
            let code = code(&std::fs::read_to_string(f).unwrap());
            Some(Module {
                path,
                is_mod_rs,
                code,
            })
        })
        .collect()
}

/// For every folder (module with children) at any depth, the graph of its
/// children: child X -> child Y when some file inside X (at any depth) names
/// a path inside Y, through `crate::` or `super::`, or through a name the
/// folder's `mod.rs` re-exports from Y (`pub use y::Item`). Returns the
/// folders whose graph has a cycle, with the graph.
fn nested_cycles(modules: &[Module]) -> Vec<(String, BTreeMap<String, BTreeSet<String>>)> {
    let all: BTreeSet<Vec<String>> = modules
        .iter()
        .flat_map(|m| (1..=m.path.len()).map(|k| m.path[..k].to_vec()))
        .collect();
    // Re-exports: parent::Item -> parent::child.
    let mut reexports: BTreeMap<Vec<String>, Vec<String>> = BTreeMap::new();
    for m in modules.iter().filter(|m| m.is_mod_rs) {
        for stmt in m.code.split(';') {
            let stmt = stmt.trim();
            let Some(tree) = ["pub use ", "pub(crate) use ", "pub(super) use "]
                .iter()
                .find_map(|p| stmt.strip_prefix(p))
            else {
                continue;
            };
            for (p, alias) in use_tree(tree).0 {
                let mut child = m.path.clone();
                child.push(p[0].clone());
                if all.contains(&child) {
                    let mut name = m.path.clone();
                    name.push(alias);
                    reexports.insert(name, child);
                }
            }
        }
    }
    let mut graphs: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for m in modules {
        let mut targets: Vec<Vec<String>> = Vec::new();
        for (prefix, base) in [("crate::", Vec::new()), ("super::", m.path.clone())] {
            for (i, _) in m.code.match_indices(prefix) {
                // `super::super::x` is matched at its first `super::`.
                if prefix == "super::" && m.code[..i].ends_with("super::") {
                    continue;
                }
                let mut base = base.clone();
                let mut rest = &m.code[i..];
                if prefix == "super::" {
                    // The file's own module is `path`; a mod.rs is its
                    // folder, so its `super` is the folder's parent.
                    while let Some(r) = rest.strip_prefix("super::") {
                        base.pop();
                        rest = r;
                    }
                } else {
                    rest = &rest[prefix.len()..];
                    // A `crate::` inside `$crate::` or a longer name is not a path.
                    if i > 0
                        && m.code[..i]
                            .ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == '$')
                    {
                        continue;
                    }
                }
                for (p, _) in use_tree(rest).0 {
                    let mut t = base.clone();
                    t.extend(p);
                    targets.push(t);
                }
            }
        }
        // Each folder above the file: the child the file is in, the child
        // the target is in.
        for depth in 0..m.path.len() {
            let folder = &m.path[..depth];
            let from = &m.path[depth];
            for t in &targets {
                if t.len() <= depth || t[..depth] != *folder {
                    continue;
                }
                let mut child = folder.to_vec();
                child.push(t[depth].clone());
                let child = if all.contains(&child) {
                    child
                } else if let Some(c) = reexports.get(&child) {
                    c.clone()
                } else {
                    continue;
                };
                let to = &child[depth];
                if to != from {
                    graphs
                        .entry(folder.to_vec())
                        .or_default()
                        .entry(from.clone())
                        .or_default()
                        .insert(to.clone());
                }
            }
        }
    }
    graphs
        .into_iter()
        .filter(|(_, g)| cycle(g).is_some())
        .map(|(f, g)| (format!("src/{}", f.join("/")), g))
        .collect()
}

/// Folders allowed an import cycle among their modules, and why. Each must
/// still have one (the test fails once it is gone, so the entry goes too).
const KNOWN_CYCLES: &[(&str, &str)] = &[];

#[test]
fn modules_of_a_folder_import_each_other_without_a_cycle() {
    let cycles = nested_cycles(&modules());
    let unexpected: Vec<_> = cycles
        .iter()
        .filter(|(f, _)| !KNOWN_CYCLES.iter().any(|(k, _)| k == f))
        .collect();
    assert!(unexpected.is_empty(), "import cycles: {unexpected:#?}");
    for (folder, why) in KNOWN_CYCLES {
        assert!(
            cycles.iter().any(|(f, _)| f == folder),
            "{folder} has no import cycle any more ({why}): remove it from KNOWN_CYCLES"
        );
    }
}

/// The nested check finds a circle between a file and a module two folders
/// down (the one `lightmap/filter.rs` and `lightmap/seams/metric.rs` once
/// made), through `super::`, `crate::` and a parent's re-export, and passes
/// the same modules once the circle is cut.
#[test]
fn the_nested_cycle_check_finds_a_circle_across_folders() {
    let module = |path: &str, is_mod_rs: bool, code: &str| Module {
        path: path.split("::").map(String::from).collect(),
        is_mod_rs,
        code: code.to_string(),
    };
    let metric = "use crate::lightmap::filter::Filter;\nfn f(x: Filter) {}";
    let filter_via_super = "fn f() { super::seams::metric::taps([0.0; 2], 1, 1); }";
    let filter_via_crate = "use crate::lightmap::{edge, seams::{metric::taps, find}};";
    let filter_via_reexport = "use crate::lightmap::Seam;";
    let lightmap = "pub mod filter;\npub mod seams;\npub use seams::Seam;";
    let seams = "pub mod metric;\npub mod find;\npub use find::Seam;";
    for filter in [filter_via_super, filter_via_crate, filter_via_reexport] {
        let ms = [
            module("lightmap", true, lightmap),
            module("lightmap::seams", true, seams),
            module("lightmap::seams::find", false, ""),
            module("lightmap::seams::metric", false, metric),
            module("lightmap::filter", false, filter),
            module("lightmap::edge", false, ""),
        ];
        let found = nested_cycles(&ms);
        assert_eq!(found.len(), 1, "{filter}: {found:?}");
        assert_eq!(found[0].0, "src/lightmap");
        // Cut: the filter no longer names the seams.
        let mut ms = ms;
        ms[4] = module("lightmap::filter", false, "fn taps() {}");
        assert!(nested_cycles(&ms).is_empty(), "{filter}");
    }
    // Two files of one folder, as the flat check saw them, still found.
    let ms = [
        module(
            "bake::sheared::gather",
            false,
            "use super::second_pass::finish;",
        ),
        module(
            "bake::sheared::second_pass",
            false,
            "use super::gather::filter_receiver;",
        ),
    ];
    assert_eq!(nested_cycles(&ms).len(), 1);
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
