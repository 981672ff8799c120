//! Attention of one query over keys and values that lie where a cache keeps them: blocks of
//! consecutive rows (a paged cache's pages), read once each, never packed or copied.
//!
//! `out = softmax(K q) V` for a query already multiplied by its scale. The kernel makes two
//! passes over the blocks: the scores, then the weighted sum of the value rows. A block keeps its
//! keys transposed (one row per key dimension, one column per entry), so the scores of
//! [`LANES`] entries are one vector accumulated over the key dimensions, with no horizontal sum
//! per entry. Every reduction runs in fixed lanes in a fixed order, so the result is the same
//! bit for bit whichever instruction set runs it: the AVX-512 and AVX2/FMA builds of the same
//! code (chosen at run time, [`kernel`]) only run those lanes wider.

use crate::shared::isa::{self, isa, Isa};

/// Accumulator lanes of every reduction: one AVX-512 register, two AVX2 registers.
const LANES: usize = 16;

/// Entries whose scores one pass over the key dimensions computes: four independent vectors
/// of lanes, reading each key dimension's row of a block front to back. A block's key stride is
/// a multiple of it.
pub(crate) const COLUMNS: usize = 64;

/// One block of a cache: `rows` entries' keys and values.
#[derive(Debug, Clone, Copy)]
pub(crate) struct KvBlock<'a> {
    /// The keys transposed: dimension `d` of entry `r` at `keys[d * stride + r]`
    /// (`head_dim * stride` floats; columns `rows..stride` are read and ignored).
    pub keys: &'a [f32],
    /// Floats from one key dimension to the next: a multiple of [`COLUMNS`], at least `rows`.
    pub stride: usize,
    /// Entries in the block.
    pub rows: usize,
    /// Value rows, one per entry: `rows * head_dim` floats.
    pub values: &'a [f32],
}

/// The build of the kernel this CPU runs (`"avx512"`, `"avx2+fma"` or `"portable"`), for
/// benchmarks and logs.
pub fn kernel() -> &'static str {
    isa::name(isa())
}

/// `out = softmax(K q) V` over every row of `blocks` except the rows `hidden` lists (indices
/// into the blocks' rows taken in order). `query` and `out` are `head_dim` floats; `scores` is
/// scratch, grown as needed. A query with no visible row gets zeros.
pub(crate) fn attend(
    query: &[f32],
    blocks: &[KvBlock<'_>],
    hidden: &[usize],
    out: &mut [f32],
    scores: &mut Vec<f32>,
) {
    match isa() {
        Isa::Portable => attend_generic(query, blocks, hidden, out, scores),
        // SAFETY: `isa` chose these builds only where the CPU has their features.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { attend_avx2(query, blocks, hidden, out, scores) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { attend_avx512(query, blocks, hidden, out, scores) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn attend_avx2(
    query: &[f32],
    blocks: &[KvBlock<'_>],
    hidden: &[usize],
    out: &mut [f32],
    scores: &mut Vec<f32>,
) {
    attend_generic(query, blocks, hidden, out, scores)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn attend_avx512(
    query: &[f32],
    blocks: &[KvBlock<'_>],
    hidden: &[usize],
    out: &mut [f32],
    scores: &mut Vec<f32>,
) {
    attend_generic(query, blocks, hidden, out, scores)
}

/// The kernel, written so that the compiler vectorises it for whichever features the caller
/// was built with: every loop runs over [`LANES`] independent lanes.
#[inline(always)]
fn attend_generic(
    query: &[f32],
    blocks: &[KvBlock<'_>],
    hidden: &[usize],
    out: &mut [f32],
    scores: &mut Vec<f32>,
) {
    let dh = query.len();
    out.fill(0.0);
    if dh == 0 {
        return;
    }
    let rows: usize = blocks.iter().map(|b| b.rows).sum();
    scores.clear();
    scores.reserve(rows);
    for block in blocks {
        block_scores(query, block, scores);
    }
    let mut visible = rows;
    for &row in hidden {
        if let Some(s) = scores.get_mut(row) {
            if *s != f32::NEG_INFINITY {
                *s = f32::NEG_INFINITY;
                visible -= 1;
            }
        }
    }
    if visible == 0 {
        return;
    }
    let top = max(scores);
    let total = exp_shifted(scores, top);
    // The usual head widths keep the sum in registers; any other width sums in `out`. Both
    // add the same products in the same order.
    match dh {
        16 => weighted_values::<16>(blocks, scores, out),
        32 => weighted_values::<32>(blocks, scores, out),
        64 => weighted_values::<64>(blocks, scores, out),
        128 => weighted_values::<128>(blocks, scores, out),
        _ => {
            let mut row = 0;
            for block in blocks {
                for value in block.values.chunks_exact(dh).take(block.rows) {
                    let p = scores[row];
                    row += 1;
                    if p != 0.0 {
                        for (o, v) in out.iter_mut().zip(value) {
                            *o += p * v;
                        }
                    }
                }
            }
        }
    }
    let inv = 1.0 / total;
    for o in out.iter_mut() {
        *o *= inv;
    }
}

/// `out = sum over rows of p_row * value_row` for a head width known at compile time.
#[inline(always)]
fn weighted_values<const D: usize>(blocks: &[KvBlock<'_>], weights: &[f32], out: &mut [f32]) {
    let mut acc = [0f32; D];
    let mut row = 0;
    for block in blocks {
        let (values, _) = block.values.as_chunks::<D>();
        for value in values.iter().take(block.rows) {
            let p = weights[row];
            row += 1;
            if p != 0.0 {
                for d in 0..D {
                    acc[d] += p * value[d];
                }
            }
        }
    }
    out.copy_from_slice(&acc);
}

/// Sums lanes in a fixed tree.
#[inline(always)]
fn sum_lanes(mut acc: [f32; LANES]) -> f32 {
    let mut width = LANES;
    while width > 1 {
        width /= 2;
        for l in 0..width {
            acc[l] += acc[l + width];
        }
    }
    acc[0]
}

/// Appends the scores of a block's entries: [`COLUMNS`] entries at a time, each summing over
/// the key dimensions in order.
#[inline(always)]
fn block_scores(query: &[f32], block: &KvBlock<'_>, scores: &mut Vec<f32>) {
    let stride = block.stride;
    for first in (0..block.rows).step_by(COLUMNS) {
        let mut acc = [0f32; COLUMNS];
        for (d, &q) in query.iter().enumerate() {
            let at = d * stride + first;
            let Some(row) = block.keys.get(at..at + COLUMNS) else {
                break; // never: the cache builds whole blocks
            };
            for l in 0..COLUMNS {
                acc[l] += q * row[l];
            }
        }
        scores.extend_from_slice(&acc[..COLUMNS.min(block.rows - first)]);
    }
}

#[inline(always)]
fn max(values: &[f32]) -> f32 {
    let mut acc = [f32::NEG_INFINITY; LANES];
    let (full, tail) = values.as_chunks::<LANES>();
    for chunk in full {
        for l in 0..LANES {
            acc[l] = if chunk[l] > acc[l] { chunk[l] } else { acc[l] };
        }
    }
    for (l, &v) in tail.iter().enumerate() {
        acc[l] = if v > acc[l] { v } else { acc[l] };
    }
    acc.into_iter()
        .fold(f32::NEG_INFINITY, |m, v| if v > m { v } else { m })
}

/// Replaces each score `s` by `exp(s - top)` (0 for a hidden row) and returns their sum.
#[inline(always)]
fn exp_shifted(values: &mut [f32], top: f32) -> f32 {
    let mut acc = [0f32; LANES];
    let (full, tail) = values.as_chunks_mut::<LANES>();
    for chunk in full {
        for l in 0..LANES {
            let e = exp_nonpositive(chunk[l] - top);
            chunk[l] = e;
            acc[l] += e;
        }
    }
    for (l, v) in tail.iter_mut().enumerate() {
        let e = exp_nonpositive(*v - top);
        *v = e;
        acc[l] += e;
    }
    sum_lanes(acc)
}

/// `exp(x)` for `x <= 0` to about one unit in the last place, 0 below -87 (and for -inf),
/// in branch-free arithmetic the compiler vectorises: `2^n * p(r)` with `x = n ln 2 + r`,
/// `|r| <= ln 2 / 2`, and the polynomial of the Cephes library's `expf`.
#[inline(always)]
fn exp_nonpositive(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding and removing 1.5 * 2^23 rounds to the nearest integer without a rounding call.
    const ROUND: f32 = 12_582_912.0;
    let below = x < -87.0;
    let x = if below { -87.0 } else { x };
    let n = (x * LOG2E + ROUND) - ROUND;
    let r = x - n * LN2_HI - n * LN2_LO;
    let p = 1.987_569_1e-4_f32;
    let p = p * r + 1.398_199_9e-3;
    let p = p * r + 8.333_452e-3;
    let p = p * r + 4.166_579_6e-2;
    let p = p * r + 1.666_666_5e-1;
    let p = p * r + 0.5;
    let e = p * r * r + r + 1.0;
    // n is in [-126, 0], so 2^n is a normal float built from its exponent bits.
    let scale = f32::from_bits(((n as i32 + 127) as u32) << 23);
    if below {
        0.0
    } else {
        e * scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kernels chosen at run time for this machine, this module's and tract's matrix
    /// kernels: on arm64, tract's NEON ones (`arm64simd`) are among those it may run
    /// (docs/PLATFORMS.md; the test also runs under qemu-user).
    #[test]
    fn kernels_are_chosen_for_this_machine() {
        let machine = tract_linalg::isa::native();
        let kernels: Vec<String> = tract_linalg::mmm_routines::runnable_for(&machine)
            .iter()
            .map(|kernel| kernel.name().to_string())
            .collect();
        println!(
            "attention: {:?}; tract: {machine:?}, matrix kernels {kernels:?}",
            isa()
        );
        assert!(!kernels.is_empty());
        if cfg!(target_arch = "aarch64") {
            assert!(
                kernels.iter().any(|k| k.starts_with("arm64simd")),
                "{kernels:?}"
            );
        }
    }

    /// Softmax attention in f64, the plain way.
    fn reference(q: &[f32], keys: &[f32], values: &[f32], hidden: &[usize]) -> Vec<f64> {
        let dh = q.len();
        let n = keys.len() / dh;
        let scores: Vec<f64> = (0..n)
            .map(|i| {
                if hidden.contains(&i) {
                    f64::NEG_INFINITY
                } else {
                    (0..dh).map(|d| q[d] as f64 * keys[i * dh + d] as f64).sum()
                }
            })
            .collect();
        let top = scores.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let w: Vec<f64> = scores.iter().map(|s| (s - top).exp()).collect();
        let total: f64 = w.iter().sum();
        (0..dh)
            .map(|d| {
                (0..n)
                    .map(|i| w[i] * values[i * dh + d] as f64)
                    .sum::<f64>()
                    / total
            })
            .collect()
    }

    fn data(n: usize, seed: u32) -> Vec<f32> {
        let mut state = seed.wrapping_mul(2_654_435_761).max(1);
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                (state as f32 / u32::MAX as f32) * 4.0 - 2.0
            })
            .collect()
    }

    #[test]
    fn exp_is_within_two_ulps_of_std_and_zero_far_below() {
        for i in 0..=100_000 {
            let x = -87.0 * i as f32 / 100_000.0;
            let (got, want) = (exp_nonpositive(x), x.exp());
            assert!(
                (got - want).abs() <= 2.0 * f32::EPSILON * want,
                "exp({x}) = {got}, std {want}"
            );
        }
        assert_eq!(exp_nonpositive(-88.0), 0.0);
        assert_eq!(exp_nonpositive(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_nonpositive(0.0), 1.0);
    }

    /// Rows `from..to` of row-major keys as a block with transposed keys of `stride` columns.
    fn block(
        keys: &[f32],
        values: &[f32],
        dh: usize,
        from: usize,
        to: usize,
        stride: usize,
    ) -> (Vec<f32>, Vec<f32>) {
        let mut t = vec![f32::NAN; dh * stride]; // unused columns must not matter
        for r in from..to {
            for d in 0..dh {
                t[d * stride + r - from] = keys[r * dh + d];
            }
        }
        (t, values[from * dh..to * dh].to_vec())
    }

    #[test]
    fn matches_plain_softmax_attention_across_blocks_and_head_widths() {
        for dh in [1, 7, 16, 64, 80] {
            for rows in [1, 5, 16, 33, 130] {
                let (q, k, v) = (data(dh, 1), data(rows * dh, 2), data(rows * dh, 3));
                let hidden: Vec<usize> = if rows > 3 { vec![1, rows - 1] } else { vec![] };
                let want = reference(&q, &k, &v, &hidden);
                // the same rows cut into uneven blocks
                let cut = rows / 3;
                let (s1, s2) = (
                    cut.next_multiple_of(COLUMNS),
                    (rows - cut).next_multiple_of(COLUMNS) + COLUMNS,
                );
                let (k1, v1) = block(&k, &v, dh, 0, cut, s1);
                let (k2, v2) = block(&k, &v, dh, cut, rows, s2);
                let blocks = [
                    KvBlock {
                        keys: &k1,
                        stride: s1,
                        rows: cut,
                        values: &v1,
                    },
                    KvBlock {
                        keys: &k2,
                        stride: s2,
                        rows: rows - cut,
                        values: &v2,
                    },
                ];
                let mut out = vec![9.0; dh];
                attend(&q, &blocks, &hidden, &mut out, &mut Vec::new());
                for (o, w) in out.iter().zip(&want) {
                    assert!(
                        (*o as f64 - w).abs() < 1e-5,
                        "dh {dh} rows {rows}: {o} vs {w}"
                    );
                }
            }
        }
    }

    #[test]
    fn every_build_this_cpu_has_gives_the_same_bits() {
        let dh = 64;
        let (q, k, v) = (data(dh, 4), data(300 * dh, 5), data(300 * dh, 6));
        let (kt, v) = block(&k, &v, dh, 0, 300, 320);
        let blocks = [KvBlock {
            keys: &kt,
            stride: 320,
            rows: 300,
            values: &v,
        }];
        let mut portable = vec![0.0; dh];
        attend_generic(&q, &blocks, &[3], &mut portable, &mut Vec::new());
        let mut chosen = vec![0.0; dh];
        attend(&q, &blocks, &[3], &mut chosen, &mut Vec::new());
        assert_eq!(portable, chosen, "kernel {}", kernel());
    }

    #[test]
    fn the_fixed_width_sums_equal_the_general_one() {
        let (rows, dh) = (70, 64);
        let (v, p) = (data(rows * dh, 9), data(rows, 10));
        let block = [KvBlock {
            keys: &[],
            stride: COLUMNS,
            rows,
            values: &v,
        }];
        let mut fixed = vec![0.0; dh];
        weighted_values::<64>(&block, &p, &mut fixed);
        let mut general = vec![0f32; dh];
        for (r, value) in v.chunks_exact(dh).enumerate() {
            for (o, x) in general.iter_mut().zip(value) {
                *o += p[r] * x;
            }
        }
        assert_eq!(fixed, general);
    }

    #[test]
    fn a_query_that_sees_nothing_gets_zeros() {
        let (q, k) = (data(4, 7), data(8, 8));
        let (kt, v) = block(&k, &k, 4, 0, 2, COLUMNS);
        let blocks = [KvBlock {
            keys: &kt,
            stride: COLUMNS,
            rows: 2,
            values: &v,
        }];
        let mut out = vec![1.0; 4];
        attend(&q, &blocks, &[0, 1], &mut out, &mut Vec::new());
        assert_eq!(out, vec![0.0; 4]);
        attend(&q, &[], &[], &mut out, &mut Vec::new());
        assert_eq!(out, vec![0.0; 4]);
    }
}
