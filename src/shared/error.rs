//! The one error type of troupe. Every variant carries enough context (file, tensor, shape, the
//! offending value) for the message alone to say what went wrong.

use std::path::PathBuf;

/// Result alias used throughout troupe.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can fail when loading a bundle or running a session.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file of the bundle could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file that could not be read.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// `troupe.json` is malformed, of an unsupported version, or inconsistent with itself.
    #[error("{}: {message}", path.display())]
    Manifest {
        /// Path of the manifest.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// An ONNX graph is corrupt or does not match what the manifest declares.
    #[error("{}: {message}", file.display())]
    Graph {
        /// The graph file.
        file: PathBuf,
        /// What is wrong, naming the tensor and shape where there is one.
        message: String,
    },
    /// Data passed to a session is unusable (wrong size, non-finite values).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A session option is out of range.
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// The bundle's family does not offer what was asked (a UMF bundle asked to stream, an
    /// ARFlow stream asked for an ARMFlow-only setting): the message names the family and what
    /// does offer it.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A long call was stopped by the calling thread's progress callback (see
    /// [`crate::with_progress`]); nothing was written and no state changed.
    #[error("cancelled: {0}")]
    Cancelled(String),
    /// A graph failed while running; the session that ran it is left unchanged.
    #[error("{graph}: inference failed: {message}")]
    Inference {
        /// The role of the graph in the bundle (`context_layers`, `velocity`, ...).
        graph: &'static str,
        /// The runtime's message.
        message: String,
    },
}

/// The article of a family's name as read aloud: "an armflow", "an arflow", "a umf", "a magnet".
pub(crate) fn a_or_an(family: &str) -> &'static str {
    if family.starts_with('a') {
        "an"
    } else {
        "a"
    }
}
