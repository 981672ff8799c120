//! The instruction sets troupe's own kernels (the attention, products with float16 weights) are
//! built for, and the one this process runs: chosen once, at first use, from what the CPU has
//! and what tract's view of it allows.

use std::sync::OnceLock;

/// The builds of troupe's kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Isa {
    /// Plain Rust, for any CPU.
    Portable,
    /// AVX2 with FMA and F16C (every AVX2 CPU has the latter two).
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
    /// AVX-512 foundation.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

/// The build this machine runs: the best the CPU has among those tract's instruction-set view
/// allows. tract reads `TRACT_CPU_ISA` (`-avx512f` to run the AVX2 kernels on an AVX-512
/// machine, `-avx2` for the portable ones), so one setting chooses troupe's kernels and tract's
/// together, and a benchmark on one machine shows how the others' kernels do.
pub(crate) fn isa() -> Isa {
    static ISA: OnceLock<Isa> = OnceLock::new();
    *ISA.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            use tract_linalg::isa::Isa as Tract;
            let allowed = tract_linalg::isa::native();
            if allowed.has(Tract::X86_64Avx512f) && std::arch::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if allowed.has(Tract::X86_64Avx2)
                && allowed.has(Tract::X86_64Fma)
                && allowed.has(Tract::X86_64F16c)
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::arch::is_x86_feature_detected!("f16c")
            {
                return Isa::Avx2Fma;
            }
        }
        Isa::Portable
    })
}

/// The name of a build, as benchmarks and logs print it.
pub(crate) fn name(isa: Isa) -> &'static str {
    match isa {
        Isa::Portable => "portable",
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => "avx2+fma",
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => "avx512",
    }
}

/// The kernels this process runs, for benchmarks and logs: the build of troupe's kernels (the
/// attention and the products with float16 weights share it) and the instruction sets tract's
/// matrix kernels may use (after `TRACT_CPU_ISA`), e.g.
/// `attention avx2+fma; float16 products avx2+fma; tract x86_64,avx,avx2,fma,f16c`.
pub fn kernels() -> String {
    let tract: Vec<&str> = tract_linalg::isa::native()
        .iter()
        .map(|i| i.name())
        .collect();
    let ours = name(isa());
    format!(
        "attention {ours}; float16 products {ours}; tract {}",
        tract.join(",")
    )
}
