//! CLIP's text tower as a bundle graph (`text_encoder`): one prompt's token ids `[1, context]`
//! in, the per-token features the text branch reads `[1, context, token_dim]` out (CLIP's
//! output after its final LayerNorm).

use tract_onnx::prelude::Tensor;

use crate::shared::error::Result;
use crate::shared::graph::{read_f32, Graph};
use crate::shared::graph_spec::{contract, float, sym, DType, Dim, GraphSpec, TensorSpec};

/// The interface a `text_encoder` graph must have: token ids `[B, context]` (int64) give the
/// token features `[B, context, token_dim]`.
pub(crate) fn text_encoder_contract(g: &GraphSpec, context: usize, token_dim: usize) -> GraphSpec {
    contract(
        g,
        vec![TensorSpec {
            name: "token_ids".into(),
            dtype: DType::Int64,
            shape: vec![sym("B"), Dim::Fixed(context)],
        }],
        vec![float(
            "clip_tokens",
            vec![sym("B"), Dim::Fixed(context), Dim::Fixed(token_dim)],
        )],
    )
}

/// A bundle's loaded text tower and the sizes of what it reads and writes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TextTower<'g> {
    /// The `text_encoder` graph.
    pub graph: &'g Graph,
    /// Token ids per prompt (CLIP's 77).
    pub context: usize,
    /// Floats per token feature.
    pub token_dim: usize,
}

impl TextTower<'_> {
    /// The token features of one prompt's `context` ids, row-major `[context, token_dim]`.
    pub(crate) fn features(&self, ids: &[i64]) -> Result<Vec<f32>> {
        debug_assert_eq!(ids.len(), self.context);
        let ids = Tensor::from_shape(&[1, self.context], ids).expect("shape matches data");
        let out = self.graph.run(vec![ids.into()])?;
        let shape = [1, self.context, self.token_dim];
        Ok(read_f32("text_encoder", "clip_tokens", &out[0], &shape)?.to_vec())
    }
}
