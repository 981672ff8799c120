//! A static file server on 127.0.0.1 for pages Chromium must load over HTTP (ES modules are
//! refused from `file://`): GET only, one thread per connection, `Connection: close`.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::path::{Component, Path, PathBuf};

/// Serves `mounts` (URL prefix, folder; the longest matching prefix wins) until the process
/// ends; returns the base URL (`http://127.0.0.1:PORT`).
pub fn serve(mounts: Vec<(String, PathBuf)>) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let mounts = mounts.clone();
            std::thread::spawn(move || {
                let mut stream = stream;
                let mut line = String::new();
                if BufReader::new(&stream).read_line(&mut line).is_err() {
                    return;
                }
                let path = line.split_whitespace().nth(1).unwrap_or("/");
                let path = path.split('?').next().unwrap_or("/");
                let (status, kind, body) = match resolve(&mounts, path)
                    .and_then(|f| std::fs::read(&f).ok().map(|b| (f, b)))
                {
                    Some((file, body)) => ("200 OK", content_type(&file), body),
                    None => ("404 Not Found", "text/plain", b"not found".to_vec()),
                };
                let head = format!(
                    "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
                     Connection: close\r\n\r\n",
                    body.len()
                );
                let _ = stream.write_all(head.as_bytes());
                let _ = stream.write_all(&body);
            });
        }
    });
    base
}

/// The file a URL path names under the mounts, never outside them.
fn resolve(mounts: &[(String, PathBuf)], path: &str) -> Option<PathBuf> {
    let (prefix, dir) = mounts
        .iter()
        .filter(|(p, _)| path.starts_with(p.as_str()))
        .max_by_key(|(p, _)| p.len())?;
    let rest = Path::new(&path[prefix.len()..]);
    if rest
        .components()
        .any(|c| !matches!(c, Component::Normal(_)))
    {
        return None;
    }
    Some(dir.join(rest)).filter(|f| f.is_file())
}

fn content_type(file: &Path) -> &'static str {
    match file.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript",
        Some("glb") => "model/gltf-binary",
        Some("json") => "application/json",
        _ => "application/octet-stream",
    }
}
