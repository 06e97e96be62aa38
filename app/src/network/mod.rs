//! The gene-network scene: a CME meta-model `P(z, t; p)` explored at its coordinates.
//!
//! The room holds the model and the user's coordinates (time and every parameter over
//! its trained range), evaluates the marginals and moments (and, for two species, the
//! joint on the whole box) only when a coordinate changes, and times each evaluation.
//! Nothing here is palpation's: the window and headless mode pick this room or the
//! palpation [`crate::session::Session`] by the scene file's kind.

pub mod build;
pub mod check;
pub mod data;
pub mod job;
pub mod offscreen;
pub mod path;
mod ui;

use std::time::Instant;

use anyhow::Context;
use palpa_core::cme::model::{CmeModel, Evaluation};
use palpa_core::cme::moments::{Moments, l1};
use palpa_core::cme::network::Network;

use crate::stats::Ring;
use check::{Exact, Sampled};
use job::{Job, JobState};

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

/// The exact check's verdict at the coordinates it ran at.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckResult {
    pub coordinates: Vec<f64>,
    /// L1 distance between the meta-model's and the exact joint, or for a views
    /// model (which keeps no whole joint) the largest over its marginals.
    pub l1: f64,
    /// Whether `l1` compares whole joints (else marginals).
    pub joint: bool,
    /// The exact solve's time, s, and the meta-model's joint evaluation there, µs.
    pub exact_s: f64,
    pub model_us: f64,
    /// The exact marginals (overlaid on the model's).
    pub exact: Moments,
}

/// The sampled check's verdict at the coordinates it ran at.
#[derive(Debug, Clone, PartialEq)]
pub struct SsaResult {
    pub sampled: Sampled,
    /// Largest L1 distance, over the species, between the meta-model's marginal and
    /// the histogram (it includes the sampling noise, about √(bins / K)).
    pub l1: f64,
}

/// The heat map's texture and the coordinates it shows.
pub struct HeatTexture {
    pub key: Vec<f64>,
    pub handle: egui::TextureHandle,
}

impl std::fmt::Debug for HeatTexture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeatTexture")
            .field("key", &self.key)
            .finish_non_exhaustive()
    }
}

/// The part of a joint worth showing, binned to at most `MAX_CELLS` a side: copy
/// numbers `a0..a0 + wa` of the first species and `b0..b0 + wb` of the second, `cells`
/// (`nx × ny`, first species fastest) summed over `bin × bin` states, `peak` their
/// largest.
#[derive(Debug, Clone, PartialEq)]
pub struct JointWindow {
    pub a0: usize,
    pub b0: usize,
    pub wa: usize,
    pub wb: usize,
    pub nx: usize,
    pub ny: usize,
    pub cells: Vec<f64>,
    pub peak: f64,
}

/// The landscape's base side and peak height (scene units).
pub const LANDSCAPE_SIDE: f32 = 100.0;
pub const LANDSCAPE_HEIGHT: f32 = 45.0;

/// Most cells a side of a [`JointWindow`].
pub const MAX_CELLS: usize = 160;

/// The copy numbers worth showing of a marginal `p`: from the first to the last where
/// it is at least 1e-4 of its largest value, two more each side (the joint's rule, so
/// its plot shows the mass instead of the whole truncated range). `None` where `p` is
/// zero (or not finite) everywhere.
pub fn marginal_window(p: &[f64]) -> Option<std::ops::RangeInclusive<usize>> {
    let top = p
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    if top <= 0.0 {
        return None;
    }
    let shown = |v: &f64| *v >= 1e-4 * top;
    let first = p.iter().position(shown)?;
    let last = p.iter().rposition(shown)?;
    Some(first.saturating_sub(2)..=(last + 2).min(p.len() - 1))
}

impl Joint {
    /// The square window (with a margin) around where the joint is at least 1e-4 of
    /// its largest value: the box is sized for every time and parameter, the
    /// distribution at one of them is smaller. `None` where it is zero.
    pub fn window(&self) -> Option<JointWindow> {
        let top = self.p.iter().copied().fold(0.0f64, f64::max);
        let (mut a0, mut a1, mut b0, mut b1) = (self.na, 0, self.nb, 0);
        for b in 0..self.nb {
            for a in 0..self.na {
                if self.p[b * self.na + a] >= 1e-4 * top {
                    (a0, a1, b0, b1) = (a0.min(a), a1.max(a + 1), b0.min(b), b1.max(b + 1));
                }
            }
        }
        if top <= 0.0 || a0 >= a1 || b0 >= b1 {
            return None;
        }
        let side = (a1 - a0).max(b1 - b0) + 4;
        let a0 = a0.saturating_sub(2).min(self.na.saturating_sub(side));
        let b0 = b0.saturating_sub(2).min(self.nb.saturating_sub(side));
        let (wa, wb) = (side.min(self.na - a0), side.min(self.nb - b0));
        let bin = wa.max(wb).div_ceil(MAX_CELLS);
        let (nx, ny) = (wa.div_ceil(bin), wb.div_ceil(bin));
        let mut cells = vec![0.0f64; nx * ny];
        for b in 0..wb {
            for a in 0..wa {
                cells[(b / bin) * nx + a / bin] += self.p[(b0 + b) * self.na + a0 + a];
            }
        }
        let peak = cells.iter().copied().fold(0.0f64, f64::max);
        Some(JointWindow {
            a0,
            b0,
            wa,
            wb,
            nx,
            ny,
            cells,
            peak,
        })
    }
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
    /// The network the model was built from, when it is known (a built-in): what the
    /// exact check solves.
    pub network: Option<Network>,
    pub check: Option<Job<Exact>>,
    pub check_result: Option<CheckResult>,
    /// The sampled (SSA) check and its verdict.
    pub ssa: Option<Job<Sampled>>,
    pub ssa_result: Option<SsaResult>,
    /// The joint's heat-map texture (the interface's, kept across frames).
    pub heat: Option<HeatTexture>,
    /// The species × copy-number strip's texture (many species).
    pub strip: Option<HeatTexture>,
    /// The window of the joint at the current coordinates (heat map and landscape),
    /// and a count of its changes (what a view compares to know it must redraw).
    pub window: Option<JointWindow>,
    pub window_generation: u64,
    /// The landscape's camera (orbit by dragging the background, zoom by the wheel).
    pub camera: crate::camera::OrbitCamera,
    /// The two species whose joint is shown (the others summed out in the model).
    pub pair: (usize, usize),
    /// Snapshot data loaded over the model, and the path typed in the panel.
    pub data: Option<data::DataOverlay>,
    pub data_path: String,
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
            network: network_of(&model),
            check: None,
            check_result: None,
            ssa: None,
            ssa_result: None,
            heat: None,
            strip: None,
            window: None,
            window_generation: 0,
            pair: model
                .pairs()
                .and_then(|p| p.first().copied())
                .unwrap_or((0, 1)),
            data: None,
            data_path: String::new(),
            camera: crate::camera::OrbitCamera::framing(
                glam::Vec3::ZERO,
                glam::Vec3::new(LANDSCAPE_SIDE, LANDSCAPE_SIDE, LANDSCAPE_HEIGHT),
            ),
            model,
        }
    }

    /// Gamepad steering: the left stick moves the first two parameters (full deflection
    /// crosses a range in 4 s), the right stick's x scrubs time and the trigger plays it
    /// forward (full: the whole axis in 5 s). Inside a dead zone of 0.15 nothing moves.
    pub fn steer(&mut self, left: [f32; 2], right_x: f32, trigger: f32, dt_s: f32) {
        let live = |v: f32| if v.abs() < 0.15 { 0.0 } else { f64::from(v) };
        let dt = f64::from(dt_s.max(0.0));
        for (c, v) in self.params.iter_mut().zip(left) {
            let span = c.hi - c.lo;
            c.value = (c.value + live(v) * span / 4.0 * dt).clamp(c.lo, c.hi);
        }
        let rate = live(right_x) + live(trigger).max(0.0);
        let t = &mut self.time;
        t.value = (t.value + rate * (t.hi - t.lo) / 5.0 * dt).clamp(t.lo, t.hi);
    }

    /// Loads snapshot data (CSV) over the model and evaluates its log-likelihood at
    /// the current rates.
    pub fn load_data(&mut self, path: &std::path::Path) -> anyhow::Result<()> {
        let mut d = data::DataOverlay::load(&self.model, path)?;
        d.evaluate(&self.params);
        self.data = Some(d);
        Ok(())
    }

    /// Fits the rates to the loaded data and moves the sliders to the maximum.
    pub fn fit_data(&mut self) -> anyhow::Result<()> {
        let d = self.data.as_mut().context("load a data file first")?;
        if self.params.is_empty() {
            anyhow::bail!("the model has no rates to fit (no range parameters)");
        }
        let mle = d.fit(&self.params);
        for (c, v) in self.params.iter_mut().zip(mle) {
            c.value = v;
        }
        Ok(())
    }

    /// The posterior of the rates given the loaded data (`steps` per chain).
    pub fn sample_posterior(&mut self, steps: usize) -> anyhow::Result<()> {
        let d = self.data.as_mut().context("load a data file first")?;
        if self.params.is_empty() {
            anyhow::bail!("the model has no rates to sample (no range parameters)");
        }
        d.sample(&self.params, steps, 0x5eed);
        Ok(())
    }

    /// Starts the exact (FSP) check at the current coordinates, replacing a running one.
    pub fn start_check(&mut self) -> anyhow::Result<()> {
        let network = self
            .network
            .as_ref()
            .context("the exact check needs the network the model was built from")?;
        let (p, _) = network.parameter_values(&self.settings())?;
        if let Some(old) = self.check.as_mut() {
            old.cancel();
        }
        self.check = Some(check::start_exact(
            network,
            &p,
            &self.model.box_sizes(),
            self.time.value,
            self.coordinates(),
        )?);
        Ok(())
    }

    /// Starts the sampled (SSA, `trajectories` paths, seeded) check at the current
    /// coordinates, replacing a running one.
    pub fn start_ssa(&mut self, trajectories: usize) -> anyhow::Result<()> {
        let network = self
            .network
            .as_ref()
            .context("the SSA check needs the network the model was built from")?;
        let (p, _) = network.parameter_values(&self.settings())?;
        if let Some(old) = self.ssa.as_mut() {
            old.cancel();
        }
        self.ssa = Some(check::start_sampled(
            network,
            &p,
            &self.model.box_sizes(),
            self.time.value,
            self.coordinates(),
            trajectories,
            0x5eed,
        )?);
        Ok(())
    }

    /// Takes a finished SSA check and compares its histograms with the model's
    /// marginals there.
    fn poll_ssa(&mut self) {
        let Some(job) = self.ssa.as_mut() else {
            return;
        };
        let JobState::Done(sampled) = job.poll().clone() else {
            return;
        };
        self.ssa = None;
        let set = self.settings_at(&sampled.coordinates);
        match self
            .model
            .evaluate(sampled.coordinates[0], &set, usize::MAX)
        {
            Ok(e) => {
                let l1 = e
                    .moments
                    .marginals
                    .iter()
                    .zip(&sampled.marginals)
                    .map(|(m, s)| l1(m, s))
                    .fold(0.0, f64::max);
                self.ssa_result = Some(SsaResult { sampled, l1 });
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// The parameter settings at stored coordinates (time first).
    fn settings_at(&self, coordinates: &[f64]) -> Vec<(String, f64)> {
        self.params
            .iter()
            .zip(&coordinates[1..])
            .map(|(c, &v)| (c.name.clone(), v))
            .collect()
    }

    /// Takes a finished check's joint and compares it with the meta-model's there.
    fn poll_check(&mut self) {
        let Some(check) = self.check.as_mut() else {
            return;
        };
        let JobState::Done(exact) = check.poll().clone() else {
            return;
        };
        self.check = None;
        let t = exact.coordinates[0];
        let set = self.settings_at(&exact.coordinates);
        let exact_moments = Moments::from_joint(t, &self.model.box_sizes(), &exact.joint);
        let t0 = Instant::now();
        // A views model keeps marginals and a few joints, not the whole one: its
        // marginals are what it is checked on.
        let compared = if self.model.pairs().is_some() {
            self.model.evaluate(t, &set, usize::MAX).map(|e| {
                let l1 = e
                    .moments
                    .marginals
                    .iter()
                    .zip(&exact_moments.marginals)
                    .map(|(m, x)| l1(m, x))
                    .fold(0.0, f64::max);
                (l1, false)
            })
        } else {
            self.model
                .joint(t, &set, usize::MAX)
                .map(|joint| (l1(&joint, &exact.joint), true))
        };
        match compared {
            Ok((l1, joint)) => {
                let model_us = t0.elapsed().as_secs_f64() * 1e6;
                self.check_result = Some(CheckResult {
                    l1,
                    joint,
                    exact: exact_moments,
                    coordinates: exact.coordinates,
                    exact_s: exact.seconds,
                    model_us,
                });
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    pub fn model(&self) -> &CmeModel {
        &self.model
    }

    /// The current coordinates: time, then the parameters in the model's order (and,
    /// last, the shown pair, so a new pair is evaluated like a moved coordinate).
    pub fn coordinates(&self) -> Vec<f64> {
        std::iter::once(self.time.value)
            .chain(self.params.iter().map(|c| c.value))
            .collect()
    }

    fn evaluation_key(&self) -> Vec<f64> {
        let mut k = self.coordinates();
        k.extend([self.pair.0 as f64, self.pair.1 as f64]);
        k
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
        self.poll_check();
        self.poll_ssa();
        let now = self.evaluation_key();
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
        if let Some(d) = &mut self.data {
            d.evaluate(&self.params);
        }
        let sizes = self.model.box_sizes();
        let (a, b) = self.pair;
        if a != b && a < sizes.len() && b < sizes.len() {
            let (na, nb) = (sizes[a], sizes[b]);
            let t0 = Instant::now();
            match self.model.pair_joint(t, &set, a, b) {
                Ok(p) => {
                    self.joint_us.push(t0.elapsed().as_secs_f64() * 1e6);
                    let joint = Joint { na, nb, p };
                    self.window = joint.window();
                    self.window_generation += 1;
                    self.joint = Some(joint);
                }
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }
}

/// The network a model was built from: the one its file keeps, else the built-in
/// network it names in its provenance (`network NAME; …`), if its species and boxes
/// are the model's.
fn network_of(model: &CmeModel) -> Option<Network> {
    let meta = model.meta();
    if let Ok(network) = Network::from_toml(&meta.provenance.network, "the model's network") {
        return Some(network);
    }
    let name = meta
        .provenance
        .mesh
        .strip_prefix("network ")?
        .split(';')
        .next()?
        .trim()
        .to_string();
    let network = Network::built_in(&name).ok()?;
    let names: Vec<String> = network.species.iter().map(|s| s.name.clone()).collect();
    let boxes: Vec<Option<usize>> = network.species.iter().map(|s| s.max).collect();
    let model_boxes: Vec<Option<usize>> = model.box_sizes().into_iter().map(Some).collect();
    (names == model.species_names() && boxes == model_boxes).then_some(network)
}

/// A network scene ready to show, or its meta-model still being built.
#[derive(Debug)]
pub enum Prepared {
    Ready(Box<NetworkRoom>),
    Building(Box<build::NetworkBuild>),
}

/// The room of `network` (from a TOML file `toml`, or built in): its cached meta-model
/// if there is one that opens, else a background build of it.
pub fn prepare(network: Network, toml: Option<&std::path::Path>) -> anyhow::Result<Prepared> {
    let recipe = palpa_core::cme::build::Recipe::default_for(&network, 300.0);
    let cache = build::cache_path(&network, &recipe, toml);
    if cache.exists()
        && let Ok(mut room) = open(&cache)
    {
        room.network = Some(network);
        return Ok(Prepared::Ready(Box::new(room)));
    }
    Ok(Prepared::Building(Box::new(build::NetworkBuild::start(
        network, recipe, cache,
    )?)))
}

/// Opens a CME meta-model file as a network room.
pub fn open(path: &std::path::Path) -> anyhow::Result<NetworkRoom> {
    let model = palpa_core::cme::model::load(path)
        .with_context(|| format!("cannot open the network scene {}", path.display()))?;
    Ok(NetworkRoom::new(model))
}

#[cfg(test)]
mod tests {
    use super::*;
    use palpa_core::cme::{build, ttsolve};

    /// The cascade (δ a coordinate) on [0, 2]: seconds to build.
    fn cascade_room() -> NetworkRoom {
        let net = Network::built_in("cascade").expect("built in");
        let options = ttsolve::Options {
            t_end: 2.0,
            h_max: 0.1,
            ..ttsolve::Options::default()
        };
        let built = build::train(&net, &options, None, &mut |_| {}).expect("builds");
        let mut room = NetworkRoom::new(built.model);
        room.network = Some(net);
        room
    }

    #[test]
    fn the_room_evaluates_on_change_and_steers_within_the_ranges() {
        let mut room = cascade_room();
        assert_eq!(room.params.len(), 1, "δ");
        room.frame(0.0);
        let e = room.eval.clone().expect("evaluated");
        // The same numbers as the model at the same coordinates.
        let direct = room
            .model()
            .evaluate(room.time.value, &room.settings(), usize::MAX)
            .expect("evaluates");
        assert_eq!(e.moments.mean, direct.moments.mean);
        assert!(room.joint.is_some(), "two species: the joint is shown");
        let n = room.eval_us.len();
        room.frame(0.0);
        assert_eq!(room.eval_us.len(), n, "no change, no evaluation");
        // Inside the dead zone nothing moves; full deflection for 1 s crosses a quarter.
        let (d0, t0) = (room.params[0].value, room.time.value);
        room.steer([0.1, 0.0], 0.1, 0.0, 1.0);
        assert_eq!((room.params[0].value, room.time.value), (d0, t0));
        room.steer([1.0, 0.0], 0.0, 0.0, 1.0);
        let span = room.params[0].hi - room.params[0].lo;
        assert!((room.params[0].value - (d0 + span / 4.0)).abs() < 1e-12);
        room.steer([1.0, 0.0], 0.0, 1.0, 100.0);
        assert_eq!(
            room.params[0].value, room.params[0].hi,
            "clamped to the range"
        );
        assert_eq!(room.time.value, room.time.hi);
        room.frame(0.0);
        assert_eq!(room.eval_us.len(), n + 1, "moved, evaluated once");
        // Another pair is evaluated like a moved coordinate: here the transpose.
        let before = room.joint.clone().expect("joint");
        room.pair = (1, 0);
        room.frame(0.0);
        let after = room.joint.clone().expect("joint");
        assert_eq!((after.na, after.nb), (before.nb, before.na));
        assert_eq!(after.p[after.na + 3], before.p[3 * before.na + 1]);
        // Playing wraps to 0 past the end.
        room.playing = true;
        room.frame(1.0);
        assert_eq!(room.time.value, 0.0);
    }

    /// A views model (many species) opens as a room that offers its stored joints
    /// only, evaluates every marginal, and refuses the exact check by the box's size
    /// with a message instead of trying.
    #[test]
    fn a_views_room_shows_its_stored_pairs_and_refuses_an_impossible_check() {
        use palpa_core::cme::build::Recipe;
        let net = Network::built_in("signaling-cascade-8").expect("built in");
        let recipe = Recipe::default_for(&net, 3.0);
        assert!(recipe.views.is_some(), "eight species: views");
        let built = recipe.build(&net, None, &mut |_| {}).expect("builds");
        let mut room = NetworkRoom::new(built.model);
        room.network = Some(net);
        assert_eq!(room.pair, (0, 1));
        assert_eq!(room.model().pairs().map(|p| p.len()), Some(7));
        room.frame(0.0);
        let e = room.eval.clone().expect("evaluated");
        assert_eq!(e.moments.marginals.len(), 8);
        assert!((e.moments.mass - 1.0).abs() < 1e-3, "{}", e.moments.mass);
        let joint = room.joint.clone().expect("the stored first pair");
        assert_eq!((joint.na, joint.nb), (64, 64));
        // A pair that is not stored: the room says so, it does not panic.
        room.pair = (0, 5);
        room.frame(0.0);
        let why = room.error.clone().expect("not stored");
        assert!(why.contains("not stored"), "{why}");
        // 64⁸ states: FSP refuses by size.
        let err = format!("{:#}", room.start_check().expect_err("too large"));
        assert!(err.contains("states"), "{err}");
    }

    /// A marginal's plot shows where its mass is (two copies' margin), within the
    /// truncated range; nothing to show where it is zero or not finite.
    #[test]
    fn a_marginal_plot_shows_where_the_mass_is() {
        let mut p = vec![0.0; 200];
        for (z, v) in p.iter_mut().enumerate().skip(30).take(20) {
            *v = (-((z as f64 - 40.0) / 3.0).powi(2)).exp();
        }
        // 1e-4 of the peak: copy 30 is below it (e^-11.1), 31 and 49 above (e^-9).
        assert_eq!(marginal_window(&p), Some(29..=51));
        p[1] = 0.5;
        p[199] = 2e-4;
        assert_eq!(marginal_window(&p), Some(0..=199));
        assert_eq!(marginal_window(&[0.0; 5]), None);
        assert_eq!(marginal_window(&[f64::NAN; 5]), None);
        assert_eq!(marginal_window(&[]), None);
    }
}
