//! Bodies passing through each other, measured and penalised on joints: the penetration loss of
//! ARFlow's physical guidance (`docs/spec/arflow.md` §3) with its analytic gradient, and
//! metrics for any two-person motion. ARFlow's sampler, the ARMFlow stream's penetration guard
//! and the metrics all use this one module.
//!
//! Loss, for a reactor's joints `p[n][j]` against the actor's body `φ_n` (the signed distance of
//! [`BodyModel`] posed at the actor's frame `n`, negative inside):
//!
//! ```text
//! L = Σ_n Σ_j h(d_safe − φ_n(p[n][j])),   h(x) = max(0, x)  (linear)  or  max(0, x)²  (squared)
//! ∂L/∂p[n][j] = −h'(d_safe − φ_n(p[n][j])) · ∇φ_n(p[n][j])
//! ```
//!
//! Beyond the safe distance the gradient is zero; the actor is held fixed.

use crate::motion::body::BodyModel;
use crate::motion::vec3::{scale, Vec3};
use crate::shared::error::{Error, Result};

/// The hinge's power (the paper does not say which; linear is the proposed default).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Hinge {
    /// `max(0, x)`: a constant push while inside the margin.
    #[default]
    Linear,
    /// `max(0, x)²`: a push that grows with depth.
    Squared,
}

/// The penetration loss's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenetrationLoss {
    /// The margin, metres (>= 0): joints nearer the other body than this are pushed out. The
    /// paper's value did not survive extraction; 0.02 m is the proposed default.
    pub d_safe: f64,
    /// Linear or squared hinge.
    pub hinge: Hinge,
}

impl Default for PenetrationLoss {
    fn default() -> Self {
        PenetrationLoss {
            d_safe: 0.02,
            hinge: Hinge::Linear,
        }
    }
}

/// The loss and its gradient with respect to the reactor's joints.
#[derive(Debug, Clone, PartialEq)]
pub struct Penetration {
    /// `L`, summed over frames and joints.
    pub loss: f64,
    /// `∂L/∂p`, `[frames][joints]`.
    pub gradient: Vec<Vec<Vec3>>,
}

/// Penetration of two people's motion, per clip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenetrationMetrics {
    /// Frames compared.
    pub frames: usize,
    /// Frames where a joint of either person lies inside the other's body.
    pub frames_intersecting: usize,
    /// `frames_intersecting / frames` (0 for no frames): the intersection frequency.
    pub frequency: f64,
    /// The depths (metres) of every joint inside the other's body, summed over joints and
    /// frames: the intersection volume's proxy.
    pub depth_sum: f64,
    /// The deepest joint, metres.
    pub max_depth: f64,
}

fn check_motion(body: &BodyModel, a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> Result<()> {
    if a.len() != b.len() {
        return Err(Error::InvalidInput(format!(
            "the two people have {} and {} frames",
            a.len(),
            b.len()
        )));
    }
    for (who, motion) in [("the first person", a), ("the second person", b)] {
        for (n, pose) in motion.iter().enumerate() {
            if pose.len() != body.joints() {
                return Err(Error::InvalidInput(format!(
                    "{who}'s frame {n} has {} joints, the body {}",
                    pose.len(),
                    body.joints()
                )));
            }
            if pose.iter().flatten().any(|v| !v.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "{who}'s frame {n} holds a non-finite position"
                )));
            }
        }
    }
    Ok(())
}

impl PenetrationLoss {
    fn check(&self) -> Result<()> {
        if !(self.d_safe.is_finite() && self.d_safe >= 0.0 && self.d_safe <= 1.0) {
            return Err(Error::InvalidOption(format!(
                "d_safe {} m: the safe distance lies in [0, 1] m",
                self.d_safe
            )));
        }
        Ok(())
    }

    /// The loss of the reactor's joints against the actor's body, and its gradient with respect
    /// to the reactor's joints (both motions `[frames][joints]`, metres, one world).
    pub fn evaluate(
        &self,
        body: &BodyModel,
        actor: &[Vec<Vec3>],
        reactor: &[Vec<Vec3>],
    ) -> Result<Penetration> {
        self.check()?;
        check_motion(body, actor, reactor)?;
        let mut loss = 0.0;
        let gradient = actor
            .iter()
            .zip(reactor)
            .map(|(a, r)| {
                // Joints beyond the body's reach add nothing (their distance exceeds d_safe).
                let reach = body.reach(a, self.d_safe);
                r.iter()
                    .map(|&p| {
                        if reach.beyond(p) {
                            return [0.0; 3];
                        }
                        let sd = body.signed_distance(a, p);
                        let x = self.d_safe - sd.distance;
                        if x <= 0.0 {
                            return [0.0; 3];
                        }
                        let (value, slope) = match self.hinge {
                            Hinge::Linear => (x, 1.0),
                            Hinge::Squared => (x * x, 2.0 * x),
                        };
                        loss += value;
                        scale(sd.gradient, -slope)
                    })
                    .collect()
            })
            .collect();
        Ok(Penetration { loss, gradient })
    }
}

/// How much two people's bodies pass through each other: each person's joints against the
/// other's body, frame by frame (`[frames][joints]` each, metres, one world).
pub fn penetration_metrics(
    body: &BodyModel,
    first: &[Vec<Vec3>],
    second: &[Vec<Vec3>],
) -> Result<PenetrationMetrics> {
    check_motion(body, first, second)?;
    let mut m = PenetrationMetrics {
        frames: first.len(),
        frames_intersecting: 0,
        frequency: 0.0,
        depth_sum: 0.0,
        max_depth: 0.0,
    };
    for (a, b) in first.iter().zip(second) {
        let mut inside = false;
        for (pose, joints) in [(a, b), (b, a)] {
            for &p in joints.iter() {
                let depth = -body.signed_distance(pose, p).distance;
                if depth > 0.0 {
                    inside = true;
                    m.depth_sum += depth;
                    m.max_depth = m.max_depth.max(depth);
                }
            }
        }
        m.frames_intersecting += usize::from(inside);
    }
    if m.frames > 0 {
        m.frequency = m.frames_intersecting as f64 / m.frames as f64;
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::skeleton::Skeleton;
    use crate::motion::vec3::add;

    fn shifted(pose: &[Vec3], by: Vec3) -> Vec<Vec3> {
        pose.iter().map(|&p| add(p, by)).collect()
    }

    /// Two rest bodies `gap` metres apart along x, for `frames` frames.
    fn pair(gap: f64, frames: usize) -> (Vec<Vec<Vec3>>, Vec<Vec<Vec3>>) {
        let rest = Skeleton::t2m22().rest_positions();
        (
            vec![rest.clone(); frames],
            vec![shifted(&rest, [gap, 0.0, 0.0]); frames],
        )
    }

    #[test]
    fn apart_bodies_have_no_loss_and_overlapping_ones_do() {
        let body = BodyModel::t2m22();
        let (a, b) = pair(3.0, 4);
        let far = PenetrationLoss::default().evaluate(&body, &a, &b).unwrap();
        assert_eq!(far.loss, 0.0);
        assert!(far.gradient.iter().flatten().all(|g| *g == [0.0; 3]));
        let m = penetration_metrics(&body, &a, &b).unwrap();
        assert_eq!((m.frames_intersecting, m.depth_sum), (0, 0.0));
        let (a, b) = pair(0.1, 4);
        let near = PenetrationLoss::default().evaluate(&body, &a, &b).unwrap();
        assert!(near.loss > 0.0);
        let m = penetration_metrics(&body, &a, &b).unwrap();
        assert_eq!((m.frames, m.frames_intersecting, m.frequency), (4, 4, 1.0));
        assert!(m.depth_sum > 0.0 && m.max_depth > 0.05);
    }

    #[test]
    fn skipping_joints_beyond_reach_changes_nothing() {
        // The reactor at many offsets, from overlapping to apart: the loss and every gradient
        // equal those of every joint's distance computed.
        let body = BodyModel::t2m22();
        let rest = Skeleton::t2m22().rest_positions();
        for hinge in [Hinge::Linear, Hinge::Squared] {
            let loss = PenetrationLoss { d_safe: 0.1, hinge };
            for step in 0..40 {
                let by = [0.03 * f64::from(step), 0.01 * f64::from(step % 7), 0.02];
                let reactor = shifted(&rest, by);
                let got = loss
                    .evaluate(
                        &body,
                        std::slice::from_ref(&rest),
                        std::slice::from_ref(&reactor),
                    )
                    .unwrap();
                let (mut want, mut grads) = (0.0, Vec::new());
                for &p in &reactor {
                    let sd = body.signed_distance(&rest, p);
                    let x = (loss.d_safe - sd.distance).max(0.0);
                    let (value, slope) = match hinge {
                        Hinge::Linear => (x, f64::from(u8::from(x > 0.0))),
                        Hinge::Squared => (x * x, 2.0 * x),
                    };
                    want += value;
                    grads.push(scale(sd.gradient, -slope));
                }
                assert_eq!(got.loss, want, "offset {by:?}");
                assert_eq!(got.gradient[0], grads, "offset {by:?}");
            }
        }
    }

    #[test]
    fn the_gradient_is_the_losses_derivative_for_both_hinges() {
        let body = BodyModel::t2m22();
        let (a, mut b) = pair(0.15, 2);
        b[1] = shifted(&b[1], [0.02, 0.03, -0.04]);
        for hinge in [Hinge::Linear, Hinge::Squared] {
            let loss = PenetrationLoss {
                d_safe: 0.05,
                hinge,
            };
            let got = loss.evaluate(&body, &a, &b).unwrap();
            let h = 1e-7;
            for n in 0..2 {
                for j in [0, 3, 9, 16, 20] {
                    for k in 0..3 {
                        let mut up = b.clone();
                        let mut down = b.clone();
                        up[n][j][k] += h;
                        down[n][j][k] -= h;
                        let fd = (loss.evaluate(&body, &a, &up).unwrap().loss
                            - loss.evaluate(&body, &a, &down).unwrap().loss)
                            / (2.0 * h);
                        let g = got.gradient[n][j][k];
                        assert!(
                            (fd - g).abs() < 1e-5,
                            "{hinge:?} n {n} j {j} k {k}: {fd} {g}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn gradient_steps_push_the_reactor_out() {
        let body = BodyModel::t2m22();
        let (a, mut b) = pair(0.12, 1);
        let loss = PenetrationLoss::default();
        let before = loss.evaluate(&body, &a, &b).unwrap().loss;
        for _ in 0..50 {
            let g = loss.evaluate(&body, &a, &b).unwrap().gradient;
            for (p, d) in b[0].iter_mut().zip(&g[0]) {
                *p = add(*p, scale(*d, -0.01));
            }
        }
        let after = loss.evaluate(&body, &a, &b).unwrap().loss;
        assert!(after < 0.5 * before, "{before} -> {after}");
    }

    #[test]
    fn bad_motion_and_options_are_refused() {
        let body = BodyModel::t2m22();
        let (a, mut b) = pair(0.5, 3);
        assert!(penetration_metrics(&body, &a, &b[..2]).is_err());
        b[1][4][1] = f64::NAN;
        assert!(penetration_metrics(&body, &a, &b).is_err());
        let (a, b) = pair(0.5, 3);
        let short: Vec<Vec<Vec3>> = b.iter().map(|p| p[..21].to_vec()).collect();
        assert!(penetration_metrics(&body, &a, &short).is_err());
        for d_safe in [-0.1, f64::NAN, 2.0] {
            let loss = PenetrationLoss {
                d_safe,
                hinge: Hinge::Linear,
            };
            assert!(loss.evaluate(&body, &a, &b).is_err(), "{d_safe}");
        }
        let empty = penetration_metrics(&body, &[], &[]).unwrap();
        assert_eq!((empty.frames, empty.frequency), (0, 0.0));
    }
}
