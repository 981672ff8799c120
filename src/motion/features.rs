//! The InterHuman 262-d feature layout (`interhuman262`): joint positions in, features out, and
//! back to a pose.
//!
//! Per frame, in the canonical frame of the clip (see [`Placement`]):
//!
//! | slice | content |
//! |---|---|
//! | `[0:66]` | 22 joint positions, metres |
//! | `[66:132]` | 22 joint velocities, `p[t+1] − p[t]` (metres per frame) |
//! | `[132:258]` | 6-D local rotations of joints 1–21 ([`SixD::InterleavedColumns`]) |
//! | `[258:262]` | contacts of left ankle, left foot, right ankle, right foot |
//!
//! InterGen reads the rotations from SMPL fits; troupe recovers them from positions by
//! inverse kinematics ([`crate::motion::ik`], which says what that can and cannot recover). A
//! foot joint is in contact when its squared step to the next frame is below 0.001 m² and its
//! height below 0.12 m (ankle) or 0.05 m (foot). Velocities and contacts need the next frame,
//! so a clip of `T` frames gives `T − 1` feature frames, and a stream emits frame `t` when frame
//! `t + 1` arrives.

use ndarray::{Array2, ArrayView1, ArrayView3};

use crate::motion::ik::inverse_kinematics;
use crate::motion::placement::Placement;
use crate::motion::resample::Resampler;
use crate::motion::rotation::{Quat, SixD};
use crate::motion::skeleton::{Skeleton, FOOT_JOINTS, T2M22, T2M22_JOINTS};
use crate::motion::vec3::{norm, sub, Vec3};
use crate::motion::world::{JointsFormat, MAX_WORLD_METRES};
use crate::shared::bundle_io::MotionSpec;
use crate::shared::error::{Error, Result};

/// The feature layout's name in bundle manifests.
pub const INTERHUMAN262: &str = "interhuman262";

/// Floats per frame of the `interhuman262` layout.
pub const FEATURE_DIM: usize = 262;

/// Where positions start in a feature frame.
pub const POSITIONS: usize = 0;
/// Where velocities start.
pub const VELOCITIES: usize = 66;
/// Where the 21 6-D rotations start.
pub const ROTATIONS: usize = 132;
/// Where the 4 contacts start.
pub const CONTACTS: usize = 258;

/// InterGen's contact threshold on the squared per-frame step of a foot joint, m².
pub const CONTACT_STEP2: f64 = 0.001;
/// InterGen's contact height thresholds: ankle, then foot joint, metres.
pub const CONTACT_HEIGHTS: [f64; 2] = [0.12, 0.05];

/// The most frames one clip may have (after resampling): ten hours at 30 fps.
pub const MAX_CLIP_FRAMES: usize = 1_080_000;

/// Checks a bundle's motion section: `interhuman262` means 262 floats on the `t2m22` skeleton.
/// Other layouts pass (their bundles take features only), but [`joints_layout`] refuses them.
pub fn check_layout(spec: &MotionSpec) -> std::result::Result<(), String> {
    if spec.layout == INTERHUMAN262 && (spec.frame_dim != FEATURE_DIM || spec.skeleton() != T2M22) {
        return Err(format!(
            "motion: layout {INTERHUMAN262} has {FEATURE_DIM} floats per frame on skeleton \
             {T2M22}, the manifest says {} on {:?}",
            spec.frame_dim,
            spec.skeleton()
        ));
    }
    Ok(())
}

/// Refuses joint-position conversion for a bundle whose features are not `interhuman262`
/// (for instance Inter-X's SMPL-X rotations), naming the bundle's layout.
pub fn joints_layout(spec: &MotionSpec) -> Result<()> {
    if spec.layout != INTERHUMAN262 {
        return Err(Error::InvalidInput(format!(
            "the bundle's features are `{}`: joint positions convert to and from \
             `{INTERHUMAN262}` only",
            spec.layout
        )));
    }
    Ok(())
}

/// One frame of the `interhuman262` layout from the canonical positions of this frame and the
/// next, into `out` (262 floats).
pub(crate) fn feature_frame(skeleton: &Skeleton, now: &[Vec3], next: &[Vec3], out: &mut [f32]) {
    for j in 0..T2M22_JOINTS {
        for d in 0..3 {
            out[POSITIONS + 3 * j + d] = now[j][d] as f32;
            out[VELOCITIES + 3 * j + d] = (next[j][d] - now[j][d]) as f32;
        }
    }
    let rotations = inverse_kinematics(skeleton, now);
    for (j, q) in rotations.iter().enumerate().skip(1) {
        let six = q.to_6d(SixD::InterleavedColumns);
        for (d, v) in six.iter().enumerate() {
            out[ROTATIONS + 6 * (j - 1) + d] = *v as f32;
        }
    }
    out[CONTACTS..CONTACTS + 4].copy_from_slice(&contacts(now, next));
}

/// InterGen's foot contacts of a frame (canonical positions) given the next: left ankle, left
/// foot, right ankle, right foot; 1 when the joint's squared step is below [`CONTACT_STEP2`] and
/// its height below [`CONTACT_HEIGHTS`].
pub(crate) fn contacts(now: &[Vec3], next: &[Vec3]) -> [f32; 4] {
    std::array::from_fn(|k| {
        let joint = FOOT_JOINTS[k];
        let still = norm(sub(next[joint], now[joint])).powi(2) < CONTACT_STEP2;
        let low = now[joint][1] < CONTACT_HEIGHTS[k % 2];
        if still && low {
            1.0
        } else {
            0.0
        }
    })
}

/// Checks one caller frame (`[22, 3]`, finite) and returns it in canonical axes.
pub(crate) fn read_frame(
    format: &JointsFormat,
    frame: ndarray::ArrayView2<f32>,
    what: &str,
) -> Result<Vec<Vec3>> {
    if frame.shape() != [T2M22_JOINTS, 3] {
        return Err(Error::InvalidInput(format!(
            "{what}: joint positions must be [22, 3] (t2m-22 joints × xyz), got {:?}",
            frame.shape()
        )));
    }
    let mut out = Vec::with_capacity(T2M22_JOINTS);
    for (j, row) in frame.outer_iter().enumerate() {
        let p = [row[0], row[1], row[2]];
        if let Some(bad) = p.iter().find(|v| !v.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "{what}, joint {j} ({}): position {bad} is not finite",
                Skeleton::t2m22().names()[j]
            )));
        }
        let c = format.to_canonical_axes(p);
        if c.iter().any(|v| v.abs() > MAX_WORLD_METRES) {
            return Err(Error::InvalidInput(format!(
                "{what}, joint {j} ({}): position {p:?} is beyond troupe's {MAX_WORLD_METRES} m \
                 from the origin",
                Skeleton::t2m22().names()[j]
            )));
        }
        out.push(c);
    }
    Ok(out)
}

/// Feature frames a clip of `n` position frames at `fps_in` gives at `fps_out`: the clip's
/// length at the output rate, less one (velocities look one frame ahead).
pub fn encoded_frames(fps_in: f32, fps_out: f32, n: usize) -> usize {
    Resampler::output_len(fps_in, fps_out, n).saturating_sub(1)
}

/// A clip turned into features, with the placement that puts output back in the caller's world.
#[derive(Debug, Clone)]
pub struct EncodedClip {
    /// `[T' − 1, 262]` features, where `T'` is the clip's length at the output frame rate.
    pub features: Array2<f32>,
    /// The clip's canonical frame in the caller's world.
    pub placement: Placement,
}

/// Features of a clip of joint positions (`[T, 22, 3]`, measured as `format` says), resampled
/// to `fps` (the bundle's rate).
///
/// `placement`: `None` canonicalises the clip as InterGen does (floor under its lowest joint,
/// origin and facing from frame 0); `Some` puts it in a frame already chosen, e.g. the first
/// person's for the second person of an interaction.
pub fn encode_clip(
    positions: ArrayView3<f32>,
    format: JointsFormat,
    fps: f32,
    placement: Option<&Placement>,
) -> Result<EncodedClip> {
    format.validate()?;
    JointsFormat { fps, ..format }.validate()?;
    let shape = positions.shape();
    if shape[1..] != [T2M22_JOINTS, 3] {
        return Err(Error::InvalidInput(format!(
            "joint positions must be [frames, 22, 3] (t2m-22 joints × xyz), got {shape:?}"
        )));
    }
    let resampled_len = Resampler::output_len(format.fps, fps, shape[0]);
    if resampled_len < 2 {
        return Err(Error::InvalidInput(format!(
            "a clip of {} frame(s) at {} fps gives {resampled_len} frame(s) at {fps} fps; \
             features need at least 2 (velocities look one frame ahead)",
            shape[0], format.fps
        )));
    }
    if resampled_len > MAX_CLIP_FRAMES {
        return Err(Error::InvalidInput(format!(
            "a clip of {resampled_len} frames at {fps} fps is longer than the {MAX_CLIP_FRAMES} \
             troupe converts at once; stream it instead"
        )));
    }
    let mut resampler = Resampler::new(format.fps, fps);
    let mut frames = Vec::with_capacity(resampled_len);
    for (t, frame) in positions.outer_iter().enumerate() {
        resampler.push(
            read_frame(&format, frame, &format!("frame {t}"))?,
            &mut frames,
        );
    }
    let placement = match placement {
        Some(p) => Placement { format, ..*p }.checked()?,
        None => Placement::of_clip(format, &frames, None)?,
    };
    let canonical: Vec<Vec<Vec3>> = frames
        .iter()
        .map(|f| f.iter().map(|p| placement.to_frame(*p)).collect())
        .collect();
    let skeleton = Skeleton::t2m22();
    let mut features = Array2::<f32>::zeros((canonical.len() - 1, FEATURE_DIM));
    for (t, mut row) in features.outer_iter_mut().enumerate() {
        let out = row
            .as_slice_mut()
            .expect("rows of a fresh array are contiguous");
        feature_frame(&skeleton, &canonical[t], &canonical[t + 1], out);
    }
    Ok(EncodedClip {
        features,
        placement,
    })
}

/// One frame of motion as an engine or a robot consumes it, in the caller's world and axes.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// World positions of the 22 joints.
    pub positions: [[f32; 3]; T2M22_JOINTS],
    /// Rotations as unit quaternions `[w, x, y, z]`: joint 0's is the root's world orientation,
    /// every other joint's is local (relative to its parent), as SMPL, BVH and engines use.
    pub rotations: [[f32; 4]; T2M22_JOINTS],
    /// The same rotations as 6-D vectors ([`SixD::InterleavedColumns`]).
    pub rotations_6d: [[f32; 6]; T2M22_JOINTS],
    /// Contact of left ankle, left foot, right ankle, right foot, as the features hold them (a
    /// generated value near 1 means contact).
    pub contacts: [f32; 4],
}

impl Pose {
    /// The root's world position (joint 0).
    pub fn root_translation(&self) -> [f32; 3] {
        self.positions[0]
    }

    /// The root's world orientation (joint 0's rotation).
    pub fn root_rotation(&self) -> [f32; 4] {
        self.rotations[0]
    }
}

/// A decoded frame in the stream's canonical frame (metres, Y up, the floor at 0), before it
/// is put back in the caller's world: what clean-ups such as the foot lock work on.
#[derive(Debug, Clone, PartialEq)]
pub struct CanonicalPose {
    /// The 22 joint positions.
    pub positions: [Vec3; T2M22_JOINTS],
    /// Joint 0's world orientation, then every other joint's local rotation.
    pub rotations: [Quat; T2M22_JOINTS],
    /// Contact of left ankle, left foot, right ankle, right foot, as the features hold them.
    pub contacts: [f32; 4],
}

impl CanonicalPose {
    /// The pose put back in the caller's world by `placement`.
    pub fn placed(&self, placement: &Placement) -> Pose {
        let mut pose = Pose {
            positions: [[0.0; 3]; T2M22_JOINTS],
            rotations: [[0.0; 4]; T2M22_JOINTS],
            rotations_6d: [[0.0; 6]; T2M22_JOINTS],
            contacts: self.contacts,
        };
        for j in 0..T2M22_JOINTS {
            pose.positions[j] = placement.frame_to_world(self.positions[j]);
            let q = if j == 0 {
                placement.rotation_to_world(self.rotations[0])
            } else {
                placement.local_rotation_to_world(self.rotations[j])
            };
            pose.rotations[j] = q.to_wxyz().map(|v| v as f32);
            pose.rotations_6d[j] = q.to_6d(SixD::InterleavedColumns).map(|v| v as f32);
        }
        pose
    }
}

/// One `interhuman262` feature frame as a [`CanonicalPose`].
///
/// Positions come from `[0:66]`; local rotations from the frame's own 6-D values (a degenerate
/// 6-D vector, which no rotation produces, decodes to no rotation); the root's orientation,
/// which the layout does not store, from the hips and spine as inverse kinematics finds it.
/// Refused when the frame has the wrong length or a value that is not finite.
pub fn decode_canonical(frame: ArrayView1<f32>) -> Result<CanonicalPose> {
    if frame.len() != FEATURE_DIM {
        return Err(Error::InvalidInput(format!(
            "an interhuman262 frame has {FEATURE_DIM} floats, got {}",
            frame.len()
        )));
    }
    if let Some((i, v)) = frame.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "feature {i} of the frame is {v}, not finite"
        )));
    }
    let positions: [Vec3; T2M22_JOINTS] =
        std::array::from_fn(|j| std::array::from_fn(|d| f64::from(frame[POSITIONS + 3 * j + d])));
    let root = Skeleton::t2m22()
        .branch_world_rotation(0, &positions)
        .unwrap_or(Quat::IDENTITY);
    let rotations = std::array::from_fn(|j| {
        if j == 0 {
            return root;
        }
        let six: [f64; 6] = std::array::from_fn(|d| f64::from(frame[ROTATIONS + 6 * (j - 1) + d]));
        Quat::from_6d(six, SixD::InterleavedColumns).unwrap_or(Quat::IDENTITY)
    });
    Ok(CanonicalPose {
        positions,
        rotations,
        contacts: std::array::from_fn(|k| frame[CONTACTS + k]),
    })
}

/// The pose of one `interhuman262` feature frame, put back in the caller's world by
/// `placement` ([`decode_canonical`], then [`CanonicalPose::placed`]).
pub fn decode_frame(frame: ArrayView1<f32>, placement: &Placement) -> Result<Pose> {
    Ok(decode_canonical(frame)?.placed(placement))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(layout: &str, frame_dim: usize, skeleton: Option<&str>) -> MotionSpec {
        MotionSpec {
            layout: layout.into(),
            frame_dim,
            fps: 30,
            declared_skeleton: skeleton.map(String::from),
        }
    }

    #[test]
    fn manifests_declare_a_layout_and_the_skeleton_it_is_on() {
        assert!(check_layout(&spec("interhuman262", 262, None)).is_ok());
        assert!(check_layout(&spec("interhuman262", 262, Some("t2m22"))).is_ok());
        let err = check_layout(&spec("interhuman262", 262, Some("smplx55"))).unwrap_err();
        assert!(
            err.contains("skeleton t2m22") && err.contains("smplx55"),
            "{err}"
        );
        assert!(check_layout(&spec("interhuman262", 263, None)).is_err());
        assert!(check_layout(&spec("interx336", 336, None)).is_ok());
        assert_eq!(spec("interx336", 336, None).skeleton(), "smplx55");
        let err = joints_layout(&spec("interx336", 336, None))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("interx336") && err.contains("interhuman262"),
            "{err}"
        );
    }
}
