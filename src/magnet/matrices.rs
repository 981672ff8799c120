//! Scheduling matrices (`docs/spec/magnet.md` §4): one row of noise levels per iteration, one
//! column per flattened window token `f = t * P + p`; iteration `r` goes from row `r` to row
//! `r + 1`. Mirrors `onnx/troupe_onnx/magnet/matrices.py`.

use super::schedule::{level_table, CLEAN};
use super::spec::ScheduleKind;

/// A level matrix: `rows x columns` levels, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Levels {
    pub columns: usize,
    pub data: Vec<i64>,
}

impl Levels {
    pub fn rows(&self) -> usize {
        self.data.len() / self.columns
    }

    pub fn row(&self, r: usize) -> &[i64] {
        &self.data[r * self.columns..(r + 1) * self.columns]
    }

    pub fn set_column(&mut self, f: usize, level: i64) {
        for r in 0..self.rows() {
            self.data[r * self.columns + f] = level;
        }
    }

    /// Drops the leading rows equal to their successor, keeping the last of them (§4.2).
    pub fn prune(mut self) -> Self {
        let rows = self.rows();
        let first = (0..rows.saturating_sub(1))
            .find(|&i| self.row(i + 1) != self.row(i))
            .unwrap_or(0);
        self.data.drain(..first * self.columns);
        self
    }

    /// The matrix of every later AR window (§4.3): from one row before the first whose first
    /// newly generated column is no longer pure noise, all columns but the last `new_flat` clean.
    pub fn ar_window(&self, new_flat: usize, pure_noise: i64) -> Self {
        let col = self.columns - new_flat;
        let rows = self.rows();
        let r0 = (0..rows)
            .find(|&r| self.row(r)[col] != pure_noise)
            .unwrap_or(rows - 1);
        // r0 = 0 takes Python's `M[-1:]`: the last row alone.
        let from = if r0 > 0 { r0 - 1 } else { rows - 1 };
        let mut out = Self {
            columns: self.columns,
            data: self.data[from * self.columns..].to_vec(),
        };
        for f in 0..col {
            out.set_column(f, CLEAN);
        }
        out
    }
}

/// Step indices `0..=steps` (§4.1) over `length` flat tokens in groups of `group`.
fn index_matrix(
    kind: ScheduleKind,
    steps: usize,
    length: usize,
    group: usize,
    offset: f64,
) -> Levels {
    let n = steps as i64;
    let (rows, cell): (usize, Box<dyn Fn(usize, usize) -> i64>) = match kind {
        ScheduleKind::FullSequence => (steps + 1, Box::new(move |m, _| n - m as i64)),
        ScheduleKind::CausalUncertainty => (
            steps + length / group,
            Box::new(move |m, f| (n + (f / group) as i64 - m as i64).clamp(0, n)),
        ),
        ScheduleKind::Autoregressive => {
            let off = (steps as f64 * (1.0 - offset)) as i64;
            let groups = length.div_ceil(group) as i64;
            let d = (n - off).max(0);
            (
                (n + (groups - 1) * d + 1) as usize,
                Box::new(move |m, f| (n + (f / group) as i64 * d - m as i64).clamp(0, n)),
            )
        }
    };
    let mut data = Vec::with_capacity(rows * length);
    for m in 0..rows {
        data.extend((0..length).map(|f| cell(m, f)));
    }
    Levels {
        columns: length,
        data,
    }
}

/// The first window's level matrix (§4.2): step indices mapped through the level table, the
/// first `context_tokens` time steps of every person clean, leading duplicates pruned.
#[allow(clippy::too_many_arguments)]
pub(crate) fn level_matrix(
    kind: ScheduleKind,
    steps: usize,
    max_t: usize,
    window: usize,
    persons: usize,
    group: usize,
    context_tokens: usize,
    offset: f64,
    prune: bool,
) -> Levels {
    let table = level_table(steps, max_t);
    let mut m = index_matrix(kind, steps, window * persons, group.max(1), offset);
    for v in &mut m.data {
        *v = table[*v as usize];
    }
    for f in 0..context_tokens * persons {
        m.set_column(f, CLEAN);
    }
    if prune {
        m.prune()
    } else {
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(kind: ScheduleKind, p: usize, g: usize, prune: bool) -> usize {
        level_matrix(kind, 50, 1000, 16, p, g, 8, 0.0, prune).rows()
    }

    #[test]
    fn released_matrices_have_the_specified_rows() {
        use ScheduleKind::*;
        assert_eq!(shape(CausalUncertainty, 2, 32, true), 51);
        assert_eq!(shape(CausalUncertainty, 2, 2, false), 66);
        assert_eq!(shape(CausalUncertainty, 2, 2, true), 58);
        assert_eq!(shape(FullSequence, 2, 2, true), 51);
        assert_eq!(shape(CausalUncertainty, 2, 4, true), 54);
        assert_eq!(shape(CausalUncertainty, 3, 12, true), 52);
        let joint = level_matrix(CausalUncertainty, 50, 1000, 16, 2, 32, 8, 0.0, true);
        assert_eq!(joint.ar_window(8, 999).rows(), 51);
        let turn = level_matrix(CausalUncertainty, 50, 1000, 16, 2, 4, 8, 0.0, true);
        assert_eq!(turn.ar_window(4, 999).rows(), 51);
        let pp = level_matrix(CausalUncertainty, 50, 1000, 16, 2, 2, 8, 0.0, true);
        let ar = pp.ar_window(4, 999);
        assert_eq!(ar.rows(), 52);
        assert!(ar.row(0)[..28].iter().all(|&l| l == CLEAN));
    }

    #[test]
    fn autoregressive_extremes() {
        let sequential = index_matrix(ScheduleKind::Autoregressive, 4, 6, 2, 1.0);
        assert_eq!(sequential.rows(), 13);
        assert_eq!(sequential.row(4), &[0, 0, 4, 4, 4, 4]);
        let together = index_matrix(ScheduleKind::Autoregressive, 4, 6, 2, 0.0);
        assert_eq!(together.rows(), 5);
    }
}
