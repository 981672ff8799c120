//! Small validation helpers every layer uses: finite inputs, and manifest rules stated as
//! conditions with their messages.

use crate::shared::error::{Error, Result};

/// Rejects NaN and infinities, naming the first offending index.
pub(crate) fn check_finite(what: &str, values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::InvalidInput(format!(
            "{what} holds a non-finite value ({}) at index {i}",
            values[i]
        ))),
    }
}

/// `Ok` when `ok`, else the message.
pub(crate) fn ensure(
    ok: bool,
    message: impl FnOnce() -> String,
) -> std::result::Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(message())
    }
}
