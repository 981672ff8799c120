//! The loaded graph of an `arflow` bundle and its typed call.

use ndarray::{Array1, Array2, Array3, ArrayView2, ArrayView3};
use tract_onnx::prelude::IntoTValue;

use super::spec::ArflowSpec;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::checks::check_output;
use crate::shared::error::Result;
use crate::shared::graph::{load_graphs, read_f32, Graph, PlanPolicy};

/// An `arflow` bundle's graph, loaded and optimised, with its manifest section. Shared (`Arc`)
/// by the [`crate::Model`] handles that loaded it.
#[derive(Debug)]
pub(crate) struct Networks {
    pub io: BundleIo,
    pub spec: ArflowSpec,
    denoiser: Graph,
    /// The online variant's one-frame graph (streams), when the bundle has it.
    denoiser_step: Option<Graph>,
}

/// One frame of [`Networks::denoise_step`] for `B` streams.
pub(crate) struct FrameStep {
    /// x̂_1 `[B, D]`.
    pub x1: Array2<f32>,
    /// The frame's keys and values, `[B, L, H, W/H]`.
    pub k: Vec<f32>,
    pub v: Vec<f32>,
}

impl Networks {
    pub(crate) fn load(files: &BundleFiles, io: BundleIo, spec: ArflowSpec) -> Result<Self> {
        let mut wanted = vec![("denoiser", &spec.graphs.denoiser)];
        if let Some(step) = &spec.graphs.denoiser_step {
            wanted.push(("denoiser_step", step));
        }
        let mut graphs = load_graphs(files, &wanted, |_| PlanPolicy::default())?.into_iter();
        let denoiser = graphs.next().expect("one graph per wanted entry");
        let denoiser_step = graphs.next();
        Ok(Self {
            io,
            spec,
            denoiser,
            denoiser_step,
        })
    }

    /// Whether the bundle streams (the online variant with its one-frame graph).
    pub(crate) fn streams(&self) -> bool {
        self.denoiser_step.is_some()
    }

    /// One frame of `B` streams: `x` `[B, D]` at times `t` and positions `position`, each row's
    /// earlier frames' keys and values `cache_k`/`cache_v` `[B, L, H, C, W/H]` (row-major; rows
    /// with fewer frames padded in front, `cache_mask` `[B, C]` 1 where a frame is real).
    pub(crate) fn denoise_step(
        &self,
        x: ArrayView2<f32>,
        t: &[f32],
        position: &[i64],
        cache: (Vec<f32>, Vec<f32>),
        cache_mask: Vec<f32>,
        cached: usize,
    ) -> Result<FrameStep> {
        let graph = self
            .denoiser_step
            .as_ref()
            .expect("callers check Networks::streams");
        let m = &self.spec.model;
        let (b, d) = x.dim();
        let dh = m.width / m.heads;
        let kv_shape = [b, m.layers, m.heads, cached, dh];
        let inputs = vec![
            x.to_owned()
                .into_shape_with_order((b, 1, d))
                .expect("rows")
                .into_dyn()
                .into_tvalue(),
            Array1::from(t.to_vec()).into_dyn().into_tvalue(),
            Array1::from(position.to_vec()).into_dyn().into_tvalue(),
            ndarray::ArrayD::from_shape_vec(&kv_shape[..], cache.0)
                .expect("sized by the caller")
                .into_tvalue(),
            ndarray::ArrayD::from_shape_vec(&kv_shape[..], cache.1)
                .expect("sized by the caller")
                .into_tvalue(),
            Array2::from_shape_vec((b, cached), cache_mask)
                .expect("sized by the caller")
                .into_dyn()
                .into_tvalue(),
        ];
        let out = graph.run(inputs)?;
        let one = [b, m.layers, m.heads, 1, dh];
        let x1 = read_f32(graph.role(), "x1", &out[0], &[b, 1, d])?;
        check_output(graph.role(), "x1", x1)?;
        let k = read_f32(graph.role(), "k", &out[1], &one)?.to_vec();
        let v = read_f32(graph.role(), "v", &out[2], &one)?.to_vec();
        Ok(FrameStep {
            x1: Array2::from_shape_vec((b, d), x1.to_vec()).expect("shape checked"),
            k,
            v,
        })
    }

    /// x̂_1 `[B, T, D]` of normalised `x` `[B, T, D]` at times `t` `[B]`.
    pub(crate) fn denoise(&self, x: ArrayView3<f32>, t: &[f32]) -> Result<Array3<f32>> {
        let shape = [x.shape()[0], x.shape()[1], x.shape()[2]];
        debug_assert_eq!(t.len(), shape[0]);
        let inputs = vec![
            x.to_owned().into_dyn().into_tvalue(),
            Array1::from(t.to_vec()).into_dyn().into_tvalue(),
        ];
        let values = self.denoiser.run_checked("x1", inputs, &shape)?;
        Ok(Array3::from_shape_vec(shape, values).expect("shape checked"))
    }
}
