//! `palpa tissue build`: the hyperelastic vademecum of a palpation scene (see
//! `palpa_core::tissue::law`) built off-line from every palpable vertex's depth
//! series, and what the staging tools share (the press log, the pool, the progress
//! line, the file's summary).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::fe::path::{StopKind, press_memory_bytes};
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::law::{DEFAULT_BITS, DEFAULT_TOLERANCE_MM, Grouping, ShapeBits, TissueLaw};
use palpa_core::tissue::options::SurfaceLawBuildError;
use palpa_core::tissue::presser::{PressLog, Shard, ShardRun};
use palpa_core::tissue::recipe::{Recipe, Stage};
use palpa_core::tissue::surface::{
    DEFAULT_REFINE_ABOVE_MM, MAX_GRID_POINTS, PressCount, SurfaceLaw, SurfaceLawOptions,
};
use serde_json::json;

use super::points::triples;
use crate::cli::args::{NonlinearModel, OrganArgs};

#[derive(Debug, Args)]
pub struct BuildArgs {
    #[command(flatten)]
    pub organ: OrganArgs,
    /// What is pressed, stage by stage: `default` (every palpable vertex and edge
    /// midpoint, the triangles whose edge surplus exceeds --refine-above-mm split in the
    /// same pass, then the band next to the fixed region), `shipped` (what made the
    /// shipped liver tissue: the worst triangles split in six stages, 190 of their
    /// sub-triangles again, then the band; hours on coarse), `quick` (the vertices only,
    /// a linear blend between them: a first look in a third of the presses).
    #[arg(long, default_value = "default", value_parser = parse_recipe)]
    pub recipe: String,
    /// Leave out the band next to the fixed region (the recipe's last stage).
    #[arg(long)]
    pub no_band: bool,
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
    /// them. There the file answers as a whole-surface build does (see `lab tissue points`).
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
    /// Press only shard I of N (I from 1): every step's presses dealt to the N shards
    /// in turn, this one's logged in `OUT.shard-I-of-N.log` (a stage's in
    /// `OUT.stage-K.shard-I-of-N.log`). It stops where a step needs the other shards'
    /// presses; `palpa tissue merge` then gathers them and either writes OUT (the same
    /// payload as one unsharded build) or says the shards are to run again for the next
    /// step. Run again after a kill, a shard goes on from its log.
    #[arg(long, value_parser = crate::cli::args::parse_shard)]
    pub shard: Option<Shard>,
    /// Press nothing: count the recipe's presses, measure a few presses and a shard's
    /// setup here, and print the predicted wall time on each of --plan-cores cores.
    #[arg(long)]
    pub plan: bool,
    /// Points whose presses --plan measures (each with its triangle's corners and
    /// edges, spread over the build's candidates, on every core here).
    #[arg(long, default_value_t = 4)]
    pub plan_presses: usize,
    /// Core counts --plan predicts for.
    #[arg(long, value_delimiter = ',', default_values_t = [2, 16, 64, 256])]
    pub plan_cores: Vec<usize>,
    /// With --plan, JSON instead of the table (a build always prints JSON).
    #[arg(long)]
    pub json: bool,
    #[arg(long)]
    pub out: PathBuf,
}

/// A duration for a progress line: `42 s`, `17 min`, `3 h 05 min`.
pub(super) fn minutes(seconds: f64) -> String {
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

/// `--recipe`: one of the named recipes.
fn parse_recipe(s: &str) -> Result<String, String> {
    match Recipe::named(s) {
        Some(_) => Ok(s.to_string()),
        None => Err(format!(
            "{s}: expected one of {} (the stages a build runs)",
            palpa_core::tissue::recipe::NAMES.join(", ")
        )),
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

/// The press log beside a build's output: an interrupted build run again with the same
/// arguments goes on from the last finished press.
pub fn press_log(out: &Path) -> PathBuf {
    let mut log = out.as_os_str().to_owned();
    log.push(".presses.log");
    PathBuf::from(log)
}

/// The threads a build presses on: `--jobs`, else one per core, fewer where the memory
/// available would not hold them ([`default_jobs`]).
pub fn press_pool(
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
    let Some(available) = crate::cli::memory::available_bytes() else {
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
pub fn progress_line(c: PressCount, elapsed_s: f64) {
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
pub(super) fn goals_json(goals: Option<palpa_app::session::GoalDepths>) -> serde_json::Value {
    let tenths = |mm: f32| (f64::from(mm) * 10.0).round() / 10.0;
    json!(goals.map(|g| json!({"both": tenths(g.both_mm), "force": tenths(g.force_mm)})))
}

/// What a tissue file holds: its samples, how far its presses reach, its bytes and
/// bound (`palpa info X.tissue`, `palpa lab tissue cut`).
pub fn summary(law: &TissueLaw, path: &Path) -> serde_json::Value {
    let o = &law.options;
    let (stopped_short, shallowest) = reach_figures(&law.reach, law.steps, o.depth_step_mm);
    let vertices = law.samples_mm.len();
    let modes = law.mode_start.last().copied().unwrap_or(0);
    json!({
        "file": path, "kind": "tissue",
        "law": o.law.name(), "element": o.element.name(),
        "young_kpa": o.material.young_kpa, "poisson": o.material.poisson,
        // The mesh the presses were made on, as a scene's provenance names it.
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
        "payload_xxh3": format!("{:016x}", law.payload_xxh3()),
        "file_bytes": std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
        "build_s": law.build_s,
        // What `palpa tissue check --record` measured against the full FE.
        "goals_to_mm": goals_json(palpa_app::session::GoalDepths::of(law)),
        "accuracy": accuracy_json(&law.accuracy),
    })
}

/// A tissue file's recorded checks (see `palpa_core::tissue::accuracy::Accuracy`): each run
/// as measured, and every run merged depth by depth, with the goals they judge by.
fn accuracy_json(a: &palpa_core::tissue::accuracy::Accuracy) -> serde_json::Value {
    use palpa_core::tissue::accuracy::{DepthFigures, GOAL_FORCE_REL, GOAL_SURFACE_MM};
    let depth = |d: &DepthFigures| {
        json!({"depth_mm": d.depth_mm, "presses": d.presses, "past_limit": d.past_limit,
            "worst_force_rel_error": d.worst_force_rel,
            "worst_surface_max_error_mm": d.worst_surface_mm})
    };
    let runs: Vec<_> = a
        .runs
        .iter()
        .map(|r| {
            json!({"seed": r.seed, "points": r.points, "held_points": r.held_points,
                "scene": r.scene, "left_out": r.left_out,
                "depths": r.depths.iter().map(depth).collect::<Vec<_>>()})
        })
        .collect();
    json!({
        "goal_surface_mm": GOAL_SURFACE_MM, "goal_force_rel": GOAL_FORCE_REL,
        "points": a.points(), "runs": runs,
        "merged": a.merged().iter().map(depth).collect::<Vec<_>>(),
        "goals_to_mm": a.goals_to_mm().map(|g| json!({"both": g.both_mm, "force": g.force_mm})),
    })
}

/// The recipe the arguments ask for: the named one, its presses' settings from the flags
/// (whose defaults are the recipes'), the first pass's split from `--refine-above-mm`
/// and `--no-refine` (the default recipe's; another names its own), without the band
/// under `--no-band`; refused, naming why, where it cannot run.
pub(super) fn recipe_of(
    args: &BuildArgs,
    within: Option<([f64; 3], f64)>,
) -> anyhow::Result<Recipe> {
    let mut r = Recipe::named(&args.recipe)
        .with_context(|| format!("--recipe {}: not a recipe", args.recipe))?;
    if args.recipe != "default" && (args.refine_above_mm.is_some() || args.no_refine) {
        bail!(
            "--recipe {}: it names its own splits; expected --refine-above-mm and --no-refine \
             with the default recipe only",
            args.recipe
        );
    }
    r.options = SurfaceLawOptions {
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
        edges: r.options.edges && !args.no_edges,
        ..r.options
    };
    if args.recipe == "default" {
        let above = args.refine_above_mm.unwrap_or(DEFAULT_REFINE_ABOVE_MM);
        if !(above.is_finite() && above >= 0.0) {
            bail!("--refine-above-mm {above}: expected a length of at least 0");
        }
        r.split_above_mm = (!args.no_refine && !args.no_edges).then_some(above);
    }
    if args.no_band {
        r.stages.retain(|s| *s != Stage::Band);
    }
    r.tolerance_mm = args.tolerance_mm;
    r.bits = ShapeBits::from_count(args.bits).context("--bits: expected 8 or 16")?;
    r.grouping = if args.separate_modes {
        Grouping::Sample
    } else {
        Grouping::SplitTriangle
    };
    if let Some(why) = r.check() {
        bail!("--recipe {}: {why}", args.recipe);
    }
    Ok(r)
}

/// Shard `shard`'s own log of step `stage` (0: the first pass):
/// `OUT.shard-I-of-N.log`, `OUT.stage-K.shard-I-of-N.log`.
pub fn shard_log(out: &Path, stage: usize, shard: Shard) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    if stage > 0 {
        p.push(format!(".stage-{stage}"));
    }
    p.push(format!(".shard-{}-of-{}.log", shard.index, shard.count));
    PathBuf::from(p)
}

/// The press log of a recipe's stage `k` (from 1; the first pass's is [`press_log`]).
pub(super) fn stage_log(out: &Path, k: usize) -> PathBuf {
    let mut log = out.as_os_str().to_owned();
    log.push(format!(".stage-{k}.presses.log"));
    PathBuf::from(log)
}

/// One stage after the first pass on the compressed file `tissue`: its points pressed
/// (logged at `log`), the file's own samples kept; the new file and what the stage did.
fn run_stage(
    organ: &OrganMesh,
    tissue: &TissueLaw,
    stage: Stage,
    within: Option<([f64; 3], f64)>,
    log: &PressLog,
    progress: &(dyn Fn(PressCount) + Sync),
) -> anyhow::Result<(TissueLaw, serde_json::Value)> {
    let t0 = Instant::now();
    Ok(match stage {
        Stage::Split { triangles } => {
            let law = tissue.surface_law(organ)?;
            let (law, resumed, above) = law.refine(
                organ,
                DEFAULT_REFINE_ABOVE_MM,
                Some(triangles),
                Some(log),
                progress,
            )?;
            let next = tissue.refined(organ, &law)?;
            let report = json!({"stage": "split", "triangles": law.refinement.triangles.len(),
                "candidates": above, "resumed_presses": resumed,
                "refine_skipped": law.refine_skip_reasons.len(), "press_s": t0.elapsed().as_secs_f64()});
            (next, report)
        }
        Stage::SubSplit { sub_triangles } => {
            let (base, mut law, plan) = tissue.second_level_plan(organ, sub_triangles, None)?;
            let (kept, resumed) = law.press_sub_split(organ, &plan, Some(log), progress)?;
            let skipped = kept.iter().filter(|k| k.is_err()).count();
            let next = base.sub_split(organ, law, &plan, &kept)?;
            let report = json!({"stage": "sub-split", "sub_triangles": plan.chosen,
                "presses": plan.presses(), "resumed_presses": resumed, "skipped": skipped,
                "press_s": t0.elapsed().as_secs_f64()});
            (next, report)
        }
        Stage::Band => {
            let law = tissue.surface_law(organ)?;
            let (law, r) = law.press_band(organ, within, Some(log), progress)?;
            // An organ whose palpable region does not reach the fixed one has no band.
            let next = if r.edges == 0 {
                tissue.clone()
            } else {
                tissue.banded(organ, &law)?
            };
            let report = json!({"stage": "band", "band_edges": r.edges, "band_kept": r.kept,
                "band_failed": r.failed, "resumed_presses": r.resumed,
                "press_s": t0.elapsed().as_secs_f64()});
            (next, report)
        }
    })
}

/// Builds, compresses and saves; returns the law and a JSON summary.
pub fn build(args: &BuildArgs) -> anyhow::Result<(TissueLaw, serde_json::Value)> {
    if args.shard.is_some() {
        bail!("--shard: a shard's build runs as `palpa tissue build … --shard I/N`, not here");
    }
    match build_run(args, None)? {
        Built::File(law, summary) => Ok((*law, summary)),
        Built::Waiting(v) => bail!("the build waits for other shards: {v}"),
    }
}

/// `--within X,Y,Z,R` as a ball, checked.
pub(super) fn within_of(args: &BuildArgs) -> anyhow::Result<Option<([f64; 3], f64)>> {
    Ok(match args.within.as_deref() {
        None => None,
        Some(&[x, y, z, r]) if [x, y, z, r].iter().all(|v| v.is_finite()) && r > 0.0 => {
            Some(([x, y, z], r))
        }
        Some(v) => bail!("--within: expected X,Y,Z,R (finite, R > 0), got {v:?}"),
    })
}

/// What a build run ends with: the file written, or a sharded run's step waiting for
/// other shards (what it did and waits for).
pub enum Built {
    File(Box<TissueLaw>, serde_json::Value),
    Waiting(serde_json::Value),
}

/// Where a run's presses of step `stage` (0: the first pass) are logged.
fn press_logs(out: &Path, stage: usize, sharding: Option<&Sharding>) -> PressLog {
    let path = if stage == 0 {
        press_log(out)
    } else {
        stage_log(out, stage)
    };
    let shard = sharding.map(|s| match s {
        Sharding::Shard(shard) => ShardRun::Press {
            shard: *shard,
            own_log: shard_log(out, stage, *shard),
        },
        Sharding::Merge(count) => ShardRun::Merge {
            count: *count,
            logs: (1..=*count)
                .map(|index| {
                    shard_log(
                        out,
                        stage,
                        Shard {
                            index,
                            count: *count,
                        },
                    )
                })
                .collect(),
        },
    });
    PressLog { path, shard }
}

/// How a build runs sharded: as one shard, or as the merge of N.
#[derive(Debug, Clone, Copy)]
pub enum Sharding {
    Shard(Shard),
    Merge(u32),
}

/// A sharded run's step that waits for other shards, as JSON; any other error as it is.
fn waiting(e: anyhow::Error, stage: usize, describe: &str) -> anyhow::Result<serde_json::Value> {
    match e.downcast_ref::<SurfaceLawBuildError>() {
        Some(
            w @ SurfaceLawBuildError::ShardWaiting {
                index,
                count,
                pressed,
                present,
                total,
                waiting,
            },
        ) => Ok(
            json!({"waiting": true, "step": stage + 1, "stage": describe,
            "shard": index, "shards": count, "pressed": pressed, "logged": present,
            "presses": total,
            "waiting_for": waiting.iter().map(|(s, ids)| json!({"shard": s, "presses": ids.len(), "ids": ids})).collect::<Vec<_>>(),
            "message": w.to_string()}),
        ),
        _ => Err(e),
    }
}

/// [`build`], or one shard's run of it, or the merge's (`sharding`).
pub fn build_run(args: &BuildArgs, sharding: Option<Sharding>) -> anyhow::Result<Built> {
    crate::cli::args::check_out(&args.out)?;
    let organ = args.organ.mesh()?;
    let within = within_of(args)?;
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
    let recipe = recipe_of(args, within)?;
    let options = recipe.options;
    let log = press_logs(&args.out, 0, sharding.as_ref());
    let started = Instant::now();
    let refine = recipe.split_above_mm;
    let pool = press_pool(args.jobs, &organ, options.element)?;
    let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
    let cover = args
        .cover
        .as_deref()
        .map(|v| triples("--cover", v))
        .transpose()?;
    let first = pool.install(|| match &cover {
        None => SurfaceLaw::build_logged(&organ, options, refine, Some(&log), &progress),
        Some(points) => {
            SurfaceLaw::build_covering(&organ, options, refine, points, Some(&log), &progress)
        }
    });
    let (law, resumed) = match first {
        Ok(done) => done,
        Err(e) => {
            eprintln!();
            return Ok(Built::Waiting(waiting(
                anyhow::Error::from(e).context("pressing the palpable vertices"),
                0,
                "the first pass: vertices, edges and split triangles' points",
            )?));
        }
    };
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
    let mut tissue = TissueLaw::compress_grouped(
        &organ,
        &law,
        recipe.tolerance_mm,
        recipe.bits,
        recipe.grouping,
    )?;
    let mut stages = Vec::new();
    let mut logs = vec![log.path.clone()];
    for (k, stage) in recipe.stages.iter().enumerate() {
        let log = press_logs(&args.out, k + 1, sharding.as_ref());
        eprintln!(
            "tissue: stage {} of {}: {}",
            k + 2,
            recipe.stages.len() + 1,
            stage.describe()
        );
        let started = Instant::now();
        let progress = |c: PressCount| progress_line(c, started.elapsed().as_secs_f64());
        let ran = pool
            .install(|| run_stage(&organ, &tissue, *stage, options.within, &log, &progress))
            .with_context(|| format!("stage {}: {}", k + 2, stage.describe()));
        eprintln!();
        let (next, report) = match ran {
            Ok(done) => done,
            Err(e) => return Ok(Built::Waiting(waiting(e, k + 1, &stage.describe())?)),
        };
        tissue = next;
        stages.push(report);
        logs.push(log.path.clone());
    }
    tissue.save(&args.out)?;
    for log in &logs {
        let _ = std::fs::remove_file(log);
    }
    let summary = json!({"out": args.out, "recipe": args.recipe, "law": options.law.name(), "element": options.element.name(),
            "samples": tissue.samples_mm.len(), "edges": tissue.edge_ends.len(),
            "edges_skipped": law.edge_skip_reasons.len(), "skipped": tissue.skipped_mm.len(),
            // The file's, after every stage (the first pass's figures are `split`).
            "refine_above_mm": refine, "split_triangles": tissue.refinement.triangles.len(),
            "quarter_points": tissue.refinement.quarter_ends.len(),
            "inner_points": tissue.refinement.inner_corners.len(),
            "sub_triangles_split": tissue.refinement.sub.sub_triangles.len(),
            "band_edges": tissue.refinement.band.len(),
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
            "most_segments": tissue.segments.iter().copied().max(),
            "stages": stages, "payload_xxh3": format!("{:016x}", tissue.payload_xxh3())});
    Ok(Built::File(Box::new(tissue), summary))
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
