//! Accuracy where the user is: held-out probe positions against full FE solves.
//!
//! The points are seeded and never nodes: random interior points of random palpable
//! faces, plus the places a model is most likely to fail (faces within 10 mm of the
//! fixed region, the faces along the sharpest palpable edges — the inferior border —
//! and the faces farthest to the patient's left, the thin left lobe). Each gets a full
//! FE solve of a unit push with the same tool along the direction the app pushes
//! there (the inward normal smoothed across edges, `fe::probe::smooth_inward_dir`; a
//! face's own normal jumps at its edges, and next to the fixed region the two change
//! the force by up to 15 %), and the model is compared on every surface node (relative
//! L2 and the largest nodal error) and on the compliance `c(s) = t·u(s)` the force law
//! uses.

use std::collections::HashMap;

use crate::axis::{Discretization, ParamValue};
use crate::fe::FeError;
use crate::fe::elasticity::LinearProblem;
use crate::fe::load::{SurfacePoint, probe_load, value_at};
use crate::fe::space::Space;
use crate::mesh::{dot, norm, sub, triangle_normal};
use crate::organ::OrganMesh;
use crate::rng::Rng;
use crate::scalar::Scalar;
use crate::separated::{EvalError, SeparatedModel};

/// One held-out probe press and its FE answer.
#[derive(Debug, Clone)]
pub struct Case {
    /// Space face and barycentric point on it.
    pub face: usize,
    pub bary: [f64; 3],
    pub point: [f64; 3],
    /// Unit push direction (the app's: the smoothed inward normal, for [`cases`]).
    pub dir: [f64; 3],
    /// What picked it: "random", "near-fixed", "sharp-border", "left-lobe".
    pub kind: &'static str,
    /// FE displacement of every node under 1 N, mm.
    pub u: Vec<f64>,
    /// `dir · u(point)`, mm/N.
    pub compliance_mm_per_n: f64,
}

/// Picks `random` random points plus two of each special kind, and solves them.
pub fn cases(
    space: &Space,
    problem: &LinearProblem,
    organ: &OrganMesh,
    radius_mm: f64,
    random: usize,
    seed: u64,
) -> Result<Vec<Case>, FeError> {
    let pal: Vec<usize> = (0..space.face_count())
        .filter(|&f| organ.palpable[f])
        .collect();
    if pal.is_empty() {
        return Err(FeError::NoPalpableSurface);
    }
    let corners = |f: usize| {
        let face = space.face(f);
        [0, 1, 2].map(|i| space.nodes[face[i] as usize])
    };
    let centroid = |f: usize| {
        let c = corners(f);
        [0, 1, 2].map(|d| (c[0][d] + c[1][d] + c[2][d]) / 3.0)
    };
    let normal = |f: usize| {
        let c = corners(f);
        triangle_normal(c[0], c[1], c[2])
    };
    // Sharpness of a palpable face: the largest normal change to a neighbour sharing
    // an edge (the inferior border is a thin wedge).
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for f in 0..space.face_count() {
        let fc = space.face(f);
        for i in 0..3 {
            let (a, b) = (fc[i], fc[(i + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(f);
        }
    }
    let sharpness = |f: usize| -> f64 {
        let fc = space.face(f);
        (0..3)
            .flat_map(|i| {
                let (a, b) = (fc[i], fc[(i + 1) % 3]);
                by_edge[&(a.min(b), a.max(b))].clone()
            })
            .filter(|&g| g != f)
            .map(|g| 1.0 - dot(normal(f), normal(g)))
            .fold(0.0, f64::max)
    };
    let fixed_nodes: Vec<[f64; 3]> = (0..space.nodes.len())
        .filter(|&v| space.dof[v] == u32::MAX)
        .map(|v| space.nodes[v])
        .collect();
    let dist_fixed = |f: usize| -> f64 {
        let c = centroid(f);
        fixed_nodes
            .iter()
            .map(|p| norm(sub(*p, c)))
            .fold(f64::INFINITY, f64::min)
    };
    let mut rng = Rng::seed(seed);
    let mut picks: Vec<(usize, &'static str)> = (0..random)
        .map(|_| (pal[rng.below(pal.len())], "random"))
        .collect();
    let mut near: Vec<usize> = pal
        .iter()
        .copied()
        .filter(|&f| dist_fixed(f) <= 10.0)
        .collect();
    near.sort_by(|&a, &b| dist_fixed(a).total_cmp(&dist_fixed(b)));
    picks.extend(near.iter().take(2).map(|&f| (f, "near-fixed")));
    let mut sharp = pal.clone();
    sharp.sort_by(|&a, &b| sharpness(b).total_cmp(&sharpness(a)));
    picks.extend(sharp.iter().take(2).map(|&f| (f, "sharp-border")));
    let mut left = pal.clone();
    left.sort_by(|&a, &b| centroid(b)[0].total_cmp(&centroid(a)[0]));
    picks.extend(left.iter().take(2).map(|&f| (f, "left-lobe")));
    let mut out = Vec::with_capacity(picks.len());
    for (face, kind) in picks {
        // Strictly inside the face: never a node, never an edge.
        let (a, b) = (rng.range(0.1, 0.8), rng.range(0.1, 0.9));
        let bary = [a, (1.0 - a) * b, (1.0 - a) * (1.0 - b)];
        let fc = space.face(face);
        let c = [0, 1, 2].map(|i| space.nodes[fc[i] as usize]);
        let point = [0, 1, 2].map(|d| (0..3).map(|i| bary[i] * c[i][d]).sum::<f64>());
        let sp = SurfacePoint {
            face,
            bary,
            point,
            normal: triangle_normal(c[0], c[1], c[2]),
            distance_mm: 0.0,
        };
        let dir = crate::fe::probe::smooth_inward_dir(organ, point)?;
        out.push(solve_case(space, problem, sp, dir, radius_mm, kind)?);
    }
    Ok(out)
}

/// The FE answer for a unit push along the inward normal at barycentric `bary` of
/// space face `face`.
pub fn press(
    space: &Space,
    problem: &LinearProblem,
    face: usize,
    bary: [f64; 3],
    radius_mm: f64,
    kind: &'static str,
) -> Result<Case, FeError> {
    let fc = space.face(face);
    let c = [0, 1, 2].map(|i| space.nodes[fc[i] as usize]);
    let point = [0, 1, 2].map(|d| (0..3).map(|i| bary[i] * c[i][d]).sum::<f64>());
    let n = triangle_normal(c[0], c[1], c[2]);
    let sp = SurfacePoint {
        face,
        bary,
        point,
        normal: n,
        distance_mm: 0.0,
    };
    solve_case(space, problem, sp, n.map(|v| -v), radius_mm, kind)
}

/// The FE answer for one press (unit force along `dir`).
pub fn solve_case(
    space: &Space,
    problem: &LinearProblem,
    sp: SurfacePoint,
    dir: [f64; 3],
    radius_mm: f64,
    kind: &'static str,
) -> Result<Case, FeError> {
    let load = probe_load(space, &sp, dir, 1.0, radius_mm)?;
    let u = problem.solve(space, &load);
    let us = value_at(space, &u, &sp);
    Ok(Case {
        face: sp.face,
        bary: sp.bary,
        point: sp.point,
        dir,
        kind,
        u,
        compliance_mm_per_n: dot(us, dir),
    })
}

/// A nodal model's errors over the held-out cases with its first `n` modes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Errors {
    /// Max over cases of the relative L2 error over the surface nodes.
    pub surface_rel_error: f64,
    /// Max over cases and surface nodes of the nodal error at 1 N, mm.
    pub surface_max_nodal_error_mm: f64,
    /// Max over cases of (max nodal error) / (max FE displacement).
    pub surface_max_nodal_rel_error: f64,
    /// Max over cases of |c_model − c_FE| / c_FE.
    pub compliance_rel_error: f64,
    /// The case with the largest surface error (index into the cases).
    pub worst_surface_case: usize,
}

/// Measures a nodal-load model (any precision; with or without its near field) on the
/// cases. `model` rows are every node of `space` (a full vademecum) or a subset whose
/// field node ids name space nodes.
pub fn nodal_errors<T: Scalar>(
    model: &SeparatedModel<T>,
    space: &Space,
    cases: &[Case],
    surface_nodes: &[u32],
    n: usize,
) -> Result<Errors, EvalError> {
    let Some(Discretization::SurfaceLoad {
        faces, field_nodes, ..
    }) = model.axes().first().map(|a| &a.info.discretization)
    else {
        return Err(EvalError::ParamCount {
            given: 0,
            expected: 1,
        });
    };
    // Load face of each space face (by its corner nodes).
    let mut by_corners: HashMap<[u32; 3], u32> = HashMap::new();
    for (i, f) in faces.iter().enumerate() {
        let mut k = [f[0], f[1], f[2]].map(|j| field_nodes[j as usize]);
        k.sort_unstable();
        by_corners.insert(k, i as u32);
    }
    let mut coeffs = vec![0.0; n];
    let mut full = vec![0.0; model.rows()];
    let mut e = Errors::default();
    for (ci, c) in cases.iter().enumerate() {
        let fc = space.face(c.face);
        let mut key = [fc[0], fc[1], fc[2]];
        key.sort_unstable();
        let Some(&lf) = by_corners.get(&key) else {
            continue;
        };
        // The load face's corner order may differ from the space face's.
        let lc = faces[lf as usize];
        let bary: [f64; 3] = std::array::from_fn(|i| {
            let node = field_nodes[lc[i] as usize];
            (0..3).find(|&k| fc[k] == node).map_or(0.0, |k| c.bary[k])
        });
        let v = [ParamValue::SurfaceMix {
            triangle: lf,
            bary,
            mix: c.dir,
        }];
        model.particularize(&v, &mut coeffs)?;
        model.reconstruct(&coeffs, &mut full);
        model.add_near_field(&v, &mut full)?;
        let (mut e2, mut n2, mut emax, mut umax) = (0.0, 0.0, 0.0f64, 0.0f64);
        for &x in surface_nodes {
            let x = x as usize;
            let mut d2 = 0.0;
            let mut u2 = 0.0;
            for d in 0..3 {
                let fe = c.u[3 * x + d];
                d2 += (full[3 * x + d] - fe).powi(2);
                u2 += fe * fe;
            }
            e2 += d2;
            n2 += u2;
            emax = emax.max(d2.sqrt());
            umax = umax.max(u2.sqrt());
        }
        if (e2 / n2).sqrt() > e.surface_rel_error {
            e.surface_rel_error = (e2 / n2).sqrt();
            e.worst_surface_case = ci;
        }
        e.surface_max_nodal_error_mm = e.surface_max_nodal_error_mm.max(emax);
        e.surface_max_nodal_rel_error = e.surface_max_nodal_rel_error.max(emax / umax);
        let comp = match model.near().and_then(|nf| nf.compliance_tensor(lf, bary)) {
            Some(t) => (0..3)
                .map(|d| (0..3).map(|k| c.dir[d] * t[d][k] * c.dir[k]).sum::<f64>())
                .sum::<f64>(),
            None => {
                let sp = SurfacePoint {
                    face: c.face,
                    bary: c.bary,
                    point: c.point,
                    normal: [0.0; 3],
                    distance_mm: 0.0,
                };
                dot(value_at(space, &full, &sp), c.dir)
            }
        };
        e.compliance_rel_error = e
            .compliance_rel_error
            .max((comp - c.compliance_mm_per_n).abs() / c.compliance_mm_per_n.abs());
    }
    Ok(e)
}
