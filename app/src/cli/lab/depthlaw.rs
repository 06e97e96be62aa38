//! `palpa lab depth-law …`: the hyperelastic force law `F(s, d)` of a palpation scene
//! (see `palpa_core::tissue::depthlaw`): build it off-line from depth series, evaluate it
//! with a scene's linear compliance.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use palpa_core::fe::{Element, Material};
use palpa_core::tissue::depthlaw::{DepthLaw, DepthLawOptions};
use serde_json::json;

use crate::cli::args::{NonlinearModel, OrganArgs};

#[derive(Debug, Subcommand)]
pub enum DepthLawCommand {
    /// Build the force law off-line (depth series at spread sample positions).
    Build(BuildArgs),
    /// Evaluate the force law at a probe point of a scene: depth in, force out, or the
    /// inverse (no solving).
    Eval(EvalArgs),
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    #[command(flatten)]
    organ: OrganArgs,
    #[arg(long, value_enum, default_value = "neo-hookean")]
    model: NonlinearModel,
    #[arg(long, default_value = "p2")]
    element: Element,
    /// Sample positions spread over the palpable surface.
    #[arg(long, default_value_t = DepthLawOptions::default().samples)]
    samples: usize,
    /// Deepest press the law covers (mm); deeper presses are clamped and flagged.
    #[arg(long, default_value_t = DepthLawOptions::default().depth_max_mm)]
    depth_max_mm: f64,
    /// Orders of each depth series.
    #[arg(long, default_value_t = DepthLawOptions::default().orders)]
    orders: usize,
    #[arg(long, default_value_t = 160.0)]
    young_kpa: f64,
    #[arg(long, default_value_t = 0.48)]
    poisson: f64,
    #[arg(long)]
    out: PathBuf,
    /// Also print each sample (position, stiffness, ratio at the deepest point, Padé
    /// change), one JSON line each.
    #[arg(long)]
    samples_json: bool,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A depth-law file (from `palpa lab depth-law build`).
    law: PathBuf,
    /// The scene whose linear compliance the law corrects: `liver` (built in) or a
    /// palpation `.palpa` file of the same organ.
    #[arg(long, default_value = "liver")]
    scene: String,
    /// Probe point X,Y,Z (mm); projected to the closest palpable surface point.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    at: Vec<f64>,
    /// Indentation (mm): force out.
    #[arg(long, conflicts_with = "force_n")]
    depth_mm: Option<f64>,
    /// Force (N): indentation out.
    #[arg(long)]
    force_n: Option<f64>,
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: &DepthLawCommand) -> anyhow::Result<()> {
    match cmd {
        DepthLawCommand::Build(args) => build(args),
        DepthLawCommand::Eval(args) => eval(args),
    }
}

fn build(args: &BuildArgs) -> anyhow::Result<()> {
    crate::cli::args::check_out(&args.out)?;
    let organ = args.organ.mesh()?;
    let options = DepthLawOptions {
        law: args.model.law(),
        material: Material {
            young_kpa: args.young_kpa,
            poisson: args.poisson,
        },
        element: args.element,
        samples: args.samples,
        depth_max_mm: args.depth_max_mm,
        orders: args.orders,
        ..DepthLawOptions::default()
    };
    // A sample is a palpable vertex; asking for more presses each once.
    let vertices = organ.pressable_vertices().len();
    if args.samples > vertices && vertices > 0 {
        eprintln!(
            "warning: --samples {}: the palpable surface has {vertices} vertices; pressing each of them",
            args.samples
        );
    }
    // Finished samples are logged beside the output: an interrupted build run again
    // with the same arguments goes on from the last one.
    let mut log = args.out.as_os_str().to_owned();
    log.push(".samples.log");
    let (law, resumed) =
        DepthLaw::build_logged(&organ, options, Some(Path::new(&log)), &mut |k, n| {
            eprint!("\rsample {k}/{n}   ");
        })
        .context("building the depth law")?;
    eprintln!();
    law.save(&args.out)?;
    let _ = std::fs::remove_file(&log);
    if args.samples_json {
        let steps = law.ratio.len() / law.samples.len();
        for (k, p) in law.samples.iter().enumerate() {
            println!(
                "{}",
                json!({"sample": k, "at": p, "stiffness_n_per_mm": law.stiffness_n_per_mm[k],
                    "ratio_at_max": law.ratio[(k + 1) * steps - 1], "pade_change": law.pade_change[k]})
            );
        }
    }
    println!(
        "{}",
        json!({"out": args.out, "law": options.law.name(), "samples": law.samples.len(),
            "samples_asked": args.samples, "orders": options.orders, "depth_max_mm": options.depth_max_mm,
            "sigma_mm": law.sigma_mm, "build_s": law.build_s, "resumed_samples": resumed,
            "worst_pade_change": law.pade_change.iter().copied().filter(|c| c.is_finite()).fold(0.0, f64::max),
            "bytes": std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0)})
    );
    Ok(())
}

fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    let law = DepthLaw::load(&args.law)?;
    let [x, y, z] = args.at[..] else {
        bail!(
            "--at: expected X,Y,Z (three numbers), got {} values",
            args.at.len()
        );
    };
    if ![x, y, z]
        .iter()
        .all(|&v| crate::cli::args::coordinate_ok(v))
    {
        bail!(
            "--at {x},{y},{z}: expected finite coordinates of magnitude at most {:e}",
            crate::cli::args::COORDINATE_MAX
        );
    }
    let loaded = palpa_app::scenes::load(&args.scene)?;
    let scene = loaded.scene;
    law.check_scene(scene.vertices_mm(), &scene.model().provenance().mesh)
        .with_context(|| format!("{} with the scene {}", args.law.display(), args.scene))?;
    let (point, distance) = scene
        .closest_palpable([x, y, z])
        .context("the scene has no palpable surface")?;
    let mut scratch = scene.contact_scratch();
    let contact = scene
        .contact(&point, scene.modes(), &mut scratch)
        .context("the contact law at the probe point")?;
    let c = contact.compliance_mm_per_n;
    let at = contact.point_mm;
    crate::cli::args::warn_far_from_surface(distance, at);
    let t = Instant::now();
    let (depth, force, clamped) = match (args.depth_mm, args.force_n) {
        (Some(d), None) if d.is_finite() && d >= 0.0 => {
            let (f, clamped) = law.force_n(at, d, c);
            (d.min(law.options.depth_max_mm), f, clamped)
        }
        (None, Some(f)) if f.is_finite() && f >= 0.0 => {
            let (d, clamped) = law.depth_mm(at, f, c);
            let (f_back, _) = law.force_n(at, d, c);
            (d, if clamped { f_back } else { f }, clamped)
        }
        _ => bail!("give one of --depth-mm D or --force-n F, finite and ≥ 0"),
    };
    let eval_us = t.elapsed().as_secs_f64() * 1e6;
    let out = json!({
        "law": law.options.law.name(),
        "probe_point": at,
        "probe_projection_distance_mm": distance,
        "probe_displacement_mm": depth,
        "force_n": force,
        "linear_force_n": depth / c,
        "ratio": law.ratio(at, depth).0,
        "clamped": clamped,
        "depth_max_mm": law.options.depth_max_mm,
        "compliance_mm_per_n": c,
        "eval_us": eval_us,
    });
    crate::cli::args::print_report(&out, args.json)
}
