//! `palpa lab bench cme`: the gene-network meta-model against stochastic simulation, in
//! one run. The PGD model is built (timed), evaluated (timed per call), and both it
//! and an SSA run with K trajectories are compared with the exact FSP marginals. SSA's
//! marginal error falls like 1/√K (checked here with K/4 and K), so the trajectories
//! SSA needs to match the PGD's accuracy are `K (e_SSA / e_PGD)²`; that count times
//! the measured cost per trajectory is set against the PGD's off-line time.

use std::time::Instant;

use anyhow::bail;
use clap::Args;
use palpa_core::cme::{Moments, fsp, ssa};
use serde_json::json;

use crate::cli::cme::{PgdArgs, model_coordinates};
use crate::cli::networks::{load_network, parse_params};

#[derive(Debug, Args)]
pub struct CmeBenchArgs {
    /// A built-in network or a TOML file.
    model: String,
    /// Comparison times, comma-separated (the PGD model is built up to the last).
    #[arg(long, value_delimiter = ',', required = true)]
    t: Vec<f64>,
    /// Parameter values, NAME=VALUE (repeatable).
    #[arg(long = "param")]
    params: Vec<String>,
    /// SSA trajectories of the main run (a run with a quarter of them checks the 1/√K law).
    #[arg(long, default_value_t = 20_000)]
    trajectories: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    pgd: PgdArgs,
    #[arg(long)]
    json: bool,
}

/// Largest over times and species of the marginal L1 distance.
fn marginal_l1(a: &[Moments], b: &[Moments]) -> f64 {
    let mut worst = 0.0f64;
    for (ma, mb) in a.iter().zip(b) {
        for (pa, pb) in ma.marginals.iter().zip(&mb.marginals) {
            let n = pa.len().max(pb.len());
            let at = |p: &[f64], i: usize| p.get(i).copied().unwrap_or(0.0);
            let d: f64 = (0..n).map(|i| (at(pa, i) - at(pb, i)).abs()).sum();
            worst = worst.max(d);
        }
    }
    worst
}

pub fn run(args: &CmeBenchArgs) -> anyhow::Result<()> {
    if args.trajectories < 8 {
        bail!("--trajectories {}: expected at least 8", args.trajectories);
    }
    if !(args.t.iter().all(|t| t.is_finite() && *t > 0.0) && args.t.windows(2).all(|w| w[0] < w[1]))
    {
        bail!(
            "--t {:?}: expected finite times > 0 in increasing order",
            args.t
        );
    }
    let network = load_network(&args.model)?;
    let set = parse_params(&args.params)?;
    let (p, _) = network.parameter_values(&set)?;
    let t_last = *args.t.last().expect("at least one time");

    let t0 = Instant::now();
    let built = args.pgd.build(&network, t_last)?;
    let offline_s = t0.elapsed().as_secs_f64();
    let model = built.built.model;
    let set = model_coordinates(&model, &network, &p);
    let mut pgd_moments = Vec::new();
    for &t in &args.t {
        pgd_moments.push(model.evaluate(t, &set, usize::MAX)?.moments);
    }
    // Evaluation time: every comparison time in turn, repeated.
    let reps = 200u32;
    let te = Instant::now();
    for k in 0..reps {
        let t = args.t[k as usize % args.t.len()];
        std::hint::black_box(model.evaluate(std::hint::black_box(t), &set, usize::MAX)?);
    }
    let eval_us = te.elapsed().as_secs_f64() * 1e6 / f64::from(reps);

    let sizes = model.box_sizes();
    let tf = Instant::now();
    let exact = fsp::solve_on(&network, &p, &sizes, &args.t)?;
    let fsp_s = tf.elapsed().as_secs_f64();
    let pgd_err = marginal_l1(&pgd_moments, &exact.moments);

    let mut ssa_runs = Vec::new();
    for k in [args.trajectories / 4, args.trajectories] {
        let ts = Instant::now();
        let sol = ssa::simulate(&network, &p, &args.t, k, args.seed);
        if let Some(why) = &sol.overflow {
            anyhow::bail!("{why}");
        }
        let secs = ts.elapsed().as_secs_f64();
        ssa_runs.push((k, secs, marginal_l1(&sol.moments, &exact.moments)));
    }
    let (k_small, _, e_small) = ssa_runs[0];
    let (k, ssa_s, ssa_err) = ssa_runs[1];
    // Measured exponent of e ∝ K^(-a) between the two runs (1/2 expected).
    let exponent = (e_small / ssa_err).ln() / (k as f64 / k_small as f64).ln();
    let k_needed = k as f64 * (ssa_err / pgd_err).powi(2);
    let ssa_needed_s = ssa_s / k as f64 * k_needed;
    let out = json!({
        "model": network.name,
        "t": args.t,
        "parameters": network.parameters.iter().map(|q| q.name.clone()).zip(p.iter().copied()).collect::<Vec<_>>(),
        "pgd": {"offline_s": offline_s, "representation": model.describe(), "stored_values": model.stored_values(), "solver": built.report, "eval_us": eval_us,
                "marginal_l1_vs_fsp": pgd_err},
        "fsp": {"seconds": fsp_s, "box": sizes, "leak": exact.leak},
        "ssa": ssa_runs.iter().map(|(k, s, e)| json!({"trajectories": k, "seconds": s, "marginal_l1_vs_fsp": e})).collect::<Vec<_>>(),
        "ssa_error_exponent": exponent,
        "ssa_trajectories_for_pgd_accuracy": k_needed,
        "ssa_seconds_for_pgd_accuracy": ssa_needed_s,
        "ssa_over_pgd_offline_time": ssa_needed_s / offline_s,
        "note": "SSA cost at the PGD's accuracy is extrapolated with the 1/sqrt(K) law from the measured run",
    });
    crate::cli::args::print_report(&out, args.json)
}
