//! Saint Venant–Kirchhoff hyperelasticity, Total Lagrangian, solved by Newton–Raphson
//! with a backtracking line search and adaptive load stepping.
//!
//! With `F = I + ∇u` (gradients in the reference configuration), Green strain
//! `E = ½(FᵀF − I)` and second Piola–Kirchhoff stress `S = λ tr(E) I + 2μ E`:
//!
//! ```text
//! internal force   f_int[a,i]        = ∫ (F S)_iK  ∂_K N_a dV
//! tangent          K[(a,i),(b,k)]    = ∫ δ_ik ∇N_a·S·∇N_b                 (geometric)
//!                                    + ∫ δE^(a,i) : ℂ : δE^(b,k)          (material)
//! with δE^(a,i)_JK = ½(F_iJ ∂_K N_a + F_iK ∂_J N_a), ℂ = λ I⊗I + 2μ 𝕀.
//! ```
//!
//! The load is *dead* (fixed direction and magnitude in the reference configuration).
//! The residual `R(u) = f_int(u) − Λ f_ext` is driven to zero for load factors Λ
//! stepping from 0 to 1: each step starts from the last converged state; a step that
//! fails (too many iterations, a growing residual, a tangent that is not positive
//! definite) is halved, and steps grow again after easy convergence. Below a minimum
//! step the solve stops with [`FeError::NoConvergence`], saying the load fraction
//! reached: never a silent wrong answer. SVK is known to lose stability in strong
//! compression (its energy does not grow without bound as volume → 0), which is where
//! that happens.
//!
//! Quadrature: degree 4 (Keast, 11 points) for P2, whose SVK integrands are quartic;
//! one point for P1 (constant gradients).

use std::time::Instant;

use rayon::prelude::*;

use super::elasticity::{assemble, cell_dofs};
use super::shape::{TET_DEGREE1, TET_DEGREE4, barycentric_gradients, tet_gradients};
use super::space::Space;
use super::sparse::{Cholesky, SymCsc};
use super::{Element, FeError, Material};

type M3 = [[f64; 3]; 3];

/// Element internal force `fe` (3·npc) and, if asked, tangent `ke` (row-major) of cell
/// `c` at the all-node displacement `u`.
pub fn element(
    space: &Space,
    c: usize,
    u: &[f64],
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
    ke: Option<&mut [f64]>,
) {
    let p2 = space.element == Element::P2;
    let npc = space.element.nodes_per_cell();
    let m = 3 * npc;
    fe[..m].fill(0.0);
    let mut ke = ke;
    if let Some(k) = ke.as_deref_mut() {
        k[..m * m].fill(0.0);
    }
    let cell = space.cell(c);
    let (gl, vol) =
        barycentric_gradients(space.cell_corners(c)).expect("mesh has no degenerate tetrahedra");
    let rule = if p2 { &TET_DEGREE4 } else { &TET_DEGREE1 };
    let mut g = [[0.0; 3]; 10];
    let mut de = vec![[[0.0; 3]; 3]; m];
    for (l, w) in rule.points.iter().zip(rule.weights) {
        tet_gradients(p2, *l, &gl, &mut g);
        let wv = w * vol;
        // F = I + Σ_a u_a ⊗ g_a
        let mut f: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for a in 0..npc {
            let n = cell[a] as usize;
            for i in 0..3 {
                for j in 0..3 {
                    f[i][j] += u[3 * n + i] * g[a][j];
                }
            }
        }
        let mut e: M3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                let ftf: f64 = (0..3).map(|k| f[k][i] * f[k][j]).sum();
                e[i][j] = 0.5 * (ftf - if i == j { 1.0 } else { 0.0 });
            }
        }
        let tr = e[0][0] + e[1][1] + e[2][2];
        let mut s: M3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] = 2.0 * mu * e[i][j] + if i == j { lambda * tr } else { 0.0 };
            }
        }
        // P = F S (first Piola–Kirchhoff)
        let mut p: M3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for k in 0..3 {
                p[i][k] = (0..3).map(|j| f[i][j] * s[j][k]).sum();
            }
        }
        for a in 0..npc {
            for i in 0..3 {
                fe[3 * a + i] += wv * (0..3).map(|k| p[i][k] * g[a][k]).sum::<f64>();
            }
        }
        let Some(k) = ke.as_deref_mut() else { continue };
        for a in 0..npc {
            for i in 0..3 {
                let d = &mut de[3 * a + i];
                for jj in 0..3 {
                    for kk in 0..3 {
                        d[jj][kk] = 0.5 * (f[i][jj] * g[a][kk] + f[i][kk] * g[a][jj]);
                    }
                }
            }
        }
        let trs: Vec<f64> = de.iter().map(|d| d[0][0] + d[1][1] + d[2][2]).collect();
        for a in 0..npc {
            let sga = [0, 1, 2].map(|j| (0..3).map(|kk| s[j][kk] * g[a][kk]).sum::<f64>());
            for b in 0..npc {
                let geo = wv * (0..3).map(|j| g[b][j] * sga[j]).sum::<f64>();
                for i in 0..3 {
                    let r = 3 * a + i;
                    for kc in 0..3 {
                        let col = 3 * b + kc;
                        let mut v = lambda * trs[r] * trs[col];
                        let (x, y) = (&de[r], &de[col]);
                        let mut dd = 0.0;
                        for jj in 0..3 {
                            for kk in 0..3 {
                                dd += x[jj][kk] * y[jj][kk];
                            }
                        }
                        v += 2.0 * mu * dd;
                        k[r * m + col] += wv * v + if i == kc { geo } else { 0.0 };
                    }
                }
            }
        }
    }
}

/// Global internal force on the free dofs at the all-node displacement `u`.
pub fn internal_force(space: &Space, u: &[f64], lambda: f64, mu: f64) -> Vec<f64> {
    let m = 3 * space.element.nodes_per_cell();
    let parts: Vec<(Vec<usize>, Vec<f64>)> = (0..space.cell_count())
        .into_par_iter()
        .map(|c| {
            let mut fe = vec![0.0; m];
            element(space, c, u, lambda, mu, &mut fe, None);
            let mut dofs = Vec::with_capacity(m);
            cell_dofs(space, c, &mut dofs);
            (dofs, fe)
        })
        .collect();
    let mut out = vec![0.0; space.free_dofs];
    for (dofs, fe) in parts {
        for (d, v) in dofs.iter().zip(fe) {
            if *d != usize::MAX {
                out[*d] += v;
            }
        }
    }
    out
}

/// The tangent stiffness on the free dofs at `u`.
pub fn tangent(space: &Space, pattern: &SymCsc, u: &[f64], lambda: f64, mu: f64) -> SymCsc {
    let mut k = pattern.clone();
    k.val.fill(0.0);
    let m = 3 * space.element.nodes_per_cell();
    assemble(space, &mut k, |c, ke| {
        let mut fe = vec![0.0; m];
        element(space, c, u, lambda, mu, &mut fe, Some(ke));
    });
    k
}

/// Newton settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonSettings {
    /// Converged when ‖R‖ ≤ rel_tol · ‖Λ f_ext‖.
    pub rel_tol: f64,
    pub max_iterations_per_step: usize,
    pub initial_step: f64,
    pub min_step: f64,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        NewtonSettings {
            rel_tol: 1e-10,
            // Quadratic convergence needs 4–6 iterations from a good start; more means
            // the step is too large, and cutting it is cheaper than persisting.
            max_iterations_per_step: 12,
            initial_step: 1.0,
            min_step: 1.0 / 1024.0,
        }
    }
}

/// What a nonlinear solve did.
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonReport {
    pub iterations: usize,
    pub load_steps: usize,
    pub step_cuts: usize,
    /// Residual norms of the final load step's iterations (for convergence-rate checks).
    pub last_step_residuals: Vec<f64>,
    pub seconds: f64,
}

/// Below this fraction of the load the residual is dominated by round-off in the
/// assembly of the internal forces (stiff, nearly incompressible elements cancel).
const ROUNDOFF_REL: f64 = 1e-8;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Solves `f_int(u) = f_ext` (all-node `f_ext`), returning the all-node displacement.
pub fn solve(
    space: &Space,
    material: Material,
    f_ext: &[f64],
    settings: NewtonSettings,
) -> Result<(Vec<f64>, NewtonReport), FeError> {
    material.validate()?;
    let t0 = Instant::now();
    let (lambda, mu) = material.lame_n_per_mm2();
    let pattern = SymCsc::pattern(space);
    let fext = space.restrict(f_ext);
    let fext_norm = norm(&fext);
    let mut u_free = vec![0.0; space.free_dofs];
    let mut done = 0.0f64;
    let mut step = settings.initial_step.min(1.0);
    let mut report = NewtonReport {
        iterations: 0,
        load_steps: 0,
        step_cuts: 0,
        last_step_residuals: Vec::new(),
        seconds: 0.0,
    };
    while done < 1.0 {
        let target = (done + step).min(1.0);
        match newton_step(
            space,
            &pattern,
            lambda,
            mu,
            &fext,
            fext_norm * target,
            target,
            &u_free,
            settings,
            &mut report,
        ) {
            Ok((u_new, residuals)) => {
                u_free = u_new;
                done = target;
                report.load_steps += 1;
                if residuals.len() <= 6 {
                    step = (step * 1.5).min(1.0);
                }
                report.last_step_residuals = residuals;
            }
            Err(why) => {
                report.step_cuts += 1;
                step *= 0.5;
                if step < settings.min_step {
                    return Err(FeError::NoConvergence(format!(
                        "reached {:.1}% of the load ({}); the step fell below {} of the load. \
                         Saint Venant–Kirchhoff loses stability under large compression: reduce the force",
                        100.0 * done,
                        why,
                        settings.min_step
                    )));
                }
            }
        }
    }
    report.seconds = t0.elapsed().as_secs_f64();
    Ok((space.expand(&u_free), report))
}

#[allow(clippy::too_many_arguments)]
fn newton_step(
    space: &Space,
    pattern: &SymCsc,
    lambda: f64,
    mu: f64,
    fext: &[f64],
    load_norm: f64,
    factor: f64,
    u0: &[f64],
    settings: NewtonSettings,
    report: &mut NewtonReport,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let mut u = u0.to_vec();
    let residual = |u: &[f64]| -> Vec<f64> {
        let full = space.expand(u);
        let fi = internal_force(space, &full, lambda, mu);
        fi.iter().zip(fext).map(|(a, b)| a - factor * b).collect()
    };
    let mut r = residual(&u);
    let mut rn = norm(&r);
    let mut history = vec![rn];
    let tol = settings.rel_tol * load_norm.max(f64::MIN_POSITIVE);
    for _ in 0..settings.max_iterations_per_step {
        if rn <= tol {
            return Ok((u, history));
        }
        report.iterations += 1;
        let k = tangent(space, pattern, &space.expand(&u), lambda, mu);
        let chol = Cholesky::factor(&k, space.fixed_count())
            .map_err(|e| format!("tangent not positive definite: {e}"))?;
        let du = chol.solve(&r);
        // Backtracking line search on ‖R‖ (Armijo-like sufficient decrease).
        let mut alpha = 1.0;
        loop {
            let trial: Vec<f64> = u.iter().zip(&du).map(|(a, d)| a - alpha * d).collect();
            let rt = residual(&trial);
            let rtn = norm(&rt);
            if rtn.is_finite() && rtn <= (1.0 - 1e-4 * alpha) * rn {
                u = trial;
                r = rt;
                rn = rtn;
                break;
            }
            alpha *= 0.5;
            if alpha < 1.0 / 64.0 {
                // No decrease possible: either we sit at the round-off floor of the
                // residual (cancellation among stiff element forces), which counts as
                // converged, or Newton is lost.
                if rn <= ROUNDOFF_REL * load_norm.max(f64::MIN_POSITIVE) {
                    return Ok((u, history));
                }
                return Err(format!("line search failed at residual {rn:.3e} N"));
            }
        }
        let previous = history[history.len() - 1];
        history.push(rn);
        // Stagnation at the round-off floor: converged as far as arithmetic allows.
        if rn > 0.5 * previous && rn <= ROUNDOFF_REL * load_norm.max(f64::MIN_POSITIVE) {
            return Ok((u, history));
        }
    }
    if rn <= tol {
        Ok((u, history))
    } else {
        Err(format!(
            "no convergence in {} iterations (residual {rn:.3e} N)",
            settings.max_iterations_per_step
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TetMesh;
    use crate::rng::Rng;

    fn one_tet_space(element: Element) -> Space {
        let mesh = TetMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [10.0, 1.0, 0.5],
                [1.0, 9.0, 0.0],
                [0.5, 1.0, 11.0],
            ],
            tets: vec![[0, 1, 2, 3]],
        };
        Space::new(&mesh, &[], &[false; 4], element)
    }

    /// The tangent is the derivative of the internal force: central differences agree
    /// to O(ε²) at a random, moderately large deformation.
    #[test]
    fn tangent_matches_finite_differences_of_the_internal_force() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        for element in [Element::P1, Element::P2] {
            let space = one_tet_space(element);
            let m = 3 * element.nodes_per_cell();
            let mut rng = Rng::seed(5);
            let u: Vec<f64> = (0..m).map(|_| rng.range(-1.0, 1.0)).collect();
            let mut ke = vec![0.0; m * m];
            let mut fe = vec![0.0; m];
            element_fn(&space, &u, lambda, mu, &mut fe, Some(&mut ke));
            let eps = 1e-5;
            let mut worst: f64 = 0.0;
            let scale = ke.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            for j in 0..m {
                let mut up = u.clone();
                let mut dn = u.clone();
                up[j] += eps;
                dn[j] -= eps;
                let (mut fp, mut fm) = (vec![0.0; m], vec![0.0; m]);
                element_fn(&space, &up, lambda, mu, &mut fp, None);
                element_fn(&space, &dn, lambda, mu, &mut fm, None);
                for i in 0..m {
                    let fd = (fp[i] - fm[i]) / (2.0 * eps);
                    worst = worst.max((fd - ke[i * m + j]).abs());
                }
            }
            // Central differences: error O(ε² · third derivative) ≈ 1e-10 · scale.
            assert!(
                worst < 1e-7 * scale,
                "{element:?}: worst {worst:e}, scale {scale:e}"
            );
            // And the tangent is symmetric.
            for i in 0..m {
                for j in 0..m {
                    assert!((ke[i * m + j] - ke[j * m + i]).abs() <= 1e-12 * scale);
                }
            }
        }
    }

    fn element_fn(
        space: &Space,
        u: &[f64],
        lambda: f64,
        mu: f64,
        fe: &mut [f64],
        ke: Option<&mut [f64]>,
    ) {
        element(space, 0, u, lambda, mu, fe, ke);
    }
}
