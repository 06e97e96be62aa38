//! Finite state projection: the CME on a box `Π_i [0, m_i)`, integrated exactly.
//!
//! The generator `A` (columns sum to ≤ 0) keeps every reaction's outflow on the
//! diagonal, also for reactions that would leave the box, so probability that leaves the
//! box is lost, not reflected: `1 − Σ_z P(z, t)` is the **leak**, and it bounds the L1
//! error of the truncated solution against the CME's (Munsky & Khammash 2006, Thm 2.2).
//!
//! **Uniformization.** With `q ≥ max_z |A_zz|` and `B = I + A/q` (non-negative),
//! `P(t + Δ) = Σ_k Pois(k; qΔ) Bᵏ P(t)`. Every term is non-negative, so the result
//! has no negative probabilities and the truncation of the sum (tail < 1e-15) is the
//! only error besides round-off. Steps are cut so that `qΔ ≤ 50` (Poisson weights stay
//! representable). Cost: about `q·t` sparse matrix–vector products: cheap for the gene
//! networks here (q ~ 1–20 per unit time), expensive for stiff networks (then a Krylov
//! or implicit method would be the choice).
//!
//! Boxes beyond ~10⁷ states are refused: that is where separated (PGD) solvers take
//! over.

use rayon::prelude::*;
use thiserror::Error;

use super::moments::Moments;
use super::network::Network;

/// Largest box the exact solver accepts.
pub const MAX_STATES: usize = 10_000_000;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FspError {
    #[error(
        "the box has {states:.4e} states (> {MAX_STATES}): FSP is for up to about three \
         species; use the PGD solver or a sub-network"
    )]
    TooLarge { states: f64 },
    #[error("species {0} has an automatic box; FSP needs sizes (use solve_auto)")]
    AutoBox(String),
    #[error("output times must be finite, ≥ 0 and increasing; got {0:?}")]
    Times(Vec<f64>),
    #[error("the box has {got} sizes but the network has {species} species")]
    BoxShape { got: usize, species: usize },
}

/// The generator on a box, in CSR (rows: target states).
#[derive(Debug, Clone)]
pub struct Generator {
    pub sizes: Vec<usize>,
    row_start: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f64>,
    diag: Vec<f64>,
}

impl Generator {
    /// Builds `A` for `network` with parameter values `p` on the box `sizes`.
    pub fn new(network: &Network, p: &[f64], sizes: &[usize]) -> Result<Self, FspError> {
        if sizes.len() != network.species.len() {
            return Err(FspError::BoxShape {
                got: sizes.len(),
                species: network.species.len(),
            });
        }
        // Twenty species of 64 states overflow 64 bits: count in f64 for the message.
        let n = match sizes.iter().try_fold(1usize, |a, &m| a.checked_mul(m)) {
            Some(n) if n <= MAX_STATES && !sizes.contains(&0) => n,
            _ => {
                return Err(FspError::TooLarge {
                    states: sizes.iter().map(|&m| m as f64).product(),
                });
            }
        };
        let d = sizes.len();
        let mut strides = vec![1usize; d];
        for i in 1..d {
            strides[i] = strides[i - 1] * sizes[i - 1];
        }
        let mut row_start = Vec::with_capacity(n + 1);
        let mut cols = Vec::with_capacity(n * network.reactions.len());
        let mut vals = Vec::with_capacity(n * network.reactions.len());
        let mut diag = vec![0.0; n];
        let mut z = vec![0i64; d];
        let mut src = vec![0i64; d];
        row_start.push(0);
        for row in 0..n {
            let mut rem = row;
            for i in 0..d {
                z[i] = (rem % sizes[i]) as i64;
                rem /= sizes[i];
            }
            for (r, re) in network.reactions.iter().enumerate() {
                diag[row] -= network.propensity(r, &z, p);
                // Inflow from z − ν_r, when that state is in the box.
                let mut inside = true;
                let mut col = 0usize;
                for i in 0..d {
                    src[i] = z[i] - i64::from(re.change[i]);
                    if src[i] < 0 || src[i] >= sizes[i] as i64 {
                        inside = false;
                        break;
                    }
                    col += src[i] as usize * strides[i];
                }
                if inside && re.change.iter().any(|&c| c != 0) {
                    let a = network.propensity(r, &src, p);
                    if a != 0.0 {
                        cols.push(col as u32);
                        vals.push(a);
                    }
                }
            }
            row_start.push(cols.len());
        }
        Ok(Generator {
            sizes: sizes.to_vec(),
            row_start,
            cols,
            vals,
            diag,
        })
    }

    pub fn states(&self) -> usize {
        self.diag.len()
    }

    /// `out = A x` (for checks; the solver uses the uniformized product).
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (row, o) in out.iter_mut().enumerate() {
            let mut s = self.diag[row] * x[row];
            for e in self.row_start[row]..self.row_start[row + 1] {
                s += self.vals[e] * x[self.cols[e] as usize];
            }
            *o = s;
        }
    }

    /// `out = (I + A/q) x`.
    fn uniformized(&self, q: f64, x: &[f64], out: &mut [f64]) {
        let inv = 1.0 / q;
        out.par_chunks_mut(4096).enumerate().for_each(|(c, chunk)| {
            let base = c * 4096;
            for (k, o) in chunk.iter_mut().enumerate() {
                let row = base + k;
                let mut s = x[row] * (1.0 + self.diag[row] * inv);
                for e in self.row_start[row]..self.row_start[row + 1] {
                    s += self.vals[e] * inv * x[self.cols[e] as usize];
                }
                *o = s;
            }
        });
    }

    /// Advances `p` by `dt` (exact up to a 1e-15 tail and round-off).
    pub fn advance(&self, p: &mut Vec<f64>, dt: f64) {
        let q = self.diag.iter().fold(0.0f64, |m, d| m.max(-d)) * 1.02 + 1e-12;
        let mut left = dt;
        let mut term = vec![0.0; p.len()];
        let mut next = vec![0.0; p.len()];
        let mut acc = vec![0.0; p.len()];
        while left > 0.0 {
            let step = left.min(50.0 / q);
            left -= step;
            let lambda = q * step;
            term.copy_from_slice(p);
            let mut w = (-lambda).exp();
            let mut cum = w;
            acc.iter_mut().zip(&term).for_each(|(a, t)| *a = w * t);
            let mut k = 0u32;
            while 1.0 - cum > 1e-15 && k < 100_000 {
                k += 1;
                self.uniformized(q, &term, &mut next);
                std::mem::swap(&mut term, &mut next);
                w *= lambda / f64::from(k);
                cum += w;
                acc.par_iter_mut().zip(&term).for_each(|(a, t)| *a += w * t);
            }
            std::mem::swap(p, &mut acc);
        }
    }
}

/// FSP result: moments at each output time and the leak.
#[derive(Debug, Clone)]
pub struct FspSolution {
    pub sizes: Vec<usize>,
    pub moments: Vec<Moments>,
    /// `1 − Σ P` at each output time.
    pub leak: Vec<f64>,
    /// Joint distributions at each output time (species 0 fastest).
    pub joint: Vec<Vec<f64>>,
}

fn check_times(times: &[f64]) -> Result<(), FspError> {
    let ok =
        times.iter().all(|t| t.is_finite() && *t >= 0.0) && times.windows(2).all(|w| w[0] < w[1]);
    if ok {
        Ok(())
    } else {
        Err(FspError::Times(times.to_vec()))
    }
}

/// Solves on the network's own box from its initial point mass.
pub fn solve(network: &Network, p: &[f64], times: &[f64]) -> Result<FspSolution, FspError> {
    let sizes = network
        .species
        .iter()
        .map(|s| s.max.ok_or_else(|| FspError::AutoBox(s.name.clone())))
        .collect::<Result<Vec<_>, _>>()?;
    solve_on(network, p, &sizes, times)
}

/// Solves on the box `sizes`.
pub fn solve_on(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    times: &[f64],
) -> Result<FspSolution, FspError> {
    check_times(times)?;
    let g = Generator::new(network, p, sizes)?;
    let mut prob = vec![0.0; g.states()];
    let mut idx = 0usize;
    let mut stride = 1usize;
    for (s, &m) in network.species.iter().zip(sizes) {
        idx += s.initial.min(m - 1) * stride;
        stride *= m;
    }
    prob[idx] = 1.0;
    let mut now = 0.0;
    let mut out = FspSolution {
        sizes: sizes.to_vec(),
        moments: Vec::new(),
        leak: Vec::new(),
        joint: Vec::new(),
    };
    for &t in times {
        g.advance(&mut prob, t - now);
        now = t;
        let m = Moments::from_joint(t, sizes, &prob);
        out.leak.push((1.0 - m.mass).max(0.0));
        out.moments.push(m);
        out.joint.push(prob.clone());
    }
    Ok(out)
}

/// Solves with automatic boxes for species marked `auto` (and grows any box while the
/// leak at the last time exceeds `max_leak`): sizes start at 32 and double, up to the
/// state limit. Returns the solution and whether the leak target was met.
pub fn solve_auto(
    network: &Network,
    p: &[f64],
    times: &[f64],
    max_leak: f64,
) -> Result<(FspSolution, bool), FspError> {
    let mut sizes: Vec<usize> = network
        .species
        .iter()
        .map(|s| s.max.unwrap_or((s.initial + 1).next_power_of_two().max(32)))
        .collect();
    loop {
        let sol = solve_on(network, p, &sizes, times)?;
        let leak = sol.leak.iter().copied().fold(0.0, f64::max);
        if leak <= max_leak {
            return Ok((sol, true));
        }
        let grown: Vec<usize> = sizes.iter().map(|&m| m * 2).collect();
        if grown
            .iter()
            .try_fold(1usize, |a, &m| a.checked_mul(m))
            .is_none_or(|n| n > MAX_STATES)
        {
            return Ok((sol, false));
        }
        sizes = grown;
    }
}
