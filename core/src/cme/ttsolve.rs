//! The CME in tensor-train form: implicit time steps whose ranks follow the error.
//!
//! `P(t, z_1…z_d, p_1…p_q)` is kept as a tensor train over (species…, parameters…)
//! ([`super::tt`]); each range parameter is an axis on its grid, entering the generator
//! as `diag(grid)` on its own axis, so one solve covers every parameter value. The step
//! is the variable-step BDF2 of [`super::pgd`] (BDF1 first):
//!
//! `[(1+2ω)/(1+ω) I − h_k A] P_k = (1+ω) P_{k−1} − ω²/(1+ω) P_{k−2}`, `ω = h_k/h_{k−1}`,
//!
//! solved by ALS with residual enrichment ([`super::amen`]), the ranks set by SVD
//! truncation to `eps` (relative), not capped by a greedy budget. Steps adapt so the
//! BDF2 local error estimate (2/9 of the distance to the quadratic extrapolation of the
//! three states before) stays near `step_error_tol`.
//!
//! The stored states (every step early, then spaced by `store_rel·t` up to `store_max`)
//! form the meta-model: a tensor train over (t, species…, parameters…) whose time core
//! holds node values (linear in between). States are added one by one, normalized, and
//! the train is rounded to `compress_eps` after each, so every stored time keeps the same
//! relative accuracy however small its norm (a spread-out distribution has a small L2
//! norm). The norms go back into the time core at the end.

use super::amen::{self, LocalTerm, Mpo};
use super::cp::Sparse1d;
use super::kron::{Factor1d, generator_terms};
use super::network::Network;
use super::pgd::CmePgdError;
use super::tt::{Core, Tt};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub t_end: f64,
    pub h_first: f64,
    pub h_max: f64,
    /// Largest ratio of consecutive steps (≤ 1.5 keeps BDF2 zero-stable).
    pub growth: f64,
    /// Estimated local error of a step, relative to the state.
    pub step_error_tol: f64,
    /// Local residual at which the ALS sweeps of a step stop.
    pub solve_tol: f64,
    /// Relative SVD truncation of the step's state.
    pub eps: f64,
    pub max_rank: usize,
    pub store_rel: f64,
    pub store_max: f64,
    /// Relative truncation of the stored history (per stored state).
    pub compress_eps: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            t_end: 300.0,
            h_first: 0.01,
            h_max: 5.0,
            growth: 1.4,
            step_error_tol: 1e-5,
            solve_tol: 1e-7,
            eps: 1e-7,
            max_rank: 120,
            store_rel: 0.02,
            store_max: 2.0,
            compress_eps: 1e-6,
        }
    }
}

/// Progress of a solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub k: usize,
    pub t: f64,
    pub h: f64,
    pub rank: usize,
    pub sweeps: usize,
    pub history_rank: usize,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    pub steps: usize,
    pub max_rank: usize,
    pub worst_local_residual: f64,
    pub sweeps: usize,
    pub gmres_iterations: usize,
    pub stored: usize,
    pub history_ranks: Vec<usize>,
    pub solve_seconds: f64,
    pub compress_seconds: f64,
}

/// The solution: a tensor train over (t, species…, range parameters…).
#[derive(Debug, Clone, PartialEq)]
pub struct History {
    pub sizes: Vec<usize>,
    pub t: Vec<f64>,
    /// `(parameter index, grid)` of each parameter axis.
    pub params: Vec<(usize, Vec<f64>)>,
    pub tt: Tt,
}

fn is_identity(f: &Factor1d) -> bool {
    f.cols
        .iter()
        .enumerate()
        .all(|(j, c)| *c == Some((j, 1.0)))
}

fn sparse_of(f: &Factor1d) -> Sparse1d {
    let m = f.cols.len();
    Sparse1d::from_triplets(
        m,
        m,
        f.cols
            .iter()
            .enumerate()
            .filter_map(|(j, c)| c.map(|(i, v)| (i, j, v))),
    )
}

/// The generator `A` as local terms over (species…, range parameters…).
pub fn generator(network: &Network, sizes: &[usize]) -> (Vec<LocalTerm>, Vec<(usize, Vec<f64>)>) {
    let coords: Vec<(usize, Vec<f64>)> = network
        .parameters
        .iter()
        .enumerate()
        .filter_map(|(q, p)| p.grid().map(|g| (q, g)))
        .collect();
    let mut out = Vec::new();
    for term in generator_terms(network, sizes) {
        let fixed: f64 = term
            .params
            .iter()
            .filter(|q| !coords.iter().any(|(c, _)| c == *q))
            .map(|&q| network.parameters[q].value)
            .product();
        let coef = term.coef * fixed;
        if coef == 0.0 {
            continue;
        }
        let mut factors: Vec<Option<Sparse1d>> = term
            .factors
            .iter()
            .map(|f| (!is_identity(f)).then(|| sparse_of(f)))
            .collect();
        for (q, grid) in &coords {
            let power = term.params.iter().filter(|&&x| x == *q).count() as i32;
            factors.push((power > 0).then(|| {
                Sparse1d::diagonal(&grid.iter().map(|g| g.powi(power)).collect::<Vec<_>>())
            }));
        }
        out.push(LocalTerm { coef, factors });
    }
    (out, coords)
}

/// Solves the network's CME from its initial point mass to `t_end`.
pub fn solve(
    network: &Network,
    options: &Options,
    progress: &mut dyn FnMut(Step),
) -> Result<(History, Report), CmePgdError> {
    let sizes: Vec<usize> = network
        .species
        .iter()
        .map(|s| s.max.ok_or_else(|| CmePgdError::AutoBox(s.name.clone())))
        .collect::<Result<_, _>>()?;
    let ok = options.t_end.is_finite()
        && options.t_end > 0.0
        && options.h_first > 0.0
        && options.h_max >= options.h_first
        && (1.0..=1.5).contains(&options.growth)
        && options.eps >= 0.0
        && options.max_rank >= 1;
    if !ok {
        return Err(CmePgdError::TimeGrid(format!(
            "t_end {}, first step {}, largest step {}, growth {}, eps {}, max rank {}: \
             expected t_end > 0, 0 < first ≤ largest, growth in [1, 1.5], eps ≥ 0, rank ≥ 1",
            options.t_end,
            options.h_first,
            options.h_max,
            options.growth,
            options.eps,
            options.max_rank
        )));
    }
    let started = std::time::Instant::now();
    let (terms, coords) = generator(network, &sizes);
    let axis_sizes: Vec<usize> = sizes
        .iter()
        .copied()
        .chain(coords.iter().map(|(_, g)| g.len()))
        .collect();
    let p0 = Tt::rank_one(
        &network
            .species
            .iter()
            .zip(&sizes)
            .map(|(s, &m)| {
                let mut v = vec![0.0; m];
                v[s.initial.min(m - 1)] = 1.0;
                v
            })
            .chain(coords.iter().map(|(_, g)| vec![1.0; g.len()]))
            .collect::<Vec<_>>(),
    );
    let settings = amen::Settings {
        tol: options.solve_tol,
        eps: options.eps,
        max_rank: options.max_rank,
        ..amen::Settings::default()
    };
    let mut report = Report::default();
    let mut compress_s = 0.0;
    let mut t = vec![0.0];
    let mut h: Vec<f64> = Vec::new();
    // The last four states (BDF2 needs two, the error estimate four).
    let mut recent: Vec<Tt> = vec![p0.clone()];
    let mut store = Stored::new(options.compress_eps, &p0);
    let mut next_h = options.h_first;
    let mut k = 0;
    while *t.last().expect("t_0") < options.t_end * (1.0 - 1e-12) {
        k += 1;
        let now = *t.last().expect("t_0");
        let rest = options.t_end - now;
        let hk = if rest - next_h < 0.3 * next_h {
            rest
        } else {
            next_h
        };
        let last = recent.last().expect("a state");
        let (c0, rhs) = if k == 1 {
            (1.0, last.clone())
        } else {
            let w = hk / h[k - 2];
            let before = &recent[recent.len() - 2];
            let mut rhs = Tt::sum(&[(1.0 + w, last), (-w * w / (1.0 + w), before)]);
            rhs.round(0.01 * options.eps, usize::MAX);
            ((1.0 + 2.0 * w) / (1.0 + w), rhs)
        };
        let mut step_terms = vec![LocalTerm {
            coef: c0,
            factors: vec![None; axis_sizes.len()],
        }];
        step_terms.extend(terms.iter().map(|t| LocalTerm {
            coef: -hk * t.coef,
            factors: t.factors.clone(),
        }));
        let op = Mpo::from_terms(&axis_sizes, &step_terms);
        let mut x = last.clone();
        let r = amen::solve(&op, &rhs, &mut x, &settings);
        report.max_rank = report.max_rank.max(r.max_rank);
        report.worst_local_residual = report.worst_local_residual.max(r.local_residual);
        report.sweeps += r.sweeps;
        report.gmres_iterations += r.gmres_iterations;
        t.push(now + hk);
        h.push(hk);
        recent.push(x);
        if recent.len() > 4 {
            recent.remove(0);
        }
        next_h = (hk * options.growth).min(options.h_max);
        if k >= 3 {
            let lagrange = |i: usize| -> f64 {
                let nodes = [t[k - 3], t[k - 2], t[k - 1]];
                (0..3)
                    .filter(|&j| j != i)
                    .map(|j| (t[k] - nodes[j]) / (nodes[i] - nodes[j]))
                    .product()
            };
            let n = recent.len();
            let diff = Tt::sum(&[
                (1.0, &recent[n - 1]),
                (-lagrange(0), &recent[n - 4]),
                (-lagrange(1), &recent[n - 3]),
                (-lagrange(2), &recent[n - 2]),
            ]);
            let state = recent[n - 1].norm().max(1e-300);
            let est = 2.0 / 9.0 * diff.norm() / state;
            let factor = if est > 0.0 {
                (0.9 * (options.step_error_tol / est).cbrt()).clamp(0.5, options.growth)
            } else {
                options.growth
            };
            next_h = (hk * factor).clamp(options.h_first.min(hk), options.h_max);
        }
        // Store the state before this one if the next stored time would be too far.
        let tc = std::time::Instant::now();
        let n = recent.len();
        if k >= 2 {
            let spacing = (options.store_rel * t[k]).min(options.store_max);
            if t[k] - store.last_t > spacing * (1.0 + 1e-9) {
                store.push(t[k - 1], &recent[n - 2]);
            }
        }
        if t[k] >= options.t_end * (1.0 - 1e-12) {
            store.push(t[k], &recent[n - 1]);
        }
        compress_s += tc.elapsed().as_secs_f64();
        progress(Step {
            k,
            t: t[k],
            h: hk,
            rank: recent[n - 1].max_rank(),
            sweeps: r.sweeps,
            history_rank: store.history.max_rank(),
        });
        if k > 200_000 {
            return Err(CmePgdError::TimeGrid("more than 200 000 time steps".into()));
        }
    }
    report.steps = k;
    report.stored = store.t.len();
    let (history, stored_t) = store.finish();
    report.history_ranks = history.ranks();
    report.compress_seconds = compress_s;
    report.solve_seconds = started.elapsed().as_secs_f64() - compress_s;
    Ok((
        History {
            sizes,
            t: stored_t,
            params: coords,
            tt: history,
        },
        report,
    ))
}

/// The growing history `Σ_k e_k ⊗ X_k/‖X_k‖`, rounded after each addition.
struct Stored {
    eps: f64,
    t: Vec<f64>,
    norms: Vec<f64>,
    last_t: f64,
    history: Tt,
}

impl Stored {
    fn new(eps: f64, p0: &Tt) -> Self {
        let mut s = Stored {
            eps,
            t: Vec::new(),
            norms: Vec::new(),
            last_t: 0.0,
            history: Tt { cores: Vec::new() },
        };
        s.push(0.0, p0);
        s
    }

    fn push(&mut self, t: f64, x: &Tt) {
        let norm = x.norm();
        let nt = self.t.len() + 1;
        let mut e = vec![0.0; nt];
        e[nt - 1] = 1.0;
        let mut cores = vec![Core {
            r0: 1,
            n: nt,
            r1: 1,
            v: e,
        }];
        cores.extend(x.cores.iter().cloned());
        let mut new = Tt { cores };
        new.scale(1.0 / norm.max(1e-300));
        self.history = if self.history.cores.is_empty() {
            new
        } else {
            // Pad the time core with a zero row for the new node.
            let c = &self.history.cores[0];
            let mut padded = Core::zeros(1, nt, c.r1);
            padded.v[..c.v.len()].copy_from_slice(&c.v);
            let mut old = self.history.clone();
            old.cores[0] = padded;
            let mut sum = Tt::sum(&[(1.0, &old), (1.0, &new)]);
            sum.round(self.eps, usize::MAX);
            sum
        };
        self.t.push(t);
        self.norms.push(norm);
        self.last_t = t;
    }

    /// The history with the norms restored, and the stored times.
    fn finish(self) -> (Tt, Vec<f64>) {
        let mut tt = self.history;
        let c = &mut tt.cores[0];
        for (i, nrm) in self.norms.iter().enumerate() {
            for b in 0..c.r1 {
                c.v[i * c.r1 + b] *= nrm;
            }
        }
        (tt, self.t)
    }
}

/// Linear-interpolation weights of `x` on `nodes` (clamped to the ends); `true` if
/// `x` lay outside.
pub fn hat_weights(nodes: &[f64], x: f64) -> (Vec<f64>, bool) {
    let n = nodes.len();
    let mut w = vec![0.0; n];
    if n == 1 || x <= nodes[0] {
        w[0] = 1.0;
        return (w, n > 1 && x < nodes[0]);
    }
    if x >= nodes[n - 1] {
        w[n - 1] = 1.0;
        return (w, x > nodes[n - 1]);
    }
    let i = nodes.partition_point(|&v| v <= x).clamp(1, n - 1);
    let s = (x - nodes[i - 1]) / (nodes[i] - nodes[i - 1]);
    w[i - 1] = 1.0 - s;
    w[i] = s;
    (w, false)
}

impl History {
    /// The tensor train over the species at time `t` and parameter values `p` (one per
    /// parameter axis), interpolated linearly between nodes and clamped to the range.
    pub fn particularize(&self, t: f64, p: &[f64]) -> Tt {
        let d = self.sizes.len();
        let (wt, _) = hat_weights(&self.t, t);
        let time = self.tt.cores[0].contract(&wt); // 1 × ρ
        let mut cores: Vec<Core> = self.tt.cores[1..=d].to_vec();
        cores[0] = super::tt::times_left(
            faer::MatRef::from_row_major_slice(&time, 1, self.tt.cores[0].r1),
            &cores[0],
        );
        // Parameters: contract from the right end into the last species core.
        let mut right = vec![1.0];
        for (q, core) in self.tt.cores[d + 1..].iter().enumerate().rev() {
            let (w, _) = hat_weights(&self.params[q].1, p[q]);
            let m = core.contract(&w); // r0 × r1
            right = (0..core.r0)
                .map(|a| (0..core.r1).map(|b| m[a * core.r1 + b] * right[b]).sum())
                .collect();
        }
        let last = cores.len() - 1;
        let r = right.len();
        cores[last] = super::tt::times_right(
            &cores[last],
            faer::MatRef::from_row_major_slice(&right, r, 1),
        );
        Tt { cores }
    }
}
