//! `palpa lab bench fe --only build_cost`: what one press of the nonlinear build costs
//! against the brute-force route, measured in one run.
//!
//! The build (`palpa tissue build`) follows each press along its depth grid with the
//! path of `fe::path`: a series on the rest factor shared by every press predicts, a
//! chord Newton with a segment's tangent corrects, and a tangent is factored again
//! only where a depth needs more than a few steps. The brute-force route solves each
//! grid depth by the reference Newton (`fe::newton`: a fresh tangent factored every
//! iteration, its residual to 1e-10 of the load), started from the previous depth's
//! equilibrium, the cheapest start it can have; `--build-from-rest` adds the literal
//! route, each depth from rest as `palpa fe solve --depth-mm` does. Both press the same
//! vertex the way the build does (at the vertex, along its area-weighted inward
//! normal) on coarse P2, neo-Hookean, 1 mm grid to 15 mm. Each row also says how far
//! apart the two routes' states are at every depth (largest nodal distance and force
//! difference), so the cheaper route is shown to answer the same press.

use std::time::Instant;

use palpa_core::fe::newton::{Control, NewtonSettings, continue_depth, solve};
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::series::Expander;
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::surface::{Pressing, SurfaceLawOptions, organ_vertex_normals};
use serde_json::json;

/// Largest nodal distance between two all-node states (mm).
fn largest_distance(a: &[f64], b: &[f64]) -> f64 {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

/// The pressable vertex nearest `p`.
pub(super) fn nearest_vertex(organ: &OrganMesh, pressable: &[u32], p: [f64; 3]) -> Option<u32> {
    pressable.iter().copied().min_by(|&a, &b| {
        let d = |v: u32| {
            let q = organ.mesh.vertices[v as usize];
            (0..3).map(|k| (q[k] - p[k]).powi(2)).sum::<f64>()
        };
        d(a).total_cmp(&d(b))
    })
}

/// The `build_cost` table: one row per position, then a summary with the ratios and
/// what each route would cost the whole coarse surface (vertices and edge midpoints,
/// the quadratic build) at the measured mean.
pub(super) fn build_cost(
    coarse: &OrganMesh,
    positions: &[(&str, [f64; 3])],
    from_rest: bool,
) -> anyhow::Result<()> {
    let o = SurfaceLawOptions {
        depth_max_mm: 15.0,
        ..SurfaceLawOptions::default()
    };
    let space = organ_space(coarse, Element::P2);
    let t = Instant::now();
    let expander = Expander::new(&space, o.law, o.material)?;
    let rest_factor_s = t.elapsed().as_secs_f64();
    let normals = organ_vertex_normals(coarse);
    let pressable = coarse.pressable_vertices();
    let fixed = |v: u32| coarse.fixed[v as usize];
    let edges = coarse
        .palpable_edges()
        .iter()
        .filter(|e| !fixed(e[0]) && !fixed(e[1]))
        .count();
    let whole = pressable.len() + edges;
    let settings = NewtonSettings::default();
    let material = Material::default();
    let (mut build_total, mut brute_total, mut rest_total) = (0.0, 0.0, 0.0);
    let mut rows = 0usize;
    let pressing = Pressing {
        space: &space,
        organ: coarse,
        expander: &expander,
        o: &o,
    };
    for &(name, near) in positions {
        let Some(v) = nearest_vertex(coarse, &pressable, near) else {
            continue;
        };
        let at = coarse.mesh.vertices[v as usize];
        let push = normals[v as usize].map(|c| -f64::from(c));
        let t = Instant::now();
        let (press, depths) = match pressing.follow_at(at, push, &[])? {
            Ok(p) => p,
            Err(why) => {
                println!(
                    "{}",
                    json!({"table": "build_cost", "position": name, "vertex": v, "skipped": why})
                );
                continue;
            }
        };
        let build_s = t.elapsed().as_secs_f64();
        let (shape, probe) = pressing.tool_load(at, push)?;
        let stiffness = press.first.force[0];
        // Brute force: the reference Newton at each depth the build reached, each
        // from the previous depth's equilibrium.
        let t = Instant::now();
        let (mut state, mut factorizations) = ((0.0, 0.0, vec![0.0; shape.len()]), 0usize);
        let (mut worst_mm, mut worst_force) = (0.0f64, 0.0f64);
        let mut reached = 0usize;
        let (mut distance_mm, mut force_difference) = (Vec::new(), Vec::new());
        let mut failed = None;
        for (j, &d) in depths.iter().enumerate().take(press.u.len()).skip(1) {
            match continue_depth(
                &space,
                o.law,
                material,
                (&shape, &probe),
                stiffness,
                (state.0, state.1, &state.2),
                d,
                settings,
                &mut factorizations,
            ) {
                Ok(sol) => {
                    let mm = largest_distance(&sol.u, &press.u[j]);
                    let df = (sol.force_n - press.force_n[j]).abs() / sol.force_n.abs();
                    (worst_mm, worst_force) = (worst_mm.max(mm), worst_force.max(df));
                    distance_mm.push(mm);
                    force_difference.push(df);
                    state = (d, sol.force_n, sol.u);
                    reached = j;
                }
                Err(e) => {
                    failed = Some(format!("{d} mm: {e}"));
                    break;
                }
            }
        }
        let brute_s = t.elapsed().as_secs_f64();
        let mut row = json!({"table": "build_cost", "position": name, "vertex": v,
            "depths": press.u.len() - 1, "build_s": build_s,
            "build_factorizations": press.factorizations, "build_chord_steps": press.chord_steps,
            "brute_s": brute_s, "brute_depths": reached,
            "brute_factorizations": factorizations, "brute_over_build": brute_s / build_s,
            "largest_state_distance_mm": worst_mm, "largest_force_difference": worst_force,
            "state_distance_mm": distance_mm, "force_difference": force_difference});
        if let Some(why) = &failed {
            row["brute_failed"] = json!(why);
        }
        if let Some(why) = &press.stopped {
            row["build_stopped"] = json!(why);
        }
        if from_rest {
            // The literal brute force: every depth from rest, as `fe solve` does.
            let t = Instant::now();
            let mut iterations = 0usize;
            for &d in depths.iter().take(press.u.len()).skip(1) {
                let control = Control::Depth {
                    shape: shape.clone(),
                    probe: probe.clone(),
                    depth_mm: d,
                };
                match solve(&space, o.law, material, &control, settings) {
                    Ok(sol) => iterations += sol.report.iterations,
                    Err(e) => {
                        row["from_rest_failed"] = json!(format!("{d} mm: {e}"));
                        break;
                    }
                }
            }
            let s = t.elapsed().as_secs_f64();
            rest_total += s;
            row["from_rest_s"] = json!(s);
            row["from_rest_factorizations"] = json!(iterations);
            row["from_rest_over_build"] = json!(s / build_s);
        }
        println!("{row}");
        if failed.is_none() {
            build_total += build_s;
            brute_total += brute_s;
            rows += 1;
        }
    }
    if rows == 0 {
        return Ok(());
    }
    let n = rows as f64;
    let mut summary = json!({"table": "build_cost", "summary": true, "presses": rows,
        "rest_factor_s": rest_factor_s, "build_mean_s": build_total / n,
        "brute_mean_s": brute_total / n, "brute_over_build": brute_total / build_total,
        "whole_surface_presses": whole,
        "whole_surface_build_h": whole as f64 * build_total / n / 3600.0,
        "whole_surface_brute_h": whole as f64 * brute_total / n / 3600.0});
    if from_rest {
        summary["from_rest_over_build"] = json!(rest_total / build_total);
    }
    println!("{summary}");
    Ok(())
}
