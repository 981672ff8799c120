//! `troupe_limits`: the bounds every size from a file or a caller is checked against (see
//! `src/shared/limits.rs`), so that a host can validate its inputs the same way.

use crate::ffi::boundary::{self, check_struct_size, non_null, troupe_status, write_versioned};
use crate::shared::limits::{Limits, LIMITS};

/// troupe's limits, one value per build (`troupe::Limits` in Rust), inside `troupe_limits`. A
/// call given more than a limit fails, naming it, before anything is allocated.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_limit_values {
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

impl From<Limits> for troupe_limit_values {
    fn from(l: Limits) -> Self {
        Self {
            max_bundle_bytes: l.max_bundle_bytes,
            max_manifest_bytes: l.max_manifest_bytes,
            max_archive_members: l.max_archive_members,
            max_graph_nodes: l.max_graph_nodes,
            max_tensor_elements: l.max_tensor_elements,
            max_steps: l.max_steps,
            max_cfg_scale: l.max_cfg_scale,
            max_abs_input: l.max_abs_input,
            max_frames_per_call: l.max_frames_per_call,
            max_queued_noise_tokens: l.max_queued_noise_tokens,
            max_context_capacity: l.max_context_capacity,
            max_people: l.max_people,
            max_text_tokens: l.max_text_tokens,
            max_manifest_dim: l.max_manifest_dim,
            max_prompt_bytes: l.max_prompt_bytes,
            max_compute_threads: l.max_compute_threads,
        }
    }
}

/// troupe's limits, for `troupe_limits_get`. A call given more than a limit fails with
/// `TROUPE_ERR_INVALID_ARG` (a caller's value) or `TROUPE_ERR_MODEL` / `TROUPE_ERR_IO` (a
/// bundle's), naming the limit, before anything is allocated. Fields are only ever appended.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_limits {
    /// `sizeof(troupe_limits)` as the caller compiled it (set by `troupe_limits_get`).
    pub struct_size: u32,
    /// Always 0.
    pub reserved: u32,
    /// The limits.
    pub values: troupe_limit_values,
}

const LIMITS_V1_SIZE: usize = 8 + std::mem::size_of::<troupe_limit_values>();
// No padding, so copying its bytes copies only initialised fields.
const _: () = assert!(std::mem::size_of::<troupe_limits>() == LIMITS_V1_SIZE);

/// Writes troupe's limits to `out` (pass `sizeof(troupe_limits)` as `size`; the library writes
/// only that many bytes, zeroing fields it does not know).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`size` smaller than the
/// first version of the struct). Thread-safe.
///
/// # Safety
/// `out` must be writable for `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_limits_get(out: *mut troupe_limits, size: usize) -> troupe_status {
    boundary::call(
        "troupe_limits_get",
        || {},
        || {
            non_null(out, "out")?;
            check_struct_size(size, LIMITS_V1_SIZE, "troupe_limits")?;
            let value = troupe_limits {
                struct_size: size as u32,
                reserved: 0,
                values: LIMITS.into(),
            };
            // SAFETY: writable for `size` bytes per the contract; no padding (asserted above).
            unsafe { write_versioned(out, size, &value) };
            Ok(())
        },
    )
}
