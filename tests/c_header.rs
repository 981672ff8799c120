//! `include/troupe.h` is generated from `src/ffi/` by cbindgen with `cbindgen.toml`, plus version
//! macros taken from Cargo.toml. This test fails when the committed header differs from a fresh
//! generation; `TROUPE_BLESS=1 cargo test --test c_header` rewrites it.

use std::path::Path;

fn generate() -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut config =
        cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml");
    let (major, minor, patch) = (
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
    );
    let packed = (major.parse::<u32>().unwrap() << 16)
        | (minor.parse::<u32>().unwrap() << 8)
        | patch.parse::<u32>().unwrap();
    config.after_includes = Some(format!(
        "\n/* Version of this header, from Cargo.toml; compare with troupe_version_number(). */\n\
         #define TROUPE_VERSION_MAJOR {major}\n#define TROUPE_VERSION_MINOR {minor}\n\
         #define TROUPE_VERSION_PATCH {patch}\n#define TROUPE_VERSION_STRING \"{}\"\n\
         #define TROUPE_VERSION_NUMBER {packed}",
        env!("CARGO_PKG_VERSION")
    ));
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_crate(root)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut out);
    String::from_utf8(out).unwrap()
}

#[test]
fn committed_header_is_up_to_date() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("include/troupe.h");
    let fresh = generate();
    if std::env::var_os("TROUPE_BLESS").is_some() {
        std::fs::write(&path, &fresh).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == fresh,
        "include/troupe.h is out of date with src/ffi/; run `TROUPE_BLESS=1 cargo test --test c_header` and commit it"
    );
}
