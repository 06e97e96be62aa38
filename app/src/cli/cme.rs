//! `palpa cme …`: gene-network models (the chemical master equation).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use palpa_core::cme::{Moments, Network, fsp, ssa};
use serde::Serialize;

#[derive(Debug, Subcommand)]
pub enum CmeCommand {
    /// Solve a network: exact FSP, stochastic simulation, or PGD.
    Solve(SolveArgs),
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
    #[arg(long, value_delimiter = ',', required = true)]
    t: Vec<f64>,
    /// SSA trajectories.
    #[arg(long, default_value_t = 10_000)]
    trajectories: usize,
    /// SSA seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// FSP: grow boxes (doubling) until the leak is below --max-leak.
    #[arg(long)]
    auto_box: bool,
    /// FSP: the leak above which the box is reported as too small.
    #[arg(long, default_value_t = 1e-6)]
    max_leak: f64,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
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
    #[serde(skip_serializing_if = "Option::is_none")]
    trajectories: Option<usize>,
    warnings: Vec<String>,
    seconds: f64,
}

/// A built-in name or a TOML file.
pub fn load_network(model: &str) -> anyhow::Result<Network> {
    let path = Path::new(model);
    if model.ends_with(".toml") || path.exists() {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {model}"))?;
        Ok(Network::from_toml(&text, model)?)
    } else {
        Ok(Network::built_in(model)?)
    }
}

fn parse_params(list: &[String]) -> anyhow::Result<Vec<(String, f64)>> {
    list.iter()
        .map(|s| {
            let (k, v) = s
                .split_once('=')
                .with_context(|| format!("--param {s:?}: expected NAME=VALUE"))?;
            let v: f64 = v
                .trim()
                .parse()
                .with_context(|| format!("--param {s:?}: {v:?} is not a number"))?;
            Ok((k.trim().to_string(), v))
        })
        .collect()
}

pub fn run(cmd: &CmeCommand) -> anyhow::Result<()> {
    match cmd {
        CmeCommand::Solve(args) => solve(args),
    }
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
    let start = Instant::now();
    let (method, moments, leaked, box_sizes, trajectories): (_, Vec<Moments>, _, _, _) = match args
        .method
    {
        Method::Fsp => {
            let (sol, met) = if args.auto_box {
                fsp::solve_auto(&network, &p, &args.t, args.max_leak)?
            } else {
                (fsp::solve(&network, &p, &args.t)?, true)
            };
            let worst = sol.leak.iter().copied().fold(0.0, f64::max);
            if worst > args.max_leak || !met {
                warnings.push(format!(
                    "the box {:?} leaks {worst:.2e} of the probability (> {:.0e}): results are truncated; \
                     enlarge the species' max or use --auto-box",
                    sol.sizes, args.max_leak
                ));
            }
            ("fsp", sol.moments, Some(sol.leak), Some(sol.sizes), None)
        }
        Method::Ssa => {
            if args.trajectories < 2 {
                bail!("--trajectories {}: expected at least 2", args.trajectories);
            }
            let sol = ssa::simulate(&network, &p, &args.t, args.trajectories, args.seed);
            if sol.truncated > 0 {
                warnings.push(format!(
                    "{} trajectories hit the event limit",
                    sol.truncated
                ));
            }
            ("ssa", sol.moments, None, None, Some(sol.trajectories))
        }
        Method::Pgd => bail!(
            "--method pgd is not implemented yet (the separated CME solver is the open part of \
             the gene-network issue); use fsp (exact, up to ~3 species) or ssa"
        ),
    };
    for w in &warnings {
        eprintln!("warning: {w}");
    }
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
        trajectories,
        warnings,
        seconds: start.elapsed().as_secs_f64(),
    };
    if args.json {
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
            println!("t = {t}: {}", parts.join(" · "));
        }
    }
    Ok(())
}
