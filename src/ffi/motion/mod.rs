//! `troupe_motion_*`: the t2m-22 skeleton, joint positions to features and back, batch and
//! streaming. Every function that converts takes the model, so that the frame rate and feature
//! layout are the bundle's own.

use std::ffi::{c_char, CString};

use ndarray::ArrayView3;
use std::sync::OnceLock;

use ndarray::ArrayView2;

pub mod bvh;
pub mod export;
pub mod rig;

use crate::ffi::boundary::{
    self, check_struct_size, checked_mul, non_null, read_versioned, required, troupe_status,
    write_versioned, Exclusive, FfiError, FfiResult, TROUPE_ERR_BUFFER_TOO_SMALL,
    TROUPE_ERR_INVALID_ARG, TROUPE_ERR_SHAPE,
};
use crate::ffi::model::troupe_model;
use crate::motion::features::{encoded_frames, read_frame, MAX_CLIP_FRAMES};
use crate::motion::rotation::Quat;
use crate::motion::{
    decode_frame, encode_clip, joints_layout, FeatureStream, Handedness, JointsFormat, Placement,
    Pose, Skeleton, Units, UpAxis, T2M22_JOINTS,
};
use crate::Model;

/// Positions in metres.
pub const TROUPE_UNITS_METERS: u32 = 0;
/// Positions in centimetres.
pub const TROUPE_UNITS_CENTIMETERS: u32 = 1;
/// Positions in millimetres.
pub const TROUPE_UNITS_MILLIMETERS: u32 = 2;
/// Positions in inches.
pub const TROUPE_UNITS_INCHES: u32 = 3;
/// +Y is up (troupe, Unity, glTF, most BVH).
pub const TROUPE_UP_Y: u32 = 0;
/// +Z is up (SMPL raw data, Blender, ROS, Unreal); converted as `(x, y, z) -> (x, z, -y)`.
pub const TROUPE_UP_Z: u32 = 1;
/// Right-handed axes.
pub const TROUPE_RIGHT_HANDED: u32 = 0;
/// Left-handed axes (Unity, Unreal): x is negated first.
pub const TROUPE_LEFT_HANDED: u32 = 1;
/// Joints of the t2m-22 skeleton every `interhuman262` bundle speaks.
pub const TROUPE_MOTION_JOINTS: usize = 22;
const _: () = assert!(TROUPE_MOTION_JOINTS == T2M22_JOINTS);

/// How the caller measures joint positions. Fill with `troupe_joints_format_init` (metres, Y up,
/// right-handed, 30 fps), then change fields. Fields are only ever appended.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_joints_format {
    /// `sizeof(troupe_joints_format)` as the caller compiled it (set by `_init`).
    pub struct_size: u32,
    /// `TROUPE_UNITS_*`.
    pub units: u32,
    /// `TROUPE_UP_Y` or `TROUPE_UP_Z`.
    pub up_axis: u32,
    /// `TROUPE_RIGHT_HANDED` or `TROUPE_LEFT_HANDED`.
    pub handedness: u32,
    /// Frames per second of the caller's motion, in [1, 1000]; resampled to the bundle's rate.
    pub fps: f32,
    /// Must be 0.
    pub reserved: u32,
}

pub(crate) const FORMAT_V1_SIZE: usize = 24;
const _: () = assert!(std::mem::size_of::<troupe_joints_format>() == FORMAT_V1_SIZE);

/// Where a clip's canonical frame sits in the caller's world (InterGen's canonicalisation): the
/// floor height and first-frame root x, z in troupe's axes (metres, Y up), and the turn about +Y
/// that makes frame 0 face +Z. Written by `troupe_motion_encode` and the streams; pass it back to
/// put generated motion where the caller's was, and to put a second person in the first one's
/// frame. A plain value: copy it freely.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct troupe_placement {
    /// Floor height, metres.
    pub floor: f64,
    /// First-frame root x, metres.
    pub origin_x: f64,
    /// First-frame root z, metres.
    pub origin_z: f64,
    /// The turn as a unit quaternion `[w, x, y, z]`.
    pub heading: [f64; 4],
}

/// Where `troupe_motion_decode` writes each part of a pose; any pointer may be NULL (with
/// length 0) to skip that part. Lengths are in floats. Every part is in the caller's world and
/// axes.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct troupe_pose_buffers {
    /// Joint positions `[frames][22][3]`.
    pub positions: *mut f32,
    /// Length of `positions`.
    pub positions_len: usize,
    /// Rotations `[frames][22][4]` as `[w, x, y, z]`: joint 0 the root's world orientation, the
    /// others local to their parent.
    pub rotations: *mut f32,
    /// Length of `rotations`.
    pub rotations_len: usize,
    /// The same rotations as 6-D vectors `[frames][22][6]`.
    pub rotations_6d: *mut f32,
    /// Length of `rotations_6d`.
    pub rotations_6d_len: usize,
    /// Contacts `[frames][4]`: left ankle, left foot, right ankle, right foot.
    pub contacts: *mut f32,
    /// Length of `contacts`.
    pub contacts_len: usize,
}

/// A stream turning joint-position frames into feature frames for one person, used from one
/// thread at a time (a call while another thread uses it fails with `TROUPE_ERR_BUSY`). Free
/// with `troupe_motion_stream_free`; it does not need its model after creation.
pub struct troupe_motion_stream {
    stream: Exclusive<FeatureStream>,
    frame_dim: usize,
    /// The most feature frames one push gives (fixed by the format at creation).
    max_out_per_frame: usize,
}

impl troupe_joints_format {
    /// The C form of `format`, for a caller's struct of `size` bytes.
    pub(crate) fn from_rust(format: &JointsFormat, size: usize) -> Self {
        troupe_joints_format {
            struct_size: size.min(FORMAT_V1_SIZE) as u32,
            units: match format.units {
                Units::Meters => TROUPE_UNITS_METERS,
                Units::Centimeters => TROUPE_UNITS_CENTIMETERS,
                Units::Millimeters => TROUPE_UNITS_MILLIMETERS,
                Units::Inches => TROUPE_UNITS_INCHES,
            },
            up_axis: match format.up {
                UpAxis::Y => TROUPE_UP_Y,
                UpAxis::Z => TROUPE_UP_Z,
            },
            handedness: match format.handedness {
                Handedness::Right => TROUPE_RIGHT_HANDED,
                Handedness::Left => TROUPE_LEFT_HANDED,
            },
            fps: format.fps,
            reserved: 0,
        }
    }

    fn to_rust(self) -> FfiResult<JointsFormat> {
        let bad = |what: &str, v: u32| {
            FfiError::new(
                TROUPE_ERR_INVALID_ARG,
                format!("format.{what} is {v}, not a known code"),
            )
        };
        let units = match self.units {
            TROUPE_UNITS_METERS => Units::Meters,
            TROUPE_UNITS_CENTIMETERS => Units::Centimeters,
            TROUPE_UNITS_MILLIMETERS => Units::Millimeters,
            TROUPE_UNITS_INCHES => Units::Inches,
            v => return Err(bad("units", v)),
        };
        let up = match self.up_axis {
            TROUPE_UP_Y => UpAxis::Y,
            TROUPE_UP_Z => UpAxis::Z,
            v => return Err(bad("up_axis", v)),
        };
        let handedness = match self.handedness {
            TROUPE_RIGHT_HANDED => Handedness::Right,
            TROUPE_LEFT_HANDED => Handedness::Left,
            v => return Err(bad("handedness", v)),
        };
        if self.reserved != 0 {
            return Err(bad("reserved", self.reserved));
        }
        let format = JointsFormat {
            units,
            up,
            handedness,
            fps: self.fps,
        };
        format.validate()?;
        Ok(format)
    }
}

impl troupe_placement {
    pub(crate) fn to_rust(self, format: JointsFormat) -> FfiResult<Placement> {
        // `checked` refuses what is not finite, out of range, or not a unit heading; the
        // heading is normalised only once it is known to be one.
        let placement = Placement {
            format,
            floor: self.floor,
            origin: [self.origin_x, self.origin_z],
            heading: Quat::from_wxyz(self.heading),
        }
        .checked()?;
        Ok(Placement {
            heading: placement.heading.normalized(),
            ..placement
        })
    }

    pub(crate) fn from_rust(p: &Placement) -> Self {
        troupe_placement {
            floor: p.floor,
            origin_x: p.origin[0],
            origin_z: p.origin[1],
            heading: [p.heading.w, p.heading.x, p.heading.y, p.heading.z],
        }
    }
}

/// People's joint positions handed over by the caller: `[n_people][n_frames][22][3]` floats
/// with a name each.
pub(crate) struct People<'a> {
    /// Each person's name: from `names`, or `person1`, `person2`, ... where it is NULL (names
    /// that can prefix BVH joint names).
    pub names: Vec<String>,
    /// Each person's `[n_frames, 22, 3]` positions, borrowed from the caller.
    pub positions: Vec<ArrayView3<'a, f32>>,
}

/// Reads people's positions: `n_people` in 1..=`max_people`, `n_frames` in 1..=`max_frames`
/// (bounds checked before anything is read).
///
/// # Safety
/// `positions` readable for `n_people * n_frames * 66` floats; a non-NULL `names` readable for
/// `n_people` pointers, each NULL or NUL-terminated.
pub(crate) unsafe fn read_people<'a>(
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    names: *const *const c_char,
    max_people: usize,
    max_frames: usize,
) -> FfiResult<People<'a>> {
    if n_people == 0 || n_people > max_people {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("n_people is {n_people}; 1 to {max_people} people are allowed"),
        ));
    }
    if n_frames == 0 || n_frames > max_frames {
        return Err(FfiError::new(
            TROUPE_ERR_INVALID_ARG,
            format!("n_frames is {n_frames}; 1 to {max_frames} frames are allowed"),
        ));
    }
    let per_person = checked_mul(n_frames, 3 * T2M22_JOINTS, "n_frames * 66")?;
    let len = checked_mul(n_people, per_person, "n_people * n_frames * 66")?;
    // SAFETY: forwarded contract.
    let flat = unsafe { boundary::slice(positions, len, "positions") }?;
    let mut labels = Vec::with_capacity(n_people);
    for i in 0..n_people {
        let given = if names.is_null() {
            None
        } else {
            // SAFETY: `names` readable for `n_people` pointers; each NULL or NUL-terminated.
            unsafe { boundary::optional_str(names.add(i).read(), &format!("names[{i}]")) }?
        };
        labels.push(given.map_or_else(|| format!("person{}", i + 1), str::to_string));
    }
    let views = flat
        .chunks_exact(per_person)
        .map(|chunk| {
            ArrayView3::from_shape((n_frames, T2M22_JOINTS, 3), chunk).expect("length checked")
        })
        .collect();
    Ok(People {
        names: labels,
        positions: views,
    })
}

/// One person's frames of t2m-22 positions in troupe's axes.
pub(crate) type Clip = Vec<Vec<crate::motion::vec3::Vec3>>;

/// People's positions (`[n_people][n_frames][22][3]` in `format`, as `read_people` takes them)
/// in troupe's axes (metres, Y up), each frame checked, with their names.
///
/// # Safety
/// As `read_people`.
pub(crate) unsafe fn canonical_people(
    positions: *const f32,
    n_people: usize,
    n_frames: usize,
    format: &JointsFormat,
    names: *const *const c_char,
    max_people: usize,
) -> FfiResult<(Vec<String>, Vec<Clip>)> {
    // SAFETY: forwarded contract.
    let people = unsafe {
        read_people(
            positions,
            n_people,
            n_frames,
            names,
            max_people,
            MAX_CLIP_FRAMES,
        )
    }?;
    let clips = people
        .positions
        .iter()
        .enumerate()
        .map(|(i, person)| {
            person
                .outer_iter()
                .enumerate()
                .map(|(t, frame)| read_frame(format, frame, &format!("person {i}, frame {t}")))
                .collect::<crate::Result<Vec<_>>>()
        })
        .collect::<crate::Result<Vec<_>>>()?;
    Ok((people.names, clips))
}

/// The caller's placement, checked, or `None` for NULL.
///
/// # Safety
/// A non-NULL `placement` must be readable.
unsafe fn optional_placement(
    placement: *const troupe_placement,
    format: JointsFormat,
) -> FfiResult<Option<Placement>> {
    if placement.is_null() {
        return Ok(None);
    }
    // SAFETY: non-NULL, readable per the contract.
    Ok(Some(unsafe { placement.read_unaligned() }.to_rust(format)?))
}

/// Reads the caller's format, checked.
///
/// # Safety
/// A non-NULL `format` must be readable for its `struct_size` bytes.
pub(crate) unsafe fn read_format(format: *const troupe_joints_format) -> FfiResult<JointsFormat> {
    non_null(format, "format")?;
    // SAFETY: non-NULL, readable per the contract.
    let f = unsafe {
        read_versioned(
            format,
            FORMAT_V1_SIZE,
            || {
                Ok(troupe_joints_format::from_rust(
                    &JointsFormat::default(),
                    FORMAT_V1_SIZE,
                ))
            },
            "format",
            "troupe_joints_format_init",
        )
    }?;
    f.to_rust()
}

/// The model's rate, after checking its features are `interhuman262`.
fn motion_fps(model: &Model) -> FfiResult<f32> {
    joints_layout(&model.manifest().motion)?;
    Ok(model.fps() as f32)
}

/// Fills `*format` with the defaults: metres, Y up, right-handed, 30 fps. `format_size` is
/// `sizeof(troupe_joints_format)`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a size smaller than
/// the first version's). Thread-safe.
///
/// # Safety
/// `format` must be writable for `format_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn troupe_joints_format_init(
    format: *mut troupe_joints_format,
    format_size: usize,
) -> troupe_status {
    boundary::call(
        "troupe_joints_format_init",
        || {},
        || {
            non_null(format, "format")?;
            check_struct_size(format_size, FORMAT_V1_SIZE, "troupe_joints_format")?;
            let value = troupe_joints_format::from_rust(&JointsFormat::default(), format_size);
            // SAFETY: writable for `format_size` bytes per the contract.
            unsafe { write_versioned(format, format_size, &value) };
            Ok(())
        },
    )
}

/// Joints of the t2m-22 skeleton (22). Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_motion_joint_count() -> usize {
    T2M22_JOINTS
}

/// The name of t2m-22 joint `joint` (`"pelvis"`, `"left_hip"`, ...; SMPL's order), or NULL when
/// `joint >= 22`. Static storage: never free it. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_motion_joint_name(joint: usize) -> *const c_char {
    static NAMES: OnceLock<Vec<CString>> = OnceLock::new();
    boundary::get(std::ptr::null(), || {
        let names = NAMES.get_or_init(|| {
            Skeleton::t2m22()
                .names()
                .iter()
                .map(|n| CString::new(n.as_str()).expect("joint names have no NUL"))
                .collect()
        });
        names.get(joint).map_or(std::ptr::null(), |n| n.as_ptr())
    })
}

/// Writes the t2m-22 skeleton: `parents[22]` (each joint's parent, -1 for the root; parents
/// come before children) and `rest_offsets[22 * 3]` (each joint's rest offset from its parent in
/// metres, Y up, facing +Z, +X the body's left; the root's is its rest position). Either may be
/// NULL with length 0 to skip it.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a length other than 22 or
/// 66). Thread-safe.
///
/// # Safety
/// Non-NULL arrays must be writable for their lengths.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_skeleton(
    parents: *mut i32,
    parents_len: usize,
    rest_offsets: *mut f32,
    rest_offsets_len: usize,
) -> troupe_status {
    boundary::call(
        "troupe_motion_skeleton",
        || {},
        || {
            let skeleton = Skeleton::t2m22();
            let n = skeleton.len();
            let wanted = |ptr_null: bool, len: usize, want: usize, what: &str| -> FfiResult<bool> {
                match (ptr_null, len) {
                    (true, 0) => Ok(false),
                    (true, _) => Err(FfiError::new(
                        boundary::TROUPE_ERR_NULL_ARG,
                        format!("`{what}` is NULL"),
                    )),
                    (false, l) if l == want => Ok(true),
                    (false, l) => Err(FfiError::new(
                        TROUPE_ERR_SHAPE,
                        format!("{what}_len is {l}, the skeleton needs {want}"),
                    )),
                }
            };
            let want_parents = wanted(parents.is_null(), parents_len, n, "parents")?;
            let want_offsets = wanted(
                rest_offsets.is_null(),
                rest_offsets_len,
                3 * n,
                "rest_offsets",
            )?;
            if want_parents {
                for (j, p) in skeleton.parents().iter().enumerate() {
                    // SAFETY: writable for `n` entries (checked length, caller's contract).
                    unsafe { *parents.add(j) = p.map_or(-1, |p| p as i32) };
                }
            }
            if want_offsets {
                for (j, o) in skeleton.offsets().iter().enumerate() {
                    for (d, v) in o.iter().enumerate() {
                        // SAFETY: writable for `3 n` floats.
                        unsafe { *rest_offsets.add(3 * j + d) = *v as f32 };
                    }
                }
            }
            Ok(())
        },
    )
}

/// Poses MAGNet frames on the t2m-22 skeleton: `frames` holds `n_frames` frames of one person in
/// the `magnet-smplx145` layout (145 floats each, row-major: betas, the 21 body joints' 6-D
/// rotations, the pelvis's pose in the world), and `positions` receives `[n_frames][22][3]`
/// joint positions (metres, Y up, the frames' world; `positions_len` = `n_frames * 66`). The
/// bone lengths are troupe's neutral body's, not the person's betas. For pictures
/// (`troupe_viewer_write`), BVH files and JSON poses of a MAGNet output.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (`positions_len`),
/// `TROUPE_ERR_INVALID_ARG` (a NaN or infinite value, a degenerate rotation). On error nothing is
/// written. Thread-safe.
///
/// # Safety
/// `frames` readable for `n_frames * 145` floats; `positions` writable for `positions_len`
/// floats and not overlapping `frames`.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_smplx145_positions(
    frames: *const f32,
    n_frames: usize,
    positions: *mut f32,
    positions_len: usize,
) -> troupe_status {
    boundary::call(
        "troupe_motion_smplx145_positions",
        || {},
        || {
            let n = boundary::checked_mul(n_frames, crate::motion::SMPLX145_DIM, "n_frames")?;
            let want = boundary::checked_mul(n_frames, 3 * T2M22_JOINTS, "n_frames")?;
            if positions_len != want {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!("positions_len is {positions_len}, {n_frames} frames need {want}"),
                ));
            }
            // SAFETY: readable for `n` floats per the contract.
            let frames = unsafe { boundary::slice(frames, n, "frames") }?;
            let posed = crate::motion::smplx145_positions(frames, &Skeleton::t2m22())?;
            if want > 0 {
                non_null(positions, "positions")?;
            }
            for (i, v) in posed.iter().flatten().flatten().enumerate() {
                // SAFETY: writable for `want` floats (checked length, caller's contract).
                unsafe { *positions.add(i) = *v as f32 };
            }
            Ok(())
        },
    )
}

/// How much two people's bodies pass through each other (`docs/ARFLOW.md`): `first` and
/// `second` hold `n_frames` frames of t2m-22 joint positions each (row-major float32
/// `[n_frames][22][3]`, metres, Y up, one world), each person's joints are tested against the
/// other's body (one capsule per bone), and the results go to the non-NULL out-pointers:
/// `*frames_intersecting` (frames where a joint lies inside the other body), `*frequency` (their
/// share, 0 for no frames), `*depth_sum` (the depths of every such joint, summed over joints and
/// frames, metres: the intersection volume's proxy) and `*max_depth` (metres).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a NaN or infinite
/// value). On error nothing is written. Thread-safe.
///
/// # Safety
/// `first` and `second` readable for `n_frames * 66` floats; each non-NULL out-pointer writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_penetration_metrics(
    first: *const f32,
    second: *const f32,
    n_frames: usize,
    frames_intersecting: *mut usize,
    frequency: *mut f64,
    depth_sum: *mut f64,
    max_depth: *mut f64,
) -> troupe_status {
    boundary::call(
        "troupe_motion_penetration_metrics",
        || {},
        || {
            let n = checked_mul(n_frames, 3 * T2M22_JOINTS, "n_frames * 66")?;
            // SAFETY: readable for `n` floats each, per the contract.
            let (a, b) = unsafe {
                (
                    boundary::slice(first, n, "first")?,
                    boundary::slice(second, n, "second")?,
                )
            };
            let joints = |v: &[f32]| -> Vec<Vec<[f64; 3]>> {
                v.chunks_exact(3 * T2M22_JOINTS)
                    .map(|f| {
                        f.chunks_exact(3)
                            .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
                            .collect()
                    })
                    .collect()
            };
            let m = crate::motion::penetration_metrics(
                &crate::motion::BodyModel::t2m22(),
                &joints(a),
                &joints(b),
            )?;
            // SAFETY: each non-NULL out-pointer is writable per the contract.
            unsafe {
                if !frames_intersecting.is_null() {
                    *frames_intersecting = m.frames_intersecting;
                }
                for (out, v) in [
                    (frequency, m.frequency),
                    (depth_sum, m.depth_sum),
                    (max_depth, m.max_depth),
                ] {
                    if !out.is_null() {
                        *out = v;
                    }
                }
            }
            Ok(())
        },
    )
}

/// Writes to `*n_frames_out` how many feature frames `troupe_motion_encode` gives for a clip of
/// `n_frames` position frames measured as `format` says: the clip resampled to the bundle's
/// rate, less one (velocities look one frame ahead).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad format, more
/// frames than `troupe_motion_encode` takes, or a bundle whose features are not
/// `interhuman262`). Thread-safe.
///
/// # Safety
/// `format` readable, `n_frames_out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_encoded_frames(
    model: Option<&troupe_model>,
    format: *const troupe_joints_format,
    n_frames: usize,
    n_frames_out: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_motion_encoded_frames",
        || {},
        || {
            let model = &required(model, "model")?.model;
            non_null(n_frames_out, "n_frames_out")?;
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            let fps = motion_fps(model)?;
            let n = encoded_frames(format.fps, fps, n_frames);
            if n >= MAX_CLIP_FRAMES {
                return Err(FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    format!(
                        "{n_frames} frames at {} fps: longer at {fps} fps than the \
                         {MAX_CLIP_FRAMES} frames troupe encodes",
                        format.fps
                    ),
                ));
            }
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *n_frames_out = n };
            Ok(())
        },
    )
}

/// Turns a clip of joint positions (`positions`: float32 `[n_frames][22][3]` measured as
/// `format` says) into the bundle's features (`features_out`: `[frames][frame_dim]`, capacity
/// `out_capacity_frames` frames; the count goes to `*n_written`, see
/// `troupe_motion_encoded_frames`). The clip is resampled to the bundle's rate and put in its
/// canonical frame: InterGen's (floor under the clip's lowest joint, origin and facing from
/// frame 0) when `placement` is NULL, else the given one (e.g. the first person's, for the
/// second). The placement used is written to `placement_out` unless it is NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
/// positions, naming frame and joint; a clip too short; a bad format or placement; a bundle
/// whose features are not `interhuman262`), `TROUPE_ERR_BUFFER_TOO_SMALL`, `TROUPE_ERR_PANIC`.
/// Nothing is written on error. Thread-safe.
///
/// # Safety
/// `positions` readable for `n_frames * 66` floats; `features_out` writable for
/// `out_capacity_frames * frame_dim` floats; the rest readable/writable as their types say.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn troupe_motion_encode(
    model: Option<&troupe_model>,
    format: *const troupe_joints_format,
    positions: *const f32,
    n_frames: usize,
    placement: *const troupe_placement,
    features_out: *mut f32,
    out_capacity_frames: usize,
    n_written: *mut usize,
    placement_out: *mut troupe_placement,
) -> troupe_status {
    boundary::call(
        "troupe_motion_encode",
        || {},
        || {
            let model = &required(model, "model")?.model;
            non_null(n_written, "n_written")?;
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            let fps = motion_fps(model)?;
            // SAFETY: forwarded contract.
            let given = unsafe { optional_placement(placement, format) }?;
            let len = checked_mul(n_frames, 3 * T2M22_JOINTS, "n_frames * 66")?;
            // SAFETY: forwarded contract.
            let flat = unsafe { boundary::slice(positions, len, "positions") }?;
            let view = ArrayView3::from_shape((n_frames, T2M22_JOINTS, 3), flat)
                .expect("length checked above");
            let needed = encoded_frames(format.fps, fps, n_frames);
            if needed > out_capacity_frames {
                return Err(FfiError::new(
                TROUPE_ERR_BUFFER_TOO_SMALL,
                format!("this clip gives {needed} frames, the output buffer holds {out_capacity_frames}"),
            ));
            }
            let encoded = encode_clip(view, format, fps, given.as_ref())?;
            let values = encoded.features.as_slice().expect("standard layout");
            if !values.is_empty() {
                non_null(features_out, "features_out")?;
                // SAFETY: writable for out_capacity_frames >= needed frames of frame_dim floats.
                unsafe {
                    std::ptr::copy_nonoverlapping(values.as_ptr(), features_out, values.len())
                };
            }
            // SAFETY: checked non-NULL / NULL-tolerant, writable per the contract.
            unsafe {
                *n_written = encoded.features.nrows();
                if !placement_out.is_null() {
                    placement_out.write_unaligned(troupe_placement::from_rust(&encoded.placement));
                }
            }
            Ok(())
        },
    )
}

/// The four parts of `troupe_pose_buffers`, checked: each NULL with length 0 (skipped) or
/// holding `frames` frames of its part (exactly, or at least when `exact` is false: a step's
/// capacity).
pub(crate) struct PoseParts<'a>([Option<&'a mut [f32]>; 4]);

/// Floats per frame of each part: positions, rotations, 6-D rotations, contacts.
const PART_FLOATS: [usize; 4] = [3 * T2M22_JOINTS, 4 * T2M22_JOINTS, 6 * T2M22_JOINTS, 4];
const PART_NAMES: [&str; 4] = ["positions", "rotations", "rotations_6d", "contacts"];

impl PoseParts<'_> {
    /// Checks the buffers of `out` for `frames` frames.
    ///
    /// # Safety
    /// `out` readable; its non-NULL buffers writable for their lengths for the call.
    pub(crate) unsafe fn check<'a>(
        out: *const troupe_pose_buffers,
        frames: usize,
        exact: bool,
    ) -> FfiResult<PoseParts<'a>> {
        non_null(out, "out")?;
        // SAFETY: non-NULL, readable per the contract.
        let out = unsafe { out.read_unaligned() };
        let raw = [
            (out.positions, out.positions_len),
            (out.rotations, out.rotations_len),
            (out.rotations_6d, out.rotations_6d_len),
            (out.contacts, out.contacts_len),
        ];
        let mut parts: [Option<&'a mut [f32]>; 4] = [None, None, None, None];
        for (k, (ptr, len)) in raw.into_iter().enumerate() {
            let what = PART_NAMES[k];
            if ptr.is_null() && len == 0 {
                continue;
            }
            non_null(ptr, what)?;
            let want = checked_mul(frames, PART_FLOATS[k], what)?;
            if len < want || (exact && len != want) {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!("{what}_len is {len}, {frames} frames need {want}"),
                ));
            }
            // SAFETY: non-NULL, writable for `len` floats per the contract.
            parts[k] = Some(unsafe { std::slice::from_raw_parts_mut(ptr, len) });
        }
        Ok(PoseParts(parts))
    }

    /// Writes `poses` from the start of each part.
    pub(crate) fn fill(self, poses: &[Pose]) {
        for (k, part) in self.0.into_iter().enumerate() {
            let Some(buffer) = part else { continue };
            for (pose, dst) in poses.iter().zip(buffer.chunks_exact_mut(PART_FLOATS[k])) {
                let src: &[f32] = match k {
                    0 => pose.positions.as_flattened(),
                    1 => pose.rotations.as_flattened(),
                    2 => pose.rotations_6d.as_flattened(),
                    _ => &pose.contacts,
                };
                dst.copy_from_slice(src);
            }
        }
    }
}

/// Turns `n_frames` feature frames (`features`: `[n_frames][frame_dim]`) into poses in the
/// caller's world: positions, rotations (quaternions and 6-D) and contacts, into the buffers of
/// `*out` (see `troupe_pose_buffers`), using the `placement` the actor's motion was encoded
/// with and the caller's axes and units from `format` (its `fps` is not used).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a buffer length other than
/// the frames need), `TROUPE_ERR_INVALID_ARG` (non-finite features, a bad format or placement, a
/// bundle whose features are not `interhuman262`), `TROUPE_ERR_PANIC`. Nothing is written on
/// error. Thread-safe.
///
/// # Safety
/// `features` readable for `n_frames * frame_dim` floats; `format`, `placement`, `out` readable;
/// the buffers in `out` writable for their lengths and not overlapping `features`.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_decode(
    model: Option<&troupe_model>,
    format: *const troupe_joints_format,
    placement: *const troupe_placement,
    features: *const f32,
    n_frames: usize,
    out: *const troupe_pose_buffers,
) -> troupe_status {
    boundary::call(
        "troupe_motion_decode",
        || {},
        || {
            let model = &required(model, "model")?.model;
            motion_fps(model)?;
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            non_null(placement, "placement")?;
            non_null(out, "out")?;
            // SAFETY: non-NULL, readable per the contract.
            let placement = unsafe { placement.read_unaligned() }.to_rust(format)?;
            let dim = model.frame_dim();
            let len = checked_mul(n_frames, dim, "n_frames * frame_dim")?;
            // SAFETY: forwarded contract.
            let flat = unsafe { boundary::slice(features, len, "features") }?;
            let frames = ArrayView2::from_shape((n_frames, dim), flat).expect("length checked");
            // Decode everything first so that nothing is written on error.
            let poses = frames
                .outer_iter()
                .enumerate()
                .map(|(t, row)| {
                    decode_frame(row, &placement).map_err(|e| {
                        FfiError::new(TROUPE_ERR_INVALID_ARG, format!("frame {t}: {e}"))
                    })
                })
                .collect::<FfiResult<Vec<_>>>()?;
            // SAFETY: forwarded contract on the buffers of `out`.
            unsafe { PoseParts::check(out, n_frames, true) }?.fill(&poses);
            Ok(())
        },
    )
}

/// Starts a stream turning one person's joint-position frames (measured as `format` says) into
/// the bundle's feature frames, for a session's actor input. The canonical frame is fixed by
/// the first frame (origin and facing as InterGen takes them, the floor under that frame's
/// lowest joint) unless `placement` is given (e.g. another person's). Feature frame t is ready
/// when position frame t + 1 has arrived: one frame of latency
/// (`troupe_motion_stream_latency_frames`). `*out` is set to NULL on entry and to the new
/// stream on success; free it with `troupe_motion_stream_free`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad format or
/// placement, a bundle whose features are not `interhuman262`), `TROUPE_ERR_PANIC`.
/// Thread-safe.
///
/// # Safety
/// `format` and a non-NULL `placement` readable; `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_stream_new(
    model: Option<&troupe_model>,
    format: *const troupe_joints_format,
    placement: *const troupe_placement,
    out: *mut *mut troupe_motion_stream,
) -> troupe_status {
    boundary::call(
        "troupe_motion_stream_new",
        || {},
        || {
            non_null(out, "out")?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { *out = std::ptr::null_mut() };
            let model = &required(model, "model")?.model;
            // SAFETY: forwarded contract.
            let format = unsafe { read_format(format) }?;
            let fps = motion_fps(model)?;
            // SAFETY: forwarded contract.
            let placement = unsafe { optional_placement(placement, format) }?;
            let stream = FeatureStream::new(format, fps, placement)?;
            let handle = Box::new(troupe_motion_stream {
                max_out_per_frame: stream.max_out_per_frame(),
                stream: Exclusive::new(stream),
                frame_dim: model.frame_dim(),
            });
            // SAFETY: as above.
            unsafe { *out = Box::into_raw(handle) };
            Ok(())
        },
    )
}

/// Frames of latency a stream adds (1): feature frame t needs position frame t + 1.
/// Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_motion_stream_latency_frames() -> usize {
    crate::motion::STREAM_LATENCY_FRAMES
}

/// The most feature frames one `troupe_motion_stream_push` writes (1 unless the caller's rate
/// is above the bundle's), or 0 for a NULL stream. Thread-safe.
#[no_mangle]
pub extern "C" fn troupe_motion_stream_max_frames(stream: Option<&troupe_motion_stream>) -> usize {
    boundary::get(0, || stream.map_or(0, |s| s.max_out_per_frame))
}

/// Feeds one frame of joint positions (`frame`: float32 `[22][3]`, `frame_len` = 66) and writes
/// the feature frames it completes into `features_out` (capacity `out_capacity_frames` frames of
/// `frame_dim` floats), their count into `*n_written` (0 for the first frame).
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (`frame_len` not 66),
/// `TROUPE_ERR_INVALID_ARG` (a NaN or infinite position, naming the joint; a first frame whose
/// hips give no facing), `TROUPE_ERR_BUFFER_TOO_SMALL` (capacity below
/// `troupe_motion_stream_max_frames`), `TROUPE_ERR_PANIC`. On error the stream is as before the
/// call. One thread at a time per stream.
///
/// # Safety
/// `stream` a live handle; `frame` readable for `frame_len` floats; `features_out` writable for
/// `out_capacity_frames * frame_dim` floats; `n_written` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_stream_push(
    stream: *mut troupe_motion_stream,
    frame: *const f32,
    frame_len: usize,
    features_out: *mut f32,
    out_capacity_frames: usize,
    n_written: *mut usize,
) -> troupe_status {
    boundary::call(
        "troupe_motion_stream_push",
        || {},
        || {
            // SAFETY: NULL or a live handle per the contract; shared access until claimed.
            let s = required(unsafe { stream.as_ref() }, "stream")?;
            non_null(n_written, "n_written")?;
            let mut feature_stream = s.stream.claim("the stream")?;
            if frame_len != 3 * T2M22_JOINTS {
                return Err(FfiError::new(
                    TROUPE_ERR_SHAPE,
                    format!("frame_len is {frame_len}, a t2m-22 frame has 66 floats"),
                ));
            }
            // SAFETY: forwarded contract.
            let flat = unsafe { boundary::slice(frame, frame_len, "frame") }?;
            let most = s.max_out_per_frame;
            if out_capacity_frames < most {
                return Err(FfiError::new(
                TROUPE_ERR_BUFFER_TOO_SMALL,
                format!("a push may give {most} frames, the output buffer holds {out_capacity_frames}"),
            ));
            }
            non_null(features_out, "features_out")?;
            let view = ArrayView2::from_shape((T2M22_JOINTS, 3), flat).expect("length checked");
            let rows = feature_stream.push(view)?;
            for (i, row) in rows.iter().enumerate() {
                // SAFETY: rows.len() <= most <= out_capacity_frames frames of frame_dim floats.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        row.as_ptr(),
                        features_out.add(i * s.frame_dim),
                        row.len(),
                    )
                };
            }
            // SAFETY: checked non-NULL.
            unsafe { *n_written = rows.len() };
            Ok(())
        },
    )
}

/// Writes the stream's placement (fixed by its first frame, or the one it was given) to `*out`.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no frame yet and no
/// placement given). One thread at a time per stream.
///
/// # Safety
/// `out` writable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_stream_placement(
    stream: Option<&troupe_motion_stream>,
    out: *mut troupe_placement,
) -> troupe_status {
    boundary::call(
        "troupe_motion_stream_placement",
        || {},
        || {
            let s = required(stream, "stream")?;
            non_null(out, "out")?;
            let stream = s.stream.claim("the stream")?;
            let p = stream.placement().ok_or_else(|| {
                FfiError::new(
                    TROUPE_ERR_INVALID_ARG,
                    "the stream has no placement before its first frame",
                )
            })?;
            // SAFETY: checked non-NULL, writable per the contract.
            unsafe { out.write_unaligned(troupe_placement::from_rust(p)) };
            Ok(())
        },
    )
}

/// Forgets the stream's motion and placement, as if new (keeping its format), or fixes the
/// placement to `placement` when it is not NULL.
///
/// Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad placement; the
/// stream is then unchanged). One thread at a time per stream.
///
/// # Safety
/// `stream` a live handle; a non-NULL `placement` readable.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_stream_reset(
    stream: *mut troupe_motion_stream,
    placement: *const troupe_placement,
) -> troupe_status {
    boundary::call(
        "troupe_motion_stream_reset",
        || {},
        || {
            // SAFETY: NULL or a live handle per the contract; shared access until claimed.
            let mut s = required(unsafe { stream.as_ref() }, "stream")?
                .stream
                .claim("the stream")?;
            // SAFETY: forwarded contract.
            let placement = unsafe { optional_placement(placement, s.format()) }?;
            Ok(s.reset(placement)?)
        },
    )
}

/// Frees a stream. NULL is a no-op.
///
/// # Safety
/// `stream` must be NULL or a live handle from `troupe_motion_stream_new`, not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn troupe_motion_stream_free(stream: *mut troupe_motion_stream) {
    // SAFETY: forwarded contract.
    unsafe { boundary::free_unless_busy(stream, |h| &h.stream, "troupe_motion_stream_free") }
}
