//! The speed/accuracy tables of the liver vademecums, measured where the user is
//! ([`nodal_table`] for the default nodal-load model, [`pgd_table`] for the earlier
//! vertex-load PGD).
//!
//! For n = 1 … N global modes (log steps) and, at all modes, for the far field's
//! tolerance knob (the stored tolerance times 1, 2, 5, 10, 30, and no far field):
//! the held-out errors of [`super::heldout`] (surface relative L2, largest nodal error,
//! compliance) with and without the near field, the time of what a frame runs
//! (particularize, the surface rows, near and far field), the time of what the force
//! loop runs (the compliance tensor at a point) and the bytes a surface-only f32 scene
//! carries.

use std::time::Instant;

use thiserror::Error;

use super::heldout::{self, Case, Errors};
use super::linear::map_error;
use super::palpation::{optimal_errors_on, setup, svd_error, terms_from_model};
use crate::axis::Discretization;
use crate::axis::ParamValue;
use crate::fe::elasticity::LinearProblem;
use crate::fe::load::{SurfacePoint, probe_load};
use crate::fe::probe::organ_space;
use crate::fe::{Element, FeError, Material};
use crate::mesh::triangle_normal;
use crate::organ::OrganMesh;
use crate::rng::Rng;
use crate::separated::{EvalError, SeparatedModel, TradeoffRow, node_rows};
use crate::timing::mean_ns;

/// Why a table could not be measured.
#[derive(Debug, Error)]
pub enum TradeoffError {
    #[error("the held-out FE reference failed: {0}")]
    Fe(#[from] FeError),
    #[error("evaluating the model at a held-out point: {0}")]
    Eval(#[from] EvalError),
    #[error("a nodal model without its near field (or with a compliance table on no face)")]
    NoNearField,
    #[error("not a palpation vademecum (no surface-vector axis on boundary faces)")]
    NotPgd,
}

/// One mode count.
#[derive(Debug, Clone, PartialEq)]
pub struct ModesRow {
    pub modes: usize,
    pub errors: Errors,
    /// The same modes without the near field (what an older file gives).
    pub without_near: Errors,
    pub surface_eval_us: f64,
    pub contact_eval_ns: f64,
    pub bytes: u64,
}

/// One far-field tolerance (`None`: without the far field), at all modes.
#[derive(Debug, Clone, PartialEq)]
pub struct FarRow {
    pub tolerance: Option<f64>,
    pub modes: usize,
    pub errors: Errors,
    pub surface_eval_us: f64,
    pub bytes: u64,
}

/// The whole table.
#[derive(Debug, Clone)]
pub struct NodalTable {
    pub rows: Vec<ModesRow>,
    pub far_rows: Vec<FarRow>,
    /// The held-out presses (their kinds and points name the worst cases).
    pub cases: Vec<Case>,
    /// Seconds spent on the held-out FE solves.
    pub fe_reference_s: f64,
}

/// Seed of the held-out points (the same in every table, so tables compare).
pub const HELD_OUT_SEED: u64 = 0x7e57;

impl NodalTable {
    /// The rows a file's header stores (what the app's accuracy knob reads).
    pub fn header_rows(&self) -> Vec<TradeoffRow> {
        self.rows
            .iter()
            .map(|r| TradeoffRow {
                modes: r.modes as u32,
                surface_rel_error: r.errors.surface_rel_error,
                probe_rel_error: r.errors.compliance_rel_error,
                map_rel_error: None,
                svd_rel_error: None,
                surface_eval_us: r.surface_eval_us,
                contact_eval_ns: r.contact_eval_ns,
                bytes: r.bytes,
                compliance_rel_error: Some(r.errors.compliance_rel_error),
                surface_max_nodal_error_mm: Some(r.errors.surface_max_nodal_error_mm),
            })
            .collect()
    }
}

/// Measures the table of a nodal-load `model` built on `organ` with this element,
/// material and tool radius: `random` random held-out points plus the special ones.
pub fn nodal_table(
    model: &SeparatedModel<f64>,
    organ: &OrganMesh,
    element: Element,
    material: Material,
    radius_mm: f64,
    random: usize,
) -> Result<NodalTable, TradeoffError> {
    let t0 = Instant::now();
    let space = organ_space(organ, element);
    let problem = LinearProblem::new(&space, material)?;
    let cases = heldout::cases(&space, &problem, organ, radius_mm, random, HELD_OUT_SEED)?;
    let fe_reference_s = t0.elapsed().as_secs_f64();
    let surface_nodes = organ.surface_nodes();
    let surface_rows = node_rows(&surface_nodes);
    let n_max = model.modes();
    let mut ns: Vec<usize> = [1, 2, 5, 10, 20, 50, 100, 150, 200, 300, 400]
        .into_iter()
        .filter(|&n| n < n_max)
        .collect();
    ns.push(n_max);
    let axis_nodes = model.axes()[0].info.discretization.node_count();
    let scene_bytes = |m: &SeparatedModel<f64>, n: usize| {
        ((surface_rows.len() + axis_nodes) * n * 4 + m.near().map_or(0, |nf| nf.bytes())) as u64
    };
    let near = model.near().ok_or(TradeoffError::NoNearField)?;
    let face0 = near
        .table_block
        .iter()
        .position(|&b| b != u32::MAX)
        .ok_or(TradeoffError::NoNearField)? as u32;
    let probe = [ParamValue::SurfaceMix {
        triangle: face0,
        bary: [1.0 / 3.0; 3],
        mix: cases.first().map_or([0.0, 0.0, 1.0], |c| c.dir),
    }];
    let contact_eval_ns = contact_ns(near, face0);
    let bare = model.clone().without_near();
    let mut rows = Vec::with_capacity(ns.len());
    for &n in &ns {
        rows.push(ModesRow {
            modes: n,
            errors: heldout::nodal_errors(model, &space, &cases, &surface_nodes, n)?,
            without_near: heldout::nodal_errors(&bare, &space, &cases, &surface_nodes, n)?,
            surface_eval_us: frame_us(model, &probe, &surface_rows, n)?,
            contact_eval_ns,
            bytes: scene_bytes(model, n),
        });
    }
    let mut far_rows = Vec::new();
    if let Some(t) = near.far.as_ref().map(|f| f.tolerance) {
        let tols = [1.0, 2.0, 5.0, 10.0, 30.0].map(|f| Some(f * t));
        for tolerance in tols.into_iter().chain([None]) {
            let m = model.clone().with_far_tolerance(tolerance);
            far_rows.push(FarRow {
                tolerance,
                modes: n_max,
                errors: heldout::nodal_errors(&m, &space, &cases, &surface_nodes, n_max)?,
                surface_eval_us: frame_us(&m, &probe, &surface_rows, n_max)?,
                bytes: scene_bytes(&m, n_max),
            });
        }
    }
    Ok(NodalTable {
        rows,
        far_rows,
        cases,
        fe_reference_s,
    })
}

/// Mean time of one frame's evaluation (µs): particularize, the surface rows, the
/// near and far field.
fn frame_us(
    model: &SeparatedModel<f64>,
    probe: &[ParamValue],
    surface_rows: &[u32],
    n: usize,
) -> Result<f64, EvalError> {
    let mut coeffs = vec![0.0; n];
    let mut out = vec![0.0; surface_rows.len()];
    let mut full = vec![0.0; model.rows()];
    let reps = 20;
    let t = Instant::now();
    for _ in 0..reps {
        model.particularize(std::hint::black_box(probe), &mut coeffs)?;
        model.reconstruct_rows(surface_rows, &coeffs, &mut out);
        model.add_near_field(probe, &mut full)?;
    }
    Ok(t.elapsed().as_secs_f64() * 1e6 / f64::from(reps))
}

/// Mean time of the force loop's evaluation (ns): the compliance tensor at a point.
fn contact_ns(near: &crate::nearfield::NearField, face: u32) -> f64 {
    let reps = 20_000u32;
    let t = Instant::now();
    let mut acc = 0.0;
    for i in 0..reps {
        let b = f64::from(i % 7) * 0.1;
        if let Some(ct) = near.compliance_tensor(
            face,
            std::hint::black_box([0.2 + b * 0.5, 0.3, 0.5 - b * 0.5]),
        ) {
            acc += ct[2][2];
        }
    }
    std::hint::black_box(acc);
    t.elapsed().as_nanos() as f64 / f64::from(reps)
}

/// The table of a PGD (vertex-load) vademecum.
#[derive(Debug, Clone)]
pub struct PgdTable {
    pub rows: Vec<TradeoffRow>,
    /// The optimal rank-n error in the surface norm, per row (when computed).
    pub surface_optimum: Vec<Option<f64>>,
    /// `(surface, probe)` errors of the FE responses at the vertices, interpolated:
    /// the floor this representation converges to.
    pub floor: (f64, f64),
    pub brute_force_solve_s: Option<f64>,
}

/// Measures a PGD vademecum: `random` held-out points against full FE solves, with
/// `optimal` the optimal rank-n errors (one FE solve per palpable node and direction).
pub fn pgd_table(
    model: &SeparatedModel<f64>,
    organ: &OrganMesh,
    element: Element,
    material: Material,
    radius_mm: f64,
    random: usize,
    optimal: bool,
) -> Result<PgdTable, TradeoffError> {
    let s = setup(organ, element, material, radius_mm)?;
    let terms = terms_from_model(&s, model);
    let n_max = model.modes();
    let triangles: Vec<[u32; 3]> = match &model.axes()[0].info.discretization {
        Discretization::SurfaceVector { triangles, .. } => triangles.clone(),
        _ => return Err(TradeoffError::NotPgd),
    };

    let (cases, floors) = pgd_cases(&s, organ, &triangles, radius_mm, random)?;
    let surface_rows = node_rows(&organ.surface_nodes());

    let svd = if optimal {
        // Surface rows as free dofs (fixed nodes carry no unknown).
        let surface_dofs: Vec<u32> = surface_rows
            .iter()
            .filter_map(|&r| {
                let d = s.space.dof[(r / 3) as usize];
                if d == u32::MAX { None } else { Some(d + r % 3) }
            })
            .collect();
        Some(optimal_errors_on(&s, &surface_dofs))
    } else {
        None
    };
    let mut ns: Vec<usize> = [1, 2, 5, 10, 20, 50, 100, 167, 200, 300, 400]
        .into_iter()
        .filter(|&n| n < n_max)
        .collect();
    ns.push(n_max);
    let mut rows = Vec::new();
    let mut surface_optimum = Vec::new();
    for &n in &ns {
        let mut coeffs = vec![0.0; n];
        let mut out = vec![0.0; surface_rows.len()];
        let (mut surf_err, mut probe_err) = (0.0f64, 0.0f64);
        for (t, bary, dir, u_fe) in &cases {
            let v = [ParamValue::SurfaceMix {
                triangle: *t,
                bary: *bary,
                mix: *dir,
            }];
            model.particularize(&v, &mut coeffs)?;
            model.reconstruct_rows(&surface_rows, &coeffs, &mut out);
            let (mut e2, mut n2) = (0.0, 0.0);
            for (i, &r) in surface_rows.iter().enumerate() {
                e2 += (out[i] - u_fe[r as usize]).powi(2);
                n2 += u_fe[r as usize].powi(2);
            }
            surf_err = surf_err.max((e2 / n2).sqrt());
            // Probe displacement along the load at the point.
            let tri = triangles[*t as usize];
            let along = |u: &dyn Fn(usize) -> f64| -> f64 {
                (0..3)
                    .map(|i| {
                        bary[i]
                            * (0..3)
                                .map(|d| u(3 * s.axis_nodes[tri[i] as usize] as usize + d) * dir[d])
                                .sum::<f64>()
                    })
                    .sum()
            };
            let full_pgd = {
                let mut all = vec![0.0; model.rows()];
                model.reconstruct(&coeffs, &mut all);
                all
            };
            let d_fe = along(&|i| u_fe[i]);
            let d_pgd = along(&|i| full_pgd[i]);
            probe_err = probe_err.max((d_pgd - d_fe).abs() / d_fe.abs());
        }
        // Timings at n modes.
        let v = [ParamValue::SurfaceMix {
            triangle: cases[0].0,
            bary: cases[0].1,
            mix: cases[0].2,
        }];
        let surface_eval_us = 1e-3
            * mean_ns(50, || {
                model.particularize(&v, &mut coeffs)?;
                model.reconstruct_rows(&surface_rows, &coeffs, &mut out);
                Ok::<(), EvalError>(())
            })?;
        let contact_rows: Vec<u32> = surface_rows[..9].to_vec();
        let mut c9 = [0.0; 9];
        let contact_eval_ns = mean_ns(5000, || {
            model.particularize(std::hint::black_box(&v), &mut coeffs)?;
            model.reconstruct_rows(&contact_rows, &coeffs, &mut c9);
            Ok::<(), EvalError>(())
        })?;
        let (map, opt) = match &svd {
            Some(o) => (
                Some(map_error(&s.ops(), &terms, n, o.g2)),
                Some(svd_error(&o.ev, n)),
            ),
            None => (None, None),
        };
        surface_optimum.push(svd.as_ref().map(|o| svd_error(&o.surface_ev, n)));
        let bytes = ((surface_rows.len() + model.axes()[0].values().len() / n_max) * n * 4) as u64;
        rows.push(TradeoffRow {
            modes: n as u32,
            surface_rel_error: surf_err,
            probe_rel_error: probe_err,
            map_rel_error: map,
            svd_rel_error: opt,
            surface_eval_us,
            contact_eval_ns,
            bytes,
            compliance_rel_error: None,
            surface_max_nodal_error_mm: None,
        });
    }
    let (mut floor_surf, mut floor_probe) = (0.0f64, 0.0f64);
    for ((t, bary, dir, u_fe), interp) in cases.iter().zip(&floors) {
        let (mut e2, mut n2) = (0.0, 0.0);
        for &r in &surface_rows {
            e2 += (interp[r as usize] - u_fe[r as usize]).powi(2);
            n2 += u_fe[r as usize].powi(2);
        }
        floor_surf = floor_surf.max((e2 / n2).sqrt());
        let tri = triangles[*t as usize];
        let along = |u: &[f64]| -> f64 {
            (0..3)
                .map(|i| {
                    bary[i]
                        * (0..3)
                            .map(|d| u[3 * s.axis_nodes[tri[i] as usize] as usize + d] * dir[d])
                            .sum::<f64>()
                })
                .sum()
        };
        floor_probe = floor_probe.max((along(interp) - along(u_fe)).abs() / along(u_fe).abs());
    }
    Ok(PgdTable {
        rows,
        surface_optimum,
        floor: (floor_surf, floor_probe),
        brute_force_solve_s: svd.as_ref().map(|s| s.solve_s),
    })
}

/// A held-out press of the PGD table: axis triangle, barycentric point, push
/// direction, and the FE answer on every node.
type PgdCase = (u32, [f64; 3], [f64; 3], Vec<f64>);

/// `random` seeded held-out presses on the axis triangles, each with its FE answer and
/// the FE responses at the triangle's vertices interpolated to it (the floor of a
/// vertex-load vademecum).
fn pgd_cases(
    s: &super::palpation::Setup,
    organ: &OrganMesh,
    triangles: &[[u32; 3]],
    radius_mm: f64,
    random: usize,
) -> Result<(Vec<PgdCase>, Vec<Vec<f64>>), TradeoffError> {
    let mut rng = Rng::seed(HELD_OUT_SEED);
    let mut cases = Vec::new();
    let mut floors: Vec<Vec<f64>> = Vec::new();
    for _ in 0..random {
        let t = rng.below(triangles.len());
        let (a, b) = (rng.range(0.1, 0.8), rng.uniform());
        let bary = [a, (1.0 - a) * b, (1.0 - a) * (1.0 - b)];
        let tri = s.axis_triangles[t];
        // The axis triangle is a boundary face; find it among the space's faces.
        let face = organ
            .boundary
            .iter()
            .position(|f| {
                f.iter()
                    .zip(&tri)
                    .all(|(&fv, &av)| fv == s.axis_nodes[av as usize])
            })
            .ok_or(TradeoffError::NotPgd)?;
        let point = [0, 1, 2].map(|d| {
            (0..3)
                .map(|i| bary[i] * s.axis_vertices[tri[i] as usize][d])
                .sum::<f64>()
        });
        let [p, q, r] = tri.map(|i| s.axis_vertices[i as usize]);
        let normal = triangle_normal(p, q, r);
        let dir = normal.map(|v| -v);
        let sp = SurfacePoint {
            face,
            bary,
            point,
            normal,
            distance_mm: 0.0,
        };
        let load = probe_load(&s.space, &sp, dir, 1.0, radius_mm)?;
        let u = s.problem.solve(&s.space, &load);
        // The s-axis floor: FE responses to the tool centred at the triangle's
        // vertices, interpolated barycentrically (what the PGD converges to as N grows).
        let mut interp = vec![0.0; u.len()];
        for (i, &av) in tri.iter().enumerate() {
            let mut b = [0.0; 3];
            b[i] = 1.0;
            let at_vertex = SurfacePoint {
                bary: b,
                point: s.axis_vertices[av as usize],
                ..sp
            };
            let lv = probe_load(&s.space, &at_vertex, dir, 1.0, radius_mm)?;
            let uv = s.problem.solve(&s.space, &lv);
            for (a, v) in interp.iter_mut().zip(uv) {
                *a += bary[i] * v;
            }
        }
        floors.push(interp);
        cases.push((t as u32, bary, dir, u));
    }
    Ok((cases, floors))
}
