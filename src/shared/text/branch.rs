//! The official text branch, shared by ARMFlow and UMF bundles: CLIP's token features for one
//! prompt and the index of its end-of-text token go in, the family's condition vector comes out.

use ndarray::ArrayView2;
use tract_onnx::prelude::Tensor;

use crate::shared::checks::check_input;
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, read_f32, Graph};
use crate::shared::graph_spec::{contract, float, sym, DType, Dim, GraphSpec, TensorSpec};
use crate::shared::limits::{at_most, LIMITS};

/// The interface a `text_branch` graph must have: CLIP's token features `[B, T, token_dim]` and
/// the end-of-text index `[B]` give the condition `[B, condition_dim]`.
pub(crate) fn text_branch_contract(
    g: &GraphSpec,
    token_dim: usize,
    condition_dim: usize,
) -> GraphSpec {
    contract(
        g,
        vec![
            float(
                "clip_tokens",
                vec![sym("B"), sym("T"), Dim::Fixed(token_dim)],
            ),
            TensorSpec {
                name: "eot_index".into(),
                dtype: DType::Int64,
                shape: vec![sym("B")],
            },
        ],
        vec![float(
            "condition",
            vec![sym("B"), Dim::Fixed(condition_dim)],
        )],
    )
}

/// A bundle's loaded text branch and the widths of what it reads and writes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TextBranch<'g> {
    /// The `text_branch` graph.
    pub graph: &'g Graph,
    /// Floats per CLIP token feature it reads.
    pub token_dim: usize,
    /// Floats of the condition it writes.
    pub condition_dim: usize,
}

impl TextBranch<'_> {
    /// Runs the branch on one prompt's `[tokens, token_dim]` features and its end-of-text index.
    pub(crate) fn encode(
        &self,
        clip_tokens: ArrayView2<f32>,
        eot_index: usize,
    ) -> Result<Vec<f32>> {
        let width = self.token_dim;
        let t = clip_tokens.nrows();
        if clip_tokens.ncols() != width || t == 0 {
            return Err(Error::InvalidInput(format!(
                "CLIP token features are {t}x{}, expected at least one token of {width} floats",
                clip_tokens.ncols()
            )));
        }
        at_most("CLIP tokens", t as u64, LIMITS.max_text_tokens, false)?;
        if eot_index >= t {
            return Err(Error::InvalidInput(format!(
                "end-of-text index {eot_index} is outside the {t} tokens"
            )));
        }
        let flat: Vec<f32> = clip_tokens.iter().copied().collect();
        check_input("CLIP token features", &flat)?;
        let eot = Tensor::from_shape(&[1], &[eot_index as i64]).expect("shape matches data");
        let out = self
            .graph
            .run(vec![f32_tensor(&[1, t, width], &flat), eot.into()])?;
        Ok(read_f32(
            "text_branch",
            "condition",
            &out[0],
            &[1, self.condition_dim],
        )?
        .to_vec())
    }
}
