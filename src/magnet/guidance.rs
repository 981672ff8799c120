//! Guidance (`docs/spec/magnet.md` §6): the mask modes and their weighted sum of x0
//! predictions, and the x0-space smoothing and foot-skating corrections (the decoder part from
//! the bundle's gradient graphs, the transform part analytic). Mirrors
//! `onnx/troupe_onnx/magnet/guidance.py`.

use ndarray::{s, Array3, Array4, ArrayView4, Axis};

use super::draws::Draws;
use super::networks::Networks;
use super::schedule::Schedule;
use super::spec::{GuidanceSpec, X0GuidanceSpec};
use crate::shared::error::Result;

/// The guidance wrapper of one sampler run (§6.1): combines the modes' x0 predictions, applies
/// the corrections while `counter / total` is in their range, counts calls.
pub(crate) struct Guidance<'a> {
    pub nets: &'a Networks,
    pub spec: &'a GuidanceSpec,
    pub schedule: &'a Schedule,
    /// Normalised betas of every sample and person, `[S, P, 10]`.
    pub betas: Array3<f32>,
    pub total: usize,
    pub counter: usize,
    /// Independent runs stacked along S (1, or a crowd of live sessions): the corrections are
    /// batch means, taken per run.
    pub runs: usize,
}

fn active(x: &Option<X0GuidanceSpec>, counter: usize, total: usize) -> Option<f32> {
    let x = x.as_ref()?;
    let progress = counter as f64 / total as f64;
    (total > 0 && f64::from(x.start) <= progress && progress <= f64::from(x.end))
        .then_some(x.weight)
}

impl Guidance<'_> {
    /// The guided x0 of window `x` `[S, Tm, P, D]` at levels `k` (`[Tm * P]`, flat), with
    /// `ctx_len` flat context tokens. `given[p]` says that person `p`'s every token in the window
    /// is given and kept whatever x0 says (the live user): the corrections leave those people
    /// out, which changes nothing they return for the others.
    pub fn x0(
        &mut self,
        x: ArrayView4<f32>,
        k: &[i64],
        ctx_len: usize,
        given: &[bool],
        draws: &mut Draws,
    ) -> Result<Array4<f32>> {
        let mut out = if ctx_len == 0 {
            self.nets.denoise(x, k)?
        } else {
            // Every mode's input (drawn in the modes' order), then one network call for all.
            let inputs = self
                .spec
                .scales
                .iter()
                .map(|(mode, _)| self.mode_input(mode, x, k, ctx_len, draws))
                .collect::<Result<Vec<_>>>()?;
            let views: Vec<_> = inputs.iter().map(|a| a.view()).collect();
            let all = ndarray::concatenate(Axis(0), &views).expect("one window shape");
            let x0 = self.nets.denoise(all.view(), k)?;
            let samples = x.dim().0;
            let mut sum = Array4::<f32>::zeros(x.raw_dim());
            for (i, (_, w)) in self.spec.scales.iter().enumerate() {
                let mode_x0 = x0.slice(s![i * samples..(i + 1) * samples, .., .., ..]);
                sum.zip_mut_with(&mode_x0, |acc, v| *acc += *w * *v);
            }
            sum
        };
        let smooth = active(&self.spec.smoothing, self.counter, self.total);
        let foot = active(&self.spec.foot_skating, self.counter, self.total);
        if smooth.is_some() || foot.is_some() {
            // Both corrections at the same x0, subtracted together: w_s grad L_s + w_f grad L_f
            // through the decoder (on the latents; one graph call), then the smoothing's
            // transform term.
            let runs = self.runs.max(1) as f32;
            let (ws, wf) = (smooth.unwrap_or(0.0) * runs, foot.unwrap_or(0.0) * runs);
            let latent = self.nets.spec.model.vq.d_latent;
            let persons: Vec<usize> = (0..x.dim().2).filter(|&p| !given[p]).collect();
            if !persons.is_empty() {
                // The losses are means over every person: the graph's mean is over the people
                // it is given, so their share scales the weights (exact for a power of two).
                let share = persons.len() as f32 / x.dim().2 as f32;
                let g = self.nets.correction_gradient(
                    out.view(),
                    self.betas.view(),
                    &persons,
                    [ws * share, wf * share],
                )?;
                for (j, &person) in persons.iter().enumerate() {
                    out.slice_mut(s![.., .., person, ..latent])
                        .zip_mut_with(&g.slice(s![.., .., j, ..]), |o, g| *o -= *g);
                }
            }
            if smooth.is_some() {
                let t = transform_smoothing_gradient(out.view(), latent);
                out.slice_mut(s![.., .., .., latent..])
                    .zip_mut_with(&t, |o, g| *o -= ws * *g);
            }
        }
        self.counter += 1;
        Ok(out)
    }

    /// What the network sees in `mode` (§6.2).
    fn mode_input(
        &self,
        mode: &str,
        x: ArrayView4<f32>,
        k: &[i64],
        ctx_len: usize,
        draws: &mut Draws,
    ) -> Result<Array4<f32>> {
        let mut out = x.to_owned();
        if mode == "clean" {
            return Ok(out);
        }
        let (s, t, p, d) = out.dim();
        let n = draws.normal(s * t * p * d)?;
        // q = sqrt(1 - abar_k) n, per flat token f = t * P + p (level -1 reads row 999: pure n).
        let q = |sample: usize, f: usize, i: usize| {
            self.schedule.noise_scale(k[f]) * n[(sample * t * p + f) * d + i]
        };
        let mut flat = out
            .view_mut()
            .into_shape_with_order((s, t * p, d))
            .expect("contiguous");
        match mode {
            "full" | "subset" | "partial" => {
                let cut = match mode {
                    "subset" => (ctx_len as f64 * f64::from(self.spec.subset_ratio)) as usize,
                    _ => ctx_len,
                }
                .min(t * p);
                let rho = self.spec.partial_level;
                for sample in 0..s {
                    for f in 0..cut {
                        for i in 0..d {
                            let v = &mut flat[[sample, f, i]];
                            *v = if mode == "partial" {
                                rho * q(sample, f, i) + (1.0 - rho) * *v
                            } else {
                                q(sample, f, i)
                            };
                        }
                    }
                }
            }
            _ => {
                let n2 = draws.normal(s * t * p * d)?;
                let negate = mode.starts_with('~');
                let person: usize = mode.trim_start_matches('~')[6..]
                    .parse()
                    .expect("modes are checked at load");
                for (idx, v) in out.indexed_iter_mut() {
                    let (sample, tt, pp, i) = idx;
                    if (pp == person) != negate {
                        *v = n2[((sample * t + tt) * p + pp) * d + i];
                    }
                }
            }
        }
        Ok(out)
    }
}

/// d mean(Lap²)/dY of the transform dims `Y = x0[..., latent..]` along the window's token axis
/// (§6.4, smoothing, part 2), `[S, Tm, P, D - latent]`.
pub(crate) fn transform_smoothing_gradient(x0: ArrayView4<f32>, latent: usize) -> Array4<f32> {
    let y = x0.slice(s![.., .., .., latent..]);
    let (s, t, p, dy) = y.dim();
    let mut grad = Array4::<f32>::zeros((s, t, p, dy));
    if t < 3 {
        return grad;
    }
    let c = 2.0 / (s * (t - 2) * p * dy) as f32;
    let laps: Vec<Array4<f32>> = (1..t - 1)
        .map(|tau| {
            let lap = &y.slice(s![.., tau - 1..tau, .., ..])
                - &(&y.slice(s![.., tau..tau + 1, .., ..]) * 2.0)
                + y.slice(s![.., tau + 1..tau + 2, .., ..]);
            lap
        })
        .collect();
    // Three passes in the reference's order, so that each element sums the same terms in the
    // same order: the left neighbours, the centres, the right neighbours.
    for (offset, scale) in [(0usize, c), (1, -2.0 * c), (2, c)] {
        for (i, lap) in laps.iter().enumerate() {
            grad.slice_mut(s![.., i + offset..i + offset + 1, .., ..])
                .zip_mut_with(lap, |g, l| *g += scale * l);
        }
    }
    grad
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::magnet::layout::BETAS;
    use crate::magnet::spec::GuidanceSpec;

    fn model() -> crate::Model {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/magnet-tiny");
        crate::Model::load(dir).expect("the committed tiny bundle loads")
    }

    /// Deterministic values in [-1, 1) of `shape`.
    fn values(shape: (usize, usize, usize, usize), seed: usize) -> Array4<f32> {
        Array4::from_shape_fn(shape, |(a, b, c, d)| {
            let i = ((a * 31 + b) * 17 + c) * 1013 + d + seed * 7919;
            ((i * 2_654_435_761) % 2000) as f32 / 1000.0 - 1.0
        })
    }

    #[test]
    fn the_corrections_of_one_person_alone_are_that_persons_rows_of_all() {
        let model = model();
        let nets = model.magnet().expect("magnet").networks();
        let m = &nets.spec.model;
        let x0 = values((3, m.window, m.persons, m.token_dim), 1);
        let betas = values((3, m.persons, BETAS, 1), 2).remove_axis(Axis(3));
        let all = nets
            .correction_gradient(x0.view(), betas.view(), &[0, 1], [2.0, 3.0])
            .expect("runs");
        assert!(
            all.iter().any(|v| *v != 0.0),
            "the gradient is not all zero"
        );
        for person in 0..2 {
            // Half the sequences, half the weights: the means' scale is unchanged, exactly.
            let alone = nets
                .correction_gradient(x0.view(), betas.view(), &[person], [1.0, 1.5])
                .expect("runs");
            assert_eq!(
                alone.slice(s![.., .., 0, ..]),
                all.slice(s![.., .., person, ..])
            );
        }
    }

    #[test]
    fn every_mode_in_one_call_equals_one_call_per_mode() {
        let model = model();
        let nets = model.magnet().expect("magnet").networks();
        let m = &nets.spec.model;
        let spec = GuidanceSpec {
            scales: vec![
                ("clean".into(), 1.5),
                ("full".into(), -0.5),
                ("~person1".into(), 0.25),
            ],
            subset_ratio: 0.5,
            partial_level: 0.5,
            smoothing: None,
            foot_skating: None,
        };
        let x = values((2, m.window, m.persons, m.token_dim), 3);
        let k: Vec<i64> = (0..m.window * m.persons)
            .map(|f| if f < 6 { -1 } else { (f * 37 % 900) as i64 })
            .collect();
        let mut guidance = Guidance {
            nets,
            spec: &spec,
            schedule: &nets.schedule,
            betas: Array3::zeros((2, m.persons, BETAS)),
            total: 1,
            counter: 0,
            runs: 1,
        };
        let together = guidance
            .x0(x.view(), &k, 6, &[false, false], &mut Draws::seeded(9))
            .expect("runs");
        let mut draws = Draws::seeded(9);
        let mut alone = Array4::<f32>::zeros(x.raw_dim());
        for (mode, w) in &spec.scales {
            let input = guidance
                .mode_input(mode, x.view(), &k, 6, &mut draws)
                .expect("draws");
            let x0 = nets.denoise(input.view(), &k).expect("runs");
            alone.zip_mut_with(&x0, |acc, v| *acc += *w * *v);
        }
        let scale = alone.iter().fold(0f32, |a, v| a.max(v.abs()));
        let worst = (&together - &alone)
            .iter()
            .fold(0f32, |a, v| a.max(v.abs()));
        assert!(
            worst <= 1e-6 * scale,
            "batched modes differ by {worst:e} of {scale:e}"
        );
    }
}
