//! `palpa cme simulate` (snapshot data from exact sample paths) and `palpa cme fit`
//! (rates from data through a meta-model).

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::cme::fit::data::Snapshots;
use palpa_core::cme::fit::likelihood::{self, MetaLikelihood, Observations};
use palpa_core::cme::fit::{self, Rate, posterior};
use palpa_core::cme::model::{self, CmeModel};
use palpa_core::cme::{Network, ssa};
use serde_json::{Value, json};

use super::networks::{load_network, parse_params};

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// A built-in network, a TOML or SBML file, or a meta-model file (.palpa: the
    /// network it was built from).
    model: String,
    /// Rates, NAME=VALUE (repeatable); the others take the network's values.
    #[arg(long = "param")]
    params: Vec<String>,
    /// Measurement times, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    t: Vec<f64>,
    /// Cells measured at each time (each cell is its own sample path).
    #[arg(long)]
    cells: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The species counted, comma-separated [default: every species].
    #[arg(long, value_delimiter = ',')]
    observe: Vec<String>,
    /// The CSV file to write (atomically): `t,<species>…`, one row per cell.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, Args)]
pub struct FitArgs {
    /// A gene-network meta-model (`palpa cme offline` with range parameters).
    file: PathBuf,
    /// Snapshot data: CSV `t,<species>…`, one row per cell.
    #[arg(long)]
    data: PathBuf,
    /// The rates to fit, comma-separated [default: every range parameter].
    #[arg(long, value_delimiter = ',')]
    fit: Vec<String>,
    /// Values of range parameters not fitted, NAME=VALUE [default: the network's].
    #[arg(long = "param")]
    params: Vec<String>,
    /// Metropolis–Hastings steps per chain (a quarter of them warm-up).
    #[arg(long)]
    posterior: Option<usize>,
    #[arg(long, default_value_t = 4)]
    chains: usize,
    /// Seed of the chains.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also fit by the exact FSP likelihood (a solve per evaluation: slow) and report
    /// how far its maximum is from the meta-model's, in interval widths.
    #[arg(long)]
    check_fsp: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// The network a meta-model file was built from (kept in its provenance).
pub fn model_network(model: &CmeModel, name: &str) -> anyhow::Result<Network> {
    let text = model.meta().provenance.network;
    if text.is_empty() {
        bail!("{name} does not hold the network it was built from");
    }
    Ok(Network::from_toml(&text, name)?)
}

pub fn simulate(args: &SimulateArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    let network = if args.model.ends_with(".palpa") {
        let m = model::load(std::path::Path::new(&args.model))
            .with_context(|| format!("loading {}", args.model))?;
        model_network(&m, &args.model)?
    } else {
        load_network(&args.model)?
    };
    let set = parse_params(&args.params)?;
    // Validated by the network, but not clamped to a range: data may come from anywhere.
    network.parameter_values(
        &set.iter()
            .map(|(n, _)| (n.clone(), 0.0))
            .collect::<Vec<_>>(),
    )?;
    let mut p: Vec<f64> = network.parameters.iter().map(|q| q.value).collect();
    for (name, v) in &set {
        if !(v.is_finite() && *v >= 0.0) {
            bail!("--param {name}={v}: expected a finite rate ≥ 0");
        }
        if let Some(i) = network.parameters.iter().position(|q| &q.name == name) {
            p[i] = *v;
        }
    }
    if args.t.is_empty()
        || !args.t.iter().all(|t| t.is_finite() && *t >= 0.0)
        || !args.t.windows(2).all(|w| w[0] < w[1])
    {
        bail!(
            "--t {:?}: expected finite times ≥ 0 in increasing order",
            args.t
        );
    }
    if args.cells == 0 {
        bail!("--cells 0: expected at least one cell at each time");
    }
    let names: Vec<String> = network.species.iter().map(|s| s.name.clone()).collect();
    let observe: Vec<usize> = if args.observe.is_empty() {
        (0..names.len()).collect()
    } else {
        args.observe
            .iter()
            .map(|s| {
                names.iter().position(|n| n == s).with_context(|| {
                    format!(
                        "--observe {s:?}: no such species; the species are {}",
                        names.join(", ")
                    )
                })
            })
            .collect::<anyhow::Result<_>>()?
    };
    let start = Instant::now();
    let mut cells = Vec::with_capacity(args.t.len());
    for (k, &t) in args.t.iter().enumerate() {
        // Each time its own cells: a snapshot destroys what it measures.
        let seed = args.seed ^ (k as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03);
        let paths = ssa::paths(&network, &p, &[t], args.cells, seed, ssa::MAX_RUN_EVENTS);
        if let Some(why) = &paths.overflow {
            bail!("{why}");
        }
        if paths.truncated > 0 {
            bail!(
                "t = {t}: {} of {} sample paths hit the event bound ({} reactions a path): the \
                 rates are too fast to simulate to this time",
                paths.truncated,
                args.cells,
                ssa::MAX_EVENTS
            );
        }
        cells.push(
            paths
                .states
                .iter()
                .map(|s| {
                    observe
                        .iter()
                        .map(|&i| s[0][i].clamp(0, u32::MAX as i64) as u32)
                        .collect()
                })
                .collect::<Vec<Vec<u32>>>(),
        );
    }
    let data = Snapshots {
        species: observe.iter().map(|&i| names[i].clone()).collect(),
        times: args.t.clone(),
        cells,
    };
    let text = format!(
        "# palpa cme simulate {}: {} cells at each time, seed {}, rates {}\n{}",
        network.name,
        args.cells,
        args.seed,
        network
            .parameters
            .iter()
            .zip(&p)
            .map(|(q, v)| format!("{}={v}", q.name))
            .collect::<Vec<_>>()
            .join(" "),
        data.to_csv()
    );
    palpa_core::fsutil::atomic_write(&args.out, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", args.out.display()))?;
    let means: Vec<Vec<f64>> = data
        .cells
        .iter()
        .map(|c| {
            (0..observe.len())
                .map(|j| c.iter().map(|x| f64::from(x[j])).sum::<f64>() / c.len() as f64)
                .collect()
        })
        .collect();
    println!(
        "{}",
        json!({
            "out": args.out,
            "model": network.name,
            "parameters": network.parameters.iter().zip(&p)
                .map(|(q, v)| (q.name.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "t": args.t,
            "cells_per_time": args.cells,
            "observed": data.species,
            "mean": means,
            "seed": args.seed,
            "seconds": start.elapsed().as_secs_f64(),
        })
    );
    Ok(())
}

/// The rates a fit moves and the full parameter vector it fills.
struct Problem {
    rates: Vec<Rate>,
    /// Model parameter index of each fitted rate.
    slots: Vec<usize>,
    /// Every model parameter's value (the fitted ones overwritten per call).
    theta: Vec<f64>,
    names: Vec<String>,
}

impl Problem {
    fn new(
        model: &CmeModel,
        network: &Network,
        fit: &[String],
        fixed: &[(String, f64)],
    ) -> anyhow::Result<Self> {
        let params = model.parameters();
        let names: Vec<String> = params.iter().map(|p| p.0.clone()).collect();
        let known = names.join(", ");
        let chosen: Vec<String> = if fit.is_empty() {
            names.clone()
        } else {
            fit.to_vec()
        };
        let mut slots = Vec::new();
        for name in &chosen {
            let i =
                names
                    .iter()
                    .position(|n| n == name)
                    .ok_or_else(|| fit::FitError::UnknownRate {
                        name: name.clone(),
                        known: known.clone(),
                    })?;
            if slots.contains(&i) {
                bail!("--fit {name} twice");
            }
            slots.push(i);
        }
        let mut theta = Vec::new();
        for (name, lo, hi) in &params {
            let given = fixed.iter().rev().find(|(n, _)| n == name).map(|(_, v)| *v);
            if given.is_some() && chosen.contains(name) {
                bail!("--param {name}: the rate is fitted; leave it out of --fit to fix it");
            }
            let v = match given {
                Some(v) => v,
                None => network
                    .parameters
                    .iter()
                    .find(|q| &q.name == name)
                    .map_or(0.5 * (lo + hi), |q| q.value),
            };
            if !(v.is_finite() && (*lo..=*hi).contains(&v)) {
                bail!("{name} = {v}: a fixed rate must lie in the model's range [{lo}, {hi}]");
            }
            theta.push(v);
        }
        for (name, _) in fixed {
            if !names.contains(name) {
                return Err(fit::FitError::UnknownRate {
                    name: name.clone(),
                    known,
                }
                .into());
            }
        }
        let rates = slots
            .iter()
            .map(|&i| Rate {
                name: params[i].0.clone(),
                lo: params[i].1,
                hi: params[i].2,
            })
            .collect();
        Ok(Problem {
            rates,
            slots,
            theta,
            names,
        })
    }

    fn theta(&self, x: &[f64]) -> Vec<f64> {
        let mut t = self.theta.clone();
        for (&i, &v) in self.slots.iter().zip(x) {
            t[i] = v;
        }
        t
    }

    /// The named values of every model parameter at the fitted `x`.
    fn named(&self, x: &[f64]) -> Vec<(String, f64)> {
        self.names.iter().cloned().zip(self.theta(x)).collect()
    }
}

/// Median µs of `f` over `n` calls.
fn median_us(n: usize, mut f: impl FnMut()) -> f64 {
    let mut us: Vec<f64> = (0..n)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    us.sort_by(f64::total_cmp);
    us[us.len() / 2]
}

pub fn fit_command(args: &FitArgs) -> anyhow::Result<()> {
    let name = args.file.display().to_string();
    let model = model::load(&args.file).with_context(|| format!("loading {name}"))?;
    let network = model_network(&model, &name)?;
    let data = Snapshots::read(&args.data)?;
    let history = model
        .history()
        .ok_or_else(|| fit::FitError::NotTrain(model.describe()))?;
    let obs = Observations::new(
        &data,
        &model.species_names(),
        &model.box_sizes(),
        model.t_end(),
    )?;
    let prep_start = Instant::now();
    let meta = MetaLikelihood::new(history, &obs)?;
    let prepare_seconds = prep_start.elapsed().as_secs_f64();
    let problem = Problem::new(&model, &network, &args.fit, &parse_params(&args.params)?)?;
    let mut scratch = Vec::new();
    let mut loglik = |x: &[f64]| meta.log_likelihood(&problem.theta(x), &mut scratch).value;
    let start = Instant::now();
    let result = fit::fit(&mut loglik, &problem.rates);
    let fit_seconds = start.elapsed().as_secs_f64();
    let mle: Vec<f64> = result.estimates.iter().map(|e| e.mle).collect();
    let mut own = Vec::new();
    let at_mle = meta.log_likelihood(&problem.theta(&mle), &mut own);
    let likelihood_us = median_us(201, || {
        std::hint::black_box(meta.log_likelihood(&problem.theta(&mle), &mut own));
    });
    // The same likelihood by exact FSP on the model's box, timed in the same run.
    let sizes = model.box_sizes();
    let network_p = |x: &[f64]| -> anyhow::Result<Vec<f64>> {
        Ok(network.parameter_values(&problem.named(x))?.0)
    };
    let p_mle = network_p(&mle)?;
    let mut exact = None;
    let fsp_likelihood_us = median_us(3, || {
        exact = Some(likelihood::exact_log_likelihood(
            &network, &p_mle, &sizes, &obs,
        ));
    });
    let exact = exact.context("timed at least once")??;
    let posterior_report = match args.posterior {
        None => Value::Null,
        Some(steps) => {
            if steps < 40 || args.chains < 2 {
                bail!(
                    "--posterior {steps} --chains {}: expected at least 40 steps and 2 chains \
                     (R-hat compares chains)",
                    args.chains
                );
            }
            let s = Instant::now();
            let post = fit::sample(
                &mut loglik,
                &problem.rates,
                &result,
                posterior::Options {
                    chains: args.chains,
                    steps,
                    seed: args.seed,
                },
            );
            json!({
                "chains": post.chains,
                "steps": post.steps,
                "warmup": post.warmup,
                "acceptance": post.acceptance,
                "evaluations": post.evaluations,
                "seconds": s.elapsed().as_secs_f64(),
                "rates": post.rates.iter().map(|r| (r.name.clone(), json!({
                    "mean": r.mean, "sd": r.sd, "ci95": r.ci95, "rhat": r.rhat, "ess": r.ess,
                }))).collect::<serde_json::Map<_, _>>(),
            })
        }
    };
    let check = if args.check_fsp {
        let s = Instant::now();
        let mut failed = None;
        let mut exact_loglik =
            |x: &[f64]| match network_p(x).map_err(|e| e.to_string()).and_then(|p| {
                likelihood::exact_log_likelihood(&network, &p, &sizes, &obs)
                    .map_err(|e| e.to_string())
            }) {
                Ok(l) => l.value,
                Err(e) => {
                    failed = Some(e);
                    f64::NEG_INFINITY
                }
            };
        let by_fsp = fit::fit(&mut exact_loglik, &problem.rates);
        if let Some(e) = failed {
            bail!("the exact FSP fit: {e}");
        }
        json!({
            "seconds": s.elapsed().as_secs_f64(),
            "evaluations": by_fsp.evaluations,
            "log_likelihood": by_fsp.log_likelihood,
            "estimates": by_fsp.estimates.iter().zip(&result.estimates).map(|(f, m)| {
                let width = m.profile_ci95[1] - m.profile_ci95[0];
                (f.name.clone(), json!({
                    "mle": f.mle,
                    "profile_ci95": f.profile_ci95,
                    "mle_difference_in_widths": (m.mle - f.mle).abs() / width,
                }))
            }).collect::<serde_json::Map<_, _>>(),
        })
    } else {
        Value::Null
    };
    let mut warnings = Vec::new();
    if at_mle.floored_cells > 0 {
        warnings.push(format!(
            "{} cells lie where the model's probability is below {:e} (floored): the data \
             reach where the model is not accurate",
            at_mle.floored_cells,
            likelihood::FLOOR
        ));
    }
    for e in &result.estimates {
        if !e.identifiable {
            warnings.push(format!(
                "{}: unidentifiable from these data (the profile likelihood stays within 1.92 \
                 of its maximum over the whole range)",
                e.name
            ));
        } else if e.at_range_end {
            warnings.push(format!(
                "{}: the maximum is on the model's range end; the range may be too small for \
                 these data",
                e.name
            ));
        } else if e.profile_open.iter().any(|o| *o) {
            warnings.push(format!(
                "{}: the 95 % interval reaches the model's range end (cut there)",
                e.name
            ));
        }
    }
    let report = json!({
        "model": name,
        "data": args.data,
        "cells": obs.cells(),
        "times": obs.times,
        "observed": data.species,
        "distinct_states": obs.distinct(),
        "fitted": problem.rates.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
        "fixed": problem.names.iter().zip(&problem.theta).enumerate()
            .filter(|(i, _)| !problem.slots.contains(i))
            .map(|(_, (n, v))| (n.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "log_likelihood": result.log_likelihood,
        "floored_cells": at_mle.floored_cells,
        "estimates": result.estimates.iter().zip(&problem.rates).map(|(e, r)| (e.name.clone(), json!({
            "mle": e.mle,
            "profile_ci95": e.profile_ci95,
            "profile_open": e.profile_open,
            "fisher_ci95": e.fisher_ci95,
            "fisher_se": e.fisher_se,
            "at_range_end": e.at_range_end,
            "identifiable": e.identifiable,
            "range": [r.lo, r.hi],
        }))).collect::<serde_json::Map<_, _>>(),
        "evaluations": result.evaluations,
        "fit_seconds": fit_seconds,
        "prepare_seconds": prepare_seconds,
        "tabled": meta.tabled(),
        "likelihood_us": likelihood_us,
        "fsp_likelihood_us": fsp_likelihood_us,
        "speedup": fsp_likelihood_us / likelihood_us,
        "fsp_log_likelihood_at_mle": exact.value,
        "posterior": posterior_report,
        "check_fsp": check,
        "warnings": warnings,
    });
    if args.json {
        println!("{report}");
        return Ok(());
    }
    println!(
        "{name}: {} cells at {} times, observed {}; log-likelihood {:.3} (FSP at the same rates {:.3})",
        obs.cells(),
        obs.times.len(),
        data.species.join(", "),
        result.log_likelihood,
        exact.value
    );
    println!(
        "{:<12} {:>12} {:>27} {:>27}",
        "rate", "MLE", "profile 95 %", "Fisher 95 %"
    );
    for e in &result.estimates {
        let fisher = e.fisher_ci95.map_or("flat".to_string(), |c| {
            format!("[{:.5}, {:.5}]", c[0], c[1])
        });
        println!(
            "{:<12} {:>12.6} {:>27} {:>27}",
            e.name,
            e.mle,
            format!("[{:.5}, {:.5}]", e.profile_ci95[0], e.profile_ci95[1]),
            fisher
        );
    }
    println!(
        "fit {:.1} ms ({} evaluations); likelihood {likelihood_us:.1} µs, by FSP {:.0} µs: {:.0}× faster",
        fit_seconds * 1e3,
        result.evaluations,
        fsp_likelihood_us,
        fsp_likelihood_us / likelihood_us
    );
    if let Some(p) = report["posterior"].as_object() {
        println!(
            "posterior: {} chains × {} steps ({} warm-up), acceptance {}, {:.2} s",
            p["chains"],
            p["steps"],
            p["warmup"],
            p["acceptance"]
                .as_array()
                .map(|a| a
                    .iter()
                    .map(|x| format!("{:.2}", x.as_f64().unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>()
                    .join(" "))
                .unwrap_or_default(),
            p["seconds"].as_f64().unwrap_or(f64::NAN)
        );
        if let Some(rates) = p["rates"].as_object() {
            for (name, r) in rates {
                let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
                println!(
                    "  {name:<10} mean {:.6} sd {:.2e}  95 % [{:.5}, {:.5}]  R-hat {:.4}  ESS {:.0}",
                    f("mean"),
                    f("sd"),
                    r["ci95"][0].as_f64().unwrap_or(f64::NAN),
                    r["ci95"][1].as_f64().unwrap_or(f64::NAN),
                    f("rhat"),
                    f("ess")
                );
            }
        }
    }
    if !check.is_null() {
        println!("check by FSP: {check}");
    }
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}
