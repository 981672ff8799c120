//! troupe installed as a C/C++ package (`scripts/install.sh`) and used the ways an engine's
//! build would: the layout of the prefix, the shared library's SONAME and stack, a pkg-config
//! consumer (shared and static) and the CMake consumer project `examples/cmake/`
//! (`find_package(troupe 0.2)`, shared and static), each built against a fresh prefix and run
//! on the installed demo model. Every consumer streams the same clip: their outputs must be
//! identical.
//!
//! The installer installs the libraries `common::c_libraries` builds (`--no-build --profile
//! dev`, the testing feature on) rather than building its own, so that the suite compiles
//! troupe once; it installs a release build the same way. `cmake` is installed by
//! `scripts/test.sh`; without it the CMake half fails under CI and is a counted skip elsewhere.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::run_ok as run;
use std::sync::OnceLock;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A scratch directory shared by the tests of this binary.
fn scratch() -> &'static Path {
    common::process_scratch()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A fresh prefix with troupe installed in it, once per test binary.
fn prefix() -> &'static Path {
    static PREFIX: OnceLock<PathBuf> = OnceLock::new();
    PREFIX.get_or_init(|| {
        common::c_libraries();
        let prefix = scratch().join("prefix");
        let out = run(Command::new("bash")
            .arg(root().join("scripts/install.sh"))
            .args(["--prefix", prefix.to_str().unwrap()])
            .args(["--profile", "dev", "--no-build"])
            .arg("--unity-package")
            .arg(scratch().join("unity")));
        assert!(stdout(&out).contains("installed: libtroupe.so.1"));
        prefix
    })
}

/// The C streaming demo's run on the installed demo model with the repository's CMU clip,
/// from the repository root: its output file's bytes and its stdout.
fn stream_demo(bin: &Path, name: &str) -> (Vec<u8>, String) {
    let npy = scratch().join(format!("{name}.npy"));
    let bundle = prefix().join("share/troupe/bundles/armflow-demo");
    let out = run(Command::new(bin).current_dir(root()).args([
        bundle.to_str().unwrap(),
        "240",
        "4",
        npy.to_str().unwrap(),
    ]));
    let text = stdout(&out);
    assert!(text.contains("240 actor frames"), "{text}");
    (std::fs::read(&npy).unwrap(), text)
}

/// The answers every consumer must reproduce: the C demo built in place against the build
/// folder's library.
fn reference_output() -> &'static [u8] {
    static OUT: OnceLock<Vec<u8>> = OnceLock::new();
    OUT.get_or_init(|| {
        let libs = common::c_libraries();
        let bin = scratch().join("stream_reference");
        run(Command::new("cc")
            .args(["-std=c99", "-O2"])
            .arg(format!("-I{}", root().join("include").display()))
            .arg(root().join("examples/c/stream.c"))
            .arg("-o")
            .arg(&bin)
            .arg(format!("-L{}", libs.display()))
            .args(["-ltroupe", "-lm"])
            .arg(format!("-Wl,-rpath,{}", libs.display())));
        stream_demo(&bin, "reference").0
    })
}

/// What a program linked against `bin` loads at run time (`ldd`).
fn needed(bin: &Path) -> String {
    stdout(&run(Command::new("ldd").arg(bin)))
}

#[test]
fn prefix_holds_the_package() {
    let p = prefix();
    for file in [
        "lib/libtroupe.so.1",
        "lib/libtroupe.a",
        "include/troupe/troupe.h",
        "include/troupe/troupe.hpp",
        "lib/pkgconfig/troupe.pc",
        "lib/pkgconfig/troupe-static.pc",
        "lib/cmake/troupe/troupeConfig.cmake",
        "lib/cmake/troupe/troupeConfigVersion.cmake",
        "share/troupe/bundles/armflow-demo/troupe.json",
    ] {
        assert!(p.join(file).is_file(), "{file} is not installed");
    }
    assert_eq!(
        std::fs::read_link(p.join("lib/libtroupe.so")).unwrap(),
        Path::new("libtroupe.so.1")
    );
    // The headers are the repository's, byte for byte.
    for (installed, source) in [
        ("include/troupe/troupe.h", "include/troupe.h"),
        ("include/troupe/troupe.hpp", "bindings/cpp/troupe.hpp"),
    ] {
        assert_eq!(
            std::fs::read(p.join(installed)).unwrap(),
            std::fs::read(root().join(source)).unwrap(),
            "{installed}"
        );
    }
    let dynamic = stdout(&run(Command::new("readelf")
        .args(["-d", "-l", "-W"])
        .arg(p.join("lib/libtroupe.so.1"))));
    assert!(
        dynamic.contains("Library soname: [libtroupe.so.1]"),
        "{dynamic}"
    );
    let stack = dynamic
        .lines()
        .find(|l| l.contains("GNU_STACK"))
        .expect("a GNU_STACK header");
    assert!(
        !stack.trim_end().ends_with('E'),
        "executable stack: {stack}"
    );
}

#[test]
fn unity_package_holds_the_binding_and_the_library() {
    prefix();
    let unity = scratch().join("unity");
    for file in [
        "package.json",
        "Runtime/Troupe.cs",
        "Runtime/Troupe.Runtime.asmdef",
        "Runtime/Plugins/x86_64/libtroupe.so",
        "Samples~/AnimatorPartner/TroupePartner.cs",
        "Samples~/AnimatorPartner/armflow-demo.bytes",
    ] {
        assert!(unity.join(file).is_file(), "the Unity package lacks {file}");
    }
    // The sample's TextAsset is the demo bundle as one archive: every file of the bundle, byte
    // for byte, and a model loads from it.
    let archive = std::fs::read(unity.join("Samples~/AnimatorPartner/armflow-demo.bytes")).unwrap();
    let bundle = root().join("onnx/bundles/armflow-demo");
    let mut members = std::collections::BTreeMap::new();
    for entry in tar::Archive::new(&archive[..]).entries().unwrap() {
        let mut entry = entry.unwrap();
        let name = entry.path().unwrap().to_string_lossy().into_owned();
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut entry, &mut data).unwrap();
        members.insert(name, data);
    }
    let mut files = std::collections::BTreeMap::new();
    for entry in std::fs::read_dir(&bundle).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            files.insert(name, std::fs::read(&path).unwrap());
        }
    }
    assert!(
        members == files,
        "the archive's members differ from the bundle's files"
    );
    troupe::Model::from_archive_bytes(&archive, "armflow-demo.bytes")
        .expect("the demo model loads from the sample's archive");
    assert_eq!(
        std::fs::read(unity.join("Runtime/Troupe.cs")).unwrap(),
        std::fs::read(root().join("bindings/csharp/Troupe.cs")).unwrap()
    );
    let manifest = std::fs::read_to_string(unity.join("package.json")).unwrap();
    assert!(
        manifest.contains(&format!("\"version\": \"{}\"", env!("CARGO_PKG_VERSION"))),
        "{manifest}"
    );
    // What Unity's importer needs: a .meta with a GUID beside every file and folder it imports
    // (not the `Samples~` folder, which it skips), unique, and the same in every install.
    let metas = unity_metas(&unity);
    let again = scratch().join("unity-again");
    run(Command::new("bash")
        .arg(root().join("scripts/install.sh"))
        .args(["--prefix", scratch().join("prefix-again").to_str().unwrap()])
        .args(["--profile", "dev", "--no-build", "--unity-package"])
        .arg(&again));
    assert_eq!(
        metas,
        unity_metas(&again),
        "the GUIDs differ between installs"
    );
    let guids: std::collections::BTreeSet<&String> = metas.values().collect();
    assert_eq!(guids.len(), metas.len(), "a GUID is used twice: {metas:?}");
    for asset in [
        "package.json",
        "README.md",
        "Runtime",
        "Runtime/Troupe.cs",
        "Runtime/Troupe.Runtime.asmdef",
        "Runtime/Plugins",
        "Runtime/Plugins/x86_64",
        "Runtime/Plugins/x86_64/libtroupe.so",
    ] {
        assert!(metas.contains_key(asset), "no .meta for {asset}: {metas:?}");
    }
    assert!(!metas.keys().any(|k| k.contains('~')), "{metas:?}");
    // The plugin loads in the Linux x86-64 editor and player only; the assembly compiles there.
    let plugin =
        std::fs::read_to_string(unity.join("Runtime/Plugins/x86_64/libtroupe.so.meta")).unwrap();
    for line in [
        "PluginImporter:",
        "Exclude Linux64: 0",
        "Exclude Win64: 1",
        "Exclude OSXUniversal: 1",
        "      Editor: Editor\n    second:\n      enabled: 1",
        "        CPU: x86_64\n        DefaultValueInitialized: true\n        OS: Linux",
        "      Standalone: Linux64\n    second:\n      enabled: 1\n      settings:\n        CPU: x86_64",
        "      Standalone: Win64\n    second:\n      enabled: 0",
    ] {
        assert!(plugin.contains(line), "the plugin's importer lacks {line:?}:\n{plugin}");
    }
    let asmdef = std::fs::read_to_string(unity.join("Runtime/Troupe.Runtime.asmdef")).unwrap();
    let asmdef: serde_json::Value = serde_json::from_str(&asmdef).unwrap();
    assert_eq!(
        asmdef["includePlatforms"],
        serde_json::json!(["Editor", "LinuxStandalone64"])
    );
}

/// Each `.meta` file of a Unity package (outside folders Unity skips): the asset it describes
/// (its path in the package) and its GUID, checked to be 32 hexadecimal digits.
fn unity_metas(package: &Path) -> std::collections::BTreeMap<String, String> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![package.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.ends_with('~') || name.starts_with('.') {
                continue;
            }
            if path.is_dir() {
                stack.push(path.clone());
            }
            if let Some(asset) = name.strip_suffix(".meta") {
                let text = std::fs::read_to_string(&path).unwrap();
                let guid = text
                    .lines()
                    .find_map(|l| l.strip_prefix("guid: "))
                    .unwrap_or_else(|| panic!("{}: no guid", path.display()))
                    .to_string();
                assert!(
                    guid.len() == 32 && guid.chars().all(|c| c.is_ascii_hexdigit()),
                    "{}: guid {guid}",
                    path.display()
                );
                assert!(
                    text.starts_with("fileFormatVersion: 2\n"),
                    "{}",
                    path.display()
                );
                let rel = dir.join(asset).strip_prefix(package).unwrap().to_path_buf();
                assert!(
                    package.join(&rel).exists(),
                    "{} describes nothing",
                    path.display()
                );
                out.insert(rel.to_string_lossy().replace('\\', "/"), guid);
            } else {
                assert!(
                    dir.join(format!("{name}.meta")).is_file(),
                    "{} has no .meta",
                    path.display()
                );
            }
        }
    }
    out
}

#[test]
fn installer_refuses_bad_arguments() {
    // A Unity package folder that is someone's other folder is never replaced.
    let theirs = scratch().join("not-a-package");
    std::fs::create_dir_all(&theirs).unwrap();
    std::fs::write(theirs.join("keep.txt"), "mine").unwrap();
    let theirs_arg = theirs.to_str().unwrap();
    let prefix_arg = scratch().join("unused-prefix");
    let prefix_arg = prefix_arg.to_str().unwrap();
    for args in [
        &[][..],
        &["--prefix"][..],
        &["--frobnicate"][..],
        &[
            "--prefix",
            prefix_arg,
            "--no-build",
            "--unity-package",
            theirs_arg,
        ][..],
    ] {
        let out = Command::new("bash")
            .arg(root().join("scripts/install.sh"))
            .args(args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!out.stderr.is_empty(), "{args:?}: no message");
    }
    assert_eq!(std::fs::read(theirs.join("keep.txt")).unwrap(), b"mine");
}

/// Flags from pkg-config for `package`, read from the installed prefix only.
fn pkg_config(package: &str, what: &str) -> Vec<String> {
    let out = run(Command::new("pkg-config")
        .env("PKG_CONFIG_PATH", prefix().join("lib/pkgconfig"))
        .env("PKG_CONFIG_LIBDIR", prefix().join("lib/pkgconfig"))
        .args([what, package]));
    stdout(&out).split_whitespace().map(String::from).collect()
}

#[test]
fn pkg_config_consumers_build_and_stream() {
    let version = pkg_config("troupe", "--modversion");
    assert_eq!(version, [env!("CARGO_PKG_VERSION")]);
    let libdir = pkg_config("troupe", "--variable=libdir").remove(0);
    for (package, name) in [("troupe", "pc_shared"), ("troupe-static", "pc_static")] {
        let bin = scratch().join(name);
        run(Command::new("cc")
            .args(["-std=c99", "-O2"])
            .arg(root().join("examples/c/stream.c"))
            .arg("-o")
            .arg(&bin)
            .args(pkg_config(package, "--cflags"))
            .args(pkg_config(package, "--libs"))
            .arg(format!("-Wl,-rpath,{libdir}"))
            .arg("-lm"));
        let linked = needed(&bin);
        assert_eq!(
            linked.contains("libtroupe.so.1"),
            package == "troupe",
            "{name}: {linked}"
        );
        let (npy, text) = stream_demo(&bin, name);
        assert!(
            npy == reference_output(),
            "{name} streamed other values:\n{text}"
        );
    }
    // The header by its installed path, as other libraries' are included.
    let source = scratch().join("by_path.c");
    std::fs::write(
        &source,
        "#include <troupe/troupe.h>\n#include <stdio.h>\n\
         int main(void) { printf(\"%s\\n\", troupe_version_string()); return 0; }\n",
    )
    .unwrap();
    let bin = scratch().join("by_path");
    run(Command::new("cc")
        .arg(&source)
        .arg("-o")
        .arg(&bin)
        .args(pkg_config("troupe", "--cflags"))
        .args(pkg_config("troupe", "--libs"))
        .arg(format!("-Wl,-rpath,{libdir}")));
    let printed = stdout(&run(&mut Command::new(&bin)));
    assert!(printed.starts_with(env!("CARGO_PKG_VERSION")), "{printed}");
}

#[test]
fn cmake_consumer_builds_and_streams() {
    if !common::tools_or_skip("cmake_consumer_builds_and_streams", &["cmake"], "cmake") {
        return;
    }
    for (static_link, name) in [("OFF", "cmake_shared"), ("ON", "cmake_static")] {
        let build = scratch().join(name);
        run(Command::new("cmake")
            .arg("-S")
            .arg(root().join("examples/cmake"))
            .arg("-B")
            .arg(&build)
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix().display()))
            .arg(format!("-DTROUPE_STATIC={static_link}"))
            .arg("-DCMAKE_BUILD_TYPE=Release"));
        run(Command::new("cmake").arg("--build").arg(&build));
        for program in ["stream_cpp", "stream_c"] {
            let linked = needed(&build.join(program));
            assert_eq!(
                linked.contains("libtroupe.so.1"),
                static_link == "OFF",
                "{name}/{program}: {linked}"
            );
        }
        let cpp = stdout(&run(&mut Command::new(build.join("stream_cpp"))));
        assert!(
            cpp.contains("streamed 120 actor frames") && cpp.contains("(C ABI 1)"),
            "{cpp}"
        );
        let (npy, text) = stream_demo(&build.join("stream_c"), name);
        assert!(
            npy == reference_output(),
            "{name} streamed other values:\n{text}"
        );
    }
}

/// The package's version is the release (0.2.0): requests for it or an older 0.x release are
/// met, and the ABI number the 0.1 package was versioned by (1); a newer release and another ABI
/// are refused (`scripts/install.sh`'s version file, `docs/INSTALL.md`).
#[test]
fn cmake_accepts_this_release_and_refuses_others() {
    if !common::tools_or_skip(
        "cmake_accepts_this_release_and_refuses_others",
        &["cmake"],
        "cmake",
    ) {
        return;
    }
    let release = env!("CARGO_PKG_VERSION");
    let minor: u32 = env!("CARGO_PKG_VERSION_MINOR").parse().unwrap();
    let newer = format!("0.{}", minor + 1);
    let requests = [
        (release, true),
        ("0.2", true),
        ("0.1", true),
        ("1", true),
        (newer.as_str(), false),
        ("0.0", false),
        ("1.1", false),
        ("2", false),
    ];
    for (i, (request, met)) in requests.into_iter().enumerate() {
        let project = scratch().join(format!("find_{i}"));
        std::fs::create_dir_all(&project).unwrap();
        std::fs::write(
            project.join("CMakeLists.txt"),
            format!(
                "cmake_minimum_required(VERSION 3.16)\nproject(find LANGUAGES C)\n\
                 find_package(troupe {request} REQUIRED)\nmessage(STATUS \"troupe ${{troupe_VERSION}}\")\n"
            ),
        )
        .unwrap();
        let out = Command::new("cmake")
            .arg("-S")
            .arg(&project)
            .arg("-B")
            .arg(project.join("build"))
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix().display()))
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(
            out.status.success(),
            met,
            "find_package(troupe {request}):\n{text}"
        );
        if met {
            assert!(text.contains(&format!("troupe {release}")), "{text}");
        } else {
            assert!(text.contains("troupeConfig.cmake"), "{text}");
        }
    }
}

/// The sizes docs/INSTALL.md gives are `scripts/sizes.sh --update-docs`'s, never typed by hand:
/// the block between its markers holds the table of each profile's shared library, static
/// library and wheel, and a stamp naming the commit they were measured at, which must be in
/// this repository's history; the demo model's size, cheap to measure, must be today's.
#[test]
fn install_doc_sizes_are_the_measuring_scripts() {
    let doc = std::fs::read_to_string(root().join("docs/INSTALL.md")).unwrap();
    let block = doc
        .split_once("<!-- sizes:begin -->\n")
        .and_then(|(_, rest)| rest.split_once("<!-- sizes:end -->"))
        .map(|(block, _)| block)
        .expect("docs/INSTALL.md has the sizes markers");
    let megabytes = |cell: &str| -> f64 {
        cell.trim()
            .strip_suffix(" MB")
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("not a size in MB: {cell:?}"))
    };
    let rows: Vec<Vec<&str>> = block
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| l.split('|').map(str::trim).collect())
        .collect();
    assert!(
        rows.iter().any(|r| r[1] == "`release`"),
        "no release row:\n{block}"
    );
    for row in &rows {
        for cell in &row[3..6] {
            assert!(megabytes(cell) > 1.0, "{row:?}");
        }
    }
    let stamp = block
        .split_once("Measured by `scripts/sizes.sh --update-docs` at commit ")
        .map(|(_, rest)| rest)
        .expect("the sizes carry their stamp");
    let commit: String = stamp.chars().take_while(char::is_ascii_hexdigit).collect();
    assert!(commit.len() >= 7, "{stamp}");
    if root().join(".git").exists() {
        let known = Command::new("git")
            .current_dir(root())
            .args(["cat-file", "-e", &format!("{commit}^{{commit}}")])
            .status()
            .unwrap();
        assert!(
            known.success(),
            "the sizes' commit {commit} is not in the history"
        );
    }
    let model: u64 = std::fs::read_dir(root().join("onnx/bundles/armflow-demo"))
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap())
        .filter(|m| m.is_file())
        .map(|m| m.len())
        .sum();
    let stated = format!(
        "The demo model the packages carry: {:.1} MB",
        model as f64 / 1e6
    );
    assert!(block.contains(&stated), "want {stated:?} in:\n{block}");
}
