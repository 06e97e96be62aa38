//! `palpa cme …`: gene-network models (the chemical master equation).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use palpa_core::cme::model::{self, CmeModel};
use palpa_core::cme::{Moments, Network, build, conservation, fsp, greedy, sizing, ssa, ttsolve};

use super::networks::network_file;
pub use super::networks::{load_network, parse_params};
use serde::Serialize;

#[derive(Debug, Subcommand)]
pub enum CmeCommand {
    /// Solve a network: exact FSP, stochastic simulation, or PGD.
    Solve(SolveArgs),
    /// Compute a network's PGD meta-model (species × time × parameters) into a file.
    Offline(OfflineArgs),
    /// Evaluate a CME meta-model file at a time and parameter values (no solving).
    Eval(EvalArgs),
    /// Read a network (SBML or TOML) and write it as palpa's TOML: what was understood.
    Convert(ConvertArgs),
    /// Snapshot data from exact sample paths: counts in single cells at a few times (CSV).
    Simulate(super::cme_fit::SimulateArgs),
    /// Fit a meta-model's rates to snapshot data: maximum likelihood, 95 % intervals,
    /// posterior (no solving).
    Fit(super::cme_fit::FitArgs),
}

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// An SBML (.xml, .sbml) or TOML network file.
    file: PathBuf,
    /// The TOML file to write (atomically); without it, the TOML goes to stdout.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Which off-line solver builds the meta-model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Solver {
    /// Tensor-train BDF2 steps (ALS with enrichment), ranks set by SVD: the default.
    Tt,
    /// Greedy rank-one PGD per step, history compressed into a separated sum.
    Greedy,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Keep {
    Auto,
    History,
    Views,
}

/// Time grid and solver settings shared by `offline`, `solve --method pgd` and
/// `bench cme`.
#[derive(Debug, Args)]
pub struct PgdArgs {
    /// [default: tt]
    #[arg(long, value_enum)]
    solver: Option<Solver>,
    /// End of the time axis (the model is valid on [0, T]).
    #[arg(long = "t-end")]
    t_end: Option<f64>,
    /// First time step [tt: 0.01, greedy: 0.02; cut to 0.1/a₀ where a₀ is the total
    /// propensity at the initial state, so that fast rates start with small steps].
    #[arg(long)]
    first_step: Option<f64>,
    /// Largest time step [tt: 5, greedy: 1].
    #[arg(long)]
    max_step: Option<f64>,
    /// Adaptive steps: relative local error per step [tt: 1e-6, greedy: 3e-5; greedy
    /// only: 0 = fixed geometric steps].
    #[arg(long)]
    step_error: Option<f64>,
    /// tt: relative SVD truncation of each step's state [history: 1e-8, views: 1e-6].
    #[arg(long)]
    eps: Option<f64>,
    /// tt: what the model keeps: the whole history over (t, species, parameters), or
    /// views (every marginal and chosen pairwise joints over t, what a scene shows)
    /// [auto: views for 5 or more species and no range parameters].
    #[arg(long, value_enum, default_value = "auto")]
    keep: Keep,
    /// views: the joints kept, "neighbours" (each species with the next), "none", or
    /// pairs of species names A:B, comma-separated (the first two species' joint is
    /// always kept: it gives their covariance).
    /// [default: neighbours]
    #[arg(long)]
    pairs: Option<String>,
    /// views: root-mean-square relative error of a stored time row [default: 1e-5].
    #[arg(long)]
    views_eps: Option<f64>,
    /// tt: relative truncation of each stored state in the history [default: 1e-6].
    #[arg(long)]
    compress_eps: Option<f64>,
    /// tt: floor of the history's probability weights, relative to each marginal's
    /// peak: small weighs the tails as much as the bulk (mass exact, ranks high),
    /// large approaches plain L2 (ranks low) [default: 0.01].
    #[arg(long)]
    weight_floor: Option<f64>,
    /// tt: largest rank of a step's state [default: 120].
    #[arg(long)]
    max_rank: Option<usize>,
    /// greedy: most terms of the final model [default: 400].
    #[arg(long)]
    modes: Option<usize>,
    /// greedy: relative L2 error of the compressed time history [default: 1e-5].
    #[arg(long)]
    tol: Option<f64>,
    /// greedy: relative residual of each implicit time step [default: 1e-6].
    #[arg(long)]
    step_tol: Option<f64>,
}

/// "--a shapes" or "--a, --b shape".
fn shape(flags: &[&str]) -> String {
    let verb = if flags.len() == 1 { "shapes" } else { "shape" };
    format!("{} {verb}", flags.join(", "))
}

/// The names of the flags marked given.
fn given(flags: &[(&'static str, bool)]) -> Vec<&'static str> {
    flags.iter().filter(|(_, g)| *g).map(|(n, _)| *n).collect()
}

/// A built meta-model and the solver's figures.
pub struct Built {
    pub built: build::Built,
    pub report: serde_json::Value,
}

impl Built {
    pub fn save(&self, network: &Network, out: &Path) -> anyhow::Result<()> {
        self.built
            .save(network, out)
            .with_context(|| format!("writing {}", out.display()))
    }
}

impl PgdArgs {
    /// The flags given that only the greedy solver reads.
    fn greedy_flags(&self) -> Vec<&'static str> {
        given(&[
            ("--modes", self.modes.is_some()),
            ("--tol", self.tol.is_some()),
            ("--step-tol", self.step_tol.is_some()),
        ])
    }

    /// The flags given that only the tensor-train solver reads.
    fn tt_flags(&self) -> Vec<&'static str> {
        given(&[
            ("--eps", self.eps.is_some()),
            ("--keep", self.keep != Keep::Auto),
            ("--pairs", self.pairs.is_some()),
            ("--views-eps", self.views_eps.is_some()),
            ("--compress-eps", self.compress_eps.is_some()),
            ("--weight-floor", self.weight_floor.is_some()),
            ("--max-rank", self.max_rank.is_some()),
        ])
    }

    /// Every solver flag given: none of them shapes an FSP or SSA solve.
    pub fn all_flags(&self) -> Vec<&'static str> {
        let mut all = given(&[
            ("--solver", self.solver.is_some()),
            ("--t-end", self.t_end.is_some()),
            ("--first-step", self.first_step.is_some()),
            ("--max-step", self.max_step.is_some()),
            ("--step-error", self.step_error.is_some()),
        ]);
        all.extend(self.tt_flags());
        all.extend(self.greedy_flags());
        all
    }

    pub fn options(&self, network: &Network, t_default: f64) -> greedy::Options {
        // The solver's own defaults are the one source; flags only override them.
        let d = greedy::Options::default();
        greedy::Options {
            t_end: self.t_end.unwrap_or(t_default),
            h_first: self
                .first_step
                .unwrap_or_else(|| sizing::first_step(network, d.h_first)),
            h_max: self.max_step.unwrap_or(d.h_max),
            max_modes: self.modes.unwrap_or(d.max_modes),
            compress_tol: self.tol.unwrap_or(d.compress_tol),
            step_tol: self.step_tol.unwrap_or(d.step_tol),
            step_error_tol: self.step_error.unwrap_or(d.step_error_tol),
            ..d
        }
    }

    /// The tensor-train build: the recipe's defaults for `network` (see
    /// [`build::Recipe::default_for`]), `--keep` and the flags given over them.
    /// `stored`: the model is kept (`cme offline`), so the views flags apply to it.
    pub fn recipe(
        &self,
        network: &Network,
        t_default: f64,
        stored: bool,
    ) -> anyhow::Result<build::Recipe> {
        let t_end = self.t_end.unwrap_or(t_default);
        let auto = build::Recipe::default_for(network, t_end);
        let views = match self.keep {
            Keep::Auto => auto.views.is_some(),
            Keep::History => false,
            Keep::Views => true,
        };
        let d = if views {
            build::Recipe::views_options(t_end)
        } else {
            ttsolve::Options {
                t_end,
                ..ttsolve::Options::default()
            }
        };
        let options = ttsolve::Options {
            t_end,
            h_first: self
                .first_step
                .unwrap_or_else(|| sizing::first_step(network, d.h_first)),
            h_max: self.max_step.unwrap_or(d.h_max),
            step_error_tol: self.step_error.unwrap_or(d.step_error_tol),
            eps: self.eps.unwrap_or(d.eps),
            compress_eps: self.compress_eps.unwrap_or(d.compress_eps),
            weight_floor: self.weight_floor.unwrap_or(d.weight_floor),
            max_rank: self.max_rank.unwrap_or(d.max_rank),
            ..d
        };
        // Named species are checked either way: a typo is an error, not a no-op.
        let pairs = parse_pairs(self.pairs.as_deref().unwrap_or("neighbours"), network)?;
        let eps = self.views_eps.unwrap_or(build::VIEWS_EPS);
        if !(eps > 0.0 && eps < 1.0) {
            bail!("--views-eps {eps}: expected a relative error above 0 and below 1");
        }
        let views = if views {
            Some(build::ViewOptions { pairs, eps })
        } else {
            if stored && (self.pairs.is_some() || self.views_eps.is_some()) {
                eprintln!(
                    "warning: --pairs and --views-eps shape a views model; this one keeps the \
                     whole history (--keep views keeps views)"
                );
            }
            None
        };
        Ok(build::Recipe { options, views })
    }

    /// Builds the meta-model of `network` on [0, t_end] (default `t_default`).
    pub fn build(&self, network: &Network, t_default: f64) -> anyhow::Result<Built> {
        self.build_for(network, t_default, None)
    }

    /// As [`Self::build`]; with `times`, the tensor-train solver keeps the states at
    /// those times only (no history to compress: what `cme solve` needs).
    pub fn build_for(
        &self,
        network: &Network,
        t_default: f64,
        times: Option<&[f64]>,
    ) -> anyhow::Result<Built> {
        let start = Instant::now();
        let network = &sized(network, self.t_end.unwrap_or(t_default))?;
        let solver = self.solver.unwrap_or(Solver::Tt);
        let (ignored, other) = match solver {
            Solver::Tt => (self.greedy_flags(), "greedy"),
            Solver::Greedy => (self.tt_flags(), "tt"),
        };
        if !ignored.is_empty() {
            eprintln!(
                "warning: {} the {other} solver only (--solver {other}); this build \
                 ignores it",
                shape(&ignored)
            );
        }
        let built = match solver {
            Solver::Greedy => run_pgd(network, &self.options(network, t_default))?,
            Solver::Tt => {
                let shaping =
                    self.pairs.is_some() || self.views_eps.is_some() || self.keep != Keep::Auto;
                if times.is_some() && shaping {
                    eprintln!(
                        "warning: --keep, --pairs and --views-eps shape a stored model (`palpa \
                         cme offline`); a solve keeps the states at its output times only"
                    );
                }
                let recipe = self.recipe(network, t_default, times.is_none())?;
                let o = recipe.options;
                let mut shown = Instant::now();
                let mut progress = |s: ttsolve::Step| {
                    // A progress line at most 4 times a second.
                    if shown.elapsed().as_secs_f64() < 0.25 && s.t < o.t_end {
                        return;
                    }
                    shown = Instant::now();
                    eprint!(
                        "\rstep {:>5}  t {:>9.3} / {}  h {:.2e}  rank {:>3}  history rank {:>3}   ",
                        s.k, s.t, o.t_end, s.h, s.rank, s.history_rank
                    );
                    let _ = std::io::stderr().flush();
                };
                let b = match times {
                    Some(times) => build::train(network, &o, Some(times), &mut progress)?,
                    None => recipe.build(network, None, &mut progress)?,
                };
                eprintln!();
                b
            }
        };
        let seconds = start.elapsed().as_secs_f64();
        let report = match &built.form {
            build::Form::Separated {
                model: m,
                report: r,
            } => serde_json::json!({
                "solver": "greedy",
                "terms": m.modes(),
                "compress_error": m.provenance().residual_per_mode.last().copied(),
                "steps": r.steps,
                "max_step_rank": r.max_step_rank,
                "worst_step_residual": r.worst_step_residual,
                "history_terms": r.history_terms,
                "seconds": seconds,
            }),
            build::Form::Train {
                history: h,
                report: r,
                ..
            } => serde_json::json!({
                "solver": "tt",
                "steps": r.steps,
                "stored_times": r.stored,
                "max_step_rank": r.max_rank,
                "history_ranks": r.history_ranks,
                "worst_local_residual": r.worst_local_residual,
                "worst_mass_correction": r.worst_mass_correction,
                "sweeps": r.sweeps,
                "gmres_iterations": r.gmres_iterations,
                "solve_seconds": r.solve_seconds,
                "compress_seconds": r.compress_seconds,
                "stored_values": h.tt.len(),
                "seconds": seconds,
            }),
            build::Form::Views {
                views: v,
                report: r,
                ..
            } => serde_json::json!({
                "solver": "tt",
                "keep": "views",
                "steps": r.steps,
                "stored_times": r.stored,
                "max_step_rank": r.max_rank,
                "view_ranks": r.history_ranks,
                "pairs": v.pairs(),
                "worst_local_residual": r.worst_local_residual,
                "worst_mass_correction": r.worst_mass_correction,
                "sweeps": r.sweeps,
                "solve_seconds": r.solve_seconds,
                "compress_seconds": r.compress_seconds,
                "stored_values": v.stored_values(),
                "seconds": seconds,
            }),
        };
        Ok(Built { built, report })
    }
}

#[derive(Debug, Args)]
pub struct OfflineArgs {
    /// A built-in network, or a TOML or SBML file.
    model: String,
    /// Make a rate a coordinate of the model: NAME=LO:HI[:POINTS], a linear grid of
    /// POINTS nodes [17] (repeatable; what a `range` in the TOML does, for an SBML file
    /// without editing it).
    #[arg(long = "range")]
    ranges: Vec<String>,
    #[command(flatten)]
    pgd: PgdArgs,
    /// Output meta-model file.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A CME meta-model file (from `palpa cme offline`).
    file: PathBuf,
    /// Times, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    t: Vec<f64>,
    /// Parameter values, NAME=VALUE (repeatable); outside the trained range: clamped and flagged.
    #[arg(long = "param")]
    params: Vec<String>,
    /// Use only the first n terms.
    #[arg(long)]
    modes: Option<usize>,
    /// Also solve this network (built-in name or TOML) exactly by FSP at the same time
    /// and parameters, and report the L1 distance of the joint distributions.
    #[arg(long, value_name = "MODEL")]
    check_fsp: Option<String>,
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Method {
    Fsp,
    Ssa,
    Pgd,
}

#[derive(Debug, Args)]
pub struct SolveArgs {
    /// A built-in network (toggle, cascade, signaling-cascade-D with D = 2..20) or a TOML file.
    model: String,
    #[arg(long, value_enum)]
    method: Method,
    /// Parameter values, NAME=VALUE (repeatable); ranges are clamped and flagged.
    #[arg(long = "param")]
    params: Vec<String>,
    /// Output times, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    t: Vec<f64>,
    /// SSA trajectories.
    #[arg(long, default_value_t = 10_000)]
    trajectories: usize,
    /// SSA seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// FSP: choose every species' box, declared maxima too, growing it as the
    /// distribution spreads until the leak stays below --max-leak.
    #[arg(long)]
    auto_box: bool,
    /// FSP: the leak above which the box is reported as too small (an automatic box
    /// grows until it leaks less).
    #[arg(long, default_value_t = fsp::DEFAULT_MAX_LEAK, allow_hyphen_values = true)]
    max_leak: f64,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    pgd: PgdArgs,
}

#[derive(Debug, Serialize)]
struct Report {
    model: String,
    method: &'static str,
    t: Vec<f64>,
    species: Vec<String>,
    parameters: Vec<(String, f64)>,
    mean: Vec<Vec<f64>>,
    var: Vec<Vec<f64>>,
    marginals: Vec<Vec<Vec<f64>>>,
    cov: Vec<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mean_se: Option<Vec<Vec<f64>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    var_se: Option<Vec<Vec<f64>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    leaked: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    box_sizes: Option<Vec<usize>>,
    /// FSP: the time from which the solution kept its shape; later times were not
    /// stepped to (`fsp::Settling`).
    #[serde(skip_serializing_if = "Option::is_none")]
    settled_at: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    trajectories: Option<usize>,
    /// `palpa cme eval --check-fsp`: L1 distance of the joint to FSP's at each time.
    #[serde(skip_serializing_if = "Option::is_none")]
    l1_joint_vs_fsp: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    most_negative: Option<Vec<f64>>,
    warnings: Vec<String>,
    seconds: f64,
    /// `palpa cme eval`: median time of one warm evaluation (µs), over repeated calls.
    #[serde(skip_serializing_if = "Option::is_none")]
    eval_us: Option<f64>,
}

/// `network` with a box for every species (an FSP pre-pass sizes the automatic ones),
/// saying on stderr how they were found.
pub fn sized(network: &Network, t_end: f64) -> anyhow::Result<Network> {
    let (sized, how) = sizing::with_boxes(network, t_end)?;
    if how != sizing::Sized::Given {
        eprintln!(
            "automatic boxes {:?} ({how:?})",
            sized
                .species
                .iter()
                .map(|s| (s.name.as_str(), s.max.unwrap_or(0)))
                .collect::<Vec<_>>()
        );
    }
    Ok(sized)
}

/// `--pairs`: "neighbours", "none" or `A:B,…` by species name, as network index pairs
/// `a < b`, always with the first two species' pair.
fn parse_pairs(list: &str, network: &Network) -> anyhow::Result<Vec<(usize, usize)>> {
    let d = network.species.len();
    let mut pairs: Vec<(usize, usize)> = match list.trim() {
        "neighbours" | "neighbors" => (1..d).map(|i| (i - 1, i)).collect(),
        "none" | "" => Vec::new(),
        list => list
            .split(',')
            .map(|pair| {
                let index = |name: &str| {
                    network
                        .species
                        .iter()
                        .position(|s| s.name == name.trim())
                        .with_context(|| {
                            format!(
                                "--pairs {pair:?}: no species {name:?}; the species are {}",
                                network
                                    .species
                                    .iter()
                                    .map(|s| s.name.as_str())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            )
                        })
                };
                let (a, b) = pair.split_once(':').with_context(|| {
                    format!("--pairs {pair:?}: expected two species names as A:B")
                })?;
                let (a, b) = (index(a)?, index(b)?);
                if a == b {
                    bail!("--pairs {pair:?}: expected two different species");
                }
                Ok((a.min(b), a.max(b)))
            })
            .collect::<anyhow::Result<_>>()?,
    };
    if d >= 2 {
        pairs.push((0, 1));
    }
    pairs.sort_unstable();
    pairs.dedup();
    Ok(pairs)
}

pub fn run(cmd: &CmeCommand) -> anyhow::Result<()> {
    match cmd {
        CmeCommand::Solve(args) => solve(args),
        CmeCommand::Offline(args) => offline(args),
        CmeCommand::Eval(args) => eval(args),
        CmeCommand::Convert(args) => convert(args),
        CmeCommand::Simulate(args) => super::cme_fit::simulate(args),
        CmeCommand::Fit(args) => super::cme_fit::fit_command(args),
    }
}

fn convert(args: &ConvertArgs) -> anyhow::Result<()> {
    let name = args.file.display().to_string();
    let network = network_file(&args.file)?;
    let toml = format!("# converted by palpa from {name}\n{}", network.to_toml());
    match &args.out {
        Some(out) => palpa_core::fsutil::atomic_write(out, |w| w.write_all(toml.as_bytes()))
            .with_context(|| format!("writing {}", out.display()))?,
        None => print!("{toml}"),
    }
    Ok(())
}

fn solve(args: &SolveArgs) -> anyhow::Result<()> {
    let network = load_network(&args.model)?;
    let (p, mut warnings) = network.parameter_values(&parse_params(&args.params)?)?;
    if !(args.t.iter().all(|t| t.is_finite() && *t >= 0.0)
        && args.t.windows(2).all(|w| w[0] < w[1]))
    {
        bail!(
            "--t {:?}: expected finite times ≥ 0 in increasing order",
            args.t
        );
    }
    if !(args.max_leak > 0.0 && args.max_leak < 1.0) {
        bail!(
            "--max-leak {}: expected a probability between 0 and 1",
            args.max_leak
        );
    }
    if args.method != Method::Pgd {
        let ignored = args.pgd.all_flags();
        if !ignored.is_empty() {
            warnings.push(format!(
                "{} the PGD solver only (--method pgd); this solve ignores it",
                shape(&ignored)
            ));
        }
    }
    let start = Instant::now();
    let mut settled_at = None;
    let (method, moments, leaked, box_sizes, trajectories): (_, Vec<Moments>, _, _, _) = match args
        .method
    {
        Method::Fsp => {
            let auto = network.species.iter().any(|s| s.max.is_none());
            let (sol, met) = if args.auto_box {
                // A declared max is a box too: --auto-box chooses them all.
                let mut open = network.clone();
                open.species.iter_mut().for_each(|s| s.max = None);
                fsp::solve_auto(&open, &p, &args.t, args.max_leak)?
            } else if auto {
                fsp::solve_auto(&network, &p, &args.t, args.max_leak)?
            } else {
                (fsp::solve(&network, &p, &args.t)?, true)
            };
            let worst = sol.leak.iter().copied().fold(0.0, f64::max);
            if worst > args.max_leak || !met {
                let what_next = if args.auto_box || auto {
                    format!(
                        "the box could grow no further (at most {} states)",
                        fsp::MAX_STATES
                    )
                } else {
                    "enlarge the species' max or use --auto-box".to_string()
                };
                warnings.push(format!(
                    "the box {:?} leaks {worst:.2e} of the probability (> {:.0e}): results are \
                     truncated; {what_next}",
                    sol.sizes, args.max_leak
                ));
            }
            settled_at = sol.settled_at;
            ("fsp", sol.moments, Some(sol.leak), Some(sol.sizes), None)
        }
        Method::Ssa => {
            if args.trajectories < 2 {
                bail!("--trajectories {}: expected at least 2", args.trajectories);
            }
            // Each path keeps its state at every output time (and the moments a copy).
            let bytes =
                args.trajectories as f64 * (args.t.len() * network.species.len()) as f64 * 16.0;
            let available = super::memory::available_bytes().map_or(f64::INFINITY, |b| b as f64);
            if bytes > 0.5 * available {
                bail!(
                    "--trajectories {}: {:.1} GB of recorded states, {:.1} GB of memory available: \
                     expected a run that fits in half of it",
                    args.trajectories,
                    bytes / 1e9,
                    available / 1e9
                );
            }
            let sol = ssa::simulate(&network, &p, &args.t, args.trajectories, args.seed);
            if let Some(why) = &sol.overflow {
                bail!("{why}");
            }
            if sol.truncated > 0 {
                warnings.push(format!(
                    "{} of {} trajectories were stopped by the event limit ({:.0e} reactions a \
                     path, {:.0e} a run) and hold the state where they stopped: these moments \
                     are not the CME's; the rates times the time are too large for SSA (use \
                     --method fsp or pgd)",
                    sol.truncated,
                    sol.trajectories,
                    ssa::MAX_EVENTS as f64,
                    ssa::MAX_RUN_EVENTS as f64
                ));
            }
            ("ssa", sol.moments, None, None, Some(sol.trajectories))
        }
        Method::Pgd => {
            let t_end = args.t.last().copied().unwrap_or(1.0).max(1e-3);
            if let Some(end) = args.pgd.t_end
                && !end.is_finite()
            {
                bail!("--t-end {end}: expected a finite end time");
            }
            if let Some(end) = args.pgd.t_end
                && end < t_end
            {
                // The model would be clamped at its end: answers at the wrong time.
                bail!(
                    "--t-end {end}: the solve must reach the last output time {}; leave \
                     --t-end out (it defaults to that time)",
                    time_text(t_end)
                );
            }
            // A conserved pair is solved with one species less and expanded back.
            let reduced = conservation::reduce(&network);
            if let Some(r) = &reduced {
                eprintln!(
                    "{} = {} {:+} · {} (conserved): solved without it",
                    network.species[r.eliminated].name,
                    r.offset,
                    r.slope,
                    network.species[r.from].name
                );
            }
            let solved = reduced.as_ref().map_or(&network, |r| &r.network);
            // Output times steer the time grid; asked only at t = 0 (the initial law),
            // any grid answers it.
            let steer = args.t.last().is_some_and(|&t| t > 0.0);
            let model = args
                .pgd
                .build_for(solved, t_end, steer.then_some(&args.t[..]))?
                .built
                .model;
            let set = model_coordinates(&model, &network, &p);
            let mut out = Vec::new();
            for &t in &args.t {
                let e = model.evaluate(t, &set, usize::MAX)?;
                if e.most_negative < -1e-8 {
                    warnings.push(format!(
                        "t = {}: most negative probability {:.2e}",
                        time_text(t),
                        e.most_negative
                    ));
                }
                out.push(match &reduced {
                    Some(r) => r.expand(&e.moments),
                    None => e.moments,
                });
            }
            ("pgd", out, None, None, None)
        }
    };
    let report = Report {
        model: network.name.clone(),
        method,
        t: args.t.clone(),
        species: network.species.iter().map(|s| s.name.clone()).collect(),
        parameters: network
            .parameters
            .iter()
            .map(|q| q.name.clone())
            .zip(p.iter().copied())
            .collect(),
        mean: moments.iter().map(|m| m.mean.clone()).collect(),
        var: moments.iter().map(|m| m.var.clone()).collect(),
        marginals: moments.iter().map(|m| m.marginals.clone()).collect(),
        cov: moments.iter().map(|m| m.cov01).collect(),
        mean_se: moments.iter().map(|m| m.mean_se.clone()).collect(),
        var_se: moments.iter().map(|m| m.var_se.clone()).collect(),
        leaked,
        box_sizes,
        settled_at,
        trajectories,
        l1_joint_vs_fsp: None,
        most_negative: None,
        warnings,
        seconds: start.elapsed().as_secs_f64(),
        eval_us: None,
    };
    print_report(&report, args.json)
}

fn print_report(report: &Report, json: bool) -> anyhow::Result<()> {
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if json {
        println!(
            "{}",
            serde_json::to_string(&report).context("encoding the report")?
        );
    } else {
        println!(
            "{} by {} in {:.3} s",
            report.model, report.method, report.seconds
        );
        for (j, t) in report.t.iter().enumerate() {
            let parts: Vec<String> = report
                .species
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    format!(
                        "{s}: mean {:.3} var {:.3}",
                        report.mean[j][i], report.var[j][i]
                    )
                })
                .collect();
            println!("t = {}: {}", time_text(*t), parts.join(" · "));
        }
        if let Some(at) = report.settled_at {
            println!(
                "settled at t ≈ {at:.4e}: its shape no longer changed (L1 < {:.0e} a step), \
                 so later times keep it, their mass decaying at its leak rate",
                fsp::SETTLE_L1
            );
        }
    }
    Ok(())
}

/// The values `p` of the network's parameters that are coordinates of `model`.
pub fn model_coordinates(model: &CmeModel, network: &Network, p: &[f64]) -> Vec<(String, f64)> {
    model
        .parameters()
        .iter()
        .filter_map(|(name, _, _)| {
            let q = network.parameters.iter().position(|x| &x.name == name)?;
            Some((name.clone(), p[q]))
        })
        .collect()
}

/// Runs the greedy PGD with a progress line on stderr.
fn run_pgd(network: &Network, options: &greedy::Options) -> anyhow::Result<build::Built> {
    let start = Instant::now();
    let max = options.max_modes;
    let out = build::greedy(network, options, &mut |p| {
        match p {
            greedy::Progress::Step {
                k,
                n,
                rank,
                residual,
            } => {
                let per = start.elapsed().as_secs_f64() / k as f64;
                eprint!(
                    "\rstep {k:>5}/{n}  rank {rank:>3}  residual {residual:.1e}  ETA ≈ {:.0} s   ",
                    per * (n - k) as f64
                );
            }
            greedy::Progress::Compress { terms, residual } => {
                eprint!(
                    "\rcompressing the history: {terms:>4}/{max} terms, error {residual:.2e}          "
                );
            }
        }
        let _ = std::io::stderr().flush();
    })?;
    eprintln!();
    Ok(out)
}

/// `--range NAME=LO:HI[:POINTS]` applied to `network`'s parameters.
fn apply_ranges(network: &mut Network, ranges: &[String]) -> anyhow::Result<()> {
    for spec in ranges {
        let expected = "expected NAME=LO:HI or NAME=LO:HI:POINTS, e.g. delta=0.01:0.05:17";
        let (name, rest) = spec
            .split_once('=')
            .with_context(|| format!("--range {spec:?}: {expected}"))?;
        let parts: Vec<&str> = rest.split(':').collect();
        let num = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
        let (lo, hi, points) = match parts[..] {
            [lo, hi] => (num(lo), num(hi), Some(17)),
            [lo, hi, n] => (num(lo), num(hi), n.trim().parse::<usize>().ok()),
            _ => (None, None, None),
        };
        let (Some(lo), Some(hi), Some(points)) = (lo, hi, points) else {
            bail!("--range {spec:?}: {expected}");
        };
        if !(0.0 <= lo && lo < hi) || points < 2 {
            bail!("--range {spec:?}: expected 0 ≤ LO < HI and at least 2 POINTS");
        }
        let known = network
            .parameters
            .iter()
            .map(|p| p.name.clone())
            .collect::<Vec<_>>()
            .join(", ");
        let p = network
            .parameters
            .iter_mut()
            .find(|p| p.name == name)
            .with_context(|| {
                format!("--range {spec:?}: no parameter {name:?}; the network has {known}")
            })?;
        p.range = Some((lo, hi, points));
        p.spacing = palpa_core::cme::network::Spacing::Linear;
        if !(lo..=hi).contains(&p.value) {
            p.value = 0.5 * (lo + hi);
        }
    }
    Ok(())
}

fn offline(args: &OfflineArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    let mut network = load_network(&args.model)?;
    apply_ranges(&mut network, &args.ranges)?;
    let built = args.pgd.build(&network, 300.0)?;
    built.save(&network, &args.out)?;
    let mut report = built.report;
    report["out"] = serde_json::json!(args.out);
    report["model"] = serde_json::json!(network.name);
    report["representation"] = serde_json::json!(built.built.model.describe());
    report["bytes"] = serde_json::json!(std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0));
    println!("{report}");
    Ok(())
}

fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    let model =
        model::load(&args.file).with_context(|| format!("loading {}", args.file.display()))?;
    let set = parse_params(&args.params)?;
    if args.modes == Some(0) {
        bail!("--modes 0: expected at least one term");
    }
    let n = args.modes.unwrap_or(usize::MAX);
    let start = Instant::now();
    let mut moments = Vec::new();
    let mut negatives = Vec::new();
    let mut warnings = Vec::new();
    for &t in &args.t {
        if t > model.t_end() {
            warnings.push(format!(
                "t = {} is past the model's time range [0, {}]: clamped to its end",
                time_text(t),
                model.t_end()
            ));
        }
        let e = model.evaluate(t, &set, n)?;
        for name in e.clamped.iter().filter(|c| *c != "t") {
            warnings.push(format!(
                "{name} is outside its trained range: clamped, not extrapolated"
            ));
        }
        if e.most_negative < -1e-8 {
            warnings.push(format!(
                "t = {}: most negative probability {:.2e}",
                time_text(t),
                e.most_negative
            ));
        }
        negatives.push(e.most_negative);
        moments.push(e.moments);
    }
    let seconds = start.elapsed().as_secs_f64();
    let eval_us = warm_eval_us(&model, &args.t, &set, n)?;
    let names = model.species_names();
    let parameters = model
        .parameters()
        .into_iter()
        .map(|(name, lo, hi)| {
            let v = set
                .iter()
                .rev()
                .find(|(p, _)| *p == name)
                .map_or(0.5 * (lo + hi), |(_, v)| v.clamp(lo, hi));
            (name, v)
        })
        .collect();
    let report = Report {
        model: args.file.display().to_string(),
        method: "pgd",
        t: args.t.clone(),
        species: names,
        parameters,
        mean: moments.iter().map(|m| m.mean.clone()).collect(),
        var: moments.iter().map(|m| m.var.clone()).collect(),
        marginals: moments.iter().map(|m| m.marginals.clone()).collect(),
        cov: moments.iter().map(|m| m.cov01).collect(),
        mean_se: None,
        var_se: None,
        leaked: Some(moments.iter().map(|m| 1.0 - m.mass).collect()),
        box_sizes: None,
        settled_at: None,
        trajectories: None,
        l1_joint_vs_fsp: None,
        most_negative: Some(negatives),
        warnings,
        seconds,
        eval_us: Some(eval_us),
    };
    let report = match &args.check_fsp {
        Some(name) => Report {
            l1_joint_vs_fsp: Some(check_fsp(&model, name, &report.parameters, &args.t, n)?),
            ..report
        },
        None => report,
    };
    print_report(&report, args.json)
}

/// Median of 201 warm evaluations (µs), cycling through `times`: what an interactive
/// caller pays per slider move once the file is loaded.
fn warm_eval_us(
    model: &CmeModel,
    times: &[f64],
    set: &[(String, f64)],
    n: usize,
) -> anyhow::Result<f64> {
    let mut us = Vec::with_capacity(201);
    for k in 0..201 {
        let t = times[k % times.len()];
        let start = Instant::now();
        std::hint::black_box(model.evaluate(std::hint::black_box(t), set, n)?);
        us.push(start.elapsed().as_secs_f64() * 1e6);
    }
    us.sort_by(f64::total_cmp);
    Ok(us[us.len() / 2])
}

/// L1 distance between the model's joint and FSP's on the same box, at each time.
fn check_fsp(
    model: &CmeModel,
    name: &str,
    params: &[(String, f64)],
    times: &[f64],
    n: usize,
) -> anyhow::Result<Vec<f64>> {
    let network = load_network(name)?;
    let (p, _) = network.parameter_values(params)?;
    let sizes = model.box_sizes();
    let exact = fsp::solve_on(&network, &p, &sizes, times)?;
    times
        .iter()
        .zip(&exact.joint)
        .map(|(&t, q)| {
            let joint = model.joint(t, params, n)?;
            Ok(palpa_core::cme::moments::l1(&joint, q))
        })
        .collect()
}

/// A time as people read it: plain where it is, scientific when tiny or huge (a time of
/// 1e-300 printed plainly is three hundred zeros).
fn time_text(t: f64) -> String {
    if t == 0.0 || (1e-4..1e7).contains(&t.abs()) {
        format!("{t}")
    } else {
        format!("{t:e}")
    }
}
