//! Which header functions each binding binds, and with which signature: Python's raw layer
//! (`bindings/python/troupe/_native.py`, its signature table), C++'s `bindings/cpp/troupe.hpp`
//! (the calls it makes) and C#'s `bindings/csharp/Troupe.cs` (its `extern` declarations). A
//! current (not deprecated) function a binding lacks must be listed in `bindings/unbound.txt`,
//! and a listed one must really be missing, so the list is the bindings' debt, exact, and a new
//! C function cannot land unbound without saying so. Deprecated names are never bound.
//!
//! The hand-written declarations of Python and C# are also checked against the header's
//! prototypes, parameter by parameter, by ABI class (pointer, 8/16/32/64-bit integer, size_t,
//! float, double, void): a parameter added, dropped or of another width, or a wrong return
//! type, would otherwise pass every call through the wrong registers and corrupt memory
//! silently. C++ compiles against the header, so its compiler checks it.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::Path;

use regex::Regex;

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap()
}

/// A function's signature, as the header or a binding writes it: each type with its ABI class
/// (or why it has none).
struct Signature {
    name: String,
    deprecated: bool,
    ret: Typed,
    params: Vec<Typed>,
}

/// A return or parameter type: its text (with the parameter's name, for messages) and class.
struct Typed {
    text: String,
    abi: Result<Abi, String>,
}

/// How a value crosses the C ABI: what must agree between the header and a binding. Signedness
/// is not an ABI difference; width is.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Abi {
    Void,
    Int8,
    Int16,
    Int32,
    Int64,
    Usize,
    F32,
    F64,
    Pointer,
    /// C#'s `IntPtr`/`UIntPtr` by value: pointer-sized, so right for a pointer or a `size_t`.
    PointerSized,
}

impl Abi {
    /// Whether a binding's declared class passes what the header declares as `c`.
    fn passes(self, c: Abi) -> bool {
        self == c || (self == Abi::PointerSized && matches!(c, Abi::Pointer | Abi::Usize))
    }
}

impl fmt::Display for Abi {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(match self {
            Abi::Void => "void",
            Abi::Int8 => "8-bit integer",
            Abi::Int16 => "16-bit integer",
            Abi::Int32 => "32-bit integer",
            Abi::Int64 => "64-bit integer",
            Abi::Usize => "size_t",
            Abi::F32 => "float",
            Abi::F64 => "double",
            Abi::Pointer => "pointer",
            Abi::PointerSized => "pointer-sized integer",
        })
    }
}

impl fmt::Display for Typed {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match &self.abi {
            Ok(abi) => write!(f, "`{}` ({abi})", self.text),
            Err(_) => write!(f, "`{}` (unclassified)", self.text),
        }
    }
}

/// Splits a parameter list at its top-level commas (C# attributes and Python calls nest some).
fn split_top_level(list: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut start) = (Vec::new(), 0i32, 0);
    for (i, c) in list.char_indices() {
        match c {
            '(' | '[' | '{' | '<' => depth += 1,
            ')' | ']' | '}' | '>' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(list[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    let last = list[start..].trim();
    if !last.is_empty() {
        parts.push(last);
    }
    parts
}

// ---- the header ----

/// The header's prototypes, deprecated ones included. cbindgen writes each declaration on one
/// line, a deprecated one behind `TROUPE_DEPRECATED("...")`.
fn header_prototypes() -> Vec<Signature> {
    let header = read("include/troupe.h");
    let typedefs = header_typedefs(&header);
    let decl =
        Regex::new(r#"^(TROUPE_DEPRECATED\("[^"]*"\)\s+)?(.*?)\b(troupe_[a-z0-9_]+)\((.*)\);$"#)
            .unwrap();
    let typed = |ty: &str, text: &str| Typed {
        text: text.to_string(),
        abi: c_class(ty, &typedefs),
    };
    let mut prototypes = Vec::new();
    for line in header.lines().map(str::trim) {
        if line.starts_with(['*', '/', '#']) || line.starts_with("typedef") {
            continue;
        }
        let Some(m) = decl.captures(line) else {
            continue;
        };
        let list = m[4].trim();
        let params = if list == "void" {
            Vec::new()
        } else {
            split_top_level(list)
                .into_iter()
                .map(|p| typed(c_param_type(p), p))
                .collect()
        };
        prototypes.push(Signature {
            name: m[3].to_string(),
            deprecated: m.get(1).is_some(),
            ret: typed(m[2].trim(), m[2].trim()),
            params,
        });
    }
    prototypes
}

/// The header's functions: (current, deprecated).
fn header_functions() -> (BTreeSet<String>, BTreeSet<String>) {
    let (mut current, mut deprecated) = (BTreeSet::new(), BTreeSet::new());
    for p in header_prototypes() {
        let set = if p.deprecated {
            &mut deprecated
        } else {
            &mut current
        };
        set.insert(p.name);
    }
    (current, deprecated)
}

/// A C parameter's type: the declaration less its name (cbindgen names every parameter).
fn c_param_type(param: &str) -> &str {
    let name_start = param
        .trim_end()
        .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .map_or(0, |i| i + 1);
    param[..name_start].trim()
}

/// The header's own type names: callback typedefs are pointers, scalar ones take their
/// underlying type's class (`troupe_status` is an `int32_t`).
fn header_typedefs(header: &str) -> BTreeMap<String, Abi> {
    let callback = Regex::new(r"^typedef .*\(\*(\w+)\)\(").unwrap();
    let scalar = Regex::new(r"^typedef (\w+) (\w+);$").unwrap();
    let mut typedefs = BTreeMap::new();
    for line in header.lines().map(str::trim) {
        if let Some(m) = callback.captures(line) {
            typedefs.insert(m[1].to_string(), Abi::Pointer);
        } else if let Some(m) = scalar.captures(line) {
            if let Ok(abi) = c_class(&m[1], &BTreeMap::new()) {
                typedefs.insert(m[2].to_string(), abi);
            }
        }
    }
    typedefs
}

/// The ABI class of a C type (no parameter name).
fn c_class(ty: &str, typedefs: &BTreeMap<String, Abi>) -> Result<Abi, String> {
    if ty.contains('*') {
        return Ok(Abi::Pointer);
    }
    let ty = ty
        .split_whitespace()
        .filter(|w| *w != "const")
        .collect::<Vec<_>>()
        .join(" ");
    Ok(match ty.as_str() {
        "void" => Abi::Void,
        "bool" | "char" | "int8_t" | "uint8_t" => Abi::Int8,
        "int16_t" | "uint16_t" => Abi::Int16,
        "int32_t" | "uint32_t" => Abi::Int32,
        "int64_t" | "uint64_t" => Abi::Int64,
        "size_t" | "uintptr_t" | "intptr_t" | "ptrdiff_t" => Abi::Usize,
        "float" => Abi::F32,
        "double" => Abi::F64,
        t if t.starts_with("enum ") => Abi::Int32,
        t => match typedefs.get(t) {
            Some(abi) => *abi,
            None => {
                return Err(format!(
                    "C type `{t}` has no ABI class here (a struct by value?): \
                     teach tests/binding_coverage.rs its class"
                ))
            }
        },
    })
}

fn bound(path: &str, pattern: &str) -> BTreeSet<String> {
    let re = Regex::new(pattern).unwrap();
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

// ---- the comparison ----

/// Where each binding's declaration disagrees with the header's prototype: the function, the
/// parameter (1-based) or return, and both types with their classes.
fn signature_mismatches(
    language: &str,
    header: &BTreeMap<&str, &Signature>,
    bound: &[Signature],
) -> Vec<String> {
    let mut problems = Vec::new();
    for b in bound {
        let Some(c) = header.get(b.name.as_str()) else {
            problems.push(format!(
                "{language} declares {}, which include/troupe.h does not",
                b.name
            ));
            continue;
        };
        let name = &b.name;
        let mut pairs = vec![("return type".to_string(), &c.ret, &b.ret)];
        if c.params.len() == b.params.len() {
            let params = c.params.iter().zip(&b.params).enumerate();
            pairs.extend(params.map(|(i, (c, b))| (format!("parameter {}", i + 1), c, b)));
        } else {
            // Parameters compared pairwise past a dropped one would all look shifted: show both lists.
            let list = |s: &Signature| {
                s.params
                    .iter()
                    .map(|p| p.text.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            problems.push(format!(
                "{language} {name}: {} parameters in include/troupe.h ({}), {} in the binding ({})",
                c.params.len(),
                list(c),
                b.params.len(),
                list(b)
            ));
        }
        for (what, c, b) in pairs {
            match (&c.abi, &b.abi) {
                (Ok(ca), Ok(ba)) if ba.passes(*ca) => {}
                (Ok(_), Ok(_)) => problems.push(format!(
                    "{language} {name}: {what} is {c} in include/troupe.h, {b} in the binding"
                )),
                (Err(e), _) | (_, Err(e)) => {
                    problems.push(format!("{language} {name}: {what}: {e}"))
                }
            }
        }
    }
    problems
}

#[test]
fn every_binding_declaration_matches_the_header_prototype() {
    let prototypes = header_prototypes();
    let header: BTreeMap<&str, &Signature> =
        prototypes.iter().map(|p| (p.name.as_str(), p)).collect();
    let mut problems = Vec::new();
    for (language, (bound, form)) in [
        ("python", python_signatures()),
        ("csharp", csharp_signatures()),
    ] {
        let names: BTreeSet<&str> = bound.iter().map(|s| s.name.as_str()).collect();
        assert!(
            names.len() > 100,
            "{language}: only {} declarations read",
            names.len()
        );
        problems.extend(form);
        problems.extend(signature_mismatches(language, &header, &bound));
        println!(
            "{language}: {} declarations of {} functions compared with include/troupe.h",
            bound.len(),
            names.len()
        );
    }
    assert!(
        problems.is_empty(),
        "{} signature problems:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

// ---- C# ----

/// C#'s `[DllImport]` declarations, and what is wrong with their form (library, calling
/// convention, a declaration this reader cannot read).
fn csharp_signatures() -> (Vec<Signature>, Vec<String>) {
    let source = read("bindings/csharp/Troupe.cs");
    // Marshalled as the native pointer they wrap or point to.
    let by_pointer: BTreeSet<String> =
        Regex::new(r"class (\w+)\s*:\s*SafeHandle\w*\b|delegate \S+ (\w+)\s*\(")
            .unwrap()
            .captures_iter(&source)
            .map(|c| c.get(1).or(c.get(2)).unwrap().as_str().to_string())
            .collect();
    let import = Regex::new(
        r"(?s)\[DllImport\(([^)]*)\)\]((?:\s*\[[^\]]*\])*)\s*(?:\w+\s+)*?extern\s+(\S+)\s+(\w+)\s*\((.*?)\)\s*;",
    )
    .unwrap();
    let (mut signatures, mut problems, mut libraries) = (Vec::new(), Vec::new(), BTreeSet::new());
    for m in import.captures_iter(&source) {
        let name = m[4].to_string();
        let args: Vec<String> = split_top_level(&m[1])
            .into_iter()
            .map(|a| a.split_whitespace().collect())
            .collect();
        libraries.insert(args.first().cloned().unwrap_or_default());
        if !args
            .iter()
            .any(|a| a == "CallingConvention=CallingConvention.Cdecl")
        {
            problems.push(format!(
                "csharp {name}: not CallingConvention.Cdecl, the header's convention"
            ));
        }
        if args.iter().any(|a| a.starts_with("EntryPoint=")) {
            problems.push(format!(
                "csharp {name}: an EntryPoint is not checked here; name the method as the C function"
            ));
        }
        // `[return: MarshalAs(...)]` travels with the return type.
        let ret = format!("{} {}", m[2].trim(), &m[3]);
        signatures.push(Signature {
            name,
            deprecated: false,
            ret: csharp_typed(ret.trim(), false, &by_pointer),
            params: split_top_level(&m[5])
                .into_iter()
                .map(|p| csharp_typed(p, true, &by_pointer))
                .collect(),
        });
    }
    let externs = Regex::new(r"\bstatic\s+extern\b")
        .unwrap()
        .find_iter(&source)
        .count();
    if externs != signatures.len() {
        problems.push(format!(
            "csharp: {externs} `static extern` declarations, {} of them in the form this test reads, \
             `[DllImport(...)] ... static extern T name(...);`",
            signatures.len()
        ));
    }
    if libraries.len() != 1 {
        problems.push(format!(
            "csharp: imports from more than one library: {libraries:?}"
        ));
    }
    (signatures, problems)
}

/// A C# return or parameter type (`[In] float[] actor`, `out UIntPtr written`,
/// `[MarshalAs(UnmanagedType.U1)] bool flag`) with its ABI class.
fn csharp_typed(text: &str, named: bool, by_pointer: &BTreeSet<String>) -> Typed {
    let mut rest = text.trim();
    let mut attributes = String::new();
    while let Some(end) = rest.strip_prefix('[').and_then(|r| r.find(']')) {
        attributes.push_str(&rest[..end + 2]);
        rest = rest[end + 2..].trim_start();
    }
    let mut words: Vec<&str> = rest.split_whitespace().collect();
    if named {
        words.pop();
    }
    let one_byte = ["UnmanagedType.U1", "UnmanagedType.I1"]
        .iter()
        .any(|u| attributes.contains(u));
    let abi = match words.as_slice() {
        ["out" | "ref" | "in", _] => Ok(Abi::Pointer),
        [ty] if ty.ends_with("[]") || by_pointer.contains(*ty) => Ok(Abi::Pointer),
        ["string" | "StringBuilder"] => Ok(Abi::Pointer),
        ["IntPtr" | "UIntPtr" | "nint" | "nuint"] => Ok(Abi::PointerSized),
        ["void"] => Ok(Abi::Void),
        ["byte" | "sbyte"] => Ok(Abi::Int8),
        // A bare bool marshals as a 4-byte Win32 BOOL.
        ["bool"] if one_byte => Ok(Abi::Int8),
        ["bool" | "int" | "uint"] => Ok(Abi::Int32),
        ["short" | "ushort"] => Ok(Abi::Int16),
        ["long" | "ulong"] => Ok(Abi::Int64),
        ["float"] => Ok(Abi::F32),
        ["double"] => Ok(Abi::F64),
        _ => Err(format!(
            "C# type `{}` has no ABI class here (a struct by value? `char`?): pass it by `ref`, \
             or teach tests/binding_coverage.rs its class",
            words.join(" ")
        )),
    };
    Typed {
        text: text.to_string(),
        abi,
    }
}

// ---- Python ----

/// Python's `PROTOTYPES` table (`name: (restype, [argtypes])`) and the module's aliases
/// (`status = ctypes.c_int32`), read from the source by Python's own parser (`ast`), each type
/// as its source text. Reading rather than importing keeps `c_size_t` apart from `c_uint64`,
/// which ctypes makes one type on 64-bit Linux but which differ elsewhere.
fn python_signatures() -> (Vec<Signature>, Vec<String>) {
    const READ_TABLE: &str = r#"
import ast, json, sys
tree = ast.parse(open(sys.argv[1]).read())
aliases, table, calls = {}, None, set()
for node in ast.walk(tree):
    if isinstance(node, ast.Call):
        calls.add(ast.unparse(node.func))
for node in tree.body:
    if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
        aliases[node.targets[0].id] = ast.unparse(node.value)
    elif isinstance(node, ast.AnnAssign) and ast.unparse(node.target) == "PROTOTYPES":
        table = node.value
entries = []
for key, value in zip(table.keys, table.values):
    if (isinstance(key, ast.Constant) and isinstance(value, ast.Tuple) and len(value.elts) == 2
            and isinstance(value.elts[1], ast.List)):
        entries.append([key.value, ast.unparse(value.elts[0]), [ast.unparse(a) for a in value.elts[1].elts]])
    else:
        entries.append(ast.unparse(key) + ": " + ast.unparse(value))
print(json.dumps({"aliases": aliases, "entries": entries, "calls": sorted(calls)}))
"#;
    let out = std::process::Command::new("python3")
        .arg("-c")
        .arg(READ_TABLE)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("bindings/python/troupe/_native.py"))
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "reading _native.py's PROTOTYPES with Python's ast: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let aliases: BTreeMap<String, String> =
        serde_json::from_value(read["aliases"].clone()).unwrap();
    let calls: Vec<String> = serde_json::from_value(read["calls"].clone()).unwrap();
    let mut problems = Vec::new();
    if !calls.iter().any(|c| c == "ctypes.CDLL")
        || calls
            .iter()
            .any(|c| c.ends_with("WinDLL") || c.ends_with("OleDLL"))
    {
        problems.push("python: the library must be opened with ctypes.CDLL (cdecl)".to_string());
    }
    let typed = |e: &str| Typed {
        text: e.to_string(),
        abi: python_class(e, &aliases),
    };
    let mut signatures = Vec::new();
    for entry in read["entries"]
        .as_array()
        .expect("_native.py has a PROTOTYPES table")
    {
        match entry {
            serde_json::Value::Array(e) => signatures.push(Signature {
                name: e[0].as_str().unwrap().to_string(),
                deprecated: false,
                ret: typed(e[1].as_str().unwrap()),
                params: e[2]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|a| typed(a.as_str().unwrap()))
                    .collect(),
            }),
            other => problems.push(format!(
                "python: PROTOTYPES entry `{other}` is not `\"name\": (restype, [argtypes])`"
            )),
        }
    }
    (signatures, problems)
}

/// The ABI class of a ctypes type expression, as Python's `ast.unparse` writes it.
fn python_class(e: &str, aliases: &BTreeMap<String, String>) -> Result<Abi, String> {
    let unknown = || {
        Err(format!(
            "ctypes type `{e}` has no ABI class here: teach tests/binding_coverage.rs its class"
        ))
    };
    let name = e.strip_prefix("ctypes.").unwrap_or(e);
    Ok(match name {
        "None" => Abi::Void,
        "c_bool" | "c_char" | "c_byte" | "c_ubyte" | "c_int8" | "c_uint8" => Abi::Int8,
        "c_short" | "c_ushort" | "c_int16" | "c_uint16" => Abi::Int16,
        "c_int" | "c_uint" | "c_int32" | "c_uint32" => Abi::Int32,
        "c_longlong" | "c_ulonglong" | "c_int64" | "c_uint64" => Abi::Int64,
        "c_size_t" | "c_ssize_t" => Abi::Usize,
        "c_float" => Abi::F32,
        "c_double" => Abi::F64,
        "c_void_p" | "c_char_p" | "c_wchar_p" => Abi::Pointer,
        "c_long" | "c_ulong" => {
            return Err(format!(
                "`{e}` is 32 bits on Windows, 64 elsewhere: use a fixed-width type"
            ))
        }
        // CFUNCTYPE, not WINFUNCTYPE: the header's callbacks are cdecl.
        _ if name.starts_with("POINTER(") || name.starts_with("CFUNCTYPE(") => Abi::Pointer,
        _ if name.contains("WINFUNCTYPE(") => {
            return Err(format!(
                "`{e}` makes a stdcall callback; the header's are cdecl: use ctypes.CFUNCTYPE"
            ))
        }
        _ => match aliases.get(e) {
            Some(aliased) => return python_class(aliased, aliases),
            None => return unknown(),
        },
    })
}
