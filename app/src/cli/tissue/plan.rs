//! `palpa tissue build … --plan`: what a build would cost on N cores, from presses
//! measured here. Each step's presses are counted from the organ and the recipe (the
//! first pass exactly; a split stage at its upper bound of nine points a triangle; the
//! band's edges exactly), the cost of one press and of a shard's setup (the rest
//! stiffness factored) measured by pressing a few of the organ's own vertices, and a
//! sharded build's wall time predicted as its rounds, each a setup and the step's
//! presses dealt over the cores.

use std::time::Instant;

use anyhow::{Context, bail};
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::series::Expander;
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::recipe::{Recipe, Stage};
use palpa_core::tissue::surface::{PressCount, SurfaceLaw, SurfaceLawOptions};
use serde_json::json;

use super::build::{BuildArgs, minutes};

/// Presses a split triangle adds at most: two quarter points on each edge and three
/// inner points (neighbours that are split too share their edge's quarter points).
const POINTS_PER_SPLIT: usize = 9;

/// The share of palpable triangles the first pass's threshold split is taken to split
/// where nothing better is known: on the coarse liver at 0.35 mm, about 6 000
/// split-point presses after its 2 147 vertex and edge presses (docs/accuracy.md), at
/// most nine a triangle: at least 0.65 of its 1 027 palpable triangles.
const ASSUMED_SPLIT_SHARE: f64 = 0.65;

/// One step of a plan: what it presses and how many.
struct Step {
    what: String,
    presses: usize,
    /// Whether the count is exact (not a bound or an assumption).
    exact: bool,
}

/// The steps of `recipe` on `organ`, with their press counts.
fn steps(organ: &OrganMesh, recipe: &Recipe) -> Vec<Step> {
    let o: &SurfaceLawOptions = &recipe.options;
    let inside = |v: u32| {
        o.within.is_none_or(|(c, r)| {
            let p = organ.mesh.vertices[v as usize];
            (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>() <= r * r
        })
    };
    let mut vertices: Vec<u32> = organ
        .pressable_vertices()
        .into_iter()
        .filter(|&v| inside(v))
        .collect();
    vertices.sort_unstable();
    vertices.dedup();
    let held = |v: &u32| vertices.binary_search(v).is_ok();
    let edges = if o.edges {
        organ
            .palpable_edges()
            .into_iter()
            .filter(|e| e.iter().all(held))
            .count()
    } else {
        0
    };
    let triangles = (0..organ.boundary.len())
        .filter(|&f| organ.palpable[f] && organ.boundary[f].iter().all(held))
        .count();
    let mut out = vec![Step {
        what: "vertices and edge midpoints".into(),
        presses: vertices.len() + edges,
        exact: true,
    }];
    if recipe.split_above_mm.is_some() {
        let split = (ASSUMED_SPLIT_SHARE * triangles as f64).round() as usize;
        out.push(Step {
            what: format!(
                "split points (assumed: {split} of {triangles} triangles, the coarse liver's share)"
            ),
            presses: split * POINTS_PER_SPLIT,
            exact: false,
        });
    }
    let mut split_so_far = 0;
    for stage in &recipe.stages {
        match *stage {
            Stage::Split { triangles: t } => {
                let new = t.min(triangles).saturating_sub(split_so_far);
                split_so_far = split_so_far.max(t.min(triangles));
                out.push(Step {
                    what: format!("{new} more triangles split (at most)"),
                    presses: new * POINTS_PER_SPLIT,
                    exact: false,
                });
            }
            Stage::SubSplit { sub_triangles } => out.push(Step {
                what: format!("{sub_triangles} sub-triangles split again (at most)"),
                presses: sub_triangles * POINTS_PER_SPLIT,
                exact: false,
            }),
            Stage::Band => {
                let fixed = |v: u32| organ.fixed[v as usize];
                let band = organ
                    .palpable_edges()
                    .into_iter()
                    .filter(|e| e.iter().any(|&v| fixed(v)) && e.iter().any(|&v| held(&v)))
                    .count();
                out.push(Step {
                    what: "band edges next to the fixed region".into(),
                    presses: band,
                    exact: true,
                });
            }
        }
    }
    out
}

/// `--plan`: the recipe's presses counted, a few measured, the wall time predicted.
pub fn run(args: &BuildArgs) -> anyhow::Result<serde_json::Value> {
    let organ = args.organ.mesh()?;
    let within = super::build::within_of(args)?;
    let recipe = super::build::recipe_of(args, within)?;
    plan(
        &organ,
        &recipe,
        args.plan_presses,
        &args.plan_cores,
        &format!("{:?}", args.organ.level).to_lowercase(),
    )
}

/// The plan of a build: printed as a table (or JSON); nothing is written.
pub fn plan(
    organ: &OrganMesh,
    recipe: &Recipe,
    samples: usize,
    cores: &[usize],
    level: &str,
) -> anyhow::Result<serde_json::Value> {
    if samples == 0 || cores.is_empty() || cores.contains(&0) {
        bail!("--plan-presses and --plan-cores: expected at least one press and cores ≥ 1");
    }
    let steps = steps(organ, recipe);
    let o = recipe.options;
    // A shard's setup: the space and the rest stiffness factored.
    let t = Instant::now();
    let space = organ_space(organ, o.element);
    Expander::new(&space, o.law, o.material).context("factoring the rest stiffness")?;
    let setup_s = t.elapsed().as_secs_f64();
    drop(space);
    // Presses where this build presses: `samples` of its own candidates spread over
    // them, each with the corners and edges of the triangle it lies on (what a
    // covering build presses), run as a build runs them, every core here busy (as
    // every core of a cluster's node is), so a press's cost includes its neighbours'
    // contention for memory.
    let inside = |v: &u32| {
        o.within.is_none_or(|(c, r)| {
            let p = organ.mesh.vertices[*v as usize];
            (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>() <= r * r
        })
    };
    let mut candidates: Vec<u32> = organ
        .pressable_vertices()
        .into_iter()
        .filter(inside)
        .collect();
    candidates.sort_unstable();
    candidates.dedup();
    if candidates.is_empty() {
        bail!("the recipe presses no vertex here: nothing to plan");
    }
    let points: Vec<[f64; 3]> = (0..samples.min(candidates.len()))
        .map(|k| {
            let v =
                candidates[(2 * k + 1) * candidates.len() / (2 * samples.min(candidates.len()))];
            organ.mesh.vertices[v as usize]
        })
        .collect();
    let here = rayon::current_num_threads().max(1);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let t = Instant::now();
    let count = |c: PressCount| {
        done.fetch_max(c.done, std::sync::atomic::Ordering::Relaxed);
    };
    SurfaceLaw::build_covering(
        organ,
        SurfaceLawOptions { within: None, ..o },
        None,
        &points,
        None,
        &count,
    )
    .context("pressing the sample points")?;
    let pressed = done.into_inner();
    // Core-seconds a press: the run's wall time less its setup, over the presses each
    // core made.
    let per_press =
        (t.elapsed().as_secs_f64() - setup_s).max(0.0) * here as f64 / pressed.max(1) as f64;
    let total: usize = steps.iter().map(|s| s.presses).sum();
    let predict = |n: usize| -> f64 {
        steps
            .iter()
            .filter(|s| s.presses > 0)
            .map(|s| setup_s + s.presses.div_ceil(n) as f64 * per_press)
            .sum()
    };
    let rows: Vec<serde_json::Value> = cores
        .iter()
        .map(
            |&n| json!({"cores": n, "predicted_s": predict(n), "speedup": predict(1) / predict(n)}),
        )
        .collect();
    Ok(json!({
        "level": level, "element": o.element.name(), "law": o.law.name(),
        "depth_max_mm": o.depth_max_mm,
        "steps": steps.iter().map(|s| json!({"presses": s.presses, "what": s.what, "exact": s.exact})).collect::<Vec<_>>(),
        "presses": total, "setup_s": setup_s, "measured_presses": pressed, "per_press_s": per_press,
        "core_hours": (total as f64 * per_press) / 3600.0,
        "predicted": rows,
        "assumes": "one press a core; a round per step, each paying a shard's setup; the merges' compression not counted",
    }))
}

/// The plan as a person reads it.
pub fn print(v: &serde_json::Value) {
    let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    println!(
        "plan: {} {} {} to {} mm: {} presses; one press {:.1} s of a core (measured here over {}), a shard's setup {:.1} s; {:.1} core-hours",
        v["level"].as_str().unwrap_or(""),
        v["element"].as_str().unwrap_or(""),
        v["law"].as_str().unwrap_or(""),
        f("depth_max_mm"),
        v["presses"],
        f("per_press_s"),
        v["measured_presses"],
        f("setup_s"),
        f("core_hours"),
    );
    for s in v["steps"].as_array().into_iter().flatten() {
        println!(
            "  {:>7} presses: {}",
            s["presses"].as_u64().unwrap_or(0),
            s["what"].as_str().unwrap_or("")
        );
    }
    println!("{:>8} {:>14} {:>9}", "cores", "wall time", "speedup");
    for r in v["predicted"].as_array().into_iter().flatten() {
        let secs = r["predicted_s"].as_f64().unwrap_or(f64::NAN);
        println!(
            "{:>8} {:>14} {:>9.1}",
            r["cores"].as_u64().unwrap_or(0),
            minutes(secs),
            r["speedup"].as_f64().unwrap_or(f64::NAN)
        );
    }
    println!("assumes {}", v["assumes"].as_str().unwrap_or(""));
}
