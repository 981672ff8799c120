//! Progress of long calls, and cancelling them.
//!
//! A model load, a group or a clip can take seconds on a large bundle (a 256-person group takes
//! most of a minute even on the tiny one). Each such call reports its progress, between units of
//! work and on the thread that made the call, to that thread's progress callback; a callback
//! that returns `false` cancels the call, which then fails with [`Error::Cancelled`] having
//! written nothing. Another thread cancels a call by setting a flag the callback reads.
//!
//! The callback is per thread, like the last error: set for a scope with [`with_progress`] (Rust)
//! or until changed with `troupe_set_progress_callback` (C).

use std::cell::RefCell;

use crate::shared::error::{Error, Result};

/// A progress callback: `(done, total) -> keep going`.
pub type ProgressFn = Box<dyn FnMut(u64, u64) -> bool>;

thread_local! {
    static CALLBACK: RefCell<Option<ProgressFn>> = const { RefCell::new(None) };
}

/// Sets (or with `None` removes) this thread's progress callback; returns the previous one.
pub(crate) fn set_thread_callback(callback: Option<ProgressFn>) -> Option<ProgressFn> {
    CALLBACK.with(|slot| std::mem::replace(&mut *slot.borrow_mut(), callback))
}

/// Runs `body` with `callback` as this thread's progress callback, then restores the previous
/// one. Long calls made by `body` on this thread report `(done, total)` to it between units of
/// work (graphs loaded, a group's network evaluations, clip tokens, BVH frames, GIF frames)
/// and stop with [`Error::Cancelled`] when it returns `false`.
///
/// ```no_run
/// use std::sync::atomic::{AtomicBool, Ordering};
/// use std::sync::Arc;
/// let stop = Arc::new(AtomicBool::new(false)); // set from another thread to cancel
/// let flag = Arc::clone(&stop);
/// let model = troupe::with_progress(
///     move |done, total| {
///         eprintln!("{done}/{total}");
///         !flag.load(Ordering::Relaxed)
///     },
///     || troupe::Model::load("onnx/bundles/armflow-tiny"),
/// )?;
/// # Ok::<(), troupe::Error>(())
/// ```
pub fn with_progress<R>(
    callback: impl FnMut(u64, u64) -> bool + 'static,
    body: impl FnOnce() -> R,
) -> R {
    /// Puts the previous callback back however `body` ends.
    struct Restore(Option<ProgressFn>);
    impl Drop for Restore {
        fn drop(&mut self) {
            set_thread_callback(self.0.take());
        }
    }
    let _restore = Restore(set_thread_callback(Some(Box::new(callback))));
    body()
}

/// Reports that `done` of `total` units of `what` are done; [`Error::Cancelled`] when this
/// thread's callback asks to stop. The callback is taken out while it runs, so a long call it
/// makes itself runs without one.
pub(crate) fn report(what: &str, done: u64, total: u64) -> Result<()> {
    let Some(mut callback) = set_thread_callback(None) else {
        return Ok(());
    };
    let keep_going = callback(done, total);
    set_thread_callback(Some(callback));
    if keep_going {
        Ok(())
    } else {
        Err(Error::Cancelled(format!(
            "{what} was cancelled by its progress callback after {done} of {total} steps"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_callback_sees_the_steps_and_can_stop_the_call() {
        let seen = std::rc::Rc::new(RefCell::new(Vec::new()));
        let log = std::rc::Rc::clone(&seen);
        let out = with_progress(
            move |done, total| {
                log.borrow_mut().push((done, total));
                done < 2
            },
            || (1..=3).try_for_each(|i| report("counting", i, 3)),
        );
        assert_eq!(*seen.borrow(), [(1, 3), (2, 3)]);
        let e = out.unwrap_err().to_string();
        assert!(
            e.contains("counting was cancelled") && e.contains("after 2 of 3"),
            "{e}"
        );
        assert!(
            report("after", 1, 1).is_ok(),
            "the callback is gone after the scope"
        );
    }
}
