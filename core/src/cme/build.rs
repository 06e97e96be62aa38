//! The off-line build of a gene-network meta-model by either solver, and what it
//! leaves to save: one entry point for the command line, benchmarks and tests.

use std::path::Path;

use thiserror::Error;

use super::greedy::{self, CmePgdError};
use super::history::History;
use super::model::{self, CmeModel, CmeModelError};
use super::network::Network;
use super::ttsolve;
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
}

impl Built {
    /// Writes the meta-model atomically.
    pub fn save(&self, network: &Network, out: &Path) -> Result<(), FileError> {
        match &self.form {
            Form::Separated { model, .. } => file::save(model, out),
            Form::Train {
                history,
                provenance,
                ..
            } => model::save_train(network, history, provenance.clone(), out),
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
