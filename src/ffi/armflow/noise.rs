//! An ARMFlow stream's noise queued token by token.

use crate::ffi::armflow::reactor;
use crate::ffi::boundary::{self, non_null, troupe_status, FfiError, TROUPE_ERR_SHAPE};
use crate::ffi::session::{troupe_session, with_session};
use crate::TokenNoise;

/// Queues the noise of the next token an ARMFlow stream has not yet generated, to reproduce a
/// run exactly: `actor_noise` (the posterior sample's standard normals) and `reactor_noise` (the
/// starting noise), `len` floats each (`troupe_model_latent_dim`), borrowed for the call. Queued
/// noise is used in order before the seeded generator; `troupe_session_reset` drops it.
/// `troupe_session_queue_normals` queues the same draws as one run of floats, on any family.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE`, `TROUPE_ERR_INVALID_ARG`
/// (non-finite value), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow stream), `TROUPE_ERR_POISONED`,
/// `TROUPE_ERR_PANIC`. One thread at a time per session.
///
/// # Safety
/// `session` must be a live handle; both noise pointers readable for `len` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_armflow_session_queue_noise(
    session: *mut troupe_session,
    actor_noise: *const f32,
    reactor_noise: *const f32,
    len: usize,
) -> troupe_status {
    // SAFETY: forwarded contract.
    unsafe {
        with_session(session, "troupe_armflow_session_queue_noise", |s| {
            let reactor = reactor(s, "queued token noise")?;
            let lat = reactor.latent_dim();
            if len != lat {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!("noise vectors have {len} floats, the bundle's latent dim is {lat}"),
                ));
            }
            non_null(actor_noise, "actor_noise")?;
            non_null(reactor_noise, "reactor_noise")?;
            let noise = TokenNoise {
                actor: boundary::slice(actor_noise, len, "actor_noise")?.to_vec(),
                reactor: boundary::slice(reactor_noise, len, "reactor_noise")?.to_vec(),
            };
            Ok(reactor.queue_noise(noise)?)
        })
    }
}
