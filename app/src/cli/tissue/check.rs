//! `palpa tissue check`: a built vademecum against the full nonlinear FE (Newton) at
//! held-out points and depths, through the scene it serves.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::fe::newton::{NewtonReport, NewtonSettings};
use palpa_core::fe::probe::{ProbeRequest, ProbeSolution, organ_space, solve_hyperelastic_depths};
use palpa_core::fe::series::{Expander, SplitTangent};
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::accuracy::{CheckRun, DepthFigures};
use palpa_core::tissue::law::{PointIndex, TissueLaw};
use palpa_core::tissue::surface::{Pressing, SurfaceLawOptions};
use palpa_core::tissue::surplus::BLEND_SURPLUS_WARN_MM;
use serde_json::json;

use super::against::{Against, Answer, max_node_errors, worst_node};
use super::eval::bound_to_scene;
use super::points::press_points;
use crate::cli::args::OrganArgs;

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
    /// Write what this check measured into the tissue file (atomically), beside what
    /// earlier checks recorded there (the same draw measured again replaces its own):
    /// `palpa info` then shows it under `accuracy`, and the panel and `palpa eval` read
    /// the depths to which the goals hold from it.
    #[arg(long)]
    record: bool,
}

/// The reference at one point: Newton at every depth, as one path (each depth from the
/// equilibrium of the one before: the states Newton reaches from rest, for less), along
/// `push` (the scene's: the interpolated vertex normal, as the app presses). Per depth,
/// in the order given, the solution or why there is none.
pub(super) fn newton_at_depths(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    at: [f64; 3],
    push: [f64; 3],
    depths_mm: &[f64],
) -> Vec<Result<(ProbeSolution, NewtonReport), String>> {
    let request = ProbeRequest {
        at,
        force_n: f64::NAN,
        dir: Some(push),
        radius_mm: o.tool_radius_mm,
        nodule: None,
    };
    let settings = NewtonSettings::default();
    match solve_hyperelastic_depths(
        organ, o.element, o.material, o.law, &request, depths_mm, settings,
    ) {
        Ok(r) => r
            .into_iter()
            .map(|r| r.map_err(|e| e.to_string()))
            .collect(),
        Err(e) => vec![Err(e.to_string()); depths_mm.len()],
    }
}

/// `palpa tissue check`.
pub fn check(args: &CheckArgs) -> anyhow::Result<()> {
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
    // The bytes checked: `--record` writes only into the file they still are.
    let checked_bytes = match args.record {
        true => {
            Some(std::fs::read(&args.tissue).with_context(|| args.tissue.display().to_string())?)
        }
        false => None,
    };
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
    bound.law.check_organ(&organ)?;
    let law = &bound.law;
    let mut scratch = bound.scratch();
    let mut contact_scratch = scene.contact_scratch();
    let mut coeffs = vec![0.0; scene.modes()];
    let rows = 3 * scene.vertices_mm().len();
    let (mut linear_rows, mut tissue_rows) = (vec![0.0; rows], vec![0.0; rows]);
    // The scene's render vertex of each organ vertex (by rest position).
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let (mut worst_force, mut worst_surface) = (0.0f64, 0.0f64);
    // The same figures depth by depth, for `--record`.
    let mut per_depth: Vec<DepthFigures> = args
        .depths
        .iter()
        .map(|&depth_mm| DepthFigures {
            depth_mm,
            presses: 0,
            past_limit: 0,
            worst_force_rel: 0.0,
            worst_surface_mm: 0.0,
        })
        .collect();
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
    let drawn = points.len();
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
                let pressing = Pressing {
                    space: &space,
                    organ: &organ,
                    expander,
                    o: &o,
                };
                let press = pressing.press_at(at, contact.push_dir, tangent)?;
                own.push((name, press, t.elapsed().as_secs_f64()));
            }
        }
        let followed = match (&expander, args.own) {
            (Some(expander), true) => {
                let t = Instant::now();
                let pressing = Pressing {
                    space: &space,
                    organ: &organ,
                    expander,
                    o: &o,
                };
                let p = pressing.follow_at(at, contact.push_dir, &args.depths)?;
                Some((p, t.elapsed().as_secs_f64()))
            }
            _ => None,
        };
        let references = newton_at_depths(&organ, &o, at, contact.push_dir, &args.depths);
        for ((&depth, reference), figures) in
            args.depths.iter().zip(references).zip(per_depth.iter_mut())
        {
            let newton_s = reference.as_ref().map_or(0.0, |(_, r)| r.seconds);
            let mut row = json!({"at": at, "depth_mm": depth, "newton_s": newton_s});
            let (limit, stopped) = bound.limit_mm(&point);
            if depth > limit {
                row["vademecum_limit_mm"] = json!(limit);
                row["vademecum_stopped"] = json!(stopped);
            }
            let (sol, _) = match reference {
                Ok(r) => r,
                Err(e) => {
                    row["newton_error"] = json!(e);
                    past_limit += usize::from(depth > limit);
                    figures.past_limit += u32::from(depth > limit);
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
                figures.past_limit += 1;
            } else {
                worst_force = worst_force.max(force_err);
                worst_surface = worst_surface.max(e_tissue);
                compared += 1;
                figures.presses += 1;
                figures.worst_force_rel = figures.worst_force_rel.max(force_err);
                figures.worst_surface_mm = figures.worst_surface_mm.max(e_tissue);
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
    if let Some(checked_bytes) = checked_bytes {
        let mut run = CheckRun {
            seed: args.at.is_none().then_some(args.seed),
            points: drawn as u32,
            held_points: held_points as u32,
            scene: args.scene.clone(),
            left_out: "palpable triangles with a corner that was not pressed (the band next \
                       to the fixed region)"
                .into(),
            depths: per_depth,
        };
        run.depths.sort_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm));
        let now = std::fs::read(&args.tissue).with_context(|| args.tissue.display().to_string())?;
        if now != checked_bytes {
            bail!(
                "{}: the file changed while it was checked: nothing recorded",
                args.tissue.display()
            );
        }
        let mut file = TissueLaw::from_bytes(&now, &args.tissue)?;
        file.accuracy.record(run);
        file.save(&args.tissue)?;
        eprintln!(
            "recorded in {}: {} points over {} checks, goals to {:?}",
            args.tissue.display(),
            file.accuracy.points(),
            file.accuracy.runs.len(),
            file.accuracy.goals_to_mm()
        );
    }
    Ok(())
}
