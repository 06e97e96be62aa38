//! `palpa tissue …`: the hyperelastic vademecum of a palpation scene (see
//! `palpa_core::pgd::tissue`): build it off-line from every palpable vertex's depth
//! series, cut it, and what the other stages share (the press log, the pool, the
//! progress line, the file's summary). Checking it against the full nonlinear FE is
//! `tissue_check`, drawing held-out points `tissue_points`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use palpa_core::fe::path::{StopKind, press_memory_bytes};
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::pgd::surfacelaw::{
    DEFAULT_REFINE_ABOVE_MM, MAX_GRID_POINTS, PressCount, SurfaceLaw, SurfaceLawOptions,
};
use palpa_core::pgd::tissue::{
    BLEND_SURPLUS_WARN_MM, BoundTissue, DEFAULT_BITS, DEFAULT_TOLERANCE_MM, Grouping, ShapeBits,
    TissueLaw,
};
use serde_json::json;

use super::args::OrganArgs;
use super::depthlaw::NonlinearModel;
use super::tissue_points::triples;

#[derive(Debug, Subcommand)]
pub enum TissueCommand {
    /// Build the nonlinear vademecum off-line: every palpable vertex's press followed
    /// to equilibrium on the depth grid, the surfaces compressed by an SVD; finished
    /// presses are logged in `OUT.presses.log`, so a killed build run again goes on.
    Build(BuildArgs),
    /// Compare a built vademecum with the full nonlinear FE (Newton) at held-out
    /// random points and depths, through a scene (what the app shows).
    Check(super::tissue_check::CheckArgs),
    /// Draw held-out points over the whole palpable surface (seeded) and print them as
    /// `X,Y,Z,…` for `tissue build --cover` and `tissue check --at`: a whole-surface
    /// accuracy table from the few triangles that hold them.
    Points(super::tissue_points::PointsArgs),
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
        TissueCommand::Check(args) => super::tissue_check::check(args),
        TissueCommand::Points(args) => super::tissue_points::points(args),
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

/// The depths a tissue is measured within the goals to, as JSON (null where unknown).
/// They are f32 tenths of a millimetre, printed as the tenths they are.
fn goals_json(goals: Option<palpa_app::session::GoalDepths>) -> serde_json::Value {
    let tenths = |mm: f32| (f64::from(mm) * 10.0).round() / 10.0;
    json!(goals.map(|g| json!({"both": tenths(g.both_mm), "force": tenths(g.force_mm)})))
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
        // The mesh the presses were made on, as a scene's provenance names it
        // (`mesh_xxh3`); null in files before format 14.
        "mesh_xxh3": law.mesh_xxh3.map(|h| format!("{h:016x}")),
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
        // Measured against the full FE to these depths (the built-in tissue's bytes).
        "goals_to_mm": goals_json(palpa_app::scenes::tissue_goals(path)),
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
    super::args::warn_far_from_surface(distance_mm, scene.frame(&point).0);
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
    let (limit_mm, stopped) = bound.limit_mm(&point);
    if beyond {
        let asked = match probe.force_n {
            Some(f) => format!("{f:.2} N"),
            None => format!("{:.2} mm", probe.depth_mm.unwrap_or(depth)),
        };
        eprintln!(
            "warning: {} (asked {asked})",
            palpa_app::session::held_text(limit_mm, stopped)
        );
    }
    let surplus_mm = bound.blend_surplus_mm(&point, depth);
    if let Some(eta) = surplus_mm.filter(|&e| e > BLEND_SURPLUS_WARN_MM) {
        eprintln!("warning: {}", palpa_app::session::blend_surplus_text(eta));
    }
    // Past the depth the file is measured within the goals to, as the panel says it.
    let goals = palpa_app::scenes::tissue_goals(file);
    if let Some(g) = goals.filter(|g| depth > f64::from(g.both_mm)) {
        eprintln!("warning: {}", g.past_text(depth as f32));
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
        "at": scene.frame(&point).0,
        // The keys of `palpa fe solve`, which presses along the same direction by default.
        "probe_point": scene.frame(&point).0, "probe_projection_distance_mm": distance_mm,
        "direction": contact.push_dir,
        "control": if probe.force_n.is_some() { "force" } else { "depth" },
        "probe_displacement_mm": depth, "force_n": force, "linear_force_n": depth / c,
        "requested_force_n": probe.force_n, "requested_depth_mm": probe.depth_mm,
        "max_displacement_mm": max, "depth_max_mm": bound.law.depth_max_mm(),
        "beyond_depth_max": beyond,
        "depth_limit_mm": limit_mm, "stopped": stopped,
        "blend_surplus_mm": surplus_mm,
        "unpressed_corners": unpressed,
        // Measured within the goals to these depths (the built-in tissue), else null.
        "goals_to_mm": goals_json(goals),
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
