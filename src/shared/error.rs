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
    /// The output a caller sized cannot hold what a step returns (the C ABI's caller-sized
    /// buffers); nothing changed.
    #[error("output too small: {0}")]
    OutputTooSmall(String),
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

/// How much of a caller's input a message quotes.
pub(crate) const EXCERPT_BYTES: usize = 64;

/// At most `max` bytes of `text` (cut on a character boundary), escaped so that control
/// characters, quotes and backslashes show as escapes, and its whole length when cut: how a
/// message quotes what it was given, so that a huge or binary input never becomes a huge or
/// unprintable message.
pub(crate) fn excerpt_of(text: &str, max: usize) -> String {
    let mut end = text.len().min(max);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let shown: String = text[..end].escape_debug().collect();
    if end < text.len() {
        format!("{shown}... ({} bytes)", text.len())
    } else {
        shown
    }
}

/// [`excerpt_of`] at [`EXCERPT_BYTES`].
pub(crate) fn excerpt(text: &str) -> String {
    excerpt_of(text, EXCERPT_BYTES)
}

/// The longest name read from a file that a message shows.
const FILE_NAME_BYTES: usize = 40;

/// A name read from a file (a manifest key, a family, a format), as a message shows it: in
/// backquotes when it is a short identifier (letters, digits, `_`, `-`, `.`), otherwise only its
/// length. A file's other bytes are never quoted: a service passes its errors on, and a caller
/// who names a file that is not a bundle must not learn what the file holds.
pub(crate) fn file_name_shown(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
    if !text.is_empty() && text.len() <= FILE_NAME_BYTES && text.chars().all(plain) {
        format!("`{text}`")
    } else {
        format!("a text of {} bytes (not shown)", text.len())
    }
}

/// A JSON reader's message about a file's contents with the contents taken out: the value
/// found (`invalid type: string "…", expected …`) becomes its kind, and a key or variant
/// (``unknown field `…` ``) shows as [`file_name_shown`] does. Positions (line, column) and what
/// was expected (the schema's own names) stay.
pub(crate) fn json_error_shown(e: &serde_json::Error) -> String {
    let message = e.to_string();
    for lead in ["invalid type: ", "invalid value: ", "invalid length "] {
        if let Some(rest) = message.strip_prefix(lead) {
            let (found, after) = rest.split_once(", expected").unwrap_or((rest, ""));
            // The kind is what precedes the quoted value: `string`, `integer`, `map`, ...
            let kind = found.split(['"', '`', '\'']).next().unwrap_or("").trim();
            return format!("{lead}{kind}, expected{after}");
        }
    }
    for lead in ["unknown field `", "unknown variant `", "duplicate field `"] {
        if let Some(rest) = message.strip_prefix(lead) {
            if let Some((name, after)) = rest.split_once('`') {
                let what = &lead[..lead.len() - 2];
                return format!("{what} {}{after}", file_name_shown(name));
            }
        }
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excerpts_are_bounded_escaped_and_say_how_long_the_input_was() {
        assert_eq!(excerpt("Hips"), "Hips");
        assert_eq!(excerpt("a\0b\n\"c\""), "a\\0b\\n\\\"c\\\"");
        let long = "\0".repeat(1 << 20);
        let e = excerpt(&long);
        assert!(e.len() <= 4 * EXCERPT_BYTES + 32, "{}", e.len());
        assert!(e.ends_with("... (1048576 bytes)"), "{e}");
        // A cut never splits a character.
        let wide = "é".repeat(100);
        assert!(excerpt(&wide).starts_with(&"é".repeat(32)));
    }
}
