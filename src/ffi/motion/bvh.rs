//! `troupe_bvh_*`: BVH files in (as t2m-22 joint positions) and out.

use std::ffi::c_char;
use std::path::Path;

use ndarray::Array3;

use super::{canonical_people, read_format, troupe_joints_format};
use super::{TROUPE_UNITS_CENTIMETERS, TROUPE_UNITS_METERS};
use super::{TROUPE_UNITS_INCHES, TROUPE_UNITS_MILLIMETERS};
use crate::ffi::boundary::{
    self, non_null, required, troupe_status, write_versioned, FfiError, FfiResult,
    TROUPE_ERR_INVALID_ARG, TROUPE_ERR_SHAPE,
};
use crate::motion::bvh::{write_bvh_file, BvhPerson, BvhWriteOptions};
use crate::motion::read_motion_file;
use crate::motion::{JointMap, JointsFormat, Units};

/// The most people one BVH file troupe writes may hold.
const MAX_BVH_PEOPLE: usize = 64;

/// Let `troupe_bvh_read` guess a file's units from the figure's height.
pub const TROUPE_UNITS_AUTO: u32 = 0xFFFF_FFFF;

/// A BVH take read as t2m-22 joint positions. Immutable: any thread may query it. Free with
/// `troupe_bvh_free`.
pub struct troupe_bvh {
    positions: Array3<f32>,
    format: JointsFormat,
    inferred: std::ffi::CString,
    /// Per t2m-22 joint, the rig joint's name it is read from (NUL-free: the reader checks).
    mapping: Vec<Option<std::ffi::CString>>,
}

pub(crate) fn units_from(code: u32, what: &str) -> FfiResult<Units> {
    Ok(match code {
        TROUPE_UNITS_METERS => Units::Meters,
        TROUPE_UNITS_CENTIMETERS => Units::Centimeters,
        TROUPE_UNITS_MILLIMETERS => Units::Millimeters,
        TROUPE_UNITS_INCHES => Units::Inches,
        v => {
            return Err(FfiError::new(
                TROUPE_ERR_INVALID_ARG,
                format!("{what} is {v}, not a TROUPE_UNITS_* code"),
            ))
        }
    })
}

/// Reads the BVH or FBX file at `path` (UTF-8; told apart by content) as t2m-22 joint positions. `joint_map_json`: a joint
/// map (JSON, see the built-in `src/motion/rigs/t2m22-joint-names.json`) or NULL for the
/// built-in one (LAFAN1, Mixamo, CMU, HumanIK, SMPL and Rigify names). t2m-22 joints the rig
/// lacks are placed from the others where they can be (`troupe_bvh_inferred` says which).
/// `units`: the file's length unit (`TROUPE_UNITS_*`), or `TROUPE_UNITS_AUTO` to guess from the
/// figure's height; an FBX file declares its own, and is converted to `units` (metres for
/// `TROUPE_UNITS_AUTO`). `*out` is set to NULL on entry and to the take on success.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO` (unreadable file),
/// `TROUPE_ERR_INVALID_ARG` (malformed file, naming line, joint and frame; a rig lacking a
/// t2m-22 joint that cannot be placed from the others, naming it and the names tried; a bad
/// map or units), `TROUPE_ERR_CANCELLED` (the progress callback stopped it: it reports every
/// 4096 frames), `TROUPE_ERR_PANIC`.
/// Thread-safe.
///
/// # Safety
/// `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_bvh_read(
    path: *const c_char,
    joint_map_json: *const c_char,
    units: u32,
    out: *mut *mut troupe_bvh,
) -> troupe_status {
    boundary::call(
        "troupe_bvh_read",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let map = if joint_map_json.is_null() {
                JointMap::builtin()
            } else {
                // SAFETY: forwarded contract.
                JointMap::from_json(unsafe {
                    boundary::required_str(joint_map_json, "joint_map_json")
                }?)?
            };
            let units = match units {
                TROUPE_UNITS_AUTO => None,
                code => Some(units_from(code, "units")?),
            };
            let joints = read_motion_file(path, units)?.to_t2m22(&map, units, path)?;
            // Lines of text never hold a NUL: joint names are checked by the reader.
            let inferred = std::ffi::CString::new(joints.inferred.join("\n")).unwrap_or_default();
            let mapping = joints
                .mapping
                .into_iter()
                .map(|name| name.and_then(|n| std::ffi::CString::new(n).ok()))
                .collect();
            let handle = Box::new(troupe_bvh {
                positions: joints.positions,
                format: joints.format,
                inferred,
                mapping,
            });
            // SAFETY: as above.
            unsafe { *out = Box::into_raw(handle) };
            Ok(())
        },
    )
}

/// The t2m-22 joints the take's rig lacks and how they were placed (spine joints along its
/// spine, toes along its feet, collars, a hand at a forearm's end; see docs/RIGS.md), one line
/// each (UTF-8, owned by the take, valid until it is freed; "" when the rig has every joint, NULL
/// for NULL). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_bvh_inferred(bvh: Option<&troupe_bvh>) -> *const c_char {
    boundary::get(std::ptr::null(), || {
        bvh.map_or(std::ptr::null(), |b| b.inferred.as_ptr())
    })
}

/// The name of the rig joint t2m-22 joint `joint` (0 to 21, the order of the take's positions)
/// is read from: which joint became which, found by the joint map's names or by the rig's
/// shape. NULL where the joint is placed from others (`troupe_bvh_inferred` says how), for
/// `joint` above 21, and for NULL. UTF-8, owned by the take, valid until it is freed.
/// Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_bvh_joint_source(bvh: Option<&troupe_bvh>, joint: usize) -> *const c_char {
    boundary::get(std::ptr::null(), || {
        bvh.and_then(|b| b.mapping.get(joint))
            .and_then(Option::as_ref)
            .map_or(std::ptr::null(), |name| name.as_ptr())
    })
}

/// Frames of a take; 0 for NULL. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_bvh_frames(bvh: Option<&troupe_bvh>) -> usize {
    boundary::get(0, || bvh.map_or(0, |b| b.positions.shape()[0]))
}

/// Writes how to read the take's positions (its units, Y up, right-handed, its frame rate) into
/// `*format` (`format_size` = `sizeof(troupe_joints_format)`): pass it to the conversion
/// functions with the positions.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a size smaller than
/// the first version's). Thread-safe.
///
/// # Safety
/// `format` writable for `format_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_bvh_format(
    bvh: Option<&troupe_bvh>,
    format: *mut troupe_joints_format,
    format_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_bvh_format",
        || {},
        || {
            let bvh = required(bvh, "bvh")?;
            non_null(format, "format")?;
            boundary::check_struct_size(
                format_size,
                super::FORMAT_V1_SIZE,
                "troupe_joints_format",
            )?;
            let value = super::troupe_joints_format::from_rust(&bvh.format, format_size);
            // SAFETY: writable for `format_size` bytes per the contract.
            unsafe { write_versioned(format, format_size, &value) };
            Ok(())
        },
    )
}

/// Copies the take's t2m-22 joint positions, float32 `[frames][22][3]` in the file's units and
/// axes, into `positions` (`positions_len` = frames × 66).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (another length).
/// Thread-safe.
///
/// # Safety
/// `positions` writable for `positions_len` floats.
#[no_mangle]
pub unsafe extern "C" fn troupe_bvh_positions(
    bvh: Option<&troupe_bvh>,
    positions: *mut f32,
    positions_len: usize,
) -> troupe_status {
    boundary::call(
        "troupe_bvh_positions",
        || {},
        || {
            let bvh = required(bvh, "bvh")?;
            let src = bvh.positions.as_slice().expect("standard layout");
            if positions_len != src.len() {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!(
                        "positions_len is {positions_len}, the take has {}",
                        src.len()
                    ),
                ));
            }
            if !src.is_empty() {
                non_null(positions, "positions")?;
                // SAFETY: writable for `positions_len` floats per the contract.
                unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), positions, src.len()) };
            }
            Ok(())
        },
    )
}

/// Frees a take. NULL is a no-op.
///
/// # Safety
/// `bvh` NULL or a live handle from `troupe_bvh_read`, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn troupe_bvh_free(bvh: *mut troupe_bvh) {
    if !bvh.is_null() {
        // SAFETY: a live handle from Box::into_raw per the contract.
        boundary::get((), || drop(unsafe { Box::from_raw(bvh) }));
    }
}

/// Writes a BVH file at `path` (UTF-8; atomically: nothing is left on error) holding `n_people`
/// people on the t2m-22 skeleton: `positions` is float32 `[n_people][n_frames][22][3]` in the
/// caller's world as `format` says (its `fps` becomes the file's rate), `names` their names (NULL
/// or a NULL entry for "person1", "person2", ...; prefixed to joint names when there are several
/// people, who then
/// share a root joint called `scene`; at most 64 people). Rotations come from inverse kinematics; each person's bone
/// lengths are measured from their motion when `fit_skeleton` is non-zero (the file then
/// reproduces the positions), else troupe's neutral body is used. `units`: the file's length unit
/// (`TROUPE_UNITS_*`; centimetres are what most tools expect). The file is Y up.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
/// positions, no people or frames, a bad format or units; a name its reader would refuse:
/// repeated, too long, with whitespace, braces or control characters; a root beyond ±1e6 file
/// units; something at `path` that is not a regular file: a directory, link, FIFO, socket or
/// device), `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`. What it writes, `troupe_bvh_read` reads back.
/// Thread-safe.
///
/// # Safety
/// `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
/// readable; a non-NULL `names` readable for `n_people` NUL-terminated strings.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_bvh_write(
    path: *const c_char,
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    format: *const troupe_joints_format,
    names: *const *const c_char,
    units: u32,
    fit_skeleton: u32,
) -> troupe_status {
    boundary::call(
        "troupe_bvh_write",
        || {},
        || {
            // SAFETY (all): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let format = unsafe { read_format(format) }?;
            let units = units_from(units, "units")?;
            // Troupe's axes (metres, Y up): what the BVH writer takes.
            let (names, clips) = unsafe {
                canonical_people(
                    positions,
                    n_people,
                    n_frames,
                    &format,
                    names,
                    MAX_BVH_PEOPLE,
                )
            }?;
            let people: Vec<BvhPerson> = clips
                .iter()
                .zip(&names)
                .map(|(c, n)| BvhPerson {
                    name: n,
                    positions: c,
                })
                .collect();
            let options = BvhWriteOptions {
                units,
                fps: format.fps,
                fit_skeleton: fit_skeleton != 0,
            };
            write_bvh_file(Path::new(path), &people, &options)?;
            Ok(())
        },
    )
}
