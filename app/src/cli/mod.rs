//! The `palpa` command line.

mod args;
mod bench;
mod bench_fe;
mod fe;
mod headless;
mod info;
mod memory;
mod mesh;
mod organ;
mod pgd;
mod synth;
mod tradeoff;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
    /// Benchmarks that print ratios measured in one run.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Write a seeded synthetic model file (benchmarks, fuzz seeds, trying the tools).
    Synth(synth::SynthArgs),
    /// Mesh an organ and report counts, regions and element quality.
    Mesh(mesh::MeshArgs),
    /// Full finite-element solves (the reference for every accuracy claim).
    #[command(subcommand)]
    Fe(fe::FeCommand),
    /// Compute a PGD vademecum off-line (resumable).
    Offline(pgd::OfflineArgs),
    /// Evaluate a palpation meta-model at a probe point (no solving).
    Eval(pgd::EvalArgs),
    /// Keep only what a scene needs (surface rows, n modes, f32) for shipping.
    ExportScene(pgd::ExportSceneArgs),
    /// Measure the speed/accuracy table of a vademecum and store it in its header.
    Tradeoff(tradeoff::TradeoffArgs),
    /// Render frames offscreen with a scripted probe while the force thread runs; report timings.
    Headless(headless::HeadlessArgs),
}

/// Parses `std::env::args` and runs the command; errors are printed with their causes.
pub fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    if let Some(bytes) = memory::available_bytes() {
        // Leave a quarter for everything else the process holds.
        palpa_core::fe::sparse::set_factor_budget_bytes(bytes / 4 * 3);
    }
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Info(args)) => info::run(&args),
        Some(Command::Bench(cmd)) => bench::run(&cmd),
        Some(Command::Synth(args)) => synth::run(&args),
        Some(Command::Mesh(args)) => mesh::run(&args),
        Some(Command::Fe(cmd)) => fe::run(&cmd),
        Some(Command::Offline(args)) => pgd::offline(&args),
        Some(Command::Eval(args)) => pgd::eval(&args),
        Some(Command::ExportScene(args)) => pgd::export_scene(&args),
        Some(Command::Tradeoff(args)) => tradeoff::run(&args),
        Some(Command::Headless(args)) => headless::run_cmd(&args),
        None => default_job(),
    }
}

/// The default scene shipped in `assets/`.
const DEFAULT_SCENE: &str = "assets/liver-coarse.palpa";

/// With no subcommand: the interactive app once it lands; until then, what the shipped
/// scene holds, one evaluation of it, and a short evaluator benchmark.
fn default_job() -> anyhow::Result<()> {
    println!(
        "palpa {} — real-time PGD meta-models",
        env!("CARGO_PKG_VERSION")
    );
    println!(
        "The interactive palpation app is not built yet (see README for the commands).\n\n\
         Default scene: {DEFAULT_SCENE}"
    );
    let scene = std::path::Path::new(DEFAULT_SCENE);
    if scene.exists() {
        info::run(&info::InfoArgs::new(scene.into(), true))?;
        println!(
            "\nPressing it with 1 N at the anterior right lobe (no solving, just evaluation):"
        );
        pgd::eval(&pgd::EvalArgs::new(scene.into(), [-30.0, 90.0, 25.0], 1.0))?;
    } else {
        println!("(not found: run from the repository root, or scripts/make-assets.sh)");
    }
    println!("\nEvaluator speed against memory bandwidth, short sweep:\n");
    bench::run(&bench::BenchCommand::quick())
}
