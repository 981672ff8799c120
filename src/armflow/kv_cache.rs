//! The context encoder's per-layer key/value cache: runtime-owned slots written in place.
//!
//! Every layer's keys and values live in one `[1, heads, slots, head_dim]` tensor per stream,
//! passed to `context_step` as its `past_*` inputs with `key_mask` hiding the empty slots. A step
//! writes only the new entries into free slots; nothing already held is copied. Attention does not
//! depend on the order of the keys (each key carries its absolute position, added before the
//! layers), so slots need no order.
//!
//! Policy when full: `<sos>` (slot 0) always stays, and the new entry overwrites the oldest other
//! entry. The slots after 0 form a ring, so a stream runs forever in bounded memory, and while the
//! history fits the cached stream equals a full causal recompute of it. Slots are allocated up to
//! [`PREALLOCATED_SLOTS`] at once and then by doubling up to the capacity, so a stream that keeps
//! its whole history (a large capacity) attends over at most twice the entries it holds.
//!
//! A step is a transaction: [`KvCache::commit`] keeps what it wrote and [`KvCache::rollback`]
//! restores the cache as the last commit left it (the session is unchanged on failure) from a
//! journal of the entries each write overwrote.

use tract_onnx::prelude::{IntoTensor, TValue, Tensor};

use super::spec::{ContextSpec, StepReturns};
use crate::shared::error::{Error, Result};
use crate::shared::graph::{f32_tensor, f32_tensor_owned, read_f32};

/// What `key_mask` adds to the score of an empty or padding slot: the softmax gives it weight 0.
const MASKED: f32 = -1e30;

/// Slots a cache allocates on its first entry (or its capacity, when smaller).
pub(crate) const PREALLOCATED_SLOTS: usize = 16;

/// Keys and values of every layer in the graph's order (`key_0, value_0, key_1, ...`).
#[derive(Debug, Clone, Default)]
pub(crate) struct KvCache {
    /// `[1, heads, slots, head_dim]` each; empty before the first entry.
    tensors: Vec<Tensor>,
    /// `key_mask` row: 0 for a slot holding an entry, [`MASKED`] for a free one.
    mask: Vec<f32>,
    /// Entries held (`<sos>` included), at most `capacity`.
    len: usize,
    /// The most entries held at once (`<sos>` included, >= 2).
    capacity: usize,
    /// Entries written after `<sos>` so far: the ring's write position once full.
    written: u64,
    heads: usize,
    head_dim: usize,
    layers: usize,
    /// Undo records since the last commit, oldest first.
    journal: Vec<Overwrite>,
    /// `(len, written)` at the last commit.
    committed: (usize, u64),
}

/// What one write replaced: the slot, whether it held an entry, and its old rows per tensor.
#[derive(Debug, Clone)]
struct Overwrite {
    slot: usize,
    held: bool,
    rows: Vec<f32>,
}

impl KvCache {
    /// A cache holding nothing that keeps up to `capacity` entries (`<sos>` included, >= 2).
    pub(crate) fn empty(spec: &ContextSpec, capacity: usize) -> Self {
        Self {
            capacity: capacity.max(2),
            heads: spec.heads,
            head_dim: spec.head_dim,
            layers: spec.layers,
            ..Self::default()
        }
    }

    /// Entries held per layer.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// Slots allocated per layer.
    fn slots(&self) -> usize {
        self.mask.len()
    }

    /// Bytes of keys and values allocated.
    pub(crate) fn bytes(&self) -> usize {
        2 * self.layers * self.heads * self.slots() * self.head_dim * 4
    }

    /// The `past_*` inputs and `key_mask` of a context step that appends `new` entries to each
    /// of a batch of streams: each cache's slots padded to the most slots in the batch,
    /// `[B, heads, P, head_dim]`, and `[B, P]` with [`MASKED`] on free slots, padding, and the
    /// entries the new ones will replace (a full cache drops its oldest before the step, so
    /// the step attends to `capacity` entries, as a full recompute of the kept ones would). A
    /// batch of one moves its tensors in without copying: [`KvCache::restore`] takes them back
    /// after the call.
    pub(crate) fn batch_inputs(
        caches: &mut [&mut KvCache],
        new: usize,
    ) -> Result<(Vec<TValue>, TValue)> {
        let slots = caches.iter().map(|c| c.slots()).max().unwrap_or(0);
        if let [one] = caches {
            let mask = one.step_mask(new);
            let past = if one.tensors.is_empty() {
                vec![Self::zeros(one.heads, one.head_dim, 0); 2 * one.layers]
            } else {
                one.tensors.drain(..).map(TValue::from).collect()
            };
            return Ok((past, f32_tensor(&[1, slots], &mask)));
        }
        let first = caches
            .first()
            .ok_or_else(|| Error::InvalidInput("an empty batch".into()))?;
        let (heads, dh, layers, b) = (first.heads, first.head_dim, first.layers, caches.len());
        let mut mask = vec![MASKED; b * slots];
        for (row, cache) in caches.iter().enumerate() {
            mask[row * slots..row * slots + cache.slots()].copy_from_slice(&cache.step_mask(new));
        }
        let mut past = Vec::with_capacity(2 * layers);
        for i in 0..2 * layers {
            let mut padded = vec![0f32; b * heads * slots * dh];
            for (row, cache) in caches.iter().enumerate() {
                let Some(tensor) = cache.tensors.get(i) else {
                    continue; // nothing held yet: all padding
                };
                let own = cache.slots();
                let src = plain(tensor)?;
                for h in 0..heads {
                    let dst = ((row * heads + h) * slots) * dh;
                    padded[dst..dst + own * dh]
                        .copy_from_slice(&src[h * own * dh..(h + 1) * own * dh]);
                }
            }
            past.push(f32_tensor_owned(&[b, heads, slots, dh], padded));
        }
        Ok((past, f32_tensor(&[b, slots], &mask)))
    }

    /// Takes back the tensors a batch of one moved into the call (the graph has released them,
    /// so this does not copy).
    pub(crate) fn restore(&mut self, past: Vec<TValue>) {
        if self.tensors.is_empty() && self.slots() > 0 {
            self.tensors = past.into_iter().map(IntoTensor::into_tensor).collect();
        }
    }

    /// Appends the `new` entries of batch row `row` from a step's key/value outputs, which hold
    /// `returned` entries per row whose last `new` are the new ones: `[B, heads, returned,
    /// head_dim]` (`returned = new` for [`StepReturns::NewEntries`], past slots + new for
    /// [`StepReturns::WholeCache`]).
    pub(crate) fn append(
        &mut self,
        outputs: &[TValue],
        row: usize,
        new: usize,
        returns: StepReturns,
        past_slots: usize,
    ) -> Result<()> {
        if self.capacity < 2 {
            // Only the placeholder a session leaves while a step holds its cache is this small.
            return Err(cache_error(&"writing to a cache that holds no slots"));
        }
        let (heads, dh) = (self.heads, self.head_dim);
        let (returned, what) = match returns {
            StepReturns::NewEntries => (new, "new key/value"),
            StepReturns::WholeCache => (past_slots + new, "present key/value"),
        };
        let batch = outputs.first().map_or(0, |t| t.shape()[0]);
        if outputs.len() != 2 * self.layers || row >= batch {
            return Err(Error::Inference {
                graph: "context_step",
                message: format!(
                    "{} key/value outputs for batch row {row}, expected {} of batch > {row}",
                    outputs.len(),
                    2 * self.layers
                ),
            });
        }
        let sources = outputs
            .iter()
            .map(|t| read_f32("context_step", what, t, &[batch, heads, returned, dh]))
            .collect::<Result<Vec<_>>>()?;
        for k in 0..new {
            let entry = returned - new + k;
            let slot = self.free_slot()?;
            let held = self.held(slot);
            let mut rows = Vec::new();
            if held {
                for tensor in &self.tensors {
                    let slots = self.mask.len();
                    let src = plain(tensor)?;
                    for h in 0..heads {
                        let at = (h * slots + slot) * dh;
                        rows.extend_from_slice(&src[at..at + dh]);
                    }
                }
            }
            // Journal first: a rollback then restores this slot whatever happens below.
            self.journal.push(Overwrite { slot, held, rows });
            self.mask[slot] = 0.0;
            for (tensor, src) in self.tensors.iter_mut().zip(&sources) {
                let dst = plain_mut(tensor)?;
                let slots = dst.len() / (heads * dh);
                for h in 0..heads {
                    let at = (h * slots + slot) * dh;
                    let from = ((row * heads + h) * returned + entry) * dh;
                    dst[at..at + dh].copy_from_slice(&src[from..from + dh]);
                }
            }
            if self.len > 0 {
                self.written += 1;
            }
            self.len = (self.len + 1).min(self.capacity);
        }
        Ok(())
    }

    /// Keeps every entry written since the last commit.
    pub(crate) fn commit(&mut self) {
        self.journal.clear();
        self.committed = (self.len, self.written);
    }

    /// Restores the entries and counts of the last commit (allocated slots stay allocated).
    pub(crate) fn rollback(&mut self) {
        let (heads, dh) = (self.heads, self.head_dim);
        for undo in self.journal.drain(..).rev() {
            self.mask[undo.slot] = if undo.held { 0.0 } else { MASKED };
            if !undo.held {
                continue;
            }
            for (tensor, old) in self.tensors.iter_mut().zip(undo.rows.chunks(heads * dh)) {
                // A tensor that cannot be viewed was never written either.
                let Ok(dst) = plain_mut(tensor) else { continue };
                let slots = dst.len() / (heads * dh);
                for h in 0..heads {
                    let at = (h * slots + undo.slot) * dh;
                    dst[at..at + dh].copy_from_slice(&old[h * dh..(h + 1) * dh]);
                }
            }
        }
        (self.len, self.written) = self.committed;
    }

    /// The `key_mask` row of a step appending `new` entries: the held slots those entries
    /// will overwrite are hidden.
    fn step_mask(&self, new: usize) -> Vec<f32> {
        let mut mask = self.mask.clone();
        let ring = self.ring();
        for k in 0..new {
            if self.len + k >= self.capacity {
                let slot = 1 + ((self.written + k as u64) % ring) as usize;
                if let Some(m) = mask.get_mut(slot) {
                    *m = MASKED;
                }
            }
        }
        mask
    }

    /// Slots in the ring after `<sos>` (at least 1, even for the empty placeholder a session
    /// leaves while a step holds its cache).
    fn ring(&self) -> u64 {
        (self.capacity as u64).saturating_sub(1).max(1)
    }

    /// Whether `slot` holds an entry.
    fn held(&self, slot: usize) -> bool {
        self.mask.get(slot).is_some_and(|&m| m == 0.0)
    }

    /// The slot the next entry goes to, allocating slots when none is free.
    fn free_slot(&mut self) -> Result<usize> {
        if self.len < self.capacity {
            if self.len == self.slots() {
                self.grow()?;
            }
            return Ok(self.len);
        }
        // Full: overwrite the oldest entry after `<sos>` (slots 1..capacity form the ring).
        Ok(1 + (self.written % self.ring()) as usize)
    }

    /// Allocates more slots, copying the held ones to the same indices (once per doubling).
    fn grow(&mut self) -> Result<()> {
        let (heads, dh, old) = (self.heads, self.head_dim, self.slots());
        let slots = if old == 0 {
            self.capacity.min(PREALLOCATED_SLOTS)
        } else {
            (2 * old).min(self.capacity)
        };
        let mut tensors = Vec::with_capacity(2 * self.layers);
        for i in 0..2 * self.layers {
            let mut data = vec![0f32; heads * slots * dh];
            if let Some(t) = self.tensors.get(i) {
                let src = plain(t)?;
                for h in 0..heads {
                    data[h * slots * dh..(h * slots + old) * dh]
                        .copy_from_slice(&src[h * old * dh..(h + 1) * old * dh]);
                }
            }
            tensors.push(
                Tensor::from_shape(&[1, heads, slots, dh], &data).map_err(|e| {
                    Error::Inference {
                        graph: "context_step",
                        message: format!("allocating cache slots: {e:#}"),
                    }
                })?,
            );
        }
        self.tensors = tensors;
        self.mask.resize(slots, MASKED);
        Ok(())
    }

    fn zeros(heads: usize, dh: usize, slots: usize) -> TValue {
        f32_tensor(&[1, heads, slots, dh], &[])
    }
}

fn plain(t: &Tensor) -> Result<&[f32]> {
    t.try_as_plain_ram()
        .and_then(|v| v.as_slice::<f32>())
        .map_err(|e| cache_error(&e))
}

fn plain_mut(t: &mut Tensor) -> Result<&mut [f32]> {
    t.to_plain_array_view_mut::<f32>()
        .map_err(|e| cache_error(&e))?
        .into_slice()
        .ok_or_else(|| cache_error(&"not contiguous"))
}

fn cache_error(e: &impl std::fmt::Display) -> Error {
    Error::Inference {
        graph: "context_step",
        message: format!("key/value cache tensor: {e:#}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADS: usize = 2;
    const DH: usize = 3;

    fn cache(capacity: usize) -> KvCache {
        let spec = ContextSpec {
            width: HEADS * DH,
            layers: 1,
            heads: HEADS,
            head_dim: DH,
            capacity_tokens: capacity,
            step_returns: StepReturns::NewEntries,
        };
        KvCache::empty(&spec, capacity)
    }

    /// The new-entry outputs of one step of one stream whose entry is filled with `id`.
    fn entry(id: f32) -> Vec<TValue> {
        vec![f32_tensor(&[1, HEADS, 1, DH], &[id; HEADS * DH]); 2]
    }

    /// The ids held, as a sorted list (the value of each held slot's first float).
    fn held(c: &KvCache) -> Vec<f32> {
        let keys = plain(&c.tensors[0]).unwrap();
        let mut ids: Vec<f32> = (0..c.slots())
            .filter(|&s| c.held(s))
            .map(|s| keys[s * DH])
            .collect();
        ids.sort_by(f32::total_cmp);
        ids
    }

    fn push(c: &mut KvCache, id: f32) {
        c.append(&entry(id), 0, 1, StepReturns::NewEntries, c.slots())
            .unwrap();
    }

    #[test]
    fn a_full_ring_keeps_sos_and_the_newest() {
        let mut c = cache(4);
        for id in 0..10 {
            assert_eq!(
                c.step_mask(1).iter().filter(|&&m| m == 0.0).count(),
                id.min(3)
            );
            push(&mut c, id as f32);
        }
        assert_eq!(held(&c), [0.0, 7.0, 8.0, 9.0]);
        assert_eq!((c.len(), c.slots()), (4, 4));
    }

    #[test]
    fn rollback_restores_overwritten_entries_and_counts() {
        let mut c = cache(3);
        for id in 0..5 {
            push(&mut c, id as f32);
        }
        c.commit();
        let (before, tensors) = (held(&c), c.tensors.clone());
        for id in 5..9 {
            push(&mut c, id as f32);
        }
        assert_eq!(held(&c), [0.0, 7.0, 8.0]);
        c.rollback();
        assert_eq!(held(&c), before);
        assert_eq!(c.tensors, tensors);
        push(&mut c, 5.0);
        assert_eq!(held(&c), [0.0, 4.0, 5.0], "the ring goes on where it was");
    }

    #[test]
    fn slots_grow_by_doubling_up_to_the_capacity() {
        let mut c = cache(300);
        let mut sizes = Vec::new();
        for id in 0..300 {
            push(&mut c, id as f32);
            if sizes.last() != Some(&c.slots()) {
                sizes.push(c.slots());
            }
        }
        assert_eq!(sizes, [16, 32, 64, 128, 256, 300]);
        assert_eq!(held(&c), (0..300).map(|i| i as f32).collect::<Vec<_>>());
    }
}
