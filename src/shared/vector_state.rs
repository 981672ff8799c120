//! Clearing the upper halves of the vector registers after tract's matrix kernels.
//!
//! tract 0.23's x86-64 matrix kernels are hand-written assembly that use the 256- and 512-bit
//! registers and return without `vzeroupper`, so the upper halves stay "dirty". Code compiled for
//! the x86-64 baseline (all of tract's other ops, troupe's Rust, parts of the C library) uses the
//! 128-bit SSE encodings, and on Intel cores an SSE instruction that runs while the upper halves
//! are dirty pays for merging them. Measured on an Emerald Rapids Xeon (`docs/PERFORMANCE.md`,
//! round four part six): `f32::sin` over 4,096 values took 1.09 ms after a tract product and
//! 16 µs after `vzeroupper`. Clearing after each operation made that machine's demo step about
//! a tenth faster; it does not explain most of why its operations cost three to four times
//! what they cost on an AMD EPYC. No AMD CPU was measured with and without the clear.
//!
//! [`clear_upper_halves`] runs `vzeroupper` (which costs about a cycle) where the CPU has AVX.
//! Every graph run calls it after each of its operations (`shared/graph.rs`).

/// Marks the upper halves of the vector registers clean, so the SSE code that follows runs at
/// full speed; nothing on a CPU without AVX, or off x86-64.
#[inline]
pub(crate) fn clear_upper_halves() {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX, checked just above, and `vzeroupper` changes no state
            // that compiled code relies on across this call: the ABI leaves the upper halves
            // undefined at every call boundary.
            unsafe { zero_upper() }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn zero_upper() {
    std::arch::x86_64::_mm256_zeroupper();
}
