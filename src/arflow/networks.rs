//! The loaded graph of an `arflow` bundle and its typed call.

use ndarray::{Array1, Array3, ArrayView3};
use tract_onnx::prelude::IntoTValue;

use super::spec::ArflowSpec;
use crate::shared::bundle::BundleFiles;
use crate::shared::bundle_io::BundleIo;
use crate::shared::error::Result;
use crate::shared::graph::{load_graphs, Graph};

/// An `arflow` bundle's graph, loaded and optimised, with its manifest section. Shared (`Arc`)
/// by the [`crate::Model`] handles that loaded it.
#[derive(Debug)]
pub(crate) struct Networks {
    pub io: BundleIo,
    pub spec: ArflowSpec,
    denoiser: Graph,
}

impl Networks {
    pub(crate) fn load(files: &BundleFiles, io: BundleIo, spec: ArflowSpec) -> Result<Self> {
        let wanted = [("denoiser", &spec.graphs.denoiser)];
        let denoiser = load_graphs(files, &wanted, &[])?
            .pop()
            .expect("one graph per wanted entry");
        Ok(Self { io, spec, denoiser })
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
