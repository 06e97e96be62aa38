//! Rates from data: a gene network's unknown rates fitted to single-cell snapshots
//! through its meta-model, without solving the CME at any rate.
//!
//! Read top-down: [`data`] (the snapshot file) → [`likelihood`] (the data's
//! log-likelihood at any rates, from the meta-model or by exact FSP) → [`optimize`]
//! (the maximum over the model's range) → [`intervals`] (95 % intervals by profile
//! likelihood and by Fisher information) → [`posterior`] (Metropolis–Hastings chains
//! with R-hat and effective sample size). [`fit`] and [`sample`] put them together
//! over any log-likelihood of the rates, so the same code fits by the meta-model or
//! by FSP (the check of the first against the second).
//!
//! The rates are searched inside the model's range only: a meta-model answers nowhere
//! else. A maximum on a range end is flagged (the range is too small for these data),
//! and a rate the data do not bound is reported unidentifiable with its profile
//! interval open to the range's ends.

pub mod data;
pub mod intervals;
pub mod likelihood;
pub mod optimize;
pub mod posterior;

use thiserror::Error;

use crate::cme::fsp::FspError;
use crate::cme::model::CmeModelError;

/// Why data could not be fitted.
#[derive(Debug, Error)]
pub enum FitError {
    #[error(
        "the data observe species {name:?}, which the model does not have; its species are {known}"
    )]
    UnknownSpecies { name: String, known: String },
    #[error(
        "the data have cells at t = {t}, past the model's time range [0, {t_end}]: rebuild \
         it with a later --t-end, or leave those cells out"
    )]
    BeyondTime { t: f64, t_end: f64 },
    #[error(
        "a cell at t = {t} has {species} = {count}, outside the model's box of {size} states \
         (0..{size}): a larger box (the species' `max`) is needed for these data"
    )]
    BeyondBox {
        species: String,
        count: u32,
        size: usize,
        t: f64,
    },
    #[error(
        "the model has no range parameters: every rate was fixed when it was built (give a \
         parameter a `range` in the network file to make it a coordinate)"
    )]
    NoParameters,
    #[error("the model's parameter cores are not contiguous in its train")]
    Layout,
    #[error(
        "a {0} model cannot be fitted: fitting reads a tensor-train history (the default \
         `palpa cme offline` with range parameters)"
    )]
    NotTrain(String),
    #[error("no rate {name:?} in the model; its range parameters are {known}")]
    UnknownRate { name: String, known: String },
    #[error("the exact likelihood: {0}")]
    Fsp(#[from] FspError),
    #[error(transparent)]
    Model(#[from] CmeModelError),
}

/// A fitted rate and its range.
#[derive(Debug, Clone, PartialEq)]
pub struct Rate {
    pub name: String,
    pub lo: f64,
    pub hi: f64,
}

impl Rate {
    fn to_rate(&self, u: f64) -> f64 {
        self.lo + u * (self.hi - self.lo)
    }

    fn width(&self) -> f64 {
        self.hi - self.lo
    }
}

/// One rate's estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    pub name: String,
    pub mle: f64,
    pub profile_ci95: [f64; 2],
    /// Which ends of the profile interval ran into the model's range (the data do not
    /// bound the rate there).
    pub profile_open: [bool; 2],
    /// `None`: a flat direction (the information is singular or the standard error
    /// wider than half the range).
    pub fisher_ci95: Option<[f64; 2]>,
    pub fisher_se: Option<f64>,
    /// The maximum lies on a range end: the range may be too small for these data.
    pub at_range_end: bool,
    /// False when the profile reaches both range ends.
    pub identifiable: bool,
}

/// The maximum-likelihood fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub estimates: Vec<Estimate>,
    pub log_likelihood: f64,
    /// The maximum in scaled units and the Fisher covariance there (scaled units).
    pub u_hat: Vec<f64>,
    pub cov_u: Option<Vec<f64>>,
    /// Log-likelihood evaluations: maximum, Fisher, profiles.
    pub evaluations: usize,
}

/// Maximum, Fisher and profile intervals of `loglik` (a function of the rates, in
/// `rates` order) over the box `rates`.
pub fn fit(loglik: &mut dyn FnMut(&[f64]) -> f64, rates: &[Rate]) -> Fit {
    let mut f = |u: &[f64]| {
        let theta: Vec<f64> = rates.iter().zip(u).map(|(r, &u)| r.to_rate(u)).collect();
        loglik(&theta)
    };
    let d = rates.len();
    let max = optimize::maximize(&mut f, d, 1e-7);
    let mut evaluations = max.evaluations;
    let cov_u = intervals::fisher(&mut f, &max.u, &mut evaluations);
    let estimates = (0..d)
        .map(|i| {
            let se_u = cov_u.as_ref().map(|c| c[i * d + i].sqrt());
            let ends = intervals::profile(
                &mut f,
                &max.u,
                max.value,
                i,
                se_u.unwrap_or(0.02),
                &mut evaluations,
            );
            let r = &rates[i];
            let mle = r.to_rate(max.u[i]);
            let fisher_se = se_u.map(|s| s * r.width());
            Estimate {
                name: r.name.clone(),
                mle,
                profile_ci95: [r.to_rate(ends[0].u), r.to_rate(ends[1].u)],
                profile_open: [ends[0].open, ends[1].open],
                fisher_ci95: fisher_se
                    .map(|s| [mle - intervals::Z95 * s, mle + intervals::Z95 * s]),
                fisher_se,
                at_range_end: max.u[i] < 1e-4 || max.u[i] > 1.0 - 1e-4,
                identifiable: !(ends[0].open && ends[1].open),
            }
        })
        .collect();
    Fit {
        estimates,
        log_likelihood: max.value,
        u_hat: max.u,
        cov_u,
        evaluations,
    }
}

/// A posterior summary of one rate.
#[derive(Debug, Clone, PartialEq)]
pub struct RatePosterior {
    pub name: String,
    pub mean: f64,
    pub sd: f64,
    pub ci95: [f64; 2],
    pub rhat: f64,
    pub ess: f64,
}

/// The posterior by Metropolis–Hastings (see [`posterior`]), in rates.
#[derive(Debug, Clone, PartialEq)]
pub struct Posterior {
    pub chains: usize,
    pub steps: usize,
    pub warmup: usize,
    pub acceptance: Vec<f64>,
    pub rates: Vec<RatePosterior>,
    /// Every kept draw of every chain, in rates.
    pub draws: Vec<Vec<f64>>,
    pub evaluations: usize,
}

impl Posterior {
    /// The largest R-hat over the rates (near 1: the chains agree).
    pub fn worst_rhat(&self) -> f64 {
        self.rates.iter().map(|r| r.rhat).fold(0.0, f64::max)
    }

    /// The smallest effective sample size over the rates.
    pub fn least_ess(&self) -> f64 {
        self.rates
            .iter()
            .map(|r| r.ess)
            .fold(f64::INFINITY, f64::min)
    }
}

/// Chains from the fit's maximum, proposals shaped by its Fisher covariance.
pub fn sample(
    loglik: &mut dyn FnMut(&[f64]) -> f64,
    rates: &[Rate],
    fit: &Fit,
    options: posterior::Options,
) -> Posterior {
    let mut f = |u: &[f64]| {
        let theta: Vec<f64> = rates.iter().zip(u).map(|(r, &u)| r.to_rate(u)).collect();
        loglik(&theta)
    };
    let c = posterior::sample(&mut f, &fit.u_hat, fit.cov_u.as_deref(), options);
    let to_rates =
        |u: &[f64]| -> Vec<f64> { rates.iter().zip(u).map(|(r, &u)| r.to_rate(u)).collect() };
    Posterior {
        chains: options.chains,
        steps: options.steps,
        warmup: c.warmup,
        acceptance: c.acceptance,
        rates: rates
            .iter()
            .zip(&c.summaries)
            .map(|(r, s)| RatePosterior {
                name: r.name.clone(),
                mean: r.to_rate(s.mean),
                sd: s.sd * r.width(),
                ci95: [r.to_rate(s.ci95[0]), r.to_rate(s.ci95[1])],
                rhat: s.rhat,
                ess: s.ess,
            })
            .collect(),
        draws: c.draws.iter().flatten().map(|u| to_rates(u)).collect(),
        evaluations: c.evaluations,
    }
}
