//! The reactor's placement fed back into its condition, for bundles trained to see it
//! (`condition.feedback`: `partner_placement`; the demo model's recipe v3).
//!
//! Where some partners stand depends on the whole stream, not on the actor's last second (the
//! demo's keep-away partner stands wherever its leash has taken it). A model that must read that
//! place out of its own latent history reads it poorly and wanders; these models are told it.
//! Before token `j > 0` the conditioning graph runs on the caller's condition followed by
//! `[1, dx, dz, fx, fz]`: the reactor's root less the actor's on the floor (metres) and the
//! reactor's unit facing on the floor, at the last frame of token `j - 1` as decoded (before any
//! clean-up); token 0 sees zeros. Both people's frames are taken in the same frame, and only
//! differences and directions are read, so where the stream or the networks' frame sits on the
//! floor (placement, recentring) does not change the vector.

use super::Reactor;
use crate::armflow::networks::{Conditioning, Networks};
use crate::motion::features::POSITIONS;
use crate::shared::error::Result;

/// Floats of a `partner_placement` feedback.
pub(crate) const DIM: usize = 5;

/// t2m22 joints the facing is read from (as the joint stream's placement reads it, with the
/// shoulders added as the demo's rules do).
const LEFT_HIP: usize = 1;
const RIGHT_HIP: usize = 2;
const LEFT_SHOULDER: usize = 16;
const RIGHT_SHOULDER: usize = 17;

/// The feedback of one reactor frame and the actor frame of the same instant (interhuman262
/// feature rows: t2m22 joint positions from [`POSITIONS`]).
pub(crate) fn partner_placement(reactor: &[f32], actor: &[f32]) -> [f32; DIM] {
    let joint = |row: &[f32], j: usize| -> [f64; 3] {
        let at = POSITIONS + 3 * j;
        [row[at], row[at + 1], row[at + 2]].map(f64::from)
    };
    let (r, a) = (joint(reactor, 0), joint(actor, 0));
    let across = |k: usize| {
        joint(reactor, RIGHT_HIP)[k] - joint(reactor, LEFT_HIP)[k]
            + joint(reactor, RIGHT_SHOULDER)[k]
            - joint(reactor, LEFT_SHOULDER)[k]
    };
    // Up (+Y) crossed with the body's left-to-right axis, on the floor.
    let (fx, fz) = (across(2), -across(0));
    let norm = fx.hypot(fz).max(1e-9);
    [1.0, r[0] - a[0], r[2] - a[2], fx / norm, fz / norm].map(|v| v as f32)
}

/// The conditioning of a token after the first: the session's condition followed by the
/// reactor's `placement` (what the token loop and recentring's rebuild both run).
pub(super) fn conditioning(
    nets: &Networks,
    session: &Reactor,
    placement: &[f32; DIM],
) -> Result<Conditioning> {
    nets.conditioning_fed(session.conditioning().condition.clone(), placement)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::skeleton::Skeleton;

    #[test]
    fn joints_are_t2m22s() {
        let s = Skeleton::t2m22();
        for (index, name) in [
            (LEFT_HIP, "left_hip"),
            (RIGHT_HIP, "right_hip"),
            (LEFT_SHOULDER, "left_shoulder"),
            (RIGHT_SHOULDER, "right_shoulder"),
        ] {
            assert_eq!(s.index_of(name), Some(index), "{name}");
        }
    }

    /// A body standing at (x, z) facing +Z (its right on -X), as a feature row.
    fn standing(x: f32, z: f32, frame_dim: usize) -> Vec<f32> {
        let mut row = vec![0f32; frame_dim];
        for j in 0..22 {
            let at = POSITIONS + 3 * j;
            row[at] = x;
            row[at + 1] = 1.0;
            row[at + 2] = z;
        }
        for (j, side) in [
            (LEFT_HIP, 1.0),
            (RIGHT_HIP, -1.0),
            (LEFT_SHOULDER, 1.0),
            (RIGHT_SHOULDER, -1.0),
        ] {
            row[POSITIONS + 3 * j] = x + 0.2 * side;
        }
        row
    }

    #[test]
    fn placement_is_relative_and_facing_is_a_floor_direction() {
        let actor = standing(3.0, -1.0, 262);
        let reactor = standing(3.5, 1.0, 262);
        let fed = partner_placement(&reactor, &actor);
        assert_eq!(fed, [1.0, 0.5, 2.0, 0.0, 1.0]);
        // Moving both people together changes nothing.
        let moved = |row: &[f32]| {
            let mut row = row.to_vec();
            for j in 0..22 {
                row[POSITIONS + 3 * j] += 7.0;
                row[POSITIONS + 3 * j + 2] -= 4.0;
            }
            row
        };
        assert_eq!(partner_placement(&moved(&reactor), &moved(&actor)), fed);
    }
}
