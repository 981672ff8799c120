//! Fixed-grid ODE solvers for flow sampling: forward Euler and the 3/8-rule RK4 that
//! torchdiffeq's `rk4` method uses (`docs/spec/umf.md` §5).
//!
//! Both step over the grid `tau_j = j / steps` (each rounded once to f32), so the grid points are
//! the solution points. Arithmetic is f32, in the order torchdiffeq writes it, so that a
//! reference run with the same network gives the same numbers.

use serde::{Deserialize, Serialize};

use crate::shared::error::{Error, Result};

/// The integration rule of one solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Forward Euler: one velocity evaluation per interval.
    Euler,
    /// Kutta's 3/8 rule: four evaluations per interval, fourth order.
    Rk4,
}

impl Method {
    /// Velocity evaluations per interval.
    pub fn evaluations_per_step(self) -> usize {
        match self {
            Method::Euler => 1,
            Method::Rk4 => 4,
        }
    }
}

/// A rule and a number of equal intervals over `tau` in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Solver {
    /// The integration rule.
    pub method: Method,
    /// Intervals over `[0, 1]`; at least 1.
    pub steps: u32,
}

impl Solver {
    /// Forward Euler with `steps` intervals.
    pub fn euler(steps: u32) -> Self {
        Self {
            method: Method::Euler,
            steps,
        }
    }

    /// 3/8-rule RK4 with `steps` intervals.
    pub fn rk4(steps: u32) -> Self {
        Self {
            method: Method::Rk4,
            steps,
        }
    }

    /// Velocity evaluations of one solve.
    pub fn evaluations(self) -> usize {
        self.method.evaluations_per_step() * self.steps as usize
    }

    pub(crate) fn check(self, what: &str) -> Result<()> {
        if self.steps == 0 || self.steps > MAX_STEPS {
            return Err(Error::InvalidOption(format!(
                "{what}: {} steps is outside 1..={MAX_STEPS}",
                self.steps
            )));
        }
        Ok(())
    }

    /// The grid `tau_j = j / steps`, j = 0..=steps, computed in f64 and rounded once.
    pub fn grid(self) -> Vec<f32> {
        let n = f64::from(self.steps);
        (0..=self.steps)
            .map(|j| (f64::from(j) / n) as f32)
            .collect()
    }

    /// Integrates `dy/dtau = velocity(tau, y)` from `tau = 0` to `1`, updating `y` in place.
    /// `velocity` returns a vector of `y.len()` floats.
    pub fn solve<F>(self, y: &mut [f32], mut velocity: F) -> Result<()>
    where
        F: FnMut(f32, &[f32]) -> Result<Vec<f32>>,
    {
        let grid = self.grid();
        let mut probe = vec![0f32; y.len()];
        for pair in grid.windows(2) {
            let (t0, t1) = (pair[0], pair[1]);
            let dt = t1 - t0;
            match self.method {
                Method::Euler => {
                    let k1 = velocity(t0, y)?;
                    for (yi, k) in y.iter_mut().zip(&k1) {
                        *yi += dt * k;
                    }
                }
                Method::Rk4 => {
                    // torchdiffeq rk4_alt_step_func, term by term.
                    let k1 = velocity(t0, y)?;
                    for ((p, yi), a) in probe.iter_mut().zip(&*y).zip(&k1) {
                        *p = yi + dt * a * ONE_THIRD;
                    }
                    let k2 = velocity(t0 + dt * ONE_THIRD, &probe)?;
                    for (((p, yi), a), b) in probe.iter_mut().zip(&*y).zip(&k1).zip(&k2) {
                        *p = yi + dt * (b - a * ONE_THIRD);
                    }
                    let k3 = velocity(t0 + dt * TWO_THIRDS, &probe)?;
                    for ((((p, yi), a), b), c) in
                        probe.iter_mut().zip(&*y).zip(&k1).zip(&k2).zip(&k3)
                    {
                        *p = yi + dt * (a - b + c);
                    }
                    let k4 = velocity(t1, &probe)?;
                    for ((((yi, a), b), c), d) in y.iter_mut().zip(&k1).zip(&k2).zip(&k3).zip(&k4) {
                        *yi += (a + 3.0 * (b + c) + d) * dt * 0.125;
                    }
                }
            }
        }
        Ok(())
    }
}

/// Upper bound on intervals per solve: far beyond any useful setting, low enough that a typo
/// cannot start an hours-long call ([`crate::shared::limits::LIMITS`]`.max_steps`).
pub const MAX_STEPS: u32 = crate::shared::limits::LIMITS.max_steps as u32;

// torchdiffeq's `_one_third` and `_two_thirds` are Python floats, rounded to f32 when they meet
// a float32 tensor.
const ONE_THIRD: f32 = (1.0f64 / 3.0) as f32;
const TWO_THIRDS: f32 = (2.0f64 / 3.0) as f32;

#[cfg(test)]
mod tests {
    use super::*;

    /// `dy/dt = y + t` from y(0) = 1: y(1) = 2e - 2. Smooth and non-autonomous, so the time
    /// argument of every stage of the RK rule matters.
    fn error(solver: Solver) -> f64 {
        let mut y = [1f32];
        solver.solve(&mut y, |t, y| Ok(vec![y[0] + t])).unwrap();
        (f64::from(y[0]) - (2.0 * std::f64::consts::E - 2.0)).abs()
    }

    #[test]
    fn euler_converges_at_first_order() {
        let (e1, e2) = (error(Solver::euler(100)), error(Solver::euler(200)));
        let order = (e1 / e2).log2();
        assert!(
            (order - 1.0).abs() < 0.05,
            "Euler order {order} ({e1}, {e2})"
        );
    }

    #[test]
    fn rk4_converges_at_fourth_order_and_beats_many_euler_steps() {
        // f32 rounding (~2e-7 here) limits how fine the grid can be before the error stops
        // falling; at 4 -> 8 steps the error (1e-4 -> 1e-5) is asymptotic and well above it.
        let (e1, e2) = (error(Solver::rk4(4)), error(Solver::rk4(8)));
        let order = (e1 / e2).log2();
        assert!((order - 4.0).abs() < 0.3, "RK4 order {order} ({e1}, {e2})");
        let euler = error(Solver::euler(1000));
        assert!(
            e2 < euler,
            "RK4 with 8 steps ({e2}) vs Euler with 1000 ({euler})"
        );
        // Many Euler steps and RK4 agree on the solution (Euler's error is ~ h e / 2).
        assert!(euler < 5e-3 && e2 < 2e-5, "{euler} {e2}");
    }

    #[test]
    fn grid_and_evaluation_counts() {
        assert_eq!(Solver::rk4(4).grid(), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(Solver::rk4(4).evaluations(), 16);
        assert_eq!(Solver::euler(45).evaluations(), 45);
        let mut calls = Vec::new();
        let mut y = [0f32];
        Solver::rk4(1)
            .solve(&mut y, |t, _| {
                calls.push(t);
                Ok(vec![1.0])
            })
            .unwrap();
        assert_eq!(calls, vec![0.0, ONE_THIRD, TWO_THIRDS, 1.0]);
        assert_eq!(y[0], 1.0);
        assert!(Solver::euler(0).check("x").is_err());
    }
}
