//! `aobake view`: serves the viewer page and one baked file on the loopback
//! interface, so a browser can relight the bake (no upload anywhere: the
//! page also opens local files by itself).
//!
//! In: the viewer directory (`viewer/`, with its npm dependencies
//! installed), an optional GLB, a port (0: any free one). Out: an HTTP
//! server on 127.0.0.1 answering GET requests: `/` is the page, `/model.glb`
//! the file, every other path a file under the viewer directory. It runs
//! until the process ends.

use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};

/// What the server serves.
#[derive(Clone, Debug)]
pub struct ViewSite {
    /// The viewer's directory (index.html, aobake-lightmap.js, node_modules/three).
    pub root: PathBuf,
    /// Served as `/model.glb`.
    pub model: Option<PathBuf>,
}

impl ViewSite {
    /// Checks that the page and three.js are where the server expects them.
    pub fn check(&self) -> Result<()> {
        if !self.root.join("index.html").is_file() {
            return Err(Error::option_conflict(
                "viewer_dir",
                format!("{} has no index.html", self.root.display()),
            ));
        }
        if !self
            .root
            .join("node_modules/three/build/three.module.js")
            .is_file()
        {
            return Err(Error::option_conflict(
                "viewer_dir",
                format!(
                    "three.js is not installed in {}; run: npm ci --prefix {}",
                    self.root.display(),
                    self.root.display()
                ),
            ));
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
    pub fn resolve(&self, path: &str) -> Option<PathBuf> {
        let path = path.split(['?', '#']).next().unwrap_or("");
        let rel = path.trim_start_matches('/');
        if rel == "model.glb" {
            return self.model.clone();
        }
        let rel = if rel.is_empty() { "index.html" } else { rel };
        let rel = Path::new(rel);
        let clean = rel.components().all(|c| match c {
            Component::Normal(p) => !p.to_string_lossy().starts_with('.'),
            _ => false,
        });
        clean.then(|| self.root.join(rel)).filter(|p| p.is_file())
    }
}

/// The content type of a served file, by its extension.
pub fn content_type(path: &Path) -> &'static str {
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
    let (status, kind, body) = if method != "GET" && method != "HEAD" {
        (
            "405 Method Not Allowed",
            "text/plain",
            b"GET only\n".to_vec(),
        )
    } else {
        match site.resolve(path).map(|p| (std::fs::read(&p), p)) {
            Some((Ok(bytes), p)) => ("200 OK", content_type(&p), bytes),
            _ => ("404 Not Found", "text/plain", b"not found\n".to_vec()),
        }
    };
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
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
            root: dir.path().join("."),
            model: Some(model.clone()),
        };
        assert_eq!(site.resolve("/"), Some(dir.path().join("./index.html")));
        assert_eq!(
            site.resolve("/?model=/model.glb"),
            Some(dir.path().join("./index.html"))
        );
        assert_eq!(
            site.resolve("/sub/a.js"),
            Some(dir.path().join("./sub/a.js"))
        );
        assert_eq!(site.resolve("/model.glb"), Some(model));
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
    }
}
