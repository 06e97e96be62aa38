//! Data in the network scene: single-cell snapshots loaded over the meta-model, their
//! histograms beside its marginals, the log-likelihood at the sliders' rates (live),
//! the fit that moves the sliders to the maximum, and the posterior of two rates as a
//! density.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use palpa_core::cme::fit::data::Snapshots;
use palpa_core::cme::fit::likelihood::{MetaLikelihood, Observations};
use palpa_core::cme::fit::{self, Estimate, Posterior, Rate, posterior};
use palpa_core::cme::model::CmeModel;

use super::Coordinate;

/// Cells per side of the posterior density.
pub const DENSITY_CELLS: usize = 32;

/// Snapshot data over a room's model.
#[derive(Debug)]
pub struct DataOverlay {
    /// Where it came from (a file name).
    pub source: String,
    pub snapshots: Snapshots,
    /// Network index of each observed species.
    pub columns: Vec<usize>,
    meta: MetaLikelihood,
    scratch: Vec<f64>,
    /// The log-likelihood at the sliders' rates, and its evaluation time, µs.
    pub log_likelihood: Option<f64>,
    pub likelihood_us: f64,
    evaluated_at: Vec<f64>,
    /// The last fit: an estimate per rate (model order), its seconds.
    pub fit: Option<(Vec<Estimate>, f64)>,
    /// The last posterior and the density of its two chosen rates.
    pub posterior: Option<(Posterior, Density)>,
    /// The two rates (model order) whose joint density is drawn.
    pub pair: (usize, usize),
    /// The ranges the posterior was sampled over.
    sampled_over: Vec<Rate>,
}

/// A posterior density of two rates over a grid (first rate fastest), normalized to
/// its largest cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Density {
    pub names: [String; 2],
    pub x: [f64; 2],
    pub y: [f64; 2],
    pub cells: Vec<f32>,
}

impl DataOverlay {
    /// Reads `path` and matches it to `model` (species, box, time range).
    pub fn load(model: &CmeModel, path: &Path) -> anyhow::Result<Self> {
        let snapshots = Snapshots::read(path)?;
        let history = model
            .history()
            .ok_or_else(|| fit::FitError::NotTrain(model.describe()))?;
        let obs = Observations::new(
            &snapshots,
            &model.species_names(),
            &model.box_sizes(),
            model.t_end(),
        )?;
        let meta = MetaLikelihood::new(history, &obs)
            .with_context(|| format!("preparing {}", path.display()))?;
        Ok(DataOverlay {
            source: path.display().to_string(),
            columns: obs.columns.clone(),
            snapshots,
            meta,
            scratch: Vec::new(),
            log_likelihood: None,
            likelihood_us: f64::NAN,
            evaluated_at: Vec::new(),
            fit: None,
            posterior: None,
            pair: (0, 1),
            sampled_over: Vec::new(),
        })
    }

    /// The data time nearest `t` and, for network species `i` when observed, the
    /// fraction of that time's cells at each copy number `0..size`.
    pub fn histogram(&self, t: f64, i: usize, size: usize) -> Option<(f64, Vec<f64>)> {
        let c = self.columns.iter().position(|&x| x == i)?;
        let k = (0..self.snapshots.times.len()).min_by(|&a, &b| {
            (self.snapshots.times[a] - t)
                .abs()
                .total_cmp(&(self.snapshots.times[b] - t).abs())
        })?;
        let cells = &self.snapshots.cells[k];
        let mut h = vec![0.0; size];
        for cell in cells {
            if let Some(v) = h.get_mut(cell[c] as usize) {
                *v += 1.0 / cells.len() as f64;
            }
        }
        Some((self.snapshots.times[k], h))
    }

    /// The log-likelihood at `params` (every model parameter, in order), kept; not
    /// evaluated again while the rates stay (moving time does not change it).
    pub fn evaluate(&mut self, params: &[Coordinate]) {
        let theta: Vec<f64> = params.iter().map(|c| c.value.clamp(c.lo, c.hi)).collect();
        if self.log_likelihood.is_some() && self.evaluated_at == theta {
            return;
        }
        self.evaluated_at = theta.clone();
        let t0 = Instant::now();
        let l = self.meta.log_likelihood(&theta, &mut self.scratch);
        self.likelihood_us = t0.elapsed().as_secs_f64() * 1e6;
        self.log_likelihood = Some(l.value);
    }

    fn rates(params: &[Coordinate]) -> Vec<Rate> {
        params
            .iter()
            .map(|c| Rate {
                name: c.name.clone(),
                lo: c.lo,
                hi: c.hi,
            })
            .collect()
    }

    /// Fits every rate; returns the maximum (model order).
    pub fn fit(&mut self, params: &[Coordinate]) -> Vec<f64> {
        let t0 = Instant::now();
        let (meta, scratch) = (&self.meta, &mut self.scratch);
        let mut f = |x: &[f64]| meta.log_likelihood(x, scratch).value;
        let result = fit::fit(&mut f, &Self::rates(params));
        let mle = result.estimates.iter().map(|e| e.mle).collect();
        self.fit = Some((result.estimates, t0.elapsed().as_secs_f64()));
        mle
    }

    /// Runs the chains (`steps` each, four chains) from a fit and bins the first two
    /// rates' draws into a density.
    pub fn sample(&mut self, params: &[Coordinate], steps: usize, seed: u64) {
        let rates = Self::rates(params);
        let (meta, scratch) = (&self.meta, &mut self.scratch);
        let mut f = |x: &[f64]| meta.log_likelihood(x, scratch).value;
        let result = fit::fit(&mut f, &rates);
        let post = fit::sample(
            &mut f,
            &rates,
            &result,
            posterior::Options {
                chains: 4,
                steps,
                seed,
            },
        );
        let density = density(&post, &rates, self.pair);
        self.posterior = Some((post, density));
        self.sampled_over = rates;
    }

    /// Draws the density of rates `i` and `j` (model order) from the same chains.
    pub fn show_pair(&mut self, i: usize, j: usize) {
        self.pair = (i, j);
        if let Some((post, d)) = &mut self.posterior {
            *d = density(post, &self.sampled_over, (i, j));
        }
    }
}

/// Two rates' draws binned over their 95 % posterior spans widened by half (one rate:
/// along x only).
fn density(post: &Posterior, rates: &[Rate], (a, b): (usize, usize)) -> Density {
    let span = |i: usize| -> [f64; 2] {
        match post.rates.get(i) {
            Some(r) => {
                let w = (r.ci95[1] - r.ci95[0]).max(1e-12);
                [
                    (r.ci95[0] - 0.5 * w).max(rates[i].lo),
                    (r.ci95[1] + 0.5 * w).min(rates[i].hi),
                ]
            }
            None => [0.0, 1.0],
        }
    };
    let (x, y) = (span(a), span(b));
    let n = DENSITY_CELLS;
    let mut cells = vec![0.0f32; n * n];
    let bin = |v: f64, r: [f64; 2]| ((v - r[0]) / (r[1] - r[0]) * n as f64).floor();
    for d in &post.draws {
        let i = d.get(a).map_or(-1.0, |&v| bin(v, x));
        let j = d.get(b).map_or(0.0, |&v| bin(v, y));
        if (0.0..n as f64).contains(&i) && (0.0..n as f64).contains(&j) {
            cells[j as usize * n + i as usize] += 1.0;
        }
    }
    let top = cells.iter().copied().fold(0.0f32, f32::max).max(1.0);
    cells.iter_mut().for_each(|c| *c /= top);
    let name = |i: usize| rates.get(i).map_or(String::new(), |r| r.name.clone());
    Density {
        names: [name(a), name(b)],
        x,
        y,
        cells,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use palpa_core::cme::fit::RatePosterior;

    /// Draws on a line `y = x` in rates 0 and 2 (rate 1 constant): the density of
    /// (0, 2) lies on its diagonal, of (0, 1) on one row.
    #[test]
    fn the_density_shows_the_chosen_pair() {
        let rate = |name: &str| Rate {
            name: name.into(),
            lo: 0.0,
            hi: 1.0,
        };
        let rates = [rate("a"), rate("b"), rate("c")];
        let draws: Vec<Vec<f64>> = (0..1000)
            .map(|k| {
                let x = 0.3 + 0.4 * k as f64 / 1000.0;
                vec![x, 0.5, x]
            })
            .collect();
        let summary = |lo: f64, hi: f64, name: &str| RatePosterior {
            name: name.into(),
            mean: 0.5,
            sd: 0.1,
            ci95: [lo, hi],
            rhat: 1.0,
            ess: 1000.0,
        };
        let post = Posterior {
            chains: 1,
            steps: 1000,
            warmup: 0,
            acceptance: vec![0.3],
            rates: vec![
                summary(0.3, 0.7, "a"),
                summary(0.49, 0.51, "b"),
                summary(0.3, 0.7, "c"),
            ],
            draws,
            evaluations: 1000,
        };
        let n = DENSITY_CELLS;
        let d = density(&post, &rates, (0, 2));
        assert_eq!(d.names, ["a".to_string(), "c".to_string()]);
        for j in 0..n {
            for i in 0..n {
                assert!(
                    i == j || d.cells[j * n + i] == 0.0,
                    "off the diagonal at ({i}, {j})"
                );
            }
        }
        let d = density(&post, &rates, (0, 1));
        let rows: Vec<usize> = (0..n)
            .filter(|&j| (0..n).any(|i| d.cells[j * n + i] > 0.0))
            .collect();
        assert_eq!(rows.len(), 1, "{rows:?}");
    }
}
