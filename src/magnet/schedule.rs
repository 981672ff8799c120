//! The noise schedule, the step -> level table, q_sample and the DDIM step
//! (`docs/spec/magnet.md` §3), in float32 exactly as the reference computes them
//! (`onnx/troupe_onnx/magnet/schedule.py`).

/// The level of a clean token.
pub const CLEAN: i64 = -1;

/// The cosine schedule's float32 tables `(ᾱ, √ᾱ, √(1 − ᾱ))` over `max_t` levels, computed in
/// float64 and rounded once (§3.1).
pub fn cosine_tables(max_t: usize, s: f64) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let g = |u: usize| {
        let x = ((u as f64 / max_t as f64) + s) / (1.0 + s) * std::f64::consts::FRAC_PI_2;
        x.cos().powi(2)
    };
    let g0 = g(0);
    let mut abar = 1.0f64;
    let mut prev = 1.0f64;
    let (mut a, mut sa, mut sr) = (Vec::new(), Vec::new(), Vec::new());
    for u in 1..=max_t {
        let raw = g(u) / g0;
        let beta = (1.0 - raw / prev).clamp(1e-9, 1.0);
        prev = raw;
        abar *= 1.0 - beta;
        a.push(abar as f32);
        sa.push(abar.sqrt() as f32);
        sr.push((1.0 - abar).sqrt() as f32);
    }
    (a, sa, sr)
}

/// `trunc(linspace(-1, max_t - 1, steps + 1))` in float32 as torch computes it (§3.2).
pub fn level_table(steps: usize, max_t: usize) -> Vec<i64> {
    let points = steps + 1;
    let (start, end) = (-1.0f32, max_t as f32 - 1.0);
    let step = (end - start) / steps as f32;
    (0..points)
        .map(|k| {
            let v = if k < points / 2 {
                start + step * k as f32
            } else {
                end - step * (points - 1 - k) as f32
            };
            v.trunc() as i64
        })
        .collect()
}

/// The schedule's tables, as the manifest ships them (checked against [`cosine_tables`]).
#[derive(Debug, Clone)]
pub(crate) struct Schedule {
    pub abar: Vec<f32>,
    pub sqrt_abar: Vec<f32>,
    pub sqrt_one_minus_abar: Vec<f32>,
}

impl Schedule {
    /// A table index for `level`: -1 reads the last row, as Python's negative index does.
    fn row(&self, level: i64) -> usize {
        if level < 0 {
            self.abar.len() - 1
        } else {
            level as usize
        }
    }

    /// `√(1 − ᾱ)` at `level` (-1: the last row, pure noise), for the guidance modes (§6.2).
    pub fn noise_scale(&self, level: i64) -> f32 {
        self.sqrt_one_minus_abar[self.row(level)]
    }

    /// `(√ᾱ, √(1 − ᾱ))` at `level` (-1: the last row), for q_sample (§3.3).
    pub fn q_coefficients(&self, level: i64) -> (f32, f32) {
        let r = self.row(level);
        (self.sqrt_abar[r], self.sqrt_one_minus_abar[r])
    }

    /// One DDIM step of one token (§3.4) from level `k` to `k_next`: `x`, `x0`, `z` its values,
    /// `out` the result. A token with `k == k_next` keeps `x`.
    pub fn ddim_token(
        &self,
        (k, k_next): (i64, i64),
        eta: f32,
        x: &[f32],
        x0: &[f32],
        z: &[f32],
        out: &mut [f32],
    ) {
        if k == k_next {
            out.copy_from_slice(x);
            return;
        }
        let kc = k.max(0) as usize;
        let a = self.abar[kc];
        let clean_next = k_next < 0;
        let a_next = if clean_next {
            1.0
        } else {
            self.abar[k_next as usize]
        };
        let sigma = if clean_next {
            0.0
        } else {
            eta * ((1.0 - a / a_next) * (1.0 - a_next) / (1.0 - a)).sqrt()
        };
        let c = (1.0 - a_next - sigma * sigma).max(0.0).sqrt();
        let root_next = a_next.sqrt();
        let (sa, sr) = (self.sqrt_abar[kc], self.sqrt_one_minus_abar[kc]);
        for i in 0..x.len() {
            let eps = (x[i] - sa * x0[i]) / sr;
            out[i] = root_next * x0[i] + c * eps + sigma * z[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_tables_match_the_specifications_test_vector() {
        let (a, sa, sr) = cosine_tables(1000, 0.008);
        let vector: [(usize, f64, f64, f64); 4] = [
            (0, 0.999958694, 0.999979377, 0.00642528012),
            (19, 0.998252511, 0.999125838, 0.0418032706),
            (499, 0.493843585, 0.702740073, 0.711446702),
            (998, 2.42876695e-06, 0.00155845017, 0.999998808),
        ];
        for (i, ea, esa, esr) in vector {
            assert!(
                (f64::from(a[i]) - ea).abs() <= 2e-7 * ea.max(1e-6),
                "abar[{i}]"
            );
            assert!((f64::from(sa[i]) - esa).abs() <= 2e-7, "sqrt_abar[{i}]");
            assert!(
                (f64::from(sr[i]) - esr).abs() <= 2e-7,
                "sqrt_one_minus_abar[{i}]"
            );
        }
        assert_eq!((a[999], sa[999], sr[999]), (0.0, 0.0, 1.0));
    }

    #[test]
    fn level_tables() {
        let fifty = level_table(50, 1000);
        assert_eq!(fifty, (0..=50).map(|m| -1 + 20 * m).collect::<Vec<i64>>());
        let thirty = level_table(30, 1000);
        assert_eq!(&thirty[..5], &[-1, 32, 65, 99, 132]);
        assert_eq!(thirty[30], 999);
    }

    #[test]
    fn ddim_lands_on_x0_and_keeps_waiting_tokens() {
        let (abar, sqrt_abar, sqrt_one_minus_abar) = cosine_tables(1000, 0.008);
        let s = Schedule {
            abar,
            sqrt_abar,
            sqrt_one_minus_abar,
        };
        let (x, x0, z) = ([0.5f32, -1.0], [0.25f32, 2.0], [1.0f32, 1.0]);
        let mut out = [0f32; 2];
        s.ddim_token((19, CLEAN), 1.0, &x, &x0, &z, &mut out);
        assert!((out[0] - 0.25).abs() < 1e-6 && (out[1] - 2.0).abs() < 1e-5);
        s.ddim_token((999, 999), 1.0, &x, &x0, &z, &mut out);
        assert_eq!(out, x);
    }
}
