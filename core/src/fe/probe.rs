//! One full FE solve of the palpation problem: project the probe point onto the
//! palpable region, build the probe load, solve, and report what the CLI and the PGD
//! validation need.

use std::time::Instant;

use super::elasticity::LinearProblem;
use super::law::Law;
use super::load::probe_functional;
use super::load::{SurfacePoint, probe_load, project, value_at};
use super::newton::{self, Control, NewtonReport, NewtonSettings};
use super::space::Space;
use super::{Element, FeError, Material};
use crate::mesh::{dot, sub};
use crate::organ::OrganMesh;

/// What to press, where and how hard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeRequest {
    /// Any point; it is projected to the closest point of the palpable region.
    pub at: [f64; 3],
    pub force_n: f64,
    /// Load direction; `None` = the inward normal at the probe point.
    pub dir: Option<[f64; 3]>,
    pub radius_mm: f64,
    /// A nodule in the organ (checked against it before the solve), or none.
    pub nodule: Option<super::nodule::Nodule>,
}

impl ProbeRequest {
    /// 1 N along `dir` at `at` with the default tool (5 mm), no nodule: the press every
    /// accuracy check compares at.
    pub fn unit(at: [f64; 3], dir: [f64; 3]) -> ProbeRequest {
        ProbeRequest {
            at,
            force_n: 1.0,
            dir: Some(dir),
            radius_mm: 5.0,
            nodule: None,
        }
    }
}

/// A solved probe problem.
#[derive(Debug, Clone)]
pub struct ProbeSolution {
    pub probe: SurfacePoint,
    /// Unit load direction.
    pub dir: [f64; 3],
    /// All-node load vector (N).
    pub load: Vec<f64>,
    /// All-node displacement (mm).
    pub u: Vec<f64>,
    /// Displacement at the probe point along the load direction (mm).
    pub probe_displacement_mm: f64,
    /// The tool's force (N): as requested under force control, the reaction under
    /// depth control.
    pub force_n: f64,
    pub max_displacement_mm: f64,
    pub assembly_s: f64,
    pub factor_s: f64,
    pub solve_s: f64,
}

/// The space of an organ mesh; its faces are the organ's boundary triangles, in order.
pub fn organ_space(organ: &OrganMesh, element: Element) -> Space {
    Space::new(&organ.mesh, &organ.boundary, &organ.fixed, element)
}

/// The space of a request: the organ's, with the request's nodule (checked) on its
/// cells.
pub fn request_space(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    req: &ProbeRequest,
) -> Result<Space, FeError> {
    let space = organ_space(organ, element);
    match &req.nodule {
        Some(n) => {
            n.check(organ)?;
            Ok(space.with_nodule(n, material.poisson))
        }
        None => Ok(space),
    }
}

/// Projects the request onto the palpable region and builds its unit direction.
pub fn locate(
    space: &Space,
    organ: &OrganMesh,
    req: &ProbeRequest,
) -> Result<(SurfacePoint, [f64; 3]), FeError> {
    if req.at.iter().any(|c| !c.is_finite()) {
        return Err(FeError::PointNotFinite { point: req.at });
    }
    let probe = project(space, &organ.palpable, req.at).ok_or(FeError::NoPalpableSurface)?;
    let dir = match req.dir {
        Some(d) => {
            let l = dot(d, d).sqrt();
            if !(l.is_finite() && l > 0.0) {
                return Err(FeError::NoDirection { dir: d });
            }
            d.map(|v| v / l)
        }
        None => probe.normal.map(|v| -v),
    };
    Ok((probe, dir))
}

/// The inward direction the app presses along at `at`: the boundary's area-weighted
/// vertex normals (from `f32` positions, as a scene computes them) interpolated with
/// the probe point's barycentric weights and normalized; the direction of a scene's
/// contact law (`PalpationScene::frame`) and of every press a tissue build makes. It
/// is smooth across edges, where a face's own normal (`locate`'s default) jumps by
/// the dihedral angle: next to the fixed region the two differ enough to change the
/// force by 15 % (docs/lab/tissue-measurements.md §11). `at` is projected as `locate`
/// projects it.
pub fn smooth_inward_dir(organ: &OrganMesh, at: [f64; 3]) -> Result<[f64; 3], FeError> {
    let space = organ_space(organ, Element::P1);
    let req = ProbeRequest {
        at,
        force_n: f64::NAN,
        dir: None,
        radius_mm: 0.0,
        nodule: None,
    };
    let (probe, face_inward) = locate(&space, organ, &req)?;
    let normals = organ_vertex_normals(organ);
    let corners = organ.boundary[probe.face];
    let mut n = [0.0; 3];
    for (k, &v) in corners.iter().enumerate() {
        for (c, x) in n.iter_mut().enumerate() {
            *x -= probe.bary[k] * f64::from(normals[v as usize][c]);
        }
    }
    let len = dot(n, n).sqrt();
    // Opposite corner normals could cancel on a degenerate surface: keep the face's.
    Ok(if len > 1e-12 {
        n.map(|c| c / len)
    } else {
        face_inward
    })
}

/// The area-weighted outward vertex normals of the organ's boundary, from `f32`
/// positions (as a scene computes them from its stored vertices).
pub fn organ_vertex_normals(organ: &OrganMesh) -> Vec<[f32; 3]> {
    let vertices: Vec<[f32; 3]> = organ
        .mesh
        .vertices
        .iter()
        .map(|p| p.map(|x| x as f32))
        .collect();
    crate::mesh::vertex_normals(&vertices, &organ.boundary)
}

/// Linear-elastic solve of one probe request.
pub fn solve_linear(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    req: &ProbeRequest,
) -> Result<ProbeSolution, FeError> {
    let space = request_space(organ, element, material, req)?;
    let (probe, dir) = locate(&space, organ, req)?;
    let load = probe_load(&space, &probe, dir, req.force_n, req.radius_mm)?;
    let problem = LinearProblem::new(&space, material)?;
    let t = Instant::now();
    let u = problem.solve(&space, &load);
    let solve_s = t.elapsed().as_secs_f64();
    let mut sol = summarize(
        &space,
        probe,
        dir,
        load,
        u,
        problem.assembly_s,
        problem.factor_s,
        solve_s,
    );
    sol.force_n = req.force_n;
    Ok(sol)
}

/// Linear solve pushed to a depth: the response to 1 N scaled so that the probe point
/// moves `depth_mm` along the tool axis (exact: the problem is linear).
pub fn solve_linear_depth(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    req: &ProbeRequest,
    depth_mm: f64,
) -> Result<ProbeSolution, FeError> {
    if !depth_mm.is_finite() {
        return Err(FeError::DepthNotFinite { depth_mm });
    }
    let unit = solve_linear(
        organ,
        element,
        material,
        &ProbeRequest {
            force_n: 1.0,
            ..*req
        },
    )?;
    let c = unit.probe_displacement_mm;
    if !(c.is_finite() && c.abs() > 0.0) {
        return Err(FeError::ProbeNotMoved);
    }
    let k = depth_mm / c;
    let mut sol = unit;
    sol.u.iter_mut().for_each(|v| *v *= k);
    sol.load.iter_mut().for_each(|v| *v *= k);
    sol.probe_displacement_mm *= k;
    sol.max_displacement_mm *= k.abs();
    sol.force_n = k;
    Ok(sol)
}

/// Hyperelastic solve of one probe request: under force control (`depth_mm` `None`) a
/// dead load of `req.force_n`; under depth control the tool pushed until the probe
/// point has moved `depth_mm` along its axis (`req.force_n` is not used; the force is
/// the result). See [`newton`].
pub fn solve_hyperelastic(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    law: Law,
    req: &ProbeRequest,
    depth_mm: Option<f64>,
    settings: NewtonSettings,
) -> Result<(ProbeSolution, NewtonReport), FeError> {
    let space = request_space(organ, element, material, req)?;
    let (probe, dir) = locate(&space, organ, req)?;
    let control = match depth_mm {
        None => Control::Force(probe_load(&space, &probe, dir, req.force_n, req.radius_mm)?),
        Some(d) => {
            if !d.is_finite() {
                return Err(FeError::DepthNotFinite { depth_mm: d });
            }
            check_thickness(&space, probe.point, dir, d)?;
            Control::Depth {
                shape: probe_load(&space, &probe, dir, 1.0, req.radius_mm)?,
                probe: probe_functional(&space, &probe, dir),
                depth_mm: d,
            }
        }
    };
    let sol = newton::solve(&space, law, material, &control, settings)?;
    let (load, force_n) = match control {
        Control::Force(load) => (load, req.force_n),
        Control::Depth { shape, .. } => {
            (shape.iter().map(|v| v * sol.force_n).collect(), sol.force_n)
        }
    };
    let s = sol.report.seconds;
    let mut out = summarize(&space, probe, dir, load, sol.u, 0.0, 0.0, s);
    out.force_n = force_n;
    Ok((out, sol.report))
}

/// Refuses a depth that would push the tool through the organ: at or past the
/// organ's thickness along the push from the probe point (its farthest node along
/// `dir`). Newton would only report, after halving its first step ten times, that it
/// found no equilibrium.
fn check_thickness(
    space: &Space,
    at: [f64; 3],
    dir: [f64; 3],
    depth_mm: f64,
) -> Result<(), FeError> {
    let thickness_mm = space
        .nodes
        .iter()
        .map(|x| dot(sub(*x, at), dir))
        .fold(0.0, f64::max);
    if depth_mm >= thickness_mm {
        return Err(FeError::DepthThroughOrgan {
            depth_mm,
            thickness_mm,
        });
    }
    Ok(())
}

/// One depth of [`solve_hyperelastic_depths`]: its solution and Newton's report, or why
/// no equilibrium was found there.
pub type DepthSolve = Result<(ProbeSolution, NewtonReport), FeError>;

/// Depth-controlled presses of one probe at several depths, as one path: the depths
/// are solved in increasing order, each by Newton from the equilibrium of the depth
/// before ([`newton::continue_depth`]), and where that finds none, from rest as
/// [`solve_hyperelastic`] does. Where the press is one path of equilibria (no branch
/// between the depths), both reach the same state to Newton's tolerance; the path is
/// cheaper, since a depth starts from a state near its own and the rest stiffness is
/// factored once. Returned in the order asked, each with its own report (its seconds
/// those of its own step).
pub fn solve_hyperelastic_depths(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    law: Law,
    req: &ProbeRequest,
    depths_mm: &[f64],
    settings: NewtonSettings,
) -> Result<Vec<DepthSolve>, FeError> {
    if let Some(&d) = depths_mm.iter().find(|d| !d.is_finite()) {
        return Err(FeError::DepthNotFinite { depth_mm: d });
    }
    let space = request_space(organ, element, material, req)?;
    let (probe, dir) = locate(&space, organ, req)?;
    let shape = probe_load(&space, &probe, dir, 1.0, req.radius_mm)?;
    let functional = probe_functional(&space, &probe, dir);
    let stiffness = newton::rest_stiffness_n_per_mm(&space, law, material, (&shape, &functional))?;
    let mut order: Vec<usize> = (0..depths_mm.len()).collect();
    order.sort_by(|&a, &b| depths_mm[a].total_cmp(&depths_mm[b]));
    let mut out: Vec<Option<DepthSolve>> = (0..depths_mm.len()).map(|_| None).collect();
    // The last equilibrium reached: depth, force, all-node state.
    let mut last = (0.0, 0.0, vec![0.0; shape.len()]);
    for i in order {
        let d = depths_mm[i];
        if let Err(e) = check_thickness(&space, probe.point, dir, d) {
            out[i] = Some(Err(e));
            continue;
        }
        let t = Instant::now();
        let mut spent = 0usize;
        let from_last = newton::continue_depth(
            &space,
            law,
            material,
            (&shape, &functional),
            stiffness,
            (last.0, last.1, &last.2),
            d,
            settings,
            &mut spent,
        );
        let sol = match from_last {
            Ok(sol) => Ok(sol),
            Err(_) if last.0 != 0.0 => {
                let control = Control::Depth {
                    shape: shape.clone(),
                    probe: functional.clone(),
                    depth_mm: d,
                };
                newton::solve(&space, law, material, &control, settings)
            }
            Err(e) => Err(e),
        };
        out[i] = Some(sol.map(|mut sol| {
            sol.report.seconds = t.elapsed().as_secs_f64();
            last = (d, sol.force_n, sol.u.clone());
            let load = shape.iter().map(|v| v * sol.force_n).collect();
            let s = sol.report.seconds;
            let mut p = summarize(&space, probe, dir, load, sol.u, 0.0, 0.0, s);
            p.force_n = sol.force_n;
            (p, sol.report)
        }));
    }
    Ok(out.into_iter().flatten().collect())
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn summarize(
    space: &Space,
    probe: SurfacePoint,
    dir: [f64; 3],
    load: Vec<f64>,
    u: Vec<f64>,
    assembly_s: f64,
    factor_s: f64,
    solve_s: f64,
) -> ProbeSolution {
    let us = value_at(space, &u, &probe);
    let max = u
        .chunks_exact(3)
        .map(|v| dot([v[0], v[1], v[2]], [v[0], v[1], v[2]]).sqrt())
        .fold(0.0, f64::max);
    ProbeSolution {
        probe,
        dir,
        load,
        probe_displacement_mm: dot(us, dir),
        force_n: f64::NAN,
        max_displacement_mm: max,
        u,
        assembly_s,
        factor_s,
        solve_s,
    }
}

/// Depth (mm) beyond which [`solve_series`] continues the expansion.
pub const CONTINUE_BEYOND_MM: f64 = 6.0;

/// Hyperelastic depth-controlled press by its power series in the depth
/// ([`super::series`]): `orders` linear solves with the rest stiffness, then the
/// solution at `depth_mm` from the series' highest pole-free Padé form (which carries
/// it past the series' radius of convergence). Deeper than [`CONTINUE_BEYOND_MM`] the
/// press is expanded again about its state at 55 % of the depth (the split is
/// returned): at the anterior point on coarse P2 that took the largest nodal error at
/// 15 mm from 1.04 to 0.034 mm.
pub fn solve_series(
    organ: &OrganMesh,
    element: Element,
    material: Material,
    law: Law,
    req: &ProbeRequest,
    depth_mm: f64,
    orders: usize,
) -> Result<(ProbeSolution, super::series::DepthSeries, Option<f64>), FeError> {
    if !depth_mm.is_finite() {
        return Err(FeError::DepthNotFinite { depth_mm });
    }
    super::series::check_orders(orders, 1)?;
    let space = request_space(organ, element, material, req)?;
    let (probe, dir) = locate(&space, organ, req)?;
    let shape = probe_load(&space, &probe, dir, 1.0, req.radius_mm)?;
    let functional = probe_functional(&space, &probe, dir);
    // Deep presses continue from the state at 55 % of the depth: one series alone
    // keeps the force past its radius (through its Padé form) but not the surface.
    let (series, force_n, u, continued_at) = if depth_mm > CONTINUE_BEYOND_MM {
        let c = super::series::continued_series(
            &space,
            law,
            material,
            &shape,
            &functional,
            0.55 * depth_mm,
            orders,
        )?;
        let (f, u) = c.evaluate(depth_mm, depth_mm);
        (c.first, f, u, Some(c.split_mm))
    } else {
        let series =
            super::series::depth_series(&space, law, material, &shape, &functional, orders)?;
        let rational = series.rational(depth_mm);
        let (f, u) = series.evaluate(&rational, depth_mm);
        (series, f, u, None)
    };
    let load = shape.iter().map(|v| v * force_n).collect();
    let mut out = summarize(
        &space,
        probe,
        dir,
        load,
        u,
        0.0,
        series.factor_s,
        series.seconds - series.factor_s,
    );
    out.force_n = force_n;
    Ok((out, series, continued_at))
}
