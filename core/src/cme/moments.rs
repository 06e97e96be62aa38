//! What a CME solver reports at one time: marginals, means, variances, and the
//! covariance of the first two species (with standard errors for sampled results).

use serde::Serialize;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Moments {
    pub t: f64,
    /// `marginals[i][z]`: probability that species i has z copies (z from 0).
    pub marginals: Vec<Vec<f64>>,
    pub mean: Vec<f64>,
    pub var: Vec<f64>,
    /// Covariance of species 0 and 1 (0 with a single species).
    pub cov01: f64,
    /// Standard errors of `mean` and `var` (sampled results only).
    pub mean_se: Option<Vec<f64>>,
    pub var_se: Option<Vec<f64>>,
    /// Total probability (1 − leak for FSP, 1 for SSA).
    pub mass: f64,
}

impl Moments {
    /// From a joint distribution on a box (`sizes[i]` states per species, species 0
    /// varying fastest).
    pub fn from_joint(t: f64, sizes: &[usize], p: &[f64]) -> Self {
        let d = sizes.len();
        let mut marginals: Vec<Vec<f64>> = sizes.iter().map(|&m| vec![0.0; m]).collect();
        let mut e01 = 0.0;
        let mut z = vec![0usize; d];
        for &pv in p {
            for i in 0..d {
                marginals[i][z[i]] += pv;
            }
            if d >= 2 {
                e01 += pv * z[0] as f64 * z[1] as f64;
            }
            for i in 0..d {
                z[i] += 1;
                if z[i] < sizes[i] {
                    break;
                }
                z[i] = 0;
            }
        }
        let mass: f64 = p.iter().sum();
        Self::from_marginals(t, marginals, e01, mass)
    }

    /// From the marginals, `E[z_0 z_1]` (unnormalized) and the total mass; means and
    /// variances are those of the distribution renormalized to mass 1. Each species'
    /// weigh its marginal divided by the marginal's own sum (the mass, up to the order
    /// the sums were added in), so a species held at one count has exactly that mean
    /// and variance 0 (`q/q` is 1 exactly, where `z q / q` may miss `z` by a unit in
    /// the last place).
    pub fn from_marginals(t: f64, marginals: Vec<Vec<f64>>, e01: f64, mass: f64) -> Self {
        let d = marginals.len();
        let own = |m: &[f64]| m.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        let mean: Vec<f64> = marginals
            .iter()
            .map(|m| {
                let s = own(m);
                m.iter()
                    .enumerate()
                    .map(|(z, &q)| z as f64 * (q / s))
                    .sum::<f64>()
            })
            .collect();
        let var = marginals
            .iter()
            .zip(&mean)
            .map(|(m, &mu)| {
                let s = own(m);
                m.iter()
                    .enumerate()
                    .map(|(z, &q)| (z as f64 - mu).powi(2) * (q / s))
                    .sum::<f64>()
            })
            .collect();
        let cov01 = if d >= 2 {
            e01 / mass.max(f64::MIN_POSITIVE) - mean[0] * mean[1]
        } else {
            0.0
        };
        Moments {
            t,
            marginals,
            mean,
            var,
            cov01,
            mean_se: None,
            var_se: None,
            mass,
        }
    }

    /// From samples `states[k][i]` (trajectory k, species i).
    pub fn from_samples(t: f64, states: &[Vec<i64>]) -> Self {
        let k = states.len().max(1) as f64;
        let d = states.first().map_or(0, Vec::len);
        let mut marginals = vec![Vec::new(); d];
        for s in states {
            for i in 0..d {
                let z = s[i].max(0) as usize;
                if marginals[i].len() <= z {
                    marginals[i].resize(z + 1, 0.0);
                }
                marginals[i][z] += 1.0 / k;
            }
        }
        let mean: Vec<f64> = (0..d)
            .map(|i| states.iter().map(|s| s[i] as f64).sum::<f64>() / k)
            .collect();
        let var: Vec<f64> = (0..d)
            .map(|i| {
                states
                    .iter()
                    .map(|s| (s[i] as f64 - mean[i]).powi(2))
                    .sum::<f64>()
                    / (k - 1.0).max(1.0)
            })
            .collect();
        let m4: Vec<f64> = (0..d)
            .map(|i| {
                states
                    .iter()
                    .map(|s| (s[i] as f64 - mean[i]).powi(4))
                    .sum::<f64>()
                    / k
            })
            .collect();
        let cov01 = if d >= 2 {
            states
                .iter()
                .map(|s| (s[0] as f64 - mean[0]) * (s[1] as f64 - mean[1]))
                .sum::<f64>()
                / (k - 1.0).max(1.0)
        } else {
            0.0
        };
        Moments {
            t,
            marginals,
            mean_se: Some(var.iter().map(|v| (v / k).sqrt()).collect()),
            // SE of the sample variance: sqrt((m4 − σ⁴ (k−3)/(k−1)) / k).
            var_se: Some(
                var.iter()
                    .zip(&m4)
                    .map(|(v, m)| ((m - v * v * (k - 3.0) / (k - 1.0)).max(0.0) / k).sqrt())
                    .collect(),
            ),
            mean,
            var,
            cov01,
            mass: 1.0,
        }
    }
}

/// L1 distance between two probability vectors (missing entries count as 0).
pub fn l1(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(b.len());
    (0..n)
        .map(|i| (a.get(i).copied().unwrap_or(0.0) - b.get(i).copied().unwrap_or(0.0)).abs())
        .sum()
}
