//! The context encoder's per-layer key/value cache and its capacity policy.
//!
//! Policy when full: the cache always keeps the `<sos>` entry (position 0) and the newest
//! entries, dropping the oldest `(actor || reactor)` pair first, so a stream runs forever in
//! bounded memory. Kept entries retain their original absolute positions (their keys were
//! computed with them); new tokens keep counting up. While the history fits, the cached stream
//! equals a full causal recompute of it.

use tract_onnx::prelude::{IntoTValue, TValue, Tensor, TractResult};

use crate::error::{Error, Result};
use crate::manifest::ContextSpec;

/// Keys and values of every layer, `[1, heads, len, head_dim]` each, in the graph's order
/// (`key_0, value_0, key_1, ...`).
#[derive(Debug, Clone)]
pub(crate) struct KvCache {
    tensors: Vec<TValue>,
    len: usize,
    heads: usize,
    head_dim: usize,
}

const SEQ_AXIS: usize = 2;

impl KvCache {
    /// A cache holding nothing.
    pub(crate) fn empty(spec: &ContextSpec) -> Self {
        let zero = Tensor::zero::<f32>(&[1, spec.heads, 0, spec.head_dim])
            .expect("zero-sized tensor")
            .into_tvalue();
        Self {
            tensors: vec![zero; 2 * spec.layers],
            len: 0,
            heads: spec.heads,
            head_dim: spec.head_dim,
        }
    }

    /// Entries held per layer.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The cache tensors, ready to be fed as `past_*` inputs.
    pub(crate) fn tensors(&self) -> &[TValue] {
        &self.tensors
    }

    /// Takes the `present_*` outputs of a step that appended `added` entries.
    pub(crate) fn replace(&mut self, present: Vec<TValue>, added: usize) -> Result<()> {
        let want = [1, self.heads, self.len + added, self.head_dim];
        if present.len() != self.tensors.len() || present.iter().any(|t| t.shape() != want) {
            return Err(Error::Inference {
                graph: "context_step",
                message: format!(
                    "present key/value tensors do not have shape {want:?} (got {:?})",
                    present
                        .iter()
                        .map(|t| t.shape().to_vec())
                        .collect::<Vec<_>>()
                ),
            });
        }
        self.tensors = present;
        self.len += added;
        Ok(())
    }

    /// Drops the oldest entries after `<sos>` so that at most `keep` remain (`keep >= 1`).
    pub(crate) fn evict_to(&mut self, keep: usize) -> Result<()> {
        if self.len <= keep {
            return Ok(());
        }
        let from = self.len - (keep - 1);
        let evict = |t: &TValue| -> TractResult<TValue> {
            let sos = t.slice(SEQ_AXIS, 0, 1)?;
            let newest = t.slice(SEQ_AXIS, from, self.len)?;
            Ok(Tensor::stack_tensors(SEQ_AXIS, &[sos, newest])?.into_tvalue())
        };
        self.tensors = self
            .tensors
            .iter()
            .map(evict)
            .collect::<TractResult<_>>()
            .map_err(|e| Error::Inference {
                graph: "context_step",
                message: format!("evicting cache entries: {e:#}"),
            })?;
        self.len = keep;
        Ok(())
    }
}
