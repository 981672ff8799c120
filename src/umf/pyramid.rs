//! Pyramid Flow's resolution ladder over latent tokens (`docs/spec/umf.md` §3-§4): the Down/Up
//! operators, the jump ("renoise") between stages, and its block-correlated noise.
//!
//! Latents are row-major `[tokens, dim]`. Two layouts of the token axis are supported:
//! * [`Layout::Grid2d`]: `n = h * h` tokens form an `h x h` grid, token `row * h + col` (UMF's
//!   16 tokens as 4x4). Down averages 2x2 blocks; Up copies a coarse token into its block.
//! * [`Layout::Temporal`]: a sequence; Down averages consecutive pairs, Up repeats a token.
//!
//! The jump from a stage ending at `o` to the next: `z <- alpha * Up(z) + beta * n'`, where
//! `n'` holds one vector per (channel, block) drawn from `N(0, Sigma)`,
//! `Sigma = (1 - gamma) I + gamma 1 1^T + 1e-6 I`, and
//! `alpha = 1 / (sqrt(1 - 1/gamma) (1 - o) + o)`, `beta = alpha (1 - o) / sqrt(-gamma)`. These
//! make the jumped state distributed as the next stage's start `s = alpha * o` would be: mean
//! `s * Up(data)`, independent per-element noise of variance `(1 - s)^2`.

use serde::{Deserialize, Serialize};

use crate::shared::error::{Error, Result};

/// How latent tokens are arranged for pooling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// A square grid pooled 2x2 (blocks of 4 tokens).
    Grid2d,
    /// A sequence pooled by pairs (blocks of 2 tokens).
    Temporal,
}

/// Diagonal jitter UMF adds to the block covariance before its Cholesky factorisation.
pub const COVARIANCE_JITTER: f64 = 1e-6;

impl Layout {
    /// Tokens per block: how many fine tokens one coarse token becomes.
    pub fn block(self) -> usize {
        match self {
            Layout::Grid2d => 4,
            Layout::Temporal => 2,
        }
    }

    /// Whether `tokens` fine tokens can be pooled once in this layout.
    pub fn can_pool(self, tokens: usize) -> bool {
        match self {
            Layout::Grid2d => {
                let h = isqrt(tokens);
                h * h == tokens && h.is_multiple_of(2) && h > 0
            }
            Layout::Temporal => tokens > 0 && tokens.is_multiple_of(2),
        }
    }

    /// For each fine token, the index of its block (= coarse token) and its place in the block
    /// (`2p + q` for row offset p and column offset q in a 2x2 grid block; 0 or 1 in a pair).
    fn fine_to_block(self, fine_tokens: usize) -> Vec<(usize, usize)> {
        match self {
            Layout::Grid2d => {
                let h = isqrt(fine_tokens);
                (0..fine_tokens)
                    .map(|i| {
                        let (row, col) = (i / h, i % h);
                        ((row / 2) * (h / 2) + col / 2, 2 * (row % 2) + col % 2)
                    })
                    .collect()
            }
            Layout::Temporal => (0..fine_tokens).map(|i| (i / 2, i % 2)).collect(),
        }
    }

    /// Nearest-neighbour upsampling: `[fine_tokens / block, dim]` to `[fine_tokens, dim]`.
    pub fn up(self, coarse: &[f32], fine_tokens: usize, dim: usize) -> Vec<f32> {
        let mut fine = Vec::with_capacity(fine_tokens * dim);
        for (block, _) in self.fine_to_block(fine_tokens) {
            fine.extend_from_slice(&coarse[block * dim..(block + 1) * dim]);
        }
        fine
    }

    /// Block-average downsampling: `[fine_tokens, dim]` to `[fine_tokens / block, dim]` (what
    /// bilinear interpolation by exactly 1/2 computes).
    pub fn down(self, fine: &[f32], dim: usize) -> Vec<f32> {
        let fine_tokens = fine.len() / dim;
        let mut coarse = vec![0f32; fine_tokens / self.block() * dim];
        for (i, (block, _)) in self.fine_to_block(fine_tokens).into_iter().enumerate() {
            for (c, v) in coarse[block * dim..(block + 1) * dim]
                .iter_mut()
                .zip(&fine[i * dim..(i + 1) * dim])
            {
                *c += v;
            }
        }
        let inv = 1.0 / self.block() as f32;
        coarse.iter_mut().for_each(|c| *c *= inv);
        coarse
    }
}

fn isqrt(n: usize) -> usize {
    let mut r = (n as f64).sqrt() as usize;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// The jump between two stages: its coefficients and the factor of its noise covariance.
#[derive(Debug, Clone)]
pub struct Jump {
    layout: Layout,
    /// Scale of the upsampled state.
    pub alpha: f32,
    /// Scale of the block noise.
    pub beta: f32,
    /// Start time of the next stage, `alpha * o`.
    pub start_t: f64,
    /// Lower Cholesky factor of the block covariance, row-major `[block, block]`, in f32.
    cholesky: Vec<f32>,
}

impl Jump {
    /// The jump out of a stage that ends at `o` (in (0, 1)), for block correlation `gamma`.
    /// `gamma` must lie in `[-1 / (block - 1), 0)`; at the lower end (UMF's paper, -1/3) the
    /// covariance is singular but for the jitter.
    pub fn new(layout: Layout, gamma: f64, o: f64) -> Result<Self> {
        let block = layout.block();
        let lowest = -1.0 / (block as f64 - 1.0);
        if !(gamma.is_finite() && gamma < 0.0 && gamma >= lowest - 1e-12) {
            return Err(Error::InvalidOption(format!(
                "pyramid gamma {gamma} is outside [{lowest}, 0) for blocks of {block} tokens"
            )));
        }
        if !(o > 0.0 && o < 1.0) {
            return Err(Error::InvalidOption(format!(
                "a jump happens inside (0, 1); got a stage ending at {o}"
            )));
        }
        let alpha = 1.0 / ((1.0 - 1.0 / gamma).sqrt() * (1.0 - o) + o);
        let beta = alpha * (1.0 - o) / (-gamma).sqrt();
        // The covariance as UMF's `sample_block_noise` builds it, in f32:
        // `eye * (1 - gamma) + ones * gamma + 1e-6 * eye`, each operation rounded to f32.
        let diagonal = ((1.0 - gamma) as f32 + gamma as f32) + COVARIANCE_JITTER as f32;
        let sigma: Vec<f64> = (0..block * block)
            .map(|k| {
                let diag = k / block == k % block;
                f64::from(if diag { diagonal } else { gamma as f32 })
            })
            .collect();
        Ok(Self {
            layout,
            alpha: alpha as f32,
            beta: beta as f32,
            start_t: alpha * o,
            cholesky: cholesky_f32(&sigma, block)?,
        })
    }

    /// Lower Cholesky factor of the block covariance, row-major.
    pub fn cholesky(&self) -> &[f32] {
        &self.cholesky
    }

    /// Turns standard normals into the block-correlated noise `n'` of a `[fine_tokens, dim]`
    /// state. `normals` holds `fine_tokens * dim` values consumed one block vector at a time,
    /// blocks in (channel, block) order as UMF's `sample_block_noise` draws them.
    pub fn block_noise(&self, normals: &[f32], fine_tokens: usize, dim: usize) -> Vec<f32> {
        let b = self.layout.block();
        let blocks = fine_tokens / b;
        let map = self.layout.fine_to_block(fine_tokens);
        let mut out = vec![0f32; fine_tokens * dim];
        for (token, &(block, place)) in map.iter().enumerate() {
            let row = &self.cholesky[place * b..(place + 1) * b];
            for c in 0..dim {
                let eps = &normals[(c * blocks + block) * b..(c * blocks + block + 1) * b];
                out[token * dim + c] = row.iter().zip(eps).map(|(l, e)| l * e).sum();
            }
        }
        out
    }

    /// `alpha * Up(coarse) + beta * noise`, with `noise` already in the fine layout.
    pub fn apply(&self, coarse: &[f32], noise: &[f32], dim: usize) -> Vec<f32> {
        let fine_tokens = noise.len() / dim;
        let up = self.layout.up(coarse, fine_tokens, dim);
        up.iter()
            .zip(noise)
            .map(|(u, n)| self.alpha * u + self.beta * n)
            .collect()
    }
}

/// Cholesky factor of the f32 covariance `a`, computed in f64 and rounded once to f32: the
/// correctly rounded factor, which LAPACK's f32 `spotrf` (torch's `linalg.cholesky`, which UMF
/// calls) is within one ulp of. For the released gamma of -0.2 the two are equal bit for bit
/// (`tests` below, against values written down from torch with MKL); across gammas MKL's
/// rounding differs by one ulp in about one entry in ten, which no portable operation order we
/// tried (f32 Crout with division or reciprocal, fused or not, either summation order)
/// reproduces.
fn cholesky_f32(a: &[f64], n: usize) -> Result<Vec<f32>> {
    let mut l = vec![0f64; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            if i == j {
                let d = a[i * n + i] - s;
                if d <= 0.0 {
                    return Err(Error::InvalidOption(
                        "pyramid block covariance is not positive definite".into(),
                    ));
                }
                l[i * n + j] = d.sqrt();
            } else {
                l[i * n + j] = (a[i * n + j] - s) / l[j * n + j];
            }
        }
    }
    Ok(l.into_iter().map(|v| v as f32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shared::noise::fill_normals;

    #[test]
    fn umf_coefficients_and_paper_limit() {
        let code = Jump::new(Layout::Grid2d, -0.2, 0.5).unwrap();
        assert!((code.alpha - 0.579_795_9).abs() < 1e-6);
        assert!((code.beta - 0.648_231_5).abs() < 1e-6);
        assert!((code.start_t - 0.289_897_948_6).abs() < 1e-9);
        let l = code.cholesky();
        assert!((l[4] + 0.199_999_9).abs() < 1e-6 && (l[15] - 0.894_427_9).abs() < 1e-6);
        // The paper's Eq. 11 is gamma = -1/3: s / e = 2/3 and beta = sqrt(3) (1 - s) / 2.
        let paper = Jump::new(Layout::Grid2d, -1.0 / 3.0, 0.5).unwrap();
        let s = paper.start_t;
        assert!((s - 1.0 / 3.0).abs() < 1e-9);
        assert!((f64::from(paper.alpha) - s / 0.5).abs() < 1e-7);
        assert!((f64::from(paper.beta) - 3f64.sqrt() * (1.0 - s) / 2.0).abs() < 1e-7);
        assert!(Jump::new(Layout::Grid2d, -0.5, 0.5).is_err());
        assert!(Jump::new(Layout::Grid2d, 0.1, 0.5).is_err());
        assert!(Jump::new(Layout::Temporal, -0.5, 0.5).is_ok());
    }

    /// `torch.linalg.cholesky(torch.eye(4) * 1.2 + torch.ones(4, 4) * -0.2 + 1e-6 *
    /// torch.eye(4))`, UMF's released covariance built and factored in f32 as its
    /// `sample_block_noise` does, written down from torch 2.15 (MKL 2024.2) as bit patterns of
    /// the lower triangle, row by row. Building the covariance in f64 instead moved 8 of these 10.
    #[test]
    fn the_block_covariance_factor_is_torchs_for_the_released_gamma() {
        let want: [u32; 10] = [
            0x3f800004, 0xbe4cccc7, 0x3f7ad3f0, 0xbe4cccc7, 0xbe7ad3dd, 0x3f72dcf2, 0xbe4cccc7,
            0xbe7ad3dd, 0xbea1e891, 0x3f64f93a,
        ];
        let l = Jump::new(Layout::Grid2d, -0.2, 0.5).unwrap();
        let lower: Vec<u32> = (0..4)
            .flat_map(|i| (0..=i).map(move |j| (i, j)))
            .map(|(i, j)| l.cholesky()[i * 4 + j].to_bits())
            .collect();
        assert_eq!(lower, want);
    }

    #[test]
    fn up_and_down_follow_the_block_layout() {
        // 4x4 grid of one channel: coarse token k copies into its 2x2 block.
        let up = Layout::Grid2d.up(&[0.0, 1.0, 2.0, 3.0], 16, 1);
        assert_eq!(
            up,
            vec![0., 0., 1., 1., 0., 0., 1., 1., 2., 2., 3., 3., 2., 2., 3., 3.]
        );
        assert_eq!(Layout::Grid2d.down(&up, 1), vec![0.0, 1.0, 2.0, 3.0]);
        let fine: Vec<f32> = (0..16).map(|v| v as f32).collect();
        assert_eq!(Layout::Grid2d.down(&fine, 1), vec![2.5, 4.5, 10.5, 12.5]);
        assert_eq!(
            Layout::Temporal.up(&[1.0, 2.0, 3.0, 4.0], 4, 2),
            vec![1.0, 2.0, 1.0, 2.0, 3.0, 4.0, 3.0, 4.0]
        );
        assert_eq!(
            Layout::Temporal.down(&[1.0, 3.0, 5.0, 9.0], 1),
            vec![2.0, 7.0]
        );
        assert!(Layout::Grid2d.can_pool(16) && !Layout::Grid2d.can_pool(9));
        assert!(Layout::Temporal.can_pool(6) && !Layout::Temporal.can_pool(5));
    }

    /// Sample covariance of `n'` within a block over 2^17 blocks equals Sigma within 1e-2.
    #[test]
    fn block_noise_has_the_block_covariance() {
        for (layout, gamma) in [(Layout::Grid2d, -0.2), (Layout::Temporal, -0.6)] {
            let jump = Jump::new(layout, gamma, 0.5).unwrap();
            let b = layout.block();
            let (tokens, dim) = (16, 1 << 15);
            let mut normals = vec![0f32; tokens * dim];
            fill_normals(11, 0, 9, &mut normals);
            let noise = jump.block_noise(&normals, tokens, dim);
            let map = layout.fine_to_block(tokens);
            let mut cov = vec![0f64; b * b];
            let mut count = 0f64;
            for block in 0..tokens / b {
                let members: Vec<usize> = (0..tokens).filter(|&t| map[t].0 == block).collect();
                for c in 0..dim {
                    let v: Vec<f64> = members
                        .iter()
                        .map(|&t| f64::from(noise[t * dim + c]))
                        .collect();
                    for i in 0..b {
                        for j in 0..b {
                            cov[map[members[i]].1 * b + map[members[j]].1] += v[i] * v[j];
                        }
                    }
                    count += 1.0;
                }
            }
            assert!(count >= 1e5);
            for i in 0..b {
                for j in 0..b {
                    let want = if i == j { 1.0 } else { gamma };
                    let got = cov[i * b + j] / count;
                    assert!(
                        (got - want).abs() < 1e-2,
                        "{layout:?} cov[{i}][{j}] = {got}"
                    );
                }
            }
        }
    }

    /// A stage-0 end state `e * data + (1 - e) eps` with data = 0, jumped, is distributed as the
    /// next stage's start: zero mean, variance (1 - s)^2, no correlation inside a block.
    #[test]
    fn jump_of_pure_noise_lands_on_the_target_marginal() {
        let jump = Jump::new(Layout::Grid2d, -0.2, 0.5).unwrap();
        let (tokens, dim) = (16, 1 << 14);
        let mut eps = vec![0f32; tokens / 4 * dim];
        fill_normals(5, 0, 7, &mut eps);
        let coarse: Vec<f32> = eps.iter().map(|v| 0.5 * v).collect();
        let mut normals = vec![0f32; tokens * dim];
        fill_normals(5, 1, 7, &mut normals);
        let z = jump.apply(&coarse, &jump.block_noise(&normals, tokens, dim), dim);
        let target_var = (1.0 - jump.start_t).powi(2);
        let n = (tokens * dim) as f64;
        let mean = z.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let var = z.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>() / n;
        assert!(mean.abs() < 5e-3, "mean {mean}");
        assert!(
            (var - target_var).abs() < 1e-2,
            "variance {var} vs {target_var}"
        );
        // Tokens 0 and 1 share a block: their covariance must vanish.
        let cross = (0..dim)
            .map(|c| f64::from(z[c]) * f64::from(z[dim + c]))
            .sum::<f64>()
            / dim as f64;
        assert!(cross.abs() < 2e-2, "in-block covariance {cross}");
    }
}
