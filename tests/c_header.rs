//! `include/troupe.h` is generated: cbindgen reads `src/ffi/` alone (`cbindgen.toml`), and this
//! file lays its items out in the fixed sections of [`SECTIONS`] after the usage guide, each
//! item in the section of the `src/ffi/` file that defines it. The tests fail when the
//! committed header differs from a fresh generation (`TROUPE_BLESS=1 cargo test --test
//! c_header` rewrites it), when an item's file belongs to no section, and when the header
//! names anything at file scope without the `troupe_`/`TROUPE_` prefix.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The header's sections in order: title, what it holds, and the `src/ffi/` files whose items
/// it takes. A section comes after every section whose types it uses (the C compile tests
/// catch a wrong order).
const SECTIONS: &[(&str, &str, &[&str])] = &[
    (
        "Version and ABI",
        "What this library is; compare with the TROUPE_VERSION_* macros above.",
        &["version.rs"],
    ),
    (
        "Status codes and errors",
        "What every fallible call returns, and the calling thread's last error message.",
        &["status.rs"],
    ),
    (
        "Limits",
        "The bounds every size from a file or a caller is checked against.",
        &["limits.rs"],
    ),
    (
        "Threads, logging and progress",
        "Process-wide settings: threads troupe may start, where its log goes, and the calling \
         thread's progress callback for long calls.",
        &["threads.rs", "log.rs", "progress.rs"],
    ),
    (
        "Model",
        "Loading a bundle and what every bundle answers, whatever its family.",
        &["model.rs"],
    ),
    (
        "Session",
        "One stream (ARMFlow reaction, MAGNet live partner, ARFlow online): options, stepping \
         one or many, reset, the settings every stream takes and those a stream reports as \
         capabilities.",
        &["session.rs"],
    ),
    (
        "Text prompts",
        "Conditions from text, for bundles with a text encoder or text branch.",
        &["text.rs"],
    ),
    (
        "Motion",
        "Joint positions of the t2m-22 skeleton in the caller's units and axes, feature \
         encoding, BVH and JSON files, the penetration metrics.",
        &["motion/mod.rs", "motion/bvh.rs", "motion/export.rs"],
    ),
    (
        "Rigs and glTF",
        "A caller's character rig, troupe's motion retargeted onto it frame by frame or as a \
         clip, and glTF (.glb) and BVH files of it.",
        &["motion/rig.rs"],
    ),
    (
        "Session motion",
        "Every streaming family's motion stages, chosen by its frame layout: joint positions \
         in and poses out, the penetration guard, the root smoothing, the foot lock.",
        &[
            "session_motion/joints.rs",
            "session_motion/guard.rs",
            "session_motion/smoothing.rs",
            "session_motion/foot_lock.rs",
        ],
    ),
    (
        "ARMFlow",
        "Online reaction: its session options, recentring, noise queued per token, the \
         official clip.",
        &[
            "armflow/options.rs",
            "armflow/recentring.rs",
            "armflow/noise.rs",
            "armflow/clip.rs",
        ],
    ),
    ("UMF", "Text to a group of any size.", &["umf/group.rs"]),
    (
        "MAGNet",
        "Multi-agent diffusion forcing: the released tasks, and the live partner's settings.",
        &["magnet/mod.rs", "magnet/session.rs"],
    ),
    (
        "ARFlow",
        "Action to reaction with penetration guidance, offline and online.",
        &["arflow/mod.rs"],
    ),
    (
        "Viewer",
        "Pictures of motion: a self-contained HTML player and a GIF.",
        &["viewer.rs"],
    ),
    (
        "Deprecated names",
        "The names before every family call had its family's prefix; each forwards to the \
         function it names. Kept until 2.0.",
        &["deprecated.rs"],
    ),
];

/// Defines the deprecation attribute the header's deprecated functions carry.
const DEPRECATION_MACRO: &str = "\
/* Marks the deprecated names; define TROUPE_NO_DEPRECATION_WARNINGS to silence them. */
#if defined(TROUPE_NO_DEPRECATION_WARNINGS)
#define TROUPE_DEPRECATED(note)
#elif defined(__cplusplus) && __cplusplus >= 201402L
#define TROUPE_DEPRECATED(note) [[deprecated(note)]]
#elif defined(__GNUC__) || defined(__clang__)
#define TROUPE_DEPRECATED(note) __attribute__((deprecated(note)))
#elif defined(_MSC_VER)
#define TROUPE_DEPRECATED(note) __declspec(deprecated(note))
#else
#define TROUPE_DEPRECATED(note)
#endif";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn version_macros() -> String {
    let (major, minor, patch) = (
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
    );
    let packed = (major.parse::<u32>().unwrap() << 16)
        | (minor.parse::<u32>().unwrap() << 8)
        | patch.parse::<u32>().unwrap();
    format!(
        "/* Version of this header, from Cargo.toml; compare with troupe_version_number(). */\n\
         #define TROUPE_VERSION_MAJOR {major}\n#define TROUPE_VERSION_MINOR {minor}\n\
         #define TROUPE_VERSION_PATCH {patch}\n#define TROUPE_VERSION_STRING \"{}\"\n\
         #define TROUPE_VERSION_NUMBER {packed}\n",
        env!("CARGO_PKG_VERSION")
    )
}

/// One top-level declaration of cbindgen's output with its doc comment.
struct Item {
    name: String,
    text: String,
}

/// Splits cbindgen's output into items: a doc comment, then a `#define` line or a declaration
/// that ends with `;` outside braces.
fn items(body: &str) -> Vec<Item> {
    let mut out = Vec::new();
    let mut current = String::new();
    let (mut in_comment, mut depth) = (false, 0i32);
    for line in body.lines() {
        let trimmed = line.trim();
        if current.is_empty() && trimmed.is_empty() {
            continue;
        }
        current.push_str(line);
        current.push('\n');
        if in_comment {
            in_comment = !trimmed.ends_with("*/");
            continue;
        }
        if trimmed.starts_with("/*") && !trimmed.ends_with("*/") {
            in_comment = true;
            continue;
        }
        if trimmed.starts_with("/*") || trimmed.starts_with("//") {
            continue;
        }
        depth += trimmed.matches('{').count() as i32 - trimmed.matches('}').count() as i32;
        let done = depth == 0 && (trimmed.starts_with("#define") || trimmed.ends_with(';'));
        if done {
            let text = std::mem::take(&mut current);
            out.push(Item {
                name: declared_name(&text),
                text,
            });
        }
    }
    assert!(current.trim().is_empty(), "unterminated item: {current}");
    out
}

/// The name an item declares: a macro, a typedef, or a function.
fn declared_name(item: &str) -> String {
    let decl: Vec<&str> = item
        .lines()
        .map(str::trim)
        .filter(|l| {
            !(l.is_empty() || l.starts_with("/*") || l.starts_with('*') || l.starts_with("//"))
        })
        .collect();
    let first = decl.first().expect("a declaration");
    let ident = |s: &str| -> String {
        s.chars()
            .rev()
            .skip_while(|c| !(c.is_alphanumeric() || *c == '_'))
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect::<String>()
            .chars()
            .rev()
            .collect()
    };
    if let Some(rest) = first.strip_prefix("#define ") {
        return rest.split_whitespace().next().unwrap().to_owned();
    }
    let last = decl.last().unwrap();
    if first.starts_with("typedef") {
        if let Some(start) = last.find("(*") {
            // typedef ret (*name)(args);
            let end = last[start..].find(')').unwrap() + start;
            return last[start + 2..end].to_owned();
        }
        // `typedef float name[4][4];` names what comes before its brackets.
        return ident(last.trim_end_matches(';').split('[').next().unwrap());
    }
    // A function: the identifier before its parameter list, after any attribute macro.
    let mut joined = decl.join(" ");
    if let Some(rest) = joined.strip_prefix("TROUPE_DEPRECATED(") {
        let close = rest.find("\")").expect("a closed note") + 2;
        joined = rest[close..].to_owned();
    }
    let open = joined
        .find('(')
        .unwrap_or_else(|| panic!("not a macro, typedef or function: {item}"));
    ident(&joined[..open])
}

/// Which `src/ffi/` file (relative, `/`-separated) defines each C name.
fn definitions() -> BTreeMap<String, String> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let ffi = root().join("src/ffi");
    let mut files = Vec::new();
    walk(&ffi, &mut files);
    let mut map = BTreeMap::new();
    for file in files {
        let relative = file
            .strip_prefix(&ffi)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let text = std::fs::read_to_string(&file).unwrap();
        for line in text.lines() {
            let line = line.trim_start();
            for keyword in ["fn ", "const ", "struct ", "type "] {
                if !line.starts_with("pub") {
                    continue;
                }
                if let Some(at) = line.find(keyword) {
                    let name: String = line[at + keyword.len()..]
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if name.starts_with("troupe_") || name.starts_with("TROUPE_") {
                        map.entry(name).or_insert_with(|| relative.clone());
                    }
                }
            }
        }
    }
    map
}

fn generate() -> String {
    let mut config =
        cbindgen::Config::from_file(root().join("cbindgen.toml")).expect("cbindgen.toml");
    let guide = config
        .header
        .take()
        .expect("cbindgen.toml has the usage guide");
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_config(config)
        .with_src(root().join("src/ffi/mod.rs"))
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut out);
    let body = String::from_utf8(out).unwrap();

    let defined = definitions();
    let mut sections: Vec<Vec<Item>> = SECTIONS.iter().map(|_| Vec::new()).collect();
    for item in items(&body) {
        let file = defined
            .get(&item.name)
            .unwrap_or_else(|| panic!("`{}` is not defined in src/ffi/", item.name));
        let index = SECTIONS
            .iter()
            .position(|(_, _, files)| files.contains(&file.as_str()))
            .unwrap_or_else(|| {
                panic!(
                    "src/ffi/{file} (which defines `{}`) belongs to no section of tests/c_header.rs",
                    item.name
                )
            });
        sections[index].push(item);
    }

    let mut header = String::new();
    header.push_str(guide.trim_start());
    header.push_str(
        "\n#ifndef TROUPE_H\n#define TROUPE_H\n\n#include <stddef.h>\n#include <stdint.h>\n\n",
    );
    header.push_str(&version_macros());
    header.push('\n');
    header.push_str(DEPRECATION_MACRO);
    header.push_str("\n\n#ifdef __cplusplus\nextern \"C\" {\n#endif\n");
    let contents: Vec<String> = SECTIONS
        .iter()
        .enumerate()
        .map(|(i, (title, _, _))| format!(" *   {:>2}. {title}", i + 1))
        .collect();
    header.push_str(&format!(
        "\n/*\n * Sections\n{}\n */\n",
        contents.join("\n")
    ));
    for (i, ((title, about, _), items)) in SECTIONS.iter().zip(&sections).enumerate() {
        assert!(!items.is_empty(), "section `{title}` is empty");
        let rule = "=".repeat(92);
        header.push_str(&format!(
            "\n/* {rule}\n * {}. {title}\n *\n{} * {rule} */\n",
            i + 1,
            wrap(about, 92)
                .iter()
                .map(|l| format!(" * {l}\n"))
                .collect::<String>()
        ));
        for item in items {
            header.push('\n');
            header.push_str(&item.text);
        }
    }
    header.push_str(
        "\n#ifdef __cplusplus\n}  /* extern \"C\" */\n#endif\n\n#endif  /* TROUPE_H */\n",
    );
    header
}

/// `text` in lines of at most `width` characters.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let line = lines.last_mut().unwrap();
        if !line.is_empty() && line.len() + 1 + word.len() > width {
            lines.push(word.to_owned());
        } else {
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
    }
    lines
}

fn committed() -> String {
    std::fs::read_to_string(root().join("include/troupe.h")).unwrap_or_default()
}

#[test]
fn committed_header_is_up_to_date() {
    let fresh = generate();
    if std::env::var_os("TROUPE_BLESS").is_some() {
        std::fs::write(root().join("include/troupe.h"), &fresh).unwrap();
        return;
    }
    assert!(
        committed() == fresh,
        "include/troupe.h is out of date with src/ffi/; run `TROUPE_BLESS=1 cargo test --test c_header` and commit it"
    );
}

/// Every name the header declares at file scope: macros, typedefs, struct tags, functions.
fn file_scope_names(header: &str) -> Vec<String> {
    let start = header.find("#ifndef TROUPE_H").expect("include guard");
    let mut names = Vec::new();
    for item in items(&strip_preprocessor_conditionals(&header[start..])) {
        names.push(item.name.clone());
        // Struct tags (`typedef struct tag {`), which C++ also puts at namespace scope.
        for line in item.text.lines() {
            let line = line.trim();
            if let Some(rest) = line
                .strip_prefix("typedef struct ")
                .or_else(|| line.strip_prefix("struct "))
            {
                let tag: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !tag.is_empty() && !line.contains('(') {
                    names.push(tag);
                }
            }
        }
    }
    for line in header.lines() {
        if let Some(rest) = line.trim().strip_prefix("#define ") {
            names.push(
                rest.split(|c: char| c.is_whitespace() || c == '(')
                    .next()
                    .unwrap()
                    .to_owned(),
            );
        }
    }
    names.sort();
    names.dedup();
    names
}

/// The header without `#if`/`#ifdef`/`#else`/`#endif`/`#include` lines and `extern "C"` braces,
/// so that [`items`] sees only declarations and `#define`s.
fn strip_preprocessor_conditionals(text: &str) -> String {
    text.lines()
        .filter(|l| {
            let t = l.trim();
            !(t.starts_with("#if")
                || t.starts_with("#el")
                || t.starts_with("#endif")
                || t.starts_with("#include")
                || t.starts_with("extern \"C\"")
                || t.starts_with("}  /* extern"))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn header_declares_only_prefixed_names() {
    let header = committed();
    let names = file_scope_names(&header);
    assert!(
        names.len() > 150,
        "the scan found only {} names; is the header parsed?",
        names.len()
    );
    let foreign: Vec<&String> = names
        .iter()
        .filter(|n| !(n.starts_with("troupe_") || n.starts_with("TROUPE_")))
        .collect();
    assert!(
        foreign.is_empty(),
        "include/troupe.h declares names without the troupe_/TROUPE_ prefix: {foreign:?}"
    );
}

#[test]
fn prefix_check_catches_a_foreign_name() {
    // The check above must be able to fail: a header with an unprefixed macro, type and
    // function is caught on each.
    let header = "#ifndef TROUPE_H\n#define TROUPE_H\n#define IDENTITY 1\n\
                  typedef struct Quat Quat;\ntypedef float Mat4[4][4];\nint helper(void);\n\
                  #endif\n";
    let names = file_scope_names(header);
    for name in ["IDENTITY", "Quat", "Mat4", "helper"] {
        assert!(
            names.iter().any(|n| n == name),
            "{name} not found in {names:?}"
        );
    }
}

#[test]
fn header_sections_come_in_order_with_the_guide_first() {
    let header = committed();
    let guide = header.find(" * Usage").expect("the usage guide");
    let mut at = guide;
    for (i, (title, _, _)) in SECTIONS.iter().enumerate() {
        let banner = format!(" * {}. {title}\n", i + 1);
        let found = header[at..]
            .find(&banner)
            .unwrap_or_else(|| panic!("section `{title}` missing or out of order"));
        at += found;
    }
    // Every family of the guide is named there with what it offers.
    for family in ["armflow", "umf", "magnet", "arflow"] {
        assert!(
            header[guide..guide + 4000].contains(&format!(" {family} ")),
            "the guide does not name the `{family}` family"
        );
    }
}
