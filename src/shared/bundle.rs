//! Where a bundle's files come from: a directory, or a tar archive of that directory (a file on
//! disk or bytes in memory, for engines that pack their assets).

use std::borrow::Cow;
use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::shared::error::{Error, Result};

/// The files of one bundle.
#[derive(Debug)]
pub(crate) enum BundleFiles {
    /// A directory holding `troupe.json` and the graphs.
    Dir(PathBuf),
    /// The regular files of an uncompressed tar archive, by name (leading `./` stripped).
    Archive {
        label: PathBuf,
        files: HashMap<String, Vec<u8>>,
    },
}

impl BundleFiles {
    /// A directory is read file by file; any other path is read as a tar archive.
    pub(crate) fn open(path: &Path) -> Result<Self> {
        if path.is_dir() {
            return Ok(Self::Dir(path.to_path_buf()));
        }
        if !path.exists() {
            return Err(Error::Io {
                path: path.join("troupe.json"),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such bundle"),
            });
        }
        let bytes = std::fs::read(path).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_archive(&bytes, path)
    }

    /// Reads an uncompressed tar archive held in memory; `label` names it in messages.
    pub(crate) fn from_archive(bytes: &[u8], label: &Path) -> Result<Self> {
        let bad = |e: std::io::Error| Error::Io {
            path: label.to_path_buf(),
            source: std::io::Error::new(e.kind(), format!("not a readable tar archive: {e}")),
        };
        let mut files = HashMap::new();
        let mut archive = tar::Archive::new(bytes);
        for entry in archive.entries().map_err(bad)? {
            let mut entry = entry.map_err(bad)?;
            if !entry.header().entry_type().is_file() {
                continue;
            }
            let name = entry.path().map_err(bad)?.to_string_lossy().into_owned();
            let name = name.trim_start_matches("./").to_owned();
            let mut data = Vec::with_capacity(entry.size() as usize);
            entry.read_to_end(&mut data).map_err(bad)?;
            files.insert(name, data);
        }
        Ok(Self::Archive {
            label: label.to_path_buf(),
            files,
        })
    }

    /// How a file of the bundle is named in messages.
    pub(crate) fn path_of(&self, name: &str) -> PathBuf {
        match self {
            Self::Dir(dir) => dir.join(name),
            Self::Archive { label, .. } => label.join(name),
        }
    }

    /// The contents of one file of the bundle (borrowed from an archive, read from a directory).
    pub(crate) fn read(&self, name: &str) -> Result<Cow<'_, [u8]>> {
        match self {
            Self::Dir(dir) => std::fs::read(dir.join(name))
                .map(Cow::Owned)
                .map_err(|source| Error::Io {
                    path: dir.join(name),
                    source,
                }),
            Self::Archive { files, .. } => files
                .get(name)
                .map(|bytes| Cow::Borrowed(bytes.as_slice()))
                .ok_or_else(|| Error::Io {
                    path: self.path_of(name),
                    source: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "the archive holds no such file",
                    ),
                }),
        }
    }
}
