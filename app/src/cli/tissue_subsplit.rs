//! `palpa tissue refine --sub-triangles N`: a split file's worst sub-triangles split
//! again (the second level of refinement), its own samples kept; with `--plan`, what
//! that would split and press, without pressing.

use std::time::Instant;

use anyhow::{Context, bail};
use palpa_core::pgd::surfacelaw::PressCount;
use serde_json::json;

use super::tissue::{press_log, press_pool, progress_line, summary};
use super::tissue_refine::RefineArgs;

/// `palpa tissue refine --sub-triangles most`.
pub fn refine_sub(args: &RefineArgs, most: usize) -> anyhow::Result<()> {
    let (at, organ, file) = super::tissue_refine::read_back(args)?;
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
        return super::args::print_report(&report, false);
    }
    let (Some(out), Some(log)) = (&args.out, log) else {
        bail!("--out: expected where to write the refined law");
    };
    let pool = press_pool(args.jobs, &organ, law.options.element)?;
    let started = Instant::now();
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let (kept, resumed) = pool
        .install(|| law.press_sub_split(&organ, &plan, Some(&log), &progress))
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
    super::args::print_report(&report, false)
}
