//! The causal context encoder: its dense work in the bundle's `context_layers` graphs, its
//! attention here, over the key/value caches the runtime owns (`kv_cache.rs`).
//!
//! One call runs every new token of every stream of a round as one row of each graph, so a
//! crowd reads each weight once per round, whatever the streams' history lengths: only the
//! attention, which is per stream, reads a stream's own cache, where it lies.
//!
//! ```text
//! tokens ─▶ layer 0 ─q,k,v─▶ attention 0 ─▶ layer 1 ─q,k,v─▶ attention 1 ─▶ … ─▶ layer L ─▶ context
//!           (graph)     │     (Rust, per    (graph)    │                          (graph)
//!                       ▼      stream)                 ▼
//!                 cache layer 0                  cache layer 1
//! ```

use tract_onnx::prelude::{TValue, Tensor};

use super::kv_cache::KvCache;
use super::spec::ContextSpec;
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, f32_tensor_owned, read_f32, Graph};

const ROLE: &str = "context_layers";

/// The loaded `context_layers` graphs.
#[derive(Debug)]
pub(crate) struct ContextEncoder {
    spec: ContextSpec,
    /// `layers + 1` graphs, in order.
    layers: Vec<Graph>,
}

impl ContextEncoder {
    pub(crate) fn new(spec: ContextSpec, layers: Vec<Graph>) -> Self {
        Self { spec, layers }
    }

    /// One step for a batch of streams. Stream `b` appends its `S` tokens (`width` floats each,
    /// at `positions[b * S..]`) to `caches[b]`, under `modulations[b]` (`[1, layers, 6,
    /// width]`), or, with `B * S` modulations, each token under its own (a feedback bundle's
    /// tokens each have their condition). Returns the contexts at each stream's last token,
    /// `[B, width]` row-major. The caches are written in place and not committed: the caller
    /// commits or rolls them back with the rest of the step.
    pub(crate) fn step(
        &self,
        caches: &mut [&mut KvCache],
        tokens: &[f32],
        positions: &[i64],
        modulations: &[&TValue],
    ) -> Result<Vec<f32>> {
        let (c, layers, b) = (self.spec.width, self.spec.layers, caches.len());
        if b == 0 {
            return Err(Error::InvalidInput("an empty batch".into()));
        }
        let s = positions.len() / b;
        let rows = b * s;
        if s == 0 || positions.len() != rows || tokens.len() != rows * c {
            return Err(Error::InvalidInput(format!(
                "{} tokens of {} floats at {} positions for {b} streams",
                tokens.len() / c.max(1),
                c,
                positions.len()
            )));
        }
        if modulations.len() != b && modulations.len() != rows {
            return Err(Error::InvalidInput(format!(
                "{} modulations for {b} streams of {s} tokens",
                modulations.len()
            )));
        }
        let per_row = modulations.len() == rows && s > 1;
        let modulations = modulations
            .iter()
            .map(|m| read_f32(ROLE, "modulation", m, &[1, layers, 6, c]))
            .collect::<Result<Vec<_>>>()?;
        // Every row's modulation of each layer, `[6, rows, width]`: component-major, so that
        // the graphs read each component as one contiguous block (a block's modulation is read
        // by the graph that starts it and by the one that finishes it).
        let layer_modulation: Vec<TValue> = (0..layers)
            .map(|i| {
                let mut data = Vec::with_capacity(6 * rows * c);
                for k in 0..6 {
                    let at = (i * 6 + k) * c;
                    for m in &modulations {
                        for _ in 0..if per_row { 1 } else { s } {
                            data.extend_from_slice(&m[at..at + c]);
                        }
                    }
                }
                f32_tensor_owned(&[6, rows, c], data)
            })
            .collect();
        let slots = caches
            .iter_mut()
            .map(|cache| cache.reserve(s))
            .collect::<Result<Vec<_>>>()?;

        let positions = Tensor::from_shape(&[rows], positions)
            .expect("shape matches data")
            .into();
        let mut out = self.layers[0].run(vec![
            f32_tensor(&[rows, c], tokens),
            positions,
            layer_modulation[0].clone(),
        ])?;
        let mut skips = Vec::new();
        let mut scores = Vec::new();
        for i in 1..=layers {
            let attention = self.attend(caches, &slots, i - 1, &out, s, &mut scores)?;
            let x = out.swap_remove(0);
            let mut inputs = vec![
                x,
                f32_tensor_owned(&[rows, c], attention),
                layer_modulation[i - 1].clone(),
            ];
            if i < layers {
                inputs.push(layer_modulation[i].clone());
                if i > layers / 2 {
                    inputs.push(skips.pop().ok_or_else(|| self.fail("no skip to fuse"))?);
                }
            }
            out = self.layers[i].run(inputs)?;
            // The in layers' outputs are the skips the out layers fuse, last first.
            if i <= layers / 2 {
                skips.push(out[0].clone());
            }
        }
        let context = read_f32(ROLE, "context", &out[0], &[rows, c])?;
        Ok((0..b)
            .flat_map(|row| &context[(row * s + s - 1) * c..(row * s + s) * c])
            .copied()
            .collect())
    }

    /// Writes block `layer`'s new keys and values (`out` of the graph that started it: `next_x`,
    /// `query`, `key`, `value`, `[rows, width]` each) into each stream's reserved slots, and
    /// returns its attention output, `[rows, width]`.
    fn attend(
        &self,
        caches: &mut [&mut KvCache],
        slots: &[Vec<usize>],
        layer: usize,
        out: &[TValue],
        s: usize,
        scores: &mut Vec<f32>,
    ) -> Result<Vec<f32>> {
        let c = self.spec.width;
        let rows = caches.len() * s;
        let [_, query, key, value] = out else {
            return Err(self.fail(&format!("{} outputs, expected 4", out.len())));
        };
        let read = |name, t| read_f32(ROLE, name, t, &[rows, c]);
        let (query, key, value) = (
            read("query", query)?,
            read("key", key)?,
            read("value", value)?,
        );
        let mut attention = vec![0f32; rows * c];
        for (b, (cache, slots)) in caches.iter_mut().zip(slots).enumerate() {
            let own = b * s * c..(b + 1) * s * c;
            for (j, &slot) in slots.iter().enumerate() {
                let row = (b * s + j) * c..(b * s + j + 1) * c;
                cache.write(layer, slot, &key[row.clone()], &value[row]);
            }
            cache.attend(
                layer,
                slots,
                &query[own.clone()],
                &mut attention[own],
                scores,
            );
        }
        Ok(attention)
    }

    fn fail(&self, message: &str) -> Error {
        Error::Inference {
            graph: ROLE,
            message: message.into(),
        }
    }
}
