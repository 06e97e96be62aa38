//! `palpa lab tissue refine`: a built file's triangles split, its own presses kept; with
//! `--plan`, what that would split and press, without pressing.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::presser::PressLog;
use palpa_core::tissue::surface::{DEFAULT_REFINE_ABOVE_MM, PressCount};
use serde_json::json;

use crate::cli::args::OrganArgs;
use crate::cli::tissue::points::triples;
use crate::cli::tissue::{press_log, press_pool, progress_line, summary};

#[derive(Debug, Args)]
pub struct RefineArgs {
    /// A tissue file: built without split triangles (`palpa tissue build --no-refine`),
    /// or split by an earlier stage, which this one goes on from (its split triangles
    /// kept, only new ones pressed).
    pub(super) tissue: PathBuf,
    #[command(flatten)]
    pub(super) organ: OrganArgs,
    /// Split the triangles whose largest edge surplus (any node, any depth) exceeds
    /// this (mm), as `tissue build` does [default: 0.35]. (Sub-triangles are ranked by
    /// their own surpluses: not with `--sub-triangles`.)
    #[arg(long, conflicts_with = "sub_triangles")]
    refine_above_mm: Option<f64>,
    /// Split only this many of them, the worst first (by their largest edge surplus):
    /// a refinement in stages. On a split file, the stage's triangles in all (those
    /// already split among them). Default: all.
    #[arg(long, conflicts_with = "sub_triangles")]
    triangles: Option<usize>,
    /// Split this many of the split triangles' sub-triangles again, the worst first
    /// (by the largest surplus at their edge midpoints): the second level of
    /// refinement, on a file split by earlier stages. Its points are pressed and kept
    /// as surpluses over the file's blend; the file's own samples are kept as they are.
    /// On a file whose sub-triangles were split again: a larger stage (this many in
    /// all, its own among them), planned from the file they were split from.
    #[arg(long)]
    sub_triangles: Option<usize>,
    /// With `--sub-triangles`: rank them by their surpluses at depths up to this one
    /// (mm) only, for a scene that presses no deeper. Default: every grid depth.
    #[arg(long, requires = "sub_triangles")]
    pub(super) rank_to_mm: Option<f64>,
    /// Presses computed at once (default: one per core).
    #[arg(long)]
    pub(super) jobs: Option<usize>,
    /// Only say what it would split and press (and how many of those presses the log
    /// of `--out` already holds), and where the triangles at `--at` rank; press nothing.
    #[arg(long)]
    pub(super) plan: bool,
    /// With `--plan`: points (X,Y,Z[,X,Y,Z…], mm) whose triangles' edge surpluses,
    /// by depth, and ranks to report.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "plan"
    )]
    pub(super) at: Option<Vec<f64>>,
    /// Where to write the refined law (atomically; it may be the input).
    #[arg(long, required_unless_present = "plan")]
    pub(super) out: Option<PathBuf>,
}

/// The `--at` points, the organ mesh and the file, after checking `--jobs`.
pub(super) fn read_back(
    args: &RefineArgs,
) -> anyhow::Result<(Vec<[f64; 3]>, OrganMesh, TissueLaw)> {
    if args.jobs == Some(0) {
        bail!("--jobs 0: expected at least one press at a time");
    }
    let at = match &args.at {
        Some(v) => triples("--at", v)?,
        None => Vec::new(),
    };
    let organ = args.organ.mesh()?;
    let base = TissueLaw::load(&args.tissue)?;
    base.check_organ(&organ)?;
    Ok((at, organ, base))
}

/// `palpa lab tissue refine`.
pub fn refine(args: &RefineArgs) -> anyhow::Result<()> {
    if let Some(out) = &args.out {
        crate::cli::args::check_out(out)?;
    }
    if let Some(most) = args.sub_triangles {
        return refine_sub(args, most);
    }
    let refine_above_mm = args.refine_above_mm.unwrap_or(DEFAULT_REFINE_ABOVE_MM);
    if !(refine_above_mm.is_finite() && refine_above_mm >= 0.0) {
        bail!(
            "--refine-above-mm {}: expected a length of at least 0",
            refine_above_mm
        );
    }
    let (at, organ, base) = read_back(args)?;
    let law = base
        .surface_law(&organ)
        .with_context(|| format!("reading back {}", args.tissue.display()))?;
    let log = args.out.as_deref().map(press_log);
    if args.plan {
        let p = law.refine_preview(&organ, refine_above_mm, args.triangles, log.as_deref(), &at)?;
        let points: Vec<_> =
            p.at.iter()
                .map(|r| {
                    json!({
                        "at": r.point_mm, "edge_surplus_mm": r.edge_surplus_mm,
                        "edge_surplus_by_depth_mm": r.edge_surplus_by_depth_mm,
                        "rank": r.rank, "split": r.split,
                    })
                })
                .collect();
        let report = json!({
            "from": args.tissue, "refine_above_mm": refine_above_mm,
            "depth_step_mm": law.options.depth_step_mm,
            "candidates": p.candidates, "triangles_above": p.above,
            "split_triangles": p.split, "split_triangles_kept": p.kept,
            "presses": p.presses,
            "presses_logged": log.as_ref().map(|_| p.logged),
            "presses_to_do": p.presses - p.logged,
            "triangles_ready": log.as_ref().map(|_| p.ready),
            "worst_edge_surplus_mm": p.worst_mm,
            "least_split_edge_surplus_mm": p.least_split_mm,
            "at": points,
        });
        return crate::cli::args::print_report(&report, false);
    }
    let (Some(out), Some(log)) = (&args.out, log) else {
        bail!("--out: expected where to write the refined law");
    };
    let kept = law.refinement.triangles.len();
    let pool = press_pool(args.jobs, &organ, law.options.element)?;
    let started = Instant::now();
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let (law, resumed, above) = pool
        .install(|| {
            law.refine(
                &organ,
                refine_above_mm,
                args.triangles,
                Some(&PressLog::at(&log)),
                &progress,
            )
        })
        .context("pressing the split triangles' points")?;
    eprintln!();
    let press_s = started.elapsed().as_secs_f64();
    let refined = base.refined(&organ, &law)?;
    refined.save(out)?;
    // A partial refinement keeps its log: a larger --triangles goes on from it.
    let split = law.refinement.triangles.len();
    if split == above {
        let _ = std::fs::remove_file(&log);
    }
    let worst = |f: fn(&(f64, f64)) -> f64| law.split_figures.iter().map(f).fold(0.0, f64::max);
    let least_split = law
        .split_figures
        .iter()
        .map(|f| f.0)
        .fold(f64::INFINITY, f64::min);
    let report = json!({
        "from": args.tissue, "out": out,
        "refine_above_mm": refine_above_mm, "triangles_above": above,
        "split_triangles": split, "split_triangles_kept": kept,
        "least_split_edge_surplus_mm": least_split.is_finite().then_some(least_split),
        "worst_edge_surplus_mm": worst(|f| f.0), "worst_point_surplus_mm": worst(|f| f.1),
        "quarter_points": law.refinement.quarter_ends.len(),
        "inner_points": law.refinement.inner_corners.len(),
        "refine_skipped": law.refine_skip_reasons.len(),
        "resumed_presses": resumed, "press_s": press_s,
        "log_kept": (split < above).then_some(&log),
        "file": summary(&refined, out),
    });
    crate::cli::args::print_report(&report, false)
}

/// `palpa lab tissue refine --sub-triangles most`: a split file's worst sub-triangles
/// split again (the second level of refinement), its own samples kept; with `--plan`,
/// what that would split and press, without pressing.
pub fn refine_sub(args: &RefineArgs, most: usize) -> anyhow::Result<()> {
    let (at, organ, file) = read_back(args)?;
    let (base, mut law, plan) = file
        .second_level_plan(&organ, most, args.rank_to_mm)
        .with_context(|| format!("splitting sub-triangles of {}", args.tissue.display()))?;
    let log = args.out.as_deref().map(press_log);
    let surplus = |k: usize| plan.candidates.get(k).map(|c| c.edge_surplus_mm);
    if args.plan {
        let logged: std::collections::HashSet<u32> = match &log {
            Some(path) => law.logged_ids(&organ, path)?.into_iter().collect(),
            None => Default::default(),
        };
        let held = plan.press_ids().filter(|id| logged.contains(id)).count();
        let points: Vec<_> = at
            .iter()
            .map(|&p| {
                let found = plan.rank_at(&organ, p);
                json!({
                    "at": p,
                    "rank": found.map(|(r, _)| r + 1),
                    "edge_surplus_mm": found.map(|(_, c)| c.edge_surplus_mm),
                    "split": found.is_some_and(|(r, _)| r < plan.chosen),
                })
            })
            .collect();
        let report = json!({
            "from": args.tissue, "candidates": plan.candidates.len(),
            "rank_to_mm": args.rank_to_mm,
            "sub_triangles": plan.chosen, "presses": plan.presses(),
            "presses_logged": log.as_ref().map(|_| held),
            "presses_to_do": plan.presses() - held,
            "worst_edge_surplus_mm": surplus(0),
            "least_split_edge_surplus_mm": plan.chosen.checked_sub(1).and_then(surplus),
            "first_left_edge_surplus_mm": surplus(plan.chosen),
            "at": points,
            "sub_triangles_mm": (0..plan.chosen)
                .map(|i| plan.corners_mm(&organ, i))
                .collect::<Vec<_>>(),
        });
        return crate::cli::args::print_report(&report, false);
    }
    let (Some(out), Some(log)) = (&args.out, log) else {
        bail!("--out: expected where to write the refined law");
    };
    let pool = press_pool(args.jobs, &organ, law.options.element)?;
    let started = Instant::now();
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let (kept, resumed) = pool
        .install(|| law.press_sub_split(&organ, &plan, Some(&PressLog::at(&log)), &progress))
        .context("pressing the sub-triangles' points")?;
    eprintln!();
    let press_s = started.elapsed().as_secs_f64();
    let skipped: Vec<&String> = kept.iter().filter_map(|k| k.as_ref().err()).collect();
    let refined = base.sub_split(&organ, law, &plan, &kept)?;
    refined.save(out)?;
    let report = json!({
        "from": args.tissue, "out": out,
        "candidates": plan.candidates.len(), "rank_to_mm": args.rank_to_mm,
        "sub_triangles": plan.chosen,
        "worst_edge_surplus_mm": surplus(0),
        "least_split_edge_surplus_mm": plan.chosen.checked_sub(1).and_then(surplus),
        "first_left_edge_surplus_mm": surplus(plan.chosen),
        "presses": plan.presses(), "resumed_presses": resumed,
        "skipped": skipped, "press_s": press_s,
        "log_kept": &log,
        "file": summary(&refined, out),
    });
    crate::cli::args::print_report(&report, false)
}
