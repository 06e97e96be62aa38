//! The off-line build of a gene-network meta-model by either solver, and what it
//! leaves to save: one entry point for the command line, benchmarks and tests.

use std::path::Path;

use thiserror::Error;

use super::greedy::{self, CmePgdError};
use super::history::History;
use super::model::{self, CmeModel, CmeModelError};
use super::network::Network;
use super::ttsolve;
use super::views::Views;
use crate::file::{self, FileError};
use crate::separated::{Provenance, SeparatedModel};

/// Why a build failed.
#[derive(Debug, Error)]
pub enum BuildError {
    #[error(transparent)]
    Solve(#[from] CmePgdError),
    #[error(transparent)]
    Model(#[from] CmeModelError),
}

/// A built meta-model: the evaluator, and the form the file stores.
#[derive(Debug)]
pub struct Built {
    pub model: CmeModel,
    pub form: Form,
}

/// What the file stores.
#[derive(Debug)]
pub enum Form {
    /// Greedy PGD: a separated sum.
    Separated {
        model: Box<SeparatedModel<f64>>,
        report: greedy::Report,
    },
    /// BDF2 on tensor trains: the history train.
    Train {
        history: Box<History>,
        provenance: Provenance,
        report: ttsolve::Report,
    },
    /// BDF2 on tensor trains, keeping only the marginals and chosen joints.
    Views {
        views: Box<Views>,
        provenance: Provenance,
        report: ttsolve::Report,
    },
}

/// What a views build keeps besides every marginal, and how finely.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewOptions {
    /// Species pairs `(a, b)`, `a < b` (network indices) whose joints are stored.
    pub pairs: Vec<(usize, usize)>,
    /// RMS relative error of a stored time row (see [`super::views`]).
    pub eps: f64,
}

impl ViewOptions {
    /// Every neighbouring pair `(i, i + 1)`: a chain's couplings, and with them the
    /// covariance of the first two species.
    pub fn neighbours(species: usize, eps: f64) -> Self {
        ViewOptions {
            pairs: (1..species).map(|i| (i - 1, i)).collect(),
            eps,
        }
    }
}

impl Built {
    /// Writes the meta-model atomically, with the network it was built from in its
    /// provenance (so a fit can solve it exactly at the rates it finds).
    pub fn save(&self, network: &Network, out: &Path) -> Result<(), FileError> {
        let with_network = |p: &Provenance| Provenance {
            network: network.to_toml(),
            ..p.clone()
        };
        match &self.form {
            Form::Separated { model, .. } => {
                let mut model = model.clone();
                model.set_provenance(with_network(model.provenance()));
                file::save(&model, out)
            }
            Form::Train {
                history,
                provenance,
                ..
            } => model::save_train(network, history, with_network(provenance), out),
            Form::Views {
                views, provenance, ..
            } => {
                let provenance = &with_network(provenance);
                views.check().map_err(|reason| FileError::Inconsistent {
                    path: out.to_path_buf(),
                    reason,
                })?;
                file::save_views(
                    &model::views_meta(network, views, provenance.clone()),
                    &views.file_blocks(),
                    out,
                )
            }
        }
    }
}

/// Builds by the greedy PGD.
pub fn greedy(
    network: &Network,
    options: &greedy::Options,
    progress: &mut dyn FnMut(greedy::Progress),
) -> Result<Built, BuildError> {
    let (m, report) = greedy::solve(network, options, progress)?;
    Ok(Built {
        model: CmeModel::new(m.clone())?,
        form: Form::Separated {
            model: Box::new(m),
            report,
        },
    })
}

/// Builds the whole meta-model by BDF2 on tensor trains, stopping with
/// `Cancelled` once `cancel` is set (between steps).
pub fn train_cancellable(
    network: &Network,
    options: &ttsolve::Options,
    cancel: &std::sync::atomic::AtomicBool,
    progress: &mut dyn FnMut(ttsolve::Step),
) -> Result<Built, BuildError> {
    let (h, report) = ttsolve::solve_cancellable(network, options, cancel, progress)?;
    train_built(network, options, h, report)
}

/// Builds by BDF2 on tensor trains; with `times`, only the states at those times are
/// kept (no history to compress).
pub fn train(
    network: &Network,
    options: &ttsolve::Options,
    times: Option<&[f64]>,
    progress: &mut dyn FnMut(ttsolve::Step),
) -> Result<Built, BuildError> {
    let (h, report) = match times {
        Some(times) => ttsolve::solve_at(network, options, times, progress)?,
        None => ttsolve::solve(network, options, progress)?,
    };
    train_built(network, options, h, report)
}

/// Builds the views of `network` (marginals and `view.pairs`' joints over time) by
/// BDF2 on tensor trains; `cancel` stops it between steps.
pub fn views(
    network: &Network,
    options: &ttsolve::Options,
    view: &ViewOptions,
    cancel: Option<&std::sync::atomic::AtomicBool>,
    progress: &mut dyn FnMut(ttsolve::Step),
) -> Result<Built, BuildError> {
    let (v, report) =
        ttsolve::solve_views(network, options, &view.pairs, view.eps, cancel, progress)?;
    let mut provenance = Provenance::now(
        "cme views: BDF2 steps by ALS with enrichment, mass balanced; marginals and chosen \
         joints per step, SVD-compressed in time",
        &format!(
            "network {}; box {:?}; {} steps to t = {}; {options:?}; {view:?}",
            network.name, v.sizes, report.steps, options.t_end
        ),
        view.eps,
        Vec::new(),
    );
    provenance.input_hash = format!(
        "{:016x}",
        xxhash_rust::xxh3::xxh3_64(format!("{network:?}{options:?}{view:?}").as_bytes())
    );
    let meta = model::views_meta(network, &v, provenance.clone());
    let model = CmeModel::from_views(meta, v.clone())?;
    Ok(Built {
        model,
        form: Form::Views {
            views: Box::new(v),
            provenance,
            report,
        },
    })
}

/// The meta-model and file form of a solved history.
fn train_built(
    network: &Network,
    options: &ttsolve::Options,
    h: History,
    report: ttsolve::Report,
) -> Result<Built, BuildError> {
    let provenance = model::train_provenance(network, &h, report.steps, options);
    let meta = model::train_meta(network, &h, provenance.clone());
    let model = CmeModel::from_train(meta, h.tt.cores.clone())?;
    Ok(Built {
        model,
        form: Form::Train {
            history: Box::new(h),
            provenance,
            report,
        },
    })
}

/// What an off-line tensor-train build keeps, with the solver options it runs under:
/// one value the command line, the app's first-open build and the cache key share.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    pub options: ttsolve::Options,
    /// `Some`: keep the views only; `None`: the whole history.
    pub views: Option<ViewOptions>,
}

/// Species from which a network without range parameters is kept as views by default.
/// Below it the whole history is small (the cascade's is 3 MB); above it the history's
/// ranks and size grow with every species while the scene still shows only marginals
/// and one pair.
pub const VIEWS_FROM_SPECIES: usize = 5;

/// The views' default row tolerance: 1e-5 of a row's L2 norm, far below the 1e-2 L1
/// the solver's step error allows.
pub const VIEWS_EPS: f64 = 1e-5;

impl Recipe {
    /// The default build of `network` up to `t_end`: views of the neighbouring pairs
    /// for a large network with no range parameters (with the looser step options such
    /// a network needs to build in minutes), else the whole history; the first step
    /// cut for fast rates ([`super::sizing::first_step`]).
    pub fn default_for(network: &Network, t_end: f64) -> Self {
        let views = network.species.len() >= VIEWS_FROM_SPECIES
            && network.parameters.iter().all(|p| p.grid().is_none());
        let mut recipe = if views {
            Recipe {
                options: Self::views_options(t_end),
                views: Some(ViewOptions::neighbours(network.species.len(), VIEWS_EPS)),
            }
        } else {
            Recipe {
                options: ttsolve::Options {
                    t_end,
                    ..ttsolve::Options::default()
                },
                views: None,
            }
        };
        recipe.options.h_first = super::sizing::first_step(network, recipe.options.h_first);
        recipe
    }

    /// The solver options of a views build. Measured on signaling-cascade-20 (S1–S3
    /// against their exact chain at 605 times): the error is the state's truncation,
    /// not the step — step error 3e-5 instead of 1e-4 left the worst marginal L1 at
    /// 8.8e-3, while eps 1e-6 instead of 3e-6 took it from 8.0e-3 to 4.6e-3.
    pub fn views_options(t_end: f64) -> ttsolve::Options {
        ttsolve::Options {
            t_end,
            eps: 1e-6,
            step_error_tol: 1e-4,
            h_max: 2.0,
            ..ttsolve::Options::default()
        }
    }

    /// Runs the build; `cancel` stops it between steps.
    pub fn build(
        &self,
        network: &Network,
        cancel: Option<&std::sync::atomic::AtomicBool>,
        progress: &mut dyn FnMut(ttsolve::Step),
    ) -> Result<Built, BuildError> {
        match (&self.views, cancel) {
            (Some(v), _) => views(network, &self.options, v, cancel, progress),
            (None, Some(c)) => train_cancellable(network, &self.options, c, progress),
            (None, None) => train(network, &self.options, None, progress),
        }
    }

    /// A key that changes when the network, anything in the recipe, palpa's version or
    /// the model file's format does: a cache made by another build of palpa is not
    /// taken for this one's.
    pub fn hash(&self, network: &Network) -> u64 {
        let code = format!(
            "palpa {} file {}",
            env!("CARGO_PKG_VERSION"),
            file::FORMAT_VERSION
        );
        xxhash_rust::xxh3::xxh3_64(format!("{code} {network:?} {self:?}").as_bytes())
    }
}
