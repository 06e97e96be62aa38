//! `palpa lab tissue band`: a built file's band next to the fixed region pressed, its own
//! presses kept.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::presser::PressLog;
use palpa_core::tissue::surface::PressCount;
use serde_json::json;

use crate::cli::args::OrganArgs;
use crate::cli::tissue::{press_log, press_pool, progress_line, summary};

#[derive(Debug, Args)]
pub struct BandArgs {
    /// A tissue file (from `palpa tissue build`, `refine`), without a band.
    tissue: PathBuf,
    #[command(flatten)]
    organ: OrganArgs,
    /// Press only the band edges whose midpoints lie within X,Y,Z,R (mm): the band of
    /// the region a scene shows.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    within: Option<Vec<f64>>,
    /// Presses computed at once (default: one per core).
    #[arg(long)]
    jobs: Option<usize>,
    /// Where to write the law with its band (atomically; it may be the input).
    #[arg(long)]
    out: PathBuf,
}

/// `palpa lab tissue band`.
pub fn band(args: &BandArgs) -> anyhow::Result<()> {
    crate::cli::args::check_out(&args.out)?;
    let within = match args.within.as_deref() {
        None => None,
        Some(&[x, y, z, r]) if [x, y, z, r].iter().all(|v| v.is_finite()) && r > 0.0 => {
            Some(([x, y, z], r))
        }
        Some(v) => bail!("--within: expected X,Y,Z,R (finite, R > 0), got {v:?}"),
    };
    if args.jobs == Some(0) {
        bail!("--jobs 0: expected at least one press at a time");
    }
    let organ = args.organ.mesh()?;
    let base = TissueLaw::load(&args.tissue)?;
    base.check_organ(&organ)?;
    if !base.refinement.band.is_empty() {
        bail!(
            "{} already holds a band next to the fixed region ({} edges): expected a file \
             without one (`palpa lab tissue cut --no-band` gives the file it was pressed on)",
            args.tissue.display(),
            base.refinement.band.len()
        );
    }
    let law = base
        .surface_law(&organ)
        .with_context(|| format!("reading back {}", args.tissue.display()))?;
    let log = press_log(&args.out);
    let pool = press_pool(args.jobs, &organ, law.options.element)?;
    let started = Instant::now();
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let (law, report) = pool
        .install(|| law.press_band(&organ, within, Some(&PressLog::at(&log)), &progress))
        .context("pressing the band next to the fixed region")?;
    eprintln!();
    if report.edges == 0 {
        bail!(
            "no band edge{}: expected a palpable edge from a pressed vertex to one on the fixed \
             region; nothing written",
            if within.is_some() {
                " within --within"
            } else {
                ""
            }
        );
    }
    let press_s = started.elapsed().as_secs_f64();
    let banded = base.banded(&organ, &law)?;
    banded.save(&args.out)?;
    let _ = std::fs::remove_file(&log);
    let report = json!({
        "from": args.tissue, "out": args.out,
        "band_edges": report.edges, "band_kept": report.kept,
        "band_failed": report.failed,
        "resumed_presses": report.resumed, "press_s": press_s,
        "file": summary(&banded, &args.out),
    });
    crate::cli::args::print_report(&report, false)
}
