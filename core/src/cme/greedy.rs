//! The CME by PGD: one separated representation over species × time × parameters,
//! computed in one run without sampling the parameters.
//!
//! `P(z, t; p) ≈ Σ_j α_j · Π_i F_i^j(z_i) · F_t^j(t) · Π_q F_q^j(p_q)`.
//!
//! **Discretization.** Species `i` on its box `0..m_i` (FSP: what leaves the box is
//! lost); each range parameter on its grid (nodal values, linear in between; the
//! parameter enters the generator as `diag(grid)` on its own axis); time on nodes
//! `0 = t_0 < … < t_n`, steps growing geometrically from `h_first` to `h_max` so the
//! transient after the point-mass start is resolved.
//!
//! **Stepping in separated form** (docs/methods.md §3). Variable-step
//! BDF2 (BDF1 for the first step), stable for the stiff modes a point mass excites:
//!
//! `[(1+2ω)/(1+ω) I − h_k A] P_k = (1+ω) P_{k−1} − ω²/(1+ω) P_{k−2}`, `ω = h_k/h_{k−1}`.
//!
//! Both sides are sums of Kronecker products over (species…, parameters…): the
//! generator's terms ([`super::kron`]) and the previous states' terms. Each step is
//! solved by greedy minimal-residual PGD ([`super::cp::solve`]) to a relative residual
//! `step_tol`, so a state keeps only the rank it needs. Steps adapt: the local error is
//! estimated as 2/9 of the distance between the new state and the quadratic
//! extrapolation of the three before (both O(h³)), from Gram products, and kept near
//! `step_error_tol`.
//!
//! **Time functions.** The states `P_k` (node indicator `e_k` in time) are then
//! compressed into one representation with smooth time functions by the same greedy
//! solver with the identity operator: `min ‖Σ_k e_k ⊗ P_k − Σ_j α_j ⊗ F^j‖₂`, to a
//! relative tolerance `compress_tol`; every 20 terms all time functions are re-fitted
//! together (one linear least-squares problem over the time axis).
//!
//! (A space-time formulation `(D_t ⊗ I − H ⊗ A) Q = h ⊗ A P_0` solved directly by
//! greedy minimal-residual PGD was tried first: its residual falls to 1e-3 while the
//! toggle's L1 error at t = 100 stays near 1, the space-time operator being too badly
//! conditioned for a greedy rank-one solver over hundreds of steps.)

use std::fmt::Write as _;

use thiserror::Error;

use super::cp::{self, OpTerm, RankOne};
use super::kron::{generator_terms, sparse_of};
use super::network::Network;
use super::step::{extrapolation_weights, next_step};
use crate::axis::Discretization;
use crate::separated::{AxisInfo, FieldInfo, ModelMeta, Provenance, SeparatedModel};
use crate::tensor::Sparse1d;

/// The kind string of a CME meta-model file.
pub const KIND: &str = "cme-probability";

#[derive(Debug, Clone, PartialEq, Error)]
pub enum CmePgdError {
    #[error("species {0} has an automatic box; the PGD solver needs a size (max = …)")]
    AutoBox(String),
    #[error("invalid time grid: {0}")]
    TimeGrid(String),
    #[error("invalid solver setting: {0}")]
    Setting(String),
    #[error("the network has {0} species and range parameters; a model holds at most 62")]
    TooManyAxes(usize),
    #[error("building the model: {0}")]
    Model(#[from] crate::separated::ModelError),
    #[error("the build was cancelled")]
    Cancelled,
}

/// Time grid and solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub t_end: f64,
    pub h_first: f64,
    pub h_max: f64,
    /// Ratio of consecutive steps while they grow (≤ 1.5 keeps BDF2 zero-stable).
    pub growth: f64,
    /// Relative residual of each implicit step.
    pub step_tol: f64,
    /// Adaptive steps: the estimated local error of a step, relative to the state, is
    /// kept near this (0: the fixed geometric grid from `h_first`, `growth`, `h_max`).
    pub step_error_tol: f64,
    /// Most terms of one step's state.
    pub step_modes: usize,
    /// Stored time nodes (the model's time axis) are spaced at most this fraction of
    /// the elapsed time apart …
    pub store_rel: f64,
    /// … and at most this far apart.
    pub store_max: f64,
    /// Relative L2 error of the compressed time history.
    pub compress_tol: f64,
    /// Most terms of the final model.
    pub max_modes: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            t_end: 300.0,
            h_first: 0.02,
            h_max: 1.0,
            growth: 1.1,
            step_tol: 1e-6,
            step_error_tol: 3e-5,
            step_modes: 40,
            store_rel: 0.02,
            store_max: 1.0,
            compress_tol: 1e-5,
            max_modes: 400,
        }
    }
}

impl Options {
    /// Time nodes `t_0 = 0 … t_n = t_end`.
    pub fn time_nodes(&self) -> Result<Vec<f64>, CmePgdError> {
        // Every greedy solve lays out its times first: its tolerances are checked here.
        for (name, v) in [
            ("step tolerance", self.step_tol),
            ("step error tolerance", self.step_error_tol),
            ("compression tolerance", self.compress_tol),
        ] {
            if !(0.0..1.0).contains(&v) {
                return Err(CmePgdError::Setting(format!(
                    "{name} {v:?}: expected a relative error from 0 to below 1"
                )));
            }
        }
        let ok = self.t_end.is_finite()
            && self.t_end > 0.0
            && self.h_first > 0.0
            && self.h_max >= self.h_first
            && (1.0..=1.5).contains(&self.growth);
        if !ok {
            return Err(CmePgdError::TimeGrid(format!(
                "t_end {:?}, first step {:?}, largest step {:?}, growth {:?}: expected t_end > 0, \
                 0 < first ≤ largest, growth in [1, 1.5]",
                self.t_end, self.h_first, self.h_max, self.growth
            )));
        }
        let mut t = vec![0.0];
        let mut h = self.h_first;
        while *t
            .last()
            .expect("the time list starts with t = 0 and only grows")
            < self.t_end * (1.0 - 1e-12)
        {
            let now = *t
                .last()
                .expect("the time list starts with t = 0 and only grows");
            let step = h.min(self.t_end - now);
            // Avoid a sliver of a last step (BDF2's step ratio would blow up).
            let step = if self.t_end - now - step < 0.3 * step {
                self.t_end - now
            } else {
                step
            };
            t.push(now + step);
            h = (h * self.growth).min(self.h_max);
            if t.len() > 100_000 {
                return Err(CmePgdError::TimeGrid("more than 100 000 time steps".into()));
            }
        }
        Ok(t)
    }
}

/// Progress of an off-line solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// Step `k` of `n` done; its state has `rank` terms, relative residual `residual`.
    Step {
        k: usize,
        n: usize,
        rank: usize,
        residual: f64,
    },
    /// The compressed history has `terms` terms, relative error `residual`.
    Compress { terms: usize, residual: f64 },
}

/// Statistics of an off-line solve, beside the model.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    pub steps: usize,
    pub max_step_rank: usize,
    pub worst_step_residual: f64,
    pub history_terms: usize,
    pub compress_residual: f64,
}

/// Computes the meta-model of `network` (fixed parameters at their values, range
/// parameters as coordinates).
pub fn solve(
    network: &Network,
    options: &Options,
    progress: &mut dyn FnMut(Progress),
) -> Result<(SeparatedModel<f64>, Report), CmePgdError> {
    let sizes: Vec<usize> = network
        .species
        .iter()
        .map(|s| s.max.ok_or_else(|| CmePgdError::AutoBox(s.name.clone())))
        .collect::<Result<_, _>>()?;
    let d = sizes.len();
    // Range parameters become axes after the species; fixed ones fold into coefficients.
    let coords: Vec<(usize, Vec<f64>)> = network
        .parameters
        .iter()
        .enumerate()
        .filter_map(|(q, p)| p.grid().map(|g| (q, g)))
        .collect();
    if d + 1 + coords.len() > 62 {
        return Err(CmePgdError::TooManyAxes(d + coords.len()));
    }
    let mut step = StepOperator::new(network, &sizes, &coords);
    let p0 = initial_state(network, &sizes, &coords);
    let mut report = Report::default();
    let (t, history) = march(&mut step, p0, options, &mut report, progress)?;
    report.steps = t.len() - 1;
    let kept = stored_nodes(&t, options);
    let stored_t: Vec<f64> = kept.iter().map(|&k| t[k]).collect();
    let compressed = compress_history(
        &history,
        &kept,
        &sizes,
        &coords,
        options,
        &mut report,
        progress,
    );
    let model = model_of(
        network,
        &sizes,
        &coords,
        stored_t,
        &compressed,
        options,
        t.len() - 1,
    )?;
    Ok((model, report))
}

/// The BDF2 step operator `c₀ I − h A(p)` as separated terms: the identity, then one
/// term per generator term (fixed parameters folded into its coefficient, range
/// parameters as diagonal factors on their axes); coefficients are set per step.
struct StepOperator {
    ops: Vec<OpTerm>,
    rates: Vec<f64>,
}

impl StepOperator {
    fn new(network: &Network, sizes: &[usize], coords: &[(usize, Vec<f64>)]) -> Self {
        let terms = generator_terms(network, sizes);
        let fixed = |params: &[usize]| -> f64 {
            params
                .iter()
                .filter(|q| !coords.iter().any(|(c, _)| c == *q))
                .map(|&q| network.parameters[q].value)
                .product()
        };
        let mut ops = vec![OpTerm {
            coef: 1.0,
            factors: sizes
                .iter()
                .map(|&m| Sparse1d::identity(m))
                .chain(coords.iter().map(|(_, g)| Sparse1d::identity(g.len())))
                .collect(),
        }];
        let mut rates = Vec::new();
        for term in &terms {
            let coef = term.coef * fixed(&term.params);
            if coef == 0.0 {
                continue;
            }
            let mut factors: Vec<Sparse1d> = term.factors.iter().map(sparse_of).collect();
            for (q, grid) in coords {
                let power = term.params.iter().filter(|&&x| x == *q).count() as i32;
                let v: Vec<f64> = grid.iter().map(|g| g.powi(power)).collect();
                factors.push(Sparse1d::diagonal(&v));
            }
            rates.push(coef);
            ops.push(OpTerm { coef, factors });
        }
        StepOperator { ops, rates }
    }

    /// Sets the coefficients for a step of size `h` with leading BDF coefficient `c0`.
    fn set(&mut self, c0: f64, h: f64) {
        self.ops[0].coef = c0;
        for (op, &rate) in self.ops[1..].iter_mut().zip(&self.rates) {
            op.coef = -h * rate;
        }
    }
}

/// The initial state: each species at its initial copy number, uniform (unit norm
/// per axis, scaled back) over the parameter grids.
fn initial_state(network: &Network, sizes: &[usize], coords: &[(usize, Vec<f64>)]) -> RankOne {
    RankOne {
        scale: coords
            .iter()
            .map(|(_, g)| (g.len() as f64).sqrt())
            .product(),
        factors: network
            .species
            .iter()
            .zip(sizes)
            .map(|(s, &m)| {
                let mut v = vec![0.0; m];
                v[s.initial.min(m - 1)] = 1.0;
                v
            })
            .chain(coords.iter().map(|(_, g)| {
                let n = (g.len() as f64).sqrt();
                vec![1.0 / n; g.len()]
            }))
            .collect(),
    }
}

/// BDF2 steps from `p0` to `t_end`, each solved in separated form by the greedy
/// minimal-residual PGD, with the adaptive step rule when asked. Returns the times and
/// the state at each.
fn march(
    step: &mut StepOperator,
    p0: RankOne,
    options: &Options,
    report: &mut Report,
    progress: &mut dyn FnMut(Progress),
) -> Result<(Vec<f64>, Vec<Vec<RankOne>>), CmePgdError> {
    let fixed_t = options.time_nodes()?;
    let adaptive = options.step_error_tol > 0.0;
    let step_settings = cp::Settings {
        max_modes: options.step_modes,
        tol: options.step_tol,
        ..cp::Settings::default()
    };
    let mut history: Vec<Vec<RankOne>> = vec![vec![p0]];
    let mut t = vec![0.0];
    let mut h: Vec<f64> = Vec::new();
    let mut next_h = options.h_first;
    let mut k = 0;
    while *t
        .last()
        .expect("the time list starts with t = 0 and only grows")
        < options.t_end * (1.0 - 1e-12)
    {
        k += 1;
        let now = *t
            .last()
            .expect("the time list starts with t = 0 and only grows");
        let hk = if adaptive {
            let rest = options.t_end - now;
            // No sliver of a last step: BDF2's step ratio would blow up.
            if rest - next_h < 0.3 * next_h {
                rest
            } else {
                next_h
            }
        } else {
            fixed_t[k] - fixed_t[k - 1]
        };
        let (c0, rhs) = if k == 1 {
            (1.0, history[0].clone())
        } else {
            let w = hk / h[k - 2];
            let mut rhs: Vec<RankOne> = history[k - 1]
                .iter()
                .map(|r| RankOne {
                    scale: (1.0 + w) * r.scale,
                    factors: r.factors.clone(),
                })
                .collect();
            rhs.extend(history[k - 2].iter().map(|r| RankOne {
                scale: -w * w / (1.0 + w) * r.scale,
                factors: r.factors.clone(),
            }));
            ((1.0 + 2.0 * w) / (1.0 + w), rhs)
        };
        step.set(c0, hk);
        let guesses: Vec<Vec<Vec<f64>>> =
            history[k - 1].iter().map(|r| r.factors.clone()).collect();
        let sol = cp::solve_from(&step.ops, &rhs, &step_settings, &guesses, &mut |_, _| {});
        let residual = sol.residual_per_mode.last().copied().unwrap_or(0.0);
        report.max_step_rank = report.max_step_rank.max(sol.terms.len());
        report.worst_step_residual = report.worst_step_residual.max(residual);
        t.push(now + hk);
        h.push(hk);
        history.push(sol.terms);
        // Next step: the local error of BDF2 is about 2/9 of the distance between the
        // new state and the quadratic extrapolation of the three before (both O(h³)).
        next_h = (hk * options.growth).min(options.h_max);
        if adaptive && k >= 3 {
            let weights = extrapolation_weights(&t[k - 3..=k]);
            let mut diff: Vec<RankOne> = history[k].clone();
            for i in 0..3 {
                let l = weights[i];
                diff.extend(history[k - 3 + i].iter().map(|r| RankOne {
                    scale: -l * r.scale,
                    factors: r.factors.clone(),
                }));
            }
            let state_norm = cp::norm_sq(&history[k]).sqrt().max(1e-300);
            let est = 2.0 / 9.0 * cp::norm_sq(&diff).max(0.0).sqrt() / state_norm;
            next_h = next_step(
                hk,
                est,
                options.step_error_tol,
                options.growth,
                options.h_first,
                options.h_max,
            );
        }
        let remaining = ((options.t_end - t[k]) / next_h).ceil() as usize;
        progress(Progress::Step {
            k,
            n: k + remaining,
            rank: history[k].len(),
            residual,
        });
        if k > 1_000_000 {
            return Err(CmePgdError::TimeGrid(
                "more than a million time steps".into(),
            ));
        }
    }
    Ok((t, history))
}

/// The stored time nodes: every step early, then spaced by `store_rel·t` up to
/// `store_max` (linear interpolation in between), always the last.
fn stored_nodes(t: &[f64], options: &Options) -> Vec<usize> {
    let mut kept = vec![0usize];
    for k in 1..t.len() {
        let last = t[*kept
            .last()
            .expect("the time list starts with t = 0 and only grows")];
        let spacing = (options.store_rel * t[k]).min(options.store_max);
        if k + 1 == t.len() || t[k + 1] - last > spacing * (1.0 + 1e-9) {
            kept.push(k);
        }
    }
    kept
}

/// Compresses the history `Σ_k e_k ⊗ P_k` at the stored nodes into smooth time
/// functions (a greedy fit of the identity system, all time functions re-fitted
/// together every 20 terms).
fn compress_history(
    history: &[Vec<RankOne>],
    kept: &[usize],
    sizes: &[usize],
    coords: &[(usize, Vec<f64>)],
    options: &Options,
    report: &mut Report,
    progress: &mut dyn FnMut(Progress),
) -> cp::Solution {
    let d = sizes.len();
    let nt = kept.len();
    let mut stacked = Vec::new();
    for (node, &k) in kept.iter().enumerate() {
        for r in &history[k] {
            let mut e = vec![0.0; nt];
            e[node] = 1.0;
            let mut factors = r.factors[..d].to_vec();
            factors.push(e);
            factors.extend_from_slice(&r.factors[d..]);
            stacked.push(RankOne {
                scale: r.scale,
                factors,
            });
        }
    }
    report.history_terms = stacked.len();
    let identity = vec![OpTerm {
        coef: 1.0,
        factors: sizes
            .iter()
            .map(|&m| Sparse1d::identity(m))
            .chain(std::iter::once(Sparse1d::identity(nt)))
            .chain(coords.iter().map(|(_, g)| Sparse1d::identity(g.len())))
            .collect(),
    }];
    let compressed = cp::solve(
        &identity,
        &stacked,
        &cp::Settings {
            max_modes: options.max_modes,
            tol: options.compress_tol,
            // Re-fit all time functions together every 20 terms.
            refit: Some((d, 20)),
            ..cp::Settings::default()
        },
        &mut |terms, residual| progress(Progress::Compress { terms, residual }),
    );
    report.compress_residual = compressed.residual_per_mode.last().copied().unwrap_or(0.0);
    compressed
}

/// The meta-model file's form: term weights as the one field row, species as discrete
/// axes, then `t` at the stored nodes, then the range parameters; with provenance.
fn model_of(
    network: &Network,
    sizes: &[usize],
    coords: &[(usize, Vec<f64>)],
    stored_t: Vec<f64>,
    compressed: &cp::Solution,
    options: &Options,
    steps: usize,
) -> Result<SeparatedModel<f64>, CmePgdError> {
    let d = sizes.len();
    let nt = stored_t.len();
    let n_modes = compressed.terms.len();
    let x: Vec<f64> = compressed.terms.iter().map(|r| r.scale).collect();
    let mut axis_values: Vec<Vec<f64>> = Vec::new();
    for a in 0..d + 1 + coords.len() {
        let m = compressed.terms.first().map_or(0, |r| r.factors[a].len());
        let mut v = vec![0.0; m * n_modes];
        for (j, r) in compressed.terms.iter().enumerate() {
            for (z, val) in r.factors[a].iter().enumerate() {
                v[z * n_modes + j] = *val;
            }
        }
        axis_values.push(v);
    }
    let mut axes: Vec<AxisInfo> = network
        .species
        .iter()
        .zip(sizes)
        .map(|(s, &m)| AxisInfo {
            name: s.name.clone(),
            unit: "copies".into(),
            discretization: Discretization::Discrete {
                labels: (0..m).map(|z| z.to_string()).collect(),
            },
        })
        .collect();
    axes.push(AxisInfo {
        name: "t".into(),
        unit: "time".into(),
        discretization: Discretization::Grid { nodes: stored_t },
    });
    for (q, g) in coords {
        axes.push(AxisInfo {
            name: network.parameters[*q].name.clone(),
            unit: String::new(),
            discretization: Discretization::Grid { nodes: g.clone() },
        });
    }
    let mut description = format!(
        "network {}; box {:?}; {} BDF2 steps to t = {} (steps {}..{}), {} stored; fixed parameters",
        network.name, sizes, steps, options.t_end, options.h_first, options.h_max, nt
    );
    for p in network.parameters.iter().filter(|p| p.range.is_none()) {
        let _ = write!(description, " {}={}", p.name, p.value);
    }
    let mut provenance = Provenance::now(
        "cme PGD: BDF2 steps in separated form (greedy minimal residual), history compressed",
        &description,
        options.compress_tol,
        compressed.residual_per_mode.clone(),
    );
    provenance.input_hash = format!(
        "{:016x}",
        xxhash_rust::xxh3::xxh3_64(format!("{network:?}{options:?}").as_bytes())
    );
    let meta = ModelMeta {
        kind: KIND.into(),
        field: FieldInfo {
            name: "term weight".into(),
            unit: "1".into(),
            components: 1,
            node_ids: Vec::new(),
        },
        axes,
        provenance,
        tradeoff: Vec::new(),
        geometry: Default::default(),
    };
    SeparatedModel::new(meta, 1, n_modes, x, axis_values).map_err(CmePgdError::from)
}
