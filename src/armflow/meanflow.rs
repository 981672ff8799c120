//! MeanFlow's time grid, shared by the streaming sessions and the official clip loop.

/// MeanFlow's time grid for `steps` steps: the official `torch.linspace(1, 0, steps + 1)` in
/// f32, computed as ATen's linspace computes it (the CUDA kernel the official code samples
/// with, and the CPU kernel's scalar path): `step = (0 - 1) / steps`, then `1 + step * k` for
/// the first half of the points and `0 - step * (steps - k)` for the rest, each operation
/// rounded to f32 (no fused multiply-add). This is one ulp away from `(steps - k) / steps` for
/// 3, 6, 7, ... steps. t = 1 is noise and t = 0 is data (`docs/spec/armflow.md` §6).
///
/// PyTorch's CPU kernel vectorises runs of 8 or 16 points and then rounds those differently
/// (9 steps with AVX2); the official models run on CUDA, whose kernel is the formula above.
pub fn meanflow_grid(steps: u32) -> Vec<f32> {
    let points = i64::from(steps) + 1;
    let (start, end) = (1f32, 0f32);
    let step = (end - start) / steps as f32;
    let halfway = points / 2;
    (0..points)
        .map(|k| {
            if k < halfway {
                start + step * k as f32
            } else {
                end - step * (points - k - 1) as f32
            }
        })
        .collect()
}

/// Whether a CFG scale guides the velocity: as in the official sampler, only a scale above 1
/// runs the null branch (`u = u_null + s (u_cond - u_null)`); 1 and below use `u_cond` alone.
pub(crate) fn guided(scale: f32) -> bool {
    scale > 1.0
}

#[cfg(test)]
mod tests {
    use super::meanflow_grid;

    /// `torch.linspace(1, 0, n + 1)` for n = 1..=8, written down from torch 2.15 on the CPU (its
    /// scalar path at these sizes, which is the CUDA kernel's formula) as f32 bit patterns.
    const TORCH_LINSPACE: [&[u32]; 8] = [
        &[0x3f800000, 0x0],
        &[0x3f800000, 0x3f000000, 0x0],
        &[0x3f800000, 0x3f2aaaaa, 0x3eaaaaab, 0x0],
        &[0x3f800000, 0x3f400000, 0x3f000000, 0x3e800000, 0x0],
        &[
            0x3f800000, 0x3f4ccccd, 0x3f19999a, 0x3ecccccd, 0x3e4ccccd, 0x0,
        ],
        &[
            0x3f800000, 0x3f555555, 0x3f2aaaaa, 0x3f000000, 0x3eaaaaab, 0x3e2aaaab, 0x0,
        ],
        &[
            0x3f800000, 0x3f5b6db7, 0x3f36db6e, 0x3f124924, 0x3edb6db8, 0x3e924925, 0x3e124925, 0x0,
        ],
        &[
            0x3f800000, 0x3f600000, 0x3f400000, 0x3f200000, 0x3f000000, 0x3ec00000, 0x3e800000,
            0x3e000000, 0x0,
        ],
    ];

    #[test]
    fn the_grid_is_torch_linspace_bit_for_bit() {
        for (i, want) in TORCH_LINSPACE.iter().enumerate() {
            let got: Vec<u32> = meanflow_grid(i as u32 + 1)
                .iter()
                .map(|v| v.to_bits())
                .collect();
            assert_eq!(got, *want, "{} steps", i + 1);
        }
    }

    #[test]
    fn three_steps_differ_from_the_exact_fractions_by_one_ulp() {
        // The old grid, (n - k) / n rounded once, gave 0x3f2aaaab for k = 1.
        assert_eq!(meanflow_grid(3)[1].to_bits(), 0x3f2aaaaa);
        assert_eq!(((2.0f64 / 3.0) as f32).to_bits(), 0x3f2aaaab);
    }
}
