//! Portable noise: the same seed gives the same motion on every platform and from every language.
//!
//! troupe never uses the platform's RNG. Every Gaussian it draws is a pure function of
//! `(seed, token index, stream, element index)`:
//!
//! * **Bits**: Philox4x32-10 (Salmon et al., SC'11; the Random123 reference algorithm), key
//!   `(seed & 0xffffffff, seed >> 32)`, counter
//!   `(block, token & 0xffffffff, token >> 32, stream)`. Block `b` yields four 32-bit words.
//! * **Normals**: Box-Muller on word pairs, in f64: `u1 = (w0 + 0.5) / 2^32`,
//!   `u2 = (w1 + 0.5) / 2^32`, `rad = sqrt(-2 ln u1)`, giving `rad * cos(2 pi u2)` then
//!   `rad * sin(2 pi u2)`, each rounded to f32. Block `b` gives elements `4b .. 4b + 3`.
//! * **Streams**: every use of noise has a stream of its own. ARMFlow's two are here:
//!   [`STREAM_ACTOR_POSTERIOR`] (the VAE posterior sample of the actor token) and
//!   [`STREAM_REACTOR_NOISE`] (the reactor token's starting noise). The other families number
//!   theirs beside their samplers: UMF 2 to 4 (`umf/group.rs`), MAGNet 8 (`magnet/draws.rs`),
//!   ARFlow 9 (`arflow/spec.rs`).
//!
//! Because the generator is counter-based, the noise of token `j` does not depend on what was
//! drawn before it: changing the sampler steps or CFG never shifts later tokens' noise, and
//! `reset()` needs no generator state. `philox_normals` in `onnx/troupe_onnx/shared/noise.py` is
//! the same algorithm in Python and the golden tests check both agree bit for bit.

/// Stream id of the actor posterior sample `xi`.
pub const STREAM_ACTOR_POSTERIOR: u32 = 0;
/// Stream id of the reactor's starting noise `eps`.
pub const STREAM_REACTOR_NOISE: u32 = 1;

const M0: u32 = 0xD251_1F53;
const M1: u32 = 0xCD9E_8D57;
const W0: u32 = 0x9E37_79B9;
const W1: u32 = 0xBB67_AE85;

/// Philox4x32 with 10 rounds: four random words for one 128-bit counter under a 64-bit key.
pub fn philox4x32_10(counter: [u32; 4], key: [u32; 2]) -> [u32; 4] {
    let [mut c0, mut c1, mut c2, mut c3] = counter;
    let [mut k0, mut k1] = key;
    for _ in 0..10 {
        let p0 = u64::from(M0) * u64::from(c0);
        let p1 = u64::from(M1) * u64::from(c2);
        (c0, c1, c2, c3) = (
            ((p1 >> 32) as u32) ^ c1 ^ k0,
            p1 as u32,
            ((p0 >> 32) as u32) ^ c3 ^ k1,
            p0 as u32,
        );
        k0 = k0.wrapping_add(W0);
        k1 = k1.wrapping_add(W1);
    }
    [c0, c1, c2, c3]
}

/// Where a sampler's standard normals come from, draw by draw: troupe's generator (draw `i` is
/// token `i` of `stream` under `seed`), or the caller's normals as one queue, each draw taking
/// the next `n` (how C and Python reproduce another implementation's run exactly).
#[derive(Debug, Clone)]
pub(crate) enum NormalSource<'a> {
    /// troupe's generator.
    Seeded {
        /// The run's seed.
        seed: u64,
        /// The family's stream.
        stream: u32,
        /// Draws made so far (the next draw's token).
        draws: u64,
    },
    /// The caller's normals.
    Queue {
        /// The normals, in the order the sampler draws.
        normals: &'a [f32],
        /// Normals taken so far.
        used: usize,
        /// Draws made so far.
        draws: usize,
    },
}

impl<'a> NormalSource<'a> {
    /// troupe's generator on `stream` under `seed`.
    pub(crate) fn seeded(seed: u64, stream: u32) -> Self {
        NormalSource::Seeded {
            seed,
            stream,
            draws: 0,
        }
    }

    /// The caller's normals, taken in order.
    pub(crate) fn queue(normals: &'a [f32]) -> Self {
        NormalSource::Queue {
            normals,
            used: 0,
            draws: 0,
        }
    }

    /// The next draw: `n` standard normals. A queue with fewer left, or a non-finite one among
    /// them, is an error naming the draw.
    pub(crate) fn draw(&mut self, n: usize) -> crate::shared::error::Result<Vec<f32>> {
        use crate::shared::error::Error;
        match self {
            NormalSource::Seeded {
                seed,
                stream,
                draws,
            } => {
                let mut out = vec![0f32; n];
                fill_normals(*seed, *draws, *stream, &mut out);
                *draws += 1;
                Ok(out)
            }
            NormalSource::Queue {
                normals,
                used,
                draws,
            } => {
                let left = normals.len() - *used;
                if left < n {
                    return Err(Error::InvalidInput(format!(
                        "draw {draws} needs {n} normals, and {left} of the {} injected are left",
                        normals.len()
                    )));
                }
                let out = &normals[*used..*used + n];
                if let Some(at) = out.iter().position(|v| !v.is_finite()) {
                    return Err(Error::InvalidInput(format!(
                        "injected normal {} is not finite",
                        *used + at
                    )));
                }
                *used += n;
                *draws += 1;
                Ok(out.to_vec())
            }
        }
    }

    /// Normals taken from the queue (0 for the generator).
    pub(crate) fn used(&self) -> usize {
        match self {
            NormalSource::Seeded { .. } => 0,
            NormalSource::Queue { used, .. } => *used,
        }
    }
}

/// Fills `out` with the standard normals of `(seed, token, stream)`.
pub fn fill_normals(seed: u64, token: u64, stream: u32, out: &mut [f32]) {
    let key = [seed as u32, (seed >> 32) as u32];
    for (block, chunk) in out.chunks_mut(4).enumerate() {
        let w = philox4x32_10(
            [block as u32, token as u32, (token >> 32) as u32, stream],
            key,
        );
        let mut normals = [0f32; 4];
        for (pair, slot) in normals.chunks_mut(2).enumerate() {
            let u1 = (f64::from(w[2 * pair]) + 0.5) * 2f64.powi(-32);
            let u2 = (f64::from(w[2 * pair + 1]) + 0.5) * 2f64.powi(-32);
            let rad = (-2.0 * u1.ln()).sqrt();
            let angle = std::f64::consts::TAU * u2;
            slot[0] = (rad * angle.cos()) as f32;
            slot[1] = (rad * angle.sin()) as f32;
        }
        chunk.copy_from_slice(&normals[..chunk.len()]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known-answer vectors of Philox4x32-10 from the Random123 distribution (kat_vectors).
    #[test]
    fn philox_matches_random123_known_answers() {
        assert_eq!(
            philox4x32_10([0; 4], [0; 2]),
            [0x6627_e8d5, 0xe169_c58d, 0xbc57_ac4c, 0x9b00_dbd8]
        );
        assert_eq!(
            philox4x32_10([u32::MAX; 4], [u32::MAX; 2]),
            [0x408f_276d, 0x41c8_3b0e, 0xa20b_c7c6, 0x6d54_51fd]
        );
        assert_eq!(
            philox4x32_10(
                [0x243f_6a88, 0x85a3_08d3, 0x1319_8a2e, 0x0370_7344],
                [0xa409_3822, 0x299f_31d0]
            ),
            [0xd16c_fe09, 0x94fd_cceb, 0x5001_e420, 0x2412_6ea1]
        );
    }

    #[test]
    fn normals_have_unit_moments_and_depend_on_every_coordinate() {
        let mut x = vec![0f32; 200_000];
        fill_normals(3, 0, STREAM_REACTOR_NOISE, &mut x);
        let n = x.len() as f64;
        let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let var = x
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.01, "variance {var}");
        let draw = |seed, token, stream| {
            let mut v = [0f32; 8];
            fill_normals(seed, token, stream, &mut v);
            v
        };
        let base = draw(1, 5, 0);
        assert_eq!(base, draw(1, 5, 0));
        assert_ne!(base, draw(2, 5, 0));
        assert_ne!(base, draw(1, 6, 0));
        assert_ne!(base, draw(1, 5, 1));
        assert_ne!(base, draw(1, 5 + (1 << 32), 0));
        // A prefix of a longer draw is the shorter draw.
        let mut short = [0f32; 3];
        fill_normals(1, 5, 0, &mut short);
        assert_eq!(short, base[..3]);
    }
}
