//! Where a bundle's files come from: a directory, or a tar archive of that directory (a file on
//! disk or bytes in memory, for engines that pack their assets).
//!
//! A bundle may come from anyone, so reading one trusts nothing in it: only regular files are
//! read (never a device, FIFO or socket, which could block or never end), files are opened
//! without blocking and without following a final symlink, a directory bundle's files must
//! resolve inside the directory, names must be plain relative paths, and every size (a tar
//! member's declared size included) is checked against [`LIMITS`] before anything is allocated.

use std::cell::Cell;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

use sha2::{Digest, Sha256};

use crate::shared::error::{excerpt, Error, Result};
use crate::shared::limits::LIMITS;
use crate::shared::paths;

/// The files of one bundle.
#[derive(Debug)]
pub(crate) enum BundleFiles {
    /// A directory holding `troupe.json` and the graphs.
    Dir {
        /// The directory, with every symlink resolved.
        dir: PathBuf,
        /// Bytes read from it so far, bounded by `LIMITS.max_bundle_bytes`.
        read: AtomicU64,
        /// What each file read held (`BundleFiles::identity`).
        digests: FileDigests,
    },
    /// The regular files of an uncompressed tar archive, by name (leading `./` stripped).
    Archive {
        label: PathBuf,
        files: HashMap<String, Vec<u8>>,
        /// What each file read held (`BundleFiles::identity`).
        digests: FileDigests,
    },
}

/// The SHA-256 of each file a load read, by name, and of each file the manifest says the bundle
/// holds.
#[derive(Debug, Default)]
pub(crate) struct FileDigests {
    /// What each file read held: the model's identity is made of them, so that a snapshot of a
    /// stream goes back only onto the bundle it was taken from, whether that bundle is a
    /// directory or a tar of it (files the load never read do not count).
    read: Mutex<BTreeMap<String, [u8; 32]>>,
    /// What the manifest records each file holds (its `sha256`), once it has been read: every
    /// file read after it is checked against it.
    expected: OnceLock<BTreeMap<String, [u8; 32]>>,
}

fn io_error(path: &Path, kind: std::io::ErrorKind, message: impl Into<String>) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(kind, message.into()),
    }
}

fn invalid(path: &Path, message: impl Into<String>) -> Error {
    io_error(path, std::io::ErrorKind::InvalidData, message)
}

/// Opens `path` for reading without blocking (a FIFO would otherwise wait for a writer; on
/// Windows a device name is refused before opening) and without following a symbolic link or
/// junction in its last component, and checks that it is a regular file of at most `limit`
/// bytes. Returns the file and its length.
fn open_regular(path: &Path, limit: u64, what: &str) -> Result<(File, u64)> {
    if let Some(device) = paths::windows_device(path) {
        return Err(invalid(
            path,
            format!("the {what}: {}", paths::device_message(&device)),
        ));
    }
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW);
    }
    #[cfg(windows)]
    {
        use std::os::windows::fs::OpenOptionsExt;
        // FILE_FLAG_OPEN_REPARSE_POINT: a symbolic link or junction is opened itself (and then
        // refused below), not followed.
        options.custom_flags(0x0020_0000);
    }
    let file = options.open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let meta = file.metadata().map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.file_type().is_file() || is_reparse_point(&meta) {
        return Err(invalid(
            path,
            format!(
                "the {what} is not a regular file (a device, FIFO, socket, directory, symbolic \
                 link or junction)"
            ),
        ));
    }
    if meta.len() > limit {
        return Err(invalid(
            path,
            format!(
                "the {what} is {} bytes, above troupe's limit of {limit}",
                meta.len()
            ),
        ));
    }
    Ok((file, meta.len()))
}

/// Whether Windows marks the file a reparse point (a symbolic link, a junction, a cloud or
/// deduplicated placeholder): troupe reads only what is stored at the path itself.
#[cfg(windows)]
fn is_reparse_point(meta: &std::fs::Metadata) -> bool {
    use std::os::windows::fs::MetadataExt;
    const FILE_ATTRIBUTE_REPARSE_POINT: u32 = 0x400;
    meta.file_attributes() & FILE_ATTRIBUTE_REPARSE_POINT != 0
}

#[cfg(not(windows))]
fn is_reparse_point(_: &std::fs::Metadata) -> bool {
    false
}

/// Files at least this large are mapped, not read: a graph's weights are then copied once, by
/// the decoder, instead of first into a buffer of their own (a fifth of a paper bundle's load).
const MAP_AT_BYTES: u64 = 1 << 20;

/// A bundle file's bytes: read into memory, borrowed from an in-memory bundle, or mapped.
pub(crate) enum FileBytes<'a> {
    Owned(Vec<u8>),
    Borrowed(&'a [u8]),
    Mapped(memmap2::Mmap),
}

impl std::ops::Deref for FileBytes<'_> {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            Self::Owned(bytes) => bytes,
            Self::Borrowed(bytes) => bytes,
            Self::Mapped(map) => map,
        }
    }
}

/// Reads at most `len` bytes (the length checked when the file was opened) and fails if the file
/// grew or shrank since.
fn read_exactly(mut file: File, len: u64, path: &Path) -> Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(len as usize);
    (&mut file)
        .take(len + 1)
        .read_to_end(&mut bytes)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
    if bytes.len() as u64 != len {
        return Err(invalid(path, "the file changed size while it was read"));
    }
    Ok(bytes)
}

/// A bundle file's name as the manifest or archive gives it: a plain relative path (no `..`, no
/// root, no empty or NUL-holding name) whose parts name the same file on every platform (no `\`,
/// `:` or Windows device name: `shared/paths.rs`), leading `./` dropped.
fn plain_name(name: &str) -> Option<String> {
    // Checked on the whole name: Windows would already have split it at a `\`.
    if name.contains(['\\', ':']) {
        return None;
    }
    let path = Path::new(name);
    let mut parts = Vec::new();
    for part in path.components() {
        match part {
            Component::Normal(p) => {
                let part = p.to_str()?;
                if !paths::is_portable_name(part) {
                    return None;
                }
                parts.push(part);
            }
            Component::CurDir => {}
            _ => return None,
        }
    }
    if parts.is_empty() || name.contains('\0') {
        return None;
    }
    Some(parts.join("/"))
}

impl BundleFiles {
    /// A directory is read file by file; any other path is read as a tar archive (a regular file
    /// of at most `LIMITS.max_bundle_bytes`).
    pub(crate) fn open(path: &Path) -> Result<Self> {
        if let Some(device) = paths::windows_device(path) {
            return Err(invalid(
                path,
                format!("the bundle: {}", paths::device_message(&device)),
            ));
        }
        let meta = std::fs::metadata(path).map_err(|source| Error::Io {
            path: path.join("troupe.json"),
            source: std::io::Error::new(source.kind(), format!("no such bundle ({source})")),
        })?;
        if meta.is_dir() {
            let dir = path.canonicalize().map_err(|source| Error::Io {
                path: path.to_path_buf(),
                source,
            })?;
            return Ok(Self::Dir {
                dir,
                read: AtomicU64::new(0),
                digests: FileDigests::default(),
            });
        }
        let (file, len) = open_regular(path, LIMITS.max_bundle_bytes, "bundle archive")?;
        Self::read_archive(std::io::BufReader::new(file), len, path)
    }

    /// Reads an uncompressed tar archive held in memory; `label` names it in messages.
    pub(crate) fn from_archive(bytes: &[u8], label: &Path) -> Result<Self> {
        if bytes.len() as u64 > LIMITS.max_bundle_bytes {
            return Err(invalid(
                label,
                format!(
                    "the archive is {} bytes, above troupe's limit of {}",
                    bytes.len(),
                    LIMITS.max_bundle_bytes
                ),
            ));
        }
        Self::read_archive(bytes, bytes.len() as u64, label)
    }

    /// The regular files of the tar archive read from `reader` (`len` bytes in all). Member
    /// sizes are checked against what is left of the archive before any is read; links, devices
    /// and FIFOs, unsafe or repeated names, and too many members are refused.
    fn read_archive(reader: impl Read, len: u64, label: &Path) -> Result<Self> {
        let consumed = Rc::new(Cell::new(0u64));
        // The tar reader's own messages quote the bytes it could not parse (a file named by
        // mistake, `/etc/passwd` say, would have its first line in the error a service passes
        // on): say where reading stopped instead, and quote only the system's I/O errors.
        let bad = |e: std::io::Error| {
            let why = match e.raw_os_error() {
                Some(_) => e.to_string(),
                None => format!(
                    "damaged, or not a tar archive (reading stopped at byte {} of {len})",
                    consumed.get()
                ),
            };
            invalid(label, format!("not a readable tar archive: {why}"))
        };
        let mut files: HashMap<String, Vec<u8>> = HashMap::new();
        let mut archive = tar::Archive::new(CountingReader {
            inner: reader,
            consumed: Rc::clone(&consumed),
        });
        let (mut members, mut total) = (0u64, 0u64);
        for entry in archive.entries().map_err(bad)? {
            let mut entry = entry.map_err(bad)?;
            members += 1;
            if members > LIMITS.max_archive_members {
                return Err(invalid(
                    label,
                    format!(
                        "the archive has more than troupe's limit of {} members",
                        LIMITS.max_archive_members
                    ),
                ));
            }
            let raw = entry.path().map_err(bad)?.to_string_lossy().into_owned();
            let shown = excerpt(&raw);
            let kind = entry.header().entry_type();
            if kind.is_dir() || kind.is_pax_global_extensions() {
                continue;
            }
            if !kind.is_file() && !kind.is_contiguous() {
                return Err(invalid(
                    label,
                    format!(
                        "member `{shown}` is a {kind:?} entry; a bundle holds only regular \
                         files and directories"
                    ),
                ));
            }
            let name = plain_name(&raw).ok_or_else(|| {
                invalid(
                    label,
                    format!("member `{shown}` is not a plain relative path"),
                )
            })?;
            let size = entry.size();
            total = total.saturating_add(size);
            if size > len || total > len {
                return Err(invalid(
                    label,
                    format!(
                        "member `{shown}` declares {size} bytes, more than the {len}-byte \
                         archive holds"
                    ),
                ));
            }
            if files.contains_key(&name) {
                return Err(invalid(label, format!("member `{shown}` appears twice")));
            }
            let mut data = Vec::with_capacity(size as usize);
            (&mut entry)
                .take(size)
                .read_to_end(&mut data)
                .map_err(bad)?;
            if data.len() as u64 != size {
                return Err(invalid(label, format!("member `{shown}` is truncated")));
            }
            files.insert(name, data);
        }
        Ok(Self::Archive {
            label: label.to_path_buf(),
            files,
            digests: FileDigests::default(),
        })
    }

    /// How a file of the bundle is named in messages.
    pub(crate) fn path_of(&self, name: &str) -> PathBuf {
        match self {
            Self::Dir { dir, .. } => dir.join(name),
            Self::Archive { label, .. } => label.join(name),
        }
    }

    /// The size in bytes of the file `name`, or 0 when it cannot be known without reading it
    /// (the read that follows reports why). Used only to schedule work.
    pub(crate) fn size_hint(&self, name: &str) -> u64 {
        match self {
            Self::Dir { .. } => std::fs::metadata(self.path_of(name)).map_or(0, |m| m.len()),
            Self::Archive { files, .. } => plain_name(name)
                .and_then(|plain| files.get(&plain))
                .map_or(0, |bytes| bytes.len() as u64),
        }
    }

    /// The identity of the model loaded from these files: the SHA-256 of every file read so far,
    /// by name, in name order (call it once the load has read them all).
    pub(crate) fn identity(&self) -> [u8; 32] {
        let (Self::Dir { digests, .. } | Self::Archive { digests, .. }) = self;
        let digests = digests.read.lock().unwrap_or_else(|e| e.into_inner());
        let mut all = Sha256::new();
        for (name, digest) in digests.iter() {
            all.update((name.len() as u64).to_le_bytes());
            all.update(name.as_bytes());
            all.update(digest);
        }
        all.finalize().into()
    }

    /// The contents of one file of the bundle (borrowed from an archive; from a directory, mapped
    /// when it is large, read otherwise), at most `limit` bytes; its digest is kept for
    /// [`BundleFiles::identity`].
    pub(crate) fn read(&self, name: &str, limit: u64) -> Result<FileBytes<'_>> {
        let bytes = self.read_unrecorded(name, limit)?;
        let (Self::Dir { digests, .. } | Self::Archive { digests, .. }) = self;
        if let Some(plain) = plain_name(name) {
            let digest: [u8; 32] = Sha256::digest(&*bytes).into();
            if let Some(expected) = digests.expected.get() {
                let why = match expected.get(&plain) {
                    Some(recorded) if *recorded == digest => None,
                    Some(_) => Some(
                        "its SHA-256 is not the one troupe.json records for it: the file was \
                         damaged or changed after the bundle was written",
                    ),
                    None => Some("troupe.json records no SHA-256 for it (its `sha256` list)"),
                };
                if let Some(why) = why {
                    return Err(Error::Graph {
                        file: self.path_of(name),
                        message: why.into(),
                    });
                }
            }
            digests
                .read
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .insert(plain, digest);
        }
        Ok(bytes)
    }

    /// From now on every file read must hold what `sha256` (the manifest's, by file name)
    /// records for it. Set once, after the manifest is read.
    pub(crate) fn expect_digests(&self, sha256: BTreeMap<String, [u8; 32]>) {
        let (Self::Dir { digests, .. } | Self::Archive { digests, .. }) = self;
        let _ = digests.expected.set(sha256);
    }

    fn read_unrecorded(&self, name: &str, limit: u64) -> Result<FileBytes<'_>> {
        let path = self.path_of(name);
        let plain = plain_name(name).ok_or_else(|| {
            invalid(
                &path,
                "a bundle file must be named by a plain relative path (no `..`, no root, no \
                 `\\` or `:`, no Windows device name such as `NUL`)",
            )
        })?;
        match self {
            Self::Dir { dir, read, .. } => {
                let resolved = dir
                    .join(&plain)
                    .canonicalize()
                    .map_err(|source| Error::Io {
                        path: path.clone(),
                        source,
                    })?;
                if !resolved.starts_with(dir) {
                    return Err(invalid(
                        &path,
                        format!(
                            "the file resolves to {}, outside the bundle directory",
                            resolved.display()
                        ),
                    ));
                }
                let left = LIMITS.max_bundle_bytes
                    - read.load(Ordering::Relaxed).min(LIMITS.max_bundle_bytes);
                let (file, len) = open_regular(&resolved, limit.min(left), "bundle file").map_err(
                    |e| match e {
                        Error::Io { source, .. } => Error::Io {
                            path: path.clone(),
                            source,
                        },
                        other => other,
                    },
                )?;
                read.fetch_add(len, Ordering::Relaxed);
                if len >= MAP_AT_BYTES {
                    // SAFETY: a private read-only mapping of a regular file opened above; its
                    // bytes are only copied out (decoded) before the mapping is dropped. Another
                    // process truncating the file in that window faults the load, as with any
                    // mapped loader (`docs/RELIABILITY.md`).
                    if let Ok(map) = unsafe { memmap2::Mmap::map(&file) } {
                        if map.len() as u64 == len {
                            return Ok(FileBytes::Mapped(map));
                        }
                    }
                }
                read_exactly(file, len, &path).map(FileBytes::Owned)
            }
            Self::Archive { files, .. } => {
                let bytes = files.get(&plain).ok_or_else(|| {
                    io_error(
                        &path,
                        std::io::ErrorKind::NotFound,
                        "the archive holds no such file",
                    )
                })?;
                if bytes.len() as u64 > limit {
                    return Err(invalid(
                        &path,
                        format!(
                            "the file is {} bytes, above troupe's limit of {limit}",
                            bytes.len()
                        ),
                    ));
                }
                Ok(FileBytes::Borrowed(bytes.as_slice()))
            }
        }
    }
}

/// A reader that counts the bytes it has handed on, so that an archive's error can say where
/// reading stopped without quoting what it read.
struct CountingReader<R> {
    inner: R,
    consumed: Rc<Cell<u64>>,
}

impl<R: Read> Read for CountingReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.consumed.set(self.consumed.get() + n as u64);
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundle_file_names_are_plain_and_portable() {
        assert_eq!(plain_name("./vae.onnx").as_deref(), Some("vae.onnx"));
        assert_eq!(
            plain_name("graphs/vae.onnx").as_deref(),
            Some("graphs/vae.onnx")
        );
        for name in [
            "../vae.onnx",
            "/etc/passwd",
            "",
            "graphs\\vae.onnx",
            "C:vae.onnx",
            "vae.onnx:hidden",
            "nul.onnx",
            "graphs/AUX/vae.onnx",
            "com1",
            "a\0b",
        ] {
            assert_eq!(plain_name(name), None, "{name:?}");
        }
    }

    #[test]
    fn large_files_are_mapped_small_ones_read_and_both_hold_the_files_bytes() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let large: Vec<u8> = (0..MAP_AT_BYTES + 7)
            .map(|i| (i * 31 % 251) as u8)
            .collect();
        std::fs::write(dir.path().join("large.onnx"), &large).expect("written");
        std::fs::write(dir.path().join("small.json"), b"{}").expect("written");
        let files = BundleFiles::open(dir.path()).expect("a directory bundle");
        let read = files.read("large.onnx", u64::MAX).expect("read");
        assert!(matches!(read, FileBytes::Mapped(_)));
        assert_eq!(&read[..], &large[..]);
        let read = files.read("small.json", u64::MAX).expect("read");
        assert!(matches!(read, FileBytes::Owned(_)));
        assert_eq!(&read[..], b"{}");
        let err = files
            .read("large.onnx", 1000)
            .err()
            .expect("over the limit");
        assert!(err.to_string().contains("above troupe's limit"), "{err}");
    }
}
