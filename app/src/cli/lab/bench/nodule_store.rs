//! `palpa lab bench nodule-store`: the nodule as coordinates of the linear vademecum
//! (`pgd::nodule`), against one full FE solve per configuration, in one run: the
//! store's columns, rows, bytes and build time; per radius, the unknowns a nodule
//! touches, the time to place it on one core, a probe's compliance correction, and the
//! FE solve with that nodule (assembly, factor, solve), with the two answers' gap.

use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::fe::load::{probe_functional, probe_load};
use palpa_core::fe::nodule::Nodule;
use palpa_core::fe::probe::{ProbeRequest, locate, smooth_inward_dir, solve_linear};
use palpa_core::fe::{Element, Material};
use palpa_core::organ::Level;
use palpa_core::organ::catalogue::{self, OrganName};
use palpa_core::pgd::nodal::setup;
use palpa_core::pgd::nodule::{InteriorResponses, NoduleRanges};
use serde_json::json;

#[derive(Debug, Args)]
pub struct NoduleStoreBenchArgs {
    /// Radii (mm), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [8.0, 10.0, 12.0, 15.0])]
    radii: Vec<f64>,
    /// The nodule's Young's modulus over the tissue's.
    #[arg(long, default_value_t = 4.4)]
    ratio: f64,
    /// The probe point X,Y,Z (mm), on the palpable surface.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, default_values_t = [-7.0, 69.34, 7.0])]
    at: Vec<f64>,
    /// How deep the nodule's centre lies below the probe point, along the press (mm).
    #[arg(long, default_value_t = 24.0)]
    centre_depth_mm: f64,
    /// Centres the store answers: within this distance of that centre (mm).
    #[arg(long, default_value_t = 4.0)]
    reach_mm: f64,
    #[arg(long, default_value = "coarse")]
    level: String,
    /// Probe corrections timed per radius.
    #[arg(long, default_value_t = 200)]
    repeats: usize,
    #[arg(long)]
    json: bool,
}

pub fn run(args: &NoduleStoreBenchArgs) -> anyhow::Result<()> {
    let at: [f64; 3] = args
        .at
        .as_slice()
        .try_into()
        .ok()
        .context("--at: expected X,Y,Z")?;
    let level: Level = args
        .level
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--level {}: {e}", args.level))?;
    if args.radii.is_empty() || args.radii.iter().any(|r| !(r.is_finite() && *r > 0.0)) {
        bail!("--radii: expected positive radii (mm)");
    }
    if !(args.reach_mm.is_finite() && args.reach_mm >= 0.0) {
        bail!("--reach-mm {}: expected a distance ≥ 0", args.reach_mm);
    }
    if args.repeats == 0 {
        bail!("--repeats: expected at least 1");
    }
    let organ = catalogue::mesh(OrganName::Liver, level);
    let material = Material::default();
    let s = setup(&organ, Element::P2, material, 5.0)?;
    let dir = smooth_inward_dir(&organ, at).context("placing the probe")?;
    let centre = [0, 1, 2].map(|d| at[d] + args.centre_depth_mm * dir[d]);
    let hi = args.radii.iter().cloned().fold(0.0, f64::max);
    let lo = args.radii.iter().cloned().fold(f64::INFINITY, f64::min);
    let ranges = NoduleRanges {
        center_mm: centre,
        reach_mm: args.reach_mm,
        radius_mm: (lo, hi),
        ratio: (1.0, args.ratio.max(1.0)),
    };
    let store = InteriorResponses::build(&s, ranges);
    let req = ProbeRequest::unit(at, dir);
    let (probe, pdir) = locate(&s.space, &organ, &req)?;
    let f = s
        .space
        .free_entries(&probe_load(&s.space, &probe, pdir, 1.0, 5.0)?);
    let phi = s
        .space
        .free_entries(&probe_functional(&s.space, &probe, pdir));
    let free = solve_linear(&organ, Element::P2, material, &req)?;
    // One core: the dense algebra of a placement without threads.
    let threads = faer::get_global_parallelism();
    faer::set_global_parallelism(faer::Par::Seq);
    let mut rows = Vec::new();
    for &r in &args.radii {
        let nodule = Nodule {
            center_mm: centre,
            radius_mm: r,
            ratio: args.ratio,
        };
        if let Err(e) = nodule.check(&organ) {
            rows.push(json!({"radius_mm": r, "refused": e.to_string()}));
            continue;
        }
        let placed = store.place(&nodule)?;
        let t = Instant::now();
        let mut dc = 0.0;
        for _ in 0..args.repeats {
            dc = std::hint::black_box(placed.correction(&store, &f, &phi));
        }
        let query_s = t.elapsed().as_secs_f64() / args.repeats as f64;
        let t = Instant::now();
        let with = solve_linear(
            &organ,
            Element::P2,
            material,
            &ProbeRequest {
                nodule: Some(nodule),
                ..req
            },
        )?;
        let fe_s = t.elapsed().as_secs_f64();
        let c = free.probe_displacement_mm + dc;
        rows.push(json!({
            "radius_mm": r, "ratio": args.ratio, "cells": placed.cells,
            "unknowns": placed.dofs.len(), "place_s": placed.place_s, "factor_s": placed.factor_s, "query_s": query_s,
            "fe_solve_s": fe_s, "fe_over_place": fe_s / placed.place_s,
            "effect": free.probe_displacement_mm / with.probe_displacement_mm - 1.0,
            "compliance_gap": (c - with.probe_displacement_mm).abs() / with.probe_displacement_mm,
        }));
    }
    faer::set_global_parallelism(threads);
    let head = json!({
        "level": level.name(), "columns": store.cols.len(), "rows": store.rows.len(),
        "bytes": store.bytes(), "build_s": store.build_s, "reach_mm": args.reach_mm,
        "centre_mm": centre, "free_unknowns": s.space.free_dofs,
    });
    if args.json {
        println!("{head}");
        for r in &rows {
            println!("{r}");
        }
        return Ok(());
    }
    println!(
        "store ({}, centres within {} mm of {:?}): {} columns × {} rows of {} unknowns, {:.0} MB, built in {:.1} s",
        level.name(),
        args.reach_mm,
        centre.map(|v| (v * 10.0).round() / 10.0),
        store.cols.len(),
        store.rows.len(),
        s.space.free_dofs,
        store.bytes() as f64 / 1e6,
        store.build_s
    );
    println!(
        "{:>9} {:>6} {:>9} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9} {:>10}",
        "radius",
        "cells",
        "unknowns",
        "place ms",
        "of it LU",
        "probe µs",
        "FE s",
        "FE/place",
        "effect",
        "gap"
    );
    for r in &rows {
        if let Some(why) = r["refused"].as_str() {
            println!(
                "{:>9.1} refused: {why}",
                r["radius_mm"].as_f64().unwrap_or(0.0)
            );
            continue;
        }
        let g = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
        println!(
            "{:>9.1} {:>6} {:>9} {:>10.1} {:>10.1} {:>10.1} {:>10.2} {:>9.0} {:>8.2}% {:>10.1e}",
            g("radius_mm"),
            r["cells"].as_u64().unwrap_or(0),
            r["unknowns"].as_u64().unwrap_or(0),
            1e3 * g("place_s"),
            1e3 * g("factor_s"),
            1e6 * g("query_s"),
            g("fe_solve_s"),
            g("fe_over_place"),
            100.0 * g("effect"),
            g("compliance_gap")
        );
    }
    Ok(())
}
