//! `aobake view`: serves the viewer page and one baked file on the loopback
//! interface, so a browser can relight the bake (no upload anywhere: the
//! page also opens local files by itself).
//!
//! In: the viewer's files (built into the binary, [`embedded`], or a
//! checkout's `viewer/` directory, whose page imports the importer packages
//! from the checkout's `packages/`), an optional GLB, a port (0: any free
//! one). Out: an HTTP server on 127.0.0.1 answering GET requests: `/` is
//! the page, `/model.glb` the file, every other path a viewer file. It
//! runs until the process ends.

pub mod embedded;

use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};

/// Where the page finds the importer packages, as served and in a checkout.
const PACKAGES: &str = "packages/";

/// What the server serves.
#[derive(Clone, Debug)]
pub struct ViewSite {
    /// A checkout's `viewer/` directory (index.html, viewer.js,
    /// vendor/three), the page's packages read from `packages/` beside it;
    /// `None`: the copy built into the binary ([`embedded`]).
    pub root: Option<PathBuf>,
    /// Served as `/model.glb`.
    pub model: Option<PathBuf>,
}

/// A file a request names.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Served {
    /// On disk (the model, or a file under the viewer directory).
    File(PathBuf),
    /// Built in: its path (for the content type) and bytes.
    Embedded(&'static str, &'static [u8]),
}

impl ViewSite {
    /// Checks that the page and three.js are where the server expects them.
    pub fn check(&self) -> Result<()> {
        if let Some(root) = &self.root {
            if !root.join("index.html").is_file() {
                return Err(Error::option_conflict(
                    "viewer_dir",
                    format!("{} has no index.html", root.display()),
                ));
            }
            if !root.join("vendor/three/build/three.module.js").is_file() {
                return Err(Error::option_conflict(
                    "viewer_dir",
                    format!(
                        "{} has no vendor/three/build/three.module.js",
                        root.display()
                    ),
                ));
            }
            let plugin = Path::new(PACKAGES).join("aobake-three/aobake-lightmap.js");
            if !root.join("..").join(&plugin).is_file() {
                return Err(Error::option_conflict(
                    "viewer_dir",
                    format!(
                        "{} has no ../{} (the page's three.js plugin)",
                        root.display(),
                        plugin.display()
                    ),
                ));
            }
        }
        if let Some(m) = &self.model
            && !m.is_file()
        {
            return Err(Error::io(
                m,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
            ));
        }
        Ok(())
    }

    /// The file a request path names, if it may be served: `/model.glb`, or
    /// a path under the root without `..`, hidden parts or a drive.
    pub fn resolve(&self, path: &str) -> Option<Served> {
        let path = path.split(['?', '#']).next().unwrap_or("");
        let rel = path.trim_start_matches('/');
        if rel == "model.glb" {
            return self.model.clone().map(Served::File);
        }
        let rel = if rel.is_empty() { "index.html" } else { rel };
        let clean = Path::new(rel).components().all(|c| match c {
            Component::Normal(p) => !p.to_string_lossy().starts_with('.'),
            _ => false,
        });
        if !clean {
            return None;
        }
        // A large module is kept gzip-compressed (`x.js.gz`) and served as
        // `x.js` with that encoding.
        let gzipped = format!("{rel}.gz");
        [rel, gzipped.as_str()]
            .into_iter()
            .find_map(|rel| match &self.root {
                // The packages' files the page imports, from the checkout's
                // packages/ (not their manifests or tests).
                Some(root) if rel.starts_with(PACKAGES) => embedded::file(rel)
                    .map(|_| root.join("..").join(rel))
                    .filter(|p| p.is_file())
                    .map(Served::File),
                Some(root) => Some(root.join(rel))
                    .filter(|p| p.is_file())
                    .map(Served::File),
                None => embedded::FILES
                    .iter()
                    .find(|(p, _)| *p == rel)
                    .map(|&(p, b)| Served::Embedded(p, b)),
            })
    }
}

/// The content type and encoding of a served file: `x.js.gz` is `x.js`
/// gzip-encoded.
fn kind_of(path: &Path) -> (&'static str, Option<&'static str>) {
    match path.extension().and_then(|e| e.to_str()) {
        Some("gz") => (content_type(&path.with_extension("")), Some("gzip")),
        _ => (content_type(path), None),
    }
}

/// The content type of a served file, by its extension.
pub(crate) fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()).unwrap_or("") {
        "html" => "text/html; charset=utf-8",
        "js" | "mjs" => "text/javascript; charset=utf-8",
        "css" => "text/css; charset=utf-8",
        "json" => "application/json",
        "glb" => "model/gltf-binary",
        "png" => "image/png",
        "jpg" | "jpeg" => "image/jpeg",
        "svg" => "image/svg+xml",
        _ => "application/octet-stream",
    }
}

/// Binds 127.0.0.1:`port` (0: a free port).
pub fn bind(port: u16) -> Result<TcpListener> {
    TcpListener::bind(("127.0.0.1", port)).map_err(|e| Error::io(format!("127.0.0.1:{port}"), e))
}

/// Serves `site` on `listener` until the process ends, one thread per
/// connection.
pub fn serve(listener: TcpListener, site: ViewSite) -> Result<()> {
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let site = site.clone();
        std::thread::spawn(move || {
            // A client that goes away mid-answer is not an error of ours.
            let _ = answer(stream, &site);
        });
    }
    Ok(())
}

fn answer(mut stream: TcpStream, site: &ViewSite) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.read_line(&mut request)?;
    // Skip the headers.
    let mut line = String::new();
    while reader.read_line(&mut line)? > 2 {
        line.clear();
    }
    let mut parts = request.split_whitespace();
    let (method, path) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let not_found = (
        "404 Not Found",
        ("text/plain", None),
        b"not found\n".to_vec(),
    );
    let (status, (kind, encoding), body) = if method != "GET" && method != "HEAD" {
        (
            "405 Method Not Allowed",
            ("text/plain", None),
            b"GET only\n".to_vec(),
        )
    } else {
        match site.resolve(path) {
            Some(Served::File(p)) => match std::fs::read(&p) {
                Ok(bytes) => ("200 OK", kind_of(&p), bytes),
                Err(_) => not_found,
            },
            Some(Served::Embedded(p, bytes)) => ("200 OK", kind_of(Path::new(p)), bytes.to_vec()),
            None => not_found,
        }
    };
    let encoding = encoding
        .map(|e| format!("Content-Encoding: {e}\r\n"))
        .unwrap_or_default();
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\n{encoding}Content-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    if method != "HEAD" {
        stream.write_all(&body)?;
    }
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_files_under_the_root_and_the_model_are_served() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("index.html"), "page").unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(dir.path().join("sub/a.js"), "js").unwrap();
        std::fs::write(dir.path().join(".secret"), "no").unwrap();
        let model = dir.path().join("m.glb");
        std::fs::write(&model, "glb").unwrap();
        let site = ViewSite {
            root: Some(dir.path().join(".")),
            model: Some(model.clone()),
        };
        let file = |p: &str| Some(Served::File(dir.path().join(p)));
        assert_eq!(site.resolve("/"), file("./index.html"));
        assert_eq!(site.resolve("/?model=/model.glb"), file("./index.html"));
        assert_eq!(site.resolve("/sub/a.js"), file("./sub/a.js"));
        std::fs::write(dir.path().join("sub/big.js.gz"), "gz").unwrap();
        assert_eq!(site.resolve("/sub/big.js"), file("./sub/big.js.gz"));
        assert_eq!(
            kind_of(Path::new("sub/big.js.gz")),
            ("text/javascript; charset=utf-8", Some("gzip"))
        );
        assert_eq!(kind_of(Path::new("a.glb")), ("model/gltf-binary", None));
        assert_eq!(site.resolve("/model.glb"), Some(Served::File(model)));
        for refused in [
            "/../etc/passwd",
            "/sub/../../x",
            "/.secret",
            "//etc/passwd",
            "/nope.js",
        ] {
            assert_eq!(site.resolve(refused), None, "{refused}");
        }
        assert_eq!(
            content_type(Path::new("a.mjs")),
            "text/javascript; charset=utf-8"
        );
        // Built in: the page and every module it imports, nothing else.
        let built_in = ViewSite {
            root: None,
            model: None,
        };
        for path in [
            "/",
            "/viewer.js",
            "/vendor/three/build/three.core.js",
            "/vendor/babylon/aobake-babylon.js",
            "/packages/aobake-three/aobake-lightmap.js",
            "/packages/aobake-contract/index.js",
        ] {
            assert!(
                matches!(built_in.resolve(path), Some(Served::Embedded(..))),
                "{path}"
            );
        }
        for refused in [
            "/../Cargo.toml",
            "/package.json",
            "/model.glb",
            "/.x",
            "/packages/aobake-three/package.json",
        ] {
            assert_eq!(built_in.resolve(refused), None, "{refused}");
        }
    }

    /// From a checkout, the page's packages come from `packages/` beside
    /// `viewer/`: the modules the page imports, not the manifests or tests.
    #[test]
    fn a_checkouts_viewer_imports_its_packages() {
        let dir = tempfile::tempdir().unwrap();
        let viewer = dir.path().join("viewer");
        let contract = dir.path().join("packages/aobake-contract");
        std::fs::create_dir_all(&viewer).unwrap();
        std::fs::create_dir_all(contract.join("test")).unwrap();
        std::fs::write(viewer.join("index.html"), "page").unwrap();
        for f in ["index.js", "sh.js", "package.json", "test/a.mjs"] {
            std::fs::write(contract.join(f), "x").unwrap();
        }
        let site = ViewSite {
            root: Some(viewer.clone()),
            model: None,
        };
        for f in ["index.js", "sh.js"] {
            assert_eq!(
                site.resolve(&format!("/packages/aobake-contract/{f}")),
                Some(Served::File(
                    viewer.join("../packages/aobake-contract").join(f)
                )),
                "{f}"
            );
        }
        for refused in [
            "/packages/aobake-contract/package.json",
            "/packages/aobake-contract/test/a.mjs",
            "/packages/../viewer/index.html",
            "/packages/aobake-contract/../../x",
        ] {
            assert_eq!(site.resolve(refused), None, "{refused}");
        }
        // check() wants the three.js plugin beside the page.
        assert!(site.check().is_err());
    }

    /// The built-in page imports only what is built in: every relative
    /// import of every built-in module resolves to a built-in file, and
    /// every import-map entry too.
    #[test]
    fn every_import_of_the_built_in_page_is_built_in() {
        let mut missing = Vec::new();
        for (path, bytes) in embedded::FILES {
            let text = String::from_utf8_lossy(bytes);
            let dir = Path::new(path).parent().unwrap_or(Path::new(""));
            let quoted = text.split(['\'', '"']).collect::<Vec<_>>();
            for (k, part) in quoted.iter().enumerate() {
                let before = quoted[k.saturating_sub(1)];
                let imported = k % 2 == 1
                    && (part.starts_with("./") || part.starts_with("../"))
                    && (part.ends_with(".js") || part.ends_with('/'))
                    && (before.trim_end().ends_with("from")
                        || before.trim_end().ends_with("import")
                        || before.trim_end().ends_with("import(")
                        || before.trim_end().ends_with(':')
                        || before.trim_end().ends_with("src="));
                if !imported {
                    continue;
                }
                let mut parts: Vec<String> = dir
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().to_string())
                    .collect();
                for c in part.split('/') {
                    match c {
                        "." | "" => {}
                        ".." => {
                            parts.pop();
                        }
                        c => parts.push(c.to_string()),
                    }
                }
                let joined = parts.join("/");
                let known = if part.ends_with('/') {
                    embedded::FILES.iter().any(|(p, _)| p.starts_with(&joined))
                } else {
                    embedded::file(&joined).is_some()
                        || embedded::file(&format!("{joined}.gz")).is_some()
                };
                if !known {
                    missing.push(format!("{path}: {part}"));
                }
            }
        }
        assert!(missing.is_empty(), "{missing:?}");
    }

    /// Every bare import of a built-in module (`'three'`,
    /// `'aobake-contract'`) is a name in the page's import map, so the
    /// browser can resolve it; the Babylon.js bundle has none.
    #[test]
    fn every_bare_import_is_in_the_import_map() {
        let page = String::from_utf8_lossy(embedded::file("index.html").unwrap());
        let map = &page[page.find("\"imports\"").unwrap()..];
        let map = &map[..map.find("</script>").unwrap()];
        let mut bare = Vec::new();
        for (path, bytes) in embedded::FILES {
            if !path.ends_with(".js") || path.starts_with("vendor/") {
                continue;
            }
            let text = String::from_utf8_lossy(bytes);
            for line in text.lines().map(str::trim) {
                let Some(from) = line.strip_prefix("} from '").or_else(|| {
                    line.starts_with("import ")
                        .then(|| line.split(" from '").nth(1))
                        .flatten()
                }) else {
                    continue;
                };
                let name = from.split('\'').next().unwrap_or("");
                if name.starts_with('.') {
                    continue;
                }
                bare.push(name.to_string());
                let mapped = map.contains(&format!("\"{name}\""))
                    || map
                        .split('"')
                        .any(|k| k.ends_with('/') && !k.starts_with('.') && name.starts_with(k));
                assert!(mapped, "{path} imports '{name}', not in the import map");
            }
        }
        for name in ["three", "aobake-three", "aobake-contract"] {
            assert!(bare.iter().any(|b| b == name), "{name}: {bare:?}");
        }
    }
}
