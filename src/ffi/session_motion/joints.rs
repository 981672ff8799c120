//! Sessions that speak joint positions: the input person's t2m-22 positions in, the other
//! person's poses out, for engines that never touch a family's frames.

use ndarray::ArrayView3;

use crate::ffi::boundary::{
    self, checked_mul, non_null, troupe_status, FfiError, TROUPE_ERR_INVALID_ARG,
};
use crate::ffi::model::{property, troupe_model};
use crate::ffi::motion::{read_format, troupe_joints_format, troupe_placement, PoseParts};
use crate::ffi::session::{troupe_session, with_session};
use crate::motion::T2M22_JOINTS;
use crate::Model;

/// Sets how `troupe_session_step_joints` reads the input person's positions (units, up axis,
/// handedness, frame rate; resampled to the bundle's rate) and forgets the joint stream's
/// frames and placement. Without it, positions are metres, Y up, right-handed, at the bundle's
/// rate. Every streaming family takes joint positions: `interhuman262` streams (ARMFlow, ARFlow)
/// as features, `magnet-smplx145` streams (MAGNet) by inverse kinematics (`docs/MOTION.md`).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad format; the
/// session is then unchanged),
/// `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
/// One thread at a time per session.
///
/// # Safety
/// `session` a live handle; `format` readable for its `struct_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_set_joints_format(
    session: *mut troupe_session,
    format: *const troupe_joints_format,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_set_joints_format", |s| {
            let format = read_format(format)?;
            s.set_joints_format(format)?;
            Ok(())
        })
    }
}

/// Feeds `n_frames` frames of the input person's joint positions (`actor`: float32
/// `[n_frames][22][3]`, measured as `troupe_session_set_joints_format` said; may be NULL when
/// `n_frames` is 0) and writes the other person's poses that became ready, in the caller's
/// world, into the buffers of `*out` (each non-NULL buffer must hold `out_capacity_frames`
/// frames of its part), their count into `*n_written`. `troupe_session_joints_ready_after`
/// gives the exact count; `troupe_model_joints_latency_frames` the latency.
///
/// On any error nothing is written and the session is exactly as before the call, except after
/// `TROUPE_ERR_PANIC`, which poisons it.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a buffer smaller than its
/// capacity says), `TROUPE_ERR_INVALID_ARG` (a NaN or infinite position, naming frame and
/// joint), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints),
/// `TROUPE_ERR_BUFFER_TOO_SMALL`,
/// `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per
/// session.
///
/// # Safety
/// `session` a live handle; `actor` readable for `n_frames * 66` floats; `out` readable and its
/// buffers writable for their lengths, overlapping nothing else; `n_written` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_step_joints(
    session: *mut troupe_session,
    actor: *const f32,
    n_frames: usize,
    out: *const crate::ffi::motion::troupe_pose_buffers,
    out_capacity_frames: usize,
    n_written: *mut usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_step_joints", |s| {
            non_null(n_written, "n_written")?;
            let len = checked_mul(n_frames, 3 * T2M22_JOINTS, "n_frames * 66")?;
            let flat = boundary::slice(actor, len, "actor")?;
            let view =
                ArrayView3::from_shape((n_frames, T2M22_JOINTS, 3), flat).expect("length checked");
            let parts = PoseParts::check(out, out_capacity_frames, false)?;
            let poses = s.step_joints_bounded(view, out_capacity_frames)?;
            parts.fill(&poses);
            *n_written = poses.len();
            Ok(())
        })
    }
}

/// Writes to `*n_out` how many poses `troupe_session_step_joints` returns for the next
/// `n_frames` joint frames.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (a stream whose frames
/// carry no joints),
/// `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` a live handle; `n_out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_joints_ready_after(
    session: *mut troupe_session,
    n_frames: usize,
    n_out: *mut usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_joints_ready_after", |s| {
            non_null(n_out, "n_out")?;
            *n_out = s.joints_ready_after(n_frames)?;
            Ok(())
        })
    }
}

/// Writes the joint stream's placement (where the poses are put: fixed by the first joint
/// frame for `interhuman262` streams, the caller's own world for `magnet-smplx145` ones) to
/// `*out`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no joint frame yet),
/// `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
/// One thread at a time per session.
///
/// # Safety
/// `session` a live handle; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_session_joints_placement(
    session: *mut troupe_session,
    out: *mut troupe_placement,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_session_joints_placement", |s| {
            non_null(out, "out")?;
            let p = s.joints_placement().ok_or_else(|| {
                FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    "the session has had no joint frame yet",
                )
            })?;
            out.write_unaligned(troupe_placement::from_rust(&p));
            Ok(())
        })
    }
}

/// Latency in frames when the input person streams joint positions: `troupe_model_latency_frames`
/// plus what the conversion waits for (one frame for `interhuman262` velocities and contacts,
/// none for `magnet-smplx145`); 0 for NULL and for a model whose streams take no joint
/// positions (a `umf` model, an ARMFlow bundle of InterX frames). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_model_joints_latency_frames(model: Option<&troupe_model>) -> usize {
    property(model, Model::joints_latency_frames)
}
