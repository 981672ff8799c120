//! `troupe_motion_write_json`: people's poses as a JSON document, for robots and tools.

use std::ffi::c_char;
use std::path::Path;

use super::{read_format, read_people, troupe_joints_format};
use crate::ffi::boundary::{self, troupe_status};
use crate::motion::export::{poses_from_positions, write_poses_json};
use crate::motion::features::MAX_CLIP_FRAMES;

/// The most people one JSON document troupe writes may hold.
const MAX_JSON_PEOPLE: usize = 64;

/// Writes people's poses as a JSON document at `path` (UTF-8; atomically: nothing is left on
/// error): per person and frame, the 22 joint positions and rotations (unit quaternions
/// `[w, x, y, z]`: joint 0 the root's world orientation, the others local to their parent, from
/// inverse kinematics) and the 4 foot contacts, with the skeleton (joint names and parents),
/// units, up axis, handedness and frame rate stated in the document. `positions` is float32
/// `[n_people][n_frames][22][3]` in the caller's world as `format` says, which the document
/// keeps; `names` as for `troupe_bvh_write` (NULL: "person1", ...; at most 64 people).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
/// positions, naming person, frame and joint; no people or frames; a bad format or name),
/// `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
/// readable; a non-NULL `names` readable for `n_people` pointers, each NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_write_json(
    path: *const c_char,
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    format: *const troupe_joints_format,
    names: *const *const c_char,
) -> troupe_status {
    boundary::call(
        "troupe_motion_write_json",
        || {},
        || {
            // SAFETY (all three): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let format = unsafe { read_format(format) }?;
            let people = unsafe {
                read_people(
                    positions,
                    n_people,
                    n_frames,
                    names,
                    MAX_JSON_PEOPLE,
                    MAX_CLIP_FRAMES,
                )
            }?;
            let poses = people
                .positions
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    poses_from_positions(*p, &format).map_err(|e| match e {
                        crate::Error::InvalidInput(m) => {
                            crate::Error::InvalidInput(format!("person {i}, {m}"))
                        }
                        other => other,
                    })
                })
                .collect::<crate::Result<Vec<_>>>()?;
            let named: Vec<(&str, &[crate::motion::Pose])> = people
                .names
                .iter()
                .map(String::as_str)
                .zip(poses.iter().map(Vec::as_slice))
                .collect();
            write_poses_json(Path::new(path), &named, &format)?;
            Ok(())
        },
    )
}
