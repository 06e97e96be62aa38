//! The checks beside the meta-model, at the room's current coordinates, as background
//! [`Job`]s that never block a frame:
//!
//! - **exact**: FSP on the model's box, advanced in 40 slices of time (uniformization is
//!   exact slice by slice), so it reports progress and stops within a slice of a cancel;
//! - **sampled**: K SSA trajectories in 20 seeded batches, each batch's histograms
//!   merged (equal batches: their average), cancelled between batches.

use std::time::Instant;

use anyhow::Context;
use palpa_core::cme::fsp::{Generator, Settling};
use palpa_core::cme::network::Network;
use palpa_core::cme::ssa;

use super::job::Job;

/// Slices the time interval is advanced in (progress and cancel granularity).
const SLICES: usize = 40;
/// Batches of SSA trajectories.
const BATCHES: usize = 20;

/// The exact joint at some coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Exact {
    /// Time, then parameters, as the room orders them.
    pub coordinates: Vec<f64>,
    /// Species 0 fastest, on the model's box.
    pub joint: Vec<f64>,
    pub seconds: f64,
}

/// Sampled marginals at some coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampled {
    pub coordinates: Vec<f64>,
    /// Per species, the histogram over copy numbers (as probabilities).
    pub marginals: Vec<Vec<f64>>,
    pub trajectories: usize,
    pub seconds: f64,
}

/// Starts FSP of `network` with parameter values `p` on the box `sizes`, to time `t`;
/// `coordinates` label the result.
pub fn start_exact(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    t: f64,
    coordinates: Vec<f64>,
) -> anyhow::Result<Job<Exact>> {
    let generator = Generator::new(network, p, sizes).context("the exact check")?;
    let mut start = 0usize;
    let mut stride = 1usize;
    for (s, &m) in network.species.iter().zip(sizes) {
        start += s.initial.min(m - 1) * stride;
        stride *= m;
    }
    Job::start("palpa-exact-check", move |ctx| {
        let t0 = Instant::now();
        let mut prob = vec![0.0; generator.states()];
        prob[start] = 1.0;
        let dt = t.max(0.0) / SLICES as f64;
        // Kept across slices: once the law settles, the rest of a long time is free.
        let mut settling = Settling::default();
        for k in 0..SLICES {
            if ctx.cancelled() {
                return Err("cancelled".into());
            }
            if dt > 0.0 {
                generator.advance_settling(&mut prob, dt, &mut settling);
            }
            ctx.progress((k + 1) as f64 / SLICES as f64);
        }
        if prob.iter().any(|v| !v.is_finite()) {
            return Err("the exact solve diverged".into());
        }
        Ok(Exact {
            coordinates,
            joint: prob,
            seconds: t0.elapsed().as_secs_f64(),
        })
    })
}

/// Starts `trajectories` SSA paths (seeded) of `network` with parameter values `p` to
/// time `t`, histogrammed on boxes of `sizes` (copy numbers beyond a box go to its last
/// bin, as the model's box would hold them).
pub fn start_sampled(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    t: f64,
    coordinates: Vec<f64>,
    trajectories: usize,
    seed: u64,
) -> anyhow::Result<Job<Sampled>> {
    let (network, p, sizes) = (network.clone(), p.to_vec(), sizes.to_vec());
    Job::start("palpa-ssa-check", move |ctx| {
        let t0 = Instant::now();
        let per = trajectories.div_ceil(BATCHES).max(1);
        let mut sums: Vec<Vec<f64>> = sizes.iter().map(|&m| vec![0.0; m]).collect();
        let mut done = 0usize;
        for b in 0..BATCHES {
            if ctx.cancelled() {
                return Err("cancelled".into());
            }
            let n = per.min(trajectories - done);
            if n == 0 {
                break;
            }
            let sol = ssa::simulate(&network, &p, &[t.max(0.0)], n, seed ^ (b as u64 + 1));
            if let Some(why) = sol.overflow {
                return Err(why);
            }
            let m = &sol.moments[0];
            for (sum, (marginal, &size)) in sums.iter_mut().zip(m.marginals.iter().zip(&sizes)) {
                for (z, &q) in marginal.iter().enumerate() {
                    sum[z.min(size - 1)] += q * n as f64;
                }
            }
            done += n;
            ctx.progress(done as f64 / trajectories as f64);
        }
        let marginals = sums
            .into_iter()
            .map(|s| s.into_iter().map(|v| v / done.max(1) as f64).collect())
            .collect();
        Ok(Sampled {
            coordinates,
            marginals,
            trajectories: done,
            seconds: t0.elapsed().as_secs_f64(),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::super::job::JobState;
    use super::*;
    use std::time::Duration;

    fn toggle() -> (Network, Vec<f64>, Vec<usize>) {
        let n = Network::built_in("toggle").expect("built in");
        let p: Vec<f64> = n.parameters.iter().map(|q| q.value).collect();
        let sizes = n
            .species
            .iter()
            .map(|s| s.max.expect("box"))
            .collect::<Vec<_>>();
        (n, p, sizes)
    }

    fn wait<T: Clone + Send + 'static>(job: &mut Job<T>) -> JobState<T> {
        let t0 = Instant::now();
        while matches!(job.poll(), JobState::Running { .. })
            && t0.elapsed() < Duration::from_secs(60)
        {
            std::thread::sleep(Duration::from_millis(2));
        }
        job.state.clone()
    }

    /// A check runs to the end off the caller's thread and returns a probability
    /// distribution labelled with its coordinates.
    #[test]
    fn an_exact_check_finishes_with_a_distribution() {
        let (n, p, sizes) = toggle();
        let mut c = start_exact(&n, &p, &sizes, 1.0, vec![1.0]).expect("starts");
        let JobState::Done(exact) = wait(&mut c) else {
            panic!("finished: {:?}", c.state);
        };
        assert_eq!(exact.coordinates, vec![1.0]);
        let mass: f64 = exact.joint.iter().sum();
        assert!((mass - 1.0).abs() < 1e-6, "{mass}");
        assert!(c.finished());
    }

    /// Sampled marginals are distributions, close to the exact ones at the sampling
    /// noise, and the same for the same seed.
    #[test]
    fn a_sampled_check_approaches_the_exact_marginals() {
        let (n, p, sizes) = toggle();
        let mut e = start_exact(&n, &p, &sizes, 2.0, vec![2.0]).expect("starts");
        let JobState::Done(exact) = wait(&mut e) else {
            panic!("exact: {:?}", e.state);
        };
        let marg0: Vec<f64> = (0..sizes[0])
            .map(|a| (0..sizes[1]).map(|b| exact.joint[b * sizes[0] + a]).sum())
            .collect();
        let run = || {
            let mut s = start_sampled(&n, &p, &sizes, 2.0, vec![2.0], 4000, 7).expect("starts");
            let JobState::Done(sampled) = wait(&mut s) else {
                panic!("sampled: {:?}", s.state);
            };
            sampled
        };
        let (a, b) = (run(), run());
        assert_eq!(a.marginals, b.marginals, "seeded");
        assert_eq!(a.trajectories, 4000);
        let total: f64 = a.marginals[0].iter().sum();
        assert!((total - 1.0).abs() < 1e-9);
        let l1 = palpa_core::cme::moments::l1(&a.marginals[0], &marg0);
        // Sampling noise: about √(bins / K) ≈ 0.1 for a dozen occupied bins.
        assert!(l1 < 0.15, "L1 {l1}");
    }

    /// Cancelling marks the check at once and its thread ends within a slice.
    #[test]
    fn a_cancelled_check_stops() {
        let (n, p, sizes) = toggle();
        let mut c = start_exact(&n, &p, &sizes, 1e5, vec![1e5]).expect("starts");
        c.cancel();
        assert_eq!(c.state, JobState::Cancelled);
        assert_eq!(*c.poll(), JobState::Cancelled);
        assert!(c.finished(), "the thread is let go");
        let t0 = Instant::now();
        while c.thread_alive() && t0.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(!c.thread_alive(), "the thread ended");
    }
}
