//! ARFlow's sampler (`docs/spec/arflow.md` §2-§4), reconstructed from the paper: x̂_1-
//! prediction Euler from the actor, physical guidance on x̂_1, back-projection, reweighting
//! toward the actor, re-interpolation, optionally stochastic. Mirrors
//! `onnx/troupe_onnx/arflow/sampler.py` operation for operation.
//!
//! Per step m of M, `t_m = m / M`, on normalised features (`x_0 = a`):
//!
//! ```text
//! x̂_1  = G(x_m, t_m)
//! x̂_1' = x̂_1 − λ ∇_{x̂_1} L_pen                  guidance (positions are features 0..66)
//! x̂_0  = (x_m − t_m x̂_1') / (1 − t_m)            back-projection (x̂_1 unless guided)
//! x̃_0  = w x̂_0 + (1 − w) a                       reweighting
//! d     = v  |  (1 − η) v + η ε  |  √(1 − η²) v + η ε,   v = x̂_1' − x̃_0
//! x_{m+1} = x̂_1' − (1 − t_{m+1}) d               re-interpolation
//! ```
//!
//! With λ = 0, w = 1 and η = 0 this is Euler's step (Eq. 9). Draws: troupe's generator on
//! [`super::spec::STREAM_ARFLOW`] (the bundle's `sampler.stream`), token = draw index: the start noise when σ > 0, then one ε per step when
//! η > 0.

use ndarray::{Array2, ArrayView2, Axis};

use super::networks::Networks;
#[cfg(test)]
use super::spec::STREAM_ARFLOW;
use super::spec::{ArflowSampling, Mixing, FRAME_DIM, POSITIONS};
use crate::motion::body::BodyModel;
use crate::motion::penetration::{Hinge, PenetrationLoss};
use crate::motion::vec3::Vec3;
use crate::shared::checks::check_frames;
use crate::shared::error::{Error, Result};
use crate::shared::noise::NormalSource;
use crate::shared::progress;

/// Changes to the bundle's sampler settings for one call; `None` keeps the bundle's.
#[derive(Debug, Clone, Default)]
pub struct ArflowOptions {
    /// Euler steps M.
    pub steps: Option<usize>,
    /// The guidance strength λ (0: off).
    pub guidance: Option<f32>,
    /// The reweighting w (1: off).
    pub weight: Option<f32>,
    /// The stochastic share η (0: deterministic).
    pub eta: Option<f32>,
    /// The safe distance, metres.
    pub d_safe: Option<f32>,
    /// A squared hinge.
    pub squared: Option<bool>,
    /// Back-project with the guided x̂_1.
    pub guided_backprojection: Option<bool>,
    /// The stochastic mixing.
    pub mixing: Option<Mixing>,
    /// The start noise σ.
    pub sigma: Option<f32>,
    /// The seed of troupe's generator.
    pub seed: u64,
}

impl ArflowOptions {
    /// The bundle's settings with these changes, checked.
    pub(crate) fn apply(&self, base: &ArflowSampling) -> Result<ArflowSampling> {
        let mut s = base.clone();
        if let Some(v) = self.steps {
            s.steps = v;
        }
        if let Some(v) = self.guidance {
            s.guidance = v;
        }
        if let Some(v) = self.weight {
            s.weight = v;
        }
        if let Some(v) = self.eta {
            s.eta = v;
        }
        if let Some(v) = self.d_safe {
            s.d_safe = v;
        }
        if let Some(v) = self.squared {
            s.squared = v;
        }
        if let Some(v) = self.guided_backprojection {
            s.guided_backprojection = v;
        }
        if let Some(v) = self.mixing {
            s.mixing = v;
        }
        if let Some(v) = self.sigma {
            s.sigma = v;
        }
        s.validate().map_err(Error::InvalidOption)?;
        Ok(s)
    }
}

/// The guidance gradient `∇_{x̂_1} L_pen` `[T, D]` on normalised features: the reactor's
/// positions `x̂_1[:, :66] · std + mean` against the actor's body (`actor` raw), the gradient on
/// positions times `std` (the normaliser is linear), zero elsewhere. In float64.
pub fn guidance_gradient(
    x1: ArrayView2<f32>,
    actor: ArrayView2<f32>,
    mean: &[f32],
    std: &[f32],
    loss: &PenetrationLoss,
) -> Result<Array2<f64>> {
    let joints = |row: ndarray::ArrayView1<f32>, denormalise: bool| -> Vec<Vec3> {
        (0..POSITIONS / 3)
            .map(|j| {
                let mut p = [0f64; 3];
                for (k, v) in p.iter_mut().enumerate() {
                    let i = 3 * j + k;
                    *v = if denormalise {
                        row[i] as f64 * std[i] as f64 + mean[i] as f64
                    } else {
                        row[i] as f64
                    };
                }
                p
            })
            .collect()
    };
    let reactor: Vec<Vec<Vec3>> = x1.outer_iter().map(|r| joints(r, true)).collect();
    let actor: Vec<Vec<Vec3>> = actor.outer_iter().map(|r| joints(r, false)).collect();
    let pen = loss.evaluate(&BodyModel::t2m22(), &actor, &reactor)?;
    let mut grad = Array2::<f64>::zeros(x1.raw_dim());
    for (n, frame) in pen.gradient.iter().enumerate() {
        for (j, g) in frame.iter().enumerate() {
            for k in 0..3 {
                grad[[n, 3 * j + k]] = g[k] * std[3 * j + k] as f64;
            }
        }
    }
    Ok(grad)
}

/// `(t_m, t_{m+1})` of step `step` of `steps`.
pub(crate) fn times(step: usize, steps: usize) -> (f32, f32) {
    (step as f32 / steps as f32, (step + 1) as f32 / steps as f32)
}

/// The penetration loss the settings ask for.
pub(crate) fn loss_of(s: &ArflowSampling) -> PenetrationLoss {
    PenetrationLoss {
        d_safe: s.d_safe as f64,
        hinge: if s.squared {
            Hinge::Squared
        } else {
            Hinge::Linear
        },
    }
}

/// One step of the sampler on rows of frames (the module's formulas): `x` (normalised, `[T, D]`)
/// becomes `x_{m+1}` given the network's `x1`, the normalised actor `a`, its raw features `raw`
/// (for the guidance), `eps` (η's draw, `T·D` normals) and `(t_m, t_{m+1})`. Rows are
/// independent, so a stream runs it one frame at a time.
#[allow(clippy::too_many_arguments)]
pub(crate) fn euler_step(
    x: &mut Array2<f32>,
    x1: &Array2<f32>,
    a: ArrayView2<f32>,
    raw: ArrayView2<f32>,
    (mean, std): (&[f32], &[f32]),
    s: &ArflowSampling,
    loss: &PenetrationLoss,
    (t, t_next): (f32, f32),
    eps: Option<&[f32]>,
) -> Result<()> {
    let x1g = if s.guidance > 0.0 {
        let g = guidance_gradient(x1.view(), raw, mean, std, loss)?;
        let lambda = s.guidance as f64;
        ndarray::Zip::from(x1)
            .and(&g)
            .map_collect(|&v, &g| (v as f64 - lambda * g) as f32)
    } else {
        x1.clone()
    };
    let back = if s.guided_backprojection { &x1g } else { x1 };
    let (w, keep) = (
        s.weight,
        match s.mixing {
            Mixing::Linear => 1.0 - s.eta,
            Mixing::VariancePreserving => (1.0 - s.eta * s.eta).sqrt(),
        },
    );
    for (i, ((xv, &bv), (&gv, &av))) in x
        .iter_mut()
        .zip(back.iter())
        .zip(x1g.iter().zip(a.iter()))
        .enumerate()
    {
        let x0 = (*xv - t * bv) / (1.0 - t);
        let x0w = w * x0 + (1.0 - w) * av;
        let v = gv - x0w;
        let d = match eps {
            Some(e) => keep * v + s.eta * e[i],
            None => v,
        };
        *xv = gv - (1.0 - t_next) * d;
    }
    Ok(())
}

/// The network as the sampler calls it: x̂_1 `[T, D]` of normalised `x` `[T, D]` at time `t`.
pub(crate) type Denoise<'a> = dyn FnMut(ArrayView2<f32>, f32) -> Result<Array2<f32>> + 'a;

/// The reactor's raw features `[T, D]` for the actor's raw features `actor` `[T, D]`, checked
/// against the bundle.
pub(crate) fn generate(
    nets: &Networks,
    actor: ArrayView2<f32>,
    s: &ArflowSampling,
    normals: &mut NormalSource,
) -> Result<Array2<f32>> {
    let m = &nets.spec.model;
    let (frames, dim) = actor.dim();
    if dim != FRAME_DIM {
        return Err(Error::InvalidInput(format!(
            "actor frames have {dim} features, bundle `{}` takes `interhuman262` ({FRAME_DIM})",
            nets.io.name
        )));
    }
    if frames == 0 || frames > m.max_frames {
        return Err(Error::InvalidInput(format!(
            "{frames} actor frames: bundle `{}` generates 1 to {} frames at once",
            nets.io.name, m.max_frames
        )));
    }
    let raw = actor.as_standard_layout();
    check_frames(
        "actor frames",
        raw.as_slice().expect("standard layout"),
        dim,
    )?;
    let mut denoise = |x: ArrayView2<f32>, t: f32| {
        Ok(nets
            .denoise(x.insert_axis(Axis(0)), &[t])?
            .index_axis_move(Axis(0), 0))
    };
    let norm = &nets.spec.normalizer;
    let _clock = progress::start_call("the reaction", s.steps as u64, "sampler steps")?;
    sample(&mut denoise, raw.view(), &norm.mean, &norm.std, s, normals)
}

/// The sampler's loop over any network (`denoise`), on checked input.
pub(crate) fn sample(
    denoise: &mut Denoise,
    raw: ArrayView2<f32>,
    mean: &[f32],
    std: &[f32],
    s: &ArflowSampling,
    normals: &mut NormalSource,
) -> Result<Array2<f32>> {
    let mut a = raw.to_owned();
    for mut row in a.outer_iter_mut() {
        for (i, v) in row.iter_mut().enumerate() {
            *v = (*v - mean[i]) / std[i];
        }
    }
    let loss = loss_of(s);
    let mut x = a.clone();
    if s.sigma > 0.0 {
        let eps = normals.draw(x.len())?;
        x.iter_mut().zip(&eps).for_each(|(v, e)| *v += s.sigma * e);
    }
    let steps = s.steps;
    for step in 0..steps {
        let (t, t_next) = times(step, steps);
        let x1 = denoise(x.view(), t)?;
        let eps = if s.eta > 0.0 {
            Some(normals.draw(x.len())?)
        } else {
            None
        };
        euler_step(
            &mut x,
            &x1,
            a.view(),
            raw,
            (mean, std),
            s,
            &loss,
            (t, t_next),
            eps.as_deref(),
        )?;
        progress::report("generating", step as u64 + 1, steps as u64)?;
    }
    for mut row in x.outer_iter_mut() {
        for (i, v) in row.iter_mut().enumerate() {
            *v = *v * std[i] + mean[i];
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arflow::spec::Mixing;

    const T: usize = 6;

    fn settings() -> ArflowSampling {
        ArflowSampling {
            steps: 5,
            guidance: 0.0,
            weight: 1.0,
            eta: 0.0,
            d_safe: 0.02,
            squared: false,
            guided_backprojection: true,
            mixing: Mixing::Linear,
            sigma: 0.0,
            stream: STREAM_ARFLOW,
        }
    }

    /// An actor standing at the origin (positions of a rough body, other features small).
    fn actor() -> Array2<f32> {
        Array2::from_shape_fn((T, FRAME_DIM), |(n, i)| {
            if i < POSITIONS {
                let j = i / 3;
                match i % 3 {
                    0 => 0.02 * (j as f32 % 3.0 - 1.0),
                    1 => 0.05 * j as f32,
                    _ => 0.01 * n as f32,
                }
            } else {
                0.1 * ((n * 7 + i) as f32).sin()
            }
        })
    }

    /// An affine stand-in for the network: x̂_1 = 0.5 x + 0.1 t + (a shift of 3 cm in x).
    fn stub(x: ArrayView2<f32>, t: f32) -> Result<Array2<f32>> {
        Ok(x.mapv(|v| 0.5 * v + 0.1 * t + 0.03))
    }

    fn unit() -> (Vec<f32>, Vec<f32>) {
        (vec![0.0; FRAME_DIM], vec![1.0; FRAME_DIM])
    }

    #[test]
    fn without_guidance_reweighting_or_noise_it_is_eulers_step() {
        let (mean, std) = unit();
        let a = actor();
        let mut normals = NormalSource::seeded(0, STREAM_ARFLOW);
        let got = sample(&mut stub, a.view(), &mean, &std, &settings(), &mut normals).unwrap();
        // Eq. 9, written out independently.
        let mut x = a.clone();
        let m = 5;
        for step in 0..m {
            let (t, tn) = (step as f32 / m as f32, (step + 1) as f32 / m as f32);
            let x1 = stub(x.view(), t).unwrap();
            x = &x * ((1.0 - tn) / (1.0 - t)) + &x1 * ((tn - t) / (1.0 - t));
        }
        let err = (&got - &x).iter().fold(0f32, |e, v| e.max(v.abs()));
        assert!(err < 1e-6, "{err}");
    }

    #[test]
    fn guidance_reweighting_and_noise_follow_the_documented_formulas() {
        let (mean, std) = unit();
        let a = actor();
        let mut s = settings();
        s.steps = 3;
        s.guidance = 2.0;
        s.weight = 0.7;
        s.eta = 0.1;
        s.mixing = Mixing::VariancePreserving;
        let seed = 11;
        let mut normals = NormalSource::seeded(seed, s.stream);
        let got = sample(&mut stub, a.view(), &mean, &std, &s, &mut normals).unwrap();
        let loss = PenetrationLoss {
            d_safe: 0.02,
            hinge: Hinge::Linear,
        };
        let mut x = a.clone();
        let mut any_guidance = false;
        for step in 0..3u64 {
            let (t, tn) = (step as f32 / 3.0, (step + 1) as f32 / 3.0);
            let x1 = stub(x.view(), t).unwrap();
            let g = guidance_gradient(x1.view(), a.view(), &mean, &std, &loss).unwrap();
            any_guidance |= g.iter().any(|v| *v != 0.0);
            let x1g = ndarray::Zip::from(&x1)
                .and(&g)
                .map_collect(|&v, &g| (v as f64 - 2.0 * g) as f32);
            let x0 = (&x - &(&x1g * t)) / (1.0 - t);
            let x0w = &x0 * 0.7 + &a * 0.3;
            let v = &x1g - &x0w;
            let mut eps = vec![0f32; x.len()];
            crate::shared::noise::fill_normals(seed, step, STREAM_ARFLOW, &mut eps);
            let eps = Array2::from_shape_vec(x.raw_dim(), eps).unwrap();
            let d = &v * (1.0f32 - 0.01).sqrt() + &eps * 0.1;
            x = &x1g - &(&d * (1.0 - tn));
        }
        assert!(
            any_guidance,
            "the stub should put the reactor inside the actor"
        );
        let err = (&got - &x).iter().fold(0f32, |e, v| e.max(v.abs()));
        assert!(err < 1e-5, "{err}");
    }

    #[test]
    fn the_guidance_gradient_is_the_losses_derivative_in_feature_space() {
        let a = actor();
        let mean: Vec<f32> = (0..FRAME_DIM).map(|i| 0.01 * i as f32).collect();
        let std: Vec<f32> = (0..FRAME_DIM).map(|i| 0.5 + 0.01 * i as f32).collect();
        // A reactor near the actor, in normalised features.
        let x1 = Array2::from_shape_fn((T, FRAME_DIM), |(n, i)| {
            (a[[n, i]] + 0.03 * ((i % 5) as f32) - mean[i]) / std[i]
        });
        let loss = PenetrationLoss {
            d_safe: 0.05,
            hinge: Hinge::Squared,
        };
        let g = guidance_gradient(x1.view(), a.view(), &mean, &std, &loss).unwrap();
        let value = |x: &Array2<f32>| {
            let body = BodyModel::t2m22();
            let joints = |row: ndarray::ArrayView1<f32>, m: &[f32], s: &[f32]| -> Vec<Vec3> {
                (0..22)
                    .map(|j| {
                        let p = |k: usize| {
                            row[3 * j + k] as f64 * s[3 * j + k] as f64 + m[3 * j + k] as f64
                        };
                        [p(0), p(1), p(2)]
                    })
                    .collect()
            };
            let zero = vec![0f32; FRAME_DIM];
            let one = vec![1f32; FRAME_DIM];
            let r: Vec<_> = x.outer_iter().map(|row| joints(row, &mean, &std)).collect();
            let act: Vec<_> = a.outer_iter().map(|row| joints(row, &zero, &one)).collect();
            loss.evaluate(&body, &act, &r).unwrap().loss
        };
        let h = 1e-3f32;
        let mut checked = 0;
        for (n, i) in [(0, 0), (1, 4), (2, 31), (3, 65), (4, 10), (5, 50)] {
            let mut up = x1.clone();
            let mut down = x1.clone();
            up[[n, i]] += h;
            down[[n, i]] -= h;
            let fd = (value(&up) - value(&down)) / (2.0 * h as f64);
            assert!(
                (fd - g[[n, i]]).abs() < 1e-3 * (1.0 + fd.abs()),
                "({n}, {i}): {fd} vs {}",
                g[[n, i]]
            );
            checked += usize::from(g[[n, i]] != 0.0);
        }
        assert!(checked > 0, "no checked entry had a gradient");
        assert!(g
            .slice(ndarray::s![.., POSITIONS..])
            .iter()
            .all(|v| *v == 0.0));
    }
}
