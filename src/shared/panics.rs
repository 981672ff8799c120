//! Panics inside troupe, turned into errors that carry their cause.
//!
//! troupe runs inside someone else's process. A panic (a bug here, or in tract on a hostile
//! graph) must reach the caller as an error with its reason, not as text on the host's stderr
//! or a multi-line backtrace when the host sets `RUST_BACKTRACE`. [`catch`] runs code so that a
//! panic becomes `Err(reason)`; while code runs under [`quietly`] (the C ABI runs every call
//! that way, and the graph loader's worker threads inherit it), the panic hook records the
//! reason and location instead of printing. Outside, the previous hook runs unchanged, so a Rust
//! program using the crate keeps its own panic output.

use std::any::Any;
use std::cell::{Cell, RefCell};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Once;

thread_local! {
    static QUIET: Cell<bool> = const { Cell::new(false) };
    static LOCATION: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Installs the hook (once per process): quiet threads record where they panicked; others print
/// as before.
fn install_hook() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if QUIET.with(Cell::get) {
                let at = info
                    .location()
                    .map(|l| format!("{}:{}", l.file(), l.line()));
                LOCATION.with(|slot| *slot.borrow_mut() = at);
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs `body` with this thread's panics recorded rather than printed.
pub(crate) fn quietly<R>(body: impl FnOnce() -> R) -> R {
    /// Restores the flag however `body` ends (a panic unwinding through included).
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            QUIET.with(|q| q.set(self.0));
        }
    }
    install_hook();
    let _restore = Restore(QUIET.with(|q| q.replace(true)));
    body()
}

/// Whether this thread runs [`quietly`] (for threads it starts, which must do the same).
pub(crate) fn is_quiet() -> bool {
    QUIET.with(Cell::get)
}

/// Runs `body`, [`quietly`] when `quiet`, turning a panic into its reason.
pub(crate) fn catch<R>(quiet: bool, body: impl FnOnce() -> R) -> Result<R, String> {
    let run = || catch_unwind(AssertUnwindSafe(body));
    let outcome = if quiet { quietly(run) } else { run() };
    outcome.map_err(|payload| reason(payload.as_ref()))
}

/// The panic's message and, when the hook recorded it on this thread, where it happened.
pub(crate) fn reason(payload: &(dyn Any + Send)) -> String {
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into());
    match LOCATION.with(|slot| slot.borrow_mut().take()) {
        Some(at) => format!("{message} (at {at})"),
        None => message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quiet_panic_becomes_its_message_and_location() {
        let err = catch(true, || panic!("deliberate: {}", 42)).unwrap_err();
        assert!(err.starts_with("deliberate: 42 (at "), "{err}");
        assert!(err.contains("panics.rs"), "{err}");
        assert!(!is_quiet(), "the flag is restored");
        assert_eq!(catch(true, || 7).unwrap(), 7);
    }
}
