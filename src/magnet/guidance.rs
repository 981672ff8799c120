//! Guidance (`docs/spec/magnet.md` §6): the mask modes and their weighted sum of x0
//! predictions, and the x0-space smoothing and foot-skating corrections (the decoder part from
//! the bundle's gradient graphs, the transform part analytic). Mirrors
//! `onnx/troupe_onnx/magnet/guidance.py`.

use ndarray::{s, Array3, Array4, ArrayView4};

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
    /// `ctx_len` flat context tokens.
    pub fn x0(
        &mut self,
        x: ArrayView4<f32>,
        k: &[i64],
        ctx_len: usize,
        draws: &mut Draws,
    ) -> Result<Array4<f32>> {
        let mut out = if ctx_len == 0 {
            self.nets.denoise(x, k)?
        } else {
            let mut sum = Array4::<f32>::zeros(x.raw_dim());
            for (mode, w) in &self.spec.scales {
                let input = self.mode_input(mode, x, k, ctx_len, draws)?;
                let x0 = self.nets.denoise(input.view(), k)?;
                sum.zip_mut_with(&x0, |acc, v| *acc += *w * *v);
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
            let g = self
                .nets
                .correction_gradient(out.view(), self.betas.view(), [ws, wf])?;
            let t = smooth.map(|_| transform_smoothing_gradient(out.view(), latent));
            out.slice_mut(s![.., .., .., ..latent])
                .zip_mut_with(&g, |o, g| *o -= *g);
            if let Some(t) = t {
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
