//! Headless frames of a network scene: time swept from 0 to the model's end over the
//! frames (parameters at the middle of their trained ranges), each frame evaluated and
//! drawn offscreen with its interface, timings reported.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::bail;
use serde::Serialize;

use super::NetworkRoom;
use super::build::BuildState;
use crate::overlay::{Overlay, headless_input};
use crate::render::gpu::{AdapterReport, Gpu};
use crate::render::landscape::Landscape;
use crate::render::offscreen::{FORMAT, Image, Offscreen};
use crate::stats::percentile;
use crate::ui::Hud;

/// What to render.
#[derive(Debug, Clone)]
pub struct NetworkHeadless {
    /// A meta-model file, a network TOML file or a built-in network's name (the last
    /// two are built first if their cache is empty).
    pub scene: String,
    pub frames: u32,
    pub size: (u32, u32),
    pub out: Option<PathBuf>,
    /// Run the exact (FSP) check at the last frame's coordinates and show it.
    pub exact_check: bool,
    /// Draw the interface (off: the landscape alone, what the display-rate goal is
    /// about).
    pub ui: bool,
    /// Coordinates over the frames (at 25 frames per clock second); `None`: time swept
    /// from 0 to its end, parameters at the middle of their ranges.
    pub path: Option<PathBuf>,
    /// Density, safe area and panel state of the interface.
    pub display: crate::layout::Display,
    /// Snapshot data loaded over the model (its histograms drawn, its log-likelihood
    /// reported), fitted before the last frame with `fit`, sampled with `posterior`
    /// steps a chain.
    pub data: Option<PathBuf>,
    pub fit: bool,
    pub posterior: Option<usize>,
}

/// What the data did in a headless run.
#[derive(Debug, Clone, Serialize)]
pub struct DataReport {
    pub source: String,
    pub cells: usize,
    /// At the last frame's rates (after a fit, the maximum).
    pub log_likelihood: Option<f64>,
    pub likelihood_us: f64,
    /// Each rate's maximum and profile interval, when fitted.
    pub estimates: Vec<EstimateValue>,
    /// The posterior's largest R-hat and smallest effective sample size.
    pub posterior_rhat: Option<f64>,
    pub posterior_ess: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct EstimateValue {
    pub name: String,
    pub mle: f64,
    pub profile_ci95: [f64; 2],
}

/// The coordinates of a frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoordinateValue {
    pub name: String,
    pub value: f64,
}

/// What a headless network run measured.
#[derive(Debug, Clone, Serialize)]
pub struct NetworkReport {
    pub scene: String,
    pub kind: &'static str,
    pub frames: u32,
    pub size: [u32; 2],
    pub species: Vec<String>,
    pub frame_ms_p50: f64,
    pub frame_ms_p95: f64,
    pub frame_ms_max: f64,
    /// Marginals and moments per coordinate change, µs.
    pub eval_us_p50: f64,
    /// The two-species joint per coordinate change, µs (NaN when not shown).
    pub joint_us_p50: f64,
    /// Time and parameters of the last frame.
    pub last_coordinates: Vec<CoordinateValue>,
    pub last_mass: f64,
    pub last_mean: Vec<f64>,
    /// Coordinates the last frame's evaluation clamped to the trained range.
    pub last_clamped: Vec<String>,
    /// The exact check at the last frame: L1 distance of the joints, FSP seconds.
    pub exact_l1: Option<f64>,
    pub exact_s: Option<f64>,
    pub adapter: AdapterReport,
    pub out: Option<String>,
    /// The interface's layout in the last frame (with the interface on).
    pub layout: Option<crate::layout::LayoutReport>,
    pub data: Option<DataReport>,
}

/// Renders the frames; returns the report and the last image.
pub fn run(opts: &NetworkHeadless) -> anyhow::Result<(NetworkReport, Image)> {
    crate::offscreen::check_frames(opts.size, opts.frames)?;
    let (w, h) = opts.size;
    let mut room = open_blocking(&opts.scene)?;
    if let Some(d) = &opts.data {
        room.load_data(d)?;
    } else if opts.fit || opts.posterior.is_some() {
        bail!("--fit and --posterior need --data (the cells to fit)");
    }
    let path = match &opts.path {
        Some(p) => {
            let path = super::path::CoordinatePath::load(p)?;
            path.check_names(&room)?;
            Some(path)
        }
        None => None,
    };
    let gpu = Gpu::headless()?;
    let target = Offscreen::new(&gpu.device, opts.size, gpu.can_reinterpret());
    let mut overlay = Overlay::new(&gpu.device, target.ui_format, gpu.is_software());
    let mut landscape = Landscape::new(&gpu.device, FORMAT);
    let mut hud = Hud::new(opts.scene.clone());
    hud.panel_open = opts.display.panel_open;
    let mut frame_ms = Vec::with_capacity(opts.frames as usize);
    for i in 0..opts.frames {
        match &path {
            Some(p) => p.apply(f64::from(i) / 25.0, &mut room),
            None => room.time.value = sweep(&room, i, opts.frames),
        }
        let last = i + 1 == opts.frames;
        if last && opts.fit {
            room.fit_data()?;
        }
        if last && let Some(steps) = opts.posterior {
            room.sample_posterior(steps)?;
        }
        if last && opts.exact_check {
            room.start_check()?;
            let waited = Instant::now();
            while room.check.is_some() && waited.elapsed().as_secs() < 600 {
                room.frame(0.0);
                if let Some(c) = &room.check
                    && let super::job::JobState::Failed(why) = &c.state
                {
                    bail!("the exact check failed: {why}");
                }
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            if room.check_result.is_none() {
                bail!("the exact check did not finish in 600 s");
            }
        }
        let t0 = Instant::now();
        room.frame(0.0);
        landscape.set(&gpu.device, room.window.as_ref(), room.window_generation);
        let mut encoder = landscape.encode(
            &gpu.device,
            &gpu.queue,
            &target.view,
            opts.size,
            &room.camera,
        );
        if opts.ui {
            let raw = headless_input(
                opts.size,
                opts.display.pixels_per_point,
                opts.display.insets,
                f64::from(i) / 25.0,
            );
            overlay.paint(
                &gpu.device,
                &gpu.queue,
                &mut encoder,
                &target.ui_view,
                opts.size,
                opts.display.pixels_per_point,
                raw,
                |ctx| super::show(ctx, &mut room, &mut hud),
            );
        }
        if last {
            target.encode_copy(&mut encoder);
        }
        gpu.submit_and_wait(encoder)?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        hud.frame_ms.push(ms);
        frame_ms.push(ms);
    }
    if let Some(e) = &room.error {
        bail!("evaluating {}: {e}", opts.scene);
    }
    let image = target.read(&gpu.device)?;
    if let Some(out) = &opts.out {
        image.save_png(out)?;
    }
    let last_coordinates = std::iter::once(&room.time)
        .chain(&room.params)
        .map(|c| CoordinateValue {
            name: c.name.clone(),
            value: c.value,
        })
        .collect();
    let moments = room.eval.as_ref().map(|e| &e.moments);
    let joint_us = if room.joint.is_some() {
        room.joint_us.quantile(0.5)
    } else {
        f64::NAN
    };
    let report = NetworkReport {
        scene: opts.scene.clone(),
        kind: "network",
        frames: opts.frames,
        size: [w, h],
        species: room.species.clone(),
        frame_ms_p50: percentile(frame_ms.clone(), 0.5),
        frame_ms_p95: percentile(frame_ms.clone(), 0.95),
        frame_ms_max: percentile(frame_ms, 1.0),
        eval_us_p50: room.eval_us.quantile(0.5),
        joint_us_p50: joint_us,
        last_coordinates,
        last_mass: moments.map_or(f64::NAN, |m| m.mass),
        last_mean: moments.map_or_else(Vec::new, |m| m.mean.clone()),
        last_clamped: room
            .eval
            .as_ref()
            .map_or_else(Vec::new, |e| e.clamped.clone()),
        exact_l1: room.check_result.as_ref().map(|r| r.l1),
        exact_s: room.check_result.as_ref().map(|r| r.exact_s),
        adapter: gpu.report(),
        out: opts.out.as_ref().map(|p| p.display().to_string()),
        data: room.data.as_ref().map(|d| DataReport {
            source: d.source.clone(),
            cells: d.snapshots.cell_count(),
            log_likelihood: d.log_likelihood,
            likelihood_us: d.likelihood_us,
            estimates: d.fit.as_ref().map_or_else(Vec::new, |(e, _)| {
                e.iter()
                    .map(|e| EstimateValue {
                        name: e.name.clone(),
                        mle: e.mle,
                        profile_ci95: e.profile_ci95,
                    })
                    .collect()
            }),
            posterior_rhat: d.posterior.as_ref().map(|(p, _)| p.worst_rhat()),
            posterior_ess: d.posterior.as_ref().map(|(p, _)| p.least_ess()),
        }),
        layout: opts.ui.then(|| {
            crate::layout::report(
                &overlay.ctx,
                hud.touch_seen,
                hud.panel_open.unwrap_or(false),
            )
        }),
    };
    Ok((report, image))
}

/// The room of `spec`; a network given by name or TOML without a cached meta-model is
/// built first (progress on stderr).
fn open_blocking(spec: &str) -> anyhow::Result<NetworkRoom> {
    let Some((network, toml)) = crate::scenes::network_source(spec)? else {
        return super::open(std::path::Path::new(spec));
    };
    match super::prepare(network, toml.as_deref())? {
        super::Prepared::Ready(room) => Ok(*room),
        super::Prepared::Building(mut b) => {
            eprintln!(
                "palpa: building the meta-model of {} into {}",
                spec,
                b.out.display()
            );
            let mut shown = 0.0;
            loop {
                match b.poll().clone() {
                    BuildState::Running { progress } => {
                        if progress >= shown + 0.1 {
                            shown = progress;
                            eprintln!(
                                "palpa: t reached {:.0} % of the time axis",
                                100.0 * progress
                            );
                        }
                        std::thread::sleep(std::time::Duration::from_millis(20));
                    }
                    BuildState::Done(path) => return b.room(&path),
                    BuildState::Failed(why) => bail!("building the meta-model of {spec}: {why}"),
                    BuildState::Cancelled => {
                        bail!("building the meta-model of {spec} was cancelled")
                    }
                }
            }
        }
    }
}

/// Frame `i` of `n`: time from 0 to the end of the trained range.
fn sweep(room: &NetworkRoom, i: u32, n: u32) -> f64 {
    if n <= 1 {
        room.time.hi
    } else {
        room.time.hi * f64::from(i) / f64::from(n - 1)
    }
}
