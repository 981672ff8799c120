//! The crate's layering, checked on its sources (`docs/ARCHITECTURE.md`):
//! - `src/shared/` imports only from `src/shared/`;
//! - `src/motion/` (skeletons, joint positions, feature layouts: what every family speaks)
//!   imports only from `src/shared/` and itself;
//! - `src/viewer/` (pictures of motion: the HTML player, the GIF) imports only from
//!   `src/shared/`, `src/motion/` and itself;
//! - `src/family/` (what a family plugs into: the `Family` and `Stream` traits, the `Session`,
//!   the motion stages) imports only from `src/shared/`, `src/motion/` and itself;
//! - a family folder (`src/armflow/`, `src/umf/`, and each one added beside them) imports only
//!   from `src/shared/`, `src/motion/`, `src/family/` and itself: never the `Model` handle, the
//!   manifest, the C ABI, the crate root's re-exports, or another family;
//! - no import cycle between modules, file by file (`armflow/session/lanes.rs` is its own
//!   module): a module may use its parent and the parent its submodules (it declares them), but
//!   no chain of imports comes back to where it started.
//!
//! Imports are read from `use` trees and from `crate::`/`super::` paths in code, in the whole of
//! every file; comments and the items marked `#[cfg(test)]` (a test module, function or `use`,
//! to its end) are left out. The Python tooling under `onnx/troupe_onnx/` has the same rule,
//! checked by `onnx/tests/test_layout.py`, which the last test here runs.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Folders under `src/` that are layers rather than families.
const NOT_FAMILIES: [&str; 5] = ["shared", "motion", "family", "ffi", "viewer"];

/// What each layer beneath the families may import besides itself.
const LOWER_LAYERS: [(&str, &[&str]); 4] = [
    ("shared", &[]),
    ("motion", &["shared"]),
    ("viewer", &["shared", "motion"]),
    ("family", &["shared", "motion"]),
];

struct SourceFile {
    /// Path relative to `src/`, for messages.
    path: PathBuf,
    /// The module this file defines, from the crate root (`["armflow", "session"]`).
    module: Vec<String>,
    /// Every crate path it names, resolved from the crate root.
    imports: Vec<Vec<String>>,
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn module_of(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without its `#[cfg(test)]` items.
fn code_of(text: &str) -> String {
    without_test_items(text)
        .lines()
        .filter(|line| !line.trim_start().starts_with("//"))
        .map(|line| line.split(" // ").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `text` without each item marked `#[cfg(test)]`: the attribute and what follows it up to the
/// `;` that ends it or the `}` that closes its body. Everything after the item is kept: a test
/// module in the middle of a file (or a test-only `use` at its top) must not hide the rest.
fn without_test_items(text: &str) -> String {
    const ATTR: &str = "#[cfg(test)]";
    let mut out = String::with_capacity(text.len());
    // Inside a test item: how deep in brackets of any kind.
    let mut skipping: Option<usize> = None;
    let mut at = 0;
    while at < text.len() {
        let rest = &text[at..];
        if skipping.is_none() && rest.starts_with(ATTR) {
            skipping = Some(0);
            at += ATTR.len();
            continue;
        }
        // Literals and comments are passed over whole, so a brace inside one is not counted.
        let len = literal_or_comment_len(rest)
            .unwrap_or_else(|| rest.chars().next().map_or(1, char::len_utf8));
        match (skipping, &rest[..len]) {
            (None, kept) => out.push_str(kept),
            (Some(depth), "{" | "(" | "[") => skipping = Some(depth + 1),
            (Some(depth), ")" | "]") => skipping = Some(depth.saturating_sub(1)),
            (Some(depth), "}") => skipping = (depth > 1).then(|| depth - 1),
            (Some(0), ";") => skipping = None,
            _ => {}
        }
        at += len;
    }
    out
}

/// The length of the comment, string or character literal that `code` starts with, if any.
fn literal_or_comment_len(code: &str) -> Option<usize> {
    let bytes = code.as_bytes();
    if code.starts_with("//") {
        return Some(code.find('\n').unwrap_or(code.len()));
    }
    if code.starts_with("/*") {
        // Block comments nest.
        let (mut depth, mut i) = (0usize, 0);
        while i < bytes.len() {
            if bytes[i..].starts_with(b"/*") {
                depth += 1;
                i += 2;
            } else if bytes[i..].starts_with(b"*/") {
                depth -= 1;
                i += 2;
                if depth == 0 {
                    return Some(i);
                }
            } else {
                i += 1;
            }
        }
        return Some(bytes.len());
    }
    if bytes[0] == b'"' {
        let mut i = 1;
        while i < bytes.len() {
            match bytes[i] {
                b'\\' => i += 2,
                b'"' => return Some(i + 1),
                _ => i += 1,
            }
        }
        return Some(bytes.len());
    }
    if bytes[0] == b'r' {
        // A raw string: r"..." or r#"..."#, as many hashes to close as to open.
        let hashes = bytes[1..].iter().take_while(|&&b| b == b'#').count();
        if bytes.get(1 + hashes) == Some(&b'"') {
            let close = format!("\"{}", "#".repeat(hashes));
            let body = 2 + hashes;
            return Some(
                code[body..]
                    .find(&close)
                    .map_or(code.len(), |e| body + e + close.len()),
            );
        }
        return None;
    }
    if bytes[0] == b'\'' {
        // '\n', '\'', '\u{..}' or one character; otherwise a lifetime, which is not a literal.
        if bytes.get(1) == Some(&b'\\') {
            let close = code.get(3..).and_then(|tail| tail.find('\''));
            return Some(close.map_or(code.len(), |e| 3 + e + 1));
        }
        let c = code[1..].chars().next()?;
        if code[1 + c.len_utf8()..].starts_with('\'') {
            return Some(1 + c.len_utf8() + 1);
        }
    }
    None
}

/// Expands a `use` tree (`a::{b, c::{d, self}}`) into its paths.
fn expand_use_tree(tree: &str) -> Vec<Vec<String>> {
    fn parse(tokens: &[String], at: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
        let mut path = prefix;
        while *at < tokens.len() {
            let token = tokens[*at].clone();
            *at += 1;
            match token.as_str() {
                "::" => {}
                "{" => {
                    loop {
                        parse(tokens, at, path.clone(), out);
                        match tokens.get(*at).map(String::as_str) {
                            Some(",") => *at += 1,
                            Some("}") => {
                                *at += 1;
                                break;
                            }
                            _ => break,
                        }
                    }
                    return;
                }
                "," | "}" => {
                    *at -= 1;
                    break;
                }
                "self" if !path.is_empty() => {}
                _ => path.push(token),
            }
        }
        if !path.is_empty() {
            out.push(path);
        }
    }
    let mut tokens = Vec::new();
    let mut word = String::new();
    let spaced = tree.replace("::", " :: ");
    for c in spaced.chars() {
        if c.is_alphanumeric() || c == '_' || c == '*' || c == ':' {
            word.push(c);
        } else {
            if !word.is_empty() {
                tokens.push(std::mem::take(&mut word));
            }
            if "{},".contains(c) {
                tokens.push(c.to_string());
            }
        }
    }
    if !word.is_empty() {
        tokens.push(word);
    }
    // `x as y`: keep the path, drop the alias.
    let mut cleaned = Vec::new();
    let mut skip = false;
    for t in tokens {
        if skip {
            skip = false;
        } else if t == "as" {
            skip = true;
        } else {
            cleaned.push(t);
        }
    }
    let mut out = Vec::new();
    let mut at = 0;
    while at < cleaned.len() {
        parse(&cleaned, &mut at, Vec::new(), &mut out);
        at += 1;
    }
    out
}

/// Resolves a path as written in `module` to a path from the crate root, or `None` for paths
/// outside the crate (`std::`, `ndarray::`, ...).
fn resolve(
    path: &[String],
    module: &[String],
    children: &BTreeSet<Vec<String>>,
) -> Option<Vec<String>> {
    let (first, rest) = path.split_first()?;
    let mut base: Vec<String> = match first.as_str() {
        "crate" => Vec::new(),
        "self" => module.to_vec(),
        "super" => module[..module.len().saturating_sub(1)].to_vec(),
        _ => {
            let mut child = module.to_vec();
            child.push(first.clone());
            if !children.contains(&child) {
                return None;
            }
            child
        }
    };
    let mut rest = rest;
    while let Some((s, tail)) = rest.split_first() {
        if s != "super" {
            break;
        }
        base.pop();
        rest = tail;
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// Every path of the crate that `code` names: `use` trees and `crate::`/`super::` paths.
fn paths_named(code: &str) -> Vec<Vec<String>> {
    let mut found = Vec::new();
    for statement in code.split(';') {
        let trimmed = statement.trim_start();
        let tree = trimmed
            .strip_prefix("pub(crate) use ")
            .or_else(|| trimmed.strip_prefix("pub use "))
            .or_else(|| trimmed.strip_prefix("use "));
        if let Some(tree) = tree {
            found.extend(expand_use_tree(tree));
        }
    }
    for anchor in ["crate::", "super::"] {
        for (at, _) in code.match_indices(anchor) {
            let before = code[..at].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let path: String = code[at..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let segments: Vec<String> = path
                .split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect();
            found.push(segments);
        }
    }
    found
}

fn load() -> Vec<SourceFile> {
    let src = src_dir();
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    let relatives: Vec<PathBuf> = paths
        .iter()
        .map(|p| p.strip_prefix(&src).unwrap().to_path_buf())
        .collect();
    let modules: BTreeSet<Vec<String>> = relatives.iter().map(|r| module_of(r)).collect();
    paths
        .iter()
        .zip(relatives)
        .map(|(path, relative)| {
            let module = module_of(&relative);
            let code = code_of(&std::fs::read_to_string(path).unwrap());
            let imports = paths_named(&code)
                .iter()
                .filter_map(|p| resolve(p, &module, &modules))
                .collect();
            SourceFile {
                path: relative,
                module,
                imports,
            }
        })
        .collect()
}

/// The family folders: every module folder under `src/` but the layers.
fn families() -> BTreeSet<String> {
    std::fs::read_dir(src_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("mod.rs").is_file())
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .filter(|name| !NOT_FAMILIES.contains(&name.as_str()))
        .collect()
}

#[test]
fn the_parser_reads_use_trees_and_paths() {
    let trees = expand_use_tree("crate::{a::{b, c as d}, e::self, f::*}");
    let want: Vec<Vec<&str>> = vec![
        vec!["crate", "a", "b"],
        vec!["crate", "a", "c"],
        vec!["crate", "e"],
        vec!["crate", "f", "*"],
    ];
    assert_eq!(trees, want);
    let children = BTreeSet::from([vec!["x".to_string(), "y".to_string()]]);
    let module = vec!["x".to_string()];
    let p = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert_eq!(
        resolve(&p(&["y", "Z"]), &module, &children),
        Some(p(&["x", "y", "Z"]))
    );
    assert_eq!(
        resolve(&p(&["super", "q"]), &module, &children),
        Some(p(&["q"]))
    );
    assert_eq!(resolve(&p(&["std", "sync"]), &module, &children), None);
    let named = paths_named("let a = crate::model::Model::load(x);\nuse super::{k, l};");
    assert!(
        named.contains(&p(&["crate", "model", "Model", "load"])),
        "{named:?}"
    );
    assert!(named.contains(&p(&["super", "l"])), "{named:?}");

    // A test item is left out to its end, braces in its literals and comments not counted,
    // and the code after it is read.
    let code = code_of(
        "use crate::a;\n#[cfg(test)]\nuse crate::b;\n#[cfg(test)]\nmod tests {\n    \
         use crate::c;\n    const X: [u8; 2] = [b'}', b'{'];\n    fn f<'a>(s: &'a str) -> &'a str \
         { \"}\" }\n    /* } */ const Y: &str = r#\"}\"#;\n}\nuse crate::d;\n",
    );
    let named = paths_named(&code);
    assert!(named.contains(&p(&["crate", "a"])), "{code}");
    assert!(named.contains(&p(&["crate", "d"])), "{code}");
    assert!(!named.contains(&p(&["crate", "b"])), "{code}");
    assert!(!named.contains(&p(&["crate", "c"])), "{code}");
}

#[test]
fn the_layers_beneath_the_families_import_only_downward() {
    let files = load();
    let mut bad = Vec::new();
    for (layer, below) in LOWER_LAYERS {
        for f in files
            .iter()
            .filter(|f| f.module.first().is_some_and(|m| m == layer))
        {
            for import in &f.imports {
                let top = import.first().map(String::as_str).unwrap_or("(crate root)");
                if top != layer && !below.contains(&top) {
                    bad.push(format!(
                        "{}: crate::{}",
                        f.path.display(),
                        import.join("::")
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "a layer beneath the families reaches above itself:\n{}",
        bad.join("\n")
    );
}

#[test]
fn a_family_imports_only_the_layers_beneath_and_itself() {
    let files = load();
    let families = families();
    assert!(
        families.contains("armflow") && families.contains("umf"),
        "families found: {families:?}"
    );
    let mut bad = Vec::new();
    for f in &files {
        let Some(family) = f.module.first().filter(|m| families.contains(*m)) else {
            continue;
        };
        for import in &f.imports {
            let top = import.first().map(String::as_str).unwrap_or("(crate root)");
            if !matches!(top, "shared" | "motion" | "family") && top != family {
                bad.push(format!(
                    "{}: crate::{}",
                    f.path.display(),
                    import.join("::")
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "a family imports the Model handle, the manifest, the C ABI, the crate root or \
         another family:\n{}",
        bad.join("\n")
    );
}

#[test]
fn no_import_cycle_between_modules() {
    let files = load();
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| f.module.clone()).collect();
    // Every file is its own module: an import names the deepest module its path goes through.
    let unit = |path: &[String]| -> Vec<String> {
        let mut known = path.to_vec();
        while !known.is_empty() && !modules.contains(&known) {
            known.pop();
        }
        known
    };
    let name = |m: &[String]| -> String {
        if m.is_empty() {
            "(crate root)".into()
        } else {
            m.join("::")
        }
    };
    // The crate root only declares modules and re-exports their items: name the item's home.
    let root = files
        .iter()
        .find(|f| f.module.is_empty())
        .expect("src/lib.rs");
    let reexports: BTreeMap<String, Vec<String>> = root
        .imports
        .iter()
        .filter_map(|p| p.last().map(|name| (name.clone(), p.clone())))
        .collect();
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files.iter().filter(|f| !f.module.is_empty()) {
        let from = unit(&f.module);
        for import in &f.imports {
            let target = match import.as_slice() {
                [name, ..] if !modules.contains(&vec![name.clone()]) => match reexports.get(name) {
                    Some(home) => home.clone(),
                    None => continue,
                },
                _ => import.clone(),
            };
            let to = unit(&target);
            // A module's imports of its own submodules are the folder using its parts (it
            // declares them); every other import is an edge.
            if to != from && !to.starts_with(&from) {
                edges.entry(name(&from)).or_default().insert(name(&to));
            }
        }
    }
    fn visit(
        node: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(node) {
            Some(2) => return None,
            Some(1) => {
                let start = stack.iter().position(|n| n == node).unwrap();
                let mut cycle = stack[start..].to_vec();
                cycle.push(node.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(node.to_string(), 1);
        stack.push(node.to_string());
        for next in edges.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, edges, state, stack) {
                return Some(cycle);
            }
        }
        stack.pop();
        state.insert(node.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in edges.keys() {
        if let Some(cycle) = visit(node, &edges, &mut state, &mut Vec::new()) {
            panic!("import cycle: {}", cycle.join(" -> "));
        }
    }
    // The checks above see the layers they are about.
    assert!(
        edges.get("model").is_some_and(|to| to.contains("armflow")),
        "{edges:#?}"
    );
    assert!(edges
        .get("armflow::session::lanes")
        .is_some_and(|to| to.contains("armflow::networks")));
}

#[test]
fn the_python_tooling_keeps_the_same_layers() {
    let (ok, text) = common::run_python(
        &[
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "onnx/tests/test_layout.py",
        ],
        &[],
    );
    assert!(
        ok,
        "onnx/tests/test_layout.py failed (it needs pytest):\n{text}"
    );
    assert!(text.contains("3 passed"), "{text}");
}
