//! The gene-network scene: a CME meta-model `P(z, t; p)` explored at its coordinates.
//!
//! The room holds the model and the user's coordinates (time and every parameter over
//! its trained range), evaluates the marginals and moments (and, for two species, the
//! joint on the whole box) only when a coordinate changes, and times each evaluation.
//! Nothing here is palpation's: the window and headless mode pick this room or the
//! palpation [`crate::session::Session`] by the scene file's kind.

pub mod offscreen;
mod ui;

use std::time::Instant;

use anyhow::Context;
use palpa_core::cme::model::{CmeModel, Evaluation};

use crate::stats::Ring;

pub use ui::show;

/// One coordinate the user moves: a parameter, or time.
#[derive(Debug, Clone, PartialEq)]
pub struct Coordinate {
    pub name: String,
    pub lo: f64,
    pub hi: f64,
    pub value: f64,
}

/// The joint distribution of two species on the model's box.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Copy numbers 0..na of the first species (fastest) and 0..nb of the second.
    pub na: usize,
    pub nb: usize,
    pub p: Vec<f64>,
}

/// A network scene being explored.
#[derive(Debug)]
pub struct NetworkRoom {
    model: CmeModel,
    pub species: Vec<String>,
    pub time: Coordinate,
    pub params: Vec<Coordinate>,
    /// Time runs by itself at `speed` model time units per second.
    pub playing: bool,
    pub speed: f64,
    /// The last evaluation at the current coordinates.
    pub eval: Option<Evaluation>,
    pub joint: Option<Joint>,
    /// Why the last evaluation failed, if it did.
    pub error: Option<String>,
    /// Evaluation time (marginals and moments), µs, recent changes.
    pub eval_us: Ring,
    /// Joint evaluation time, µs, recent changes.
    pub joint_us: Ring,
    evaluated_at: Option<Vec<f64>>,
}

impl NetworkRoom {
    pub fn new(model: CmeModel) -> Self {
        let t_end = model.t_end();
        let params = model
            .parameters()
            .into_iter()
            .map(|(name, lo, hi)| Coordinate {
                value: 0.5 * (lo + hi),
                name,
                lo,
                hi,
            })
            .collect();
        NetworkRoom {
            species: model.species_names(),
            time: Coordinate {
                name: "t".into(),
                lo: 0.0,
                hi: t_end,
                value: 0.5 * t_end,
            },
            params,
            playing: false,
            speed: t_end / 10.0,
            eval: None,
            joint: None,
            error: None,
            eval_us: Ring::new(240),
            joint_us: Ring::new(240),
            evaluated_at: None,
            model,
        }
    }

    pub fn model(&self) -> &CmeModel {
        &self.model
    }

    /// The current coordinates: time, then the parameters in the model's order.
    pub fn coordinates(&self) -> Vec<f64> {
        std::iter::once(self.time.value)
            .chain(self.params.iter().map(|c| c.value))
            .collect()
    }

    /// The parameter settings as the model takes them.
    pub fn settings(&self) -> Vec<(String, f64)> {
        self.params
            .iter()
            .map(|c| (c.name.clone(), c.value))
            .collect()
    }

    /// Advances time by `dt_s` seconds of the clock when playing (wrapping to 0 at the
    /// end), then evaluates if any coordinate changed since the last evaluation.
    pub fn frame(&mut self, dt_s: f64) {
        if self.playing && self.time.hi > 0.0 {
            let t = self.time.value + self.speed * dt_s;
            self.time.value = if t > self.time.hi { 0.0 } else { t };
        }
        let now = self.coordinates();
        if self.evaluated_at.as_ref() != Some(&now) {
            self.evaluate();
            self.evaluated_at = Some(now);
        }
    }

    /// Evaluates the marginals and moments (and the joint of a two-species model) at
    /// the current coordinates.
    pub fn evaluate(&mut self) {
        let set = self.settings();
        let t = self.time.value;
        let t0 = Instant::now();
        match self.model.evaluate(t, &set, usize::MAX) {
            Ok(e) => {
                self.eval_us.push(t0.elapsed().as_secs_f64() * 1e6);
                self.eval = Some(e);
                self.error = None;
            }
            Err(e) => {
                self.error = Some(e.to_string());
                return;
            }
        }
        let sizes = self.model.box_sizes();
        if let [na, nb] = sizes[..] {
            let t0 = Instant::now();
            match self.model.joint(t, &set, usize::MAX) {
                Ok(p) => {
                    self.joint_us.push(t0.elapsed().as_secs_f64() * 1e6);
                    self.joint = Some(Joint { na, nb, p });
                }
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }
}

/// Opens a CME meta-model file as a network room.
pub fn open(path: &std::path::Path) -> anyhow::Result<NetworkRoom> {
    let model = palpa_core::cme::model::load(path)
        .with_context(|| format!("cannot open the network scene {}", path.display()))?;
    Ok(NetworkRoom::new(model))
}
