//! The `palpa` command line.

mod args;
mod cme;
mod cme_fit;
mod fe;
mod headless;
mod info;
mod kinds;
mod lab;
mod liver;
mod memory;
mod mesh;
mod networks;
mod nodule;
mod organ;
mod plot;
mod scene;
mod tissue;
mod tradeoff;

use std::process::ExitCode;

use clap::{FromArgMatches, Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "palpa",
    version,
    about = "Real-time PGD meta-models: liver palpation and gene networks"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Describe a meta-model file: axes, rows, modes, provenance, tradeoff table.
    Info(info::InfoArgs),
    /// Mesh an organ and report counts, regions and element quality.
    Mesh(mesh::MeshArgs),
    /// Full finite-element solves (the reference for every accuracy claim).
    #[command(subcommand)]
    Fe(fe::FeCommand),
    /// Compute a PGD vademecum off-line (resumable).
    Offline(liver::OfflineArgs),
    /// Evaluate a palpation meta-model at a probe point (no solving).
    Eval(liver::EvalArgs),
    /// Keep only what a scene needs (surface rows, n modes, f32) for shipping.
    ExportScene(liver::ExportSceneArgs),
    /// Measure the speed/accuracy table of a vademecum and store it in its header.
    Tradeoff(tradeoff::TradeoffArgs),
    /// Gene-network models: the chemical master equation.
    #[command(subcommand)]
    Cme(cme::CmeCommand),
    /// The hyperelastic vademecum of a palpation scene (force and surface, every
    /// palpable vertex): build it, check it against the full nonlinear FE.
    #[command(subcommand)]
    Tissue(tissue::TissueCommand),
    /// The nodule table of a scene: a stiff nodule's effect on the probe's force,
    /// answered without a solve by `palpa eval --nodule-at …`.
    #[command(subcommand)]
    Nodule(nodule::NoduleCommand),
    /// A user's organ surface to a palpation scene: `palpa scene build`.
    #[command(subcommand)]
    Scene(scene::SceneCommand),
    /// Open the interactive app in a window (the default with no subcommand).
    Open(OpenArgs),
    /// Render frames offscreen with a scripted probe while the force thread runs; report timings.
    Headless(headless::HeadlessArgs),
    /// Tools for developing palpa: benchmarks, synthetic models, the depth law, the
    /// tissue's staging tools.
    #[command(subcommand)]
    Lab(lab::LabCommand),
}

/// Parses `std::env::args` and runs the command; errors are printed with their causes.
pub fn main() -> ExitCode {
    quiet_on_a_closed_pipe();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                // egui-wgpu warns that it "prefers" a plain target whenever it draws
                // into an sRGB one. palpa does that only where the adapter cannot view
                // a texture in its sRGB twin (GL), and egui then picks its shader for
                // that target itself: the frame is right, the warning is noise.
                .unwrap_or_else(|_| {
                    tracing_subscriber::EnvFilter::new("warn,egui_wgpu::renderer=error")
                }),
        )
        .with_writer(std::io::stderr)
        .init();
    let matches = command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Err(why) = memory::memory_cap_bytes() {
        eprintln!("error: {why}");
        return ExitCode::FAILURE;
    }
    if let Some(bytes) = memory::available_bytes() {
        // Leave a quarter for everything else the process holds.
        palpa_core::fe::sparse::set_factor_budget_bytes(bytes / 4 * 3);
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            if let Some(what) = kinds::hint(&e) {
                eprintln!("note: {what}");
            }
            ExitCode::FAILURE
        }
    }
}

/// A report piped into a reader that stops early (`palpa info F | head`) ends the
/// process quietly, as the shell's own tools do, instead of a panic and its backtrace:
/// `println!` panics when its pipe is closed, and this hook turns that one panic into
/// an exit (141, a shell's code for a broken pipe). Every other panic is reported as
/// before.
fn quiet_on_a_closed_pipe() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        report(info);
    }));
}

/// The command line, every subcommand reading `-1` as a value: depths, forces,
/// coordinates and ratios are numbers a user may give negative, and each command's own
/// check then says what it expects (without this, clap took `--poisson -1` for a flag
/// and suggested `-- -1`).
pub fn command() -> clap::Command {
    fn negative_numbers(c: clap::Command) -> clap::Command {
        c.allow_negative_numbers(true)
            .mut_subcommands(negative_numbers)
    }
    negative_numbers(<Cli as clap::CommandFactory>::command())
}

/// An error and its causes joined by ": ", as `{:#}` joins them, but without a cause
/// whose text the message before it already ends with (core errors such as
/// `"{path}: {source}"` show their source themselves, and it would print twice).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.is_empty() {
            out = text;
        } else if !out.ends_with(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::error_chain;

    #[test]
    fn a_cause_already_in_its_message_prints_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let e = anyhow::Error::new(io).context("model.palpa: no such file");
        let e = e.context("loading model.palpa");
        assert_eq!(
            error_chain(&e),
            "loading model.palpa: model.palpa: no such file"
        );
        let plain = anyhow::anyhow!("bad flag").context("parsing");
        assert_eq!(error_chain(&plain), "parsing: bad flag");
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Info(args)) => info::run(&args),
        Some(Command::Scene(cmd)) => scene::run(&cmd),
        Some(Command::Mesh(args)) => mesh::run(&args),
        Some(Command::Fe(cmd)) => fe::run(&cmd),
        Some(Command::Offline(args)) => liver::offline(&args),
        Some(Command::Eval(args)) => liver::eval(&args),
        Some(Command::ExportScene(args)) => liver::export_scene(&args),
        Some(Command::Tradeoff(args)) => tradeoff::run(&args),
        Some(Command::Headless(args)) => headless::run_cmd(&args),
        Some(Command::Cme(cmd)) => cme::run(&cmd),
        Some(Command::Lab(cmd)) => lab::run(&cmd),
        Some(Command::Tissue(cmd)) => tissue::run(&cmd),
        Some(Command::Nodule(cmd)) => nodule::run(&cmd),
        Some(Command::Open(args)) => palpa_app::window::run(&args.scene),
        None => default_job(),
    }
}

/// Options of the interactive app.
#[derive(Debug, clap::Args)]
pub struct OpenArgs {
    /// `liver` (the default scene shipped in assets/, built into the binary) or a
    /// palpation `.palpa` file (e.g. one written by `palpa export-scene`).
    #[arg(long, default_value = "liver")]
    scene: String,
}

/// With no subcommand: the interactive app on the default scene.
fn default_job() -> anyhow::Result<()> {
    palpa_app::window::run("liver")
}
