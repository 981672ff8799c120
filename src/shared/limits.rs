//! Every size troupe accepts from a file or a caller, bounded in one place.
//!
//! Rust aborts the process when an allocation fails, and `catch_unwind` cannot stop an abort: a
//! size read from a bundle or passed by a caller must therefore be checked *before* anything is
//! allocated for it. Each check below names the limit it enforces, and [`LIMITS`] is what
//! `troupe_limits` reports to C callers, so a host can validate its own inputs the same way.

use crate::shared::error::{Error, Result};

/// troupe's limits, one value per build (`troupe_limit_values` in C, inside `troupe_limits`). A
/// call given more than a limit fails, naming it, before anything is allocated.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Bytes of a whole bundle: the archive file or memory, or the sum of a directory bundle's
    /// files. The paper-size ARMFlow bundle is about 200 MB.
    pub max_bundle_bytes: u64,
    /// Bytes of `troupe.json`.
    pub max_manifest_bytes: u64,
    /// Members of a tar bundle (graphs, manifest, directories).
    pub max_archive_members: u64,
    /// Nodes of one ONNX graph.
    pub max_graph_nodes: u64,
    /// Elements of any one tensor a graph declares or would build from constants.
    pub max_tensor_elements: u64,
    /// Solver steps per token or per stage (MeanFlow, Euler, RK4).
    pub max_steps: u64,
    /// Magnitude of a classifier-free guidance scale.
    pub max_cfg_scale: u64,
    /// Magnitude of a motion feature or conditioning value a caller passes in.
    pub max_abs_input: u64,
    /// Motion frames passed to one call (a step, a clip, an encoding).
    pub max_frames_per_call: u64,
    /// Tokens of noise queued on a session and not yet used.
    pub max_queued_noise_tokens: u64,
    /// Tokens kept in a session's context cache.
    pub max_context_capacity: u64,
    /// People in one generated group.
    pub max_people: u64,
    /// Text tokens passed to the text branch: CLIP's context, the most its text tower makes.
    pub max_text_tokens: u64,
    /// Any integer a manifest declares outside `producer` (layers, heads, dimensions, token and
    /// frame counts, steps).
    pub max_manifest_dim: u64,
    /// Bytes of UTF-8 in one text prompt (a few hundred make 77 CLIP tokens; the rest is cut).
    pub max_prompt_bytes: u64,
    /// Threads of the compute pool (`troupe_set_compute_threads`).
    pub max_compute_threads: u64,
}

/// The limits of this build.
pub const LIMITS: Limits = Limits {
    max_bundle_bytes: 2 << 30,
    max_manifest_bytes: 16 << 20,
    max_archive_members: 1024,
    max_graph_nodes: 1 << 20,
    max_tensor_elements: 1 << 30,
    max_steps: 10_000,
    max_cfg_scale: 1000,
    max_abs_input: 1_000_000,
    max_frames_per_call: 1 << 20,
    max_queued_noise_tokens: 1 << 16,
    max_context_capacity: 1 << 16,
    max_people: 256,
    max_text_tokens: 77,
    max_manifest_dim: 1 << 16,
    max_prompt_bytes: 1 << 16,
    max_compute_threads: 1024,
};

/// `Ok` when `value <= limit`, else an [`Error::InvalidOption`] or [`Error::InvalidInput`]
/// (`option` chooses) naming what and the limit.
pub(crate) fn at_most(what: &str, value: u64, limit: u64, option: bool) -> Result<()> {
    if value <= limit {
        return Ok(());
    }
    let message = format!("{what} is {value}, above troupe's limit of {limit}");
    Err(if option {
        Error::InvalidOption(message)
    } else {
        Error::InvalidInput(message)
    })
}

/// Solver steps (per token or per stage): at least 1, at most `LIMITS.max_steps`.
pub(crate) fn check_steps(what: &str, steps: u32) -> Result<()> {
    if steps == 0 {
        return Err(Error::InvalidOption(format!("{what} must be at least 1")));
    }
    at_most(what, steps.into(), LIMITS.max_steps, true)
}

/// A CFG scale must be finite and within `±LIMITS.max_cfg_scale`: beyond, the guided velocity
/// overflows.
pub(crate) fn check_cfg(scale: f32) -> Result<()> {
    let limit = LIMITS.max_cfg_scale as f32;
    if !scale.is_finite() || scale.abs() > limit {
        return Err(Error::InvalidOption(format!(
            "CFG scale must be finite and within ±{limit}, got {scale:e}"
        )));
    }
    Ok(())
}

/// The product of `factors`, or a message naming `what` when it overflows or passes `limit`.
pub(crate) fn product_at_most(
    what: &str,
    factors: &[u64],
    limit: u64,
) -> std::result::Result<u64, String> {
    let product = factors
        .iter()
        .try_fold(1u64, |acc, &f| acc.checked_mul(f))
        .filter(|&p| p <= limit);
    product.ok_or_else(|| {
        format!(
            "{what} ({}) is above troupe's limit of {limit}",
            factors
                .iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(" x ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_that_overflow_or_pass_the_limit_are_refused() {
        assert_eq!(product_at_most("p", &[2, 3], 6).unwrap(), 6);
        assert!(product_at_most("p", &[2, 4], 6).is_err());
        assert!(product_at_most("p", &[u64::MAX, 2], u64::MAX).is_err());
        let most = LIMITS.max_steps;
        assert!(at_most("steps", most + 1, most, true).is_err());
        assert!(at_most("steps", most, most, true).is_ok());
        assert!(check_steps("steps", 0).is_err() && check_steps("steps", 10_000).is_ok());
        assert!(check_cfg(f32::MAX).is_err() && check_cfg(-1000.0).is_ok());
    }
}
