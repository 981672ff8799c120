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
//!
//! Beside it, a [`CallBudget`] bounds a long call up front: the work it may take (checked before
//! it starts, from what it will do) and the seconds it may run (checked wherever it reports).
//! A service sets one before passing a caller's request on, instead of racing a cancel flag.

use std::cell::{Cell, RefCell};
use std::time::Instant;

use crate::shared::error::{Error, Result};

/// A progress callback: `(done, total) -> keep going`.
pub type ProgressFn = Box<dyn FnMut(u64, u64) -> bool>;

/// What one long call may cost, set per thread ([`with_call_budget`],
/// `troupe_set_call_budget`). A zero field sets no bound. Calls bounded: a group, a clip, a
/// MAGNet generation, an ARFlow generation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CallBudget {
    /// The most work one call may take, in the call's own unit: a group's network evaluations,
    /// a clip's tokens × solver steps, a MAGNet generation's sampler iterations, an ARFlow
    /// generation's sampler steps. A call that would take more is refused before it starts
    /// ([`Error::InvalidOption`]).
    pub max_work: u64,
    /// The most seconds one call may run; a call past it stops at its next unit of work with
    /// [`Error::Cancelled`], having written nothing.
    pub max_seconds: f64,
}

thread_local! {
    static CALLBACK: RefCell<Option<ProgressFn>> = const { RefCell::new(None) };
    static BUDGET: Cell<CallBudget> = const { Cell::new(CallBudget { max_work: 0, max_seconds: 0.0 }) };
    /// When the outermost budgeted call running on this thread started.
    static STARTED: Cell<Option<Instant>> = const { Cell::new(None) };
}

/// Sets this thread's call budget (all zero: none); returns the previous one. A budget whose
/// `max_seconds` is negative or not a number is refused.
pub(crate) fn set_thread_budget(budget: CallBudget) -> Result<CallBudget> {
    if budget.max_seconds.is_nan() || budget.max_seconds < 0.0 {
        return Err(Error::InvalidOption(format!(
            "a call budget's seconds are 0 (no bound) or more, got {}",
            budget.max_seconds
        )));
    }
    Ok(BUDGET.with(|slot| slot.replace(budget)))
}

/// Runs `body` with `budget` as this thread's call budget, then restores the previous one.
/// Groups, clips and MAGNet and ARFlow generations made by `body` on this thread are refused
/// when they would take more than `budget.max_work`, and stop with [`Error::Cancelled`] once
/// they have run `budget.max_seconds`.
///
/// ```
/// let model = troupe::Model::load("onnx/bundles/umf-tiny")?;
/// let budget = troupe::CallBudget { max_work: 5_000, max_seconds: 2.0 };
/// let group = troupe::with_call_budget(budget, || {
///     model.umf()?.generate_group(None, 4, &troupe::GroupOptions::default())
/// })?;
/// # Ok::<(), troupe::Error>(())
/// ```
pub fn with_call_budget<R>(budget: CallBudget, body: impl FnOnce() -> Result<R>) -> Result<R> {
    /// Puts the previous budget back however `body` ends.
    struct Restore(CallBudget);
    impl Drop for Restore {
        fn drop(&mut self) {
            BUDGET.with(|slot| slot.set(self.0));
        }
    }
    let _restore = Restore(set_thread_budget(budget)?);
    body()
}

/// The time budget of one call: runs from [`start_call`] until this is dropped. A call made
/// inside another (a clip inside a service's own budgeted work) keeps the outer start.
pub(crate) struct CallClock {
    outermost: bool,
}

impl Drop for CallClock {
    fn drop(&mut self) {
        if self.outermost {
            STARTED.with(|started| started.set(None));
        }
    }
}

/// Starts a budgeted call: refused when `work` (in `unit`s) is above the thread's budget,
/// else its time budget runs until the returned clock is dropped.
pub(crate) fn start_call(what: &str, work: u64, unit: &str) -> Result<CallClock> {
    check_work(what, work, unit)?;
    Ok(start_clock())
}

/// [`Error::InvalidOption`] when `work` (in `unit`s) is above the thread's budget: for a call
/// that knows its work only once it has begun (a MAGNet task), after [`start_clock`].
pub(crate) fn check_work(what: &str, work: u64, unit: &str) -> Result<()> {
    let budget = BUDGET.with(Cell::get).max_work;
    if budget != 0 && work > budget {
        return Err(Error::InvalidOption(format!(
            "{what} would take {work} {unit}, above this thread's call budget of {budget}"
        )));
    }
    Ok(())
}

/// Starts the time budget of a call (see [`start_call`]).
pub(crate) fn start_clock() -> CallClock {
    let outermost = STARTED.with(|started| {
        let first = started.get().is_none();
        if first {
            started.set(Some(Instant::now()));
        }
        first
    });
    CallClock { outermost }
}

/// [`Error::Cancelled`] once the running call has spent its time budget.
pub(crate) fn check_time(what: &str) -> Result<()> {
    let limit = BUDGET.with(Cell::get).max_seconds;
    match STARTED.with(Cell::get) {
        Some(start) if limit > 0.0 && start.elapsed().as_secs_f64() > limit => {
            Err(Error::Cancelled(format!(
                "{what} stopped at this thread's call budget of {limit} s"
            )))
        }
        _ => Ok(()),
    }
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
/// thread's callback asks to stop or the call's time budget is spent. The callback is taken out while it runs, so a long call it
/// makes itself runs without one.
pub(crate) fn report(what: &str, done: u64, total: u64) -> Result<()> {
    check_time(what).map_err(|e| match e {
        Error::Cancelled(m) => Error::Cancelled(format!("{m}, after {done} of {total} steps")),
        other => other,
    })?;
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

    #[test]
    fn a_budget_refuses_work_up_front_and_stops_a_call_in_time() {
        let budget = CallBudget {
            max_work: 10,
            max_seconds: 0.05,
        };
        let e = with_call_budget(budget, || start_call("the sum", 11, "additions").map(drop))
            .unwrap_err();
        assert!(
            matches!(&e, Error::InvalidOption(m) if m.contains("would take 11 additions") && m.contains("budget of 10")),
            "{e}"
        );
        let out = with_call_budget(budget, || {
            let _clock = start_call("the sum", 10, "additions")?;
            report("the sum", 1, 10)?;
            std::thread::sleep(std::time::Duration::from_millis(60));
            report("the sum", 2, 10)
        });
        let e = out.unwrap_err().to_string();
        assert!(
            e.contains("the sum stopped at this thread's call budget of 0.05 s, after 2 of 10"),
            "{e}"
        );
        // Outside the scope and after the call, no bound applies.
        assert!(start_call("the sum", u64::MAX, "additions").is_ok());
        assert!(check_time("the sum").is_ok());
        for bad in [-1.0, f64::NAN] {
            let bad = CallBudget {
                max_work: 0,
                max_seconds: bad,
            };
            assert!(with_call_budget(bad, || Ok(())).is_err());
        }
    }
}
