//! `troupe_model`: loading bundles and querying them.

use std::ffi::{c_char, CString};

use super::boundary::{
    self, non_null, troupe_status, FfiError, FfiResult, TROUPE_ERR_BUFFER_TOO_SMALL,
    TROUPE_ERR_SHAPE,
};
use crate::shared::logging::{log, Level};
use crate::Model;

/// A loaded bundle. Immutable and thread-safe: every function taking a `const troupe_model*`
/// may be called from any number of threads at once. Free it with `troupe_model_free`; sessions
/// created from it keep it alive, so it may be freed before them.
pub struct troupe_model {
    pub(crate) model: Model,
    /// The family's manifest name, NUL-terminated for C; it lives as long as the handle.
    family: CString,
    /// The names of the bundle's condition labels, NUL-terminated for C (the manifest refuses
    /// names holding NUL); they live as long as the handle.
    label_names: Vec<CString>,
    /// The graphs whose weights are not float32, by role, with their storage (`"int8"`),
    /// NUL-terminated for C; they live as long as the handle.
    reduced_precision: Vec<(CString, CString)>,
    /// A `magnet` bundle's released sampling configurations, by name, NUL-terminated for C.
    pub(crate) magnet_configs: Vec<CString>,
}

/// The condition a generation call was given: NULL with length 0 is the null condition
/// (`None`); anything else must be `condition_dim` readable floats (`TROUPE_ERR_SHAPE` names
/// both lengths otherwise).
///
/// # Safety
/// A non-NULL `condition` must be readable for `len` floats for the duration of the call.
pub(crate) unsafe fn optional_condition<'a>(
    model: &Model,
    condition: *const f32,
    len: usize,
) -> FfiResult<Option<&'a [f32]>> {
    if condition.is_null() && len == 0 {
        return Ok(None);
    }
    // SAFETY: forwarded contract.
    let c = unsafe { boundary::slice(condition, len, "condition") }?;
    if c.len() != model.condition_dim() {
        return Err(FfiError::new(
            TROUPE_ERR_SHAPE,
            format!(
                "condition_len is {}, the bundle's condition has {} floats",
                c.len(),
                model.condition_dim()
            ),
        ));
    }
    Ok(Some(c))
}

fn publish(model: Model, out: *mut *mut troupe_model) {
    log(Level::Info, "troupe::model", || {
        format!(
            "loaded bundle `{}` from {}",
            model.manifest().name,
            model.source().display()
        )
    });
    let label_names = model
        .condition_labels()
        .iter()
        .map(|l| CString::new(l.name.as_str()).unwrap_or_default())
        .collect();
    let reduced_precision = model
        .manifest()
        .reduced_precision_graphs()
        .into_iter()
        .map(|(role, weights)| {
            (
                CString::new(role).unwrap_or_default(),
                CString::new(weights.name()).unwrap_or_default(),
            )
        })
        .collect();
    let magnet_configs = model
        .magnet()
        .ok()
        .map(|m| {
            m.spec()
                .sampling
                .keys()
                .map(|name| CString::new(name.as_str()).unwrap_or_default())
                .collect()
        })
        .unwrap_or_default();
    let handle = troupe_model {
        family: CString::new(model.family()).unwrap_or_default(),
        model,
        label_names,
        reduced_precision,
        magnet_configs,
    };
    // SAFETY: `out` was checked non-NULL by the caller of `publish`.
    unsafe { *out = Box::into_raw(Box::new(handle)) };
}

/// Loads a bundle from `path` (UTF-8): a bundle directory, or an uncompressed tar archive of
/// one. Loading parses, validates and optimises every graph; it takes a fraction of a second.
///
/// On success `*out` receives a new handle owned by the caller (free with `troupe_model_free`);
/// on failure `*out` is set to NULL. `path` is borrowed for the call only.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (path or out NULL), `TROUPE_ERR_INVALID_ARG`
/// (path not UTF-8), `TROUPE_ERR_IO` (missing file), `TROUPE_ERR_MODEL` (corrupt or mismatched
/// bundle; the message names file, tensor and shape), `TROUPE_ERR_PANIC`. Thread-safe.
///
/// ```c
/// troupe_model *model = NULL;
/// if (troupe_model_load_file("onnx/bundles/armflow-tiny", &model) != TROUPE_OK)
///     fprintf(stderr, "%s\n", troupe_last_error_message());
/// ```
///
/// # Safety
/// `path` must be NUL-terminated; `out` must be writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_load_file(
    path: *const c_char,
    out: *mut *mut troupe_model,
) -> troupe_status {
    boundary::call(
        "troupe_model_load_file",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            publish(Model::load(path)?, out);
            Ok(())
        },
    )
}

/// Loads a bundle from memory: `data` holds `len` bytes of an uncompressed tar archive of a
/// bundle directory. The bytes are copied; `data` is borrowed for the call only.
///
/// Ownership of `*out`, statuses and threading as `troupe_model_load_file`.
///
/// # Safety
/// `data` must be readable for `len` bytes; `out` must be writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_load_memory(
    data: *const u8,
    len: usize,
    out: *mut *mut troupe_model,
) -> troupe_status {
    boundary::call(
        "troupe_model_load_memory",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: readable for `len` bytes per the contract.
            let bytes = unsafe { boundary::slice(data, len, "data") }?;
            publish(Model::from_archive_bytes(bytes, "<memory>")?, out);
            Ok(())
        },
    )
}

/// Releases the caller's reference to a model; the model itself lives on while sessions made
/// from it exist. NULL is a no-op. The handle must not be used afterwards.
///
/// # Safety
/// `model` must be NULL or a handle from `troupe_model_load_*` not freed before.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_free(model: *mut troupe_model) {
    if !model.is_null() {
        // SAFETY: a live handle created by Box::into_raw, freed once per the contract.
        boundary::get((), || drop(unsafe { Box::from_raw(model) }));
    }
}

/// Reads a property of a model; 0 for NULL.
pub(crate) fn property(model: Option<&troupe_model>, f: impl FnOnce(&Model) -> usize) -> usize {
    model.map_or(0, |m| boundary::get(0, || f(&m.model)))
}

/// The model's family as its manifest names it (`"armflow"`, `"umf"`, `"magnet"`, `"arflow"`):
/// which family's calls (`troupe_<family>_...`) it serves. NULL for NULL. The string is owned by
/// the model and valid until `troupe_model_free`; never free it. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_family(model: Option<&troupe_model>) -> *const c_char {
    model.map_or(std::ptr::null(), |m| m.family.as_ptr())
}

/// Floats per motion frame (262 for the `interhuman262` layout); 0 for NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_frame_dim(model: Option<&troupe_model>) -> usize {
    property(model, Model::frame_dim)
}

/// Writes the model's identity to `out` (32 bytes): the SHA-256 of its bundle's files as the
/// load read them, the same for a directory and a tar of it. Two processes hold the same model
/// exactly when their identities are equal; session snapshots carry it.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `out` writable for 32 bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_identity(
    model: Option<&troupe_model>,
    out: *mut u8,
) -> troupe_status {
    boundary::call(
        "troupe_model_identity",
        || {},
        || {
            non_null(out, "out")?;
            let identity = boundary::required(model, "model")?.model.identity();
            // SAFETY: checked non-NULL; writable for 32 bytes per the contract.
            unsafe { std::ptr::copy_nonoverlapping(identity.as_ptr(), out, identity.len()) };
            Ok(())
        },
    )
}

/// Frames per second of the motion; 0 for NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_fps(model: Option<&troupe_model>) -> usize {
    property(model, |m| m.fps() as usize)
}

/// Motion frames per generated token (reactor frames come out in multiples of it); 0 for NULL
/// and for a `umf` bundle. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_frames_per_token(model: Option<&troupe_model>) -> usize {
    property(model, Model::frames_per_token)
}

/// Algorithmic latency in frames: at worst, how many actor frames after frame t arrive before
/// reactor frame t is returned; 0 for NULL and for a `umf` bundle. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_latency_frames(model: Option<&troupe_model>) -> usize {
    property(model, Model::latency_frames)
}

/// Floats in the conditioning vector (`troupe_session_set_condition`, `troupe_umf_generate`);
/// 0 for NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_condition_dim(model: Option<&troupe_model>) -> usize {
    property(model, Model::condition_dim)
}

/// Named conditions the bundle was trained on (the demo model's partner rules `mirror`,
/// `follow`, `keep-away`); 0 for NULL and for bundles conditioned on free vectors. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_condition_label_count(model: Option<&troupe_model>) -> usize {
    model.map_or(0, |m| m.label_names.len())
}

/// The name of condition label `index` (`0 <= index < troupe_model_condition_label_count`), or
/// NULL for NULL or an index out of range. The string is owned by the model and valid until
/// `troupe_model_free`; never free it. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_condition_label(
    model: Option<&troupe_model>,
    index: usize,
) -> *const c_char {
    model
        .and_then(|m| m.label_names.get(index))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// Writes the conditioning vector of the label `label` (UTF-8, borrowed for the call) into
/// `condition[0 .. troupe_model_condition_dim)`, ready for `troupe_session_set_condition`,
/// `troupe_armflow_clip_generate` or `troupe_umf_generate`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no such label: the
/// message lists the bundle's labels; or `label` not UTF-8), `TROUPE_ERR_BUFFER_TOO_SMALL`
/// (`capacity` below the condition's length), `TROUPE_ERR_PANIC`. `condition` is untouched on
/// failure. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle; `label` NUL-terminated; `condition` writable for
/// `capacity` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_condition_for_label(
    model: Option<&troupe_model>,
    label: *const c_char,
    condition: *mut f32,
    capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_model_condition_for_label",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            // SAFETY: NUL-terminated per the contract.
            let label = unsafe { boundary::required_str(label, "label") }?;
            non_null(condition, "condition")?;
            let vector = model.condition_for(label)?;
            if capacity < vector.len() {
                return Err(FfiError::new(
                    TROUPE_ERR_BUFFER_TOO_SMALL,
                    format!(
                        "the condition needs {} floats, the buffer holds {capacity}",
                        vector.len()
                    ),
                ));
            }
            // SAFETY: non-NULL and writable for capacity >= vector.len() floats.
            unsafe { std::ptr::copy_nonoverlapping(vector.as_ptr(), condition, vector.len()) };
            Ok(())
        },
    )
}

/// How many of the bundle's graphs hold weights in reduced precision (a graph entry's
/// `"weights": "int8"`, checked against the file at load); 0 for a float32 bundle and for NULL.
/// Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_reduced_precision_count(
    model: Option<&troupe_model>,
) -> usize {
    model.map_or(0, |m| m.reduced_precision.len())
}

/// The role of reduced-precision graph `index` (`"context_layers"`, `"velocity"`, ...;
/// `0 <= index < troupe_model_reduced_precision_count`), or NULL for NULL or an index out of
/// range. Owned by the model and valid until `troupe_model_free`; never free it. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_reduced_precision_graph(
    model: Option<&troupe_model>,
    index: usize,
) -> *const c_char {
    model
        .and_then(|m| m.reduced_precision.get(index))
        .map_or(std::ptr::null(), |(role, _)| role.as_ptr())
}

/// How reduced-precision graph `index` stores its weights (`"int8"`), or NULL for NULL or an
/// index out of range. Owned by the model and valid until `troupe_model_free`; never free it.
/// Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_reduced_precision_weights(
    model: Option<&troupe_model>,
    index: usize,
) -> *const c_char {
    model
        .and_then(|m| m.reduced_precision.get(index))
        .map_or(std::ptr::null(), |(_, weights)| weights.as_ptr())
}

/// Floats per latent token (the length of injected noise vectors, per token); 0 for NULL.
/// Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_latent_dim(model: Option<&troupe_model>) -> usize {
    property(model, Model::latent_dim)
}

/// The most reactor frames one `troupe_session_step` call with `n_actor_frames` input frames can
/// return, whatever the session's state: size output buffers with it. 0 for NULL and for a
/// `umf` bundle. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_max_output_frames(
    model: Option<&troupe_model>,
    n_actor_frames: usize,
) -> usize {
    property(model, |m| m.max_output_frames(n_actor_frames))
}

/// Frames of motion per clip (0 for other bundles or NULL): per person of
/// `troupe_umf_generate` (`[people][clip_frames][frame_dim]`) for a `umf` bundle, of
/// `troupe_armflow_clip_generate` for an `armflow` bundle with an official clip. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_clip_frames(model: Option<&troupe_model>) -> usize {
    property(model, Model::clip_frames)
}
