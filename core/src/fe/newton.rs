//! Newton–Raphson for the hyperelastic palpation problem ([`super::hyper`]), with a
//! backtracking line search and adaptive stepping, under force or depth control.
//!
//! **Force control** (a dead load `F f̂`, fixed in the reference configuration): the
//! residual `R(u) = f_int(u) − Λ F f̂` is driven to zero for load factors Λ stepping
//! from 0 to 1.
//!
//! **Depth control** (the tool pushed to depth `d`, the force its reaction): the load
//! keeps its shape `f̂` (the unit disk load) and its magnitude `F` becomes an unknown,
//! with the constraint that the probe point moves by `d` along the tool axis,
//! `g(u) = n̂·u − d = 0` (`n̂` the point evaluation at `s` along `t`). Each Newton step
//! solves the bordered system with the one tangent factorization:
//!
//! ```text
//! K x₁ = R,  K x₂ = f̂,  ΔF = (n̂·x₁ − g) / (n̂·x₂),  Δu = ΔF x₂ − x₁
//! ```
//!
//! Depth control passes the force limit points that stop force control (where the
//! tissue softens, the force needed falls while the depth still rises), and is what a
//! haptic device does: depth in, force out. Past such a point the tangent `K` is no
//! longer positive definite while the state is still stable under depth control (`K`
//! is, on `n̂·δu = 0`): there the step is solved with `K + α n̂n̂ᵀ`, which gives the
//! same correction (see [`super::path`]); only where that fails too has the tissue
//! lost stability under the tool itself.
//!
//! Both step from 0 to the target: each step starts from the last converged state; a
//! step that fails (too many iterations, a growing residual, a tangent that is not
//! positive definite, an inverted element) is halved, and steps grow again after easy
//! convergence. Below a minimum step the solve stops with [`FeError::NoConvergence`],
//! saying how far it got: never a silent wrong answer. SVK loses stability in strong
//! compression, which is where that happens for it.

use std::time::Instant;

use rayon::prelude::*;

use super::elasticity::{assemble, cell_dofs};
use super::law::Law;
use super::space::Space;
use super::sparse::{Cholesky, SymCsc};
use super::{FeError, Material, StepFailure};

/// Global internal force on the free dofs at the all-node displacement `u`.
pub fn internal_force(space: &Space, law: Law, u: &[f64], lambda: f64, mu: f64) -> Vec<f64> {
    assemble_vector(space, |c, fe| {
        super::lanes::element_force(space, law, c, u, lambda, mu, fe);
    })
}

/// A global vector on the free dofs from per-cell vectors (`element(c, fe)` fills the
/// cell's `3·nodes` entries), cells in parallel.
pub fn assemble_vector<F>(space: &Space, element: F) -> Vec<f64>
where
    F: Fn(usize, &mut [f64]) + Sync,
{
    let all: Vec<usize> = (0..space.cell_count()).collect();
    assemble_vector_on(space, &all, element)
}

/// [`assemble_vector`] over the cells `cells` only (the others contribute zero).
pub fn assemble_vector_on<F>(space: &Space, cells: &[usize], element: F) -> Vec<f64>
where
    F: Fn(usize, &mut [f64]) + Sync,
{
    let m = 3 * space.element.nodes_per_cell();
    // The cells' vectors side by side, then added in the cells' order: the same sums
    // in the same order whatever the threads (one allocation, not two a cell).
    let mut parts = vec![0.0; cells.len() * m];
    parts
        .par_chunks_mut(m)
        .zip(cells.par_iter())
        .for_each(|(fe, &c)| {
            crate::cpu::clear_upper_halves();
            element(c, fe);
        });
    let mut out = vec![0.0; space.free_dofs];
    let mut dofs = Vec::with_capacity(m);
    for (&c, fe) in cells.iter().zip(parts.chunks_exact(m)) {
        cell_dofs(space, c, &mut dofs);
        for (d, v) in dofs.iter().zip(fe) {
            if *d != usize::MAX {
                out[*d] += v;
            }
        }
    }
    out
}

/// The tangent stiffness on the free dofs at `u`.
pub fn tangent(
    space: &Space,
    law: Law,
    pattern: &SymCsc,
    u: &[f64],
    lambda: f64,
    mu: f64,
) -> SymCsc {
    let mut k = pattern.clone();
    k.val.fill(0.0);
    assemble(space, &mut k, |c, ke| {
        super::lanes::element_tangent(space, law, c, u, lambda, mu, ke);
    });
    k
}

/// The tangent at the all-node displacement `u`, factored; a tangent that is not
/// positive definite is named with the count of fixed nodes (the usual cause at rest:
/// a body held nowhere).
pub fn factor_tangent(
    space: &Space,
    law: Law,
    pattern: &SymCsc,
    u: &[f64],
    lambda: f64,
    mu: f64,
) -> Result<Cholesky, FeError> {
    let k = tangent(space, law, pattern, u, lambda, mu);
    // `factor` names a failed factorization itself; wrapping its error again would
    // call a refusal for want of memory "not positive definite".
    Cholesky::factor(&k, space.fixed_count())
}

/// Newton settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonSettings {
    /// Converged when ‖R‖ ≤ rel_tol · ‖Λ f_ext‖.
    pub rel_tol: f64,
    pub max_iterations_per_step: usize,
    pub initial_step: f64,
    pub min_step: f64,
    /// Most Newton iterations over the whole solve, each a tangent factorization: a
    /// caller with a budget (a press's fallback, see [`super::path`]) stops here rather
    /// than cutting its step further. Unbounded by default.
    pub max_iterations: usize,
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
            max_iterations: usize::MAX,
        }
    }
}

/// What a nonlinear solve did.
#[derive(Debug, Clone, PartialEq, Default)]
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

/// The residual's absolute round-off floor, in units of `(λ + 2μ) ε L²` (`ε` the
/// machine epsilon, `L` the body's extent). The stresses' rounding does not shrink with
/// the strain (`I − C⁻¹` and `ln J` cancel to about `ε`), so however small a press, its
/// residual stalls near a fixed force: measured 1e-15 to 1e-12 N on coarse P1 at
/// depths from 1e-12 to 1e-5 mm, where `(λ + 2μ) ε L²` is about 2e-11 N. Without this
/// floor every press under about 0.1 mN failed its line search.
const ROUNDOFF_ABS: f64 = 10.0;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// What drives the solve.
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// The all-node load vector (N), applied in full.
    Force(Vec<f64>),
    /// The load's shape `f̂` (all-node, for a unit force) and the probe point's
    /// displacement functional `n̂` (all-node: `n̂·u` is the probe displacement along
    /// the tool axis, mm), pushed to `depth_mm`.
    Depth {
        shape: Vec<f64>,
        probe: Vec<f64>,
        depth_mm: f64,
    },
}

/// A converged nonlinear solve.
#[derive(Debug, Clone, PartialEq)]
pub struct NewtonSolution {
    /// All-node displacement (mm).
    pub u: Vec<f64>,
    /// The load factor reached (force control: 1; depth control: the force in N).
    pub force_n: f64,
    pub report: NewtonReport,
}

/// The fixed parts of one nonlinear problem on the free dofs.
struct Problem<'a> {
    space: &'a Space,
    law: Law,
    lambda: f64,
    mu: f64,
    pattern: SymCsc,
    /// Load shape (free dofs).
    shape: Vec<f64>,
    shape_norm: f64,
    /// Probe functional (free dofs); `None` under force control.
    probe: Option<Vec<f64>>,
    /// Force per mm of depth error in the merit (the linear stiffness at the probe).
    depth_weight: f64,
    /// Below this residual (N) no press can go, however small (see [`ROUNDOFF_ABS`]).
    roundoff_floor_n: f64,
    settings: NewtonSettings,
}

/// One Newton state: free-dof displacement and load factor.
#[derive(Clone)]
struct State {
    u: Vec<f64>,
    force: f64,
}

/// Solves the hyperelastic problem under `control`; `law` sets the material's form.
pub fn solve(
    space: &Space,
    law: Law,
    material: Material,
    control: &Control,
    settings: NewtonSettings,
) -> Result<NewtonSolution, FeError> {
    material.validate()?;
    let t0 = Instant::now();
    let (lambda, mu) = material.lame_n_per_mm2();
    let (shape, probe, target) = match control {
        Control::Force(f) => (space.restrict(f), None, 1.0),
        Control::Depth {
            shape,
            probe,
            depth_mm,
        } => {
            if !depth_mm.is_finite() {
                return Err(FeError::DepthNotFinite {
                    depth_mm: *depth_mm,
                });
            }
            (
                space.restrict(shape),
                Some(space.restrict(probe)),
                *depth_mm,
            )
        }
    };
    let mut report = NewtonReport::default();
    let state = State {
        u: vec![0.0; space.free_dofs],
        force: 0.0,
    };
    if target == 0.0 || shape.iter().all(|&v| v == 0.0) {
        // Nothing pushes: the rest state, exactly.
        return Ok(NewtonSolution {
            u: vec![0.0; 3 * space.nodes.len()],
            force_n: 0.0,
            report,
        });
    }
    let mut pb = Problem::new(space, law, (lambda, mu), shape, probe, settings);
    // A tangent beyond the memory is refused before any assembly.
    Cholesky::check_budget(&pb.pattern)?;
    if let Some(n) = &pb.probe {
        let c0 = rest_compliance(space, law, (lambda, mu), &pb.pattern, &pb.shape, n)?;
        pb.depth_weight = pb.shape_norm / c0.abs();
    }
    let state = pb.ramp(state, 0.0, target, &mut report)?;
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(NewtonSolution {
        u: space.expand(&state.u),
        force_n: if pb.probe.is_some() { state.force } else { 1.0 },
        report,
    })
}

/// The linear compliance at the probe, `n̂·K₀⁻¹f̂` (mm per unit force; `shape` and
/// `probe` on the free dofs), or [`FeError::ProbeNotMoved`] where the tool moves nothing.
fn rest_compliance(
    space: &Space,
    law: Law,
    (lambda, mu): (f64, f64),
    pattern: &SymCsc,
    shape: &[f64],
    probe: &[f64],
) -> Result<f64, FeError> {
    let rest = vec![0.0; 3 * space.nodes.len()];
    let chol = factor_tangent(space, law, pattern, &rest, lambda, mu)?;
    let x = chol.solve(shape);
    let c0: f64 = probe.iter().zip(&x).map(|(a, b)| a * b).sum();
    if !(c0.is_finite() && c0.abs() > 0.0) {
        return Err(FeError::ProbeNotMoved);
    }
    Ok(c0)
}

/// The linear stiffness at the probe, `1 / n̂·K₀⁻¹f̂` (N/mm; `shape` and `probe`
/// all-node): what [`continue_depth`] weighs the depth error with.
pub fn rest_stiffness_n_per_mm(
    space: &Space,
    law: Law,
    material: Material,
    (shape, probe): (&[f64], &[f64]),
) -> Result<f64, FeError> {
    material.validate()?;
    let pattern = SymCsc::pattern(space);
    Cholesky::check_budget(&pattern)?;
    let c0 = rest_compliance(
        space,
        law,
        material.lame_n_per_mm2(),
        &pattern,
        &space.restrict(shape),
        &space.restrict(probe),
    )?;
    Ok(1.0 / c0.abs())
}

/// Depth control from an equilibrium already reached: `start` is its depth (mm), force
/// (N) and all-node state (mm), and the solve steps from there to `depth_mm` as
/// [`solve`] steps from rest (the same line search, cuts and errors, the steps now
/// shares of `depth_mm − start depth`). `stiffness_n_per_mm` is the press's linear
/// stiffness at the probe (`1 / n̂·K₀⁻¹f̂`), which weighs the depth error in the merit;
/// the caller has it, so the rest tangent is not factored again. This is what a press
/// followed along a depth grid ([`super::path`]) falls back on where its own
/// corrections find no equilibrium. `iterations` counts the Newton iterations (each a
/// tangent factorization) it spent, whether it converged or not, so the caller can keep
/// a budget ([`NewtonSettings::max_iterations`]).
#[allow(clippy::too_many_arguments)]
pub fn continue_depth(
    space: &Space,
    law: Law,
    material: Material,
    (shape, probe): (&[f64], &[f64]),
    stiffness_n_per_mm: f64,
    (start_mm, start_force_n, start_u): (f64, f64, &[f64]),
    depth_mm: f64,
    settings: NewtonSettings,
    iterations: &mut usize,
) -> Result<NewtonSolution, FeError> {
    material.validate()?;
    if !depth_mm.is_finite() {
        return Err(FeError::DepthNotFinite { depth_mm });
    }
    let t0 = Instant::now();
    let (lambda, mu) = material.lame_n_per_mm2();
    let mut pb = Problem::new(
        space,
        law,
        (lambda, mu),
        space.restrict(shape),
        Some(space.restrict(probe)),
        settings,
    );
    pb.depth_weight = pb.shape_norm * stiffness_n_per_mm.abs();
    let mut report = NewtonReport::default();
    let start = State {
        u: space.restrict(start_u),
        force: start_force_n,
    };
    let state = pb.ramp(start, start_mm, depth_mm, &mut report);
    *iterations += report.iterations;
    let state = state?;
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(NewtonSolution {
        u: space.expand(&state.u),
        force_n: state.force,
        report,
    })
}

impl<'a> Problem<'a> {
    /// The problem with the merit's depth weight still 0 (the caller sets it under
    /// depth control).
    fn new(
        space: &'a Space,
        law: Law,
        (lambda, mu): (f64, f64),
        shape: Vec<f64>,
        probe: Option<Vec<f64>>,
        settings: NewtonSettings,
    ) -> Self {
        Problem {
            space,
            law,
            lambda,
            mu,
            pattern: SymCsc::pattern(space),
            shape_norm: norm(&shape),
            shape,
            probe,
            depth_weight: 0.0,
            roundoff_floor_n: ROUNDOFF_ABS
                * (lambda + 2.0 * mu)
                * f64::EPSILON
                * extent_mm(space).powi(2),
            settings,
        }
    }

    /// Steps the target from `from` to `to` (load factors under force control, depths
    /// under depth control), each step from the last converged state: a failed step is
    /// halved, steps grow again after easy convergence, and below the minimum step the
    /// solve stops saying how far it got.
    fn ramp(
        &self,
        mut state: State,
        from: f64,
        to: f64,
        report: &mut NewtonReport,
    ) -> Result<State, FeError> {
        let settings = self.settings;
        let mut done = 0.0f64;
        let mut step = settings.initial_step.min(1.0);
        while done < 1.0 {
            let frac = (done + step).min(1.0);
            match self.step(from + frac * (to - from), &state, report) {
                Ok((next, residuals)) => {
                    state = next;
                    done = frac;
                    report.load_steps += 1;
                    if residuals.len() <= 6 {
                        step = (step * 1.5).min(1.0);
                    }
                    report.last_step_residuals = residuals;
                }
                Err(why) => {
                    report.step_cuts += 1;
                    step *= 0.5;
                    let spent = matches!(why, StepFailure::Budget { .. });
                    if spent || step < settings.min_step {
                        let advice = match self.law {
                            Law::Svk => {
                                "Saint Venant–Kirchhoff loses stability under large \
                                 compression: press less, or use the neo-Hookean law"
                            }
                            Law::NeoHookean => "the mesh may be too coarse for this deformation",
                        };
                        return Err(match self.probe {
                            None => FeError::NoConvergence {
                                law: self.law.name(),
                                reached_share: from + done * (to - from),
                                why,
                                min_step: settings.min_step,
                                advice,
                            },
                            Some(_) => FeError::NoConvergenceDepth {
                                law: self.law.name(),
                                reached_mm: from + done * (to - from),
                                target_mm: to,
                                force_n: state.force,
                                why,
                                min_step: settings.min_step,
                                advice,
                            },
                        });
                    }
                }
            }
        }
        Ok(state)
    }

    /// `R(u, F) = f_int(u) − F f̂` and, under depth control, `g = n̂·u − d`.
    fn residual(&self, st: &State, target: f64) -> (Vec<f64>, f64) {
        let full = self.space.expand(&st.u);
        let fi = internal_force(self.space, self.law, &full, self.lambda, self.mu);
        let force = if self.probe.is_some() {
            st.force
        } else {
            target
        };
        let r = fi
            .iter()
            .zip(&self.shape)
            .map(|(a, b)| a - force * b)
            .collect();
        let g = self.probe.as_ref().map_or(0.0, |n| {
            n.iter().zip(&st.u).map(|(a, b)| a * b).sum::<f64>() - target
        });
        (r, g)
    }

    /// The merit the line search decreases: `√(‖R‖² + (w g)²)` (force units).
    fn merit(&self, r: &[f64], g: f64) -> f64 {
        (norm(r).powi(2) + (self.depth_weight * g).powi(2)).sqrt()
    }

    /// Newton iterations from `start` to the target (load factor or depth).
    fn step(
        &self,
        target: f64,
        start: &State,
        report: &mut NewtonReport,
    ) -> Result<(State, Vec<f64>), StepFailure> {
        let settings = self.settings;
        let mut st = start.clone();
        let (mut r, mut g) = self.residual(&st, target);
        let mut rn = self.merit(&r, g);
        let mut history = vec![rn];
        // Force scale: the target load, or under depth control the linear estimate of
        // the force at this depth (the current force once it is larger). Magnitudes: a
        // negative depth is a pull, whose force is as large as a push's.
        let scale = match self.probe {
            None => self.shape_norm * target.abs(),
            Some(_) => (self.depth_weight * target.abs()).max(self.shape_norm * st.force.abs()),
        }
        .max(f64::MIN_POSITIVE);
        let tol = settings.rel_tol * scale;
        // Where the residual may stall and still count as converged: round-off in the
        // internal forces, relative for a large press, absolute for a tiny one.
        let floor = (ROUNDOFF_REL * scale).max(self.roundoff_floor_n);
        for _ in 0..settings.max_iterations_per_step {
            if rn <= tol {
                return Ok((st, history));
            }
            if report.iterations >= settings.max_iterations {
                return Err(StepFailure::Budget {
                    factorizations: settings.max_iterations,
                });
            }
            report.iterations += 1;
            let all = self.space.expand(&st.u);
            let (du, df) = match &self.probe {
                None => {
                    let k = tangent(
                        self.space,
                        self.law,
                        &self.pattern,
                        &all,
                        self.lambda,
                        self.mu,
                    );
                    let chol = Cholesky::factor(&k, self.space.fixed_count())
                        .map_err(|e| StepFailure::Tangent(e.to_string()))?;
                    (chol.solve(&r).iter().map(|v| -v).collect::<Vec<_>>(), 0.0)
                }
                Some(n) => {
                    let (chol, aug) = factor_bordered(
                        self.space,
                        self.law,
                        &self.pattern,
                        &all,
                        (self.lambda, self.mu),
                        n,
                        false,
                    )
                    .map_err(|e| StepFailure::Tangent(e.to_string()))?
                    .ok_or_else(|| {
                        StepFailure::Tangent(
                            "not positive definite even under the tool's constraint: the \
                             tissue is unstable under depth control"
                                .into(),
                        )
                    })?;
                    let x1 = aug.solve(&chol, &r, g);
                    let x2 = chol.solve(&self.shape);
                    let dot =
                        |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
                    let df = (dot(n, &x1) - g) / dot(n, &x2);
                    let du = x2.iter().zip(&x1).map(|(b, a)| df * b - a).collect();
                    (du, df)
                }
            };
            // Backtracking line search on the merit (Armijo-like sufficient decrease).
            let mut alpha = 1.0;
            loop {
                let trial = State {
                    u: st.u.iter().zip(&du).map(|(a, d)| a + alpha * d).collect(),
                    force: st.force + alpha * df,
                };
                let (rt, gt) = self.residual(&trial, target);
                let mt = self.merit(&rt, gt);
                if mt.is_finite() && mt <= (1.0 - 1e-4 * alpha) * rn {
                    st = trial;
                    (r, g, rn) = (rt, gt, mt);
                    break;
                }
                if alpha == 1.0 && mt <= self.roundoff_floor_n {
                    // The full Newton step lands within the absolute round-off floor:
                    // converged as far as arithmetic can tell. For a press so small that
                    // its load is itself near the floor this is the linear answer, exact
                    // to round-off; a backtracking search there would take whichever
                    // partial step the noise favours.
                    history.push(mt);
                    return Ok((trial, history));
                }
                alpha *= 0.5;
                if alpha < 1.0 / 64.0 {
                    // No decrease possible: either we sit at the round-off floor of the
                    // residual (cancellation among stiff element forces), which counts
                    // as converged, or Newton is lost.
                    if rn <= floor {
                        return Ok((st, history));
                    }
                    return Err(StepFailure::LineSearch { residual_n: rn });
                }
            }
            let previous = history[history.len() - 1];
            history.push(rn);
            // Stagnation at the round-off floor: converged as far as arithmetic allows.
            if rn > 0.5 * previous && rn <= floor {
                return Ok((st, history));
            }
        }
        if rn <= tol {
            Ok((st, history))
        } else {
            Err(StepFailure::Iterations {
                iterations: settings.max_iterations_per_step,
                residual_n: rn,
            })
        }
    }
}

/// The diagonal of the nodes' bounding box (mm).
fn extent_mm(space: &Space) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &space.nodes {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let d2: f64 = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum();
    if d2.is_finite() { d2.sqrt() } else { 0.0 }
}

/// A tangent factored as `K_α = K + α n̂n̂ᵀ` (α > 0) where `K` alone is not positive
/// definite: past a force limit point under depth control the equilibrium is stable
/// (K is positive definite on `n̂·δu = 0`) while `K` has a negative direction, and
/// Cholesky fails. Since every step also fixes `n̂·δu`, `K_α` gives the same
/// corrections: `K_α δu = K δu + α n̂ (n̂·δu)` with `n̂·δu` known. `z = K_α⁻¹ n̂`.
#[derive(Clone, Default)]
pub(super) struct Augment {
    pub(super) alpha: f64,
    pub(super) z: Vec<f64>,
}

impl Augment {
    /// `K_α⁻¹ (r + α g n̂)`: the chord's `K⁻¹ r` for a step that makes `n̂·δu = −g`.
    pub(super) fn solve(&self, k: &Cholesky, r: &[f64], g: f64) -> Vec<f64> {
        let mut x = k.solve(r);
        if self.alpha > 0.0 {
            x.iter_mut()
                .zip(&self.z)
                .for_each(|(a, b)| *a += self.alpha * g * b);
        }
        x
    }
}

/// The tangent at `u` factored, augmented by `α n̂n̂ᵀ` where it is not positive
/// definite (see [`Augment`]); `α` starts at a hundred times the largest diagonal
/// entry on the probe's dofs and grows a hundredfold once. `None` where even that
/// fails: the state is unstable under depth control too.
pub(super) fn factor_bordered(
    space: &Space,
    law: Law,
    pattern: &SymCsc,
    u: &[f64],
    (lambda, mu): (f64, f64),
    probe: &[f64],
    always: bool,
) -> Result<Option<(Cholesky, Augment)>, FeError> {
    // Single precision: the segment's factor only steers the corrections (see the
    // module doc), so its rounding changes the steps, not the equilibrium.
    let factor = |k: &SymCsc| Cholesky::factor_single(k, space.fixed_count());
    let k = tangent(space, law, pattern, u, lambda, mu);
    if !always {
        match factor(&k) {
            Ok(c) => return Ok(Some((c, Augment::default()))),
            Err(FeError::NotPositiveDefinite { .. }) => {}
            Err(e) => return Err(e),
        }
    }
    let support: Vec<usize> = (0..probe.len()).filter(|&i| probe[i] != 0.0).collect();
    let diagonal = |i: usize| {
        let (lo, hi) = (k.col_ptr[i], k.col_ptr[i + 1]);
        (lo..hi)
            .find(|&q| k.row_idx[q] == i)
            .map_or(0.0, |q| k.val[q].abs())
    };
    let top = support.iter().map(|&i| diagonal(i)).fold(0.0f64, f64::max);
    for alpha in [1e2 * top, 1e4 * top] {
        if !(alpha.is_finite() && alpha > 0.0) {
            break;
        }
        let mut ka = k.clone();
        for &c in &support {
            for &r in support.iter().filter(|&&r| r >= c) {
                if !ka.has(r, c) {
                    // One face's nodes share a cell, so this does not happen; if it
                    // did, the augmentation would not be rank one.
                    return Ok(None);
                }
                ka.add(r, c, alpha * probe[r] * probe[c]);
            }
        }
        match factor(&ka) {
            Ok(chol) => {
                let z = chol.solve(probe);
                return Ok(Some((chol, Augment { alpha, z })));
            }
            Err(FeError::NotPositiveDefinite { .. }) => continue,
            Err(e) => return Err(e),
        }
    }
    Ok(None)
}
