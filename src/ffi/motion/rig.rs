//! `troupe_rig_*` and `troupe_gltf_write`: a caller's character rig, troupe's motion retargeted
//! onto it (one frame at a time or a whole clip), and glTF, BVH and FBX files of it.

use std::ffi::{c_char, CString};
use std::path::Path;

use super::bvh::{units_from, TROUPE_UNITS_AUTO};
use super::{canonical_people, read_format, troupe_joints_format, Clip};
use crate::ffi::boundary::{
    self, non_null, required, troupe_status, Exclusive, FfiError, FfiResult,
    TROUPE_ERR_BUFFER_TOO_SMALL, TROUPE_ERR_INVALID_ARG, TROUPE_ERR_SHAPE,
};
use crate::motion::bvh::{write_rig_bvh_file, BvhWriteOptions};
use crate::motion::fbx::{write_rig_fbx_file, FbxWriteOptions};
use crate::motion::features::read_frame;
use crate::motion::gltf::PERSON_COLORS;
use crate::motion::read_motion_file;
use crate::motion::retarget::{retarget_clip, RetargetOptions, Retargeter, SourceFrame};
use crate::motion::{
    read_gltf_rig_file, write_glb_file, GltfOptions, GltfPerson, JointMap, JointsFormat, Rig,
    RigPose, Skeleton, T2M22_JOINTS,
};

/// `troupe_rig_from_bvh`: the rest pose is the file's all-zero pose (its offsets).
pub const TROUPE_RIG_ZERO_POSE: u32 = 0xFFFF_FFFF;
/// Retargeting flag: do not pin feet in contact.
pub const TROUPE_RETARGET_NO_FOOT_LOCK: u32 = 1;
/// Retargeting flag: no two-bone IK for hands and feet (feet are then not pinned either).
pub const TROUPE_RETARGET_NO_LIMB_IK: u32 = 2;
/// `troupe_gltf_write` flag: no capsule bodies, the skeletons only.
pub const TROUPE_GLTF_NO_BODIES: u32 = 4;
const KNOWN_FLAGS: u32 =
    TROUPE_RETARGET_NO_FOOT_LOCK | TROUPE_RETARGET_NO_LIMB_IK | TROUPE_GLTF_NO_BODIES;

/// The most people one glTF file troupe writes may hold.
const MAX_GLTF_PEOPLE: usize = 64;

/// A character rig with the joint map that says which of its joints is which t2m-22 joint.
/// Immutable: any thread may use it. Free with `troupe_rig_free`.
pub struct troupe_rig {
    rig: Rig,
    map: JointMap,
    names: Vec<CString>,
}

/// Retargeting one stream onto a rig, one frame at a time; used from one thread at a time (a
/// call while another thread uses it fails with `TROUPE_ERR_BUSY`). Free with
/// `troupe_rig_retargeter_free`; it does not need its rig afterwards.
pub struct troupe_rig_retargeter {
    state: Exclusive<(Retargeter, JointsFormat)>,
    joints: usize,
}

fn joint_map(json: *const c_char) -> FfiResult<JointMap> {
    if json.is_null() {
        return Ok(JointMap::builtin());
    }
    // SAFETY: a non-NULL `joint_map_json` is NUL-terminated per every caller's contract.
    Ok(JointMap::from_json(unsafe {
        boundary::required_str(json, "joint_map_json")
    }?)?)
}

/// [`options_from`] for the functions that write no glTF (`TROUPE_GLTF_NO_BODIES` refused).
fn retarget_options(flags: u32, fps: f32) -> FfiResult<RetargetOptions> {
    if flags & TROUPE_GLTF_NO_BODIES != 0 {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            "TROUPE_GLTF_NO_BODIES is a flag of troupe_gltf_write",
        ));
    }
    options_from(flags, fps)
}

fn options_from(flags: u32, fps: f32) -> FfiResult<RetargetOptions> {
    if flags & !KNOWN_FLAGS != 0 {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("flags {flags:#x} has bits that are not TROUPE_RETARGET_* or TROUPE_GLTF_*"),
        ));
    }
    Ok(RetargetOptions {
        foot_lock: flags & TROUPE_RETARGET_NO_FOOT_LOCK == 0,
        limb_ik: flags & TROUPE_RETARGET_NO_LIMB_IK == 0,
        fps,
        ..RetargetOptions::default()
    })
}

fn new_rig(rig: Rig, map: JointMap) -> FfiResult<*mut troupe_rig> {
    let names = rig
        .names()
        .iter()
        .map(|n| {
            CString::new(n.as_str()).map_err(|_| {
                FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    format!("joint name {n:?} holds a NUL"),
                )
            })
        })
        .collect::<FfiResult<_>>()?;
    Ok(Box::into_raw(Box::new(troupe_rig { rig, map, names })))
}

/// Reads the rig of the BVH or FBX file at `path` (UTF-8; told apart by content). `units`: the
/// file's length unit (`TROUPE_UNITS_*`, or `TROUPE_UNITS_AUTO` to guess from the rest pose's
/// height); an FBX file declares its own and is converted to `units` (metres for
/// `TROUPE_UNITS_AUTO`), its rest pose being its bind pose where it has one.
/// `rest_frame`: the frame whose pose is the rig's rest pose (for files whose all-zero pose lies
/// down, as LAFAN1's does), or `TROUPE_RIG_ZERO_POSE`. `joint_map_json`: which rig joint is
/// which t2m-22 joint (JSON), or NULL for the built-in names (Mixamo, LAFAN1, CMU, HumanIK,
/// SMPL, Rigify). `*out` is set to NULL on entry and to the rig on success.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO`, `TROUPE_ERR_INVALID_ARG` (a
/// malformed file, a frame past its end, a bad map or units), `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_from_bvh(
    path: *const c_char,
    units: u32,
    rest_frame: u32,
    joint_map_json: *const c_char,
    out: *mut *mut troupe_rig,
) -> troupe_status {
    boundary::call(
        "troupe_rig_from_bvh",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let units = match units {
                TROUPE_UNITS_AUTO => None,
                code => Some(units_from(code, "units")?),
            };
            let map = joint_map(joint_map_json)?;
            let bvh = read_motion_file(path, units)?;
            let rig = match rest_frame {
                TROUPE_RIG_ZERO_POSE => bvh.rig(units, path)?,
                frame => bvh.rig_at_frame(frame as usize, units, path)?,
            };
            let handle = new_rig(rig, map)?;
            // SAFETY: as above.
            unsafe { *out = handle };
            Ok(())
        },
    )
}

/// The rig of skin `skin` in the glTF file at `path` (UTF-8; `.glb`, or `.gltf` JSON): the
/// skin's joints with their nodes' hierarchy and transforms as the rest pose (metres, Y up),
/// with `joint_map_json` as in `troupe_rig_from_bvh`. `*out` is set to NULL on entry and to the
/// rig on success.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO`, `TROUPE_ERR_INVALID_ARG` (not
/// glTF, no such skin, joints that are no tree, scaled joints, a bad map), `TROUPE_ERR_PANIC`.
/// Thread-safe.
///
/// # Safety
/// `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_from_gltf(
    path: *const c_char,
    skin: usize,
    joint_map_json: *const c_char,
    out: *mut *mut troupe_rig,
) -> troupe_status {
    boundary::call(
        "troupe_rig_from_gltf",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let map = joint_map(joint_map_json)?;
            let handle = new_rig(read_gltf_rig_file(Path::new(path), skin)?, map)?;
            // SAFETY: as above.
            unsafe { *out = handle };
            Ok(())
        },
    )
}

/// A rig from its JSON document (`rig_json`: name, units, up axis, handedness, and joints with
/// parent, rest offset, optional rest rotation `[w, x, y, z]` and end site; see docs/RIGS.md),
/// with `joint_map_json` as in `troupe_rig_from_bvh`. `*out` is set to NULL on entry and to the
/// rig on success.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a malformed document or
/// map, naming what is wrong), `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `rig_json` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_from_json(
    rig_json: *const c_char,
    joint_map_json: *const c_char,
    out: *mut *mut troupe_rig,
) -> troupe_status {
    boundary::call(
        "troupe_rig_from_json",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            // SAFETY: forwarded contract.
            let text = unsafe { boundary::required_str(rig_json, "rig_json") }?;
            let rig = Rig::from_json(text)?;
            let handle = new_rig(rig, joint_map(joint_map_json)?)?;
            // SAFETY: as above.
            unsafe { *out = handle };
            Ok(())
        },
    )
}

/// Joints of a rig; 0 for NULL. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_rig_joint_count(rig: Option<&troupe_rig>) -> usize {
    boundary::get(0, || rig.map_or(0, |r| r.rig.len()))
}

/// The name of joint `joint` of a rig (UTF-8, owned by the rig, valid until it is freed), or
/// NULL for NULL or a joint past the end. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_rig_joint_name(rig: Option<&troupe_rig>, joint: usize) -> *const c_char {
    boundary::get(std::ptr::null(), || {
        rig.and_then(|r| r.names.get(joint))
            .map_or(std::ptr::null(), |n| n.as_ptr())
    })
}

/// Frees a rig. NULL is a no-op.
///
/// # Safety
/// `rig` NULL or a live handle from `troupe_rig_from_*`, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_free(rig: *mut troupe_rig) {
    if !rig.is_null() {
        // SAFETY: a live handle from Box::into_raw per the contract.
        boundary::get((), || drop(unsafe { Box::from_raw(rig) }));
    }
}

/// A retargeter of one stream onto `rig`: the stream's t2m-22 joint positions are in the
/// caller's world as `format` says (its `fps` sets contact speeds); `flags` is 0 or
/// `TROUPE_RETARGET_*` bits. `*out` is set to NULL on entry and to the retargeter on success.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a rig lacking a joint
/// retargeting needs, naming it and the names tried; a bad format or flags), `TROUPE_ERR_PANIC`.
/// Thread-safe.
///
/// # Safety
/// `format` readable; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_retargeter_new(
    rig: Option<&troupe_rig>,
    format: *const troupe_joints_format,
    flags: u32,
    out: *mut *mut troupe_rig_retargeter,
) -> troupe_status {
    boundary::call(
        "troupe_rig_retargeter_new",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let rig = required(rig, "rig")?;
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            let options = retarget_options(flags, format.fps)?;
            let retargeter = Retargeter::new(&rig.rig, &rig.map, &Skeleton::t2m22(), options)?;
            let handle = Box::new(troupe_rig_retargeter {
                joints: rig.rig.len(),
                state: Exclusive::new((retargeter, format)),
            });
            // SAFETY: as above.
            unsafe { *out = Box::into_raw(handle) };
            Ok(())
        },
    )
}

/// Poses the rig for the stream's next frame: `positions` holds its 22 t2m-22 joint positions
/// (`positions_len` = 66) in the caller's world; writes every rig joint's local rotation as
/// `[w, x, y, z]` in the rig's axes into `rotations` (`rotations_len` = joints × 4), the moving
/// joint's local translation (rig units and axes) into `root_translation` (3 floats), and that
/// joint's index into `*root_joint`. No latency: the pose is this frame's.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (other lengths),
/// `TROUPE_ERR_INVALID_ARG` (NaN or infinite positions; the stream is then unchanged),
/// `TROUPE_ERR_BUSY`, `TROUPE_ERR_PANIC`. One thread at a time per retargeter.
///
/// # Safety
/// `retargeter` a live handle; `positions` readable for `positions_len` floats; `rotations`
/// writable for `rotations_len` floats; `root_translation` writable for 3 floats; `root_joint`
/// writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_retarget_push(
    retargeter: *mut troupe_rig_retargeter,
    positions: *const f32,
    positions_len: usize,
    rotations: *mut f32,
    rotations_len: usize,
    root_translation: *mut f32,
    root_joint: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_rig_retarget_push",
        || {},
        || {
            // SAFETY: NULL or a live handle per the contract; shared access until claimed.
            let handle = required(unsafe { retargeter.as_ref() }, "retargeter")?;
            non_null(root_translation, "root_translation")?;
            non_null(root_joint, "root_joint")?;
            non_null(rotations, "rotations")?;
            let mut state = handle.state.claim("the retargeter")?;
            if positions_len != 3 * T2M22_JOINTS {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!("positions_len is {positions_len}, a t2m-22 frame has 66 floats"),
                ));
            }
            if rotations_len != 4 * handle.joints {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!(
                        "rotations_len is {rotations_len}, the rig's {} joints need {}",
                        handle.joints,
                        4 * handle.joints
                    ),
                ));
            }
            // SAFETY: forwarded contract.
            let flat = unsafe { boundary::slice(positions, positions_len, "positions") }?;
            let (retargeter, format) = &mut *state;
            let view =
                ndarray::ArrayView2::from_shape((T2M22_JOINTS, 3), flat).expect("length checked");
            let frame = read_frame(format, view, "positions")?;
            let pose = retargeter.push(&SourceFrame {
                positions: &frame,
                rotations: None,
                contacts: None,
            })?;
            for (j, q) in pose.rotations.iter().enumerate() {
                let v = [q.w, q.x, q.y, q.z].map(|x| x as f32);
                // SAFETY: writable for 4 × joints floats, checked above.
                unsafe { std::ptr::copy_nonoverlapping(v.as_ptr(), rotations.add(4 * j), 4) };
            }
            let t = pose.root_translation.map(|x| x as f32);
            // SAFETY: writable for 3 floats and one index per the contract.
            unsafe {
                std::ptr::copy_nonoverlapping(t.as_ptr(), root_translation, 3);
                *root_joint = pose.root;
            }
            Ok(())
        },
    )
}

/// Forgets the stream (foot pins, the previous frame), as if new.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_BUSY`. One thread at a time per
/// retargeter.
///
/// # Safety
/// `retargeter` a live handle.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_retarget_reset(
    retargeter: *mut troupe_rig_retargeter,
) -> troupe_status {
    boundary::call(
        "troupe_rig_retarget_reset",
        || {},
        || {
            // SAFETY: NULL or a live handle per the contract; shared access until claimed.
            let handle = required(unsafe { retargeter.as_ref() }, "retargeter")?;
            handle.state.claim("the retargeter")?.0.reset();
            Ok(())
        },
    )
}

/// How the retargeter mapped its rig: for each t2m-22 joint (the order
/// `troupe_rig_retarget_push` takes positions in), the index of the rig joint it drives
/// (`troupe_rig_joint_name` names it), or -1 where the rig has none and that joint drives
/// nothing. Found by the joint map's names, or by the rig's shape where the names fall short
/// (`docs/RIGS.md`): this shows the user which joint became which. Writes 22 values.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_BUFFER_TOO_SMALL` (`capacity` under
/// 22: nothing written), `TROUPE_ERR_BUSY`. One thread at a time per retargeter.
///
/// # Safety
/// `retargeter` a live handle; `rig_joints` writable for `capacity` values.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_retargeter_mapping(
    retargeter: *mut troupe_rig_retargeter,
    rig_joints: *mut i64,
    capacity: usize,
) -> troupe_status {
    boundary::call(
        "troupe_rig_retargeter_mapping",
        || {},
        || {
            // SAFETY: NULL or a live handle per the contract; shared access until claimed.
            let handle = required(unsafe { retargeter.as_ref() }, "retargeter")?;
            non_null(rig_joints, "rig_joints")?;
            let claimed = handle.state.claim("the retargeter")?;
            let mapping = claimed.0.rig_joints();
            if capacity < mapping.len() {
                return Err(FfiError::new(
                    TROUPE_ERR_BUFFER_TOO_SMALL,
                    format!(
                        "the mapping is {} values, the buffer holds {capacity}",
                        mapping.len()
                    ),
                ));
            }
            for (k, joint) in mapping.iter().enumerate() {
                let value = joint.map_or(-1, |j| j as i64);
                // SAFETY: writable for `capacity >= 22` values per the contract.
                unsafe { *rig_joints.add(k) = value };
            }
            Ok(())
        },
    )
}

/// Frees a retargeter. NULL is a no-op.
///
/// # Safety
/// `retargeter` NULL or a live handle from `troupe_rig_retargeter_new`, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_retargeter_free(retargeter: *mut troupe_rig_retargeter) {
    // SAFETY: forwarded contract.
    unsafe { boundary::free_unless_busy(retargeter, |h| &h.state, "troupe_rig_retargeter_free") }
}

/// Retargets a whole clip onto `rig`: `positions`, float32 `[n_frames][22][3]` in the caller's
/// world as `format` says, with `flags` (0 or `TROUPE_RETARGET_*`); the source's proportions are
/// measured from the clip first (a stream uses troupe's neutral body). Writes each frame's local
/// rotations `[n_frames][joints][4]` (`[w, x, y, z]`, the rig's axes) into `rotations`
/// (`rotations_len` = frames × joints × 4), the moving joint's local translations `[n_frames][3]`
/// (rig units and axes) into `root_translations` (`root_len` = frames × 3), and the moving
/// joint's index into `*root_joint`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (other lengths),
/// `TROUPE_ERR_INVALID_ARG` (as `troupe_rig_retargeter_new`; NaN or infinite positions; no
/// frames); on error nothing is written. `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `positions` readable for `n_frames * 66` floats; `format` readable; `rotations` and
/// `root_translations` writable for their lengths; `root_joint` writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_rig_retarget_clip(
    rig: Option<&troupe_rig>,
    positions: *const f32,
    n_frames: usize,
    format: *const troupe_joints_format,
    flags: u32,
    rotations: *mut f32,
    rotations_len: usize,
    root_translations: *mut f32,
    root_len: usize,
    root_joint: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_rig_retarget_clip",
        || {},
        || {
            let rig = required(rig, "rig")?;
            non_null(rotations, "rotations")?;
            non_null(root_translations, "root_translations")?;
            non_null(root_joint, "root_joint")?;
            // SAFETY (all): forwarded contract.
            let format = unsafe { read_format(format) }?;
            let options = retarget_options(flags, format.fps)?;
            let joints = rig.rig.len();
            let want_rotations =
                boundary::checked_mul(n_frames, 4 * joints, "n_frames * joints * 4")?;
            if rotations_len != want_rotations || root_len != 3 * n_frames {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!(
                        "rotations_len is {rotations_len} and root_len {root_len}; {n_frames} \
                         frames of {joints} joints need {want_rotations} and {}",
                        3 * n_frames
                    ),
                ));
            }
            let (_, clips) =
                unsafe { canonical_people(positions, 1, n_frames, &format, std::ptr::null(), 1) }?;
            let poses = retarget_clip(&rig.rig, &rig.map, &clips[0], None, options)?;
            for (t, pose) in poses.iter().enumerate() {
                for (j, q) in pose.rotations.iter().enumerate() {
                    let v = [q.w, q.x, q.y, q.z].map(|x| x as f32);
                    // SAFETY: writable for frames × joints × 4 floats, checked above.
                    unsafe {
                        std::ptr::copy_nonoverlapping(
                            v.as_ptr(),
                            rotations.add(4 * (t * joints + j)),
                            4,
                        )
                    };
                }
                let r = pose.root_translation.map(|x| x as f32);
                // SAFETY: writable for frames × 3 floats, checked above.
                unsafe {
                    std::ptr::copy_nonoverlapping(r.as_ptr(), root_translations.add(3 * t), 3)
                };
            }
            // SAFETY: writable per the contract.
            unsafe { *root_joint = poses[0].root };
            Ok(())
        },
    )
}

/// One person's clip for `troupe_gltf_write_people`: its own number of frames.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_person_clip {
    /// The person's name (NUL-terminated UTF-8), or NULL for "person1", "person2", ...
    pub name: *const c_char,
    /// t2m-22 joint positions, float32 `[n_frames][22][3]`, in the caller's world.
    pub positions: *const f32,
    /// Frames of `positions`, at least 1.
    pub n_frames: usize,
}

/// `troupe_gltf_write` for people of different lengths (a partner streamed back lags its actor
/// by the stream's latency): `people`, `n_people` clips, each with its own frames. Each person's
/// animation keeps its own keys, and a shorter one holds its last pose to the end of the longest,
/// as glTF clients hold a sampler past its last key. Nothing is trimmed or padded. The rest is as
/// `troupe_gltf_write` says: retargeted onto `rig` (NULL: troupe's own body), `format` for every
/// person (its `fps` the animation's rate), `flags` its bits.
///
/// Returns what `troupe_gltf_write` returns. Every buffer is borrowed for the call.
/// Thread-safe.
///
/// ```c
/// troupe_person_clip people[2] = {{"actor", actor, n_actor}, {"partner", partner, n_partner}};
/// troupe_status st = troupe_gltf_write_people("duet.glb", NULL, people, 2, &format, 0);
/// ```
///
/// # Safety
/// `path` NUL-terminated; `people` readable for `n_people` clips, each clip's `positions`
/// readable for `n_frames * 66` floats and its `name` NULL or NUL-terminated; `format` readable.
#[no_mangle]
pub unsafe extern "C" fn troupe_gltf_write_people(
    path: *const c_char,
    rig: Option<&troupe_rig>,
    people: *const troupe_person_clip,
    n_people: usize,
    format: *const troupe_joints_format,
    flags: u32,
) -> troupe_status {
    boundary::call(
        "troupe_gltf_write_people",
        || {},
        || {
            // SAFETY (all): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let format = unsafe { read_format(format) }?;
            let options = options_from(flags, format.fps)?;
            if n_people > MAX_GLTF_PEOPLE {
                return Err(FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    format!("{n_people} people, at most {MAX_GLTF_PEOPLE} in one file"),
                ));
            }
            let people = unsafe { boundary::slice(people, n_people, "people") }?;
            let mut names = Vec::with_capacity(people.len());
            let mut clips = Vec::with_capacity(people.len());
            for (k, person) in people.iter().enumerate() {
                // Each person read as a group of one, so every check and message is the same.
                let (mut name, mut clip) = unsafe {
                    canonical_people(
                        person.positions,
                        1,
                        person.n_frames,
                        &format,
                        &person.name,
                        1,
                    )
                }?;
                if person.name.is_null() {
                    name[0] = format!("person{}", k + 1);
                }
                names.append(&mut name);
                clips.append(&mut clip);
            }
            write_people(path, rig, &names, &clips, options, &format, flags)
        },
    )
}

/// Writes a glTF 2.0 binary file (`.glb`) at `path` (UTF-8; atomically): `n_people` people,
/// each retargeted onto `rig` (NULL: troupe's own t2m-22 body) from t2m-22 joint positions
/// `positions`, float32 `[n_people][n_frames][22][3]` in the caller's world as `format` says (its
/// `fps` becomes the animation's rate). Each person is a skeleton of nodes with a skin, a skinned
/// capsule body (unless `TROUPE_GLTF_NO_BODIES`) coloured per person, and channels of one
/// animation; `names` (NULL, or NULL entries, for "person1", ...) prefix node names when there
/// are several people (at most 64). `flags`: 0 or `TROUPE_RETARGET_*` and `TROUPE_GLTF_*` bits.
/// The file is in glTF's axes: metres, +Y up.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
/// positions, no people or frames, a bad format or flags, a rig lacking a joint retargeting
/// needs, something at `path` that is not a regular file), `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`.
/// Thread-safe.
///
/// # Safety
/// `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
/// readable; a non-NULL `names` readable for `n_people` pointers, each NULL or NUL-terminated.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_gltf_write(
    path: *const c_char,
    rig: Option<&troupe_rig>,
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    format: *const troupe_joints_format,
    names: *const *const c_char,
    flags: u32,
) -> troupe_status {
    boundary::call(
        "troupe_gltf_write",
        || {},
        || {
            // SAFETY (all): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let format = unsafe { read_format(format) }?;
            let options = options_from(flags, format.fps)?;
            let (names, clips) = unsafe {
                canonical_people(
                    positions,
                    n_people,
                    n_frames,
                    &format,
                    names,
                    MAX_GLTF_PEOPLE,
                )
            }?;
            write_people(path, rig, &names, &clips, options, &format, flags)
        },
    )
}

/// People's clips retargeted onto `rig` (None: troupe's own body) and written as a `.glb`.
fn write_people(
    path: &str,
    rig: Option<&troupe_rig>,
    names: &[String],
    clips: &[Clip],
    options: RetargetOptions,
    format: &JointsFormat,
    flags: u32,
) -> FfiResult<()> {
    let own;
    let (rig, map) = match rig {
        Some(r) => (&r.rig, &r.map),
        None => {
            own = (Rig::t2m22(), JointMap::builtin());
            (&own.0, &own.1)
        }
    };
    let poses = clips
        .iter()
        .map(|clip| retarget_clip(rig, map, clip, None, options))
        .collect::<crate::Result<Vec<_>>>()?;
    let people: Vec<GltfPerson> = names
        .iter()
        .zip(&poses)
        .enumerate()
        .map(|(k, (name, poses))| GltfPerson {
            name,
            rig,
            poses,
            color: PERSON_COLORS[k % PERSON_COLORS.len()],
        })
        .collect();
    let gltf = GltfOptions {
        fps: format.fps,
        bodies: flags & TROUPE_GLTF_NO_BODIES == 0,
    };
    write_glb_file(Path::new(path), &people, &gltf)?;
    Ok(())
}

/// Writes a BVH file at `path` (UTF-8; atomically) of `rig` posed by one person's t2m-22 joint
/// positions (`positions`, float32 `[n_frames][22][3]` in the caller's world as `format` says;
/// its `fps` becomes the file's rate), retargeted with `flags` (0 or `TROUPE_RETARGET_*`). The
/// file has the rig's hierarchy and rest offsets in `units` (`TROUPE_UNITS_*`), Y up; each
/// joint's channels hold its whole local rotation.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (as
/// `troupe_gltf_write`; a joint name with spaces or braces), `TROUPE_ERR_IO`,
/// `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `path` NUL-terminated; `positions` readable for `n_frames * 66` floats; `format` readable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_bvh_write(
    path: *const c_char,
    rig: Option<&troupe_rig>,
    positions: *const f32,
    n_frames: usize,
    format: *const troupe_joints_format,
    units: u32,
    flags: u32,
) -> troupe_status {
    boundary::call(
        "troupe_rig_bvh_write",
        || {},
        || {
            // SAFETY (all): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let rig = required(rig, "rig")?;
            let (poses, format) =
                unsafe { retargeted_clip(rig, positions, n_frames, format, flags) }?;
            let units = units_from(units, "units")?;
            let bvh = BvhWriteOptions {
                units,
                fps: format.fps,
                fit_skeleton: false,
            };
            write_rig_bvh_file(Path::new(path), &rig.rig, &poses, &bvh)?;
            Ok(())
        },
    )
}

/// One person's t2m-22 clip retargeted onto `rig` with `flags`, and its format: what the rig
/// file writers write.
///
/// # Safety
/// As the writers': `positions` readable for `n_frames * 66` floats; `format` readable.
unsafe fn retargeted_clip(
    rig: &troupe_rig,
    positions: *const f32,
    n_frames: usize,
    format: *const troupe_joints_format,
    flags: u32,
) -> FfiResult<(Vec<RigPose>, JointsFormat)> {
    // SAFETY (all): forwarded contract.
    let format = unsafe { read_format(format) }?;
    let options = retarget_options(flags, format.fps)?;
    let (_, clips) =
        unsafe { canonical_people(positions, 1, n_frames, &format, std::ptr::null(), 1) }?;
    let poses = retarget_clip(&rig.rig, &rig.map, &clips[0], None, options)?;
    Ok((poses, format))
}

/// Writes a binary FBX 7.4 file at `path` (UTF-8; atomically) of `rig` posed by one person's t2m-22 joint
/// positions (`positions`, float32 `[n_frames][22][3]` in the caller's world as `format` says;
/// its `fps` becomes the file's rate), retargeted with `flags` (0 or `TROUPE_RETARGET_*`). The
/// file has the rig's skeleton (`LimbNode`s, its rest pose as their transforms, `_end` leaves
/// at its end sites) in `units` (`TROUPE_UNITS_*`; FBX's own is centimetres), Y up, and one
/// animation with a key per frame: every joint's rotation, the moving joint's translation.
/// Blender, Unity, Unreal and Maya import it; `troupe_rig_from_bvh` reads it back.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (as
/// `troupe_gltf_write`; a joint name holding the bytes 0 or 1), `TROUPE_ERR_IO`,
/// `TROUPE_ERR_PANIC`. Thread-safe.
///
/// # Safety
/// `path` NUL-terminated; `positions` readable for `n_frames * 66` floats; `format` readable.
#[no_mangle]
pub unsafe extern "C" fn troupe_rig_fbx_write(
    path: *const c_char,
    rig: Option<&troupe_rig>,
    positions: *const f32,
    n_frames: usize,
    format: *const troupe_joints_format,
    units: u32,
    flags: u32,
) -> troupe_status {
    boundary::call(
        "troupe_rig_fbx_write",
        || {},
        || {
            // SAFETY (all): forwarded contract.
            let path = unsafe { boundary::required_str(path, "path") }?;
            let rig = required(rig, "rig")?;
            let (poses, format) =
                unsafe { retargeted_clip(rig, positions, n_frames, format, flags) }?;
            let units = units_from(units, "units")?;
            let fbx = FbxWriteOptions {
                units,
                fps: format.fps,
            };
            write_rig_fbx_file(Path::new(path), &rig.rig, &poses, &fbx)?;
            Ok(())
        },
    )
}
