//! A bundle packed as an uncompressed tar archive loads from disk and from memory, and runs
//! exactly like the directory it was packed from.

mod common;

use common::*;
use troupe::{Error, Model, TokenTrace};

fn pack_bundle() -> Vec<u8> {
    let mut builder = tar::Builder::new(Vec::new());
    let mut names: Vec<_> = std::fs::read_dir(bundle_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    names.sort();
    for path in names {
        let name = path.file_name().unwrap().to_str().unwrap().to_owned();
        builder
            .append_path_with_name(&path, format!("./{name}"))
            .unwrap();
    }
    builder.into_inner().unwrap()
}

fn stream(model: &Model) -> (Vec<f32>, Vec<TokenTrace>) {
    run_chunked(&mut model.session(default_options()).unwrap(), &actor(), 4)
}

#[test]
fn archive_in_memory_and_on_disk_match_the_directory() {
    let bytes = pack_bundle();
    let from_memory = Model::from_archive_bytes(&bytes, "tiny.troupe").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tiny.troupe");
    std::fs::write(&file, &bytes).unwrap();
    let from_file = Model::load(&file).unwrap();
    let reference = stream(model());
    assert!(stream(&from_memory) == reference);
    assert!(stream(&from_file) == reference);
    assert_eq!(from_memory.source(), std::path::Path::new("tiny.troupe"));
}

#[test]
fn bad_archives_are_rejected_with_the_archive_named() {
    let e = Model::from_archive_bytes(
        b"definitely not a tar archive, far too short",
        "junk.troupe",
    )
    .unwrap_err();
    let text = e.to_string();
    assert!(text.contains("junk.troupe"), "{text}");

    // An archive without the velocity graph names the missing member.
    let mut builder = tar::Builder::new(Vec::new());
    let layers = (0..4).map(|i| format!("context_layer_{i}.onnx"));
    let names = ["troupe.json".to_string(), "conditioning.onnx".into()];
    for name in names.into_iter().chain(layers) {
        builder
            .append_path_with_name(bundle_dir().join(&name), &name)
            .unwrap();
    }
    let e =
        Model::from_archive_bytes(&builder.into_inner().unwrap(), "partial.troupe").unwrap_err();
    assert!(matches!(e, Error::Io { .. }));
    assert!(
        e.to_string().contains("partial.troupe/velocity.onnx"),
        "{e}"
    );
}

/// A message quotes a bounded, escaped excerpt of an archive: a symbolic link whose name is
/// 100,000 bytes (a GNU long name) is refused with a message of a few hundred bytes giving the
/// name's length, not the name; a header of garbage does not paste the file into the message.
#[test]
fn archive_messages_quote_bounded_excerpts() {
    let mut builder = tar::Builder::new(Vec::new());
    let long = format!("{}\u{7}", "n".repeat(99_999));
    let mut header = tar::Header::new_gnu();
    header.set_entry_type(tar::EntryType::Symlink);
    header.set_size(0);
    builder
        .append_link(&mut header, &long, "troupe.json")
        .unwrap();
    let e = Model::from_archive_bytes(&builder.into_inner().unwrap(), "long.troupe")
        .unwrap_err()
        .to_string();
    assert!(e.len() < 400, "{} bytes", e.len());
    assert!(e.contains("(100000 bytes)") && e.contains("Symlink"), "{e}");
    let mut garbage = vec![0xABu8; 1 << 16];
    garbage[..512].fill(b'7');
    let e = Model::from_archive_bytes(&garbage, "garbage.troupe")
        .unwrap_err()
        .to_string();
    assert!(
        e.len() < 600 && e.contains("garbage.troupe"),
        "{} bytes: {e}",
        e.len()
    );
}
