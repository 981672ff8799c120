//! `troupe_session`: one stream, whatever the family: an ARMFlow reactor to an actor, a MAGNet
//! live partner to a user, or ARFlow's online stream (`src/family/session.rs`). What only one
//! family's stream takes lives in that family's module (`ffi/armflow/`, `ffi/magnet/`,
//! `ffi/arflow/`) and is refused with `TROUPE_ERR_UNSUPPORTED` on another family's session.

use std::ffi::c_char;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::ffi::boundary::{
    self, check_struct_size, checked_mul, non_null, read_versioned, troupe_status, write_versioned,
    Exclusive, FfiError, FfiResult, TROUPE_ERR_BUFFER_TOO_SMALL, TROUPE_ERR_INVALID_ARG,
    TROUPE_ERR_POISONED, TROUPE_ERR_SHAPE, TROUPE_ERR_UNSUPPORTED,
};
use crate::ffi::model::troupe_model;
use crate::{ActorLatent, Capability, Model, ReactorOptions, Session, SessionOptions};

/// Actor tokens are the VAE posterior sample `(mean + std * noise) * scale` (the official choice).
pub const TROUPE_ACTOR_LATENT_SAMPLE: i32 = 0;
/// Actor tokens are the posterior mean: no actor noise is drawn.
pub const TROUPE_ACTOR_LATENT_MEAN: i32 = 1;

/// The C code of an actor latent choice.
pub(crate) fn actor_latent_code(latent: ActorLatent) -> i32 {
    match latent {
        ActorLatent::Sample => TROUPE_ACTOR_LATENT_SAMPLE,
        ActorLatent::Mean => TROUPE_ACTOR_LATENT_MEAN,
    }
}

/// The actor latent choice a C code names, or `TROUPE_ERR_INVALID_ARG` naming `field`.
pub(crate) fn actor_latent_of(code: i32, field: &str) -> FfiResult<ActorLatent> {
    match code {
        TROUPE_ACTOR_LATENT_SAMPLE => Ok(ActorLatent::Sample),
        TROUPE_ACTOR_LATENT_MEAN => Ok(ActorLatent::Mean),
        other => Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("{field} {other} is neither TROUPE_ACTOR_LATENT_SAMPLE nor _MEAN"),
        )),
    }
}

/// Options every stream takes at its start. Fill with `troupe_session_options_init`, then change
/// fields. Fields are only ever appended; `struct_size` tells the library which version the
/// caller has. A family's own options go in its own struct (`troupe_armflow_session_options`);
/// `cfg_scale` and `actor_latent` are ARMFlow's, kept here (deprecated since 0.2) so that 0.1
/// programs keep their layout: `troupe_session_new` still reads them, and
/// `troupe_armflow_session_new` does not.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_session_options {
    /// `sizeof(troupe_session_options)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// Sampler steps, >= 1: MeanFlow steps per token (armflow), DDIM steps per chunk (magnet).
    pub steps: u32,
    /// Seed of the portable noise generator: equal seeds give bit-identical motion everywhere.
    pub seed: u64,
    /// Deprecated since 0.2 (use `troupe_armflow_session_options.cfg_scale`): an ARMFlow
    /// stream's classifier-free guidance scale, finite; another family's session takes 1.
    pub cfg_scale: f32,
    /// armflow: tokens kept in the context cache, `<sos>` included, >= 2; older ones slide out.
    /// magnet: context tokens per window (1 to window - 1; the window advances by the rest).
    pub context_capacity: u32,
    /// Deprecated since 0.2 (use `troupe_armflow_session_options.actor_latent`):
    /// `TROUPE_ACTOR_LATENT_SAMPLE` or `_MEAN` for an ARMFlow stream; another family's session
    /// takes `_SAMPLE`.
    pub actor_latent: i32,
    /// Must be 0.
    pub reserved: u32,
}

/// One stream. A session is used from one thread at a time (it may move between threads);
/// distinct sessions run fully in parallel. A call on a session that another thread is using
/// fails with `TROUPE_ERR_BUSY` instead of racing.
pub struct troupe_session {
    session: Exclusive<Session>,
    /// Set by a panic inside a call; cleared by `troupe_session_reset`.
    poisoned: AtomicBool,
}

impl troupe_session {
    /// A new handle owning `session`, for the caller to free with `troupe_session_free`.
    pub(crate) fn into_raw(session: Session) -> *mut troupe_session {
        Box::into_raw(Box::new(troupe_session {
            session: Exclusive::new(session),
            poisoned: AtomicBool::new(false),
        }))
    }
}

/// The family's own stream behind a session, or `TROUPE_ERR_UNSUPPORTED` saying that `what` is
/// for `needed` streams only.
pub(crate) fn family_stream<'a, S: 'static>(
    session: &'a mut Session,
    needed: &str,
    what: &str,
) -> FfiResult<&'a mut S> {
    let family = session.family();
    session.family_mut::<S>().map_err(|_| {
        let article = crate::shared::error::a_or_an(family);
        FfiError::new(
            TROUPE_ERR_UNSUPPORTED,
            format!("{what}: only {needed} streams take this; this session runs {article} `{family}` model"),
        )
    })
}

/// `sizeof(troupe_session_options)` in this library, for bindings to check their mirror.
#[no_mangle]
pub extern "C" fn troupe_session_options_size() -> usize {
    std::mem::size_of::<troupe_session_options>()
}

/// The size of the first published `troupe_session_options`; smaller structs are rejected.
const OPTIONS_V1_SIZE: usize = 32;
// Version 1 has no padding, so copying its bytes copies only initialised fields.
const _: () = assert!(std::mem::size_of::<troupe_session_options>() == OPTIONS_V1_SIZE);

/// Fills `options` with the defaults of `model`'s bundle (sampler steps, CFG scale, context
/// capacity, actor latent) and seed 0, and sets `struct_size`. Pass
/// `sizeof(troupe_session_options)` as `options_size`: the library writes only that many bytes
/// (zeroing fields it does not know), so callers built against an older or newer header are safe.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, or `TROUPE_ERR_INVALID_ARG` when `options_size`
/// is smaller than the first version of the struct. Thread-safe.
///
/// ```c
/// troupe_session_options opt;
/// troupe_session_options_init(model, &opt, sizeof opt);
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` must be writable for `options_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_options_init(
    model: Option<&troupe_model>,
    options: *mut troupe_session_options,
    options_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_session_options_init",
        || {},
        || {
            let model = &boundary::required(model, "model")?.model;
            non_null(options, "options")?;
            check_struct_size(options_size, OPTIONS_V1_SIZE, "troupe_session_options")?;
            let defaults = option_defaults(model, options_size)?;
            // SAFETY: writable for `options_size` bytes per the contract; the struct has no
            // padding (asserted above).
            unsafe { write_versioned(options, options_size, &defaults) };
            Ok(())
        },
    )
}

/// The options `troupe_session_options_init` writes for `model`: the bundle's defaults (an
/// ARMFlow bundle's CFG scale and actor latent; 1 and the sample for the others).
fn option_defaults(model: &Model, size: usize) -> FfiResult<troupe_session_options> {
    let common = model.session_defaults()?;
    let (cfg_scale, actor_latent) = match model.armflow() {
        Ok(a) => (a.spec().sampler.cfg_scale, a.spec().sampler.actor_latent),
        Err(_) => (1.0, ActorLatent::Sample),
    };
    let clamp = |v: usize| v.min(u32::MAX as usize) as u32;
    Ok(troupe_session_options {
        struct_size: size as u32,
        steps: common.steps.unwrap_or(1),
        seed: common.seed,
        cfg_scale,
        context_capacity: clamp(common.context_capacity.unwrap_or(0)),
        actor_latent: actor_latent_code(actor_latent),
        reserved: 0,
    })
}

/// Reads the caller's options (an older caller's missing fields: the bundle's defaults; a newer
/// caller's extra fields must be zero).
///
/// # Safety
/// `options` must be readable for `struct_size` bytes.
unsafe fn read_raw(
    model: &Model,
    options: *const troupe_session_options,
) -> FfiResult<troupe_session_options> {
    // SAFETY: readable for its `struct_size` per the contract.
    let o = unsafe {
        read_versioned(
            options,
            OPTIONS_V1_SIZE,
            || option_defaults(model, OPTIONS_V1_SIZE),
            "options",
            "troupe_session_options_init",
        )
    }?;
    if o.reserved != 0 {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            "options.reserved must be 0",
        ));
    }
    Ok(o)
}

/// What every stream takes of `o`.
fn common_of(o: &troupe_session_options) -> SessionOptions {
    SessionOptions {
        seed: o.seed,
        steps: Some(o.steps),
        context_capacity: Some(o.context_capacity as usize),
    }
}

/// Reads what every stream takes of the caller's options; the deprecated ARMFlow fields are
/// not read (a family's own call takes its own struct).
///
/// # Safety
/// `options` must be readable for `struct_size` bytes.
pub(crate) unsafe fn read_common_options(
    model: &Model,
    options: *const troupe_session_options,
) -> FfiResult<SessionOptions> {
    // SAFETY: forwarded contract.
    Ok(common_of(&unsafe { read_raw(model, options) }?))
}

/// Reads the caller's options for `troupe_session_new`, the deprecated ARMFlow fields too.
///
/// # Safety
/// `options` must be readable for `struct_size` bytes.
unsafe fn read_options(
    model: &Model,
    options: *const troupe_session_options,
) -> FfiResult<CallerOptions> {
    // SAFETY: forwarded contract.
    let o = unsafe { read_raw(model, options) }?;
    Ok(CallerOptions {
        common: common_of(&o),
        cfg_scale: o.cfg_scale,
        actor_latent: actor_latent_of(o.actor_latent, "options.actor_latent")?,
    })
}

/// `troupe_session_options` as read: what every stream takes, and ARMFlow's two fields.
struct CallerOptions {
    common: SessionOptions,
    cfg_scale: f32,
    actor_latent: ActorLatent,
}

impl CallerOptions {
    /// Opens `model`'s stream. ARMFlow takes every field; another family refuses a CFG scale
    /// other than 1 and the actor's posterior mean, which it cannot honour.
    fn open(self, model: &Model) -> FfiResult<Session> {
        if let Ok(armflow) = model.armflow() {
            let reactor = armflow.reactor(ReactorOptions {
                cfg_scale: Some(self.cfg_scale),
                actor_latent: Some(self.actor_latent),
                ..self.common.into()
            })?;
            return Ok(reactor.into());
        }
        if self.cfg_scale != 1.0 || self.actor_latent != ActorLatent::Sample {
            return Err(FfiError::new(
                TROUPE_ERR_UNSUPPORTED,
                format!(
                    "options.cfg_scale {} or options.actor_latent MEAN: only armflow streams take \
                     them; this is {} `{}` model",
                    self.cfg_scale,
                    crate::shared::error::a_or_an(model.family()),
                    model.family()
                ),
            ));
        }
        Ok(model.session(self.common)?)
    }
}

/// Starts a stream on `model` with `options` (NULL: the bundle's defaults). On an `armflow`
/// model the session answers an actor with the reactor, starting with the null condition (set
/// one with `troupe_session_set_condition`); `troupe_armflow_session_new` opens one with
/// ARMFlow's own options. On a two-person `magnet` model it answers a user
/// with the live partner (its `motion_control_live` configuration); give the partner's opening
/// frames with `troupe_magnet_session_set_partner_opening` before the first step.
///
/// On success `*out` receives a new handle owned by the caller (free with
/// `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad option values or
/// `struct_size`), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe with respect to
/// `model`: sessions may be created from many threads at once.
///
/// ```c
/// troupe_session_options opt;
/// troupe_session_options_init(model, &opt, sizeof opt);
/// opt.seed = 42;
/// troupe_session *session = NULL;
/// troupe_status st = troupe_session_new(model, &opt, &session);
/// ```
///
/// # Safety
/// `model` must be a live handle; `options` NULL or readable for its `struct_size`; `out`
/// writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_new(
    model: Option<&troupe_model>,
    options: *const troupe_session_options,
    out: *mut *mut troupe_session,
) -> troupe_status {
    boundary::call(
        "troupe_session_new",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let model = &boundary::required(model, "model")?.model;
            let session = if options.is_null() {
                model.session(SessionOptions::default())?
            } else {
                // SAFETY: readable per the contract.
                unsafe { read_options(model, options) }?.open(model)?
            };
            // SAFETY: checked non-NULL above.
            unsafe { *out = troupe_session::into_raw(session) };
            Ok(())
        },
    )
}

/// Frees a session. NULL is a no-op. The handle must not be used afterwards. A session that
/// another thread is using at that moment is not freed (that would free memory in use): the
/// call logs an error and leaks it.
///
/// # Safety
/// `session` must be NULL or a handle from `troupe_session_new` not freed before.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_free(session: *mut troupe_session) {
    // SAFETY: forwarded contract.
    unsafe { boundary::free_unless_busy(session, |h| &h.session, "troupe_session_free") }
}

/// Runs `body` on a live session: NULL, busy and poison checks, panic capture (which poisons).
///
/// # Safety
/// `session` must be NULL or a live handle.
pub(crate) unsafe fn with_session(
    session: *mut troupe_session,
    name: &'static str,
    body: impl FnOnce(&mut Session) -> FfiResult,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe { run_on_session(session, name, false, body) }
}

/// [`with_session`]; `reset` clears the poison of an earlier panic instead of refusing.
///
/// # Safety
/// As [`with_session`].
unsafe fn run_on_session(
    session: *mut troupe_session,
    name: &'static str,
    reset: bool,
    body: impl FnOnce(&mut Session) -> FfiResult,
) -> troupe_status {
    // SAFETY: NULL or a live handle per the contract; shared access only until claimed.
    let Some(handle) = (unsafe { session.as_ref() }) else {
        return boundary::call(name, || {}, || non_null(session, "session"));
    };
    boundary::call(
        name,
        || handle.poisoned.store(true, Ordering::Relaxed),
        || {
            let mut session = handle.session.claim("the session")?;
            if reset {
                handle.poisoned.store(false, Ordering::Relaxed);
            } else if handle.poisoned.load(Ordering::Relaxed) {
                return Err(FfiError::new(
                    TROUPE_ERR_POISONED,
                    "the session panicked earlier; call troupe_session_reset",
                ));
            }
            body(&mut session)
        },
    )
}

/// Feeds `n_actor_frames` actor frames (`actor`: row-major float32
/// `[n_actor_frames][frame_dim]`, borrowed for the call; may be NULL when `n_actor_frames` is 0)
/// and writes the reactor frames that became ready into `out` (capacity `out_capacity_frames`
/// frames of `frame_dim` floats), their count into `*n_written`. Any number of frames may be
/// fed per call; reactor frames come in multiples of `troupe_model_frames_per_token`.
/// `troupe_model_max_output_frames(model, n)` frames always suffice, and
/// `troupe_session_output_frames` gives the exact count. No allocation is handed to the caller.
///
/// On any error nothing is written and the session is exactly as before the call, except after
/// `TROUPE_ERR_PANIC`, which poisons it.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a NaN or infinite
/// value; the message gives its index), `TROUPE_ERR_BUFFER_TOO_SMALL` (the message says how many
/// frames are needed), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
/// thread at a time per session.
///
/// ```c
/// float reactor[4 * 262];
/// size_t n = 0;
/// troupe_status st = troupe_session_step(session, frame, 1, reactor, 4, &n);
/// ```
///
/// # Safety
/// `session` must be a live handle; `actor` readable for `n_actor_frames * frame_dim` floats;
/// `out` writable for `out_capacity_frames * frame_dim` floats and not overlapping `actor`;
/// `n_written` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_step(
    session: *mut troupe_session,
    actor: *const f32,
    n_actor_frames: usize,
    out: *mut f32,
    out_capacity_frames: usize,
    n_written: *mut usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_step", |s| {
            non_null(n_written, "n_written")?;
            let dim = s.frame_dim();
            let n_in = checked_mul(n_actor_frames, dim, "n_actor_frames * frame_dim")?;
            let actor = boundary::slice(actor, n_in, "actor")?;
            // The room for the frames is checked by the session's step, the only place that does.
            if out.is_null() && s.frames_ready_after(n_actor_frames) > 0 {
                non_null(out, "out")?;
            }
            let output = s.step_bounded(actor, out_capacity_frames)?;
            let frames = output.frames.as_slice().expect("standard layout");
            if !frames.is_empty() {
                // `out` is non-NULL (checked above: frames.len() == ready * dim > 0) and holds
                // out_capacity_frames >= ready frames per the contract.
                std::ptr::copy_nonoverlapping(frames.as_ptr(), out, frames.len());
            }
            *n_written = frames.len() / dim;
            Ok(())
        })
    }
}

/// Advances `n_sessions` sessions of one model in one call, reading the model's weights once
/// per token for all of them rather than once per session: the way to run a crowd. For each
/// `i < n_sessions`, `actor[i]` holds `n_actor_frames[i]` frames for `sessions[i]` (row-major
/// float32, borrowed; may be NULL when the count is 0), and the reactor frames that became ready
/// go to `out[i]` (capacity `out_capacity_frames[i]` frames; may be NULL when none are ready),
/// their count to `n_written[i]`. Each session's result equals what `troupe_session_step` gives
/// it alone, up to float rounding (1e-5). Sessions may differ in every option and in how many
/// frames they are given (0 included), but must share one model and appear once each.
///
/// On any error nothing is written and every session is exactly as before the call, except after
/// `TROUPE_ERR_PANIC`, which poisons every session of the call. Messages name the session index.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a session listed twice,
/// sessions of different models, a NaN or infinite value), `TROUPE_ERR_BUFFER_TOO_SMALL`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. The sessions must not be
/// used by another thread during the call; the arrays are borrowed for the call.
///
/// ```c
/// troupe_session *crowd[64]; const float *in[64]; size_t n_in[64];
/// float *out[64]; size_t cap[64], n_out[64];
/// troupe_status st = troupe_sessions_step(crowd, 64, in, n_in, out, cap, n_out);
/// ```
///
/// # Safety
/// Each array must be readable (`n_written` writable) for `n_sessions` entries (any may be NULL
/// when `n_sessions` is 0); `sessions[i]` live handles; `actor[i]` readable for
/// `n_actor_frames[i] * frame_dim` floats; `out[i]` writable for `out_capacity_frames[i] *
/// frame_dim` floats, overlapping no other buffer of the call.
#[no_mangle]
pub unsafe extern "C" fn troupe_sessions_step(
    sessions: *const *mut troupe_session,
    n_sessions: usize,
    actor: *const *const f32,
    n_actor_frames: *const usize,
    out: *const *mut f32,
    out_capacity_frames: *const usize,
    n_written: *mut usize,
) -> troupe_status {
    let handles: &[*mut troupe_session] = if n_sessions == 0 || sessions.is_null() {
        &[]
    } else {
        // SAFETY: readable for n_sessions entries per the contract.
        unsafe { std::slice::from_raw_parts(sessions, n_sessions) }
    };
    let poison_all = || {
        for &h in handles {
            // SAFETY: NULL or live handles per the contract; only the atomic flag is touched.
            if let Some(handle) = unsafe { h.as_ref() } {
                handle.poisoned.store(true, Ordering::Relaxed);
            }
        }
    };
    boundary::call("troupe_sessions_step", poison_all, || {
        if n_sessions == 0 {
            return Ok(());
        }
        // SAFETY (all four): readable (writable) for n_sessions entries per the contract.
        let (actor, n_actor_frames, out, capacity) = unsafe {
            (
                boundary::slice(actor, n_sessions, "actor")?,
                boundary::slice(n_actor_frames, n_sessions, "n_actor_frames")?,
                boundary::slice(out, n_sessions, "out")?,
                boundary::slice(out_capacity_frames, n_sessions, "out_capacity_frames")?,
            )
        };
        non_null(sessions, "sessions")?;
        non_null(n_written, "n_written")?;
        let mut seen: Vec<(usize, usize)> = handles.iter().map(|&h| h as usize).zip(0..).collect();
        seen.sort_unstable();
        for pair in seen.windows(2) {
            if pair[0].0 == pair[1].0 {
                return Err(FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    format!(
                        "sessions[{}] and sessions[{}] are the same session",
                        pair[0].1.min(pair[1].1),
                        pair[0].1.max(pair[1].1)
                    ),
                ));
            }
        }
        let mut claims = Vec::with_capacity(n_sessions);
        for (i, &h) in handles.iter().enumerate() {
            non_null(h, &format!("sessions[{i}]"))?;
            // SAFETY: a live handle per the contract; shared access only until claimed. Each
            // handle appears once (checked above), so the claims are of distinct sessions.
            let handle = unsafe { &*h };
            claims.push(handle.session.claim(&format!("sessions[{i}]"))?);
            if handle.poisoned.load(Ordering::Relaxed) {
                return Err(FfiError::new(
                    TROUPE_ERR_POISONED,
                    format!("sessions[{i}] panicked earlier; call troupe_session_reset"),
                ));
            }
        }
        let mut live: Vec<&mut Session> = claims.iter_mut().map(|c| &mut **c).collect();
        let dim = live[0].frame_dim();
        let mut chunks = Vec::with_capacity(n_sessions);
        for i in 0..n_sessions {
            let n_in = checked_mul(n_actor_frames[i], dim, "n_actor_frames[i] * frame_dim")?;
            // SAFETY: readable for n_in floats per the contract.
            chunks.push(unsafe { boundary::slice(actor[i], n_in, &format!("actor[{i}]"))? });
            if out[i].is_null() && live[i].frames_ready_after(n_actor_frames[i]) > 0 {
                non_null(out[i], &format!("out[{i}]"))?;
            }
        }
        let outputs = crate::family::session::step_sessions_bounded(&mut live, &chunks, capacity)?;
        for (i, output) in outputs.iter().enumerate() {
            let frames = output.frames.as_slice().expect("standard layout");
            if !frames.is_empty() {
                // SAFETY: out[i] is non-NULL (checked: frames were ready) and holds
                // out_capacity_frames[i] >= frames.len() / dim frames per the contract.
                unsafe { std::ptr::copy_nonoverlapping(frames.as_ptr(), out[i], frames.len()) };
            }
            // SAFETY: writable for n_sessions entries per the contract.
            unsafe { *n_written.add(i) = frames.len() / dim };
        }
        Ok(())
    })
}

/// Writes to `*n_frames` exactly how many reactor frames a `troupe_session_step` with
/// `n_actor_frames` frames would return now.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
/// thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `n_frames` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_output_frames(
    session: *mut troupe_session,
    n_actor_frames: usize,
    n_frames: *mut usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_output_frames", |s| {
            non_null(n_frames, "n_frames")?;
            *n_frames = s.frames_ready_after(n_actor_frames);
            Ok(())
        })
    }
}

/// Saves everything the stream needs to go on (its settings, caches, pending frames, noise
/// position) as bytes: `troupe_session_restore` on the same model, in this process or another,
/// gives a session whose steps are this one's bit for bit. The format is versioned, checksummed
/// and bound to the model (`troupe_model_identity`). The session is unchanged.
///
/// Writes the snapshot's size to `*needed`, and the snapshot to `buf` when `capacity` holds it.
/// Call with `buf` NULL and `capacity` 0 to learn the size (it changes when the session steps
/// or its settings change), then with a buffer that size.
///
/// Returns `TROUPE_OK` (also for the size query), `TROUPE_ERR_NULL_ARG` (`needed` NULL, or `buf`
/// NULL with a non-zero capacity), `TROUPE_ERR_BUFFER_TOO_SMALL` (nothing written but
/// `*needed`), `TROUPE_ERR_UNSUPPORTED` (a family whose streams cannot be saved yet),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// ```c
/// size_t size = 0;
/// troupe_session_snapshot(session, NULL, 0, &size);
/// uint8_t *bytes = malloc(size);
/// troupe_status st = troupe_session_snapshot(session, bytes, size, &size);
/// ```
///
/// # Safety
/// `session` must be a live handle; `buf` writable for `capacity` bytes; `needed` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_snapshot(
    session: *mut troupe_session,
    buf: *mut u8,
    capacity: usize,
    needed: *mut usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_snapshot", |s| {
            non_null(needed, "needed")?;
            if capacity > 0 {
                non_null(buf, "buf")?;
            }
            hand_over(&s.snapshot()?, "the snapshot", buf, capacity, needed)
        })
    }
}

/// Writes `bytes.len()` to `*needed` and, unless this is a size query (`buf` NULL, `capacity`
/// 0), `bytes` to `buf`: `TROUPE_ERR_BUFFER_TOO_SMALL` when they do not fit.
///
/// # Safety
/// `needed` writable; `buf` NULL or writable for `capacity` bytes.
unsafe fn hand_over(
    bytes: &[u8],
    what: &str,
    buf: *mut u8,
    capacity: usize,
    needed: *mut usize,
) -> FfiResult<()> {
    // SAFETY: writable per the contract.
    unsafe { *needed = bytes.len() };
    if buf.is_null() && capacity == 0 {
        return Ok(());
    }
    if capacity < bytes.len() {
        return Err(FfiError::new(
            TROUPE_ERR_BUFFER_TOO_SMALL,
            format!(
                "{what} needs {} bytes, the buffer holds {capacity}",
                bytes.len()
            ),
        ));
    }
    // SAFETY: `buf` holds `capacity >= bytes.len()` bytes, per the contract.
    unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), buf, bytes.len()) };
    Ok(())
}

/// Seals a snapshot (`snapshot`, `len` bytes, from `troupe_session_snapshot`) under `key`
/// (`key_len` bytes, at least 16, kept secret by the caller): an HMAC-SHA-256 tag that only a
/// holder of the key can make, for snapshot stores that others can write. Restore it with
/// `troupe_session_restore_sealed` and the same key; another key, or any changed byte, is
/// refused there. The layout is in `docs/SNAPSHOTS.md`.
///
/// Writes the sealed size (`len` + 44) to `*needed`, and the sealed snapshot to `buf` when
/// `capacity` holds it (`buf` NULL and `capacity` 0: the size only). Returns `TROUPE_OK`,
/// `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a key under 16 bytes, or bytes that are not
/// a snapshot), `TROUPE_ERR_BUFFER_TOO_SMALL` (nothing written but `*needed`),
/// `TROUPE_ERR_PANIC`. Every buffer is borrowed for the call. Thread-safe.
///
/// ```c
/// size_t sealed_size = 0;
/// troupe_snapshot_seal(bytes, size, key, 32, NULL, 0, &sealed_size);
/// uint8_t *sealed = malloc(sealed_size);
/// troupe_status st = troupe_snapshot_seal(bytes, size, key, 32, sealed, sealed_size, &sealed_size);
/// ```
///
/// # Safety
/// `snapshot` readable for `len` bytes, `key` for `key_len`; `buf` writable for `capacity`;
/// `needed` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_snapshot_seal(
    snapshot: *const u8,
    len: usize,
    key: *const u8,
    key_len: usize,
    buf: *mut u8,
    capacity: usize,
    needed: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_snapshot_seal",
        || {},
        || {
            non_null(needed, "needed")?;
            if capacity > 0 {
                non_null(buf, "buf")?;
            }
            // SAFETY: readable for their lengths per the contract.
            let (snapshot, key) = unsafe {
                (
                    boundary::slice(snapshot, len, "snapshot")?,
                    boundary::slice(key, key_len, "key")?,
                )
            };
            let sealed = crate::shared::sealed::seal(snapshot, key)?;
            // SAFETY: forwarded contract.
            unsafe { hand_over(&sealed, "the sealed snapshot", buf, capacity, needed) }
        },
    )
}

/// Starts a session that goes on exactly where the session saved in `bytes` (`len` bytes, from
/// `troupe_session_snapshot`; borrowed for the call) stopped. The snapshot must come from this
/// model (the same bundle files); a truncated, altered, foreign or other-version snapshot is
/// refused before anything it claims is allocated.
///
/// On success `*out` receives a new handle owned by the caller (free with
/// `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (the message says what
/// is wrong with the snapshot), `TROUPE_ERR_UNSUPPORTED`, `TROUPE_ERR_INFERENCE`,
/// `TROUPE_ERR_PANIC`. Thread-safe with respect to `model`.
///
/// ```c
/// troupe_session *again = NULL;
/// troupe_status st = troupe_session_restore(model, bytes, size, &again);
/// ```
///
/// # Safety
/// `model` must be a live handle; `bytes` readable for `len` bytes; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_restore(
    model: Option<&troupe_model>,
    bytes: *const u8,
    len: usize,
    out: *mut *mut troupe_session,
) -> troupe_status {
    boundary::call(
        "troupe_session_restore",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let model = &boundary::required(model, "model")?.model;
            // SAFETY: readable for `len` bytes per the contract.
            let bytes = unsafe { boundary::slice(bytes, len, "bytes") }?;
            let session = model.restore(bytes)?;
            // SAFETY: checked non-NULL above.
            unsafe { *out = troupe_session::into_raw(session) };
            Ok(())
        },
    )
}

/// `troupe_session_restore` of a snapshot sealed with `troupe_snapshot_seal` under `key`
/// (`key_len` bytes). The seal is checked first, in constant time, so a snapshot sealed under
/// another key, or with any byte changed, is refused before any of it is read; an unsealed
/// snapshot is refused too (a store that needs seals takes no other).
///
/// On success `*out` receives a new handle owned by the caller (free with
/// `troupe_session_free`); on failure `*out` is NULL. Returns what `troupe_session_restore`
/// returns; `TROUPE_ERR_INVALID_ARG` names a seal that does not match. Every buffer is borrowed
/// for the call. Thread-safe with respect to `model`.
///
/// # Safety
/// `model` must be a live handle; `bytes` readable for `len` bytes, `key` for `key_len`; `out`
/// writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_restore_sealed(
    model: Option<&troupe_model>,
    bytes: *const u8,
    len: usize,
    key: *const u8,
    key_len: usize,
    out: *mut *mut troupe_session,
) -> troupe_status {
    boundary::call(
        "troupe_session_restore_sealed",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL; writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let model = &boundary::required(model, "model")?.model;
            // SAFETY: readable for their lengths per the contract.
            let (bytes, key) = unsafe {
                (
                    boundary::slice(bytes, len, "bytes")?,
                    boundary::slice(key, key_len, "key")?,
                )
            };
            let session = model.restore_sealed(bytes, key)?;
            // SAFETY: checked non-NULL above.
            unsafe { *out = troupe_session::into_raw(session) };
            Ok(())
        },
    )
}

/// Makes the session equal to a fresh one with its current settings (seed, steps, CFG,
/// condition, capacity); queued noise is dropped. Clears the poison left by a panic.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_PANIC`. One thread at a time per
/// session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_reset(session: *mut troupe_session) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        run_on_session(session, "troupe_session_reset", true, |s| {
            s.reset();
            Ok(())
        })
    }
}

/// Sets the noise seed for tokens generated from now on.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
/// thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_seed(
    session: *mut troupe_session,
    seed: u64,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_seed", |s| {
            s.set_seed(seed);
            Ok(())
        })
    }
}

/// Sets the sampler's steps (>= 1): MeanFlow steps per token (armflow), DDIM steps per chunk
/// (a magnet live partner), for what is generated from now on.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (0 steps),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_steps(
    session: *mut troupe_session,
    steps: u32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_steps", |s| {
            Ok(s.set_steps(steps)?)
        })
    }
}

/// Sets the classifier-free guidance scale (finite) for what is generated from now on, on a
/// stream with the capability (`troupe_session_capabilities`, `TROUPE_CAP_CFG_SCALE`: ARMFlow's),
/// applied as the family's official sampler applies it (ARMFlow: guided only above 1; the null
/// branch zeroes the actor token and the context). A stream without guidance accepts 1.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite),
/// `TROUPE_ERR_UNSUPPORTED` (a scale other than 1 on a stream without the capability),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_cfg_scale(
    session: *mut troupe_session,
    scale: f32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_cfg_scale", |s| {
            Ok(s.set_cfg_scale(scale)?)
        })
    }
}

/// Sets the conditioning vector (`len` must equal `troupe_model_condition_dim`; borrowed for the
/// call) for what is generated from now on, on a stream with the capability
/// (`TROUPE_CAP_CONDITION`). `condition` NULL with `len` 0 selects the null condition, which
/// every stream accepts.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (wrong `len`),
/// `TROUPE_ERR_INVALID_ARG` (NaN or infinite value), `TROUPE_ERR_UNSUPPORTED` (a condition other
/// than the null one on a stream without the capability), `TROUPE_ERR_INFERENCE`,
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `condition` readable for `len` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_condition(
    session: *mut troupe_session,
    condition: *const f32,
    len: usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_condition", |s| {
            if condition.is_null() && len == 0 {
                return Ok(s.set_condition(None)?);
            }
            if s.capabilities().has(Capability::Condition) && len != s.condition_dim() {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!(
                        "condition has {len} floats, the bundle expects {}",
                        s.condition_dim()
                    ),
                ));
            }
            let condition = boundary::slice(condition, len, "condition")?;
            Ok(s.set_condition(Some(condition))?)
        })
    }
}

/// Conditions what is generated from now on on a text prompt (a NUL-terminated UTF-8 string,
/// borrowed for the call): the condition `troupe_text_prompt_encode` gives, on a stream with
/// the capability (`TROUPE_CAP_PROMPT`: bundles with `troupe_model_takes_prompts`). The model
/// caches the last 64 prompts it encoded.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (text that is not UTF-8
/// or longer than 64 KiB), `TROUPE_ERR_UNSUPPORTED` (a stream without the capability),
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_BUSY`, `TROUPE_ERR_PANIC`. One
/// thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `prompt` NUL-terminated and readable for the call.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_prompt(
    session: *mut troupe_session,
    prompt: *const c_char,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_prompt", |s| {
            let prompt = boundary::required_str(prompt, "prompt")?;
            Ok(s.set_prompt(prompt)?)
        })
    }
}

/// The session takes a conditioning vector (`troupe_session_set_condition`).
pub const TROUPE_CAP_CONDITION: u32 = 1 << 0;
/// The session takes a text prompt (`troupe_session_set_prompt`).
pub const TROUPE_CAP_PROMPT: u32 = 1 << 1;
/// The session takes a CFG scale other than 1 (`troupe_session_set_cfg_scale`).
pub const TROUPE_CAP_CFG_SCALE: u32 = 1 << 2;
/// The session takes queued standard normals (`troupe_session_queue_normals`).
pub const TROUPE_CAP_QUEUED_NORMALS: u32 = 1 << 3;

/// Writes to `*out` the session's capabilities: the `TROUPE_CAP_*` bits of what it takes beyond
/// frames, seed and steps. A call for a capability it lacks returns `TROUPE_ERR_UNSUPPORTED`
/// naming it.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
/// thread at a time per session.
///
/// # Safety
/// `session` must be NULL or a live handle; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_capabilities(
    session: *mut troupe_session,
    out: *mut u32,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_capabilities", |s| {
            non_null(out, "out")?;
            out.write_unaligned(s.capabilities().bits());
            Ok(())
        })
    }
}

/// Queues standard normals for the draws the stream makes next, to replay another
/// implementation's stream exactly (`TROUPE_CAP_QUEUED_NORMALS`: every streaming family):
/// `normals` holds `len` floats (borrowed for the call), appended to any still queued. Each
/// draw takes the next ones it needs while any are queued, in the sampler's order (ARMFlow per
/// token the actor's posterior noise then the reactor's start noise, `troupe_model_latent_dim`
/// each, whole tokens only; MAGNet as `docs/MAGNET.md` gives; ARFlow per frame the start noise
/// when σ > 0, then one ε per step when η > 0, 262 each); then the seeded generator goes on as
/// if the queued draws had been its. A step whose draw needs more than are left fails with
/// `TROUPE_ERR_INVALID_ARG`, the session as it was. `troupe_session_reset` drops them.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a non-finite value;
/// ARMFlow: not whole tokens), `TROUPE_ERR_UNSUPPORTED` (a stream without the capability),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; `normals` readable for `len` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_queue_normals(
    session: *mut troupe_session,
    normals: *const f32,
    len: usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_queue_normals", |s| {
            let normals = boundary::slice(normals, len, "normals")?;
            Ok(s.queue_normals(normals)?)
        })
    }
}

/// Test hook, built only with the `testing` cargo feature and absent from the header: panics
/// inside the boundary so tests can check `TROUPE_ERR_PANIC` -> `TROUPE_ERR_POISONED` -> reset.
///
/// # Safety
/// `session` must be NULL or a live handle.
#[cfg(feature = "testing")]
#[no_mangle]
pub unsafe extern "C" fn troupe_testing_panic(session: *mut troupe_session) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_testing_panic", |_| {
            panic!("deliberate test panic")
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_capability_bits_are_the_rust_ones() {
        for (c, bit) in [
            (Capability::Condition, TROUPE_CAP_CONDITION),
            (Capability::Prompt, TROUPE_CAP_PROMPT),
            (Capability::CfgScale, TROUPE_CAP_CFG_SCALE),
            (Capability::QueuedNormals, TROUPE_CAP_QUEUED_NORMALS),
        ] {
            assert_eq!(c.bit(), bit, "{c}");
        }
        assert_eq!(
            Capability::ALL.len(),
            4,
            "a capability without a TROUPE_CAP_ bit"
        );
    }
}
