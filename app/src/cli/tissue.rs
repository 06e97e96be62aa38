//! `palpa tissue …`: the hyperelastic vademecum of a palpation scene (see
//! `palpa_core::pgd::tissue`): build it off-line from every palpable vertex's depth
//! series, and check it against the full nonlinear FE at held-out presses.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use palpa_core::fe::newton::NewtonSettings;
use palpa_core::fe::path::{StopKind, press_memory_bytes};
use palpa_core::fe::probe::{ProbeRequest, organ_space, solve_hyperelastic};
use palpa_core::fe::series::{Expander, SplitTangent};
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::pgd::surfacelaw::{
    DEFAULT_REFINE_ABOVE_MM, MAX_GRID_POINTS, PressCount, SurfaceLaw, SurfaceLawOptions, follow_at,
    press_at,
};
use palpa_core::pgd::tissue::{
    BLEND_SURPLUS_WARN_MM, BoundTissue, DEFAULT_BITS, DEFAULT_TOLERANCE_MM, Grouping, PointIndex,
    ShapeBits, TissueLaw,
};
use palpa_core::rng::Rng;
use serde_json::json;

use super::args::OrganArgs;
use super::depthlaw::NonlinearModel;
use super::tissue_against::{Against, Answer};

#[derive(Debug, Subcommand)]
pub enum TissueCommand {
    /// Build the nonlinear vademecum off-line: every palpable vertex's press followed
    /// to equilibrium on the depth grid, the surfaces compressed by an SVD; finished
    /// presses are logged in `OUT.presses.log`, so a killed build run again goes on.
    Build(BuildArgs),
    /// Compare a built vademecum with the full nonlinear FE (Newton) at held-out
    /// random points and depths, through a scene (what the app shows).
    Check(CheckArgs),
    /// Draw held-out points over the whole palpable surface (seeded) and print them as
    /// `X,Y,Z,…` for `tissue build --cover` and `tissue check --at`: a whole-surface
    /// accuracy table from the few triangles that hold them.
    Points(PointsArgs),
    /// Cut a built vademecum to fewer modes per sample (or per group of samples that
    /// share them), fewer bits or a longer depth step (what `palpa tradeoff` measures)
    /// and save it: a scene ships only what it shows. The stored bound grows by what the cut drops.
    Cut(CutArgs),
    /// Split the triangles of a file built without splitting (`--no-refine`): their
    /// quarter and inner points pressed, the file's own presses kept as stored. Presses
    /// are logged in `OUT.presses.log` under the same key as `tissue build`'s, so a
    /// killed refinement run again goes on, and a larger `--triangles` later reuses them.
    Refine(super::tissue_refine::RefineArgs),
    /// Press the band next to the fixed region: the midpoint of every palpable edge from
    /// a pressed vertex to one on the fixed region (which no press may push), each kept
    /// as its surplus over its pressed end; the file's own presses kept as stored. The
    /// last stage: a file with a band is not split further. Presses are logged in
    /// `OUT.presses.log`, so a killed run again goes on.
    Band(super::tissue_band::BandArgs),
}

#[derive(Debug, Args)]
pub struct CutArgs {
    /// A tissue file (from `palpa tissue build`).
    tissue: PathBuf,
    /// Most modes a sample (or a group of samples sharing them) keeps: its first, by
    /// singular value.
    #[arg(long, default_value_t = palpa_core::pgd::tissue::MAX_RANK)]
    modes: usize,
    /// Bits per stored shape entry: 8 or 16 (default: as built).
    #[arg(long, value_parser = parse_bits)]
    bits: Option<u32>,
    /// Keep every k-th grid depth (k must divide the grid's intervals).
    #[arg(long, default_value_t = 1)]
    depth_stride: usize,
    /// Drop the split triangles' quarter and inner points: the quadratic blend
    /// everywhere, as a build with `--no-refine` stores the same presses (what `palpa
    /// tissue refine` starts from).
    #[arg(long)]
    unsplit: bool,
    /// Drop the band next to the fixed region (`palpa tissue band`): the file it was
    /// pressed on. (`--unsplit` drops it too.)
    #[arg(long)]
    no_band: bool,
    /// Round every weight to sixteen bits (IEEE half): what a build stores now (the
    /// fifth-stage shipped law: 7.65 → 6.18 MB). The bound grows by the most that
    /// moves a node (`weights_halved_mm`).
    #[arg(long)]
    half_weights: bool,
    /// Where to write the cut law (atomically; it may be the input).
    #[arg(long)]
    out: PathBuf,
}

#[derive(Debug, Args)]
pub struct PointsArgs {
    #[command(flatten)]
    organ: OrganArgs,
    #[arg(long, default_value_t = 16)]
    heldout: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Draw them inside the split triangles of this tissue file only: what a
    /// refinement buys, measured where it split (`tissue check --at` on the file and
    /// on the one it refined).
    #[arg(long)]
    split_of: Option<PathBuf>,
    /// Draw them inside the palpable triangles that touch the fixed region only (a
    /// corner fixed, so never pressed: the blend there renormalizes over the pressed
    /// corners). The default draw leaves this band out.
    #[arg(long, conflicts_with = "split_of")]
    next_to_fixed: bool,
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    #[command(flatten)]
    pub organ: OrganArgs,
    #[arg(long, value_enum, default_value = "neo-hookean")]
    pub model: NonlinearModel,
    #[arg(long, default_value = "p2")]
    pub element: Element,
    /// Deepest press covered (mm); deeper presses are held there and flagged.
    #[arg(long, default_value_t = 15.0)]
    pub depth_max_mm: f64,
    /// Grid step in depth (mm).
    #[arg(long, default_value_t = 1.0)]
    pub depth_step_mm: f64,
    /// Orders of the rest series (each press's first predictor; later segments use 6).
    #[arg(long, default_value_t = SurfaceLawOptions::default().orders)]
    pub orders: usize,
    /// The compression's guaranteed bound on any node's residual (mm).
    #[arg(long, default_value_t = DEFAULT_TOLERANCE_MM)]
    pub tolerance_mm: f64,
    /// Bits per stored entry of a mode's shape: 8 (half the bytes) or 16 (the
    /// quantization is part of the bound; `palpa tradeoff` measures both).
    #[arg(long, default_value_t = DEFAULT_BITS.count(), value_parser = parse_bits)]
    pub bits: u32,
    /// Higher orders assembled where the first order varies by at least this fraction
    /// of its peak (0: everywhere).
    #[arg(long, default_value_t = SurfaceLawOptions::default().active_cutoff)]
    pub active_cutoff: f64,
    /// Press only the palpable vertices within X,Y,Z,R (mm): model only the region a
    /// scene shows.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        conflicts_with = "cover"
    )]
    pub within: Option<Vec<f64>>,
    /// Press only what answers at these points (X,Y,Z[,X,Y,Z…], mm, on the palpable
    /// surface): the triangles holding them, split as the whole build would split
    /// them. There the file answers as a whole-surface build does (see `tissue points`).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub cover: Option<Vec<f64>>,
    #[arg(long, default_value_t = 160.0)]
    pub young_kpa: f64,
    #[arg(long, default_value_t = 0.48)]
    pub poisson: f64,
    /// Press the palpable vertices only, not also the edge midpoints: a third of the
    /// presses, and a linear blend between vertices (measured up to 3 mm off near the
    /// sharp border at 13 mm, where the quadratic blend erred by 0.2 mm).
    #[arg(long)]
    pub no_edges: bool,
    /// Split into four the triangles whose largest edge surplus (the midpoint's press
    /// off its ends' mean, any node, any depth) exceeds this (mm), and press their
    /// quarter and inner points: a denser blend where the response turns quickly
    /// [default: 0.35].
    #[arg(long, conflicts_with_all = ["no_refine", "no_edges"])]
    pub refine_above_mm: Option<f64>,
    /// Split no triangle: the quadratic blend everywhere.
    #[arg(long)]
    pub no_refine: bool,
    /// Give each split triangle's quarter and inner points modes of their own, not one
    /// set shared by the triangle's points (measured: about three times the modes).
    #[arg(long, conflicts_with_all = ["no_refine", "no_edges"])]
    pub separate_modes: bool,
    /// Presses computed at once. Each holds its own factored tangent: on medium P2
    /// two at once peaked at 21.7 GB. Default: one per core.
    #[arg(long)]
    pub jobs: Option<usize>,
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    /// A tissue file (from `palpa tissue build`).
    tissue: PathBuf,
    #[command(flatten)]
    organ: OrganArgs,
    /// The scene it serves: `liver` (built in) or a `.palpa` file of the same mesh.
    #[arg(long, default_value = "liver")]
    scene: String,
    /// Held-out random points (inside palpable triangles whose corners were pressed).
    #[arg(long, default_value_t = 4, conflicts_with = "at")]
    heldout: usize,
    /// Depths of each held-out press (mm), off the depth grid.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true,
          default_values_t = [2.6, 7.3, 12.7])]
    depths: Vec<f64>,
    #[arg(long, default_value_t = 7, conflicts_with = "at")]
    seed: u64,
    /// Press at these points (X,Y,Z[,X,Y,Z…], mm) instead of random ones: compare two
    /// files at the same presses.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    at: Option<Vec<f64>>,
    /// Also expand the press at each held-out point itself by the two-segment series
    /// (one factorization at the split, and the exact two): what an uncorrected
    /// series gives there, apart from the blend between vertices. (The build now
    /// corrects each vertex's states to equilibrium; see `fe::path`.)
    #[arg(long)]
    series: bool,
    /// Also follow the press at each held-out point itself to equilibrium, as the
    /// build follows a vertex's (`own_*` keys): its error against Newton is the
    /// press's own, its distance from the vademecum's surface the blend's.
    #[arg(long)]
    own: bool,
    /// Also answer every press with this tissue file (of the same model, for the same
    /// scene) against the same Newton solves: two stages or cuts compared in one run
    /// (`against` keys per press and in the summary; `changed` where its answer differs
    /// from the checked file's at all).
    #[arg(long)]
    against: Option<PathBuf>,
}

/// A duration for a progress line: `42 s`, `17 min`, `3 h 05 min`.
fn minutes(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min", s / 60),
        _ => format!("{} h {:02} min", s / 3600, s % 3600 / 60),
    }
}

/// `, about … left` for a progress line: the presses still to do at the rate of those
/// this run computed, `elapsed_s` after it started. Presses taken from the log are
/// left out of the rate (they cost nothing: counted in, a build resumed at 3 129 of
/// 8 191 presses said an hour was left where six were); nothing is said before the
/// first computed press. The total counts the presses planned so far, so the estimate
/// grows when the split triangles are planned.
fn time_left(c: PressCount, elapsed_s: f64) -> String {
    match c.done.saturating_sub(c.from_log) {
        0 => String::new(),
        computed => format!(
            ", about {} left",
            minutes(elapsed_s / computed as f64 * c.total.saturating_sub(c.done) as f64)
        ),
    }
}

/// `--bits`: 8 or 16.
pub fn parse_bits(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(b) if ShapeBits::from_count(b).is_some() => Ok(b),
        _ => Err(format!(
            "{s}: expected 8 or 16 (bits per stored shape entry)"
        )),
    }
}

pub fn run(cmd: &TissueCommand) -> anyhow::Result<()> {
    match cmd {
        TissueCommand::Build(args) => build(args).map(|(_, summary)| println!("{summary}")),
        TissueCommand::Check(args) => check(args),
        TissueCommand::Points(args) => {
            if args.heldout == 0 {
                bail!("--heldout 0: expected at least one point");
            }
            let organ = args.organ.mesh()?;
            let points = match &args.split_of {
                None if args.next_to_fixed => {
                    let faces = faces_next_to_fixed(&organ);
                    if faces.is_empty() {
                        bail!("this organ has no palpable triangle with a fixed corner");
                    }
                    let palpable: Vec<usize> = (0..organ.boundary.len())
                        .filter(|&f| organ.palpable[f])
                        .collect();
                    eprintln!(
                        "tissue points: {} triangles touch the fixed region, {:.1} % of the \
                         palpable surface's area",
                        faces.len(),
                        100.0 * faces_area(&organ, &faces) / faces_area(&organ, &palpable)
                    );
                    points_in(&organ, &faces, args.heldout, args.seed)?
                }
                None => surface_points(&organ, args.heldout, args.seed)?,
                Some(file) => {
                    let law = TissueLaw::load(file)?;
                    law.check_organ(&organ.mesh.vertices)?;
                    let faces = split_faces(&organ, &law)?;
                    points_in(&organ, &faces, args.heldout, args.seed)?
                }
            };
            let text: Vec<String> = points.iter().flatten().map(|c| format!("{c:.4}")).collect();
            println!("{}", text.join(","));
            Ok(())
        }
        TissueCommand::Cut(args) => cut(args),
        TissueCommand::Refine(args) => super::tissue_refine::refine(args),
        TissueCommand::Band(args) => super::tissue_band::band(args),
    }
}

/// `palpa tissue cut`: a law with fewer modes, bits or depths, saved.
fn cut(args: &CutArgs) -> anyhow::Result<()> {
    let law = TissueLaw::load(&args.tissue)?;
    let without = args.no_band.then(|| law.without_band());
    let unsplit = args
        .unsplit
        .then(|| without.as_ref().unwrap_or(&law).unsplit())
        .or(without);
    let bits = match args.bits {
        None => law.shape.bits(),
        Some(b) => ShapeBits::from_count(b).context("--bits: expected 8 or 16")?,
    };
    let cut = unsplit
        .as_ref()
        .unwrap_or(&law)
        .coarsened(args.modes, bits, args.depth_stride)
        .map_err(|why| anyhow::anyhow!("cutting {}: {why}", args.tissue.display()))?;
    let (out, halved_mm) = match args.half_weights {
        true => cut.law.with_half_weights(),
        false => (cut.law, 0.0),
    };
    out.save(&args.out)?;
    let summary = json!({
        "from": summary(&law, &args.tissue),
        "out": summary(&out, &args.out),
        "dropped_sigma_mm": cut.dropped_sigma_mm,
        "requantized_mm": cut.requantized_mm,
        "weights_halved_mm": halved_mm,
    });
    super::args::print_report(&summary, false)
}

/// The press log beside a build's output: an interrupted build run again with the same
/// arguments goes on from the last finished press.
pub(super) fn press_log(out: &std::path::Path) -> PathBuf {
    let mut log = out.as_os_str().to_owned();
    log.push(".presses.log");
    PathBuf::from(log)
}

/// The threads a build presses on: `--jobs`, else one per core, fewer where the memory
/// available would not hold them ([`default_jobs`]).
pub(super) fn press_pool(
    jobs: Option<usize>,
    organ: &OrganMesh,
    element: Element,
) -> anyhow::Result<rayon::ThreadPool> {
    let jobs = match jobs {
        Some(0) => bail!("--jobs 0: expected at least one press at a time"),
        Some(n) => n,
        None => default_jobs(organ, element)?,
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .thread_name(|i| format!("tissue-press-{i}"))
        .build()
        .context("starting the press threads")
}

/// Presses at once without `--jobs`: one per core, but no more than the memory
/// available holds beside the shared rest factor, each press at its peak
/// (`fe::path::press_memory_bytes`); at least one. Said on stderr with its figures.
fn default_jobs(organ: &OrganMesh, element: Element) -> anyhow::Result<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let Some(available) = super::memory::available_bytes() else {
        return Ok(cores);
    };
    let (shared, each) = press_memory_bytes(&organ_space(organ, element))
        .context("estimating the memory a press needs")?;
    let fit = jobs_that_fit(available, shared, each);
    let jobs = fit.clamp(1, cores);
    let gb = |b: u64| b as f64 / 1e9;
    eprintln!(
        "tissue: {jobs} press(es) at a time ({cores} cores; about {:.1} GB shared and {:.1} GB \
         a press, {:.1} GB available){}",
        gb(shared),
        gb(each),
        gb(available),
        if fit == 0 {
            ": even one may not fit, and a factorization beyond the memory is refused"
        } else {
            ""
        }
    );
    Ok(jobs)
}

/// How many presses of `each` bytes fit in `available` beside `shared` (0 where not one).
fn jobs_that_fit(available: u64, shared: u64, each: u64) -> usize {
    (available.saturating_sub(shared) / each.max(1)) as usize
}

/// A build's progress line, with an estimate of what is left from the presses this run
/// computed (not those taken from the log, which cost nothing).
pub(super) fn progress_line(c: PressCount, elapsed_s: f64) {
    eprint!(
        "\rtissue: press {}/{}, {} elapsed{}   ",
        c.done,
        c.total,
        minutes(elapsed_s),
        time_left(c, elapsed_s)
    );
}

/// Of presses that reached `reach` grid depths (depth 0 included) out of `steps`: how
/// many stopped short, and the shallowest depth any reached (mm).
fn reach_figures(reach: &[u32], steps: u32, step_mm: f64) -> (usize, Option<f64>) {
    let stopped_short = reach.iter().filter(|&&r| r < steps).count();
    let shallowest = reach.iter().min().map(|&r| f64::from(r - 1) * step_mm);
    (stopped_short, shallowest)
}

/// How many stored samples stopped short for each reason ([`StopKind`]), and how many
/// of those that found no equilibrium ran out of their factorization budget: a surplus
/// keeps the reason of whichever of its press and its bases stopped first, so one
/// press that stopped counts once for itself and once for each sample it holds back.
fn stopped_by(stopped: &[String]) -> serde_json::Value {
    let kinds: Vec<StopKind> = stopped.iter().filter_map(|w| StopKind::of(w)).collect();
    let count = |f: fn(&StopKind) -> bool| kinds.iter().filter(|k| f(k)).count();
    json!({
        "force_peak": count(|k| *k == StopKind::ForcePeak),
        "no_equilibrium": count(|k| matches!(k, StopKind::NoEquilibrium { .. })),
        "no_equilibrium_budget_spent":
            count(|k| *k == StopKind::NoEquilibrium { budget_spent: true }),
    })
}

/// What a tissue file holds: its samples, how far its presses reach, its bytes and
/// bound (`palpa info X.tissue`, `palpa tissue cut`).
pub fn summary(law: &TissueLaw, path: &std::path::Path) -> serde_json::Value {
    let o = &law.options;
    let (stopped_short, shallowest) = reach_figures(&law.reach, law.steps, o.depth_step_mm);
    let vertices = law.samples_mm.len();
    let modes = law.mode_start.last().copied().unwrap_or(0);
    json!({
        "file": path, "kind": "tissue",
        "law": o.law.name(), "element": o.element.name(),
        "young_kpa": o.material.young_kpa, "poisson": o.material.poisson,
        "depth_max_mm": law.depth_max_mm(), "depth_step_mm": o.depth_step_mm,
        "vertices": vertices, "vertices_skipped": law.skipped_mm.len(),
        "edges": law.edge_ends.len(),
        "split_triangles": law.refinement.triangles.len(),
        "quarter_points": law.refinement.quarter_ends.len(),
        "inner_points": law.refinement.inner_corners.len(),
        "sub_triangles_split": law.refinement.sub.sub_triangles.len(),
        "second_level_points": law.refinement.sub.points.len(),
        "presses": law.reach.len(),
        "stopped_short": stopped_short, "stopped_by": stopped_by(&law.stopped),
        "shallowest_reach_mm": shallowest,
        "rows": law.rows_mm.len(), "rank": law.rank, "modes": modes,
        "mode_groups": law.mode_start.len() - 1,
        "bits": law.shape.bits().count(),
        "truncation_bound_mm": law.truncation_bound_mm, "tolerance_mm": law.tolerance_mm,
        "payload_bytes": law.payload_bytes(),
        "file_bytes": std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
        "build_s": law.build_s,
    })
}

/// Builds, compresses and saves; returns the law and a JSON summary.
pub fn build(args: &BuildArgs) -> anyhow::Result<(TissueLaw, serde_json::Value)> {
    super::args::check_out(&args.out)?;
    let organ = args.organ.mesh()?;
    let within = match args.within.as_deref() {
        None => None,
        Some(&[x, y, z, r]) if [x, y, z, r].iter().all(|v| v.is_finite()) && r > 0.0 => {
            Some(([x, y, z], r))
        }
        Some(v) => bail!("--within: expected X,Y,Z,R (finite, R > 0), got {v:?}"),
    };
    // A ball that holds no palpable vertex would end in "the surface law is empty".
    if let Some((c, r)) = within {
        let nearest = organ
            .pressable_vertices()
            .iter()
            .map(|&v| {
                let p = organ.mesh.vertices[v as usize];
                (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>().sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        if nearest > r {
            bail!(
                "--within {},{},{},{r}: no palpable vertex lies within {r} mm of that point (the \
                 nearest is {nearest:.1} mm away); expected a ball that holds some",
                c[0],
                c[1],
                c[2]
            );
        }
    }
    if !(args.tolerance_mm.is_finite() && args.tolerance_mm > 0.0) {
        bail!(
            "--tolerance-mm {}: expected a positive length",
            args.tolerance_mm
        );
    }
    palpa_core::fe::depth_grid_points(args.depth_max_mm, args.depth_step_mm, MAX_GRID_POINTS)
        .context("--depth-max-mm, --depth-step-mm")?;
    let options = SurfaceLawOptions {
        law: args.model.law(),
        material: Material {
            young_kpa: args.young_kpa,
            poisson: args.poisson,
        },
        element: args.element,
        depth_max_mm: args.depth_max_mm,
        depth_step_mm: args.depth_step_mm,
        orders: args.orders,
        active_cutoff: args.active_cutoff,
        within,
        edges: !args.no_edges,
        ..SurfaceLawOptions::default()
    };
    let log = press_log(&args.out);
    let started = Instant::now();
    let refine_above_mm = args.refine_above_mm.unwrap_or(DEFAULT_REFINE_ABOVE_MM);
    if !(refine_above_mm.is_finite() && refine_above_mm >= 0.0) {
        bail!("--refine-above-mm {refine_above_mm}: expected a length of at least 0");
    }
    let refine = (!args.no_refine && !args.no_edges).then_some(refine_above_mm);
    let pool = press_pool(args.jobs, &organ, options.element)?;
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let cover = args
        .cover
        .as_deref()
        .map(|v| triples("--cover", v))
        .transpose()?;
    let (law, resumed) = pool
        .install(|| match &cover {
            None => SurfaceLaw::build_logged(&organ, options, refine, Some(&log), &progress),
            Some(points) => {
                SurfaceLaw::build_covering(&organ, options, refine, points, Some(&log), &progress)
            }
        })
        .context("pressing the palpable vertices")?;
    eprintln!();
    let mut reasons = std::collections::BTreeMap::<&str, usize>::new();
    for r in law
        .skip_reasons
        .iter()
        .chain(&law.edge_skip_reasons)
        .chain(&law.refine_skip_reasons)
    {
        // The reason without its figures (after " ("), so like skips count together.
        let kind = r.split(" (").next().unwrap_or(r);
        *reasons.entry(kind).or_default() += 1;
    }
    // Presses that found no equilibrium before the grid's end: how many, and the
    // shallowest depth any reached (the vademecum answers each probe to the least
    // reach of the presses it blends).
    let (stopped_short, shallowest) =
        reach_figures(&law.reach, law.steps() as u32, options.depth_step_mm);
    let bits = ShapeBits::from_count(args.bits).context("--bits: expected 8 or 16")?;
    let grouping = if args.separate_modes {
        Grouping::Sample
    } else {
        Grouping::SplitTriangle
    };
    let tissue = TissueLaw::compress_grouped(&organ, &law, args.tolerance_mm, bits, grouping)?;
    tissue.save(&args.out)?;
    let _ = std::fs::remove_file(&log);
    let summary = json!({"out": args.out, "law": options.law.name(), "element": options.element.name(),
            "samples": tissue.samples_mm.len(), "edges": tissue.edge_ends.len(),
            "edges_skipped": law.edge_skip_reasons.len(), "skipped": tissue.skipped_mm.len(),
            "refine_above_mm": refine, "split_triangles": law.refinement.triangles.len(),
            "quarter_points": law.refinement.quarter_ends.len(),
            "inner_points": law.refinement.inner_corners.len(),
            "refine_skipped": law.refine_skip_reasons.len(),
            "split": law.split_figures.iter().map(|(edge, points)| json!({"edge_surplus_mm": edge, "quarter_surplus_mm": points})).collect::<Vec<_>>(),
            "skip_reasons": reasons,
            "stopped_short": stopped_short, "shallowest_reach_mm": shallowest,
            "rows": tissue.rows_mm.len(), "depth_max_mm": tissue.depth_max_mm(),
            "bits": tissue.shape.bits().count(),
            "rank": tissue.rank, "truncation_bound_mm": tissue.truncation_bound_mm,
            "modes": tissue.mode_start.last(), "mode_groups": tissue.mode_start.len() - 1,
            "uncompressed_bytes": law.bytes(), "payload_bytes": tissue.payload_bytes(),
            "file_bytes": std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0),
            "build_s": tissue.build_s, "resumed_presses": resumed, "compress_s": tissue.compress_s,
            "worst_correction_mm": tissue.correction_mm.iter().copied().fold(0.0f32, f32::max),
            "most_segments": tissue.segments.iter().copied().max()});
    Ok((tissue, summary))
}

/// A tissue file loaded and bound to the scene it serves (`liver` or a `.palpa` file).
pub(super) fn bound_to_scene(
    file: &std::path::Path,
    scene: &str,
) -> anyhow::Result<(BoundTissue, palpa_core::scene::PalpationScene)> {
    let law = TissueLaw::load(file)?;
    let scene = palpa_app::scenes::load(scene)?.scene;
    law.check_linear_model(&scene.model().provenance().mesh)?;
    let bound = BoundTissue::bind(
        law,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )?;
    Ok((bound, scene))
}

fn check(args: &CheckArgs) -> anyhow::Result<()> {
    // A check compares forces relative to Newton's: a press must push.
    if let Some(d) = args.depths.iter().find(|d| !(d.is_finite() && **d > 0.0)) {
        bail!("--depths: {d:?} mm: expected finite depths above 0 mm (presses into the tissue)");
    }
    // The same press twice is the same Newton solve twice (minutes on medium).
    if let Some(w) = args
        .depths
        .iter()
        .enumerate()
        .find(|(i, d)| args.depths[..*i].contains(d))
    {
        bail!(
            "--depths: {:?} mm given twice: expected distinct depths",
            w.1
        );
    }
    if args.at.is_none() && args.heldout == 0 {
        bail!("--heldout 0: expected at least one point (or points given by --at)");
    }
    let (bound, scene) = bound_to_scene(&args.tissue, &args.scene)?;
    let o = bound.law.options;
    // Past its deepest depth the vademecum holds and flags; a check a little beyond
    // shows that, but Newton far beyond would push the tool through the organ.
    let deepest_check_mm = 2.0 * o.depth_max_mm;
    if let Some(d) = args.depths.iter().find(|d| **d > deepest_check_mm) {
        bail!(
            "--depths: {d:?} mm: expected depths up to {deepest_check_mm} mm, twice the \
             vademecum's deepest ({} mm)",
            o.depth_max_mm
        );
    }
    let organ = args.organ.mesh()?;
    bound.law.check_organ(&organ.mesh.vertices)?;
    let law = &bound.law;
    let mut scratch = bound.scratch();
    let mut contact_scratch = scene.contact_scratch();
    let mut coeffs = vec![0.0; scene.modes()];
    let rows = 3 * scene.vertices_mm().len();
    let (mut linear_rows, mut tissue_rows) = (vec![0.0; rows], vec![0.0; rows]);
    // The scene's render vertex of each organ vertex (by rest position).
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let (mut worst_force, mut worst_surface) = (0.0f64, 0.0f64);
    // Presses Newton answered: with none, no goal is met or missed.
    let mut compared = 0usize;
    // Presses deeper than the vademecum answers at their point (a press of its blend
    // found no equilibrium deeper): reported, not compared.
    let mut past_limit = 0usize;
    // Of the compared presses: those the panel warns at (finest surplus above
    // BLEND_SURPLUS_WARN_MM, or a corner never pressed), and those missing 0.5 mm
    // with and without a warning.
    let (mut warned, mut missed_warned, mut missed_unwarned) = (0usize, 0usize, 0usize);
    let space = organ_space(&organ, o.element);
    let expander = if args.series || args.own {
        Some(Expander::new(&space, o.law, o.material)?)
    } else {
        None
    };
    let mut against = match &args.against {
        Some(file) => Some(Against::open(file, &args.scene, &bound)?),
        None => None,
    };
    let points = press_points(&organ, law, args.at.as_deref(), args.heldout, args.seed)?;
    // Points on the fixed region (a palpable triangle whose corners are all held):
    // nothing there moves, so there is no press to compare.
    let mut held_points = 0usize;
    for at in points {
        let (point, _) = scene
            .closest_palpable(at)
            .context("the scene has no palpable surface")?;
        let contact = match scene.contact(&point, scene.modes(), &mut contact_scratch) {
            Ok(c) => c,
            Err(e @ palpa_core::scene::ContactError::Held { .. }) => {
                println!("{}", json!({"at": at, "held": e.to_string()}));
                held_points += 1;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let c = contact.compliance_mm_per_n;
        // The method at this very point: (name, press) for each tangent.
        let mut own = Vec::new();
        if let Some(expander) = &expander {
            for (name, tangent) in [
                ("shared", SplitTangent::Shared),
                ("exact", SplitTangent::Exact),
            ] {
                let t = Instant::now();
                let press = press_at(&space, &organ, expander, &o, at, contact.push_dir, tangent)?;
                own.push((name, press, t.elapsed().as_secs_f64()));
            }
        }
        let followed = match (&expander, args.own) {
            (Some(expander), true) => {
                let t = Instant::now();
                let p = follow_at(
                    &space,
                    &organ,
                    expander,
                    &o,
                    at,
                    contact.push_dir,
                    &args.depths,
                )?;
                Some((p, t.elapsed().as_secs_f64()))
            }
            _ => None,
        };
        for &depth in &args.depths {
            let t = Instant::now();
            let reference = solve_hyperelastic(
                &organ,
                o.element,
                o.material,
                o.law,
                // Along the scene's push (the interpolated vertex normal), as the app
                // presses.
                &ProbeRequest {
                    at,
                    force_n: f64::NAN,
                    dir: Some(contact.push_dir),
                    radius_mm: o.tool_radius_mm,
                },
                Some(depth),
                NewtonSettings::default(),
            );
            let newton_s = t.elapsed().as_secs_f64();
            let mut row = json!({"at": at, "depth_mm": depth, "newton_s": newton_s});
            let (limit, stopped) = bound.limit_mm(&point);
            if depth > limit {
                row["vademecum_limit_mm"] = json!(limit);
                row["vademecum_stopped"] = json!(stopped);
            }
            let (sol, _) = match reference {
                Ok(r) => r,
                Err(e) => {
                    row["newton_error"] = json!(e.to_string());
                    past_limit += usize::from(depth > limit);
                    println!("{row}");
                    continue;
                }
            };
            let t = Instant::now();
            let (force, beyond) = bound.force_n(&point, depth, c);
            let force_us = t.elapsed().as_secs_f64() * 1e6;
            let push = contact.push_dir.map(|d| d * depth / c);
            scene.displacement(&point, push, &mut coeffs, &mut linear_rows)?;
            tissue_rows.copy_from_slice(&linear_rows);
            let t = Instant::now();
            bound.add_surface(&point, depth, &mut scratch, &mut tissue_rows);
            let surface_us = t.elapsed().as_secs_f64() * 1e6;
            let ([e_tissue, e_linear], top) =
                max_node_errors(&organ, &vertex_of, &sol.u, [&tissue_rows, &linear_rows]);
            let f_ref = sol.force_n;
            let force_err = (force - f_ref).abs() / f_ref;
            let surplus = bound.blend_surplus_mm(&point, depth);
            if depth > limit {
                past_limit += 1;
            } else {
                worst_force = worst_force.max(force_err);
                worst_surface = worst_surface.max(e_tissue);
                compared += 1;
                // The panel warns where the surplus is large and next to the fixed
                // region (a corner never pressed).
                let warn = surplus.is_some_and(|e| e > BLEND_SURPLUS_WARN_MM)
                    || bound.unpressed_corners(&point) > 0;
                warned += usize::from(warn);
                if e_tissue > 0.5 {
                    *(if warn {
                        &mut missed_warned
                    } else {
                        &mut missed_unwarned
                    }) += 1;
                }
            }
            row["force_n"] = json!(force);
            row["reference_force_n"] = json!(f_ref);
            row["force_rel_error"] = json!(force_err);
            row["linear_force_rel_error"] = json!((depth / c - f_ref).abs() / f_ref);
            row["surface_max_error_mm"] = json!(e_tissue);
            row["linear_surface_max_error_mm"] = json!(e_linear);
            row["max_displacement_mm"] = json!(top);
            row["beyond"] = json!(beyond);
            // The finest surplus here: where the blend is likely to miss.
            row["blend_surplus_mm"] = json!(surplus);
            row["unpressed_corners"] = json!(bound.unpressed_corners(&point));
            for (name, press, seconds) in &own {
                let key = format!("series_{name}");
                row[&key] = match press {
                    Err(why) => json!({"skipped": why}),
                    Ok(p) => {
                        let (press, change) = (&p.press, p.pade_change);
                        let (f, u) = press.evaluate(depth, o.depth_max_mm);
                        let e = organ
                            .surface_nodes()
                            .iter()
                            .map(|&v| {
                                (0..3)
                                    .map(|k| {
                                        (u[3 * v as usize + k] - sol.u[3 * v as usize + k]).powi(2)
                                    })
                                    .sum::<f64>()
                                    .sqrt()
                            })
                            .fold(0.0, f64::max);
                        json!({"force_rel_error": (f - f_ref).abs() / f_ref,
                            "surface_max_error_mm": e, "split_mm": press.split_mm,
                            "pade_change": change, "expand_s": seconds,
                            "correction_rel": press.correction_rel,
                            "residual_rel": p.residual_rel(&space, &o, o.depth_max_mm)})
                    }
                };
            }
            if let Some((p, seconds)) = &followed {
                row["own"] = match p {
                    Err(why) => json!({"skipped": why}),
                    Ok((p, depths)) => match depths.iter().position(|&d| d == depth) {
                        None => json!({"skipped": "past the grid's largest depth"}),
                        Some(j) if j >= p.u.len() => {
                            json!({"skipped": p.stopped.as_deref().unwrap_or("stopped")})
                        }
                        Some(j) => {
                            let (mut own, mut blend) = (0.0f64, 0.0f64);
                            for v in organ.surface_nodes() {
                                let i = 3 * v as usize;
                                let Some(r) = vertex_of.find(organ.mesh.vertices[v as usize])
                                else {
                                    continue;
                                };
                                let (mut a, mut b) = (0.0, 0.0);
                                for k in 0..3 {
                                    a += (p.u[j][i + k] - sol.u[i + k]).powi(2);
                                    b += (tissue_rows[3 * r as usize + k] - p.u[j][i + k]).powi(2);
                                }
                                own = own.max(a.sqrt());
                                blend = blend.max(b.sqrt());
                            }
                            json!({"force_rel_error": (p.force_n[j] - f_ref).abs() / f_ref,
                                "surface_max_error_mm": own,
                                "blend_surface_max_mm": blend,
                                "blend_force_rel": (force - p.force_n[j]).abs() / p.force_n[j],
                                "segments": p.segment_starts_mm.len(), "follow_s": seconds})
                        }
                    },
                };
            }
            row["worst_node"] = worst_node(
                &organ,
                &vertex_of,
                &sol.u,
                &tissue_rows,
                at,
                contact.push_dir,
                o.tool_radius_mm,
            );
            row["force_eval_us"] = json!(force_us);
            row["surface_eval_us"] = json!(surface_us);
            if let Some(other) = against.as_mut() {
                let main = Answer {
                    point: &point,
                    depth_mm: depth,
                    compliance_mm_per_n: c,
                    linear_rows: &linear_rows,
                    tissue_rows: &tissue_rows,
                    force_n: force,
                };
                row["against"] = other.press(&organ, &vertex_of, &sol.u, f_ref, &main);
            }
            println!("{row}");
        }
    }
    println!(
        "{}",
        json!({"summary": true, "law": o.law.name(), "element": o.element.name(),
            "presses_compared": compared, "presses_past_limit": past_limit,
            "points_held": held_points,
            "worst_force_rel_error": worst_force, "worst_surface_max_error_mm": worst_surface,
            "goal_force_5_percent": (compared > 0).then_some(worst_force <= 0.05),
            "goal_surface_0_5_mm": (compared > 0).then_some(worst_surface <= 0.5),
            "blend_surplus_warn_mm": BLEND_SURPLUS_WARN_MM, "presses_warned": warned,
            "surface_misses_warned": missed_warned,
            "surface_misses_unwarned": missed_unwarned,
            "against": against.as_ref().map(Against::summary)})
    );
    Ok(())
}

/// The points a check presses at: `at` (X,Y,Z triples) where given, else `heldout`
/// seeded random points inside organ triangles whose three corners were pressed
/// (never a sample itself).
pub(super) fn press_points(
    organ: &OrganMesh,
    law: &TissueLaw,
    at: Option<&[f64]>,
    heldout: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    if let Some(v) = at {
        return triples("--at", v);
    }
    let pressed = PointIndex::new(law.samples_mm.iter().map(|p| p.map(f64::from)));
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| {
            organ.palpable[f]
                && organ.boundary[f]
                    .iter()
                    .all(|&v| pressed.find(organ.mesh.vertices[v as usize]).is_some())
        })
        .collect();
    if faces.is_empty() {
        bail!("no palpable triangle of this organ has all three corners pressed in the file");
    }
    points_in(organ, &faces, heldout, seed)
}

/// `n` seeded random points in `faces`: a face drawn uniformly, then a point uniformly
/// inside it.
fn points_in(
    organ: &OrganMesh,
    faces: &[usize],
    n: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    check_heldout(n)?;
    let mut rng = Rng::seed(seed);
    Ok((0..n)
        .map(|_| super::bench_fe::heldout_point(organ, faces, &mut rng).0)
        .collect())
}

/// The most held-out points a command draws. Each is checked with a full FE solve
/// (seconds to minutes), so more is no run anyone waits for; 10⁹ points would need
/// 24 GB for the points alone (`tissue points` was still drawing them after 30 s).
pub(super) const MAX_HELDOUT: usize = 10_000;

/// Refuses more held-out points than [`MAX_HELDOUT`].
pub(super) fn check_heldout(n: usize) -> anyhow::Result<()> {
    if n > MAX_HELDOUT {
        bail!("{n} held-out points: expected at most {MAX_HELDOUT} (each is a full FE solve)");
    }
    Ok(())
}

/// A flag's `X,Y,Z[,X,Y,Z…]` list as points, or what was wrong with it.
pub(super) fn triples(flag: &str, v: &[f64]) -> anyhow::Result<Vec<[f64; 3]>> {
    use super::args::{COORDINATE_MAX, coordinate_ok};
    if v.is_empty() || !v.len().is_multiple_of(3) || !v.iter().all(|&x| coordinate_ok(x)) {
        bail!(
            "{flag}: expected X,Y,Z triples of finite numbers of magnitude at most \
             {COORDINATE_MAX:e}, got {v:?}"
        );
    }
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// `n` seeded random points over the whole palpable surface: a triangle drawn
/// uniformly among the palpable ones with no fixed corner (those a whole build
/// presses), then a point uniformly inside it.
pub(super) fn surface_points(
    organ: &OrganMesh,
    n: usize,
    seed: u64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| organ.palpable[f] && !touches_fixed(organ, f))
        .collect();
    if faces.is_empty() {
        bail!("this organ has no palpable triangle clear of its fixed region");
    }
    points_in(organ, &faces, n, seed)
}

/// The palpable boundary faces with at least one fixed corner: the band along the
/// fixed region, where a probe's blend has a corner that was never pressed.
fn faces_next_to_fixed(organ: &OrganMesh) -> Vec<usize> {
    (0..organ.boundary.len())
        .filter(|&f| organ.palpable[f] && touches_fixed(organ, f))
        .collect()
}

/// Whether boundary face `f` has a corner on the fixed region.
fn touches_fixed(organ: &OrganMesh, f: usize) -> bool {
    organ.boundary[f].iter().any(|&v| organ.fixed[v as usize])
}

/// The total area of some boundary faces (mm²).
fn faces_area(organ: &OrganMesh, faces: &[usize]) -> f64 {
    let v = |i: u32| glam::DVec3::from_array(organ.mesh.vertices[i as usize]);
    faces
        .iter()
        .map(|&f| {
            let [a, b, c] = organ.boundary[f];
            0.5 * (v(b) - v(a)).cross(v(c) - v(a)).length()
        })
        .sum()
}

/// The organ's boundary faces that a tissue file split (by its corners' rest
/// positions), or why there are none.
fn split_faces(organ: &OrganMesh, law: &TissueLaw) -> anyhow::Result<Vec<usize>> {
    let index = PointIndex::new(organ.mesh.vertices.iter().copied());
    let mut split: Vec<[u32; 3]> = Vec::new();
    for tri in &law.refinement.triangles {
        let mut corners = [0u32; 3];
        for (c, &s) in corners.iter_mut().zip(tri) {
            let at = law.samples_mm[s as usize].map(f64::from);
            *c = index
                .find(at)
                .with_context(|| format!("sample at {at:?} is not a vertex of this organ mesh"))?;
        }
        corners.sort_unstable();
        split.push(corners);
    }
    split.sort_unstable();
    let faces: Vec<usize> = (0..organ.boundary.len())
        .filter(|&f| {
            let mut c = organ.boundary[f];
            c.sort_unstable();
            split.binary_search(&c).is_ok()
        })
        .collect();
    if faces.is_empty() {
        bail!("the tissue file splits no triangle of this organ mesh");
    }
    Ok(faces)
}

/// Over the organ's surface nodes drawn by the scene (`vertex_of`: a node's render
/// vertex by rest position): each candidate's largest nodal distance from the
/// reference field `reference` (organ node order; candidates in the scene's row
/// order), and the reference's largest displacement (mm).
pub(super) fn max_node_errors<const N: usize>(
    organ: &OrganMesh,
    vertex_of: &PointIndex,
    reference: &[f64],
    candidates: [&[f64]; N],
) -> ([f64; N], f64) {
    let (mut worst, mut top) = ([0.0f64; N], 0.0f64);
    for v in organ.surface_nodes() {
        let Some(r) = vertex_of.find(organ.mesh.vertices[v as usize]) else {
            continue;
        };
        let (i, r) = (3 * v as usize, 3 * r as usize);
        let dist = |rows: &[f64]| {
            (0..3)
                .map(|k| (rows[r + k] - reference[i + k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        for (w, rows) in worst.iter_mut().zip(candidates) {
            *w = w.max(dist(rows));
        }
        top = top.max((0..3).map(|k| reference[i + k].powi(2)).sum::<f64>().sqrt());
    }
    (worst, top)
}

/// Where the vademecum's surface errs most at one press, and how the error falls off
/// away from the tool: the worst node's distance from the probe and the part of its
/// error along the push (a depth error) against the rest (tissue sliding sideways
/// under the tool), and the largest error in shells 0–1, 1–2, 2–4, 4–8 and past 8 tool
/// radii from the probe.
fn worst_node(
    organ: &OrganMesh,
    vertex_of: &PointIndex,
    reference: &[f64],
    rows: &[f64],
    at: [f64; 3],
    push: [f64; 3],
    tool_radius_mm: f64,
) -> serde_json::Value {
    const RINGS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];
    let mut ring_max = [0.0f64; RINGS.len() + 1];
    let (mut worst, mut from_probe, mut along) = (0.0f64, 0.0, 0.0);
    for v in organ.surface_nodes() {
        let x = organ.mesh.vertices[v as usize];
        let Some(r) = vertex_of.find(x) else {
            continue;
        };
        let (i, r) = (3 * v as usize, 3 * r as usize);
        let e = [0, 1, 2].map(|k| rows[r + k] - reference[i + k]);
        let size = e.iter().map(|c| c * c).sum::<f64>().sqrt();
        let dist = (0..3).map(|k| (x[k] - at[k]).powi(2)).sum::<f64>().sqrt();
        let ring = RINGS
            .iter()
            .position(|&m| dist <= m * tool_radius_mm)
            .unwrap_or(RINGS.len());
        ring_max[ring] = ring_max[ring].max(size);
        if size > worst {
            worst = size;
            from_probe = dist;
            along = (0..3).map(|k| e[k] * push[k]).sum();
        }
    }
    json!({"error_mm": worst, "from_probe_mm": from_probe, "along_push_mm": along,
        "max_error_mm_by_tool_radii": {"0-1": ring_max[0], "1-2": ring_max[1],
            "2-4": ring_max[2], "4-8": ring_max[3], "8-": ring_max[4]}})
}

/// `palpa eval` on a tissue file: the press at the palpable point closest to `--at`,
/// through the scene the file serves, depth in (force out) or force in (depth out),
/// with the same keys as `palpa fe solve`. The vademecum presses along the surface's
/// vertex normal (each vertex was pressed along its own), so `--dir` is refused.
pub fn eval(
    file: &std::path::Path,
    probe: &super::args::ProbeArgs,
    scene: &str,
    out: Option<&std::path::Path>,
    json_out: bool,
) -> anyhow::Result<()> {
    if probe.dir.is_some() {
        bail!(
            "--dir: a tissue vademecum presses along the surface normal, the direction its \
             vertices were pressed in; leave --dir out"
        );
    }
    let at = probe.at()?;
    probe.check_press()?;
    let (bound, scene) = bound_to_scene(file, scene)?;
    let (point, distance_mm) = scene
        .closest_palpable(at)
        .context("the scene has no palpable surface")?;
    let mut contact_scratch = scene.contact_scratch();
    let contact = scene.contact(&point, scene.modes(), &mut contact_scratch)?;
    let c = contact.compliance_mm_per_n;
    let t = Instant::now();
    let (depth, force, beyond) = match (probe.depth_mm, probe.force_n) {
        (Some(d), _) => {
            // Past the limit both the force and the surface are held at it.
            let (f, beyond) = bound.force_n(&point, d, c);
            (d.min(bound.limit_mm(&point).0), f, beyond)
        }
        (None, Some(f)) => {
            let (d, beyond) = bound.depth_mm(&point, f, c);
            // Held at the limit, the press is the one there: its force, not the one
            // asked for (that is `requested_force_n`).
            let f = if beyond {
                bound.force_n(&point, d, c).0
            } else {
                f
            };
            (d, f, beyond)
        }
        (None, None) => bail!("give --depth-mm or --force-n"),
    };
    let force_eval_us = t.elapsed().as_secs_f64() * 1e6;
    let mut coeffs = vec![0.0; scene.modes()];
    let mut rows = vec![0.0; 3 * scene.vertices_mm().len()];
    let mut scratch = bound.scratch();
    let t = Instant::now();
    let push = contact.push_dir.map(|d| d * depth / c);
    scene.displacement(&point, push, &mut coeffs, &mut rows)?;
    bound.add_surface(&point, depth, &mut scratch, &mut rows);
    let surface_eval_us = t.elapsed().as_secs_f64() * 1e6;
    let max = rows
        .chunks_exact(3)
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .fold(0.0, f64::max);
    if let Some(out) = out {
        use palpa_core::export::{FieldValue, PointField, write_surface_vtu};
        let nodes: Vec<[f64; 3]> = scene
            .vertices_mm()
            .iter()
            .map(|p| p.map(f64::from))
            .collect();
        let fields = [PointField {
            name: "displacement".into(),
            components: 3,
            values: rows.clone(),
        }];
        let meta = [
            FieldValue {
                name: "force_n".into(),
                value: force,
            },
            FieldValue {
                name: "depth_mm".into(),
                value: depth,
            },
        ];
        write_surface_vtu(out, &nodes, scene.triangles(), &fields, &meta)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    let unpressed = bound.unpressed_corners(&point);
    if unpressed > 0 {
        eprintln!(
            "warning: {}",
            palpa_app::session::next_to_fixed_text(unpressed)
        );
    }
    let report = json!({
        "model": "tissue", "law": bound.law.options.law.name(),
        "element": bound.law.options.element.name(),
        "at": scene.frame(&point).0, "projected_distance_mm": distance_mm,
        // The keys of `palpa fe solve`, which presses along the same direction by default.
        "probe_point": scene.frame(&point).0, "direction": contact.push_dir,
        "probe_displacement_mm": depth, "force_n": force, "linear_force_n": depth / c,
        "requested_force_n": probe.force_n,
        "max_displacement_mm": max, "depth_max_mm": bound.law.depth_max_mm(),
        "beyond_depth_max": beyond,
        "depth_limit_mm": bound.limit_mm(&point).0, "stopped": bound.limit_mm(&point).1,
        "blend_surplus_mm": bound.blend_surplus_mm(&point, depth),
        "unpressed_corners": unpressed,
        "force_eval_us": force_eval_us, "surface_eval_us": surface_eval_us,
    });
    super::args::print_report(&report, json_out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_durations_read_as_a_person_would_say_them() {
        assert_eq!(minutes(0.4), "0 s");
        assert_eq!(minutes(59.4), "59 s");
        assert_eq!(minutes(61.0), "1 min");
        assert_eq!(minutes(3599.0), "59 min");
        assert_eq!(minutes(3600.0 * 3.0 + 5.0 * 60.0 + 20.0), "3 h 05 min");
        assert_eq!(minutes(f64::NAN), "0 s");
    }

    #[test]
    fn the_time_left_counts_computed_presses_only() {
        let at = |done, total, from_log| PressCount {
            done,
            total,
            from_log,
        };
        // Nothing computed yet: no estimate.
        assert_eq!(time_left(at(3129, 8191, 3129), 60.0), "");
        // 200 computed in 14 min: 4.2 s each, 4 862 to go.
        assert_eq!(
            time_left(at(3329, 8191, 3129), 840.0),
            ", about 5 h 40 min left"
        );
        // A fresh build: every done press computed.
        assert_eq!(time_left(at(100, 400, 0), 100.0), ", about 5 min left");
        assert_eq!(time_left(at(400, 400, 0), 400.0), ", about 0 s left");
    }

    #[test]
    fn bits_are_eight_or_sixteen() {
        assert_eq!(parse_bits("8"), Ok(8));
        assert_eq!(parse_bits("16"), Ok(16));
        let e = parse_bits("12").expect_err("12 bits");
        assert!(e.contains("8 or 16"), "{e}");
    }

    /// Medium P2's estimate (6.2 GB shared, 8.3 GB a press): two at once on this
    /// 24 GB machine when idle (23.3 GB available), one under a compile's load; none
    /// fits in 12 GB, which the caller turns into one press and a warning.
    #[test]
    fn presses_at_once_are_what_the_memory_holds() {
        let gb = |x: f64| (x * 1e9) as u64;
        assert_eq!(jobs_that_fit(gb(23.3), gb(6.2), gb(8.3)), 2);
        assert_eq!(jobs_that_fit(gb(15.3), gb(6.2), gb(8.3)), 1);
        assert_eq!(jobs_that_fit(gb(12.0), gb(6.2), gb(8.3)), 0);
        assert_eq!(jobs_that_fit(gb(4.0), gb(6.2), gb(8.3)), 0);
        assert_eq!(jobs_that_fit(gb(100.0), 0, 0), 100_000_000_000);
    }
}
