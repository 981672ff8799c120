//! The C entry points of a session's motion stages, for every stream whose frames the stages
//! know (`family/motion/`): joint positions in and poses out, the penetration guard, the root
//! smoothing and the foot lock.

pub mod foot_lock;
pub mod guard;
pub mod joints;
pub mod smoothing;
