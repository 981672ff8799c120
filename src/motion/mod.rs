//! Motion people have, in and out: skeletons, joint positions in a caller's world, and the
//! feature vectors the networks speak.
//!
//! A layer beside `crate::shared`: it knows no model family, and every family may use it.
//!
//! - [`skeleton`]: the t2m-22 skeleton as data (names, parents, rest offsets of a neutral body);
//! - [`body`]: the body as capsules over the joints, signed distances and their gradients;
//! - [`penetration`]: bodies passing through each other: a loss, its gradient, metrics;
//! - [`world`]: how a caller measures positions (units, up axis, handedness, frame rate);
//! - [`placement`]: InterGen's canonical frame of a clip, kept to put output back;
//! - [`ik`]: joint rotations from positions and back;
//! - [`features`]: the `interhuman262` layout, positions to features and features to a pose;
//! - [`stream`]: the same one frame at a time, for sessions, and [`foot_lock`]: generated feet
//!   kept still while their contact labels are on;
//! - [`resample`]: frame-rate conversion at the boundary;
//! - [`bvh`]: BVH files in and out, [`joint_map`]: which rig joint is which t2m-22 joint, and
//!   [`joint_inference`]: the t2m-22 joints a rig lacks, placed from those it has;
//! - [`rig`]: a caller's character rig, and [`retarget`]: troupe's motion posed on it;
//! - [`export`]: poses as JSON for robots and tools, and [`gltf`]: rigs and motion as `.glb`;
//! - [`smplx145`]: MAGNet's SMPL-X frames, posed on the t2m-22 skeleton;
//! - [`rotation`]: quaternions, matrices and both 6-D layouts, in f64 and (for MAGNet) f32;
//! - [`vec3`]: the vector algebra beneath.

pub mod body;
pub mod bvh;
pub mod export;
pub mod fbx;
pub mod features;
pub mod foot_lock;
pub mod gltf;
pub mod ik;
pub mod joint_inference;
pub mod joint_map;
pub mod penetration;
pub mod placement;
pub mod resample;
pub mod retarget;
pub mod rig;
pub mod rotation;
pub(crate) mod shape_map;
pub mod skeleton;
pub mod smplx145;
pub mod stream;
pub mod vec3;
pub mod world;

pub use body::{BodyModel, Capsule, SignedDistance};
pub use features::{
    check_layout, decode_canonical, decode_frame, encode_clip, joints_layout, CanonicalPose,
    EncodedClip, Pose, FEATURE_DIM, INTERHUMAN262,
};
pub use foot_lock::{FootLock, FootLockOptions};
pub use gltf::{
    read_gltf_rig, read_gltf_rig_file, write_glb, write_glb_file, GltfOptions, GltfPerson,
};
pub use joint_map::JointMap;
pub use penetration::{
    penetration_metrics, Hinge, Penetration, PenetrationLoss, PenetrationMetrics,
};
pub use placement::Placement;
pub use retarget::{retarget_clip, RetargetOptions, Retargeter, SourceFrame};
pub use rig::{Rig, RigJoint, RigPose};
pub use skeleton::{Skeleton, T2M22, T2M22_JOINTS};
pub use smplx145::{smplx145_positions, smplx145_rotations, SMPLX145, SMPLX145_DIM};
pub use stream::{FeatureStream, STREAM_LATENCY_FRAMES};
pub use world::{Handedness, JointsFormat, Units, UpAxis};

/// Reads a skeleton's clip from a BVH or an FBX file, told apart by their content (not their
/// name), refusing anything that is not a regular file of at most 256 MiB. `units`: for FBX,
/// the unit the clip is given in (the file declares its own; metres when `None`); a BVH file's
/// numbers are read as they are, and `units` says later what they mean ([`bvh::Bvh::to_t2m22`],
/// [`bvh::Bvh::rig`]). Builds for wasm32 read BVH only.
pub fn read_motion_file(
    path: impl AsRef<std::path::Path>,
    units: Option<Units>,
) -> crate::shared::error::Result<bvh::Bvh> {
    let path = path.as_ref();
    let bytes = crate::shared::files::read_bounded(path, bvh::MAX_BVH_BYTES, "motion files")?;
    let label = path.display().to_string();
    #[cfg(not(target_arch = "wasm32"))]
    if fbx::is_fbx(&bytes) {
        return fbx::parse_fbx(&bytes, &label, units);
    }
    let _ = units;
    bvh::parse_bvh(&bytes, &label)
}

#[cfg(test)]
mod tests;
