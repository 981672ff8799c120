//! The token and feature layout MAGNet's code hard-codes (`docs/spec/magnet.md` §1), and
//! troupe's frame layout for it: what a caller gives and gets per person and frame.

use crate::motion::smplx145;

/// Frames per token (the VQ-VAE's temporal factor).
pub const FRAMES_PER_TOKEN: usize = 4;
/// SMPL-X body joints without the pelvis.
pub const BODY_JOINTS: usize = 21;
/// SMPL-X shape coefficients MAGNet reads.
pub const BETAS: usize = 10;
/// A rigid transform as `[6-D rotation (the first two columns of R), tx, ty, tz]`.
pub const TRANSFORM: usize = 9;
/// The VQ-VAE's pose per frame: body 6-D rotations, then the root in the canonical frame.
pub const POSE_DIM: usize = BODY_JOINTS * 6 + TRANSFORM;
/// The VQ encoder's condition per frame: betas, the canonical frame's transition.
pub const ENCODER_COND_DIM: usize = BETAS + TRANSFORM;
/// A token's transforms of one kind: one per frame.
pub const TOKEN_TRANSFORMS: usize = FRAMES_PER_TOKEN * TRANSFORM;
/// The VQ decoder's condition per token: betas, the token's four transitions.
pub const DECODER_COND_DIM: usize = BETAS + TOKEN_TRANSFORMS;
/// Length of the normalisation statistics (§1.3).
pub const STATS_DIM: usize = 361;
/// The foot-skating loss's joints: left/right ankle, left/right foot (§6.4).
pub const FOOT_JOINTS: [usize; 4] = [6, 7, 9, 10];

/// troupe's frame layout for MAGNet (`motion.layout`; `crate::motion::smplx145` poses it).
pub const FRAME_LAYOUT: &str = smplx145::SMPLX145;
/// Floats per person and frame: betas, the body joints' 6-D rotations, the root in the world.
pub const FRAME_DIM: usize = smplx145::SMPLX145_DIM;
/// Where each field sits in a frame.
pub const FRAME_BETAS: std::ops::Range<usize> = smplx145::SMPLX145_BETAS;
/// The body joints' 6-D rotations.
pub const FRAME_BODY: std::ops::Range<usize> = smplx145::SMPLX145_BODY;
/// The root's pose in the world (9-D), y up.
pub const FRAME_ROOT: std::ops::Range<usize> = smplx145::SMPLX145_ROOT;
const _: () = assert!(FRAME_DIM == BETAS + BODY_JOINTS * 6 + TRANSFORM);

/// The statistics' fields (§1.3, `dataset_config.py:StdMeanIdx`).
pub(crate) mod stats {
    use std::ops::Range;
    /// Betas.
    pub const BETAS: Range<usize> = 0..10;
    /// Body joint rotations.
    pub const BODY: Range<usize> = 10..136;
    /// The canonical frame's transition from the previous frame.
    pub const TM1_T: Range<usize> = 316..325;
    /// The root in the canonical frame.
    pub const CANONICAL_ROOT: Range<usize> = 325..334;
    /// A partner's canonical frame in one's own.
    pub const PARTNER: Range<usize> = 352..361;
}
