//! `palpa lab bench fit`: rates from data, measured in one run on seeded synthetic data
//! sets at rates drawn off the grid: how often the 95 % intervals hold the true rates,
//! how far the meta-model's maximum is from the exact-FSP likelihood's (in interval
//! widths), the model's joint against FSP's at the true rates, and the costs: a
//! likelihood by the meta-model and by FSP, a whole fit, a posterior.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::cme::fit::data::Snapshots;
use palpa_core::cme::fit::likelihood::{MetaLikelihood, Observations, exact_log_likelihood};
use palpa_core::cme::fit::optimize::nelder_mead;
use palpa_core::cme::fit::{self, Rate, posterior};
use palpa_core::cme::{fsp, model, moments, ssa};
use palpa_core::rng::Rng;
use serde_json::json;

use crate::cli::cme_fit::model_network;

#[derive(Debug, Args)]
pub struct FitBenchArgs {
    /// A gene-network meta-model with range parameters.
    file: PathBuf,
    /// Synthetic data sets.
    #[arg(long, default_value_t = 50)]
    sets: usize,
    /// Cells at each time.
    #[arg(long, default_value_t = 1000)]
    cells: usize,
    /// Measurement times [default: four, even in the model's time range].
    #[arg(long, value_delimiter = ',')]
    t: Vec<f64>,
    /// Sets also fitted by the exact FSP likelihood (a solve per evaluation).
    #[arg(long, default_value_t = 5)]
    fsp_sets: usize,
    /// Metropolis–Hastings steps per chain of the posterior timed on the first set.
    #[arg(long, default_value_t = 10_000)]
    posterior: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long)]
    json: bool,
}

pub fn run(args: &FitBenchArgs) -> anyhow::Result<()> {
    let name = args.file.display().to_string();
    let model = model::load(&args.file).with_context(|| format!("loading {name}"))?;
    let network = model_network(&model, &name)?;
    let history = model
        .history()
        .ok_or_else(|| fit::FitError::NotTrain(model.describe()))?;
    let rates: Vec<Rate> = model
        .parameters()
        .into_iter()
        .map(|(name, lo, hi)| Rate { name, lo, hi })
        .collect();
    if rates.is_empty() {
        return Err(fit::FitError::NoParameters.into());
    }
    if args.sets == 0 || args.cells == 0 {
        bail!("--sets and --cells: expected at least one");
    }
    let times: Vec<f64> = if args.t.is_empty() {
        (1..=4).map(|k| model.t_end() * k as f64 / 4.0).collect()
    } else {
        args.t.clone()
    };
    let species = model.species_names();
    let sizes = model.box_sizes();
    let mut rng = Rng::seed(args.seed);
    let (mut profile_in, mut fisher_in, mut cases) = (0usize, 0usize, 0usize);
    let (mut fit_s, mut prepare_s) = (Vec::new(), Vec::new());
    let (mut worst_off, mut worst_l1) = (0.0f64, 0.0f64);
    let mut timing = None;
    let mut rows = Vec::new();
    if !args.json {
        println!(
            "{name}: {} sets, {} cells at t = {times:?}, rates drawn in the inner 80 % of the range",
            args.sets, args.cells
        );
        println!(
            "{:>4} {:>28} {:>28} {:>8} {:>9} {:>10}",
            "set", "true rates", "MLE", "covered", "fit ms", "off (FSP)"
        );
    }
    for set in 0..args.sets {
        let truth: Vec<f64> = rates
            .iter()
            .map(|r| r.lo + (r.hi - r.lo) * rng.range(0.1, 0.9))
            .collect();
        let named: Vec<(String, f64)> = rates
            .iter()
            .map(|r| r.name.clone())
            .zip(truth.clone())
            .collect();
        let (p, _) = network.parameter_values(&named)?;
        let cells = times
            .iter()
            .enumerate()
            .map(|(k, &t)| {
                let seed = args.seed ^ ((set as u64) << 32) ^ (k as u64 + 1);
                let paths = ssa::paths(&network, &p, &[t], args.cells, seed, ssa::MAX_RUN_EVENTS);
                if let Some(why) = paths.overflow {
                    bail!("{why}");
                }
                Ok(paths
                    .states
                    .iter()
                    .map(|s| {
                        s[0].iter()
                            .map(|&z| z.clamp(0, u32::MAX as i64) as u32)
                            .collect()
                    })
                    .collect())
            })
            .collect::<anyhow::Result<Vec<Vec<Vec<u32>>>>>()?;
        let data = Snapshots {
            species: species.clone(),
            times: times.clone(),
            cells,
        };
        let s0 = Instant::now();
        let obs = Observations::new(&data, &species, &sizes, model.t_end())?;
        let meta = MetaLikelihood::new(history, &obs)?;
        prepare_s.push(s0.elapsed().as_secs_f64());
        let mut scratch = Vec::new();
        let mut f = |x: &[f64]| meta.log_likelihood(x, &mut scratch).value;
        let s1 = Instant::now();
        let result = fit::fit(&mut f, &rates);
        fit_s.push(s1.elapsed().as_secs_f64());
        let mut covered = Vec::new();
        for (e, &t) in result.estimates.iter().zip(&truth) {
            cases += 1;
            let pin = e.profile_ci95[0] <= t && t <= e.profile_ci95[1];
            let fin = e.fisher_ci95.is_some_and(|c| c[0] <= t && t <= c[1]);
            profile_in += usize::from(pin);
            fisher_in += usize::from(fin);
            covered.push(format!(
                "{}{}",
                if pin { "P" } else { "-" },
                if fin { "F" } else { "-" }
            ));
        }
        let mut off = None;
        if set < args.fsp_sets {
            let mut exact = |u: &[f64]| -> f64 {
                let theta: Vec<f64> = rates
                    .iter()
                    .zip(u)
                    .map(|(r, u)| r.lo + u * (r.hi - r.lo))
                    .collect();
                let named: Vec<(String, f64)> =
                    rates.iter().map(|r| r.name.clone()).zip(theta).collect();
                network
                    .parameter_values(&named)
                    .ok()
                    .and_then(|(p, _)| exact_log_likelihood(&network, &p, &sizes, &obs).ok())
                    .map_or(f64::NEG_INFINITY, |l| l.value)
            };
            let m = nelder_mead(&mut exact, &result.u_hat, 0.002, 1e-6, 400);
            let worst = result
                .estimates
                .iter()
                .zip(&rates)
                .zip(&m.u)
                .map(|((e, r), u)| {
                    (e.mle - (r.lo + u * (r.hi - r.lo))).abs()
                        / (e.profile_ci95[1] - e.profile_ci95[0])
                })
                .fold(0.0, f64::max);
            worst_off = worst_off.max(worst);
            off = Some(worst);
            // The model's joint against FSP's at the true rates, each data time.
            let exact_joint = fsp::solve_on(&network, &p, &sizes, &times)?;
            for (j, &t) in times.iter().enumerate() {
                let joint = model.joint(t, &named, usize::MAX)?;
                worst_l1 = worst_l1.max(moments::l1(&joint, &exact_joint.joint[j]));
            }
        }
        if set == 0 {
            let theta: Vec<f64> = result.estimates.iter().map(|e| e.mle).collect();
            let mut us: Vec<f64> = (0..201)
                .map(|_| {
                    let s = Instant::now();
                    std::hint::black_box(meta.log_likelihood(&theta, &mut Vec::new()));
                    s.elapsed().as_secs_f64() * 1e6
                })
                .collect();
            us.sort_by(f64::total_cmp);
            let named: Vec<(String, f64)> =
                rates.iter().map(|r| r.name.clone()).zip(theta).collect();
            let (p_hat, _) = network.parameter_values(&named)?;
            let mut fsp_us: Vec<f64> = (0..3)
                .map(|_| {
                    let s = Instant::now();
                    std::hint::black_box(exact_log_likelihood(&network, &p_hat, &sizes, &obs)).ok();
                    s.elapsed().as_secs_f64() * 1e6
                })
                .collect();
            fsp_us.sort_by(f64::total_cmp);
            let s2 = Instant::now();
            let post = fit::sample(
                &mut f,
                &rates,
                &result,
                posterior::Options {
                    chains: 4,
                    steps: args.posterior,
                    seed: args.seed,
                },
            );
            let posterior_s = s2.elapsed().as_secs_f64();
            let (rhat, ess) = (post.worst_rhat(), post.least_ess());
            timing = Some((us[100], fsp_us[1], posterior_s, rhat, ess));
        }
        let mle: Vec<f64> = result.estimates.iter().map(|e| e.mle).collect();
        if args.json {
            rows.push(
                json!({"set": set, "truth": truth, "mle": mle, "covered": covered,
                "fit_s": fit_s[set], "prepare_s": prepare_s[set], "mle_off_fsp_widths": off}),
            );
        } else {
            println!(
                "{set:>4} {:>28} {:>28} {:>8} {:>9.1} {:>10}",
                format!("{truth:.5?}"),
                format!("{mle:.5?}"),
                covered.join(" "),
                1e3 * (prepare_s[set] + fit_s[set]),
                off.map_or(String::new(), |o| format!("{o:.4}"))
            );
        }
    }
    let (likelihood_us, fsp_us, posterior_s, rhat, ess) = timing.context("at least one set")?;
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let summary = json!({
        "model": name,
        "sets": args.sets,
        "cells_per_time": args.cells,
        "times": times,
        "coverage_profile": profile_in as f64 / cases as f64,
        "coverage_fisher": fisher_in as f64 / cases as f64,
        "mle_off_fsp_widths_max": worst_off,
        "fsp_sets": args.fsp_sets.min(args.sets),
        "joint_l1_vs_fsp_max": worst_l1,
        "likelihood_us": likelihood_us,
        "fsp_likelihood_us": fsp_us,
        "speedup": fsp_us / likelihood_us,
        "fit_s_max": max(&fit_s),
        "prepare_s_max": max(&prepare_s),
        "posterior_steps": args.posterior,
        "posterior_s": posterior_s,
        "posterior_rhat_max": rhat,
        "posterior_ess_min": ess,
    });
    if args.json {
        for r in rows {
            println!("{r}");
        }
        println!("{summary}");
    } else {
        println!(
            "coverage of the 95 % intervals: profile {profile_in}/{cases} ({:.1} %), Fisher {fisher_in}/{cases} ({:.1} %)",
            100.0 * profile_in as f64 / cases as f64,
            100.0 * fisher_in as f64 / cases as f64
        );
        println!(
            "maximum against the exact-FSP likelihood's (first {} sets): at most {worst_off:.4} of the interval's width; the model's joint within L1 {worst_l1:.2e} of FSP's at the true rates",
            args.fsp_sets.min(args.sets)
        );
        println!(
            "likelihood {likelihood_us:.1} µs, by FSP {fsp_us:.0} µs: {:.0}× faster; a whole fit ≤ {:.3} s (preparing the data ≤ {:.3} s); a {}-step posterior (4 chains) {posterior_s:.2} s, R-hat ≤ {rhat:.4}, ESS ≥ {ess:.0}",
            fsp_us / likelihood_us,
            max(&fit_s),
            max(&prepare_s),
            args.posterior
        );
    }
    Ok(())
}
