//! The context encoder's per-layer key/value cache and its capacity policy.
//!
//! Policy when full: the cache always keeps the `<sos>` entry (position 0) and the newest
//! entries, dropping the oldest `(actor || reactor)` pair first, so a stream runs forever in
//! bounded memory. Kept entries retain their original absolute positions (their keys were
//! computed with them); new tokens keep counting up. While the history fits, the cached stream
//! equals a full causal recompute of it.

use tract_onnx::prelude::{IntoTValue, TValue, Tensor, TractResult};

use super::spec::ContextSpec;
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, f32_tensor_owned, read_f32};

/// What `key_mask` adds to the score of a padding entry: the softmax gives it weight 0.
const MASKED: f32 = -1e30;

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

    /// Bytes of keys and values held.
    pub(crate) fn bytes(&self) -> usize {
        self.tensors.iter().map(|t| t.len() * 4).sum()
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

    /// The `past_*` inputs and `key_mask` of a context step over a batch of streams: each cache
    /// padded to the longest, `[B, heads, P, head_dim]`, and `[B, P]` with [`MASKED`] on the
    /// padding. A batch of one is passed through without copying.
    pub(crate) fn batch_inputs(caches: &[&KvCache]) -> Result<(Vec<TValue>, TValue)> {
        let longest = caches.iter().map(|c| c.len).max().unwrap_or(0);
        if let [one] = caches {
            return Ok((
                one.tensors.clone(),
                f32_tensor(&[1, longest], &vec![0.0; longest]),
            ));
        }
        let first = caches
            .first()
            .ok_or_else(|| Error::InvalidInput("an empty batch".into()))?;
        let (heads, dh, b) = (first.heads, first.head_dim, caches.len());
        let mut mask = vec![0f32; b * longest];
        for (row, cache) in caches.iter().enumerate() {
            mask[row * longest + cache.len..(row + 1) * longest].fill(MASKED);
        }
        let mut past = Vec::with_capacity(first.tensors.len());
        for i in 0..first.tensors.len() {
            let mut padded = vec![0f32; b * heads * longest * dh];
            for (row, cache) in caches.iter().enumerate() {
                let len = cache.len;
                let src = read_f32(
                    "context_step",
                    "past",
                    &cache.tensors[i],
                    &[1, heads, len, dh],
                )?;
                for h in 0..heads {
                    let dst = ((row * heads + h) * longest) * dh;
                    padded[dst..dst + len * dh]
                        .copy_from_slice(&src[h * len * dh..(h + 1) * len * dh]);
                }
            }
            past.push(f32_tensor_owned(&[b, heads, longest, dh], padded));
        }
        Ok((past, f32_tensor(&[b, longest], &mask)))
    }

    /// Takes stream `row`'s entries from a batched step's `present_*` outputs
    /// (`[B, heads, padded + 1, head_dim]`): its own `len` entries and the one appended.
    pub(crate) fn take_row(&mut self, present: &[TValue], row: usize, padded: usize) -> Result<()> {
        let batch = present.first().map_or(0, |t| t.shape()[0]);
        let (heads, dh, len) = (self.heads, self.head_dim, self.len);
        let mut tensors = Vec::with_capacity(present.len());
        for t in present {
            let all = read_f32(
                "context_step",
                "present",
                t,
                &[batch, heads, padded + 1, dh],
            )?;
            let mut mine = Vec::with_capacity(heads * (len + 1) * dh);
            for h in 0..heads {
                let at = ((row * heads + h) * (padded + 1)) * dh;
                mine.extend_from_slice(&all[at..at + len * dh]);
                mine.extend_from_slice(&all[at + padded * dh..at + (padded + 1) * dh]);
            }
            tensors.push(f32_tensor_owned(&[1, heads, len + 1, dh], mine));
        }
        self.replace(tensors, 1)
    }

    /// Drops the oldest entries after `<sos>` so that at most `keep` remain (`keep >= 1`).
    pub(crate) fn evict_to(&mut self, keep: usize) -> Result<()> {
        let keep = keep.max(1);
        if self.len <= keep {
            return Ok(());
        }
        let from = self.len - (keep - 1);
        let evict = |t: &TValue| -> TractResult<TValue> {
            let sos = t.slice(SEQ_AXIS, 0, 1)?;
            // keep == 1 (capacity 2) keeps `<sos>` alone: tract refuses an empty slice.
            if from == self.len {
                return Ok(sos.into_tvalue());
            }
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
