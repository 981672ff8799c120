//! `troupe_viewer_*`: pictures a person can look at, of people moving on the t2m-22 skeleton: a
//! self-contained HTML player and an animated GIF (see `troupe::viewer`).

use std::ffi::c_char;
use std::path::Path;

use ndarray::ArrayView3;

use crate::ffi::boundary::{self, optional_str, troupe_status, FfiError, TROUPE_ERR_NULL_ARG};
use crate::ffi::motion::{read_format, read_people, troupe_joints_format};
use crate::viewer::{GifOptions, Scene, MAX_FRAMES, MAX_PEOPLE};

/// Writes pictures of `n_people` people moving on the t2m-22 skeleton: a self-contained HTML
/// player (no network; drag to orbit, wheel to zoom, play/pause, frame slider, speed) to
/// `html_path`, and an animated GIF (480 × 360, at most 15 frames per second, from the
/// player's starting view) to `gif_path`. Either path may be NULL, not both.
///
/// `positions` holds float32 `[n_people][n_frames][22][3]` joint positions measured as `format`
/// says (units, up axis, handedness; its `fps` is the playback rate). `names` holds `n_people`
/// UTF-8 names for the legend (at most 64 characters each); NULL names them "person1",
/// "person2", ..., as does a NULL entry. `title` is a UTF-8 title (at most 200 characters) or
/// NULL for none. People are coloured blue (#1f77b4), orange (#ff7f0e), green, red, purple,
/// brown, pink, cyan, in order.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (`positions` or `format` NULL, or both paths
/// NULL), `TROUPE_ERR_INVALID_ARG` (`n_people` not in 1..=8; `n_frames` not in 1..=18000; a
/// non-finite position or one farther than 10 km, naming the person, frame and joint; a bad
/// format; a path, name or title not UTF-8 or too long; something at a path that is not a
/// regular file: a directory, link, FIFO, socket or device), `TROUPE_ERR_IO` (a file that
/// cannot be written, e.g. its directory is missing), `TROUPE_ERR_CANCELLED` (the progress
/// callback stopped the GIF, which reports every frame), `TROUPE_ERR_PANIC`. Nothing is
/// written on error:
/// both files are rendered and written to temporary files beside them first, then renamed into
/// place. Thread-safe.
///
/// # Safety
/// `positions` readable for `n_people * n_frames * 66` floats; `format` readable for its
/// `struct_size` bytes; a non-NULL `names` readable for `n_people` pointers, each NULL or
/// NUL-terminated; non-NULL `html_path`, `gif_path` and `title` NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn troupe_viewer_write(
    html_path: *const c_char,
    gif_path: *const c_char,
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    format: *const troupe_joints_format,
    names: *const *const c_char,
    title: *const c_char,
) -> troupe_status {
    boundary::call(
        "troupe_viewer_write",
        || {},
        || {
            // SAFETY (all three): forwarded contract.
            let html = unsafe { optional_str(html_path, "html_path") }?;
            let gif = unsafe { optional_str(gif_path, "gif_path") }?;
            let title = unsafe { optional_str(title, "title") }?.unwrap_or("");
            if html.is_none() && gif.is_none() {
                return Err(FfiError::new(
                    TROUPE_ERR_NULL_ARG,
                    "`html_path` and `gif_path` are both NULL: nothing to write",
                ));
            }
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            // SAFETY: forwarded contract.
            let people = unsafe {
                read_people(positions, n_people, n_frames, names, MAX_PEOPLE, MAX_FRAMES)
            }?;
            let views: Vec<(&str, ArrayView3<'_, f32>)> = people
                .names
                .iter()
                .map(String::as_str)
                .zip(people.positions.iter().copied())
                .collect();
            let scene = Scene::from_world(title, &format, &views)?;
            scene.write_pictures(
                html.map(Path::new),
                gif.map(Path::new),
                &GifOptions::default(),
            )?;
            Ok(())
        },
    )
}
