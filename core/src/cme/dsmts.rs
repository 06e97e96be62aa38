//! The Discrete Stochastic Model Test Suite's cases: reading one, and its pass criteria.
//!
//! A case folder `NNNNN/` (the SBML Test Suite's layout) holds the model as SBML, the
//! expected mean and standard deviation of each output species at `t = 0, 1, …, 50`
//! (`NNNNN-results.csv`) and the settings (`NNNNN-settings.txt`).
//!
//! The suite's test of a stochastic simulator with `n` trajectories, at every output
//! time: `Z = √n (X̄ − μ)/σ` within `(−3, 3)` and `Y = √(n/2) (S²/σ² − 1)` within
//! `(−5, 5)` (the settings' `meanRange` and `sdRange`), where `μ, σ` are the expected
//! values and `X̄, S²` the sample mean and variance. Where `σ = 0` the sample must be
//! exact. The tests are statistical: the suite's guide expects a correct simulator with
//! `n = 10⁴` to fail about 2–3 mean tests and 5–6 sd tests over the whole suite (all
//! models, all times), more for the sd because its normal approximation ignores the
//! kurtosis of bursty models. [`SUITE_MEAN_FAILS`] and [`SUITE_SD_FAILS`] are those
//! allowances, for the suite's total.

use std::path::{Path, PathBuf};

use super::network::{Network, NetworkError};

/// Mean tests a correct simulator may fail over the whole suite at `n = 10⁴`.
pub const SUITE_MEAN_FAILS: usize = 3;
/// Standard-deviation tests a correct simulator may fail over the whole suite.
pub const SUITE_SD_FAILS: usize = 6;

/// One DSMTS case.
#[derive(Debug, Clone)]
pub struct Case {
    /// The folder's name, e.g. `00001`.
    pub id: String,
    pub dir: PathBuf,
    /// The output species.
    pub variables: Vec<String>,
    pub times: Vec<f64>,
    /// `mean[v][t]`, `sd[v][t]`.
    pub mean: Vec<Vec<f64>>,
    pub sd: Vec<Vec<f64>>,
    pub mean_range: (f64, f64),
    pub sd_range: (f64, f64),
}

/// Why a case could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CaseError {
    #[error("{0}: {1}")]
    Io(PathBuf, std::io::Error),
    #[error("{0}: {1}")]
    Format(PathBuf, String),
}

impl Case {
    /// Reads the settings and expected results of the case in `dir`.
    pub fn load(dir: &Path) -> Result<Case, CaseError> {
        let id = dir
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let read = |name: String| {
            let p = dir.join(name);
            std::fs::read_to_string(&p).map_err(|e| CaseError::Io(p, e))
        };
        let settings_path = dir.join(format!("{id}-settings.txt"));
        let settings = read(format!("{id}-settings.txt"))?;
        let field = |key: &str| {
            settings
                .lines()
                .find_map(|l| l.strip_prefix(key).map(|v| v.trim().to_string()))
                .unwrap_or_default()
        };
        let bad = |what: String| CaseError::Format(settings_path.clone(), what);
        let range = |key: &str| -> Result<(f64, f64), CaseError> {
            let v = field(key);
            let inner = v.trim_start_matches('(').trim_end_matches(')');
            let (a, b) = inner
                .split_once(',')
                .ok_or_else(|| bad(format!("{key} {v:?}: expected (lo, hi)")))?;
            let num = |s: &str| {
                s.trim()
                    .parse::<f64>()
                    .map_err(|_| bad(format!("{key} {v:?}")))
            };
            Ok((num(a)?, num(b)?))
        };
        let variables: Vec<String> = field("variables:")
            .split(',')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect();
        let mean_range = range("meanRange:")?;
        let sd_range = range("sdRange:")?;
        let results_path = dir.join(format!("{id}-results.csv"));
        let csv = read(format!("{id}-results.csv"))?;
        let bad = |what: String| CaseError::Format(results_path.clone(), what);
        let mut lines = csv.lines();
        let header: Vec<&str> = lines
            .next()
            .ok_or_else(|| bad("empty".into()))?
            .split(',')
            .map(str::trim)
            .collect();
        let column = |name: String| {
            header
                .iter()
                .position(|h| *h == name)
                .ok_or_else(|| bad(format!("no column {name}")))
        };
        let mut cols = Vec::new();
        for v in &variables {
            cols.push((column(format!("{v}-mean"))?, column(format!("{v}-sd"))?));
        }
        let mut times = Vec::new();
        let mut mean = vec![Vec::new(); variables.len()];
        let mut sd = vec![Vec::new(); variables.len()];
        for (k, line) in lines.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
            let row: Vec<f64> = line
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| bad(format!("row {}: {line:?} is not numbers", k + 2)))?;
            if row.len() != header.len() {
                return Err(bad(format!("row {}: {} values", k + 2, row.len())));
            }
            times.push(row[0]);
            for (v, &(m, s)) in cols.iter().enumerate() {
                mean[v].push(row[m]);
                sd[v].push(row[s]);
            }
        }
        Ok(Case {
            id,
            dir: dir.to_path_buf(),
            variables,
            times,
            mean,
            sd,
            mean_range,
            sd_range,
        })
    }

    /// The case's model, from its SBML file of the given level and version (`"l3v1"`).
    pub fn network(&self, level_version: &str) -> Result<Network, NetworkError> {
        let path = self
            .dir
            .join(format!("{}-sbml-{level_version}.xml", self.id));
        let name = path.display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|e| NetworkError::Syntax {
            source_name: name.clone(),
            message: e.to_string(),
        })?;
        Network::from_text(&text, &name)
    }

    /// Where each output variable is in `network`: a species of the state, or a
    /// species held fixed; `None` if one is neither.
    pub fn outputs(&self, network: &Network) -> Option<Vec<Output>> {
        self.variables
            .iter()
            .map(|v| {
                network
                    .species
                    .iter()
                    .position(|s| &s.name == v)
                    .map(Output::Species)
                    .or_else(|| {
                        network
                            .fixed
                            .iter()
                            .find(|f| &f.0 == v)
                            .map(|f| Output::Fixed(f.1))
                    })
            })
            .collect()
    }
}

/// An output variable of a case in the imported network.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Output {
    /// Index among the species.
    Species(usize),
    /// A species held at this amount.
    Fixed(f64),
}

impl Output {
    /// `(mean, variance)` from a solver's moments.
    pub fn moments(&self, m: &super::Moments) -> (f64, f64) {
        match *self {
            Output::Species(i) => (m.mean[i], m.var[i]),
            Output::Fixed(v) => (v, 0.0),
        }
    }
}

/// The suite's statistics at one time for `n` trajectories: `(Z, Y)`.
pub fn z_y(n: usize, sample_mean: f64, sample_var: f64, mean: f64, sd: f64) -> (f64, f64) {
    let n = n as f64;
    if sd == 0.0 {
        // A point mass: the sample must be exact.
        let exact = (sample_mean - mean).abs() < 1e-12 && sample_var < 1e-12;
        return if exact {
            (0.0, 0.0)
        } else {
            (f64::INFINITY, f64::INFINITY)
        };
    }
    let z = n.sqrt() * (sample_mean - mean) / sd;
    let y = (n / 2.0).sqrt() * (sample_var / (sd * sd) - 1.0);
    (z, y)
}

/// A deterministic solver's distance to a case's expected values: the largest over
/// output variables and times of `|a − b| / max(|b|, 1)` for the mean and the sd
/// (relative, or absolute below one molecule).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distance {
    pub mean: f64,
    pub sd: f64,
    pub seconds: f64,
}

/// The suite's test of a simulator: the largest `|Z|` and `|Y|` over variables and times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SsaCheck {
    pub z_max: f64,
    pub y_max: f64,
    /// Output points (variable, time) outside the mean and sd ranges.
    pub mean_fails: usize,
    pub sd_fails: usize,
    /// No point outside either range.
    pub passed: bool,
    pub trajectories: usize,
    pub seed: u64,
    pub seconds: f64,
}

impl Case {
    /// The distance of moments at the case's times (one per time) to the expected ones.
    pub fn distance(
        &self,
        outputs: &[Output],
        moments: &[super::Moments],
        seconds: f64,
    ) -> Distance {
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1.0);
        let mut d = Distance {
            mean: 0.0,
            sd: 0.0,
            seconds,
        };
        for (v, o) in outputs.iter().enumerate() {
            for (k, m) in moments.iter().enumerate() {
                let (mean, var) = o.moments(m);
                d.mean = d.mean.max(rel(mean, self.mean[v][k]));
                d.sd = d.sd.max(rel(var.max(0.0).sqrt(), self.sd[v][k]));
            }
        }
        d
    }

    /// Exact FSP with automatic boxes (leak ≤ `max_leak` at every output time), and
    /// the boxes it ended with.
    pub fn check_fsp(
        &self,
        network: &Network,
        outputs: &[Output],
        max_leak: f64,
    ) -> Result<(Distance, Vec<usize>), super::fsp::FspError> {
        let start = std::time::Instant::now();
        let p: Vec<f64> = network.parameters.iter().map(|q| q.value).collect();
        let (sol, _) = super::fsp::solve_auto(network, &p, &self.times, max_leak)?;
        let d = self.distance(outputs, &sol.moments, start.elapsed().as_secs_f64());
        Ok((d, sol.sizes))
    }

    /// The SSA with `trajectories` paths from `seed`, judged by the suite's test.
    pub fn check_ssa(
        &self,
        network: &Network,
        outputs: &[Output],
        trajectories: usize,
        seed: u64,
    ) -> SsaCheck {
        let start = std::time::Instant::now();
        let p: Vec<f64> = network.parameters.iter().map(|q| q.value).collect();
        let sol = super::ssa::simulate(network, &p, &self.times, trajectories, seed);
        let (mut z_max, mut y_max) = (0.0f64, 0.0f64);
        let (mut mean_fails, mut sd_fails) = (0, 0);
        for (v, o) in outputs.iter().enumerate() {
            for (k, m) in sol.moments.iter().enumerate() {
                let (mean, var) = o.moments(m);
                let (z, y) = z_y(trajectories, mean, var, self.mean[v][k], self.sd[v][k]);
                z_max = z_max.max(z.abs());
                y_max = y_max.max(y.abs());
                mean_fails += usize::from(!(self.mean_range.0 < z && z < self.mean_range.1));
                sd_fails += usize::from(!(self.sd_range.0 < y && y < self.sd_range.1));
            }
        }
        SsaCheck {
            z_max,
            y_max,
            mean_fails,
            sd_fails,
            passed: mean_fails + sd_fails == 0,
            trajectories,
            seed,
            seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// The default PGD at the case's times, as `palpa cme solve --method pgd` runs it:
    /// a conserved pair reduced ([`super::conservation`]), tensor-train BDF2 with the
    /// default options and first step, on `boxes` (`None`: sized by
    /// [`super::sizing::with_boxes`], the default; the FSP check's boxes come from the
    /// same rule, so passing them saves a second pre-pass).
    pub fn check_pgd(
        &self,
        network: &Network,
        outputs: &[Output],
        boxes: Option<&[usize]>,
    ) -> Result<Distance, String> {
        let start = std::time::Instant::now();
        let t_end = self.times.last().copied().unwrap_or(1.0);
        let mut net = network.clone();
        if let Some(b) = boxes {
            for (s, &m) in net.species.iter_mut().zip(b) {
                s.max = Some(m);
            }
        }
        let moments = solve_pgd(&net, &self.times, t_end).map_err(|e| e.to_string())?;
        Ok(self.distance(outputs, &moments, start.elapsed().as_secs_f64()))
    }
}

/// The default PGD of `network` at `times` (see [`Case::check_pgd`]), the moments of
/// the network's own species.
pub fn solve_pgd(
    network: &Network,
    times: &[f64],
    t_end: f64,
) -> Result<Vec<super::Moments>, Box<dyn std::error::Error + Send + Sync>> {
    use super::{build, conservation, sizing, ttsolve};
    let reduced = conservation::reduce(network);
    let solved = reduced.as_ref().map_or(network, |r| &r.network);
    let (sized, _) = sizing::with_boxes(solved, t_end)?;
    let recipe = build::Recipe::default_for(&sized, t_end);
    let built = build::train(
        &sized,
        &recipe.options,
        Some(times),
        &mut |_: ttsolve::Step| {},
    )?;
    times
        .iter()
        .map(|&t| {
            let m = built.model.evaluate(t, &[], usize::MAX)?.moments;
            Ok(match &reduced {
                Some(r) => r.expand(&m),
                None => m,
            })
        })
        .collect()
}
