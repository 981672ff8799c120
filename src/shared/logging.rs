//! A tiny log sink: silent by default; the C ABI installs a callback, and `TROUPE_LOG=<level>` in
//! the environment sends lines to stderr when no callback is set.

use std::sync::{OnceLock, RwLock};

/// Severity of a log line (lower is more severe; the values are the C `TROUPE_LOG_*` levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Something failed.
    Error = 1,
    /// Something works but should be looked at (a bundle without digests of its files).
    Warn = 2,
    /// Milestones: a model loaded, a session started.
    Info = 3,
    /// Details useful when debugging an integration.
    Debug = 4,
}

/// Where log lines go. `user_data` is the C caller's opaque pointer, stored as an address.
pub(crate) struct Sink {
    pub callback: unsafe extern "C" fn(
        user_data: *mut std::ffi::c_void,
        level: i32,
        target: *const std::ffi::c_char,
        message: *const std::ffi::c_char,
    ),
    pub user_data: usize,
    pub max_level: i32,
}

static SINK: RwLock<Option<Sink>> = RwLock::new(None);

pub(crate) fn set_sink(sink: Option<Sink>) {
    *SINK.write().unwrap_or_else(|e| e.into_inner()) = sink;
}

fn env_level() -> i32 {
    static LEVEL: OnceLock<i32> = OnceLock::new();
    *LEVEL.get_or_init(|| match std::env::var("TROUPE_LOG").as_deref() {
        Ok("error") => 1,
        Ok("warn") => 2,
        Ok("info") => 3,
        Ok("debug") | Ok("trace") => 4,
        _ => 0,
    })
}

/// Emits one line to the installed callback, or to stderr under `TROUPE_LOG`.
pub(crate) fn log(level: Level, target: &str, message: impl FnOnce() -> String) {
    let sink = SINK.read().unwrap_or_else(|e| e.into_inner());
    match sink.as_ref() {
        Some(s) if level as i32 <= s.max_level => {
            let target = std::ffi::CString::new(target).unwrap_or_default();
            let message = std::ffi::CString::new(message().replace('\0', " ")).unwrap_or_default();
            // SAFETY: the callback and its user data were registered together through
            // `troupe_set_log_callback`, whose contract requires the callback to be thread-safe;
            // the strings outlive the call.
            unsafe {
                (s.callback)(
                    s.user_data as *mut std::ffi::c_void,
                    level as i32,
                    target.as_ptr(),
                    message.as_ptr(),
                )
            };
        }
        None if level as i32 <= env_level() => {
            eprintln!("troupe [{level:?}] {target}: {}", message());
        }
        _ => {}
    }
}
