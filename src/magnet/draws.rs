//! Where MAGNet's samplers get their standard normals, in the order of
//! `docs/spec/magnet.md` §3.5: troupe's portable generator (draw `i` of a run is the Philox
//! normals of token `i` on stream [`STREAM_MAGNET`], so every language and platform draws the
//! same), or the caller's own draws, injected in order (for parity with another generator):
//! each draw given whole, or one queue of normals from which each draw takes the next `n`.

use crate::shared::error::{Error, Result};
use crate::shared::limits::{at_most, LIMITS};
use crate::shared::noise::{fill_normals, NormalSource};

/// troupe's Philox stream for MAGNet's draws.
pub const STREAM_MAGNET: u32 = 8;

/// The draws of one sampler run.
#[derive(Debug, Clone)]
pub enum Draws {
    /// Philox normals keyed by `seed`, draw `i` on token `i`.
    Seeded {
        /// The run's seed.
        seed: u64,
        /// Draws made so far.
        count: u64,
    },
    /// The caller's draws, used in order; each must have the size the sampler asks for.
    Injected {
        /// The draws, in the order of §3.5.
        draws: Vec<Vec<f32>>,
        /// Draws used so far.
        count: usize,
    },
    /// The caller's normals as one queue: each draw takes the next `n` (what C and Python give).
    Queue {
        /// The normals, in the order of §3.5.
        normals: Vec<f32>,
        /// Normals taken so far.
        used: usize,
        /// Draws made so far.
        count: usize,
    },
    /// A stream's queued normals (`Session::queue_normals`) in front of its own draws: while
    /// any are queued, a draw takes the next it needs from them, and `then` moves on by one
    /// draw as if it had been its.
    Queued {
        /// The normals, in the order the sampler draws.
        queue: Vec<f32>,
        /// Normals taken so far.
        used: usize,
        /// The draws behind the queue.
        then: Box<Draws>,
    },
    /// Independent runs stacked along the sample axis (a crowd of live sessions): every draw is
    /// `[S, ...]`, and run `i`'s share (its samples) comes from its own draws.
    PerRun(Vec<Draws>),
}

impl Draws {
    /// Seeded draws.
    pub fn seeded(seed: u64) -> Self {
        Draws::Seeded { seed, count: 0 }
    }

    /// The caller's draws, in order.
    pub fn injected(draws: Vec<Vec<f32>>) -> Self {
        Draws::Injected { draws, count: 0 }
    }

    /// The caller's normals, taken in order.
    pub fn queue(normals: Vec<f32>) -> Self {
        Draws::Queue {
            normals,
            used: 0,
            count: 0,
        }
    }

    /// Draws made so far.
    pub fn count(&self) -> usize {
        match self {
            Draws::Seeded { count, .. } => *count as usize,
            Draws::Injected { count, .. } | Draws::Queue { count, .. } => *count,
            Draws::Queued { then, .. } => then.count(),
            Draws::PerRun(runs) => runs.iter().map(Draws::count).max().unwrap_or(0),
        }
    }

    /// Puts `normals` in front of the draws to come, after any still queued (at most
    /// `LIMITS.max_tensor_elements` queued at once).
    pub(crate) fn enqueue(&mut self, normals: &[f32]) -> Result<()> {
        let queued = match self {
            Draws::Queued { queue, used, .. } => queue.len() - *used,
            _ => 0,
        };
        let total = queued as u64 + normals.len() as u64;
        at_most("queued normals", total, LIMITS.max_tensor_elements, false)?;
        match self {
            Draws::Queued { queue, used, .. } => {
                queue.drain(..*used);
                *used = 0;
                queue.extend_from_slice(normals);
            }
            other => {
                let then = Box::new(std::mem::replace(other, Draws::seeded(0)));
                *other = Draws::Queued {
                    queue: normals.to_vec(),
                    used: 0,
                    then,
                };
            }
        }
        Ok(())
    }

    /// Draws from `seed` from now on, the count (and any queued normals) kept.
    pub(crate) fn reseed(&mut self, seed: u64) {
        match self {
            Draws::Seeded { seed: s, .. } => *s = seed,
            Draws::Queued { then, .. } => then.reseed(seed),
            _ => {}
        }
    }

    /// The next draw of `n` standard normals.
    pub(crate) fn normal(&mut self, n: usize) -> Result<Vec<f32>> {
        match self {
            Draws::Seeded { seed, count } => {
                let mut out = vec![0f32; n];
                fill_normals(*seed, *count, STREAM_MAGNET, &mut out);
                *count += 1;
                Ok(out)
            }
            Draws::Injected { draws, count } => {
                let i = *count;
                let draw = draws.get(i).ok_or_else(|| {
                    Error::InvalidInput(format!(
                        "the run needs more than the {} injected draws",
                        draws.len()
                    ))
                })?;
                if draw.len() != n {
                    return Err(Error::InvalidInput(format!(
                        "injected draw {i} holds {} normals, the sampler needs {n} here",
                        draw.len()
                    )));
                }
                if draw.iter().any(|v| !v.is_finite()) {
                    return Err(Error::InvalidInput(format!(
                        "injected draw {i} holds a non-finite value"
                    )));
                }
                *count += 1;
                Ok(draw.clone())
            }
            Draws::Queue {
                normals,
                used,
                count,
            } => {
                let mut queue = NormalSource::Queue {
                    normals,
                    used: *used,
                    draws: *count,
                };
                let draw = queue.draw(n)?;
                *used = queue.used();
                *count += 1;
                Ok(draw)
            }
            Draws::Queued { queue, used, then } if *used < queue.len() => {
                let mut source = NormalSource::Queue {
                    normals: queue,
                    used: *used,
                    draws: then.count(),
                };
                let draw = source.draw(n)?;
                *used = source.used();
                then.normal(n)?; // the draw the queued one stands for
                Ok(draw)
            }
            Draws::Queued { then, .. } => then.normal(n),
            Draws::PerRun(runs) => {
                let share = n / runs.len().max(1);
                debug_assert_eq!(
                    share * runs.len(),
                    n,
                    "draws are [S, ...], one run per sample"
                );
                let mut out = Vec::with_capacity(n);
                for run in runs {
                    out.extend(run.normal(share)?);
                }
                Ok(out)
            }
        }
    }
}
