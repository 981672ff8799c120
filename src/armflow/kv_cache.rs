//! The context encoder's key/value cache: fixed-size pages the runtime owns, written in place
//! and read where they lie by the attention kernel (`shared/attention.rs`).
//!
//! A stream's cache is a list of pages of [`PAGE_SLOTS`] slots. A page holds every layer's keys
//! and values for its slots, laid out `[layer][head]` then the keys transposed
//! (`[head_dim][slot]`, what the kernel reads a vector of entries from) and the values
//! (`[slot][head_dim]`), so what one head of one layer attends over is two contiguous blocks per
//! page. Growing adds a page;
//! nothing already held is ever copied, packed or padded, and streams of different lengths
//! step together with no common shape. Attention does not depend on the order of the keys
//! (each key carries its absolute position, added before the layers), so slots need no order:
//! the held entries are always slots `0..len`.
//!
//! Policy when full: `<sos>` (slot 0) always stays, and the new entry overwrites the oldest other
//! entry. The slots after 0 form a ring, so a stream runs forever in bounded memory, and while the
//! history fits the cached stream equals a full causal recompute of it.
//!
//! A step is a transaction: [`KvCache::reserve`] journals what the step's slots held,
//! [`KvCache::commit`] keeps what it wrote and [`KvCache::rollback`] restores the cache as the
//! last commit left it (the session is unchanged on failure).

use super::spec::ContextSpec;
use crate::shared::attention::{attend, KvBlock, COLUMNS};
use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{SnapshotReader, SnapshotWriter};

/// Slots per page: small enough that a short stream holds little (paper size: 1.8 MB a page),
/// large enough that a page's block of one head (`64 * head_dim` floats, 16 KB) streams well. A
/// multiple of the kernel's columns.
pub(crate) const PAGE_SLOTS: usize = 64;
const _: () = assert!(PAGE_SLOTS.is_multiple_of(COLUMNS));

/// Keys and values of every layer of one stream.
#[derive(Debug, Clone, Default)]
pub(crate) struct KvCache {
    pages: Vec<Box<[f32]>>,
    /// Entries held (`<sos>` included), at most `capacity`: slots `0..len`.
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

/// What one reserved slot held before: its rows of every layer when it held an entry.
#[derive(Debug, Clone)]
struct Overwrite {
    slot: usize,
    rows: Option<Vec<f32>>,
}

/// The slots a step writes its new entries to, per stream, in token order.
pub(crate) type StepSlots = Vec<usize>;

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

    /// Floats of one page.
    fn page_floats(&self) -> usize {
        PAGE_SLOTS * 2 * self.layers * self.heads * self.head_dim
    }

    /// Bytes of keys and values allocated.
    pub(crate) fn bytes(&self) -> usize {
        self.pages.len() * self.page_floats() * 4
    }

    /// Where the block of `head` of `layer`'s keys (`kind` 0) or values (1) starts in a page.
    fn block(&self, layer: usize, kind: usize, head: usize) -> usize {
        ((layer * self.heads + head) * 2 + kind) * PAGE_SLOTS * self.head_dim
    }

    /// Where dimension `d` of `slot`'s key (`kind` 0, transposed) or value (1) lies in its page.
    fn at(&self, layer: usize, kind: usize, head: usize, slot: usize, d: usize) -> usize {
        let (base, s) = (self.block(layer, kind, head), slot % PAGE_SLOTS);
        base + if kind == 0 {
            d * PAGE_SLOTS + s
        } else {
            s * self.head_dim + d
        }
    }

    /// Takes the slots of `new` entries, journaling what they held, and counts them as held:
    /// the caller writes every layer's rows with [`KvCache::write`] before attending. The
    /// entries a full cache overwrites are the oldest after `<sos>`.
    pub(crate) fn reserve(&mut self, new: usize) -> Result<StepSlots> {
        if self.capacity < 2 || self.layers == 0 {
            // Only the placeholder a session leaves while a step holds its cache is this small.
            return Err(cache_error("writing to a cache that holds no slots"));
        }
        let mut slots = Vec::with_capacity(new);
        for _ in 0..new {
            let slot = if self.len < self.capacity {
                self.len
            } else {
                1 + (self.written % (self.capacity as u64 - 1)) as usize
            };
            if slot / PAGE_SLOTS >= self.pages.len() {
                self.pages
                    .push(vec![0f32; self.page_floats()].into_boxed_slice());
            }
            let rows = (slot < self.len).then(|| self.rows_of(slot));
            // Journal first: a rollback then restores this slot whatever happens after.
            self.journal.push(Overwrite { slot, rows });
            if self.len > 0 {
                self.written += 1;
            }
            self.len = (self.len + 1).min(self.capacity);
            slots.push(slot);
        }
        Ok(slots)
    }

    /// Where every float of `slot` lies in its page, every layer's key then value, head by head:
    /// the order the journal keeps a slot's rows in.
    fn slot_floats(&self, slot: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.layers).flat_map(move |layer| {
            (0..2).flat_map(move |kind| {
                (0..self.heads).flat_map(move |head| {
                    (0..self.head_dim).map(move |d| self.at(layer, kind, head, slot, d))
                })
            })
        })
    }

    /// Every layer's key and value rows of `slot`, in [`KvCache::slot_floats`] order. Read block
    /// by block, as [`KvCache::write`] writes them: a full cache journals a slot every token,
    /// and an index computation per float was a visible part of a small model's step.
    fn rows_of(&self, slot: usize) -> Vec<f32> {
        let (dh, s) = (self.head_dim, slot % PAGE_SLOTS);
        let page = &self.pages[slot / PAGE_SLOTS];
        let mut rows = Vec::with_capacity(2 * self.layers * self.heads * dh);
        for layer in 0..self.layers {
            for head in 0..self.heads {
                let keys = &page[self.block(layer, 0, head)..][..PAGE_SLOTS * dh];
                rows.extend(keys.iter().skip(s).step_by(PAGE_SLOTS));
            }
            for head in 0..self.heads {
                rows.extend_from_slice(&page[self.block(layer, 1, head) + s * dh..][..dh]);
            }
        }
        debug_assert!(rows.iter().eq(self.slot_floats(slot).map(|at| &page[at])));
        rows
    }

    /// Writes one entry's key and value of `layer` (`heads * head_dim` floats each, the heads
    /// side by side) into a reserved slot.
    pub(crate) fn write(&mut self, layer: usize, slot: usize, key: &[f32], value: &[f32]) {
        let (dh, s) = (self.head_dim, slot % PAGE_SLOTS);
        // One slice per head's block, not an index computation per float.
        for (head, (k, v)) in key.chunks_exact(dh).zip(value.chunks_exact(dh)).enumerate() {
            let (k_at, v_at) = (self.block(layer, 0, head), self.block(layer, 1, head));
            let page = &mut self.pages[slot / PAGE_SLOTS];
            // Keys are stored transposed: dimension d of every slot in a row of PAGE_SLOTS.
            let keys = &mut page[k_at..][..PAGE_SLOTS * dh];
            for (column, &x) in keys.chunks_exact_mut(PAGE_SLOTS).zip(k) {
                column[s] = x;
            }
            page[v_at + s * dh..][..dh].copy_from_slice(v);
        }
    }

    /// Attention of a step's `queries` (one row of `heads * head_dim` floats per new entry, in
    /// the order of `slots`, each already scaled) over `layer`: query `j` sees every held entry
    /// but those the step's later entries were written to (a causal step), as a full recompute
    /// of the kept entries would. Writes one row per query into `out`.
    pub(crate) fn attend(
        &self,
        layer: usize,
        slots: &[usize],
        queries: &[f32],
        out: &mut [f32],
        scores: &mut Vec<f32>,
    ) {
        let (heads, dh) = (self.heads, self.head_dim);
        let used = self.len.div_ceil(PAGE_SLOTS);
        let mut blocks = Vec::with_capacity(used);
        for (j, (query, out)) in queries
            .chunks_exact(heads * dh)
            .zip(out.chunks_exact_mut(heads * dh))
            .enumerate()
        {
            // The blocks are the pages in order, so a slot is also its row index in them.
            let hidden = &slots[(j + 1).min(slots.len())..];
            for head in 0..heads {
                blocks.clear();
                let (k, v) = (self.block(layer, 0, head), self.block(layer, 1, head));
                for (p, page) in self.pages[..used].iter().enumerate() {
                    let rows = (self.len - p * PAGE_SLOTS).min(PAGE_SLOTS);
                    blocks.push(KvBlock {
                        keys: &page[k..k + PAGE_SLOTS * dh],
                        stride: PAGE_SLOTS,
                        rows,
                        values: &page[v..v + rows * dh],
                    });
                }
                let range = head * dh..(head + 1) * dh;
                attend(
                    &query[range.clone()],
                    &blocks,
                    hidden,
                    &mut out[range],
                    scores,
                );
            }
        }
    }

    /// Keeps every entry written since the last commit.
    pub(crate) fn commit(&mut self) {
        self.journal.clear();
        self.committed = (self.len, self.written);
    }

    /// Whether the cache can be what a stream of `tokens` tokens leaves in it: empty before the
    /// first token, else `<sos>` and at most a pair for each token after the first (all of them
    /// while the ring has room, the newest once full; fewer after recentring rebuilt it around a
    /// new centre, `armflow/session/recentre.rs`). With the counts' own agreement, checked by
    /// [`KvCache::load`], this is all the token loop relies on.
    pub(crate) fn holds_tokens(&self, tokens: u64) -> bool {
        match tokens {
            0 => self.len == 0 && self.written == 0,
            _ => self.len >= 1 && self.written < tokens,
        }
    }

    /// The runs of page floats that hold the first `used` slots of a page, in a fixed order
    /// (layer, key then value, head): a value block's first `used` rows are contiguous, a key
    /// block (transposed) holds a run of `used` floats per dimension.
    fn held_runs(&self, used: usize) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let dh = self.head_dim;
        (0..self.layers).flat_map(move |layer| {
            (0..self.heads).flat_map(move |head| {
                let k = self.block(layer, 0, head);
                let v = self.block(layer, 1, head);
                (0..dh)
                    .map(move |d| k + d * PAGE_SLOTS..k + d * PAGE_SLOTS + used)
                    .chain(std::iter::once(v..v + used * dh))
            })
        })
    }

    /// Writes the counts and every held entry to a snapshot, page by page as held (a memory
    /// copy, not a gather per entry). Only a committed cache is saved: between steps, which is
    /// when a session can be snapshotted.
    pub(crate) fn save(&self, w: &mut SnapshotWriter) {
        debug_assert!(self.journal.is_empty(), "a cache mid-step is not saved");
        w.u64(self.capacity as u64)
            .u64(self.len as u64)
            .u64(self.written);
        for (p, page) in self.pages.iter().enumerate() {
            let used = self.len.saturating_sub(p * PAGE_SLOTS).min(PAGE_SLOTS);
            if used == 0 {
                break;
            }
            for run in self.held_runs(used) {
                w.f32s_raw(&page[run]);
            }
        }
    }

    /// The cache [`KvCache::save`] wrote, for `spec` and the session's `capacity`; the counts are
    /// checked before anything is allocated, each page only once the bytes for it are there.
    pub(crate) fn load(
        spec: &ContextSpec,
        capacity: usize,
        r: &mut SnapshotReader,
    ) -> Result<Self> {
        let mut c = Self::empty(spec, capacity);
        let saved = r.u64("the cache's capacity")?;
        if saved != c.capacity as u64 {
            return Err(cache_error(&format!(
                "the snapshot's cache holds {saved} entries, the session {}",
                c.capacity
            )));
        }
        let (len, written) = (r.u64("the cache's entries")?, r.u64("the cache's writes")?);
        let full = len == c.capacity as u64;
        if len > c.capacity as u64 || (!full && written != len.saturating_sub(1)) {
            return Err(cache_error(&format!(
                "the snapshot's cache counts do not agree ({len} entries, {written} written)"
            )));
        }
        let len = len as usize;
        let entry = 2 * c.layers * c.heads * c.head_dim;
        for p in 0..len.div_ceil(PAGE_SLOTS) {
            let used = (len - p * PAGE_SLOTS).min(PAGE_SLOTS);
            r.expect_bytes("the cache's entries", used * entry * 4)?;
            let mut page = vec![0f32; c.page_floats()].into_boxed_slice();
            for run in c.held_runs(used) {
                r.f32s_into("the cache's entries", &mut page[run])?;
            }
            c.pages.push(page);
        }
        (c.len, c.written) = (len, written);
        c.committed = (c.len, c.written);
        Ok(c)
    }

    /// Restores the entries and counts of the last commit (allocated pages stay allocated).
    pub(crate) fn rollback(&mut self) {
        for undo in std::mem::take(&mut self.journal).into_iter().rev() {
            let Some(rows) = undo.rows else { continue };
            let positions: Vec<usize> = self.slot_floats(undo.slot).collect();
            let page = &mut self.pages[undo.slot / PAGE_SLOTS];
            for (at, x) in positions.into_iter().zip(rows) {
                page[at] = x;
            }
        }
        (self.len, self.written) = self.committed;
    }
}

fn cache_error(message: &str) -> Error {
    Error::Inference {
        graph: "context_layers",
        message: format!("key/value cache: {message}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADS: usize = 2;
    const DH: usize = 3;
    const LAYERS: usize = 2;

    fn spec() -> ContextSpec {
        ContextSpec {
            width: HEADS * DH,
            layers: LAYERS,
            heads: HEADS,
            head_dim: DH,
            capacity_tokens: 3,
        }
    }

    fn cache(capacity: usize) -> KvCache {
        KvCache::empty(&spec(), capacity)
    }

    /// Appends one entry whose every float of layer `l` is `id + l / 10`.
    fn push(c: &mut KvCache, id: f32) -> usize {
        let slot = c.reserve(1).unwrap()[0];
        for layer in 0..LAYERS {
            let row = [id + layer as f32 / 10.0; HEADS * DH];
            c.write(layer, slot, &row, &row);
        }
        slot
    }

    /// The ids held, sorted (read from layer 0's keys of head 1).
    fn held(c: &KvCache) -> Vec<f32> {
        let mut ids: Vec<f32> = (0..c.len())
            .map(|s| c.pages[s / PAGE_SLOTS][c.at(0, 0, 1, s, 0)])
            .collect();
        ids.sort_by(f32::total_cmp);
        ids
    }

    #[test]
    fn a_full_ring_keeps_sos_and_the_newest() {
        let mut c = cache(4);
        for id in 0..10 {
            push(&mut c, id as f32);
            c.commit();
        }
        assert_eq!(held(&c), [0.0, 7.0, 8.0, 9.0]);
        assert_eq!((c.len(), c.pages.len()), (4, 1));
    }

    #[test]
    fn rollback_restores_overwritten_entries_and_counts() {
        let mut c = cache(3);
        for id in 0..5 {
            push(&mut c, id as f32);
        }
        c.commit();
        let (before, pages) = (held(&c), c.pages.clone());
        for id in 5..9 {
            push(&mut c, id as f32);
        }
        assert_eq!(held(&c), [0.0, 7.0, 8.0]);
        c.rollback();
        assert_eq!(held(&c), before);
        assert_eq!(c.pages, pages, "every layer, key and value restored");
        push(&mut c, 5.0);
        assert_eq!(held(&c), [0.0, 4.0, 5.0], "the ring goes on where it was");
    }

    #[test]
    fn growing_adds_pages_and_never_moves_what_is_held() {
        let mut c = cache(300);
        let first = push(&mut c, 0.0);
        let page = c.pages[0].as_ptr();
        for id in 1..300 {
            push(&mut c, id as f32);
        }
        assert_eq!((first, c.pages.len()), (0, 300usize.div_ceil(PAGE_SLOTS)));
        assert_eq!(
            c.pages[0].as_ptr(),
            page,
            "the first page was not reallocated"
        );
        assert_eq!(held(&c), (0..300).map(|i| i as f32).collect::<Vec<_>>());
        let pages = 300usize.div_ceil(PAGE_SLOTS);
        assert_eq!(c.bytes(), pages * PAGE_SLOTS * 2 * LAYERS * HEADS * DH * 4);
    }

    #[test]
    fn a_causal_step_hides_its_later_entries_from_earlier_queries() {
        let mut c = cache(40);
        for id in 0..20 {
            push(&mut c, id as f32);
        }
        c.commit();
        // two new entries in one step with very different values
        let slots = c.reserve(2).unwrap();
        for (slot, v) in slots.iter().zip([100.0, -100.0]) {
            for layer in 0..LAYERS {
                c.write(layer, *slot, &[0.0; HEADS * DH], &[v; HEADS * DH]);
            }
        }
        let queries = vec![0.0; 2 * HEADS * DH]; // equal scores: the mean of what is visible
        let mut out = vec![0.0; 2 * HEADS * DH];
        c.attend(0, &slots, &queries, &mut out, &mut Vec::new());
        let mean_first: f32 = ((0..20).map(|i| i as f32).sum::<f32>() + 100.0) / 21.0;
        let mean_second: f32 = ((0..20).map(|i| i as f32).sum::<f32>()) / 22.0;
        assert!(
            (out[0] - mean_first).abs() < 1e-4,
            "{} vs {mean_first}",
            out[0]
        );
        assert!((out[HEADS * DH] - mean_second).abs() < 1e-4);
    }

    #[test]
    fn a_saved_cache_loads_back_entry_for_entry() {
        use crate::shared::snapshot::{SnapshotReader, SnapshotWriter, MODEL_ID_BYTES};
        let id = [1; MODEL_ID_BYTES];
        for n in [0, 1, 2, 3, 7] {
            let mut c = cache(3);
            for i in 0..n {
                push(&mut c, i as f32);
            }
            c.commit();
            let mut w = SnapshotWriter::new("armflow", &id, 0);
            c.save(&mut w);
            let bytes = w.finish();
            let mut r = SnapshotReader::open(&bytes, "armflow", &id).unwrap();
            let spec = spec();
            let back = KvCache::load(&spec, 3, &mut r).unwrap();
            r.finish().unwrap();
            assert_eq!(held(&back), held(&c), "{n} pushes");
            assert_eq!((back.len, back.written), (c.len, c.written));
            let mut r = SnapshotReader::open(&bytes, "armflow", &id).unwrap();
            assert!(KvCache::load(&spec, 4, &mut r).is_err(), "another capacity");
        }
    }
}
