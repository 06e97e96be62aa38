//! `palpa nodule build`: the nodule table of a scene's organ (`pgd::nodule::table`),
//! written beside the scene as `S.nodules`, which `palpa eval S.palpa --nodule-at …`
//! reads; `nodule tissue` adds a tissue's power (`pgd::nodule::amplification`), `check`
//! measures it all.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use palpa_core::fe::{Element, Material};
use palpa_core::pgd::nodal;
use palpa_core::pgd::nodule::amplification::{Keep, PRESS_DEPTH_MM};
use palpa_core::pgd::nodule::heldout::{self, CheckSummary};
use palpa_core::pgd::nodule::table::{EffectTable, FIT_RATIOS, TableSettings, apply_surface_gain};
use palpa_core::tissue::law::{PointIndex, max_node_errors};
use serde_json::json;

use super::args::OrganArgs;

#[derive(Debug, Subcommand)]
pub enum NoduleCommand {
    /// Tabulate the nodule's effect on the probe's force over a cube of centres (a
    /// lattice) or the whole band under the palpable surface, a range of radii and
    /// ratios 1–100, at every palpable point within reach: a scene then answers any
    /// nodule there without a solve.
    Build(BuildArgs),
    /// Join the shards of one build (`palpa nodule build --shard I/N`) into the table
    /// the build unsharded writes (the same payload: `palpa info --json`'s
    /// `payload_xxh3`).
    Merge(MergeArgs),
    /// Measure a table against the full FE at held-out (probe point, nodule) pairs
    /// drawn off its grids; `--record` writes the measurement into the table, where
    /// `palpa info` and the app read it.
    Check(CheckArgs),
    /// Press every palpable vertex of a tissue without a nodule and keep, in the
    /// table, how each press shares its power among the cells near the vertex at each
    /// depth: the tissue then answers a nodule with the table's effect amplified as its
    /// own press loads the nodule (docs/methods.md §2i). Clears the table's tissue
    /// checks (measure them again with `check --tissue --record`).
    Tissue(TissueArgs),
}

#[derive(Debug, Args)]
pub struct TissueArgs {
    /// The table (`palpa nodule build`), written in place.
    file: PathBuf,
    /// The tissue (`palpa tissue build`) of the table's organ.
    #[arg(long)]
    tissue: PathBuf,
    #[command(flatten)]
    organ: OrganArgs,
    /// A vertex keeps the cells with a corner within this distance (mm): the table's
    /// probe reach plus its largest radius covers every nodule it answers near;
    #[arg(long, default_value_t = Keep::default().reach_mm)]
    reach_mm: f64,
    /// and at least this share of its linear press's power.
    #[arg(long, default_value_t = Keep::default().share_floor)]
    share_floor: f64,
    /// How deep each vertex is pressed (mm; at most the tissue's grid): past it the
    /// amplification reached there is held. The build's time grows with it (15 mm took
    /// 1.5 times 10 mm's).
    #[arg(long, default_value_t = PRESS_DEPTH_MM)]
    depth_max_mm: f64,
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The table (`palpa nodule build`).
    file: PathBuf,
    #[command(flatten)]
    organ: OrganArgs,
    /// Pairs whose effect exceeds 5 % of the force to draw (others are drawn on the
    /// way, at most 4 × this + 8 in all); two full FE solves a pair.
    #[arg(long, default_value_t = 12)]
    felt: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// The nodules' ratios, LO,HI (drawn log-uniformly; above 1, at most 100).
    #[arg(long, value_delimiter = ',', default_values_t = [1.5, 10.0])]
    ratios: Vec<f64>,
    /// The nodules' radii (mm), LO,HI, drawn uniformly [default: the radii tabulated;
    /// the table answers to 1.25 times the largest].
    #[arg(long, value_delimiter = ',')]
    radii_mm: Option<Vec<f64>>,
    /// Draw only nodules past the table's band (deeper, or beside a surface no probe
    /// presses), which the table answers by its far field.
    #[arg(long)]
    past_band: bool,
    /// Write the check into the table (replacing one of the same seed).
    #[arg(long)]
    record: bool,
    /// Measure the scene's nonlinear tissue with the table's effect instead (as the
    /// app's force loop answers: the tissue's force times `1 + effect`): Newton with
    /// and without each nodule at `--depths`, along the scene's push; `--felt` counts
    /// pairs whose effect exceeds 5 % at some depth.
    #[arg(long)]
    tissue: Option<PathBuf>,
    /// The scene whose drawn surface is measured (with --tissue: the scene the tissue
    /// serves), `liver` (built in) or a `.palpa` file of the table's mesh [default:
    /// `liver`; without --tissue, where its mesh is not the table's, the surface is not
    /// measured, and said so].
    #[arg(long)]
    scene: Option<String>,
    /// With --tissue: each pair's press depths (mm), off the tissue's depth grid.
    #[arg(long, value_delimiter = ',', default_values_t = [2.6, 6.1, 9.7], requires = "tissue")]
    depths: Vec<f64>,
    /// With --tissue: the probe right above each nodule (at the palpable point nearest
    /// its centre) instead of within 20 mm of it, where a trainee presses once the
    /// nodule is found; the same nodules as the seed's without it.
    #[arg(long, requires = "tissue")]
    above: bool,
    #[arg(long)]
    json: bool,
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
        required_unless_present = "band_depth_mm",
        conflicts_with = "band_depth_mm"
    )]
    around: Vec<f64>,
    /// Instead of a cube: every centre in the organ within this depth under the
    /// palpable surface (mm), on a lattice over the whole palpable surface. Deeper
    /// nodules (radius to 12 mm, ratio to 10) change the force by less than 5 %
    /// (docs/lab/nodule-measurements.md §11); the table answers them by its far field
    /// from the band's deepest centres (§14).
    #[arg(long)]
    band_depth_mm: Option<f64>,
    /// Build only shard I of N (I from 1), the lattice's blocks dealt in turn, into
    /// `OUT.shard-I-of-N`; `palpa nodule merge` joins the N shards into OUT.
    #[arg(long, value_parser = super::args::parse_shard)]
    shard: Option<palpa_core::tissue::presser::Shard>,
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
    /// Probe points within this distance of a centre get entries of their own (mm);
    /// farther ones read the far field fitted to the outermost entries.
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
        NoduleCommand::Check(args) => check(args),
        NoduleCommand::Merge(args) => merge(args),
        NoduleCommand::Tissue(args) => tissue_power(args),
    }
}

fn check(args: &CheckArgs) -> anyhow::Result<()> {
    if args.felt == 0 {
        bail!("--felt 0: expected at least one pair to measure");
    }
    if let Some(tissue) = &args.tissue {
        return check_tissue(args, tissue);
    }
    let mut table = EffectTable::load(&args.file)?;
    // The scene that draws the surface: the one given, of the table's mesh; else the
    // built-in liver where the table is of its mesh.
    let name = args.scene.as_deref().unwrap_or("liver");
    let scene = palpa_app::scenes::load(name)?.scene;
    let of_mesh = table
        .check_mesh(&scene.model().provenance().mesh)
        .with_context(|| format!("{} for the scene {name}", args.file.display()));
    let scene = match (of_mesh, &args.scene) {
        (Ok(()), _) => Some(scene),
        (Err(e), Some(_)) => return Err(e),
        (Err(_), None) => {
            eprintln!(
                "note: the built-in scene is not of {}'s mesh: the surface is not measured \
                 (give --scene S.palpa built on it)",
                args.file.display()
            );
            None
        }
    };
    let organ = args.organ.mesh()?;
    let [lo, hi] = args.ratios[..] else {
        bail!("--ratios {:?}: expected LO,HI", args.ratios);
    };
    let radii = match args.radii_mm.as_deref() {
        None => [table.radii_mm[0], table.radii_mm[table.radii_mm.len() - 1]],
        Some(&[a, b]) => [a, b],
        Some(other) => bail!("--radii-mm {other:?}: expected LO,HI"),
    };
    // The surface the scene draws at 1 N with the nodule: its nodule-free one at the
    // depth the force reaches, times the gain away from the probe; against the FE's.
    let mut surface = scene.as_ref().map(|scene| {
        let index = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
        let (mut scratch, mut coeffs) = (scene.contact_scratch(), vec![0.0; scene.modes()]);
        let mut rows = vec![0.0; 3 * scene.vertices_mm().len()];
        let organ = &organ;
        move |at: [f64; 3], effect: f64, fe_u: &[f64]| {
            let (point, _) = scene.closest_palpable(at)?;
            let contact = scene.contact(&point, scene.modes(), &mut scratch).ok()?;
            let force = contact.push_dir.map(|d| d / (1.0 + effect));
            scene
                .displacement(&point, force, &mut coeffs, &mut rows)
                .ok()?;
            let vertices = scene.vertices_mm().iter().map(|p| p.map(f64::from));
            apply_surface_gain(effect, scene.frame(&point).0, vertices, &mut rows);
            Some(max_node_errors(organ, &index, fe_u, [&rows]).0[0])
        }
    });
    let measured = heldout::check(
        &table,
        &organ,
        surface
            .as_mut()
            .map(|f| f as &mut heldout::SurfaceCheck<'_>),
        args.felt,
        args.seed,
        radii,
        [lo, hi],
        args.past_band,
    )
    .with_context(|| format!("checking {}", args.file.display()))?;
    let pairs: Vec<_> = measured
        .pairs
        .iter()
        .map(|p| {
            json!({"nodule_mm_ratio": p.nodule, "at_mm": p.at_mm, "effect_fe": p.effect_fe,
                   "effect_table": p.effect_table, "surface_mm": p.surface_mm})
        })
        .collect();
    let this = CheckSummary::of(&measured.pairs);
    let fe_s = measured.fe_s;
    // The same nodules chosen from the table, timed in this run against the FE's two
    // solves a pair: what one solve per configuration costs against the table.
    let mut place_s: Vec<f64> = measured
        .pairs
        .iter()
        .filter_map(|p| table.place(&p.nodule()).ok().map(|e| e.place_s))
        .collect();
    place_s.sort_by(f64::total_cmp);
    let place_ms = place_s.get(place_s.len() / 2).map(|s| s * 1e3);
    let solve_s = fe_s / (2 * measured.pairs.len().max(1)) as f64;
    let cost = json!({
        "fe_solve_s": solve_s, "table_place_ms_p50": place_ms,
        "solve_over_place": place_ms.map(|ms| solve_s * 1e3 / ms),
        "build_s": table.build_s, "build_in_fe_solves": table.build_s / solve_s,
    });
    if args.record {
        table.checks.retain(|c| c.seed != args.seed);
        table.checks.push(measured);
        table.save(&args.file)?;
    }
    let summary = json!({
        "file": args.file, "seed": args.seed, "pairs": pairs, "fe_s": fe_s,
        "summary": this, "recorded": args.record, "cost": cost,
        "all_recorded": heldout::recorded(&table),
    });
    super::args::print_report(&summary, args.json)
}

/// `palpa tradeoff S.nodules`: the table's knobs (the lattice's spacing, the radii
/// tabulated) against its error at the held-out pairs its checks recorded, each knob's
/// table cut from this one as a build with it would have written it.
pub fn tradeoff(path: &std::path::Path, organ: &OrganArgs, json_out: bool) -> anyhow::Result<()> {
    let table = EffectTable::load(path)?;
    // The knobs are the band's lattice and its tabulated radii: measured at the pairs
    // there (not those answered past the largest radius or by the far field past the
    // band).
    let largest = table.radii_mm[table.radii_mm.len() - 1];
    let pairs: Vec<&heldout::CheckedPair> = table
        .checks
        .iter()
        .flat_map(|c| &c.pairs)
        .filter(|p| p.nodule[3] <= largest && table.place_in_band(&p.nodule()).is_ok())
        .collect();
    if pairs.is_empty() {
        bail!(
            "{}: no held-out check recorded; measure one first with `palpa nodule check {} --record`",
            path.display(),
            path.display()
        );
    }
    let organ = organ.mesh()?;
    if organ.fingerprint() != table.mesh_xxh3 {
        bail!(
            "{}: built on mesh {:016x}, the organ given is mesh {:016x}: give the table's organ and level",
            path.display(),
            table.mesh_xxh3,
            organ.fingerprint()
        );
    }
    let within = pairs
        .iter()
        .filter(|p| p.nodule[4] <= FIT_RATIOS[1])
        .count();
    let space = palpa_core::fe::probe::organ_space(&organ, Element::P2);
    let points: Vec<_> = pairs
        .iter()
        .map(|p| palpa_core::fe::load::project(&space, &organ.palpable, p.at_mm))
        .collect();
    let r = table.radii_mm.len();
    let all: Vec<usize> = (0..r).collect();
    let ends = vec![0, r - 1];
    let mut rows = Vec::new();
    for step in 1..=4 {
        for radii in [&all, &ends] {
            if radii.len() == r && radii == &ends && step > 1 {
                continue;
            }
            let Some(t) = table.coarsened(step, radii) else {
                continue;
            };
            let mut measured = Vec::new();
            let mut beyond = Vec::new();
            let mut place_s = Vec::new();
            for (p, point) in pairs.iter().zip(&points) {
                let Some(point) = point else { continue };
                let Ok(effect) = t.place(&p.nodule()) else {
                    continue;
                };
                place_s.push(effect.place_s);
                if let Some(e) = effect.at(&t, point.face, point.bary) {
                    // The surface was measured for the whole table, not this one.
                    let pair = heldout::CheckedPair {
                        effect_table: e,
                        surface_mm: f64::NAN,
                        ..(*p).clone()
                    };
                    if p.nodule[4] <= FIT_RATIOS[1] {
                        measured.push(pair);
                    } else {
                        beyond.push(pair);
                    }
                }
            }
            place_s.sort_by(f64::total_cmp);
            rows.push(json!({
                "spacing_mm": t.spacing_mm, "radii_mm": t.radii_mm,
                "centres": t.valid.iter().filter(|&&v| v).count(),
                "table_bytes": t.bytes(),
                "answered": measured.len(), "pairs": within,
                "place_ms_p50": place_s.get(place_s.len() / 2).map(|s| s * 1e3),
                "heldout": CheckSummary::of(&measured),
                "heldout_beyond_ratio_10": CheckSummary::of(&beyond),
            }));
            if radii.len() == r && r == 2 {
                break;
            }
        }
    }
    // The baseline a table must beat: the nodule ignored (no effect anywhere).
    let ignored: Vec<_> = pairs
        .iter()
        .filter(|p| p.nodule[4] <= FIT_RATIOS[1])
        .map(|p| heldout::CheckedPair {
            effect_table: 0.0,
            surface_mm: f64::NAN,
            ..(*p).clone()
        })
        .collect();
    let ignored = CheckSummary::of(&ignored);
    if json_out {
        return super::args::print_report(
            &json!({"file": path, "rows": rows, "nodule_ignored": ignored}),
            true,
        );
    }
    println!(
        "{}: the effect at {within} held-out pairs at ratios to 10 (recorded by `palpa nodule check`) against each knob;",
        path.display(),
    );
    println!(
        "build time and bytes grow with the centres. Errors: where the FE's effect exceeds 5 %."
    );
    println!(
        "{:<9} {:<14} {:>7} {:>7} {:>9} {:>7} {:>7} {:>7} {:>11}",
        "spacing", "radii (mm)", "centres", "MB", "answered", "median", "p90", "max", "within 10 %"
    );
    let pct = |h: &serde_json::Value, k: &str| {
        h[k].as_f64()
            .map_or("-".to_string(), |v| format!("{:.1} %", 100.0 * v))
    };
    for row in &rows {
        let h = &row["heldout"];
        let radii: Vec<String> = row["radii_mm"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|r| format!("{}", r.as_f64().unwrap_or(f64::NAN)))
            .collect();
        println!(
            "{:<9} {:<14} {:>7} {:>7.2} {:>9} {:>7} {:>7} {:>7} {:>11}",
            format!("{} mm", row["spacing_mm"].as_f64().unwrap_or(f64::NAN)),
            radii.join(","),
            row["centres"].as_u64().unwrap_or(0),
            row["table_bytes"].as_f64().unwrap_or(f64::NAN) / 1e6,
            format!("{}/{}", row["answered"], row["pairs"]),
            pct(h, "error_median"),
            pct(h, "error_p90"),
            pct(h, "error_max"),
            pct(h, "within_10_percent")
        );
    }
    let ignored = json!(ignored);
    println!(
        "{:<9} {:<14} {:>7} {:>7} {:>9} {:>7} {:>7} {:>7} {:>11}",
        "ignored",
        "(no nodule)",
        "0",
        "0",
        "-",
        pct(&ignored, "error_median"),
        pct(&ignored, "error_p90"),
        pct(&ignored, "error_max"),
        pct(&ignored, "within_10_percent")
    );
    if let Some(b) = rows.first().map(|r| &r["heldout_beyond_ratio_10"])
        && !b.is_null()
    {
        println!(
            "ratios 10-100 ({} pairs), the table as built: median {}, p90 {}, max {}, {} within 10 % (`--json`: every knob)",
            pairs.len() - within,
            pct(b, "error_median"),
            pct(b, "error_p90"),
            pct(b, "error_max"),
            pct(b, "within_10_percent")
        );
    }
    Ok(())
}

/// What `palpa info` says of a nodule table.
pub fn summary(table: &EffectTable, path: &std::path::Path) -> serde_json::Value {
    let recorded = heldout::recorded(table);
    json!({
        "file": path, "kind": "nodule-table", "format_version": palpa_core::pgd::nodule::table::VERSION,
        "shard": table.shard,
        "lattice": table.dims, "centres": table.valid.iter().filter(|&&v| v).count(),
        "box_mm": table.box_mm(), "spacing_mm": table.spacing_mm, "radii_mm": table.radii_mm,
        "radii_answered_mm": table.radius_range_mm(),
        "ratios": [1.0, palpa_core::pgd::nodule::table::MAX_RATIO],
        "probe_nodes": table.probe_nodes.len(),
        "mesh_xxh3": format!("{:016x}", table.mesh_xxh3),
        "file_bytes": std::fs::metadata(path).map(|m| m.len()).ok(),
        "payload_xxh3": format!("{:016x}", table.payload_xxh3()),
        "build_s": table.build_s,
        "checks": table.checks.iter().map(|c| json!({"seed": c.seed, "pairs": c.pairs.len(),
            "summary": CheckSummary::of(&c.pairs)})).collect::<Vec<_>>(),
        // In the band at tabulated radii: ratios to 10 (where the one-pole form is
        // fitted), then beyond (to 100); radii past the tabulated; past the band.
        "accuracy": recorded[0],
        "accuracy_beyond_ratio_10": recorded[1],
        "accuracy_past_largest_radius": recorded[2],
        "accuracy_past_band": recorded[3],
        "tissue_checks": table.tissue_checks.iter().map(|c| json!({"seed": c.seed,
            "tissue": c.tissue, "law": c.law, "tissue_xxh3": format!("{:016x}", c.tissue_xxh3),
            "amplified": c.amplified,
            "presses": c.pairs.len()})).collect::<Vec<_>>(),
        "tissue_power": table.tissue_power.as_ref().map(|p| json!({
            "tissue_xxh3": format!("{:016x}", p.tissue_xxh3), "vertices": p.vertices.len(),
            "cells": p.cells.len(), "reach_mm": p.reach_mm, "share_floor": p.share_floor,
            "depths_mm": p.depths_mm,
            "bytes": p.bytes(), "build_s": p.build_s})),
        "accuracy_tissue": heldout::recorded_tissue(table),
    })
}

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Every shard of the build (`OUT.shard-I-of-N`), in any order.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    #[arg(long)]
    out: PathBuf,
    #[arg(long)]
    json: bool,
}

fn merge(args: &MergeArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    let parts = args
        .shards
        .iter()
        .map(|p| EffectTable::load_shard(p).with_context(|| format!("reading {}", p.display())))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let table = EffectTable::merge(parts)?;
    table.save(&args.out)?;
    super::args::print_report(&build_summary(&table, &args.out), args.json)
}

/// Where shard `shard` of a build into `out` goes: `OUT.shard-I-of-N`.
pub fn shard_path(out: &std::path::Path, shard: palpa_core::tissue::presser::Shard) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(format!(".shard-{}-of-{}", shard.index, shard.count));
    PathBuf::from(p)
}

fn build(args: &BuildArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    let organ = args.organ.mesh()?;
    // The lattice's middle and half widths: the cube asked for, or the palpable
    // surface's box grown by the band's depth.
    let (around, half_width_mm) = match args.band_depth_mm {
        Some(d) => {
            if !(d.is_finite() && d > 0.0) {
                bail!("--band-depth-mm {d}: expected a positive depth");
            }
            let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
            for t in organ.palpable_triangles() {
                for v in t {
                    let x = organ.mesh.vertices[v as usize];
                    for k in 0..3 {
                        lo[k] = lo[k].min(x[k] - d);
                        hi[k] = hi[k].max(x[k] + d);
                    }
                }
            }
            if lo[0] > hi[0] {
                bail!("--band-depth-mm: the organ has no palpable surface");
            }
            (
                [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k])),
                [0, 1, 2].map(|k| 0.5 * (hi[k] - lo[k])),
            )
        }
        None => {
            let around = super::args::to3(&args.around, "--around")?;
            if !palpa_core::fe::nodule::inside(&organ, around) {
                bail!("--around {around:?}: expected a point inside the organ (the cube's middle)");
            }
            (around, [args.half_width_mm; 3])
        }
    };
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
    if args.band_depth_mm.is_none() && args.half_width_mm < args.spacing_mm {
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
        half_width_mm,
        max_depth_mm: args.band_depth_mm,
        spacing_mm: args.spacing_mm,
        radii_mm: args.radii_mm.clone(),
        probe_reach_mm: args.probe_reach_mm,
        block: 4,
        shard: args.shard.map(|s| [s.index as usize, s.count as usize]),
    };
    let table = EffectTable::build(&setup, &organ, &settings)?;
    let out = match args.shard {
        Some(shard) => shard_path(&args.out, shard),
        None => args.out.clone(),
    };
    table.save(&out)?;
    super::args::print_report(&build_summary(&table, &out), args.json)
}

fn build_summary(table: &EffectTable, out: &std::path::Path) -> serde_json::Value {
    json!({
        "out": out, "shard": table.shard,
        "lattice": table.dims, "centres": table.valid.iter().filter(|&&v| v).count(),
        "spacing_mm": table.spacing_mm, "radii_mm": table.radii_mm,
        "probe_nodes": table.probe_nodes.len(), "placements": table.placements,
        "bytes": std::fs::metadata(out).map(|m| m.len()).ok(),
        "stores_s": table.stores_s, "placements_s": table.placements_s, "build_s": table.build_s,
        "mesh_xxh3": format!("{:016x}", table.mesh_xxh3),
        "payload_xxh3": format!("{:016x}", table.payload_xxh3()),
    })
}

/// `palpa nodule tissue`: every palpable vertex of the tissue pressed without a nodule
/// along the tissue build's push, through its depth grid; each keeps its cells' shares
/// of the press's power (`pgd::nodule::amplification`).
fn tissue_power(args: &TissueArgs) -> anyhow::Result<()> {
    use palpa_core::fe::probe::{organ_space, organ_vertex_normals};
    use palpa_core::fe::series::Expander;
    use palpa_core::pgd::nodule::amplification::{CURVE_DEPTHS, STEPS_PER_DEPTH, VertexPower};
    use palpa_core::tissue::law::TissueLaw;
    use palpa_core::tissue::press::Pressing;
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Instant;

    if !(args.reach_mm.is_finite() && args.reach_mm > 0.0) {
        bail!("--reach-mm {}: expected a positive distance", args.reach_mm);
    }
    if !(args.share_floor >= 0.0 && args.share_floor < 1.0) {
        bail!(
            "--share-floor {}: expected a share from 0 to below 1",
            args.share_floor
        );
    }
    let keep = Keep {
        reach_mm: args.reach_mm,
        share_floor: args.share_floor,
    };
    let mut table = EffectTable::load(&args.file)?;
    let law = TissueLaw::load(&args.tissue)?;
    let organ = args.organ.mesh()?;
    law.check_organ(&organ)?;
    if organ.fingerprint() != table.mesh_xxh3 {
        bail!(
            "{}: built on mesh {:016x}, the organ given is mesh {:016x}: give the table's organ and level",
            args.file.display(),
            table.mesh_xxh3,
            organ.fingerprint()
        );
    }
    let mut o = law.options;
    if !(args.depth_max_mm > 0.0 && args.depth_max_mm <= o.depth_max_mm) {
        bail!(
            "--depth-max-mm {}: expected a depth above 0 and at most the tissue's {} mm",
            args.depth_max_mm,
            o.depth_max_mm
        );
    }
    o.depth_max_mm = args.depth_max_mm;
    let steps = (o.depth_max_mm / o.depth_step_mm).round() as usize;
    if !(1..=CURVE_DEPTHS).contains(&(steps / STEPS_PER_DEPTH)) {
        bail!(
            "{}: {steps} depth steps: expected {STEPS_PER_DEPTH} to {}",
            args.tissue.display(),
            STEPS_PER_DEPTH * (CURVE_DEPTHS + 1) - 1
        );
    }
    let t0 = Instant::now();
    let space = organ_space(&organ, o.element);
    let expander = Expander::new(&space, o.law, o.material)?;
    let pressing = Pressing {
        space: &space,
        organ: &organ,
        expander: &expander,
        o: &o,
    };
    let normals = organ_vertex_normals(&organ);
    let mut vertices = organ.pressable_vertices();
    vertices.sort_unstable();
    vertices.dedup();
    let done = AtomicUsize::new(0);
    let pressed: Vec<anyhow::Result<Option<VertexPower>>> = vertices
        .par_iter()
        .with_max_len(1)
        .map(|&v| {
            let at = organ.mesh.vertices[v as usize];
            let push = normals[v as usize].map(|c| -f64::from(c));
            // A vertex the tool cannot press (beside the fixed region) keeps nothing.
            let press = pressing.vertex_power(at, push, keep);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            if !args.json && n.is_multiple_of(25) {
                eprintln!(
                    "{n} of {} vertices pressed, {:.0} s",
                    vertices.len(),
                    t0.elapsed().as_secs_f64()
                );
            }
            Ok(press.ok())
        })
        .collect();
    let mut kept = Vec::new();
    let mut skipped = 0usize;
    for p in pressed {
        match p? {
            Some(v) => kept.push(v),
            None => skipped += 1,
        }
    }
    let power = pressing.cell_power(law.payload_xxh3(), keep, kept, t0.elapsed().as_secs_f64());
    let report = json!({
        "file": args.file, "tissue": args.tissue, "vertices": power.vertices.len(),
        "skipped": skipped, "cells": power.cells.len(), "bytes": power.bytes(),
        "build_s": power.build_s,
    });
    table.tissue_power = Some(power);
    table.tissue_checks.clear();
    table.save(&args.file)?;
    super::args::print_report(&report, args.json)
}

/// `palpa nodule check --tissue X.tissue`: the scene's nonlinear tissue with the table's
/// effect (the tissue's force at the depth times `1 + e`, the surface the tissue's
/// without the nodule) against Newton with the nodule, at held-out pairs drawn as the
/// linear check draws them, each pressed along the scene's push to `--depths`.
fn check_tissue(args: &CheckArgs, tissue: &std::path::Path) -> anyhow::Result<()> {
    use palpa_core::fe::newton::NewtonSettings;
    use palpa_core::fe::nodule::Nodule;
    use palpa_core::fe::probe::{ProbeRequest, solve_hyperelastic_depths};
    use palpa_core::pgd::nodule::heldout::{PROBE_SPREAD_MM, TissueSummary};
    use palpa_core::pgd::nodule::table::{
        MAX_RATIO, TissueCheck, TissuePair, apply_surface_gain, nodule_row,
    };
    use palpa_core::pgd::nodule::training::{CaseRanges, draw};
    use palpa_core::rng::Rng;
    use palpa_core::tissue::law::PointIndex;
    use std::time::Instant;

    let [lo, hi] = args.ratios[..] else {
        bail!("--ratios {:?}: expected LO,HI", args.ratios);
    };
    if !(lo > 1.0 && lo <= hi && hi <= MAX_RATIO) {
        bail!("--ratios {lo},{hi}: expected 1 < LO <= HI <= {MAX_RATIO}");
    }
    if let Some(d) = args.depths.iter().find(|d| !(d.is_finite() && **d > 0.0)) {
        bail!("--depths: {d:?} mm: expected finite depths above 0 mm (presses into the tissue)");
    }
    if !args.depths.windows(2).all(|w| w[0] < w[1]) {
        bail!(
            "--depths {:?}: expected ascending, distinct depths",
            args.depths
        );
    }
    let mut table = EffectTable::load(&args.file)?;
    let name = args.scene.as_deref().unwrap_or("liver");
    let (bound, scene, _) = super::tissue::eval::bound_to_scene_with_nodules(tissue, name)?;
    table
        .check_mesh(&scene.model().provenance().mesh)
        .with_context(|| format!("{} for the scene {name}", args.file.display()))?;
    let organ = args.organ.mesh()?;
    bound.law.check_organ(&organ)?;
    let o = bound.law.options;
    if let Some(d) = args.depths.iter().find(|d| **d > o.depth_max_mm) {
        bail!(
            "--depths: {d} mm: expected depths within the tissue's deepest, {} mm",
            o.depth_max_mm
        );
    }
    let tissue_xxh3 = bound.law.payload_xxh3();
    let amplified = table
        .tissue_power
        .as_ref()
        .is_some_and(|p| p.tissue_xxh3 == tissue_xxh3);
    if !amplified {
        eprintln!(
            "note: {} holds no power of {}: the linear effect is measured as it is \
             (palpa nodule tissue {} --tissue {})",
            args.file.display(),
            tissue.display(),
            args.file.display(),
            tissue.display()
        );
    }
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let mut contact_scratch = scene.contact_scratch();
    let mut scratch = bound.scratch();
    let mut coeffs = vec![0.0; scene.modes()];
    let mut rows = vec![0.0; 3 * scene.vertices_mm().len()];
    let ranges = CaseRanges {
        radius_mm: [table.radii_mm[0], table.radii_mm[table.radii_mm.len() - 1]],
        ratio: [1.0, MAX_RATIO],
        past_band: false,
    };
    let mut rng = Rng::seed(args.seed);
    let (mut pairs, mut felt, mut drawn) = (Vec::new(), 0usize, 0usize);
    let t0 = Instant::now();
    while felt < args.felt && drawn < 4 * args.felt + 8 {
        let case = draw(&table, &ranges, rng.next_u64())?;
        let ratio = (lo.ln() + rng.uniform() * (hi.ln() - lo.ln())).exp();
        let nodule = Nodule {
            ratio,
            ..case.nodule()
        };
        let spread = if args.above { 0.0 } else { PROBE_SPREAD_MM };
        let aim = [0, 1, 2].map(|d| case.surface_mm[d] + rng.range(-spread, spread));
        if nodule.check(&organ).is_err() {
            continue;
        }
        let Some((point, _)) = scene.closest_palpable(aim) else {
            continue;
        };
        // A point the fixed region holds has no press to change.
        let Ok(contact) = scene.contact(&point, scene.modes(), &mut contact_scratch) else {
            continue;
        };
        let placed = table.place(&nodule)?;
        let Ok(effect) = super::tissue::eval::effect_at_point(&table, &placed, &scene, &point)
        else {
            continue;
        };
        drawn += 1;
        let (curve, _) =
            super::tissue::eval::effect_curve(&table, &nodule, tissue_xxh3, &scene, &point, effect);
        let at = scene.frame(&point).0;
        let c = contact.compliance_mm_per_n;
        let solve = |n: Option<Nodule>| {
            let req = ProbeRequest {
                at,
                force_n: f64::NAN,
                dir: Some(contact.push_dir),
                radius_mm: o.tool_radius_mm,
                nodule: n,
            };
            solve_hyperelastic_depths(
                &organ,
                o.element,
                o.material,
                o.law,
                &req,
                &args.depths,
                NewtonSettings::default(),
            )
        };
        let (without, with) = (solve(None)?, solve(Some(nodule))?);
        let mut any_felt = false;
        for ((&depth, free), with) in args.depths.iter().zip(without).zip(with) {
            let (Ok((free, _)), Ok((with, _))) = (free, with) else {
                continue;
            };
            if depth > bound.limit_mm(&point).0 {
                continue;
            }
            let push = contact.push_dir.map(|d| d * depth / c);
            scene.displacement(&point, push, &mut coeffs, &mut rows)?;
            bound.add_surface(&point, depth, &mut scratch, &mut rows);
            let answered = curve.at(depth);
            apply_surface_gain(
                answered,
                at,
                scene.vertices_mm().iter().map(|p| p.map(f64::from)),
                &mut rows,
            );
            let ([surface_mm], _) = max_node_errors(&organ, &vertex_of, &with.u, [&rows]);
            let n = nodule;
            let pair = TissuePair {
                nodule: nodule_row(&n),
                at_mm: at,
                depth_mm: depth,
                force_fe_without_n: free.force_n,
                force_fe_n: with.force_n,
                force_tissue_without_n: bound.force_n(&point, depth, c).0,
                effect_linear: effect,
                effect_answered: answered,
                surface_mm,
            };
            any_felt |= pair.effect_fe() > heldout::FELT;
            if !args.json {
                println!(
                    "nodule r {:.1} mm, ratio {:.2}, depth {depth:.1} mm: Newton {:.3} N ({:+.1} %), tissue x (1 + e A) {:.3} N ({:+.1} %; linear {:+.1} %), surface {:.2} mm",
                    n.radius_mm,
                    n.ratio,
                    pair.force_fe_n,
                    100.0 * pair.effect_fe(),
                    pair.force_tissue_without_n * (1.0 + pair.effect_answered),
                    100.0 * pair.effect_answered,
                    100.0 * effect,
                    surface_mm
                );
            }
            pairs.push(pair);
        }
        felt += usize::from(any_felt);
    }
    let measured = TissueCheck {
        seed: args.seed,
        tissue: tissue.display().to_string(),
        law: bound.law.options.law.name().to_string(),
        tissue_xxh3: bound.law.payload_xxh3(),
        amplified,
        pairs,
        fe_s: t0.elapsed().as_secs_f64(),
    };
    let this = TissueSummary::of(&measured.pairs);
    if args.record {
        table.tissue_checks.retain(|c| c.seed != args.seed);
        table.tissue_checks.push(measured.clone());
        table.save(&args.file)?;
    }
    let report = json!({
        "file": args.file, "tissue": tissue, "seed": args.seed, "depths_mm": args.depths,
        "pairs": drawn, "presses": measured.pairs, "fe_s": measured.fe_s, "summary": this,
        "amplified": amplified, "recorded": args.record,
        "all_recorded": heldout::recorded_tissue(&table),
    });
    super::args::print_report(&report, args.json)
}
