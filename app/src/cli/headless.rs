//! `palpa headless`: offscreen frames with a scripted probe, on whatever adapter wgpu
//! gives (Mesa's software Vulkan on a machine without a GPU).

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;

use palpa_app::offscreen::{HeadlessOptions, HiddenNodule, run};

#[derive(Debug, Args)]
pub struct HeadlessArgs {
    /// `liver` (the built-in default scene) or a palpation `.palpa` file.
    #[arg(long, default_value = "liver")]
    scene: String,
    /// Frames to render (25 per scripted second of the probe path).
    #[arg(long, default_value_t = 250)]
    frames: u32,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// `default` or a JSON file `{"keyframes": [{"t_s", "at_mm", "depth_mm"}, ...]}`.
    #[arg(long, default_value = "default")]
    probe_path: String,
    /// Where to write the last frame (PNG).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Modes kept (default: all the scene has).
    #[arg(long)]
    modes: Option<u32>,
    /// Colour by displacement magnitude, this many mm at the top of the scale.
    #[arg(long)]
    colormap_mm: Option<f32>,
    /// Where the surface is deformed: `gpu` (the compute shader) or `cpu` (every row
    /// and the normals evaluated on the CPU and uploaded). Default: the CPU on a
    /// software adapter, else the GPU; `palpa lab bench deform` measures both.
    #[arg(long, value_name = "gpu|cpu")]
    deform: Option<DeformArg>,
    /// Frame pacing, frames per second, as a display's refresh would pace them
    /// (0: back to back, the force thread's worst case).
    #[arg(long, default_value_t = 60.0)]
    fps: f64,
    /// Leave out the egui interface (the scene only).
    #[arg(long)]
    no_ui: bool,
    /// Network scenes: a coordinate path (JSON keyframes `{"t_s": .., "coordinates":
    /// {"t": .., "delta": ..}}`, 25 frames per second) instead of the time sweep.
    #[arg(long)]
    coordinate_path: Option<PathBuf>,
    /// Network scenes: run the exact (FSP) check at the last frame's coordinates and
    /// report its L1 distance to the meta-model.
    #[arg(long)]
    exact_check: bool,
    /// Network scenes: snapshot data (CSV `t,<species>…`) over the model: its
    /// histograms drawn, its log-likelihood reported.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Network scenes: fit the rates to --data before the last frame (the sliders
    /// moved to the maximum).
    #[arg(long)]
    fit: bool,
    /// Network scenes: Metropolis–Hastings steps per chain on --data before the last
    /// frame (the posterior's density drawn).
    #[arg(long)]
    posterior: Option<usize>,
    /// Physical pixels per interface point: 1 on a desktop monitor, 2 or 3 on tablets
    /// and phones (which also get touch sizes when the short side is ≤ 900 points).
    #[arg(long, default_value_t = 1.0)]
    pixels_per_point: f32,
    /// Safe-area insets TOP,RIGHT,BOTTOM,LEFT in points (a phone's notch and home
    /// indicator, e.g. `47,0,34,0`).
    #[arg(long, default_value = "0,0,0,0")]
    safe_area: String,
    /// The panel unfolded or folded (default: unfolded as a side drawer, folded as a
    /// phone's bottom sheet).
    #[arg(long)]
    panel: Option<PanelState>,
    /// Find the nodule: hide a nodule here (the scene needs its nodule table,
    /// `X.nodules`; the built-in liver has one); the report gives the force with and
    /// without it along the probe path.
    #[command(flatten)]
    nodule: super::args::NoduleArgs,
    /// Find the nodule: hide one drawn from the table's ranges with this seed.
    #[arg(long, conflicts_with = "nodule_at")]
    nodule_seed: Option<u64>,
    /// Mark the hidden nodule where the probe is at the last frame: it is drawn, and
    /// the report scores the mark.
    #[arg(long)]
    mark: bool,
    /// Colour the surface by the trainer's stiffness map (the force with the hidden
    /// nodule over the force without).
    #[arg(long)]
    stiffness_map: bool,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

/// Where the palpation surface is deformed (`--deform`).
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DeformArg {
    Gpu,
    Cpu,
}

impl From<DeformArg> for palpa_app::render::deform::DeformOn {
    fn from(a: DeformArg) -> Self {
        match a {
            DeformArg::Gpu => Self::Gpu,
            DeformArg::Cpu => Self::Cpu,
        }
    }
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum PanelState {
    Open,
    Folded,
}

impl HeadlessArgs {
    fn display(&self) -> anyhow::Result<palpa_app::layout::Display> {
        let ppp = self.pixels_per_point;
        if !(ppp.is_finite() && (0.25..=8.0).contains(&ppp)) {
            bail!("--pixels-per-point {ppp}: expected a density from 0.25 to 8");
        }
        let insets = palpa_app::layout::Insets::parse(&self.safe_area).with_context(|| {
            format!(
                "--safe-area {:?}: expected TOP,RIGHT,BOTTOM,LEFT in points, each ≥ 0",
                self.safe_area
            )
        })?;
        Ok(palpa_app::layout::Display {
            pixels_per_point: ppp,
            insets,
            panel_open: self.panel.map(|p| matches!(p, PanelState::Open)),
        })
    }
}

pub fn run_cmd(args: &HeadlessArgs) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        super::args::check_out(out)?;
    }
    let size = parse_size(&args.size)?;
    let opts = HeadlessOptions {
        scene: args.scene.clone(),
        frames: args.frames,
        size,
        probe_path: (args.probe_path != "default").then(|| PathBuf::from(&args.probe_path)),
        out: args.out.clone(),
        modes: args.modes,
        colormap_mm: args.colormap_mm,
        deform_on: args.deform.map(Into::into),
        fps: args.fps,
        ui: !args.no_ui,
        display: args.display()?,
        nodule: match (args.nodule.nodule()?, args.nodule_seed) {
            (Some(n), _) => Some(HiddenNodule::At(n)),
            (None, Some(s)) => Some(HiddenNodule::Seed(s)),
            (None, None) => None,
        },
        mark: args.mark,
        stiffness_map: args.stiffness_map,
    };
    if !(args.fps.is_finite() && args.fps >= 0.0) {
        bail!(
            "--fps {}: expected a frame rate ≥ 0 (0: back to back)",
            args.fps
        );
    }
    if args.modes == Some(0) {
        bail!("--modes 0: expected at least one mode");
    }
    if let Some(mm) = args.colormap_mm.filter(|mm| !(mm.is_finite() && *mm > 0.0)) {
        bail!("--colormap-mm {mm}: expected a positive displacement (mm) for the colormap's top");
    }
    // A flag of the other kind of scene would be ignored without a word.
    let (network, palpation) = (
        [
            ("--coordinate-path", args.coordinate_path.is_some()),
            ("--exact-check", args.exact_check),
            ("--data", args.data.is_some()),
            ("--fit", args.fit),
            ("--posterior", args.posterior.is_some()),
        ],
        [
            ("--probe-path", args.probe_path != "default"),
            ("--modes", args.modes.is_some()),
            ("--colormap-mm", args.colormap_mm.is_some()),
            ("--deform", args.deform.is_some()),
            ("--nodule-at", args.nodule.nodule_at.is_some()),
            ("--nodule-seed", args.nodule_seed.is_some()),
            ("--mark", args.mark),
            ("--stiffness-map", args.stiffness_map),
        ],
    );
    let given = |flags: &[(&str, bool)]| -> Vec<String> {
        flags
            .iter()
            .filter(|f| f.1)
            .map(|f| f.0.to_string())
            .collect()
    };
    if palpa_app::scenes::is_network(&args.scene) {
        let wrong = given(&palpation);
        if !wrong.is_empty() {
            bail!(
                "{} a palpation scene; {} is a network scene (--coordinate-path drives \
                 it, --exact-check checks it)",
                drive(&wrong),
                args.scene
            );
        }
        return run_network(args, size);
    }
    let wrong = given(&network);
    if !wrong.is_empty() {
        bail!(
            "{} a network scene; {} is a palpation scene (--probe-path drives it)",
            drive(&wrong),
            args.scene
        );
    }
    let (report, _) = run(&opts)?;
    if !print_json(args.json, &report)? {
        println!(
            "{} frames at {}x{} on {} ({}, {}): frame p50 {:.2} ms, p95 {:.2} ms",
            report.frames,
            size.0,
            size.1,
            report.adapter.name,
            report.adapter.backend,
            report.adapter.device_type,
            report.frame_ms_p50,
            report.frame_ms_p95
        );
        println!(
            "force loop: {:.1} Hz, period p50 {:.1} µs, p99 {:.1} µs, {} missed deadlines; contact eval p50 {:.2} µs",
            report.force_hz,
            report.force_period_us_p50,
            report.force_period_us_p99,
            report.missed_deadlines,
            report.eval_us_p50
        );
        if let Some(out) = &report.out {
            println!("last frame: {out}");
        }
    }
    Ok(())
}

/// A network scene: time swept over the frames (the probe options do not apply).
fn run_network(args: &HeadlessArgs, size: (u32, u32)) -> anyhow::Result<()> {
    use palpa_app::network::offscreen::{NetworkHeadless, run};
    let opts = NetworkHeadless {
        scene: args.scene.clone(),
        frames: args.frames,
        size,
        out: args.out.clone(),
        exact_check: args.exact_check,
        ui: !args.no_ui,
        path: args.coordinate_path.clone(),
        display: args.display()?,
        data: args.data.clone(),
        fit: args.fit,
        posterior: args.posterior,
    };
    let (report, _) = run(&opts)?;
    if !print_json(args.json, &report)? {
        println!(
            "{} frames at {}x{} on {} ({}, {}): frame p50 {:.2} ms, p95 {:.2} ms; evaluation p50 {:.1} µs, joint {:.1} µs",
            report.frames,
            size.0,
            size.1,
            report.adapter.name,
            report.adapter.backend,
            report.adapter.device_type,
            report.frame_ms_p50,
            report.frame_ms_p95,
            report.eval_us_p50,
            report.joint_us_p50
        );
        if let Some(out) = &report.out {
            println!("last frame: {out}");
        }
    }
    Ok(())
}

/// "--a drives" or "--a, --b drive".
fn drive(flags: &[String]) -> String {
    let verb = if flags.len() == 1 { "drives" } else { "drive" };
    format!("{} {verb}", flags.join(", "))
}

/// Prints `report` as pretty JSON when `json` is set; returns whether it did.
fn print_json(json: bool, report: &impl serde::Serialize) -> anyhow::Result<bool> {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).context("encoding the report")?
        );
    }
    Ok(json)
}

/// `WIDTHxHEIGHT`.
pub fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)));
    match parsed {
        Some((w, h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => bail!("--size {s:?}: expected WIDTHxHEIGHT, e.g. 1280x720"),
    }
}
