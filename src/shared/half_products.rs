//! Matrix products with float16 weights, run by troupe's own kernels.
//!
//! A streaming step at batch 1 multiplies one row by every weight of the network once: it is
//! bound by the time to read the weights, so weights in 16 bits should halve it. tract's mixed
//! float16 × float32 kernels convert in their inner loop and ran the paper bundle's step at
//! 2.09× the time to read its float16 bytes (`docs/PERFORMANCE.md`, round four). Here each
//! float16 graph's products with a float16 weight are replaced at load by [`HalfProduct`], an
//! op of troupe's that reads the weight once per call, as one stream:
//!
//! - **Layout.** The weight `W` (`k × n`, `out = x · W`) is stored in panels of [`PANEL`]
//!   columns: row `kk` of a panel is one 64-byte line (32 values, zero past `n`), and a panel's
//!   `k` lines follow each other, then the next panel's. A row of `x` reads the whole weight
//!   front to back, which the hardware prefetcher streams at the memory's speed.
//! - **Kernels.** Each line is converted to float32 in registers (`vcvtph2ps`) and multiplied
//!   into accumulators for a block of rows (up to 8 with AVX-512, 2 with AVX2); a single row
//!   keeps two sets of accumulators (even and odd `kk`) so that the additions are not one chain.
//!   The AVX-512 and AVX2/FMA builds are chosen at run time (`shared/isa.rs`), with a portable
//!   one for other CPUs; their sums run in different orders, so they agree to rounding, not to
//!   the bit.
//! - **Larger batches** take the rows in blocks panel by panel, so a panel (`k` × 64 bytes, 128
//!   KiB at `k` = 2048) is read from memory once and from the cache for its other blocks; when
//!   troupe's compute pool has several threads (`set_compute_threads`), a large product's panels
//!   are split over them.

use std::sync::Arc;

use half::slice::HalfFloatSliceExt;
use half::{f16, slice::HalfBitsSliceExt};
use tract_linalg::multithread::{current_tract_executor, Executor};
use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::einsum::EinSum;
use tract_onnx::tract_core::ops::konst::Const;

use crate::shared::isa::{self, isa, Isa};

/// Columns of a panel: one 64-byte line of float16 values per row of the weight.
const PANEL: usize = 32;

/// Multiply-adds from which a product is split over the compute pool's threads (below it the
/// hand-off costs more than it saves).
const SPLIT_FROM: usize = 1 << 20;

/// One row of a panel: [`PANEL`] float16 values (as bits), aligned so that it is one cache line.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Line([u16; PANEL]);

/// A `k × n` float16 weight in panels of [`PANEL`] columns (module docs).
pub(crate) struct HalfMatrix {
    k: usize,
    n: usize,
    lines: Vec<Line>,
}

impl std::fmt::Debug for HalfMatrix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "HalfMatrix({} x {})", self.k, self.n)
    }
}

impl HalfMatrix {
    /// Packs the `k × n` weight whose value at row `kk`, column `nn` is `at(kk, nn)`.
    fn pack(k: usize, n: usize, at: impl Fn(usize, usize) -> f16) -> Self {
        let panels = n.div_ceil(PANEL);
        let mut lines = vec![Line([0; PANEL]); panels * k];
        for panel in 0..panels {
            let first = panel * PANEL;
            for (kk, line) in lines[panel * k..(panel + 1) * k].iter_mut().enumerate() {
                for (j, bits) in line.0.iter_mut().enumerate().take(n - first) {
                    *bits = at(kk, first + j).to_bits();
                }
            }
        }
        Self { k, n, lines }
    }

    /// `out = x · W` for `rows` rows: `x` is `rows × k`, `out` `rows × n`, both row-major.
    pub(crate) fn product(&self, x: &[f32], rows: usize, out: &mut [f32]) {
        assert!(x.len() == rows * self.k && out.len() == rows * self.n);
        let panels = self.n.div_ceil(PANEL);
        let target = OutColumns(out.as_mut_ptr());
        let run = |first: usize, last: usize| {
            for panel in first..last {
                // SAFETY: each panel writes only its own columns of `out`, which outlives the
                // call, and no two calls share a panel.
                unsafe { self.panel_product(panel, x, rows, &target) };
            }
        };
        let work = rows * self.k * self.n;
        match current_tract_executor() {
            Executor::MultiThread(pool) if work >= SPLIT_FROM && panels > 1 => {
                let parts = (pool.current_num_threads() * 2).min(panels);
                pool.scope(|scope| {
                    for part in 0..parts {
                        let run = &run;
                        scope.spawn(move |_| {
                            run(part * panels / parts, (part + 1) * panels / parts)
                        });
                    }
                });
            }
            _ => run(0, panels),
        }
    }

    /// Columns `PANEL * panel ..` of every row of `out`.
    ///
    /// # Safety
    /// `out` points at `rows × n` floats no other thread writes in these columns.
    unsafe fn panel_product(&self, panel: usize, x: &[f32], rows: usize, out: &OutColumns) {
        let first = panel * PANEL;
        let call = PanelCall {
            lines: &self.lines[panel * self.k..(panel + 1) * self.k],
            x,
            k: self.k,
            rows,
            out: unsafe { out.0.add(first) },
            out_stride: self.n,
            cols: PANEL.min(self.n - first),
        };
        match isa() {
            Isa::Portable => call.portable(),
            // SAFETY: `isa` chose these builds only where the CPU has their features.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma => unsafe { x86::panel_avx2(&call) },
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { x86::panel_avx512(&call) },
        }
    }
}

/// The output of a product, shared by the threads that write its panels' columns.
struct OutColumns(*mut f32);
// SAFETY: threads write disjoint columns (`HalfMatrix::product`).
unsafe impl Sync for OutColumns {}

/// One panel of a product: what every build's kernel reads and writes.
struct PanelCall<'a> {
    lines: &'a [Line],
    x: &'a [f32],
    k: usize,
    rows: usize,
    /// Column 0 of this panel in row 0 of the output.
    out: *mut f32,
    out_stride: usize,
    /// Columns of the panel that exist (`PANEL`, or fewer in the last panel).
    cols: usize,
}

impl PanelCall<'_> {
    /// Writes `sums` (one row's panel of sums) to row `row` of the output.
    ///
    /// # Safety
    /// As [`HalfMatrix::panel_product`].
    #[inline(always)]
    unsafe fn store(&self, row: usize, sums: &[f32; PANEL]) {
        let out = unsafe { self.out.add(row * self.out_stride) };
        // SAFETY: `cols` columns from this panel's first lie inside row `row` of the output.
        unsafe { std::ptr::copy_nonoverlapping(sums.as_ptr(), out, self.cols) };
    }

    /// The build for any CPU: each line converted once, then added into every row's sums.
    fn portable(&self) {
        const BLOCK: usize = 8;
        let mut weights = [0f32; PANEL];
        for first in (0..self.rows).step_by(BLOCK) {
            let block = BLOCK.min(self.rows - first);
            let mut sums = [[0f32; PANEL]; BLOCK];
            for (kk, line) in self.lines.iter().enumerate() {
                line.0
                    .reinterpret_cast::<f16>()
                    .convert_to_f32_slice(&mut weights);
                for (r, row_sums) in sums.iter_mut().enumerate().take(block) {
                    let xv = self.x[(first + r) * self.k + kk];
                    for (s, w) in row_sums.iter_mut().zip(&weights) {
                        *s += xv * w;
                    }
                }
            }
            for (r, row_sums) in sums.iter().enumerate().take(block) {
                // SAFETY: as the caller's.
                unsafe { self.store(first + r, row_sums) };
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{PanelCall, PANEL};

    /// The AVX-512 build: blocks of up to 8 rows, 2 registers of 16 sums per row.
    ///
    /// # Safety
    /// The CPU has AVX-512F; the call's output is as [`super::HalfMatrix::panel_product`] says.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn panel_avx512(call: &PanelCall<'_>) {
        let mut first = 0;
        while first < call.rows {
            let block = (call.rows - first).min(8);
            unsafe {
                match block {
                    1 => one_row_avx512(call, first),
                    2 => rows_avx512::<2>(call, first),
                    3 => rows_avx512::<3>(call, first),
                    4 => rows_avx512::<4>(call, first),
                    5 => rows_avx512::<5>(call, first),
                    6 => rows_avx512::<6>(call, first),
                    7 => rows_avx512::<7>(call, first),
                    _ => rows_avx512::<8>(call, first),
                }
            }
            first += block;
        }
    }

    /// One line's 32 weights as two registers of 16 floats.
    #[inline(always)]
    unsafe fn line_avx512(line: &super::Line) -> [__m512; 2] {
        let p = line.0.as_ptr() as *const __m256i;
        // SAFETY: a line is 64 bytes, aligned to 64.
        unsafe {
            [
                _mm512_cvtph_ps(_mm256_load_si256(p)),
                _mm512_cvtph_ps(_mm256_load_si256(p.add(1))),
            ]
        }
    }

    #[inline(always)]
    unsafe fn store_avx512(call: &PanelCall<'_>, row: usize, sums: [__m512; 2]) {
        let mut out = [0f32; PANEL];
        unsafe {
            _mm512_storeu_ps(out.as_mut_ptr(), sums[0]);
            _mm512_storeu_ps(out.as_mut_ptr().add(16), sums[1]);
            call.store(row, &out);
        }
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn rows_avx512<const R: usize>(call: &PanelCall<'_>, first: usize) {
        let mut acc = [[_mm512_setzero_ps(); 2]; R];
        let x = &call.x[first * call.k..(first + R) * call.k];
        for (kk, line) in call.lines.iter().enumerate() {
            let w = unsafe { line_avx512(line) };
            for (r, sums) in acc.iter_mut().enumerate() {
                let xv = _mm512_set1_ps(x[r * call.k + kk]);
                sums[0] = _mm512_fmadd_ps(xv, w[0], sums[0]);
                sums[1] = _mm512_fmadd_ps(xv, w[1], sums[1]);
            }
        }
        for (r, sums) in acc.into_iter().enumerate() {
            unsafe { store_avx512(call, first + r, sums) };
        }
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn one_row_avx512(call: &PanelCall<'_>, row: usize) {
        let x = &call.x[row * call.k..(row + 1) * call.k];
        let (mut even, mut odd) = ([_mm512_setzero_ps(); 2], [_mm512_setzero_ps(); 2]);
        let (pairs, last) = call.lines.as_chunks::<2>();
        for (pair, xs) in pairs.iter().zip(x.as_chunks::<2>().0) {
            let (a, b) = unsafe { (line_avx512(&pair[0]), line_avx512(&pair[1])) };
            let (xa, xb) = (_mm512_set1_ps(xs[0]), _mm512_set1_ps(xs[1]));
            even[0] = _mm512_fmadd_ps(xa, a[0], even[0]);
            even[1] = _mm512_fmadd_ps(xa, a[1], even[1]);
            odd[0] = _mm512_fmadd_ps(xb, b[0], odd[0]);
            odd[1] = _mm512_fmadd_ps(xb, b[1], odd[1]);
        }
        if let Some(line) = last.first() {
            let w = unsafe { line_avx512(line) };
            let xv = _mm512_set1_ps(x[call.k - 1]);
            even[0] = _mm512_fmadd_ps(xv, w[0], even[0]);
            even[1] = _mm512_fmadd_ps(xv, w[1], even[1]);
        }
        let sums = [
            _mm512_add_ps(even[0], odd[0]),
            _mm512_add_ps(even[1], odd[1]),
        ];
        unsafe { store_avx512(call, row, sums) };
    }

    /// The AVX2/FMA/F16C build: blocks of up to 2 rows, 4 registers of 8 sums per row.
    ///
    /// # Safety
    /// The CPU has AVX2, FMA and F16C; the call's output is as
    /// [`super::HalfMatrix::panel_product`] says.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn panel_avx2(call: &PanelCall<'_>) {
        let mut first = 0;
        while first < call.rows {
            let block = (call.rows - first).min(2);
            unsafe {
                match block {
                    1 => one_row_avx2(call, first),
                    _ => rows_avx2::<2>(call, first),
                }
            }
            first += block;
        }
    }

    #[inline(always)]
    unsafe fn line_avx2(line: &super::Line) -> [__m256; 4] {
        let p = line.0.as_ptr() as *const __m128i;
        // SAFETY: a line is 64 bytes, aligned to 64.
        unsafe {
            [
                _mm256_cvtph_ps(_mm_load_si128(p)),
                _mm256_cvtph_ps(_mm_load_si128(p.add(1))),
                _mm256_cvtph_ps(_mm_load_si128(p.add(2))),
                _mm256_cvtph_ps(_mm_load_si128(p.add(3))),
            ]
        }
    }

    #[inline(always)]
    unsafe fn store_avx2(call: &PanelCall<'_>, row: usize, sums: [__m256; 4]) {
        let mut out = [0f32; PANEL];
        unsafe {
            for (i, s) in sums.into_iter().enumerate() {
                _mm256_storeu_ps(out.as_mut_ptr().add(8 * i), s);
            }
            call.store(row, &out);
        }
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn rows_avx2<const R: usize>(call: &PanelCall<'_>, first: usize) {
        let mut acc = [[_mm256_setzero_ps(); 4]; R];
        let x = &call.x[first * call.k..(first + R) * call.k];
        for (kk, line) in call.lines.iter().enumerate() {
            let w = unsafe { line_avx2(line) };
            for (r, sums) in acc.iter_mut().enumerate() {
                let xv = _mm256_set1_ps(x[r * call.k + kk]);
                for (s, wv) in sums.iter_mut().zip(w) {
                    *s = _mm256_fmadd_ps(xv, wv, *s);
                }
            }
        }
        for (r, sums) in acc.into_iter().enumerate() {
            unsafe { store_avx2(call, first + r, sums) };
        }
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn one_row_avx2(call: &PanelCall<'_>, row: usize) {
        let x = &call.x[row * call.k..(row + 1) * call.k];
        let (mut even, mut odd) = ([_mm256_setzero_ps(); 4], [_mm256_setzero_ps(); 4]);
        let (pairs, last) = call.lines.as_chunks::<2>();
        for (pair, xs) in pairs.iter().zip(x.as_chunks::<2>().0) {
            let (a, b) = unsafe { (line_avx2(&pair[0]), line_avx2(&pair[1])) };
            let (xa, xb) = (_mm256_set1_ps(xs[0]), _mm256_set1_ps(xs[1]));
            for i in 0..4 {
                even[i] = _mm256_fmadd_ps(xa, a[i], even[i]);
                odd[i] = _mm256_fmadd_ps(xb, b[i], odd[i]);
            }
        }
        if let Some(line) = last.first() {
            let w = unsafe { line_avx2(line) };
            let xv = _mm256_set1_ps(x[call.k - 1]);
            for i in 0..4 {
                even[i] = _mm256_fmadd_ps(xv, w[i], even[i]);
            }
        }
        let mut sums = even;
        for (s, o) in sums.iter_mut().zip(odd) {
            *s = _mm256_add_ps(*s, o);
        }
        unsafe { store_avx2(call, row, sums) };
    }
}

/// A product of rows (any leading axes, the last `k` long) with a float16 weight, by troupe's
/// kernels: what [`use_half_products`] puts in place of tract's.
#[derive(Debug, Clone)]
pub(crate) struct HalfProduct {
    weight: Arc<HalfMatrix>,
}

impl PartialEq for HalfProduct {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.weight, &other.weight)
    }
}

impl Eq for HalfProduct {}

impl Op for HalfProduct {
    fn name(&self) -> StaticName {
        "TroupeHalfProduct".into()
    }

    fn info(&self) -> TractResult<Vec<String>> {
        Ok(vec![format!(
            "{} x {} float16 weight, troupe's {} kernel",
            self.weight.k,
            self.weight.n,
            isa::name(isa())
        )])
    }

    op_as_typed_op!();
}

impl EvalOp for HalfProduct {
    op_out_of_plan!();

    fn eval(&self, _: &EvalContext, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        let x = &inputs[0];
        let (k, n) = (self.weight.k, self.weight.n);
        ensure!(
            x.shape().last() == Some(&k),
            "rows of {k} values expected, got shape {:?}",
            x.shape()
        );
        let rows = x.len() / k.max(1);
        let mut shape: TVec<usize> = x.shape().into();
        *shape.last_mut().expect("rank at least 1") = n;
        let mut out = vec![0f32; rows * n];
        let plain = x.try_as_plain_ram()?;
        // Axes of length 1 may carry any stride (`shared/unit_axes.rs`); only the others
        // decide whether the values lie row-major.
        let natural = Tensor::natural_strides(x.shape());
        let row_major = x
            .shape()
            .iter()
            .zip(x.strides().iter().zip(natural.iter()))
            .all(|(&len, (a, b))| len == 1 || a == b);
        if row_major {
            self.weight
                .product(plain.as_slice::<f32>()?, rows, &mut out);
        } else {
            let copy: Vec<f32> = x.to_plain_array_view::<f32>()?.iter().copied().collect();
            self.weight.product(&copy, rows, &mut out);
        }
        Ok(tvec!(
            tract_ndarray::ArrayD::from_shape_vec(&*shape, out)?.into_tvalue()
        ))
    }
}

impl TypedOp for HalfProduct {
    fn output_facts(&self, inputs: &[&TypedFact]) -> TractResult<TVec<TypedFact>> {
        let x = inputs[0];
        ensure!(x.datum_type == f32::datum_type() && x.rank() >= 1);
        let mut shape: TVec<TDim> = x.shape.iter().cloned().collect();
        *shape.last_mut().expect("rank at least 1") = self.weight.n.into();
        Ok(tvec!(f32::fact(shape)))
    }

    as_op!();
}

/// Replaces every product of float32 rows with a float16 constant weight (`x · W` or `x · Wᵀ`,
/// as ONNX `MatMul` and `Gemm` make them: the rows' last axis summed, their other axes kept in
/// front; at least 16 output columns) by a [`HalfProduct`]; returns how many. Other products
/// are left to tract.
pub(crate) fn use_half_products(model: &mut TypedModel) -> TractResult<usize> {
    let mut replaced = 0;
    for id in 0..model.nodes.len() {
        let node = &model.nodes[id];
        let Some(einsum) = node.op_as::<EinSum>() else {
            continue;
        };
        if node.inputs.len() != 2 {
            continue;
        }
        let Some(weight) = model.nodes[node.inputs[1].node].op_as::<Const>() else {
            continue;
        };
        let weight = weight.val().clone();
        if weight.datum_type() != f16::datum_type()
            || weight.rank() != 2
            || model.outlet_fact(node.inputs[0])?.datum_type != f32::datum_type()
        {
            continue;
        }
        let Some(transposed) = rows_times_weight(&einsum.axes.to_string()) else {
            continue;
        };
        let (rows, cols) = (weight.shape()[0], weight.shape()[1]);
        let (k, n) = if transposed {
            (cols, rows)
        } else {
            (rows, cols)
        };
        // Panels pad `n` to a multiple of 32 columns: a weight of fewer than 16 columns would
        // take more than twice its bytes (and an empty one nothing), so tract keeps those.
        if k == 0 || n < PANEL / 2 {
            continue;
        }
        // The weight's values row-major (a constant's always are; copied in order if not):
        // indexing a dynamic-rank view per element made packing a visible part of the load.
        let view = weight.to_plain_array_view::<f16>()?;
        let copy: Vec<f16>;
        let values = match view.as_slice() {
            Some(values) => values,
            None => {
                copy = view.iter().copied().collect();
                &copy
            }
        };
        let matrix = if transposed {
            HalfMatrix::pack(k, n, |kk, nn| values[nn * k + kk])
        } else {
            HalfMatrix::pack(k, n, |kk, nn| values[kk * n + nn])
        };
        let op = HalfProduct {
            weight: Arc::new(matrix),
        };
        let patch = TypedModelPatch::replace_single_op(model, node, &[node.inputs[0]], op)?;
        patch.apply(model)?;
        replaced += 1;
    }
    // The float16 constants the products held are no longer used: drop them now, not when the
    // model is optimised (a deferred graph would hold both until its first call).
    if replaced > 0 {
        model.compact()?;
    }
    Ok(replaced)
}

/// For an einsum expression `rows,weight->out` (`"amk,kn->amn"`, `"mk,nk->mn"`): whether it is
/// rows times a 2-axis weight as [`HalfProduct`] computes it, and if so whether the weight is
/// stored transposed (`n × k`).
fn rows_times_weight(expression: &str) -> Option<bool> {
    let (inputs, out) = expression.split_once("->")?;
    let (rows, weight) = inputs.split_once(',')?;
    let (rows, weight, out): (Vec<char>, Vec<char>, Vec<char>) = (
        rows.chars().collect(),
        weight.chars().collect(),
        out.chars().collect(),
    );
    let (&k, leading) = rows.split_last()?;
    let (&n, out_leading) = out.split_last()?;
    let transposed = match weight[..] {
        [a, b] if a == k && b == n => false,
        [a, b] if a == n && b == k => true,
        _ => return None,
    };
    let distinct = k != n && !leading.contains(&k) && !leading.contains(&n);
    (distinct && leading == out_leading).then_some(transposed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(n: usize, seed: u32) -> Vec<f32> {
        let mut state = seed.wrapping_mul(2654435761).wrapping_add(12345);
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(1664525).wrapping_add(1013904223);
                (state >> 8) as f32 / (1u32 << 24) as f32 - 0.5
            })
            .collect()
    }

    /// `x · W` in f64 from the float16 weight's exact values.
    fn reference(x: &[f32], w: &[f16], rows: usize, k: usize, n: usize) -> Vec<f64> {
        let mut out = vec![0f64; rows * n];
        for r in 0..rows {
            for kk in 0..k {
                for nn in 0..n {
                    out[r * n + nn] += x[r * k + kk] as f64 * w[kk * n + nn].to_f64();
                }
            }
        }
        out
    }

    fn check(rows: usize, k: usize, n: usize, chosen: Isa) {
        let x = data(rows * k, 1);
        let w: Vec<f16> = data(k * n, 2).into_iter().map(f16::from_f32).collect();
        let matrix = HalfMatrix::pack(k, n, |kk, nn| w[kk * n + nn]);
        let mut out = vec![f32::NAN; rows * n];
        let target = OutColumns(out.as_mut_ptr());
        for panel in 0..n.div_ceil(PANEL) {
            let first = panel * PANEL;
            let call = PanelCall {
                lines: &matrix.lines[panel * k..(panel + 1) * k],
                x: &x,
                k,
                rows,
                out: unsafe { target.0.add(first) },
                out_stride: n,
                cols: PANEL.min(n - first),
            };
            match chosen {
                Isa::Portable => call.portable(),
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2Fma => unsafe { x86::panel_avx2(&call) },
                #[cfg(target_arch = "x86_64")]
                Isa::Avx512 => unsafe { x86::panel_avx512(&call) },
            }
        }
        let want = reference(&x, &w, rows, k, n);
        for (i, (&got, &want)) in out.iter().zip(&want).enumerate() {
            // Sums of k products of values below 0.5 in float32: a few ulps of their size.
            let bound = 1e-6 * (k as f64).sqrt() * 4.0;
            assert!(
                (got as f64 - want).abs() <= bound,
                "{chosen:?}, {rows} x {k} x {n}, entry {i}: {got} against {want}"
            );
        }
    }

    /// The builds this CPU can run.
    fn builds() -> Vec<Isa> {
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut builds = vec![Isa::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx2")
                && is_x86_feature_detected!("fma")
                && is_x86_feature_detected!("f16c")
            {
                builds.push(Isa::Avx2Fma);
            }
            if is_x86_feature_detected!("avx512f") {
                builds.push(Isa::Avx512);
            }
        }
        builds
    }

    #[test]
    fn every_build_matches_the_exact_product_for_every_row_block_and_ragged_sizes() {
        for chosen in builds() {
            for rows in [1, 2, 3, 5, 8, 9, 17] {
                for (k, n) in [(1, 1), (7, 33), (64, 32), (65, 100), (256, 70)] {
                    check(rows, k, n, chosen);
                }
            }
        }
    }

    #[test]
    fn a_product_split_over_the_compute_pool_equals_one_on_the_calling_thread() {
        let (rows, k, n) = (4, 512, 1000);
        let x = data(rows * k, 3);
        let w: Vec<f16> = data(k * n, 4).into_iter().map(f16::from_f32).collect();
        let matrix = HalfMatrix::pack(k, n, |kk, nn| w[kk * n + nn]);
        let mut alone = vec![0f32; rows * n];
        matrix.product(&x, rows, &mut alone);
        let pool = Executor::multithread_with_name(2, "half-products-test");
        let mut split = vec![0f32; rows * n];
        tract_linalg::multithread::multithread_tract_scope(pool, || {
            matrix.product(&x, rows, &mut split)
        });
        assert_eq!(alone, split);
    }

    #[test]
    fn only_rows_times_a_two_axis_weight_is_taken() {
        assert_eq!(rows_times_weight("amk,kn->amn"), Some(false));
        assert_eq!(rows_times_weight("mk,nk->mn"), Some(true));
        assert_eq!(rows_times_weight("k,kn->n"), Some(false));
        for other in [
            "mk,kn->nm",    // the output transposed
            "km,kn->mn",    // the rows' first axis summed
            "amk,kn->mn",   // an axis of the rows summed away
            "mk,kkn->mn",   // a weight of three axes
            "bmk,bkn->bmn", // a batched weight
            "mk,kn->mkn",   // nothing summed
        ] {
            assert_eq!(rows_times_weight(other), None, "{other}");
        }
    }

    /// Every float16 product of the demo's graphs is taken, and a graph runs the same with
    /// troupe's products as with tract's float16 kernels (same weights, sums in another order).
    #[test]
    fn a_float16_graph_runs_the_same_with_troupes_products_as_with_tracts() {
        use crate::shared::graph::keep_float16_weights;
        let bundle =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("onnx/bundles/armflow-demo-f16");
        for file in [
            "velocity.onnx",
            "vae_decoder_step.onnx",
            "context_layer_1.onnx",
        ] {
            let mut tracts = tract_onnx::onnx()
                .model_for_path(bundle.join(file))
                .unwrap()
                .into_typed()
                .unwrap();
            keep_float16_weights(&mut tracts).unwrap();
            let half_weights = tracts
                .nodes
                .iter()
                .filter(|node| {
                    node.op_is::<EinSum>()
                        && node.inputs.iter().any(|i| {
                            tracts.nodes[i.node]
                                .op_as::<Const>()
                                .is_some_and(|c| c.val().datum_type() == f16::datum_type())
                        })
                })
                .count();
            let mut ours = tracts.clone();
            let replaced = use_half_products(&mut ours).unwrap();
            assert!(
                replaced > 0 && replaced == half_weights,
                "{file}: {replaced} of {half_weights}"
            );
            let tracts = tracts.into_optimized().unwrap().into_runnable().unwrap();
            let ours = ours.into_optimized().unwrap().into_runnable().unwrap();
            for rows in [1, 3] {
                let inputs: TVec<TValue> = (0..tracts.model().inputs.len())
                    .map(|i| {
                        let fact = tracts.model().input_fact(i).unwrap();
                        let shape: Vec<usize> = fact
                            .shape
                            .iter()
                            .map(|d| d.to_usize().unwrap_or(rows))
                            .collect();
                        let len = shape.iter().product();
                        tract_ndarray::ArrayD::from_shape_vec(shape, data(len, i as u32))
                            .unwrap()
                            .into_tvalue()
                    })
                    .collect();
                let (want, got) = (
                    tracts.run(inputs.clone()).unwrap(),
                    ours.run(inputs).unwrap(),
                );
                for (w, g) in want.iter().zip(&got) {
                    let (w, g) = (
                        w.try_as_plain_ram()
                            .unwrap()
                            .as_slice::<f32>()
                            .unwrap()
                            .to_vec(),
                        g.try_as_plain_ram()
                            .unwrap()
                            .as_slice::<f32>()
                            .unwrap()
                            .to_vec(),
                    );
                    let scale = w.iter().fold(0f32, |m, v| m.max(v.abs()));
                    let diff = w
                        .iter()
                        .zip(&g)
                        .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
                    println!("{file}, {rows} rows: {diff:.2e} of {scale:.2}");
                    assert!(
                        scale > 0.0 && diff <= 1e-5 * scale,
                        "{file}: {diff} of {scale}"
                    );
                }
            }
        }
    }
}
