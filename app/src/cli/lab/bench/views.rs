//! `palpa lab bench views`: the signaling cascade's views model over all t against the
//! exact marginals of its first species, in one run.
//!
//! In `signaling-cascade-D` species `S_i` is produced at a rate set by `S_{i−1}` alone,
//! so `S_1…S_k` obey the CME of `signaling-cascade-k` whatever follows them: exact FSP
//! of that small chain (64³ states for k = 3) is the reference for the big model's first
//! k marginals at every time. The comparison grid falls between the model's time nodes
//! (quarter steps off a half-unit grid, plus the first fractions of a unit, where the
//! distribution moves fastest), and t = 0 itself.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::cme::model::{self, CmeModel};
use palpa_core::cme::{Moments, Network, fsp};
use palpa_core::rng::Rng;
use serde_json::json;

use crate::cli::cme::PgdArgs;

#[derive(Debug, Args)]
pub struct ViewsBenchArgs {
    /// Species of the signaling cascade whose model is measured.
    #[arg(long, default_value_t = 20)]
    species: usize,
    /// Leading species checked against the exact FSP of their closed chain.
    #[arg(long, default_value_t = 3)]
    exact: usize,
    /// A model file already built for this cascade (else it is built, timed, with the
    /// defaults and the flags below).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Where to save the model built here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Spacing of the comparison times.
    #[arg(long, default_value_t = 0.5)]
    t_step: f64,
    #[command(flatten)]
    pgd: PgdArgs,
    #[arg(long)]
    json: bool,
}

/// The goals the issue sets, checked in the report.
const MARGINAL_L1_GOAL: f64 = 1e-2;
const MASS_GOAL: f64 = 1e-3;
const BYTES_GOAL: u64 = 100 << 20;
const BUILD_S_GOAL: f64 = 600.0;
const EVAL_US_GOAL: f64 = 1000.0;

pub fn run(args: &ViewsBenchArgs) -> anyhow::Result<()> {
    if !(2..=20).contains(&args.species) || !(1..=3).contains(&args.exact) {
        bail!(
            "--species {} --exact {}: expected 2 ≤ species ≤ 20 and 1 ≤ exact ≤ 3 (the \
             exact chain is solved on a dense 64^exact box)",
            args.species,
            args.exact
        );
    }
    if args.exact > args.species {
        bail!(
            "--exact {} is more than --species {}",
            args.exact,
            args.species
        );
    }
    if !(args.t_step.is_finite() && args.t_step > 0.0) {
        bail!("--t-step {}: expected a finite spacing > 0", args.t_step);
    }
    let network = Network::built_in(&format!("signaling-cascade-{}", args.species))?;
    let (model, build_s, bytes, solver): (CmeModel, Option<f64>, Option<u64>, serde_json::Value) =
        match &args.model {
            Some(path) => {
                let m = model::load(path).with_context(|| format!("loading {}", path.display()))?;
                let bytes = std::fs::metadata(path).map(|m| m.len()).ok();
                (m, None, bytes, serde_json::Value::Null)
            }
            None => {
                let t0 = Instant::now();
                let built = args.pgd.build(&network, 300.0)?;
                let secs = t0.elapsed().as_secs_f64();
                let out = match &args.out {
                    Some(p) => p.clone(),
                    None => std::env::temp_dir()
                        .join(format!("palpa-bench-views-{}.palpa", std::process::id())),
                };
                built.save(&network, &out)?;
                let bytes = std::fs::metadata(&out).map(|m| m.len()).ok();
                if args.out.is_none() {
                    let _ = std::fs::remove_file(&out);
                }
                (built.built.model, Some(secs), bytes, built.report)
            }
        };
    if model.species_names().len() != args.species {
        bail!(
            "the model has {} species, not the {} of signaling-cascade-{}",
            model.species_names().len(),
            args.species,
            args.species
        );
    }
    let t_end = model.t_end();
    let mut times = vec![0.0, 0.01, 0.03, 0.1, 0.3, 0.7];
    let mut t = 0.5 * args.t_step;
    while t < t_end {
        if t > 0.7 {
            times.push(t);
        }
        t += args.t_step;
    }

    // The exact chain, stepped through the same times.
    let chain = Network::built_in(&format!("signaling-cascade-{}", args.exact))?;
    let sizes = &model.box_sizes()[..args.exact];
    let tf = Instant::now();
    let (p, _) = chain.parameter_values(&[])?;
    let g = fsp::Generator::new(&chain, &p, sizes)?;
    let mut prob = vec![0.0; g.states()];
    prob[0] = 1.0;
    let mut now = 0.0;
    let mut worst = vec![(0.0f64, 0.0f64); args.exact];
    let mut worst_mass = (0.0f64, 0.0f64);
    let mut most_negative = 0.0f64;
    for &t in &times {
        g.advance(&mut prob, t - now);
        now = t;
        let exact = Moments::from_joint(t, sizes, &prob);
        let e = model.evaluate(t, &[], usize::MAX)?;
        most_negative = most_negative.min(e.most_negative);
        for (i, w) in worst.iter_mut().enumerate() {
            let l1: f64 = e.moments.marginals[i]
                .iter()
                .zip(&exact.marginals[i])
                .map(|(a, b)| (a - b).abs())
                .sum();
            if l1 > w.0 {
                *w = (l1, t);
            }
        }
        for m in &e.moments.marginals {
            let dm = (m.iter().sum::<f64>() - 1.0).abs();
            if dm > worst_mass.0 {
                worst_mass = (dm, t);
            }
        }
    }
    let fsp_s = tf.elapsed().as_secs_f64();

    // On-line: all marginals at random times, and the first pair's joint.
    let mut rng = Rng::seed(7);
    let mut eval_us = Vec::new();
    let mut joint_us = Vec::new();
    for _ in 0..400 {
        let t = rng.uniform() * t_end;
        let te = Instant::now();
        std::hint::black_box(model.evaluate(std::hint::black_box(t), &[], usize::MAX)?);
        eval_us.push(te.elapsed().as_secs_f64() * 1e6);
        let tj = Instant::now();
        std::hint::black_box(model.pair_joint(t, &[], 0, 1)?);
        joint_us.push(tj.elapsed().as_secs_f64() * 1e6);
    }
    let p50 = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (eval_p50, joint_p50) = (p50(&mut eval_us), p50(&mut joint_us));
    let names = model.species_names();
    let worst_l1 = worst.iter().map(|w| w.0).fold(0.0, f64::max);
    let out = json!({
        "model": network.name,
        "representation": model.describe(),
        "stored_values": model.stored_values(),
        "bytes": bytes,
        "build_s": build_s,
        "solver": solver,
        "compared_times": times.len(),
        "t_end": t_end,
        "exact_chain": chain.name,
        "exact_fsp_s": fsp_s,
        "marginal_l1": worst.iter().zip(&names).map(|((l1, t), n)| json!({"species": n, "max_l1": l1, "at_t": t})).collect::<Vec<_>>(),
        "mass_error": {"max": worst_mass.0, "at_t": worst_mass.1},
        "most_negative": most_negative,
        "eval_all_marginals_us_p50": eval_p50,
        "pair_joint_us_p50": joint_p50,
        "goals": {
            "marginal_l1_le_1e-2": worst_l1 <= MARGINAL_L1_GOAL,
            "mass_within_1e-3": worst_mass.0 <= MASS_GOAL,
            "file_le_100_mb": bytes.map(|b| b <= BYTES_GOAL),
            "build_le_10_min": build_s.map(|s| s <= BUILD_S_GOAL),
            "eval_le_1_ms": eval_p50 <= EVAL_US_GOAL,
        },
    });
    crate::cli::args::print_report(&out, args.json)
}
