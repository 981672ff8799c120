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
//!
//! The structs Python and C# declare themselves are checked against the C compiler's layout
//! of the header's (size, and every field's offset and width; `struct layouts` below).

mod common;

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

// ---- struct layouts ----
//
// A struct a binding declares itself (Python's ctypes classes, C#'s `[StructLayout]` structs)
// is laid out by that language's rules, not by the C compiler's: a field in the wrong place or
// of the wrong width would pass every call a corrupted struct without any error. So each mirror
// is compared with the C compiler's layout of the header's struct, field by field, from the
// real `cc`, `ctypes` and Mono. C++ includes the header, so its compiler lays out the C structs.

/// A struct's layout: its size and its leaf fields (nested structs flattened, an array one
/// field), each as (name, offset, size) in bytes, by offset.
#[derive(Debug, Default)]
struct Layout {
    size: usize,
    fields: Vec<(String, usize, usize)>,
}

/// Layouts from `S <struct> <size>` and `F <struct> <field> <offset> <size>` lines; others are
/// left alone.
fn parse_layouts(text: &str) -> BTreeMap<String, Layout> {
    let mut layouts: BTreeMap<String, Layout> = BTreeMap::new();
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let number = |i: usize| -> usize { words[i].parse().expect(line) };
        match words.as_slice() {
            ["S", name, _] => layouts.entry(name.to_string()).or_default().size = number(2),
            ["F", name, field, _, _] => layouts.entry(name.to_string()).or_default().fields.push((
                field.to_string(),
                number(3),
                number(4),
            )),
            _ => {}
        }
    }
    for layout in layouts.values_mut() {
        layout.fields.sort_by_key(|f| f.1);
    }
    layouts
}

/// The header's struct definitions: each struct's members as (type, name), arrays by name.
fn header_structs() -> BTreeMap<String, Vec<(String, String)>> {
    let header = read("include/troupe.h");
    let comments = Regex::new(r"(?s)/\*.*?\*/|//[^\n]*").unwrap();
    let header = comments.replace_all(&header, "");
    let definition = Regex::new(r"(?s)typedef struct (\w+) \{(.*?)\} (\w+);").unwrap();
    let member = Regex::new(r"^(.*?)(\w+)\s*(\[[^\]]*\])?$").unwrap();
    let mut structs = BTreeMap::new();
    for c in definition.captures_iter(&header) {
        assert_eq!(c[1], c[3], "typedef name");
        let members = c[2]
            .split(';')
            .map(|m| m.split_whitespace().collect::<Vec<_>>().join(" "))
            .filter(|m| !m.is_empty())
            .map(|m| {
                let parts = member
                    .captures(&m)
                    .unwrap_or_else(|| panic!("member `{m}`"));
                (parts[1].trim().to_owned(), parts[2].to_owned())
            })
            .collect();
        structs.insert(c[1].to_owned(), members);
    }
    assert!(
        structs.len() >= 10,
        "{} structs in the header",
        structs.len()
    );
    structs
}

/// The C compiler's layout of every struct of the header, compiled and run once per test
/// binary (both languages' tests compare with it).
fn c_layouts() -> &'static BTreeMap<String, Layout> {
    static LAYOUTS: std::sync::OnceLock<BTreeMap<String, Layout>> = std::sync::OnceLock::new();
    LAYOUTS.get_or_init(compile_c_layouts)
}

/// A program that includes the header prints each struct's size and every leaf's `offsetof`
/// and `sizeof`.
fn compile_c_layouts() -> BTreeMap<String, Layout> {
    fn leaves(
        structs: &BTreeMap<String, Vec<(String, String)>>,
        name: &str,
        path: &str,
        out: &mut Vec<(String, String)>,
    ) {
        for (ty, field) in &structs[name] {
            let path = format!("{path}{field}");
            let nested = ty.trim_start_matches("struct ").trim();
            if !ty.contains('*') && structs.contains_key(nested) {
                leaves(structs, nested, &format!("{path}."), out);
            } else {
                out.push((field.clone(), path));
            }
        }
    }
    let structs = header_structs();
    let mut program = String::from(
        "#include <stddef.h>\n#include <stdio.h>\n#include \"troupe.h\"\nint main(void) {\n",
    );
    for name in structs.keys() {
        program += &format!("    printf(\"S {name} %zu\\n\", sizeof({name}));\n");
        let mut fields = Vec::new();
        leaves(&structs, name, "", &mut fields);
        for (field, path) in fields {
            program += &format!(
                "    printf(\"F {name} {field} %zu %zu\\n\", offsetof({name}, {path}), \
                 sizeof((({name} *)0)->{path}));\n"
            );
        }
    }
    program += "    return 0;\n}\n";
    let scratch = tempfile::tempdir().unwrap();
    let source = scratch.path().join("layouts.c");
    let exe = scratch.path().join("layouts");
    std::fs::write(&source, program).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    common::run_ok(
        std::process::Command::new("cc")
            .args(["-std=c11", "-Wall", "-Werror", "-I"])
            .arg(root.join("include"))
            .arg("-o")
            .arg(&exe)
            .arg(&source),
    );
    let out = common::run_ok(&mut std::process::Command::new(&exe));
    let layouts = parse_layouts(&common::output_text(&out));
    assert_eq!(layouts.len(), structs.len(), "every header struct laid out");
    layouts
}

/// Letters and digits, lower case: `origin_x` and C#'s `OriginX` name one field.
fn plain(name: &str) -> String {
    name.chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// Where `mirror` (a binding's struct) is not laid out as `c` (the header's): sizes differ, or
/// a C field is not covered exactly, from its first byte to its last, by binding fields whose
/// names begin with its name (an array may be mirrored by one field per element, as C#'s
/// `Placement` mirrors `heading[4]` with `HeadingW`..`HeadingZ`), or a binding field lies
/// outside every C field.
fn layout_mismatches(what: &str, mirror: &Layout, c: &Layout) -> Vec<String> {
    let mut problems = Vec::new();
    if mirror.size != c.size {
        problems.push(format!(
            "{what}: {} bytes, the header's {}",
            mirror.size, c.size
        ));
    }
    let mut used = vec![false; mirror.fields.len()];
    for (name, offset, size) in &c.fields {
        let mut end = *offset;
        for (i, (field, at, bytes)) in mirror.fields.iter().enumerate() {
            if *at < *offset || *at >= offset + size {
                continue;
            }
            used[i] = true;
            if *at != end || !plain(field).starts_with(&plain(name)) {
                end = usize::MAX;
                break;
            }
            end += bytes;
        }
        if end != offset + size {
            let found: Vec<String> = mirror
                .fields
                .iter()
                .filter(|(_, at, _)| *at >= *offset && *at < offset + size)
                .map(|(f, at, b)| format!("{f} at {at} ({b} bytes)"))
                .collect();
            problems.push(format!(
                "{what}: the header's `{name}` is {size} bytes at {offset}; the binding has {}",
                if found.is_empty() {
                    "nothing there".to_owned()
                } else {
                    found.join(", ")
                }
            ));
        }
    }
    for ((field, at, bytes), used) in mirror.fields.iter().zip(used) {
        if !used {
            problems.push(format!(
                "{what}: `{field}` ({bytes} bytes at {at}) lies outside every field of the header's"
            ));
        }
    }
    problems
}

/// Compares each (binding struct, C struct) pair; panics with every mismatch, and prints which
/// header structs the binding mirrors.
fn check_mirrors(
    language: &str,
    mirrors: &BTreeMap<String, String>,
    layouts: &BTreeMap<String, Layout>,
) {
    let c = c_layouts();
    let mut problems = Vec::new();
    for (binding, header) in mirrors {
        let what = format!("{language} `{binding}` (mirror of `{header}`)");
        match (layouts.get(binding), c.get(header)) {
            (Some(mirror), Some(c)) => problems.extend(layout_mismatches(&what, mirror, c)),
            (None, _) => problems.push(format!("{what}: no layout was printed for it")),
            (_, None) => problems.push(format!("{what}: the header has no such struct")),
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    let mirrored: BTreeSet<&String> = mirrors.values().collect();
    let unmirrored: Vec<&String> = c.keys().filter(|k| !mirrored.contains(k)).collect();
    println!(
        "{language}: {} of the header's {} structs mirrored, each laid out as the C compiler \
         lays it out; not mirrored: {unmirrored:?}",
        mirrored.len(),
        c.len()
    );
}

#[test]
fn python_structs_have_the_header_layouts() {
    let (ok, out) = common::run_python(
        &[
            "tests/python/struct_layouts.py",
            "bindings/python/troupe/_native.py",
        ],
        &[],
    );
    assert!(ok, "{out}");
    let mut mirrors = BTreeMap::new();
    for line in out.lines() {
        if let ["M", class, header] = line.split_whitespace().collect::<Vec<_>>().as_slice() {
            assert_ne!(
                *header, "?",
                "Python's `{class}` is a ctypes struct whose docstring names no header struct \
                 (\"Mirror of `troupe_...`\")"
            );
            mirrors.insert(class.to_string(), header.to_string());
        }
    }
    assert!(mirrors.len() >= 10, "{out}");
    check_mirrors("Python", &mirrors, &parse_layouts(&out));
}

#[test]
fn csharp_structs_have_the_header_layouts() {
    let test = "csharp_structs_have_the_header_layouts";
    if !common::tools_or_skip(test, &["mcs", "mono"], "mono-mcs mono-runtime") {
        return;
    }
    // Each struct whose doc comment says "Mirror of <c>troupe_...</c>".
    let source = read("bindings/csharp/Troupe.cs");
    let declaration = Regex::new(r"^\s*(?:public|internal) struct (\w+)").unwrap();
    let named = Regex::new(r"[Mm]irror of\s+(?:///\s*)?<c>(troupe_\w+)</c>").unwrap();
    let mut mirrors = BTreeMap::new();
    let mut doc = String::new();
    for line in source.lines() {
        let text = line.trim_start();
        if text.starts_with("///") {
            doc += text;
            doc.push(' ');
        } else if let Some(c) = declaration.captures(line) {
            if let Some(header) = named.captures(&doc) {
                mirrors.insert(c[1].to_owned(), header[1].to_owned());
            }
            doc.clear();
        } else if !text.starts_with('[') {
            doc.clear();
        }
    }
    assert!(mirrors.len() >= 10, "{mirrors:?}");

    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scratch = tempfile::tempdir().unwrap();
    let exe = scratch.path().join("layouts.exe");
    common::run_ok(
        std::process::Command::new("mcs")
            .arg("-warnaserror")
            .arg(format!("-out:{}", exe.display()))
            .arg(root.join("bindings/csharp/Troupe.cs"))
            .arg(root.join("bindings/csharp/tests/Layouts.cs")),
    );
    let out = common::output_text(&common::run_ok(
        std::process::Command::new("mono")
            .arg(&exe)
            .args(mirrors.keys()),
    ));
    // Every struct a P/Invoke declaration passes must be one compared here.
    for line in out.lines() {
        if let ["P", name] = line.split_whitespace().collect::<Vec<_>>().as_slice() {
            assert!(
                mirrors.contains_key(*name),
                "C#'s `{name}` crosses to C in a [DllImport] declaration but its doc comment \
                 names no header struct (\"Mirror of <c>troupe_...</c>\")"
            );
        }
    }
    check_mirrors("C#", &mirrors, &parse_layouts(&out));
}
