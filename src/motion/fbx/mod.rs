//! FBX files, read as the clip of a skeleton: the same [`Bvh`](crate::motion::bvh::Bvh) value a BVH file gives, so that
//! everything troupe does with a BVH take or rig (t2m-22 joints, retargeting, rigs for the
//! writers) works on FBX too.
//!
//! Why ufbx: FBX is a closed format defined by what Autodesk's SDK does. ufbx (MIT, bound by its
//! authors' `ufbx` crate) reads binary and ASCII FBX of every version, applies the format's
//! transform rules (units and axes from the file's settings, rotation orders, pre- and
//! post-rotations, pivots and offsets, scale inheritance modes) and is fuzzed by its authors.
//! Its alternatives in Rust: `fbxcel` parses the binary node tree only (no ASCII, no transform
//! rules: troupe would reimplement the part that is hard), and the Autodesk SDK is proprietary.
//!
//! How a file becomes a [`Bvh`](crate::motion::bvh::Bvh):
//! - The skeleton is the file's bones (`LimbNode`s), each with the nearest bone above it as its
//!   parent; a bone without children named like an end marker (`…_end`, `…End`, `…Nub`: what
//!   Blender, Mixamo and 3ds Max add at the tips) becomes its parent's end site.
//! - The scene is converted to Y up, right-handed, in the caller's unit (metres by default), so
//!   a Z-up file in centimetres reads like any other.
//! - The rest pose is the file's bind pose (written with skinned meshes: the pose the skin was
//!   bound in), else the bones' own transforms in the file (for Blender, the pose at export).
//!   Each joint's offset is its rest position relative to its parent's, in world axes (a BVH
//!   rest pose has no rotations), and each frame's rotation channels hold the joint's turn away
//!   from its rest orientation, so that forward kinematics gives the file's joint positions.
//!   Joints whose translation is animated (the root; any other whose distance to its parent
//!   changes) get position channels.
//! - Frames are sampled at the file's frame rate over its first animation stack; a file
//!   without animation is one frame, the rest pose.
//!
//! Builds for wasm32 have no C compiler here: there, FBX is written but not read (the web page
//! says a dropped FBX file is one).
//!
//! Bounds, for files from others: at most [`MAX_FBX_BYTES`] read, ufbx's allocations capped in
//! proportion to the file, at most 1,080,000 frames and [`MAX_FBX_NODE_FRAMES`] scene nodes ×
//! frames evaluated, at most [`MAX_BVH_JOINTS`](crate::motion::bvh::MAX_BVH_JOINTS) bones and
//! [`MAX_FBX_VALUES`] channel values, every position within
//! [`MAX_BVH_COORDINATE`](crate::motion::bvh::MAX_BVH_COORDINATE). Long files report progress
//! (and can be cancelled) every 4096 frames.

#[cfg(not(target_arch = "wasm32"))]
mod read;
mod write;
#[cfg(not(target_arch = "wasm32"))]
pub use read::{parse_fbx, read_fbx};
pub use write::{write_rig_fbx, write_rig_fbx_file, FbxWriteOptions};

/// The largest FBX file troupe reads.
pub const MAX_FBX_BYTES: u64 = 1 << 28;

/// The most channel values (frames × channels) a clip read from FBX may hold: 128 MiB.
pub const MAX_FBX_VALUES: usize = 1 << 25;

/// The most scene nodes × frames a clip read from FBX may cost to evaluate (each frame
/// evaluates the whole scene): 2^26, seconds of work.
pub const MAX_FBX_NODE_FRAMES: usize = 1 << 26;

/// The first bytes of a binary FBX file.
const BINARY_MAGIC: &[u8] = b"Kaydara FBX Binary";

/// Whether `bytes` look like an FBX file: binary FBX's magic, or ASCII FBX's first comment
/// (`; FBX 7.4.0 project file`).
pub fn is_fbx(bytes: &[u8]) -> bool {
    bytes.starts_with(BINARY_MAGIC) || {
        let head = &bytes[..bytes.len().min(64)];
        let text = String::from_utf8_lossy(head);
        text.trim_start_matches('\u{feff}')
            .trim_start()
            .starts_with("; FBX")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fbx_is_told_from_bvh_by_content() {
        assert!(is_fbx(b"Kaydara FBX Binary  \x00\x1a\x00"));
        assert!(is_fbx(b"; FBX 7.4.0 project file\n"));
        assert!(!is_fbx(b"HIERARCHY\nROOT Hips\n"));
        assert!(!is_fbx(b""));
    }
}
