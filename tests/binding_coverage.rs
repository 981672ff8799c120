//! Which header functions each binding binds: Python's raw layer (`bindings/python/troupe/_native.py`,
//! its signature table), C++'s `bindings/cpp/troupe.hpp` (the calls it makes) and C#'s
//! `bindings/csharp/Troupe.cs` (its `extern` declarations). A current (not deprecated) function
//! a binding lacks must be listed in `bindings/unbound.txt`, and a listed one must really be
//! missing, so the list is the bindings' debt, exact, and a new C function cannot land unbound
//! without saying so. Deprecated names are never bound.

use std::collections::BTreeSet;
use std::path::Path;

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap()
}

/// The header's functions: (current, deprecated). cbindgen writes each declaration on one line.
fn header_functions() -> (BTreeSet<String>, BTreeSet<String>) {
    let name = regex::Regex::new(r"\b(troupe_[a-z0-9_]+)\(").unwrap();
    let (mut current, mut deprecated) = (BTreeSet::new(), BTreeSet::new());
    for line in read("include/troupe.h").lines().map(str::trim) {
        if line.starts_with(['*', '/', '#']) || !line.ends_with(");") {
            continue;
        }
        if let Some(m) = name.captures(line) {
            let set = if line.starts_with("TROUPE_DEPRECATED") {
                &mut deprecated
            } else {
                &mut current
            };
            set.insert(m[1].to_string());
        }
    }
    (current, deprecated)
}

fn bound(path: &str, pattern: &str) -> BTreeSet<String> {
    let re = regex::Regex::new(pattern).unwrap();
    re.captures_iter(&read(path))
        .map(|c| c[1].to_string())
        .collect()
}

#[test]
fn every_header_function_is_bound_or_listed_as_unbound() {
    let (current, deprecated) = header_functions();
    assert!(current.len() > 100 && !deprecated.is_empty());
    let bindings = [
        (
            "python",
            bound(
                "bindings/python/troupe/_native.py",
                r#""(troupe_[a-z0-9_]+)":"#,
            ),
        ),
        (
            "cpp",
            bound("bindings/cpp/troupe.hpp", r"\b(troupe_[a-z0-9_]+)\s*\("),
        ),
        (
            "csharp",
            bound(
                "bindings/csharp/Troupe.cs",
                r"extern [^;(]*\b(troupe_[a-z0-9_]+)\s*\(",
            ),
        ),
    ];
    let ledger = read("bindings/unbound.txt");
    let mut problems = Vec::new();
    for (language, bound) in &bindings {
        let listed: BTreeSet<String> = ledger
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .filter_map(|l| {
                let mut parts = l.splitn(3, ' ');
                let (lang, function) = (parts.next()?, parts.next()?);
                let reason = parts.next().unwrap_or("").trim();
                assert!(
                    !reason.is_empty(),
                    "bindings/unbound.txt: no reason in `{l}`"
                );
                (lang == *language).then(|| function.to_string())
            })
            .collect();
        let missing: BTreeSet<String> = current.difference(bound).cloned().collect();
        for f in missing.difference(&listed) {
            problems.push(format!(
                "{language} does not bind {f}, and bindings/unbound.txt does not say so"
            ));
        }
        for f in listed.difference(&missing) {
            problems.push(format!(
                "bindings/unbound.txt lists {language} {f}, which is bound (or not a current function)"
            ));
        }
        for f in deprecated.intersection(bound) {
            problems.push(format!("{language} binds the deprecated name {f}"));
        }
        println!(
            "{language}: {} of {} current header functions bound ({} deprecated names not bound)",
            current.len() - missing.len(),
            current.len(),
            deprecated.len()
        );
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
