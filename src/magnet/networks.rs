//! The loaded graphs of a `magnet` bundle and their typed calls, with the codebook (read from its
//! file) and the manifest section they are run by.

use ndarray::{s, Array2, Array3, Array4, ArrayView3, ArrayView4, Axis};
use tract_onnx::prelude::{IntoTValue, TValue};

use super::layout::{BETAS, DECODER_COND_DIM, ENCODER_COND_DIM, FRAMES_PER_TOKEN, POSE_DIM};
use super::schedule::Schedule;
use super::spec::MagnetSpec;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::error::{Error, Result};
use crate::shared::graph::{load_graphs, Graph, PlanPolicy};
use crate::shared::limits::LIMITS;

/// A `magnet` bundle's graphs, loaded and optimised, with its own manifest section, the common
/// facts it needs and the codebook. Shared (`Arc`) by the [`crate::Model`] handles that loaded it.
#[derive(Debug)]
pub(crate) struct Networks {
    pub io: BundleIo,
    pub spec: MagnetSpec,
    /// The manifest's schedule tables, as the sampler reads them.
    pub schedule: Schedule,
    denoiser: Graph,
    vq_encoder: Graph,
    vq_decoder: Graph,
    guidance: Graph,
    /// `[code_nb, d_latent]`, row-major.
    codebook: Vec<f32>,
    /// `‖c‖²` of each codebook row, for [`Networks::snap`].
    code_norms: Vec<f32>,
}

impl Networks {
    /// Loads every graph `spec` names, and the codebook, from `files`. The guidance graph is
    /// checked at load and optimised on first use (configurations may turn guidance off).
    pub(crate) fn load(files: &BundleFiles, io: BundleIo, spec: MagnetSpec) -> Result<Self> {
        let g = &spec.graphs;
        let wanted = [
            ("denoiser", &g.denoiser),
            ("vq_encoder", &g.vq_encoder),
            ("vq_decoder", &g.vq_decoder),
            ("guidance", &g.guidance),
        ];
        let mut graphs = load_graphs(files, &wanted, |role| PlanPolicy {
            deferred: role == "guidance",
            ..PlanPolicy::default()
        })?
        .into_iter();
        let mut next = || graphs.next().expect("one graph per wanted entry");
        let (denoiser, vq_encoder, vq_decoder, guidance) = (next(), next(), next(), next());
        let codebook = read_codebook(files, &spec)?;
        let code_norms = codebook
            .chunks_exact(spec.model.vq.d_latent)
            .map(|code| code.iter().fold(0f32, |acc, v| acc + v * v))
            .collect();
        let s = &spec.schedule;
        let schedule = Schedule {
            abar: s.abar.clone(),
            sqrt_abar: s.sqrt_abar.clone(),
            sqrt_one_minus_abar: s.sqrt_one_minus_abar.clone(),
        };
        Ok(Self {
            schedule,
            io,
            spec,
            denoiser,
            vq_encoder,
            vq_decoder,
            guidance,
            codebook,
            code_norms,
        })
    }

    /// x0 of a window `[B, Tm, P, D]` at per-token `levels` `[Tm, P]`, the same for every row.
    pub(crate) fn denoise(&self, x: ArrayView4<f32>, levels: &[i64]) -> Result<Array4<f32>> {
        let shape = x.shape().to_vec();
        let per_row = shape[1] * shape[2];
        let k: Vec<i64> = (0..shape[0]).flat_map(|_| levels.iter().copied()).collect();
        debug_assert_eq!(levels.len(), per_row);
        let k = ndarray::Array3::from_shape_vec((shape[0], shape[1], shape[2]), k)
            .expect("levels match the window")
            .into_tvalue();
        let values = self.denoiser.run_checked(
            "x0",
            vec![x.to_owned().into_dyn().into_tvalue(), k],
            &shape,
        )?;
        Ok(
            Array4::from_shape_vec((shape[0], shape[1], shape[2], shape[3]), values)
                .expect("shape checked"),
        )
    }

    /// The VQ encoder (not snapped): pose `[N, T, 135]`, condition `[N, T, 19]` ->
    /// `[N, T/4, d_latent]`.
    pub(crate) fn encode(
        &self,
        pose: ArrayView3<f32>,
        condition: ArrayView3<f32>,
    ) -> Result<Array3<f32>> {
        let (n, t) = (pose.shape()[0], pose.shape()[1]);
        debug_assert_eq!(pose.shape()[2], POSE_DIM);
        debug_assert_eq!(condition.shape()[2], ENCODER_COND_DIM);
        let shape = [n, t / FRAMES_PER_TOKEN, self.spec.model.vq.d_latent];
        let inputs = vec![
            pose.to_owned().into_dyn().into_tvalue(),
            condition.to_owned().into_dyn().into_tvalue(),
        ];
        let values = self.vq_encoder.run_checked("latents", inputs, &shape)?;
        Ok(Array3::from_shape_vec(shape, values).expect("shape checked"))
    }

    /// The VQ decoder: latents `[N, Z, d_latent]`, condition `[N, Z, 46]` -> `[N, 4Z, 135]`.
    pub(crate) fn decode(
        &self,
        latents: ArrayView3<f32>,
        condition: ArrayView3<f32>,
    ) -> Result<Array3<f32>> {
        let (n, z) = (latents.shape()[0], latents.shape()[1]);
        debug_assert_eq!(condition.shape()[2], DECODER_COND_DIM);
        let shape = [n, z * FRAMES_PER_TOKEN, POSE_DIM];
        let inputs = vec![
            latents.to_owned().into_dyn().into_tvalue(),
            condition.to_owned().into_dyn().into_tvalue(),
        ];
        let values = self.vq_decoder.run_checked("pose", inputs, &shape)?;
        Ok(Array3::from_shape_vec(shape, values).expect("shape checked"))
    }

    /// The x0 corrections' gradient on the latents (§6.4) of the people `persons` of x0
    /// `[B, Tm, P, D]` (betas `[B, P, 10]`): of `weights[0] * smoothing + weights[1] * foot
    /// skating`, the losses' means taken over the person-sequences given ->
    /// `[B, Tm, persons.len(), d_latent]`. The graph sees one person of one sample a row,
    /// sample-major as the decoder folds them.
    pub(crate) fn correction_gradient(
        &self,
        x0: ArrayView4<f32>,
        betas: ArrayView3<f32>,
        persons: &[usize],
        weights: [f32; 2],
    ) -> Result<Array4<f32>> {
        debug_assert_eq!(betas.shape()[2], BETAS);
        let (b, t, _, d) = x0.dim();
        let q = persons.len();
        let mut sequences = Array3::<f32>::zeros((b * q, t, d));
        let mut sequence_betas = Array2::<f32>::zeros((b * q, BETAS));
        for sample in 0..b {
            for (j, &person) in persons.iter().enumerate() {
                let row = sample * q + j;
                sequences.index_axis_mut(Axis(0), row).assign(&x0.slice(s![
                    sample,
                    ..,
                    person,
                    ..
                ]));
                sequence_betas
                    .row_mut(row)
                    .assign(&betas.slice(s![sample, person, ..]));
            }
        }
        let latent = self.spec.model.vq.d_latent;
        let shape = [b * q, t, latent];
        let inputs: Vec<TValue> = vec![
            sequences.into_dyn().into_tvalue(),
            sequence_betas.into_dyn().into_tvalue(),
            ndarray::arr1(&weights).into_dyn().into_tvalue(),
        ];
        let values = self
            .guidance
            .run_checked("latent_gradient", inputs, &shape)?;
        let by_sequence = Array4::from_shape_vec((b, q, t, latent), values).expect("shape checked");
        Ok(by_sequence.permuted_axes([0, 2, 1, 3]))
    }

    /// The nearest codebook row of `z` by `‖z‖² − 2 z·c + ‖c‖²`, ties to the first (§1.4).
    pub(crate) fn snap(&self, z: &[f32], out: &mut [f32]) {
        let d = self.spec.model.vq.d_latent;
        let zz: f32 = z.iter().map(|v| v * v).sum();
        let mut best = (f32::INFINITY, 0);
        for (i, (code, cc)) in self
            .codebook
            .chunks_exact(d)
            .zip(&self.code_norms)
            .enumerate()
        {
            let dot = z.iter().zip(code).fold(0f32, |acc, (a, b)| acc + a * b);
            let dist = zz - 2.0 * dot + cc;
            if dist < best.0 {
                best = (dist, i);
            }
        }
        out.copy_from_slice(&self.codebook[best.1 * d..(best.1 + 1) * d]);
    }
}

/// The codebook file: `code_nb x d_latent` little-endian float32, every value finite.
fn read_codebook(files: &BundleFiles, spec: &MagnetSpec) -> Result<Vec<f32>> {
    let c = &spec.codebook;
    let want = c.shape.iter().product::<usize>() * 4;
    let bytes = files.read(&c.file, LIMITS.max_bundle_bytes)?;
    let bad = |message: String| Error::Graph {
        file: files.path_of(&c.file),
        message,
    };
    if bytes.len() != want {
        return Err(bad(format!(
            "the codebook holds {} bytes; float32 {:?} is {want}",
            bytes.len(),
            c.shape
        )));
    }
    let values: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!(
            "codebook row {} holds a non-finite value",
            i / c.shape[1]
        )));
    }
    Ok(values)
}
