//! Writing files a caller asked for: through a temporary file in the target's directory, renamed
//! into place once complete, so that a failed write leaves neither a partial file nor the
//! temporary one.

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

impl Pending {
    /// Writes `bytes` to a new temporary file beside `path`.
    pub(crate) fn write(path: &Path, bytes: &[u8]) -> Result<Pending> {
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
