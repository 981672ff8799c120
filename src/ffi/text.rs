//! Text through the C ABI: prompts to conditions (`troupe_text_prompt_encode`, the bundle's own
//! tokenizer and CLIP text tower), and the text branch alone on CLIP features computed elsewhere
//! (`troupe_text_encode`). See `crate::shared::text`.

use std::ffi::c_char;

use ndarray::ArrayView2;

use crate::ffi::boundary::{self, non_null, troupe_status};
use crate::ffi::model::{property, troupe_model};

/// 1 if the bundle turns text prompts into conditions (`troupe_text_prompt_encode`): it carries
/// CLIP's text tower, its tokenizer and a text branch; 0 otherwise or for NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_takes_prompts(model: Option<&troupe_model>) -> usize {
    property(model, |m| usize::from(m.takes_prompts()))
}

/// Encodes a text prompt into the bundle's condition vector, as the official code does: the
/// prompt tokenized as CLIP tokenizes it (lower-cased, cleaned, byte-pair encoded, cut at 77
/// tokens), CLIP's text tower, then the family's text branch at the end-of-text token. The
/// empty prompt `""` gives the official "no text". Writes `troupe_model_condition_dim` floats to
/// `condition` (capacity `condition_capacity` floats). The last 64 prompts are cached, so asking
/// again is cheap. Nothing is written unless the call succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bundle that takes no
/// prompts, text that is not UTF-8 or longer than 64 KiB), `TROUPE_ERR_BUFFER_TOO_SMALL`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may encode on
/// one model at once.
///
/// # Safety
/// `model` must be a live handle; `prompt` a NUL-terminated string readable for the call;
/// `condition` writable for `condition_capacity` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_text_prompt_encode(
    model: Option<&troupe_model>,
    prompt: *const c_char,
    condition: *mut f32,
    condition_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_text_prompt_encode",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            // SAFETY: NUL-terminated and readable per the contract.
            let prompt = unsafe { boundary::required_str(prompt, "prompt") }?;
            non_null(condition, "condition")?;
            boundary::room(model.condition_dim(), condition_capacity, "the condition")?;
            let out = model.encode_prompt(prompt)?;
            // SAFETY: non-NULL, writable for condition_capacity >= condition_dim floats.
            unsafe { std::ptr::copy_nonoverlapping(out.as_ptr(), condition, out.len()) };
            Ok(())
        },
    )
}

/// Width of the CLIP token features `troupe_text_encode` reads (the bundle's CLIP width: the
/// condition dim of an official ARMFlow bundle, 768 for UMF as released); 0 for bundles without
/// a text branch, or NULL. Thread-safe.
///
/// # Safety
/// `model` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_model_text_token_dim(model: Option<&troupe_model>) -> usize {
    property(model, |m| m.text_token_dim().unwrap_or(0))
}

/// Runs the official text branch of a bundle that has one (`troupe_model_text_token_dim` > 0:
/// official ARMFlow and UMF bundles): CLIP's token features `clip_tokens`, row-major
/// `[n_tokens][text_token_dim]` (the output of CLIP's final LayerNorm for one prompt), and the
/// index of the end-of-text token (the argmax of CLIP's token ids) give the condition vector,
/// written to `condition` (capacity `condition_capacity` floats, at least
/// `troupe_model_condition_dim`). Inputs are borrowed; nothing is written unless the call
/// succeeds.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no text branch, no
/// tokens, index out of range, non-finite input), `TROUPE_ERR_BUFFER_TOO_SMALL`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `model` must be a live handle; `clip_tokens` readable for `n_tokens * text_token_dim` floats;
/// `condition` writable for `condition_capacity` floats and not overlapping `clip_tokens`.
#[no_mangle]
pub unsafe extern "C" fn troupe_text_encode(
    model: Option<&troupe_model>,
    clip_tokens: *const f32,
    n_tokens: usize,
    eot_index: usize,
    condition: *mut f32,
    condition_capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_text_encode",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            let (dim, width) = (model.condition_dim(), model.text_branch()?.token_dim);
            let n = boundary::checked_mul(n_tokens, width, "n_tokens * text_token_dim")?;
            // SAFETY: readable for `n` floats per the contract.
            let tokens = unsafe { boundary::slice(clip_tokens, n, "clip_tokens") }?;
            non_null(condition, "condition")?;
            boundary::room(dim, condition_capacity, "the condition")?;
            let view = ArrayView2::from_shape((n_tokens, width), tokens).expect("n floats");
            let out = model.encode_text(view, eot_index)?;
            // SAFETY: non-NULL, writable for condition_capacity >= dim floats.
            unsafe { std::ptr::copy_nonoverlapping(out.as_ptr(), condition, out.len()) };
            Ok(())
        },
    )
}
