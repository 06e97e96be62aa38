//! The CME in tensor-train form: implicit time steps whose ranks follow the error.
//!
//! `P(t, z_1…z_d, p_1…p_q)` is kept as a tensor train over (species…, parameters…)
//! ([`crate::tensor::tt`]); each range parameter is an axis on its grid, entering the generator
//! as `diag(grid)` on its own axis, so one solve covers every parameter value. The step
//! is the variable-step BDF2 of [`super::greedy`] (BDF1 first):
//!
//! `[(1+2ω)/(1+ω) I − h_k A] P_k = (1+ω) P_{k−1} − ω²/(1+ω) P_{k−2}`, `ω = h_k/h_{k−1}`,
//!
//! solved by ALS with residual enrichment ([`crate::tensor::amen`]), the ranks set by SVD
//! truncation to `eps` (relative), not capped by a greedy budget. Steps adapt so the
//! BDF2 local error estimate (2/9 of the distance to the quadratic extrapolation of the
//! three states before) stays near `step_error_tol`.
//!
//! The stored states (every step early, then spaced by `store_rel·t` up to `store_max`)
//! form the meta-model: a tensor train over (t, species…, parameters…) whose time core
//! holds node values (interpolated in between). States are merged in blocks of
//! consecutive nodes, each merge rounded to `compress_eps` in a norm weighted by the
//! block's marginal envelopes and normalized per node (`round_block`), so the
//! truncation is measured in probability and every stored time keeps the same relative
//! accuracy.

use super::greedy::CmePgdError;
use super::history::{History, Slot, lagrange_weights, slot_order};
use super::kron::{Factor1d, generator_terms, sparse_of};
use super::network::Network;
use super::step::{extrapolation_weights, next_step};
use super::views::{Samples, Views};
use crate::tensor::Sparse1d;
use crate::tensor::amen::{self, LocalTerm, Mpo};
use crate::tensor::tt::{Core, Tt};
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub t_end: f64,
    pub h_first: f64,
    pub h_max: f64,
    /// Largest ratio of consecutive steps (≤ 1.5 keeps BDF2 zero-stable).
    pub growth: f64,
    /// Estimated local error of a step, relative to the state. The default 1e-6 is
    /// what the DSMTS birth–death case with the fastest rates (λ = 1, μ = 1.1 over
    /// t ≤ 50) needs for its mean within 1e-3: 3e-6 left 1.4e-3, 1e-6 gives 5.8e-4.
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
    /// Floor of the history's probability weights, relative to each marginal's peak
    /// (see `round_block`).
    pub weight_floor: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            t_end: 300.0,
            h_first: 0.01,
            h_max: 5.0,
            growth: 1.4,
            step_error_tol: 1e-6,
            solve_tol: 1e-7,
            eps: 1e-8,
            max_rank: 120,
            store_rel: 0.02,
            store_max: 2.0,
            compress_eps: 1e-6,
            weight_floor: 1e-2,
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
    /// The largest relative mass correction of a step (see `solve`).
    pub worst_mass_correction: f64,
    pub sweeps: usize,
    pub gmres_iterations: usize,
    pub stored: usize,
    pub history_ranks: Vec<usize>,
    pub solve_seconds: f64,
    pub compress_seconds: f64,
}

fn is_identity(f: &Factor1d) -> bool {
    f.cols.iter().enumerate().all(|(j, c)| *c == Some((j, 1.0)))
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
    let (kept, report) = run(network, options, &Keep::History, None, progress)?;
    Ok((kept.into_history(), report))
}

/// As [`solve`], stopping with [`CmePgdError::Cancelled`] at the first step after
/// `cancel` is set (an app's background build).
pub fn solve_cancellable(
    network: &Network,
    options: &Options,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(Step),
) -> Result<(History, Report), CmePgdError> {
    let (kept, report) = run(network, options, &Keep::History, Some(cancel), progress)?;
    Ok((kept.into_history(), report))
}

/// The states at `times` only (increasing, ≥ 0): steps land on each time and nothing
/// else is stored, so no history is compressed. `options.t_end` is replaced by the
/// last time. The result is a [`History`] whose nodes are `times`, exact there (the
/// states stacked, ranks adding), for a caller that shows a few times, not a slider.
pub fn solve_at(
    network: &Network,
    options: &Options,
    times: &[f64],
    progress: &mut dyn FnMut(Step),
) -> Result<(History, Report), CmePgdError> {
    let last = times.last().copied().unwrap_or(0.0);
    if !(times.iter().all(|t| t.is_finite() && *t >= 0.0)
        && times.windows(2).all(|w| w[0] < w[1])
        && last > 0.0)
    {
        return Err(CmePgdError::TimeGrid(format!(
            "output times {times:?}: expected finite, increasing, ≥ 0, the last > 0"
        )));
    }
    let options = Options {
        t_end: last,
        ..*options
    };
    let (kept, report) = run(network, &options, &Keep::Outputs(times), None, progress)?;
    Ok((kept.into_history(), report))
}

/// Solves to `options.t_end` and keeps only the views a scene shows (see
/// [`super::views`]): every species' marginal and the joints of `pairs` (network
/// indices), read from every step's state and compressed to `views_eps`. The network
/// must have no range parameters (a view is a function of time alone).
pub fn solve_views(
    network: &Network,
    options: &Options,
    pairs: &[(usize, usize)],
    views_eps: f64,
    cancel: Option<&AtomicBool>,
    progress: &mut dyn FnMut(Step),
) -> Result<(Views, Report), CmePgdError> {
    let ranged: Vec<&str> = network
        .parameters
        .iter()
        .filter(|p| p.grid().is_some())
        .map(|p| p.name.as_str())
        .collect();
    if !ranged.is_empty() {
        return Err(CmePgdError::Setting(format!(
            "a views model is a function of time only, but {} has range parameters {}: \
             build the full tensor train instead",
            network.name,
            ranged.join(", ")
        )));
    }
    let d = network.species.len();
    if let Some(&(a, b)) = pairs.iter().find(|(a, b)| a >= b || *b >= d) {
        return Err(CmePgdError::Setting(format!(
            "pair ({a}, {b}): expected two species indices a < b < {d}"
        )));
    }
    let (kept, report) = run(
        network,
        options,
        &Keep::Views {
            pairs: pairs.to_vec(),
            eps: views_eps,
        },
        cancel,
        progress,
    )?;
    match kept {
        Kept::Views(v) => Ok((v, report)),
        Kept::History(_) => unreachable!("views asked for"),
    }
}

/// What a run keeps of the states it steps through.
enum Keep<'a> {
    /// The whole history, rounded (the meta-model over all t).
    History,
    /// The states at these times only.
    Outputs(&'a [f64]),
    /// Marginals and these joints at every step.
    Views {
        pairs: Vec<(usize, usize)>,
        eps: f64,
    },
}

enum Kept {
    History(History),
    Views(Views),
}

impl Kept {
    fn into_history(self) -> History {
        match self {
            Kept::History(h) => h,
            Kept::Views(_) => unreachable!("a history was asked for"),
        }
    }
}

fn run(
    network: &Network,
    options: &Options,
    keep: &Keep<'_>,
    cancel: Option<&AtomicBool>,
    progress: &mut dyn FnMut(Step),
) -> Result<(Kept, Report), CmePgdError> {
    let outputs = match keep {
        Keep::Outputs(times) => Some(times),
        _ => None,
    };
    let sizes: Vec<usize> = network
        .species
        .iter()
        .map(|s| s.max.ok_or_else(|| CmePgdError::AutoBox(s.name.clone())))
        .collect::<Result<_, _>>()?;
    check(options)?;
    let started = std::time::Instant::now();
    let Setup {
        terms,
        coords,
        order,
        axis_sizes,
        generator_op,
        p0,
    } = setup(network, &sizes);
    let settings = amen::Settings {
        // Truncating to eps leaves local residuals of that order: asking the sweeps for
        // less only burns them.
        tol: options.solve_tol.max(3.0 * options.eps),
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
    let (mut store, mut samples) = match keep {
        Keep::History => (
            Some(Stored::new(
                options.compress_eps,
                options.weight_floor,
                &order,
                &p0,
            )),
            None,
        ),
        Keep::Outputs(_) => (None, None),
        Keep::Views { pairs, .. } => {
            let core_of = (0..sizes.len())
                .map(|i| {
                    order
                        .iter()
                        .position(|o| *o == Slot::Species(i))
                        .expect("every species has a core")
                })
                .collect();
            let mut s = Samples::new(core_of, sizes.clone(), pairs.clone());
            s.push(0.0, &p0);
            (None, Some(s))
        }
    };
    let mut next_h = options.h_first;
    let mut k = 0;
    // Output mode: the states at the requested times, in order.
    let mut pending: Vec<f64> = outputs.map_or(Vec::new(), |o| o.to_vec());
    let mut shown: Vec<(f64, Tt)> = Vec::new();
    while pending.first().is_some_and(|&to| to <= 0.0) {
        shown.push((0.0, p0.clone()));
        pending.remove(0);
    }
    while *t
        .last()
        .expect("the time list starts with t = 0 and only grows")
        < options.t_end * (1.0 - 1e-12)
    {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(CmePgdError::Cancelled);
        }
        k += 1;
        let now = *t
            .last()
            .expect("the time list starts with t = 0 and only grows");
        let rest = options.t_end - now;
        let mut hk = if rest - next_h < 0.3 * next_h {
            rest
        } else {
            next_h
        };
        // Land on the next output time (stretching by at most 30 % or shortening).
        let landing = pending.first().copied().filter(|&to| to - now < 1.3 * hk);
        if let Some(to) = landing {
            hk = to - now;
        }
        let last = recent
            .last()
            .expect("the initial state is pushed before the loop");
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
        // Rank truncation does not conserve probability, and in d dimensions a small L2
        // error can carry a large L1 mass (the all-ones tensor has norm Π√m_i). The exact
        // step conserves it: c0⟨1, P_k⟩ − h⟨1, A P_k⟩ = ⟨1, rhs⟩ (⟨1, A P⟩ is minus the
        // FSP leak rate). Rescale to that balance, per parameter value where there is one
        // parameter axis.
        balance_mass(&mut x, &rhs, &generator_op, &order, c0, hk, &mut report);
        report.max_rank = report.max_rank.max(r.max_rank);
        report.worst_local_residual = report.worst_local_residual.max(r.local_residual);
        report.sweeps += r.sweeps;
        report.gmres_iterations += r.gmres_iterations;
        t.push(landing.unwrap_or(now + hk));
        h.push(hk);
        recent.push(x);
        if recent.len() > 4 {
            recent.remove(0);
        }
        next_h = (hk * options.growth).min(options.h_max);
        if k >= 3 {
            next_h = next_step(
                hk,
                local_error(&t[k - 3..=k], &recent),
                options.step_error_tol,
                options.growth,
                options.h_first,
                options.h_max,
            );
        }
        // Store the state before this one if the next stored time would be too far.
        let tc = std::time::Instant::now();
        let n = recent.len();
        if landing.is_some() {
            shown.push((t[k], recent[n - 1].clone()));
            pending.remove(0);
        }
        if let Some(store) = &mut store {
            if k >= 2 {
                let spacing = (options.store_rel * t[k]).min(options.store_max);
                if t[k] - store.last_t > spacing * (1.0 + 1e-9) {
                    store.push(t[k - 1], &recent[n - 2]);
                }
            }
            if t[k] >= options.t_end * (1.0 - 1e-12) {
                store.push(t[k], &recent[n - 1]);
            }
        }
        if let Some(samples) = &mut samples {
            samples.push(t[k], &recent[n - 1]);
        }
        compress_s += tc.elapsed().as_secs_f64();
        progress(Step {
            k,
            t: t[k],
            h: hk,
            rank: recent[n - 1].max_rank(),
            sweeps: r.sweeps,
            history_rank: store.as_ref().map_or(0, |s| s.max_rank()),
        });
        if k > MAX_STEPS {
            return Err(CmePgdError::TimeGrid(format!(
                "more than {MAX_STEPS} time steps"
            )));
        }
    }
    report.steps = k;
    if let (Keep::Views { eps, .. }, Some(samples)) = (keep, samples) {
        let tc = std::time::Instant::now();
        report.stored = samples.nodes();
        let views = samples.finish(*eps);
        report.history_ranks = views.views.iter().map(|v| v.rank).collect();
        compress_s += tc.elapsed().as_secs_f64();
        report.compress_seconds = compress_s;
        report.solve_seconds = started.elapsed().as_secs_f64() - compress_s;
        return Ok((Kept::Views(views), report));
    }
    let (history, stored_t) = match store {
        Some(store) => store.finish(),
        None => stack_outputs(shown),
    };
    report.stored = stored_t.len();
    report.history_ranks = history.ranks();
    report.compress_seconds = compress_s;
    report.solve_seconds = started.elapsed().as_secs_f64() - compress_s;
    Ok((
        Kept::History(History {
            sizes,
            t: stored_t,
            params: coords,
            order,
            tt: history,
        }),
        report,
    ))
}

/// Checks the solver options; the error names every value and what is expected.
fn check(options: &Options) -> Result<(), CmePgdError> {
    let ok = options.t_end.is_finite()
        && options.t_end > 0.0
        && options.h_first > 0.0
        && options.h_max >= options.h_first
        && (1.0..=1.5).contains(&options.growth)
        && (0.0..1.0).contains(&options.eps)
        && (0.0..1.0).contains(&options.compress_eps)
        && options.weight_floor > 0.0
        && options.weight_floor.is_finite()
        && options.max_rank >= 1;
    if !ok {
        return Err(CmePgdError::TimeGrid(format!(
            // Debug prints 1e-300 as such, where Display writes 300 zeros.
            "t_end {:?}, first step {:?}, largest step {:?}, growth {:?}, eps {:?}, compress \
             eps {:?}, weight floor {:?}, max rank {}: expected t_end > 0, 0 < first ≤ largest, growth \
             in [1, 1.5], eps and compress eps in [0, 1) (relative), 0 < floor < ∞, rank ≥ 1",
            options.t_end,
            options.h_first,
            options.h_max,
            options.growth,
            options.eps,
            options.compress_eps,
            options.weight_floor,
            options.max_rank
        )));
    }
    // The step rule aims each step's local error at this: zero or less would shrink
    // every step to the first, and NaN compares false everywhere.
    if !(options.step_error_tol > 0.0 && options.step_error_tol < 1.0) {
        return Err(CmePgdError::Setting(format!(
            "step error tolerance {:?}: expected a relative error above 0 and below 1",
            options.step_error_tol
        )));
    }
    // No step is longer than the largest: refuse before stepping what cannot end.
    let fewest = options.t_end / options.h_max;
    if fewest > MAX_STEPS as f64 {
        return Err(CmePgdError::TimeGrid(format!(
            "t_end {:?} in steps of at most {:?} needs at least {fewest:.3e} steps; expected at \
             most {MAX_STEPS}: raise the largest step or shorten the time",
            options.t_end, options.h_max
        )));
    }
    Ok(())
}

/// The most BDF2 steps a solve takes: about 5 minutes for the toggle switch here
/// (1.4 ms a step to t = 10⁴), one stored state a step.
const MAX_STEPS: usize = 200_000;

/// The generator in the solver's axis order, as local terms and as an operator, and
/// the initial state.
struct Setup {
    terms: Vec<LocalTerm>,
    coords: Vec<(usize, Vec<f64>)>,
    order: Vec<Slot>,
    axis_sizes: Vec<usize>,
    generator_op: Mpo,
    p0: Tt,
}

fn setup(network: &Network, sizes: &[usize]) -> Setup {
    let (terms, coords) = generator(network, sizes);
    let order = slot_order(sizes.len(), coords.len());
    let natural = |slot: Slot| match slot {
        Slot::Species(i) => i,
        Slot::Param(q) => sizes.len() + q,
    };
    let terms: Vec<LocalTerm> = terms
        .into_iter()
        .map(|t| LocalTerm {
            coef: t.coef,
            factors: order
                .iter()
                .map(|&o| t.factors[natural(o)].clone())
                .collect(),
        })
        .collect();
    let axis_sizes: Vec<usize> = order
        .iter()
        .map(|&o| match o {
            Slot::Species(i) => sizes[i],
            Slot::Param(q) => coords[q].1.len(),
        })
        .collect();
    let generator_op = Mpo::from_terms(&axis_sizes, &terms);
    let p0 = Tt::rank_one(
        &order
            .iter()
            .map(|&o| match o {
                Slot::Species(i) => {
                    let m = sizes[i];
                    let mut v = vec![0.0; m];
                    v[network.species[i].initial.min(m - 1)] = 1.0;
                    v
                }
                Slot::Param(q) => vec![1.0; coords[q].1.len()],
            })
            .collect::<Vec<_>>(),
    );
    Setup {
        terms,
        coords,
        order,
        axis_sizes,
        generator_op,
        p0,
    }
}

/// Rank truncation does not conserve probability, and in d dimensions a small L2 error
/// can carry a large L1 mass (the all-ones tensor has norm Π√m_i). The exact step
/// conserves it: `c0⟨1, P_k⟩ − h⟨1, A P_k⟩ = ⟨1, rhs⟩` (`⟨1, A P⟩` is minus the FSP
/// leak rate). Rescales `x` to that balance, per parameter value where there is one
/// parameter axis.
#[allow(clippy::too_many_arguments)]
fn balance_mass(
    x: &mut Tt,
    rhs: &Tt,
    generator_op: &Mpo,
    order: &[Slot],
    c0: f64,
    hk: f64,
    report: &mut Report,
) {
    let (mass_rhs, mass_x, leak) = (
        masses(rhs, order),
        masses(x, order),
        masses(&generator_op.apply(x), order),
    );
    let ratio: Vec<f64> = (0..mass_x.len())
        .map(|i| {
            let target = (mass_rhs[i] + hk * leak[i]) / c0;
            if mass_x[i].abs() > 1e-300 {
                target / mass_x[i]
            } else {
                1.0
            }
        })
        .collect();
    for &q in &ratio {
        report.worst_mass_correction = report.worst_mass_correction.max((q - 1.0).abs());
    }
    scale_by_parameter(x, order, &ratio);
}

/// BDF2's local error estimate: about 2/9 of the distance between the newest state and
/// the quadratic extrapolation of the three before it (both O(h³)), relative to the
/// state; `t` holds the four times of `recent`'s last four states.
fn local_error(t: &[f64], recent: &[Tt]) -> f64 {
    let l = extrapolation_weights(t);
    let n = recent.len();
    let diff = Tt::sum(&[
        (1.0, &recent[n - 1]),
        (-l[0], &recent[n - 4]),
        (-l[1], &recent[n - 3]),
        (-l[2], &recent[n - 2]),
    ]);
    let state = recent[n - 1].norm().max(1e-300);
    2.0 / 9.0 * diff.norm() / state
}

/// The states at the requested output times stacked into one train over time.
fn stack_outputs(shown: Vec<(f64, Tt)>) -> (Tt, Vec<f64>) {
    let mut it = shown.into_iter().map(|(t, x)| (t, time_node(&x)));
    let (t0, first) = it.next().expect("the last output lands");
    it.fold((first, vec![t0]), |(acc, mut ts), (t, x)| {
        ts.push(t);
        (stack_in_time(&acc, &x), ts)
    })
}

/// Total probability: one value, or one per grid value when there is exactly one
/// parameter axis.
pub fn masses(x: &Tt, order: &[Slot]) -> Vec<f64> {
    let single = order.iter().filter(|o| matches!(o, Slot::Param(_))).count() == 1;
    // v[j][a]: partial sums for each value j of the open parameter (one row if none).
    let mut v: Vec<Vec<f64>> = vec![vec![1.0]];
    for (c, slot) in x.cores.iter().zip(order) {
        if single && matches!(slot, Slot::Param(_)) {
            v = (0..c.n)
                .map(|i| {
                    (0..c.r1)
                        .map(|b| (0..c.r0).map(|a| v[0][a] * c.at(a, i, b)).sum())
                        .collect()
                })
                .collect();
        } else {
            let m = c.contract(&vec![1.0; c.n]);
            for row in &mut v {
                *row = (0..c.r1)
                    .map(|b| (0..c.r0).map(|a| row[a] * m[a * c.r1 + b]).sum())
                    .collect();
            }
        }
    }
    v.into_iter().map(|row| row[0]).collect()
}

/// Multiplies by `ratio` (one value, or one per value of the single parameter axis).
fn scale_by_parameter(x: &mut Tt, order: &[Slot], ratio: &[f64]) {
    if ratio.len() == 1 {
        x.scale(ratio[0]);
        return;
    }
    let k = order
        .iter()
        .position(|o| matches!(o, Slot::Param(_)))
        .expect("one value per parameter grid value means one parameter axis");
    let c = &mut x.cores[k];
    for a in 0..c.r0 {
        for (i, q) in ratio.iter().enumerate() {
            for b in 0..c.r1 {
                c.v[(a * c.n + i) * c.r1 + b] *= q;
            }
        }
    }
}

/// The stored history, built as a binary counter of blocks of consecutive nodes: each
/// block is a tensor train over (its nodes, species…, parameters…); two blocks of equal
/// size merge (time cores stacked, other cores block-diagonal) and are rounded to `eps`
/// in a norm that tracks probability (see [`round_block`]). Rounding cost is then
/// dominated by the last few merges instead of one rounding at full rank per state.
struct Stored {
    eps: f64,
    floor: f64,
    order: Vec<Slot>,
    t: Vec<f64>,
    last_t: f64,
    /// Oldest first, sizes strictly decreasing.
    blocks: Vec<Block>,
}

struct Block {
    nodes: usize,
    tt: Tt,
    /// Per slot, the largest marginal over the block's nodes (empty for parameters).
    envelope: Vec<Vec<f64>>,
}

/// Rounds a block of states `X(t_j, z, p)` to `eps` in the norm
/// `‖diag(1/ν) ⊗ W X‖`, `W = ⊗_i diag(1/√(π̂_i + f))`, with `π̂_i(z)` the largest
/// marginal of species `i` at `z` over the block's states, `f = floor·max π̂_i`,
/// and `ν_j` the weighted norm of state `j`.
///
/// Why: in the plain L2 norm a truncation `E` with `‖E‖ ≤ ε‖X‖` can move
/// `⟨1, E⟩ ≤ ‖1‖·ε‖X‖` of probability, and in 20 dimensions `‖1‖·‖X‖` is about 10⁸
/// (measured: `compress_eps` 1e-4 left masses of −2 700 at t = 10). In the weighted
/// norm `⟨1, E_j⟩ = ⟨W⁻¹1, W E_j⟩ ≤ ‖W⁻¹1‖·‖W E_j‖`, where `‖W⁻¹1‖² = Π_i Σ_z (π̂_i + f)`
/// is the product of the envelopes' masses (1 for a species that does not move, a few
/// for one that does) and `ν_j ≤ 1` for states close to a product of their marginals
/// (`Σ_z π(z)²/π̂(z) ≤ Σ_z π(z)`). The error is then measured in probability. (The
/// block's *mean* marginal is not a safe weight: a state far from the mean gets a huge
/// `ν_j`, and its probability error with it; measured, t = 30 masses of 10².)
fn round_block(m: &mut Tt, envelope: &[Vec<f64>], eps: f64, floor: f64) {
    let mut weights = Vec::new();
    for (k, p) in envelope.iter().enumerate() {
        let top = p.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        if !(top > 0.0 && top.is_finite()) {
            continue;
        }
        let w: Vec<f64> = p
            .iter()
            .map(|x| 1.0 / (x.abs() + floor * top).sqrt())
            .collect();
        m.scale_axis(k + 1, &w);
        weights.push((k + 1, w));
    }
    m.orthogonalize_right();
    let time = &m.cores[0];
    let nu: Vec<f64> = time
        .v
        .chunks_exact(time.r1)
        .map(|row| row.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300))
        .collect();
    m.scale_axis(0, &nu.iter().map(|x| 1.0 / x).collect::<Vec<_>>());
    m.round_orthogonal(eps, usize::MAX);
    m.scale_axis(0, &nu);
    for (k, w) in weights {
        m.scale_axis(k, &w.iter().map(|x| 1.0 / x).collect::<Vec<_>>());
    }
}

/// `x` as a train over (one time node, slots…).
fn time_node(x: &Tt) -> Tt {
    let mut cores = vec![Core {
        r0: 1,
        n: 1,
        r1: 1,
        v: vec![1.0],
    }];
    cores.extend(x.cores.iter().cloned());
    Tt { cores }
}

/// The train over the nodes of `a` then of `b`.
fn stack_in_time(a: &Tt, b: &Tt) -> Tt {
    let (ta, tb) = (&a.cores[0], &b.cores[0]);
    let (na, nb) = (ta.n, tb.n);
    let r1 = ta.r1 + tb.r1;
    let mut time = Core::zeros(1, na + nb, r1);
    for i in 0..na {
        for q in 0..ta.r1 {
            time.v[i * r1 + q] = ta.v[i * ta.r1 + q];
        }
    }
    for i in 0..nb {
        for q in 0..tb.r1 {
            time.v[(na + i) * r1 + ta.r1 + q] = tb.v[i * tb.r1 + q];
        }
    }
    // The rest: block-diagonal cores (a sum of trains whose first core is the identity
    // on the stacked rank index).
    let rest = |x: &Tt| Tt {
        cores: x.cores[1..].to_vec(),
    };
    let (ra, rb) = (rest(a), rest(b));
    let d = ra.cores.len();
    let mut cores = vec![time];
    for k in 0..d {
        let (ca, cb) = (&ra.cores[k], &rb.cores[k]);
        let n = ca.n;
        let r0 = ca.r0 + cb.r0;
        let r1 = if k + 1 == d { 1 } else { ca.r1 + cb.r1 };
        let mut c = Core::zeros(r0, n, r1);
        for (x, off0, off1) in [(ca, 0, 0), (cb, ca.r0, if k + 1 == d { 0 } else { ca.r1 })] {
            for a0 in 0..x.r0 {
                for i in 0..n {
                    for b0 in 0..x.r1 {
                        c.v[((off0 + a0) * n + i) * r1 + off1 + b0] += x.at(a0, i, b0);
                    }
                }
            }
        }
        cores.push(c);
    }
    Tt { cores }
}

impl Stored {
    fn new(eps: f64, floor: f64, order: &[Slot], p0: &Tt) -> Self {
        let mut s = Stored {
            eps,
            floor,
            order: order.to_vec(),
            t: Vec::new(),
            last_t: 0.0,
            blocks: Vec::new(),
        };
        s.push(0.0, p0);
        s
    }

    fn push(&mut self, t: f64, x: &Tt) {
        let envelope = x
            .marginals()
            .into_iter()
            .zip(&self.order)
            .map(|(m, slot)| match slot {
                Slot::Species(_) => m,
                Slot::Param(_) => Vec::new(),
            })
            .collect();
        self.blocks.push(Block {
            nodes: 1,
            tt: time_node(x),
            envelope,
        });
        while self.blocks.len() >= 2
            && self.blocks[self.blocks.len() - 1].nodes == self.blocks[self.blocks.len() - 2].nodes
        {
            self.merge_last();
        }
        self.t.push(t);
        self.last_t = t;
    }

    fn merge_last(&mut self) {
        let b = self
            .blocks
            .pop()
            .expect("a merge is asked for only with two blocks or more");
        let a = self
            .blocks
            .pop()
            .expect("a merge is asked for only with two blocks or more");
        let envelope: Vec<Vec<f64>> = a
            .envelope
            .iter()
            .zip(&b.envelope)
            .map(|(x, y)| x.iter().zip(y).map(|(p, q)| p.abs().max(q.abs())).collect())
            .collect();
        let mut tt = stack_in_time(&a.tt, &b.tt);
        round_block(&mut tt, &envelope, self.eps, self.floor);
        self.blocks.push(Block {
            nodes: a.nodes + b.nodes,
            tt,
            envelope,
        });
    }

    /// The largest bond rank over the blocks.
    fn max_rank(&self) -> usize {
        self.blocks
            .iter()
            .map(|b| b.tt.max_rank())
            .max()
            .unwrap_or(0)
    }

    /// The history and the stored times.
    fn finish(mut self) -> (Tt, Vec<f64>) {
        while self.blocks.len() >= 2 {
            self.merge_last();
        }
        let last = self
            .blocks
            .pop()
            .expect("the initial state is never popped");
        (last.tt, self.t)
    }
}

fn mat_mul(a: &[f64], rows: usize, inner: usize, b: &[f64], cols: usize) -> Vec<f64> {
    let mut out = vec![0.0; rows * cols];
    for i in 0..rows {
        for k in 0..inner {
            let x = a[i * inner + k];
            if x == 0.0 {
                continue;
            }
            for j in 0..cols {
                out[i * cols + j] += x * b[k * cols + j];
            }
        }
    }
    out
}

impl History {
    /// The tensor train over the species at time `t` and parameter values `p` (one per
    /// parameter axis), interpolated linearly between nodes and clamped to the range.
    pub fn particularize(&self, t: f64, p: &[f64]) -> Tt {
        self.particularize_with(t, p, 4)
    }

    /// As [`Self::particularize`], with Lagrange interpolation through `points` nodes.
    /// The result's cores are the species in network order.
    pub fn particularize_with(&self, t: f64, p: &[f64], points: usize) -> Tt {
        let (wt, _) = lagrange_weights(&self.t, t, points);
        // `pending`: a matrix (rows × r) to multiply into the next species core.
        let c0 = &self.tt.cores[0];
        let mut pending: Option<(usize, Vec<f64>)> = Some((1, c0.contract(&wt)));
        let mut kept: Vec<(usize, Core)> = Vec::new();
        for (slot, core) in self.order.iter().zip(&self.tt.cores[1..]) {
            match *slot {
                Slot::Param(q) => {
                    let (w, _) = lagrange_weights(&self.params[q].1, p[q], points);
                    let m = core.contract(&w); // r0 × r1
                    pending = Some(match pending.take() {
                        Some((rows, l)) => (rows, mat_mul(&l, rows, core.r0, &m, core.r1)),
                        None => (core.r0, m),
                    });
                }
                Slot::Species(i) => {
                    let c = match pending.take() {
                        Some((rows, l)) => crate::tensor::tt::times_left(
                            faer::MatRef::from_row_major_slice(&l, rows, core.r0),
                            core,
                        ),
                        None => core.clone(),
                    };
                    kept.push((i, c));
                }
            }
        }
        if let Some((rows, l)) = pending {
            let last = kept.len() - 1;
            let c = &kept[last].1;
            let cols = l.len() / rows;
            kept[last].1 = crate::tensor::tt::times_right(
                c,
                faer::MatRef::from_row_major_slice(&l, rows, cols),
            );
        }
        kept.sort_by_key(|(i, _)| *i);
        // Species cores in network order are still a train only if the order kept them
        // contiguous, which slot_order does (parameters are contracted away).
        Tt {
            cores: kept.into_iter().map(|(_, c)| c).collect(),
        }
    }
}
