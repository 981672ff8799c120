//! Writing files a caller asked for: through a temporary file in the target's directory, renamed
//! into place once complete, so that a failed write leaves neither a partial file nor the
//! temporary one.
//!
//! What may be at the path: nothing, or a regular file, which is replaced. Anything else (a
//! directory, a symbolic link, a FIFO, a socket, a device, a Windows device name such as `NUL`)
//! is refused before anything is written: a writer never writes through a link or into a
//! special file, nor replaces one with a regular file. (The check and the final rename are two
//! steps: something created at the path between them is replaced.)

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::shared::error::{Error, Result};

/// A temporary file beside `path`, removed on drop unless [`Pending::commit`] renamed it.
pub(crate) struct Pending {
    temp: PathBuf,
    target: PathBuf,
    committed: bool,
}

fn io_error(path: &Path, source: std::io::Error) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Refuses a path where something other than a regular file is (see the module documentation).
fn check_target(path: &Path) -> Result<()> {
    if let Some(device) = crate::shared::paths::windows_device(path) {
        return Err(Error::InvalidInput(format!(
            "{}: {}; troupe writes a new file or replaces a regular file, nothing else",
            path.display(),
            crate::shared::paths::device_message(&device)
        )));
    }
    let kind = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io_error(path, e)),
        Ok(meta) => meta.file_type(),
    };
    if kind.is_file() {
        return Ok(());
    }
    let what = if kind.is_dir() {
        "a directory"
    } else if kind.is_symlink() {
        "a symbolic link"
    } else {
        special_kind(&kind)
    };
    Err(Error::InvalidInput(format!(
        "{}: {what} is there; troupe writes a new file or replaces a regular file, nothing else",
        path.display()
    )))
}

#[cfg(unix)]
fn special_kind(kind: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_fifo() {
        "a FIFO"
    } else if kind.is_socket() {
        "a socket"
    } else if kind.is_char_device() || kind.is_block_device() {
        "a device"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    // Windows: a junction or another reparse point that is neither a file nor a directory.
    "a special file (a junction or another reparse point)"
}

impl Pending {
    /// Writes `bytes` to a new temporary file beside `path`, once `path` is checked to hold
    /// nothing or a regular file.
    pub(crate) fn write(path: &Path, bytes: &[u8]) -> Result<Pending> {
        check_target(path)?;
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let name = path.file_name().ok_or_else(|| {
            io_error(
                path,
                std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
            )
        })?;
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(
            ".{}-{}.tmp",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let temp = path.with_file_name(temp_name);
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|e| io_error(path, e))?;
        let pending = Pending {
            temp,
            target: path.to_path_buf(),
            committed: false,
        };
        file.write_all(bytes)
            .and_then(|()| file.sync_all())
            .map_err(|e| io_error(path, e))?;
        Ok(pending)
    }

    /// Renames the temporary file to its target.
    pub(crate) fn commit(mut self) -> Result<()> {
        std::fs::rename(&self.temp, &self.target).map_err(|e| io_error(&self.target, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically (see the module documentation).
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    Pending::write(path, bytes)?.commit()
}

/// The bytes of the regular file at `path`, refused before reading when it names a Windows
/// device, is not a regular file, or holds more than `max` bytes (`what` names such files in the
/// message, e.g. "BVH files"); what is read is bounded by `max` even if the file grows meanwhile.
pub(crate) fn read_bounded(path: &Path, max: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    if let Some(device) = crate::shared::paths::windows_device(path) {
        return Err(Error::InvalidInput(format!(
            "{}: {}",
            path.display(),
            crate::shared::paths::device_message(&device)
        )));
    }
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(Error::InvalidInput(format!(
            "{}: not a regular file",
            path.display()
        )));
    }
    if meta.len() > max {
        return Err(Error::InvalidInput(format!(
            "{}: {} bytes; troupe reads {what} of at most {max}",
            path.display(),
            meta.len()
        )));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)
        .map_err(io)?
        .take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    Ok(bytes)
}
