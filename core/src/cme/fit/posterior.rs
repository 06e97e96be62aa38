//! The posterior of the rates by random-walk Metropolis–Hastings, with convergence
//! diagnostics.
//!
//! The prior is uniform on the model's range (the box the meta-model answers in); the
//! chains walk the scaled coordinates with a Gaussian proposal `N(0, (2.38²/d) Σ)`,
//! `Σ` the Fisher covariance where there is one (the optimal scaling for a Gaussian
//! target), else a diagonal of 0.05². Each chain starts at the maximum moved by a
//! draw of twice the proposal (over-dispersed, as R-hat needs), and its first quarter
//! is warm-up, discarded.
//!
//! **R-hat** is the split-chain potential scale reduction (Gelman et al., BDA3 §11.4):
//! each kept chain halved, `√(((n−1)/n · W + B/n) / W)`. **Effective sample size**:
//! `m n / (1 + 2 Σ ρ_t)` with the autocorrelations `ρ_t = 1 − (W − mean_c γ_t,c) / V⁺`
//! pooled over chains and summed in pairs while the pairs stay positive (Geyer's
//! initial positive sequence).

use super::optimize::Objective;
use crate::rng::Rng;

/// What a posterior run is asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub chains: usize,
    /// Steps per chain, warm-up included.
    pub steps: usize,
    pub seed: u64,
}

/// One rate's posterior summary (scaled units; the caller maps them to rates).
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    pub mean: f64,
    pub sd: f64,
    /// The 2.5 % and 97.5 % quantiles.
    pub ci95: [f64; 2],
    pub rhat: f64,
    pub ess: f64,
}

/// Chains' draws after warm-up and their diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct Chains {
    pub warmup: usize,
    /// Acceptance rate of each chain (after warm-up).
    pub acceptance: Vec<f64>,
    /// `draws[c]`: chain `c`'s kept states (scaled units).
    pub draws: Vec<Vec<Vec<f64>>>,
    pub summaries: Vec<Summary>,
    pub evaluations: usize,
}

/// Runs the chains on `f` (log-likelihood in scaled units) from the maximum `u_hat`.
pub fn sample(f: &mut Objective<'_>, u_hat: &[f64], cov: Option<&[f64]>, o: Options) -> Chains {
    let d = u_hat.len();
    // Proposal factor: Cholesky of (2.38²/d) Σ.
    let base: Vec<f64> = match cov {
        Some(c) => c.to_vec(),
        None => (0..d * d)
            .map(|k| if k % (d + 1) == 0 { 0.05 * 0.05 } else { 0.0 })
            .collect(),
    };
    let scale = 2.38 * 2.38 / d.max(1) as f64;
    let chol = cholesky(&base.iter().map(|x| x * scale).collect::<Vec<_>>(), d);
    let step = |rng: &mut Rng, spread: f64| -> Vec<f64> {
        let z: Vec<f64> = (0..d).map(|_| rng.normal()).collect();
        (0..d)
            .map(|i| spread * (0..=i).map(|k| chol[i * d + k] * z[k]).sum::<f64>())
            .collect()
    };
    let warmup = o.steps / 4;
    let mut evaluations = 0;
    let mut draws = Vec::with_capacity(o.chains);
    let mut acceptance = Vec::with_capacity(o.chains);
    for c in 0..o.chains {
        let mut rng = Rng::seed(o.seed ^ (c as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut x: Vec<f64> = u_hat
            .iter()
            .zip(step(&mut rng, 2.0))
            .map(|(u, s)| (u + s).clamp(0.0, 1.0))
            .collect();
        let mut fx = f(&x);
        evaluations += 1;
        let (mut kept, mut accepted) = (Vec::with_capacity(o.steps - warmup), 0usize);
        for s in 0..o.steps {
            let y: Vec<f64> = x
                .iter()
                .zip(step(&mut rng, 1.0))
                .map(|(a, b)| a + b)
                .collect();
            // Outside the range the uniform prior is zero: rejected without a call.
            if y.iter().all(|v| (0.0..=1.0).contains(v)) {
                let fy = f(&y);
                evaluations += 1;
                if fy - fx >= (1.0 - rng.uniform()).ln() {
                    (x, fx) = (y, fy);
                    if s >= warmup {
                        accepted += 1;
                    }
                }
            }
            if s >= warmup {
                kept.push(x.clone());
            }
        }
        acceptance.push(accepted as f64 / kept.len().max(1) as f64);
        draws.push(kept);
    }
    let summaries = (0..d).map(|i| summarize(&draws, i)).collect();
    Chains {
        warmup,
        acceptance,
        draws,
        summaries,
        evaluations,
    }
}

fn cholesky(a: &[f64], d: usize) -> Vec<f64> {
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            let s = a[i * d + j] - (0..j).map(|k| l[i * d + k] * l[j * d + k]).sum::<f64>();
            l[i * d + j] = if i == j {
                s.max(1e-12).sqrt()
            } else {
                s / l[j * d + j]
            };
        }
    }
    l
}

fn mean_var(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    (
        m,
        x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0),
    )
}

/// Mean, spread, quantiles, split R-hat and ESS of coordinate `i` over all chains.
pub fn summarize(draws: &[Vec<Vec<f64>>], i: usize) -> Summary {
    let chains: Vec<Vec<f64>> = draws
        .iter()
        .map(|c| c.iter().map(|x| x[i]).collect())
        .collect();
    let mut all: Vec<f64> = chains.concat();
    let (mean, var) = mean_var(&all);
    all.sort_by(f64::total_cmp);
    let q = |p: f64| all[((p * (all.len() - 1) as f64).round() as usize).min(all.len() - 1)];
    Summary {
        mean,
        sd: var.sqrt(),
        ci95: [q(0.025), q(0.975)],
        rhat: split_rhat(&chains),
        ess: ess(&chains),
    }
}

/// B and W of equal-length chains.
fn between_within(chains: &[&[f64]]) -> (f64, f64, f64) {
    let n = chains[0].len() as f64;
    let stats: Vec<(f64, f64)> = chains.iter().map(|c| mean_var(c)).collect();
    let w = stats.iter().map(|s| s.1).sum::<f64>() / stats.len() as f64;
    let means: Vec<f64> = stats.iter().map(|s| s.0).collect();
    let b = n * mean_var(&means).1;
    (n, b, w)
}

/// Split-chain R-hat.
pub fn split_rhat(chains: &[Vec<f64>]) -> f64 {
    let half = chains.iter().map(Vec::len).min().unwrap_or(0) / 2;
    if half < 2 {
        return f64::NAN;
    }
    let halves: Vec<&[f64]> = chains
        .iter()
        .flat_map(|c| [&c[..half], &c[half..2 * half]])
        .collect();
    let (n, b, w) = between_within(&halves);
    if w <= 0.0 {
        return if b <= 0.0 { 1.0 } else { f64::INFINITY };
    }
    (((n - 1.0) / n * w + b / n) / w).sqrt()
}

/// Effective sample size over all chains (see the module doc).
pub fn ess(chains: &[Vec<f64>]) -> f64 {
    let n = chains.iter().map(Vec::len).min().unwrap_or(0);
    if n < 4 {
        return f64::NAN;
    }
    let cs: Vec<&[f64]> = chains.iter().map(|c| &c[..n]).collect();
    let (nf, b, w) = between_within(&cs);
    let var_plus = (nf - 1.0) / nf * w + b / nf;
    if var_plus <= 0.0 {
        return (cs.len() * n) as f64;
    }
    let stats: Vec<(f64, f64)> = cs.iter().map(|c| mean_var(c)).collect();
    let autocov = |t: usize| -> f64 {
        cs.iter()
            .zip(&stats)
            .map(|(c, (m, _))| {
                (0..n - t).map(|k| (c[k] - m) * (c[k + t] - m)).sum::<f64>() / n as f64
            })
            .sum::<f64>()
            / cs.len() as f64
    };
    let rho = |t: usize| 1.0 - (w - autocov(t)) / var_plus;
    let mut sum = 0.0;
    let mut t = 1;
    while t + 1 < n {
        let pair = rho(t) + rho(t + 1);
        if pair <= 0.0 {
            break;
        }
        sum += pair;
        t += 2;
    }
    (cs.len() * n) as f64 / (1.0 + 2.0 * sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_on_a_gaussian_recover_its_mean_and_spread_and_mix() {
        let (m, s) = ([0.4, 0.6], [0.03, 0.05]);
        let mut f =
            |u: &[f64]| -0.5 * (((u[0] - m[0]) / s[0]).powi(2) + ((u[1] - m[1]) / s[1]).powi(2));
        let cov = [s[0] * s[0], 0.0, 0.0, s[1] * s[1]];
        let o = Options {
            chains: 4,
            steps: 8_000,
            seed: 7,
        };
        let c = sample(&mut f, &m, Some(&cov), o);
        for (i, sum) in c.summaries.iter().enumerate() {
            // 24 000 draws, ESS a few thousand: the mean to a few percent of σ.
            assert!((sum.mean - m[i]).abs() < 0.1 * s[i], "{sum:?}");
            assert!((sum.sd / s[i] - 1.0).abs() < 0.1, "{sum:?}");
            assert!(sum.rhat < 1.01, "{sum:?}");
            assert!(sum.ess > 1_000.0, "{sum:?}");
        }
        // The optimal acceptance for a 2-d Gaussian with this scaling is about 0.35.
        assert!(
            c.acceptance.iter().all(|a| (0.25..0.5).contains(a)),
            "{:?}",
            c.acceptance
        );
        // Chains stuck apart show in R-hat.
        let stuck = [vec![0.1; 100], vec![0.9; 100]];
        let jitter: Vec<Vec<f64>> = stuck
            .iter()
            .map(|c| {
                c.iter()
                    .enumerate()
                    .map(|(k, x)| x + 1e-3 * (k % 7) as f64)
                    .collect()
            })
            .collect();
        assert!(split_rhat(&jitter) > 10.0);
    }
}
