//! Small validation helpers every layer uses: finite values in range, and manifest rules stated
//! as conditions with their messages.

use crate::shared::error::{Error, Result};
use crate::shared::limits::LIMITS;

/// Rejects NaN and infinities, naming the first offending value by `place` (its index in, its
/// place out).
fn finite_at(what: &str, values: &[f32], place: impl Fn(usize) -> String) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::InvalidInput(format!(
            "{what} holds a non-finite value ({}) at {}",
            values[i],
            place(i)
        ))),
    }
}

/// Checks values a caller passes in (motion features, conditions, noise): finite, and within
/// `±LIMITS.max_abs_input`, beyond which the networks' arithmetic overflows. Names the first
/// offending index.
pub(crate) fn check_input(what: &str, values: &[f32]) -> Result<()> {
    input_at(what, values, |i| format!("index {i}"))
}

/// [`check_input`] naming the offending value by `place`.
fn input_at(what: &str, values: &[f32], place: impl Fn(usize) -> String) -> Result<()> {
    finite_at(what, values, &place)?;
    let limit = LIMITS.max_abs_input as f32;
    match values.iter().position(|v| v.abs() > limit) {
        None => Ok(()),
        Some(i) => Err(Error::InvalidInput(format!(
            "{what} holds {:e} at {}, beyond troupe's limit of ±{limit:e}",
            values[i],
            place(i)
        ))),
    }
}

/// Checks one call's frames from a caller (`what`: "actor frames", "user frames"): a whole
/// number of `dim`-float frames, at most [`LIMITS`]`.max_frames_per_call` of them, every value
/// as [`check_input`] wants it (a bad one named by its frame and feature).
pub(crate) fn check_frames(what: &str, frames: &[f32], dim: usize) -> Result<()> {
    check_frame_count(what, frames, dim)?;
    input_at(what, frames, |i| {
        format!("frame {}, feature {}", i / dim, i % dim)
    })
}

/// [`check_frames`] without looking at the values: a whole number of `dim`-float frames, at most
/// [`LIMITS`]`.max_frames_per_call` of them (what a caller needs before counting frames, when
/// the values are checked where they are read).
pub(crate) fn check_frame_count(what: &str, frames: &[f32], dim: usize) -> Result<()> {
    if !frames.len().is_multiple_of(dim) {
        return Err(Error::InvalidInput(format!(
            "{} floats is not a whole number of {dim}-float frames",
            frames.len()
        )));
    }
    crate::shared::limits::at_most(
        &format!("{what} in one call"),
        (frames.len() / dim) as u64,
        LIMITS.max_frames_per_call,
        false,
    )
}

/// Checks values a network computed: a non-finite one (extreme inputs or settings overflowed the
/// arithmetic) fails the call with an [`Error::Inference`] naming `graph` and `what`.
pub(crate) fn check_output(graph: &'static str, what: &str, values: &[f32]) -> Result<()> {
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    check_output_counted(graph, what, bad, values.len())
}

/// [`check_output`] for values counted elsewhere: `bad` of `total` are not finite.
pub(crate) fn check_output_counted(
    graph: &'static str,
    what: &str,
    bad: usize,
    total: usize,
) -> Result<()> {
    if bad == 0 {
        return Ok(());
    }
    Err(Error::Inference {
        graph,
        message: format!(
            "{bad} of {total} values of the {what} are not finite (extreme inputs or settings \
             overflowed the network)"
        ),
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_beyond_the_limit_or_not_finite_are_named_by_index() {
        assert!(check_input("x", &[0.0, -1e6, 1e6, -0.0, 1e-40]).is_ok());
        let e = check_input("x", &[0.0, f32::MAX]).unwrap_err().to_string();
        assert!(e.contains("index 1") && e.contains("limit"), "{e}");
        let e = check_input("x", &[f32::NAN]).unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{e}");
    }
}
