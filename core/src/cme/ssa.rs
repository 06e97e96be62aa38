//! Gillespie's direct method: exact sample paths of the CME, no box.
//!
//! Each trajectory draws the waiting time `τ ~ Exp(a₀)` with `a₀ = Σ_r a_r(z)` and the
//! reaction with probability `a_r/a₀`, and records its state at the output times.
//! Trajectory `k` uses the generator seeded with `(seed, k)`, so results do not depend
//! on how rayon schedules them. Moments carry standard errors; a marginal's L1 error
//! from K samples is about `√(m/K)` for m occupied states, which is why SSA needs many
//! trajectories where FSP or PGD give the distribution at once.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::moments::Moments;
use super::network::Network;
use crate::rng::Rng;

/// A bound on reactions per trajectory, so a runaway network cannot hang a run.
pub const MAX_EVENTS: u64 = 200_000_000;

/// A bound on reactions over a whole run (all trajectories; about 80 s on two cores,
/// measured on the toggle switch): rates so large that every path hits [`MAX_EVENTS`]
/// would otherwise take `trajectories × MAX_EVENTS` reactions (10 000 paths: days)
/// before saying so.
pub const MAX_RUN_EVENTS: u64 = 2_000_000_000;

/// Events a trajectory simulates between updates of the run's shared count.
const EVENT_BATCH: u64 = 4_096;

/// SSA result: moments at each output time, and the events simulated.
#[derive(Debug, Clone)]
pub struct SsaSolution {
    pub moments: Vec<Moments>,
    pub trajectories: usize,
    pub events: u64,
    /// Trajectories stopped by [`MAX_EVENTS`] or [`MAX_RUN_EVENTS`] (their later
    /// states are the last reached).
    pub truncated: usize,
    /// A propensity that overflowed, said (the paths stopped there).
    pub overflow: Option<String>,
}

/// Simulates `trajectories` paths with parameter values `p`, recording at `times`
/// (finite, ≥ 0, increasing: checked by the caller's front end).
pub fn simulate(
    network: &Network,
    p: &[f64],
    times: &[f64],
    trajectories: usize,
    seed: u64,
) -> SsaSolution {
    simulate_within(network, p, times, trajectories, seed, MAX_RUN_EVENTS)
}

/// As [`simulate`], with `max_run_events` in place of [`MAX_RUN_EVENTS`] (a run
/// stops every path soon after that many reactions in all; the budget is shared in
/// batches of 4 096, so it may run over by a batch a path).
pub fn simulate_within(
    network: &Network,
    p: &[f64],
    times: &[f64],
    trajectories: usize,
    seed: u64,
    max_run_events: u64,
) -> SsaSolution {
    let paths = paths(network, p, times, trajectories, seed, max_run_events);
    let moments = times
        .iter()
        .enumerate()
        .map(|(j, &t)| {
            let states: Vec<Vec<i64>> = paths.states.iter().map(|s| s[j].clone()).collect();
            Moments::from_samples(t, &states)
        })
        .collect();
    SsaSolution {
        moments,
        trajectories,
        events: paths.events,
        truncated: paths.truncated,
        overflow: paths.overflow,
    }
}

/// Sample paths' states at the output times.
#[derive(Debug, Clone)]
pub struct Paths {
    /// `states[k][j]`: trajectory `k`'s copy numbers at `times[j]`.
    pub states: Vec<Vec<Vec<i64>>>,
    pub events: u64,
    /// Trajectories stopped by the event bounds (their later states are the last
    /// reached).
    pub truncated: usize,
    /// The first propensity that overflowed (its path stopped there), said.
    pub overflow: Option<String>,
}

/// The states of `trajectories` paths at `times`, as [`simulate_within`] draws them.
pub fn paths(
    network: &Network,
    p: &[f64],
    times: &[f64],
    trajectories: usize,
    seed: u64,
    max_run_events: u64,
) -> Paths {
    let d = network.species.len();
    let run_events = AtomicU64::new(0);
    // Each path: its states, events, whether it stopped early, an overflow said.
    type Path = (Vec<Vec<i64>>, u64, bool, Option<String>);
    let results: Vec<Path> = (0..trajectories)
        .into_par_iter()
        .map(|k| {
            crate::cpu::clear_upper_halves();
            let mut rng = Rng::seed(seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut z: Vec<i64> = network.species.iter().map(|s| s.initial as i64).collect();
            let mut a = vec![0.0; network.reactions.len()];
            let mut t = 0.0;
            let mut out = Vec::with_capacity(times.len());
            let mut events = 0u64;
            let mut stopped = false;
            let mut overflow = None;
            for &t_out in times {
                loop {
                    let mut a0 = 0.0;
                    for (r, ar) in a.iter_mut().enumerate() {
                        *ar = network.propensity(r, &z, p);
                        if !ar.is_finite() && overflow.is_none() {
                            overflow = Some(network.overflow_message(r, &z, *ar));
                            stopped = true;
                        }
                        a0 += *ar;
                    }
                    if a0 <= 0.0 || stopped {
                        break;
                    }
                    let tau = -(1.0 - rng.uniform()).ln() / a0;
                    if t + tau > t_out {
                        // Memoryless: the next event is redrawn from t_out on.
                        break;
                    }
                    t += tau;
                    let mut u = rng.uniform() * a0;
                    let mut r = 0;
                    while r + 1 < a.len() && u >= a[r] {
                        u -= a[r];
                        r += 1;
                    }
                    for i in 0..d {
                        z[i] += i64::from(network.reactions[r].change[i]);
                    }
                    events += 1;
                    if events >= MAX_EVENTS {
                        stopped = true;
                    }
                    if events.is_multiple_of(EVENT_BATCH)
                        && run_events.fetch_add(EVENT_BATCH, Ordering::Relaxed) + EVENT_BATCH
                            >= max_run_events
                    {
                        stopped = true;
                    }
                }
                t = t_out;
                out.push(z.clone());
            }
            (out, events, stopped, overflow)
        })
        .collect();
    let events = results.iter().map(|r| r.1).sum();
    let truncated = results.iter().filter(|r| r.2).count();
    let overflow = results.iter().find_map(|r| r.3.clone());
    Paths {
        states: results.into_iter().map(|r| r.0).collect(),
        events,
        truncated,
        overflow,
    }
}
