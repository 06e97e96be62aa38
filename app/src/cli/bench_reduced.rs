//! `palpa bench fe --only reduced`: can a point between presses already made be
//! pressed in the span of their states instead of on the whole mesh?
//!
//! On a palpable triangle of coarse P2 (neo-Hookean, to 15 mm) its corners and edge
//! midpoints are followed to equilibrium as the tissue build does (`fe::path`); then at
//! held-out points inside it (a quarter point of an edge, an inner point, the centroid:
//! where a split triangle presses) the full press is compared, at 3/6/9/12/15 mm, with
//! - the quadratic blend of the six presses' residuals (what the tissue answers there
//!   without a split);
//! - the best approximation of the full state in the reduced span (Euclidean
//!   projection: the span's floor);
//! - the reduced press ([`palpa_core::fe::reduced`]) in several spans: the six
//!   presses' states at every grid depth; those (or the three corners') and the point's
//!   own first six series orders (on the shared rest factor); the own orders alone
//!   (six, or twelve); and some of these with the whole-mesh check that grows the span
//!   (a chord step with the rest factor, within the full press's 0.05 mm).
//!
//! Each row carries the times (the reduced press, its tangents, residuals and check,
//! the own orders, the full press) so the cost is read beside the error.
//! Errors are the largest over the surface nodes (the rows a scene draws), in mm.

use std::time::Instant;

use palpa_core::fe::probe::organ_space;
use palpa_core::fe::reduced::{Basis, Check, krylov_correction, reduced_press};
use palpa_core::fe::series::Expander;
use palpa_core::fe::{Element, Material};
use palpa_core::organ::OrganMesh;
use palpa_core::pgd::surfacelaw::{SurfaceLawOptions, follow_at, organ_vertex_normals, tool_load};
use serde_json::json;

/// Triangles near these points are measured (the first `count`).
pub const NEAR: [[f64; 3]; 4] = [
    [-30.3, 70.7, 16.9],
    [10.0, 80.0, 20.0],
    [60.0, 40.0, 20.0],
    [-20.0, 20.0, 60.0],
];

const COMPARED_MM: [f64; 5] = [3.0, 6.0, 9.0, 12.0, 15.0];

/// Conjugate-gradient steps after which the Krylov correction is reported (0: the
/// check's chord step).
const KRYLOV_STEPS: [usize; 6] = [0, 1, 2, 4, 8, 16];

fn largest_on(rows: &[u32], a: &[f64], b: &[f64]) -> f64 {
    rows.iter()
        .map(|&r| {
            let i = 3 * r as usize;
            ((a[i] - b[i]).powi(2) + (a[i + 1] - b[i + 1]).powi(2) + (a[i + 2] - b[i + 2]).powi(2))
                .sqrt()
        })
        .fold(0.0, f64::max)
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / n)
}

/// The palpable triangle with all three corners pressable whose centroid is nearest
/// to `p`.
fn triangle_near(organ: &OrganMesh, p: [f64; 3]) -> Option<[u32; 3]> {
    let pressable = organ.pressable_vertices();
    organ
        .boundary
        .iter()
        .zip(&organ.palpable)
        .filter(|(t, palp)| **palp && t.iter().all(|v| pressable.binary_search(v).is_ok()))
        .map(|(t, _)| *t)
        .min_by(|s, t| {
            let d = |t: &[u32; 3]| {
                (0..3)
                    .map(|k| {
                        let c: f64 = t.iter().map(|&v| organ.mesh.vertices[v as usize][k]).sum();
                        (c / 3.0 - p[k]).powi(2)
                    })
                    .sum::<f64>()
            };
            d(s).total_cmp(&d(t))
        })
}

pub(super) fn reduced(
    coarse: &OrganMesh,
    first: usize,
    count: usize,
    refresh: usize,
) -> anyhow::Result<()> {
    let o = SurfaceLawOptions {
        depth_max_mm: 15.0,
        ..SurfaceLawOptions::default()
    };
    let space = organ_space(coarse, Element::P2);
    let expander = Expander::new(&space, o.law, o.material)?;
    let rows = coarse.surface_nodes();
    let normals = organ_vertex_normals(coarse);
    let grid: Vec<f64> = (1..=15).map(f64::from).collect();
    // The check a build would run: a chord step with the shared rest factor, within
    // the full press's trust tolerance.
    let check = Check {
        factor: expander.rest_factor(),
        tolerance_mm: palpa_core::fe::path::PathOptions::default().tolerance_mm,
        max_added: 8,
    };
    for near in NEAR.iter().skip(first).take(count) {
        let Some(tri) = triangle_near(coarse, *near) else {
            continue;
        };
        let corner = tri.map(|v| coarse.mesh.vertices[v as usize]);
        let normal = tri.map(|v| normals[v as usize].map(f64::from));
        // Barycentric point and push (the corners' normals blended, as a scene does).
        let point = |l: [f64; 3]| {
            let at = [0, 1, 2].map(|k| (0..3).map(|i| l[i] * corner[i][k]).sum::<f64>());
            let push = unit([0, 1, 2].map(|k| -(0..3).map(|i| l[i] * normal[i][k]).sum::<f64>()));
            (at, push)
        };
        let six: [[f64; 3]; 6] = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.5, 0.5, 0.0],
            [0.0, 0.5, 0.5],
            [0.5, 0.0, 0.5],
        ];
        let t0 = Instant::now();
        let mut made = Vec::new();
        for l in six {
            let (at, push) = point(l);
            match follow_at(&space, coarse, &expander, &o, at, push, &[])? {
                Ok((press, _)) => made.push((l, press)),
                Err(why) => println!(
                    "{}",
                    json!({"table": "reduced", "triangle": tri, "skipped_press": at, "why": why})
                ),
            }
        }
        let six_s = t0.elapsed().as_secs_f64();
        if made.len() < 6 {
            continue;
        }
        let reach = made.iter().map(|(_, p)| p.u.len()).min().unwrap_or(0);
        // Every grid state of the chosen presses (indices into the six).
        let states = |which: &[usize]| -> Vec<Vec<f64>> {
            which
                .iter()
                .flat_map(|&i| made[i].1.u.iter().skip(1).take(reach.saturating_sub(1)))
                .map(|u| space.restrict(u))
                .collect()
        };
        let held: [(&str, [f64; 3]); 4] = [
            ("edge midpoint", [0.5, 0.5, 0.0]),
            ("quarter point", [0.75, 0.25, 0.0]),
            ("inner point", [0.5, 0.25, 0.25]),
            ("centroid", [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0]),
        ];
        for (name, l) in held {
            let (at, push) = point(l);
            let t = Instant::now();
            let full = match follow_at(&space, coarse, &expander, &o, at, push, &[])? {
                Ok((p, _)) => p,
                Err(why) => {
                    println!("{}", json!({"table": "reduced", "point": name, "why": why}));
                    continue;
                }
            };
            let full_s = t.elapsed().as_secs_f64();
            // The point's own first orders, as a reduced press would compute them:
            // the rest series on the shared rest factor, six orders.
            let (shape, probe) = tool_load(&space, coarse, &o, at, push)?;
            let t = Instant::now();
            let own = expander
                .expand_active(&shape, &probe, 6, o.active_cutoff)?
                .u;
            let own_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let own12 = expander
                .expand_active(&shape, &probe, 12, o.active_cutoff)?
                .u;
            let own12_s = t.elapsed().as_secs_f64();
            // Quadratic (P2 Lagrange) weights of the six presses at `l`.
            let w: Vec<f64> = made
                .iter()
                .map(|(m, _)| {
                    let nz: Vec<usize> = (0..3).filter(|&i| m[i] > 0.0).collect();
                    match nz.as_slice() {
                        [i] => l[*i] * (2.0 * l[*i] - 1.0),
                        [i, j] => 4.0 * l[*i] * l[*j],
                        _ => 0.0,
                    }
                })
                .collect();
            // (label, presses spanned, own orders); the midpoint is one of the six, so
            // only spans without it say anything there.
            let variants: &[(&str, &[usize], usize, bool)] = if name == "edge midpoint" {
                &[
                    ("three corners", &[0, 1, 2], 0, false),
                    ("three corners + own u1..u6", &[0, 1, 2], 6, false),
                    ("own u1..u6", &[], 6, false),
                    ("own u1..u6, checked", &[], 6, true),
                    ("own u1..u12, checked", &[], 12, true),
                ]
            } else {
                &[
                    ("six presses", &[0, 1, 2, 3, 4, 5], 0, false),
                    ("six + own u1..u6", &[0, 1, 2, 3, 4, 5], 6, false),
                    ("own u1..u6", &[], 6, false),
                    ("own u1..u6, checked", &[], 6, true),
                    ("own u1..u12, checked", &[], 12, true),
                    ("three corners + own u1..u6, checked", &[0, 1, 2], 6, true),
                ]
            };
            let mut rows_out = Vec::new();
            for &(label, which, orders, checked) in variants {
                let corners_only = which.len() == 3;
                let orders_from = if orders > 6 { &own12 } else { &own };
                let basis = Basis::orthonormal(
                    states(which)
                        .into_iter()
                        .chain(orders_from.iter().take(orders).map(|u| space.restrict(u))),
                    1e-8,
                );
                let t = Instant::now();
                let rom = reduced_press(
                    &space,
                    o.law,
                    Material::default(),
                    &basis,
                    &shape,
                    &probe,
                    &grid,
                    0.005,
                    refresh,
                    checked.then_some(&check),
                )?;
                let rom_s = t.elapsed().as_secs_f64();
                for &d in &COMPARED_MM {
                    let j = d as usize;
                    if j >= full.u.len() || j >= reach {
                        continue;
                    }
                    let exact = &full.u[j];
                    let fit = space.expand(&basis.lift(&basis.project(&space.restrict(exact))));
                    let mut row = json!({"table": "reduced", "triangle": tri, "point": name,
                        "at": at, "depth_mm": d, "span": label, "rank": basis.rank(),
                        "full_force_n": full.force_n[j],
                        "span_floor_mm": largest_on(&rows, &fit, exact),
                        "reduced_seconds": rom_s,
                        "own_orders_seconds": if orders > 6 { own12_s } else { own_s }, "reduced_tangents": rom.tangents,
                        "reduced_residuals": rom.residuals, "reduced_tangent_seconds": rom.tangent_s,
                        "reduced_residual_seconds": rom.residual_s, "reduced_solves": rom.solves,
                        "reduced_check_seconds": rom.check_s, "reduced_added": rom.added,
                        "reduced_rank": rom.rank, "full_seconds": full_s,
                        "six_presses_seconds": six_s});
                    if let (Some(u), Some(f)) = (rom.u.get(j - 1), rom.force_n.get(j - 1)) {
                        row["reduced_error_mm"] = json!(largest_on(&rows, u, exact));
                        if label == "own u1..u6" {
                            // What Newton's correction there is, seen through a few
                            // conjugate-gradient steps on the tangent's action with
                            // the rest factor: an error estimate, and a corrector.
                            let k = krylov_correction(
                                &space,
                                o.law,
                                Material::default(),
                                expander.rest_factor(),
                                &shape,
                                &probe,
                                u,
                                *f,
                                KRYLOV_STEPS[KRYLOV_STEPS.len() - 1],
                            )?;
                            let zero = vec![0.0; u.len()];
                            let (mut estimate, mut corrected) = (Vec::new(), Vec::new());
                            for &n in &KRYLOV_STEPS {
                                let Some(delta) = k.steps.get(n) else {
                                    break;
                                };
                                let delta = space.expand(delta);
                                estimate.push(largest_on(&rows, &delta, &zero));
                                let moved: Vec<f64> =
                                    u.iter().zip(&delta).map(|(a, b)| a + b).collect();
                                corrected.push(largest_on(&rows, &moved, exact));
                            }
                            let krylov = json!({"krylov_steps": KRYLOV_STEPS,
                                "krylov_estimate_mm": estimate,
                                "krylov_corrected_error_mm": corrected,
                                "krylov_indefinite": k.indefinite, "krylov_seconds": k.seconds,
                                "krylov_residuals": k.residuals, "krylov_solves": k.solves,
                                "krylov_load_probe_cosine": k.load_probe_cosine});
                            if let (Some(r), Some(f)) = (row.as_object_mut(), krylov.as_object()) {
                                r.extend(f.clone());
                            }
                        }
                        row["reduced_check_mm"] = json!(rom.check_mm[j - 1]);
                        row["reduced_force_rel_error"] =
                            json!((f - full.force_n[j]) / full.force_n[j]);
                    } else {
                        row["reduced_stopped"] = json!(rom.stopped);
                    }
                    if orders == 0 && !which.is_empty() {
                        // The blend the tissue answers without these presses: the
                        // point's own linear field plus the presses' residuals, weighed
                        // quadratically over the six (linearly over the corners alone).
                        let weights: Vec<f64> = if corners_only {
                            (0..6).map(|i| if i < 3 { l[i] } else { 0.0 }).collect()
                        } else {
                            w.clone()
                        };
                        let mut blend: Vec<f64> = own[0].iter().map(|x| d * x).collect();
                        for ((_, p), wi) in made.iter().zip(&weights) {
                            for (k, b) in blend.iter_mut().enumerate() {
                                *b += wi * (p.u[j][k] - d * p.first.u[0][k]);
                            }
                        }
                        let key = if corners_only {
                            "linear_blend_error_mm"
                        } else {
                            "quadratic_blend_error_mm"
                        };
                        row[key] = json!(largest_on(&rows, &blend, exact));
                    }
                    rows_out.push(row);
                }
            }
            for r in rows_out {
                println!("{r}");
            }
        }
    }
    Ok(())
}
