"""The token and feature layout MAGNet's code hard-codes (`docs/spec/magnet.md` §1), shared by
the networks, the samplers and the motion conversions (no torch needed)."""

FRAMES_PER_TOKEN = 4  # the VQ-VAE's temporal factor (two stride-2 convolutions)
BODY_JOINTS = 21  # SMPL-X body joints without the pelvis
POSE_DIM = BODY_JOINTS * 6 + 9  # 135: body 6-D rotations, then T_canonical_root (9-D)
BETAS = 10
TRANSFORM = 9  # an SE(3) as 6-D rotation + translation
ENCODER_COND_DIM = BETAS + TRANSFORM  # 19: betas, T_canonical_tm1_canonical_t
TOKEN_TRANSFORMS = FRAMES_PER_TOKEN * TRANSFORM  # 36: one transform per frame of a token
DECODER_COND_DIM = BETAS + TOKEN_TRANSFORMS  # 46: betas, the token's four tm1_t
FOOT_JOINTS = (6, 7, 9, 10)  # left/right ankle, left/right foot among the 21 body joints
