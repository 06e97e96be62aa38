//! What a solver must know of a network before it starts: a box for every species and
//! the fastest rate at the start.
//!
//! **Boxes.** A species given as `max = "auto"` (every SBML species) gets the box that
//! exact FSP needs to lose less than [`PREPASS_LEAK`] of the probability by `t_end`,
//! at the parameters' values and, for range parameters, at every corner of their
//! ranges (the leak only grows with time, so checking `t_end` covers `[0, t_end]`).
//! FSP's automatic boxes grow only the species whose top band leaks
//! ([`super::fsp::solve_auto`]). Where FSP refuses the box (over 10⁷ states), the
//! boxes come from [`PREPASS_TRAJECTORIES`] seeded SSA paths instead: twice the largest
//! count seen plus 16, rounded up to a power of two (a rule, not a bound: the PGD's
//! mass check and an exact check in the app are what show whether it held).
//!
//! **First step.** A BDF2 start with `h · a₀ ≫ 1`, where `a₀` is the total propensity
//! at the initial state, steps over the first events and leaves negative
//! probabilities (an immigration at rate 1000 with `h = 0.01` gave −2.6e-3); the first
//! step is cut to `0.1 / a₀` (largest over the parameter corners).

use thiserror::Error;

use super::fsp::{self, FspError};
use super::network::Network;
use super::ssa;

/// The leak the box pre-pass allows by `t_end`.
pub const PREPASS_LEAK: f64 = 1e-9;
/// SSA paths of the fallback pre-pass.
pub const PREPASS_TRAJECTORIES: usize = 1000;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum SizingError {
    #[error("sizing the automatic boxes: {0}")]
    Fsp(#[from] FspError),
    #[error("sizing the automatic boxes: t_end = {0}: expected a finite end time > 0")]
    TEnd(f64),
    #[error("{0}")]
    Overflow(String),
}

/// How the boxes were found.
#[derive(Debug, Clone, PartialEq)]
pub enum Sized {
    /// Every species had a box.
    Given,
    /// Exact FSP with the leak at `t_end` (largest over the corners).
    Fsp { leak: f64 },
    /// SSA paths (FSP refused the box).
    Ssa { trajectories: usize },
}

/// The parameter values a sizing looks at: the values, and every corner of the range
/// parameters' ranges (at most 2⁴; beyond, each range's ends one at a time).
pub fn parameter_corners(network: &Network) -> Vec<Vec<f64>> {
    let base: Vec<f64> = network.parameters.iter().map(|p| p.value).collect();
    let ranged: Vec<(usize, f64, f64)> = network
        .parameters
        .iter()
        .enumerate()
        .filter_map(|(q, p)| p.range.map(|(lo, hi, _)| (q, lo, hi)))
        .collect();
    let mut out = vec![base.clone()];
    if ranged.len() <= 4 {
        for mask in 0..1usize << ranged.len() {
            let mut p = base.clone();
            for (b, &(q, lo, hi)) in ranged.iter().enumerate() {
                p[q] = if mask >> b & 1 == 1 { hi } else { lo };
            }
            out.push(p);
        }
    } else {
        for &(q, lo, hi) in &ranged {
            for v in [lo, hi] {
                let mut p = base.clone();
                p[q] = v;
                out.push(p);
            }
        }
    }
    out
}

/// `network` with a box for every species (see the module doc), and how they were
/// found.
pub fn with_boxes(network: &Network, t_end: f64) -> Result<(Network, Sized), SizingError> {
    let (sized, how) = boxes(network, t_end)?;
    // A separated solver multiplies each species' factors over its whole box: a rate
    // that overflows there would make NaN (or a zero first step) deep inside it.
    let sizes: Vec<usize> = sized.species.iter().map(|s| s.max.unwrap_or(1)).collect();
    for p in parameter_corners(&sized) {
        if let Some(why) = sized.overflow_on_box(&p, &sizes) {
            return Err(SizingError::Overflow(why));
        }
    }
    Ok((sized, how))
}

fn boxes(network: &Network, t_end: f64) -> Result<(Network, Sized), SizingError> {
    if network.species.iter().all(|s| s.max.is_some()) {
        return Ok((network.clone(), Sized::Given));
    }
    if !(t_end.is_finite() && t_end > 0.0) {
        return Err(SizingError::TEnd(t_end));
    }
    let mut sizes = vec![2usize; network.species.len()];
    let mut leak: f64 = 0.0;
    let mut how = Sized::Fsp { leak: 0.0 };
    for p in parameter_corners(network) {
        match fsp::solve_auto(network, &p, &[t_end], PREPASS_LEAK) {
            Ok((sol, _)) => {
                leak = leak.max(sol.leak.iter().copied().fold(0.0, f64::max));
                for (s, m) in sizes.iter_mut().zip(&sol.sizes) {
                    *s = (*s).max(*m);
                }
            }
            Err(FspError::TooLarge { .. }) => {
                how = Sized::Ssa {
                    trajectories: PREPASS_TRAJECTORIES,
                };
                let times: Vec<f64> = (1..=32).map(|k| t_end * k as f64 / 32.0).collect();
                let sol = ssa::simulate(network, &p, &times, PREPASS_TRAJECTORIES, 1);
                for m in &sol.moments {
                    for (s, marginal) in sizes.iter_mut().zip(&m.marginals) {
                        let top = marginal.iter().rposition(|&q| q > 0.0).unwrap_or(0);
                        *s = (*s).max((2 * top + 16).next_power_of_two());
                    }
                }
            }
            Err(e) => return Err(e.into()),
        }
    }
    if let Sized::Fsp { leak: l } = &mut how {
        *l = leak;
    }
    let mut out = network.clone();
    for (s, &m) in out.species.iter_mut().zip(&sizes) {
        if s.max.is_none() {
            s.max = Some(m.max(s.initial + 1).max(2));
        }
    }
    Ok((out, how))
}

/// The first time step for `network`: `h_default`, cut to `0.1 / a₀` where `a₀` is the
/// largest total propensity at the initial state over the parameter corners.
pub fn first_step(network: &Network, h_default: f64) -> f64 {
    let z: Vec<i64> = network.species.iter().map(|s| s.initial as i64).collect();
    let a0 = parameter_corners(network)
        .iter()
        .map(|p| {
            (0..network.reactions.len())
                .map(|r| network.propensity(r, &z, p))
                .sum::<f64>()
        })
        .fold(0.0, f64::max);
    if a0 > 0.0 {
        h_default.min(0.1 / a0)
    } else {
        h_default
    }
}
