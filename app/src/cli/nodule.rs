//! `palpa nodule build`: the nodule table of a scene's organ (`pgd::nodule::table`),
//! written beside the scene as `S.nodules`, which `palpa eval S.palpa --nodule-at …`
//! reads.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use palpa_core::fe::{Element, Material};
use palpa_core::pgd::nodal;
use palpa_core::pgd::nodule::table::{EffectTable, TableSettings};
use serde_json::json;

use super::args::OrganArgs;

#[derive(Debug, Subcommand)]
pub enum NoduleCommand {
    /// Tabulate the nodule's effect on the probe's force over a cube of centres (a
    /// lattice), a range of radii and ratios 1–10, at every palpable point within
    /// reach: a scene then answers any nodule in the cube without a solve.
    Build(BuildArgs),
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    #[command(flatten)]
    organ: OrganArgs,
    /// The cube's middle X,Y,Z (mm), inside the organ.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    around: Vec<f64>,
    /// Half the cube's width (mm): centres within it along each axis.
    #[arg(long, default_value_t = 6.0)]
    half_width_mm: f64,
    /// Lattice spacing (mm): 3 mm kept the effect within 10 % (docs/lab/nodule-measurements.md §6).
    #[arg(long, default_value_t = 3.0)]
    spacing_mm: f64,
    /// The radii tabulated (mm), ascending: radii between the first and the last are
    /// answered. Coarse resolves radii from 8 mm.
    #[arg(long, value_delimiter = ',', default_values_t = [8.0, 10.0, 12.0])]
    radii_mm: Vec<f64>,
    /// Probe points farther than this from a centre feel none of its nodule (mm).
    #[arg(long, default_value_t = 30.0)]
    probe_reach_mm: f64,
    /// Probe tool radius (mm), as the scene's.
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    #[arg(long)]
    out: PathBuf,
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: &NoduleCommand) -> anyhow::Result<()> {
    match cmd {
        NoduleCommand::Build(args) => build(args),
    }
}

fn build(args: &BuildArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    let around = super::args::to3(&args.around, "--around")?;
    let organ = args.organ.mesh()?;
    if !palpa_core::fe::nodule::inside(&organ, around) {
        bail!("--around {around:?}: expected a point inside the organ (the cube's middle)");
    }
    for (flag, v) in [
        ("--half-width-mm", args.half_width_mm),
        ("--spacing-mm", args.spacing_mm),
        ("--probe-reach-mm", args.probe_reach_mm),
        ("--radius-mm", args.radius_mm),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{flag} {v}: expected a positive length");
        }
    }
    if args.half_width_mm < args.spacing_mm {
        bail!(
            "--half-width-mm {} under --spacing-mm {}: expected a cube of at least three nodes a side",
            args.half_width_mm,
            args.spacing_mm
        );
    }
    let min = palpa_core::fe::nodule::min_radius_mm(organ.h_mm);
    if args.radii_mm.first().is_some_and(|&r| r < min) {
        bail!(
            "--radii-mm {:?}: the mesh (spacing {:.1} mm) resolves radii from {min:.1} mm",
            args.radii_mm,
            organ.h_mm
        );
    }
    let setup = nodal::setup(&organ, Element::P2, Material::default(), args.radius_mm)
        .context("building the FE operators")?;
    let settings = TableSettings {
        centre_mm: around,
        half_width_mm: args.half_width_mm,
        spacing_mm: args.spacing_mm,
        radii_mm: args.radii_mm.clone(),
        probe_reach_mm: args.probe_reach_mm,
        block: 4,
    };
    let table = EffectTable::build(&setup, &organ, &settings)?;
    table.save(&args.out)?;
    let summary = json!({
        "out": args.out,
        "lattice": table.dims, "centres": table.valid.iter().filter(|&&v| v).count(),
        "spacing_mm": table.spacing_mm, "radii_mm": table.radii_mm,
        "probe_nodes": table.probe_nodes.len(), "placements": table.placements,
        "bytes": std::fs::metadata(&args.out).map(|m| m.len()).ok(),
        "stores_s": table.stores_s, "placements_s": table.placements_s, "build_s": table.build_s,
        "mesh_xxh3": format!("{:016x}", table.mesh_xxh3),
    });
    super::args::print_report(&summary, args.json)
}
