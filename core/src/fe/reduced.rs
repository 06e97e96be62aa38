//! A press solved in a reduced space: the Galerkin projection of the bordered
//! depth-controlled problem on a basis `V` (free dofs, `n × r`, orthonormal).
//!
//! With `u = V a` the unknowns are the `r` coordinates `a` and the force `F`:
//!
//! ```text
//! Vᵀ (f_int(V a) − F f̂) = 0,        n̂·V a = d.
//! ```
//!
//! Newton on that bordered system needs the reduced tangent `J = Vᵀ K_t(V a) V`, the
//! reduced load `b = Vᵀ f̂` and the reduced probe `c = Vᵀ n̂`:
//!
//! ```text
//! [ J   −b ] [Δa]   [−Vᵀ(f_int − F f̂)]
//! [ cᵀ   0 ] [ΔF] = [ d − c·a         ]
//! ```
//!
//! `J` is formed at rest and kept from depth to depth, Broyden's update making it agree
//! with every pair of residuals assembled; it is formed again, at the current state,
//! only where the corrections stop shrinking. An optional [`Check`] takes one chord
//! step of the bordered problem on the whole mesh with a given factor and, where it
//! moves a node by more than its tolerance, adds that step to the basis and solves the
//! depth again.
//!
//! Why: the tissue build follows every press to equilibrium on the full mesh (one
//! factored tangent per segment, `fe::path`), which puts the whole coarse surface at
//! hours. Measured by `palpa bench fe --only reduced` (docs/tissue-measurements.md §10): a point's
//! own first six series orders alone give its press to 6 mm within 0.03 mm for about a
//! sixth of a full press, but not deeper (0.3–2.3 mm at 12–15 mm). The check with the
//! rest factor brings 12–15 mm within 0.05–0.23 mm, but it understates the error there
//! (the rest stiffness is not the tangent's action) and costs 0.6–0.8 of a full press.
//! [`krylov_correction`] approaches Newton's correction with the tangent's action
//! (conjugate gradients, the rest factor as preconditioner): 16 steps track the error
//! at 9 mm but understate it by up to half at 12 mm, for a quarter of a full press a
//! depth (§10 there). So the build does not use this module yet.

use std::time::Instant;

use super::hyper::Law;
use super::newton::{internal_force, tangent};
use super::series::solve_dense;
use super::space::Space;
use super::sparse::{Cholesky, SymCsc};
use super::{FeError, Material};

/// An orthonormal basis on the free dofs.
#[derive(Debug, Clone)]
pub struct Basis {
    pub cols: Vec<Vec<f64>>,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Basis {
    /// Orthonormalizes `vectors` (free dofs) in order by twice-repeated Gram–Schmidt,
    /// dropping a vector whose part outside the ones kept is below `drop` of its norm.
    pub fn orthonormal(vectors: impl IntoIterator<Item = Vec<f64>>, drop: f64) -> Basis {
        let mut cols: Vec<Vec<f64>> = Vec::new();
        for mut v in vectors {
            let norm0 = dot(&v, &v).sqrt();
            if !(norm0 > 0.0 && norm0.is_finite()) {
                continue;
            }
            for _ in 0..2 {
                for q in &cols {
                    let s = dot(q, &v);
                    v.iter_mut().zip(q).for_each(|(x, y)| *x -= s * y);
                }
            }
            let norm = dot(&v, &v).sqrt();
            if norm > drop * norm0 {
                v.iter_mut().for_each(|x| *x /= norm);
                cols.push(v);
            }
        }
        Basis { cols }
    }

    pub fn rank(&self) -> usize {
        self.cols.len()
    }

    /// `Vᵀ x`.
    pub fn project(&self, x: &[f64]) -> Vec<f64> {
        self.cols.iter().map(|q| dot(q, x)).collect()
    }

    /// `V a`.
    pub fn lift(&self, a: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.cols.first().map_or(0, Vec::len)];
        for (q, &s) in self.cols.iter().zip(a) {
            out.iter_mut().zip(q).for_each(|(x, y)| *x += s * y);
        }
        out
    }
}

/// A reduced press at the requested depths.
#[derive(Debug, Clone)]
pub struct ReducedPress {
    /// All-node states (mm) and forces (N) at the depths reached.
    pub u: Vec<Vec<f64>>,
    pub force_n: Vec<f64>,
    /// Per depth reached, the largest node of the last check's correction (mm; see
    /// [`Check`]), or zero where no check was asked for.
    pub check_mm: Vec<f64>,
    /// Reduced tangents formed, residuals assembled, solves with the check's factor,
    /// and vectors the check added to the basis, over all depths.
    pub tangents: usize,
    pub residuals: usize,
    pub solves: usize,
    pub added: usize,
    /// Seconds spent forming reduced tangents, assembling residuals, and in the check.
    pub tangent_s: f64,
    pub residual_s: f64,
    pub check_s: f64,
    /// The basis's rank at the end (the given one plus what the check added).
    pub rank: usize,
    /// Why it stopped before the last depth, if it did.
    pub stopped: Option<String>,
}

/// The check of a reduced state on the whole mesh: the correction a chord step with
/// `factor` (a factored stiffness, e.g. the shared rest one) would make there,
///
/// ```text
/// x = K⁻¹ R,  y = K⁻¹ f̂,  ΔF = n̂·x / n̂·y,  Δu = ΔF y − x,    R = f_int(u) − F f̂,
/// ```
///
/// the bordered step that keeps the depth. A depth is accepted when `Δu` moves no node
/// by more than `tolerance_mm` (the full press's trust rule, with this factor in place
/// of the segment's); otherwise `Δu` joins the basis and the depth is solved again
/// (at most `max_added` times a depth). The new column of the reduced tangent,
/// `Vᵀ K_t q`, is the directional derivative `(f_int(u + h q) − f_int(u)) / h`: one
/// more residual, no assembly.
#[derive(Clone, Copy)]
pub struct Check<'a> {
    pub factor: &'a Cholesky,
    pub tolerance_mm: f64,
    pub max_added: usize,
}

impl std::fmt::Debug for Check<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Check")
            .field("tolerance_mm", &self.tolerance_mm)
            .field("max_added", &self.max_added)
            .finish_non_exhaustive()
    }
}

/// The reduced internal force `Vᵀ f_int(V a)` and the full one on the free dofs.
fn forces(
    space: &Space,
    law: Law,
    basis: &Basis,
    a: &[f64],
    lame: (f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let u_all = space.expand(&basis.lift(a));
    let full = internal_force(space, law, &u_all, lame.0, lame.1);
    (basis.project(&full), full)
}

/// The reduced tangent `Vᵀ K_t(V a) V` (row-major `r × r`).
fn reduced_tangent(
    space: &Space,
    law: Law,
    pattern: &SymCsc,
    basis: &Basis,
    a: &[f64],
    lame: (f64, f64),
) -> Vec<f64> {
    let r = basis.rank();
    let u_all = space.expand(&basis.lift(a));
    let kt = tangent(space, law, pattern, &u_all, lame.0, lame.1);
    let mut kq = vec![0.0; space.free_dofs];
    let mut j = vec![0.0; r * r];
    for (k, q) in basis.cols.iter().enumerate() {
        kt.mul(q, &mut kq);
        for i in 0..r {
            j[i * r + k] = dot(&basis.cols[i], &kq);
        }
    }
    j
}

/// The largest node of a free-dof vector's all-node expansion (mm).
fn largest_node(space: &Space, x: &[f64]) -> f64 {
    space
        .expand(x)
        .chunks_exact(3)
        .map(|n| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt())
        .fold(0.0, f64::max)
}

/// Follows the press (load shape `shape`, probe functional `probe`: all-node, as for
/// [`super::series::Expander::expand`]) through `depths_mm` (increasing) in the span
/// of `basis`. In the span, a depth is converged when the last correction moves no node
/// by more than `tolerance_mm` and the force by less than `1e-4` of itself; with a
/// `check`, it is then accepted only as [`Check`] says, the basis growing until it is.
///
/// The reduced tangent is formed at rest and then only where a depth needs more than
/// `refresh_after` corrections or its corrections grow (`0`: at every depth); between
/// those it is kept current by Broyden's update from every pair of residuals assembled
/// (`J += (y − J s) sᵀ / sᵀs`, `s` the step in `a`, `y` the change of `Vᵀ f_int`; the
/// load column and the depth row are exact and kept). Residuals cost one assembly on
/// the mesh each; a tangent one assembly and `r` sparse products.
#[allow(clippy::too_many_arguments)]
pub fn reduced_press(
    space: &Space,
    law: Law,
    material: Material,
    basis: &Basis,
    shape: &[f64],
    probe: &[f64],
    depths_mm: &[f64],
    tolerance_mm: f64,
    refresh_after: usize,
    check: Option<&Check>,
) -> Result<ReducedPress, FeError> {
    material.validate()?;
    let lame = material.lame_n_per_mm2();
    let mut basis = basis.clone();
    let pattern = SymCsc::pattern(space);
    let shape_free = space.restrict(shape);
    let probe_free = space.restrict(probe);
    let mut b = basis.project(&shape_free);
    let mut c = basis.project(&probe_free);
    let mut out = ReducedPress {
        u: Vec::new(),
        force_n: Vec::new(),
        check_mm: Vec::new(),
        tangents: 0,
        residuals: 0,
        solves: 0,
        added: 0,
        tangent_s: 0.0,
        residual_s: 0.0,
        check_s: 0.0,
        rank: basis.rank(),
        stopped: None,
    };
    // The check's load response `y = K⁻¹ f̂` and its probe value, once a press.
    let y = check.map(|ch| {
        out.solves += 1;
        let y = ch.factor.solve(&shape_free);
        let ny = dot(&probe_free, &y);
        (y, ny)
    });
    // Accepted depths, coordinates and forces (rest first).
    let mut history: Vec<(f64, Vec<f64>, f64)> = vec![(0.0, vec![0.0; basis.rank()], 0.0)];
    let mut jac: Option<Vec<f64>> = None;
    // The last point where Vᵀ f_int was assembled, for Broyden's update.
    let mut last_eval: Option<(Vec<f64>, Vec<f64>)> = None;
    for &d in depths_mm {
        let (mut a, mut force) = predict(&history, d);
        let mut added_here = 0;
        let check_mm = loop {
            let Some(converged) = in_span(
                space,
                law,
                lame,
                &pattern,
                &basis,
                &b,
                &c,
                d,
                tolerance_mm,
                refresh_after,
                &mut a,
                &mut force,
                &mut jac,
                &mut last_eval,
                &mut out,
            ) else {
                out.stopped = Some(format!("singular reduced tangent at {d} mm"));
                return Ok(out);
            };
            if !converged {
                out.stopped = Some(format!("no reduced equilibrium at {d} mm"));
                return Ok(out);
            }
            let (Some(ch), Some((y, ny))) = (check, y.as_ref()) else {
                break 0.0;
            };
            // The bordered chord step with the check's factor at the converged state.
            let t = Instant::now();
            let r = basis.rank();
            let (_, fint) = forces(space, law, &basis, &a, lame);
            out.residuals += 1;
            let resid: Vec<f64> = fint
                .iter()
                .zip(&shape_free)
                .map(|(f, s)| f - force * s)
                .collect();
            let x = ch.factor.solve(&resid);
            out.solves += 1;
            let df = dot(&probe_free, &x) / ny;
            let du: Vec<f64> = y.iter().zip(&x).map(|(yi, xi)| df * yi - xi).collect();
            let size = largest_node(space, &du);
            out.check_s += t.elapsed().as_secs_f64();
            if size <= ch.tolerance_mm {
                break size;
            }
            if added_here == ch.max_added {
                out.stopped = Some(format!(
                    "the reduced state at {d} mm still moves a node by {size:.3} mm under \
                     the check after {added_here} added vectors"
                ));
                return Ok(out);
            }
            // Enrich: the correction joins the basis; the tangent grows by its
            // directional derivative.
            let t = Instant::now();
            let grown = Basis::orthonormal(basis.cols.iter().cloned().chain([du]), 1e-10);
            if grown.rank() == r {
                out.stopped = Some(format!("the check's correction at {d} mm is in the span"));
                return Ok(out);
            }
            let q = grown.cols[r].clone();
            let h = 1e-4;
            let u_free = basis.lift(&a);
            let shifted: Vec<f64> = u_free.iter().zip(&q).map(|(u, qi)| u + h * qi).collect();
            let fint_h = internal_force(space, law, &space.expand(&shifted), lame.0, lame.1);
            out.residuals += 1;
            let kq: Vec<f64> = fint_h.iter().zip(&fint).map(|(p, m)| (p - m) / h).collect();
            let col = grown.project(&kq);
            let j_old = jac.take().unwrap_or_default();
            let mut j = vec![0.0; (r + 1) * (r + 1)];
            for i in 0..r {
                j[i * (r + 1)..i * (r + 1) + r].copy_from_slice(&j_old[i * r..i * r + r]);
                j[i * (r + 1) + r] = col[i];
                j[r * (r + 1) + i] = col[i];
            }
            j[r * (r + 1) + r] = col[r];
            jac = Some(j);
            b.push(dot(&q, &shape_free));
            c.push(dot(&q, &probe_free));
            a.push(0.0);
            last_eval = None;
            for h in history.iter_mut() {
                h.1.push(0.0);
            }
            basis = grown;
            added_here += 1;
            out.added += 1;
            out.check_s += t.elapsed().as_secs_f64();
        };
        out.u.push(space.expand(&basis.lift(&a)));
        out.force_n.push(force);
        out.check_mm.push(check_mm);
        history.push((d, a, force));
    }
    out.rank = basis.rank();
    Ok(out)
}

/// Newton in the span at depth `d` from `(a, force)`: `Some(converged)`, `None` where
/// the bordered reduced tangent is singular.
#[allow(clippy::too_many_arguments)]
fn in_span(
    space: &Space,
    law: Law,
    lame: (f64, f64),
    pattern: &SymCsc,
    basis: &Basis,
    b: &[f64],
    c: &[f64],
    d: f64,
    tolerance_mm: f64,
    refresh_after: usize,
    a: &mut [f64],
    force: &mut f64,
    jac: &mut Option<Vec<f64>>,
    last_eval: &mut Option<(Vec<f64>, Vec<f64>)>,
    out: &mut ReducedPress,
) -> Option<bool> {
    let r = basis.rank();
    let mut refreshed = false;
    let mut last = f64::INFINITY;
    for step in 0..40 {
        let t = Instant::now();
        let (fa, _) = forces(space, law, basis, a, lame);
        out.residual_s += t.elapsed().as_secs_f64();
        out.residuals += 1;
        let slow = step > refresh_after || (step > 0 && last.is_infinite());
        if jac.is_none() || (refresh_after == 0 && step == 0) || (slow && !refreshed) {
            let t = Instant::now();
            *jac = Some(reduced_tangent(space, law, pattern, basis, a, lame));
            out.tangent_s += t.elapsed().as_secs_f64();
            refreshed = true;
            out.tangents += 1;
        } else if let (Some(j), Some((a0, f0))) = (jac.as_mut(), last_eval.as_ref()) {
            broyden(j, a, &fa, a0, f0);
        }
        *last_eval = Some((a.to_vec(), fa.clone()));
        let mut rhs: Vec<f64> = fa.iter().zip(b).map(|(x, bi)| -(x - *force * bi)).collect();
        rhs.push(d - dot(c, a));
        let j = jac.as_ref().map_or(&[][..], Vec::as_slice);
        let mut m = vec![0.0; (r + 1) * (r + 1)];
        for i in 0..r {
            m[i * (r + 1)..i * (r + 1) + r].copy_from_slice(&j[i * r..i * r + r]);
            m[i * (r + 1) + r] = -b[i];
            m[r * (r + 1) + i] = c[i];
        }
        let delta = solve_dense(m, rhs)?;
        let du = basis.lift(&delta[..r]);
        let largest = largest_node(space, &du);
        if !largest.is_finite() {
            return Some(false);
        }
        a.iter_mut().zip(&delta).for_each(|(x, dx)| *x += dx);
        *force += delta[r];
        if largest <= tolerance_mm && delta[r].abs() <= 1e-4 * force.abs().max(1e-9) {
            return Some(true);
        }
        // A growing correction marks the chord as diverging: refresh next step.
        last = if step > 0 && largest > last {
            f64::INFINITY
        } else {
            largest
        };
    }
    Some(false)
}

/// The correction Newton would make to a state on the whole mesh, approached by
/// conjugate gradients on the tangent's action with a factored stiffness (`factor`,
/// e.g. the shared rest one) as preconditioner: what [`Check`]'s single chord step
/// understates where the tangent is softer than that stiffness.
///
/// At the state `u` (all nodes) with force `F`, the bordered Newton step solves
///
/// ```text
/// K_t δ − ΔF f̂ = −R,   n̂·δ = 0,        R = f_int(u) − F f̂.
/// ```
///
/// The load shape `f̂` and the probe functional `n̂` are not parallel (the tool's
/// disk spreads its load by the shape functions and averages the displacement by
/// area), so the bordered system is not symmetric. Split instead by the scalar `ΔF`:
///
/// ```text
/// K_t δ_R = −R,   K_t δ_f = f̂,   ΔF = −n̂·δ_R / n̂·δ_f,   δ = δ_R + ΔF δ_f,
/// ```
///
/// two symmetric problems (the tangent is positive definite at a stable press), each
/// solved by preconditioned conjugate gradients from the chord step's `factor⁻¹ b`.
/// Step 0 is then the check's chord step exactly; each step after it costs two
/// residuals (the tangent's action `K_t p` is the directional derivative
/// `(f_int(u + h p) − f_int(u)) / h`) and two solves with `factor`.
#[derive(Debug, Clone)]
pub struct KrylovCorrection {
    /// The correction (free dofs) after 0, 1, … conjugate-gradient steps.
    pub steps: Vec<Vec<f64>>,
    /// Where a direction had `pᵀ K_t p ≤ 0` (the tangent not positive definite): the
    /// steps stop there.
    pub indefinite: bool,
    /// The cosine between the load shape and the probe functional.
    pub load_probe_cosine: f64,
    /// Residuals assembled, solves with `factor`, and seconds.
    pub residuals: usize,
    pub solves: usize,
    pub seconds: f64,
}

/// Preconditioned conjugate gradients on one right-hand side, one step at a time (the
/// operator's action is the caller's).
struct Pcg {
    x: Vec<f64>,
    r: Vec<f64>,
    p: Vec<f64>,
    rz: f64,
}

impl Pcg {
    /// From `x0` with residual `r0 = b − A x0` and its preconditioned `z0`.
    fn new(x0: Vec<f64>, r0: Vec<f64>, z0: Vec<f64>) -> Pcg {
        let rz = dot(&r0, &z0);
        Pcg {
            x: x0,
            r: r0,
            p: z0,
            rz,
        }
    }

    /// One step with `q = A p`; then `precondition(r)`. `false` where `pᵀAp ≤ 0`.
    fn step(&mut self, q: &[f64], precondition: &mut dyn FnMut(&[f64]) -> Vec<f64>) -> bool {
        let pq = dot(&self.p, q);
        // Not positive (or not a number): the tangent is not positive definite along p.
        if !(pq > 0.0 && pq.is_finite()) {
            return false;
        }
        let alpha = self.rz / pq;
        self.x
            .iter_mut()
            .zip(&self.p)
            .for_each(|(x, p)| *x += alpha * p);
        self.r.iter_mut().zip(q).for_each(|(r, q)| *r -= alpha * q);
        let z = precondition(&self.r);
        let rz = dot(&self.r, &z);
        let beta = if self.rz > 0.0 { rz / self.rz } else { 0.0 };
        self.rz = rz;
        self.p
            .iter_mut()
            .zip(&z)
            .for_each(|(p, z)| *p = z + beta * *p);
        true
    }
}

/// `steps` conjugate-gradient steps of [`KrylovCorrection`] at the all-node state `u`
/// with force `force_n` (load shape `shape`, probe functional `probe`, all-node).
#[allow(clippy::too_many_arguments)]
pub fn krylov_correction(
    space: &Space,
    law: Law,
    material: Material,
    factor: &Cholesky,
    shape: &[f64],
    probe: &[f64],
    u: &[f64],
    force_n: f64,
    steps: usize,
) -> Result<KrylovCorrection, FeError> {
    material.validate()?;
    let t0 = Instant::now();
    let (lambda, mu) = material.lame_n_per_mm2();
    let shape_free = space.restrict(shape);
    let probe_free = space.restrict(probe);
    let cosine = dot(&shape_free, &probe_free)
        / (dot(&shape_free, &shape_free) * dot(&probe_free, &probe_free)).sqrt();
    let fint = internal_force(space, law, u, lambda, mu);
    let u_free = space.restrict(u);
    let mut out = KrylovCorrection {
        steps: Vec::new(),
        indefinite: false,
        load_probe_cosine: cosine,
        residuals: 1,
        solves: 0,
        seconds: 0.0,
    };
    // The tangent's action: a step of 1e-4 mm at the largest dof, well inside the
    // tangent's validity and well above the residual's round-off.
    let mut residuals = 0;
    let mut action = |p: &[f64]| -> Vec<f64> {
        let size = p.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if !(size > 0.0 && size.is_finite()) {
            return vec![0.0; p.len()];
        }
        let h = 1e-4 / size;
        let shifted: Vec<f64> = u_free.iter().zip(p).map(|(a, b)| a + h * b).collect();
        let fint_h = internal_force(space, law, &space.expand(&shifted), lambda, mu);
        residuals += 1;
        fint_h.iter().zip(&fint).map(|(a, b)| (a - b) / h).collect()
    };
    let mut solves = 0;
    let mut precondition = |r: &[f64]| -> Vec<f64> {
        solves += 1;
        factor.solve(r)
    };
    // Each system from the chord step x0 = factor⁻¹ b: r0 = b − K_t x0.
    let minus_r: Vec<f64> = fint
        .iter()
        .zip(&shape_free)
        .map(|(f, s)| -(f - force_n * s))
        .collect();
    let mut start = |b: &[f64], precondition: &mut dyn FnMut(&[f64]) -> Vec<f64>| {
        let x0 = precondition(b);
        let ax = action(&x0);
        let r0: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let z0 = precondition(&r0);
        Pcg::new(x0, r0, z0)
    };
    let mut load = start(&shape_free, &mut precondition);
    let mut resid = start(&minus_r, &mut precondition);
    let combine = |resid: &Pcg, load: &Pcg| -> Vec<f64> {
        let df = -dot(&probe_free, &resid.x) / dot(&probe_free, &load.x);
        resid
            .x
            .iter()
            .zip(&load.x)
            .map(|(r, l)| r + df * l)
            .collect()
    };
    out.steps.push(combine(&resid, &load));
    for _ in 0..steps {
        let q_load = action(&load.p);
        let q_resid = action(&resid.p);
        if !(load.step(&q_load, &mut precondition) && resid.step(&q_resid, &mut precondition)) {
            out.indefinite = true;
            break;
        }
        out.steps.push(combine(&resid, &load));
    }
    out.residuals += residuals;
    out.solves += solves;
    out.seconds = t0.elapsed().as_secs_f64();
    Ok(out)
}

/// Broyden's update of the reduced tangent `j` (row-major `r × r`) from `Vᵀ f_int`
/// assembled at `a0` (`f0`) and at `a` (`f`). No update for a zero step.
fn broyden(j: &mut [f64], a: &[f64], f: &[f64], a0: &[f64], f0: &[f64]) {
    let r = a.len();
    let s: Vec<f64> = a.iter().zip(a0).map(|(x, y)| x - y).collect();
    let ss = dot(&s, &s);
    if !(ss > 0.0 && ss.is_finite()) {
        return;
    }
    for i in 0..r {
        let js: f64 = (0..r).map(|k| j[i * r + k] * s[k]).sum();
        let w = (f[i] - f0[i] - js) / ss;
        for k in 0..r {
            j[i * r + k] += w * s[k];
        }
    }
}

/// The state at `d` extrapolated from the last accepted ones: through the last three
/// (quadratic in the depth) where there are three, else linearly.
fn predict(history: &[(f64, Vec<f64>, f64)], d: f64) -> (Vec<f64>, f64) {
    let n = history.len();
    let (d1, a1, f1) = &history[n - 1];
    if n < 2 {
        return (a1.clone(), *f1);
    }
    let (d0, a0, f0) = &history[n - 2];
    if n < 3 {
        let t = (d - d1) / (d1 - d0);
        let a = a1.iter().zip(a0).map(|(x, y)| x + t * (x - y)).collect();
        return (a, f1 + t * (f1 - f0));
    }
    let (dm, am, fm) = &history[n - 3];
    // Lagrange weights of the three depths at d.
    let w1 = (d - d0) * (d - dm) / ((d1 - d0) * (d1 - dm));
    let w0 = (d - d1) * (d - dm) / ((d0 - d1) * (d0 - dm));
    let wm = (d - d1) * (d - d0) / ((dm - d1) * (dm - d0));
    let a = a1
        .iter()
        .zip(a0)
        .zip(am)
        .map(|((x, y), z)| w1 * x + w0 * y + wm * z)
        .collect();
    (a, w1 * f1 + w0 * f0 + wm * fm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::Element;
    use crate::fe::hyper::tests::one_tet;

    /// One P2 tetrahedron held at three corners, pressed at the fourth along −z: 12
    /// free dofs, so the whole space is a basis.
    fn held_tet() -> (Space, Vec<f64>, Vec<f64>) {
        let mesh = one_tet();
        let space = Space::new(&mesh, &[], &[true, true, true, false], Element::P2);
        let mut push = vec![0.0; 3 * space.nodes.len()];
        push[3 * 3 + 2] = -1.0;
        (space, push.clone(), push)
    }

    fn identity(n: usize) -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| (0..n).map(|k| if i == k { 1.0 } else { 0.0 }).collect())
            .collect()
    }

    /// With the whole space as its basis the reduced press is Newton itself: each state
    /// is an equilibrium at its depth. With the span of those states alone it gives
    /// them back.
    #[test]
    fn a_press_in_a_span_holding_its_states_is_the_full_press() {
        let (space, shape, probe) = held_tet();
        assert_eq!(space.free_dofs, 12);
        let material = Material::default();
        let (lambda, mu) = material.lame_n_per_mm2();
        let depths = [0.5, 1.0, 1.5, 2.0];
        for law in [Law::NeoHookean, Law::Svk] {
            let full = Basis::orthonormal(identity(12), 1e-12);
            let press = reduced_press(
                &space, law, material, &full, &shape, &probe, &depths, 1e-9, 3, None,
            )
            .expect("valid material");
            assert_eq!(press.stopped, None, "{law:?}");
            for ((u, f), d) in press.u.iter().zip(&press.force_n).zip(depths) {
                let reached: f64 = u.iter().zip(&probe).map(|(a, b)| a * b).sum();
                assert!((reached - d).abs() < 1e-12, "{law:?}: {reached} at {d}");
                let fint = internal_force(&space, law, u, lambda, mu);
                let load = space.restrict(&shape);
                let worst = fint
                    .iter()
                    .zip(&load)
                    .map(|(a, b)| (a - f * b).abs())
                    .fold(0.0, f64::max);
                assert!(
                    *f > 0.0 && worst < 1e-8 * f,
                    "{law:?} at {d}: {worst} of {f} N"
                );
            }
            let span = Basis::orthonormal(press.u.iter().map(|u| space.restrict(u)), 1e-10);
            let again = reduced_press(
                &space, law, material, &span, &shape, &probe, &depths, 1e-9, 3, None,
            )
            .expect("valid material");
            for (a, b) in again.u.iter().zip(&press.u) {
                let gap = a
                    .iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(gap < 1e-8, "{law:?}: {gap} mm");
            }
            let forces = again.force_n.iter().zip(&press.force_n);
            assert!(forces.into_iter().all(|(a, b)| (a - b).abs() < 1e-8 * b));
        }
    }

    /// From a one-vector span (the first depth's state), the check with the rest
    /// factor grows the basis until every depth is Newton's equilibrium.
    #[test]
    fn the_check_grows_a_poor_span_until_each_depth_is_an_equilibrium() {
        let (space, shape, probe) = held_tet();
        let material = Material::default();
        let (lambda, mu) = material.lame_n_per_mm2();
        let depths = [0.5, 1.0, 1.5, 2.0];
        let pattern = SymCsc::pattern(&space);
        let rest = crate::fe::newton::factor_tangent(
            &space,
            Law::NeoHookean,
            &pattern,
            &vec![0.0; 3 * space.nodes.len()],
            lambda,
            mu,
        )
        .expect("held at three corners");
        let press = |basis: &Basis, check: Option<&Check>| {
            reduced_press(
                &space,
                Law::NeoHookean,
                material,
                basis,
                &shape,
                &probe,
                &depths,
                1e-10,
                3,
                check,
            )
            .expect("valid material")
        };
        let largest_gap = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        let newton = press(&Basis::orthonormal(identity(12), 1e-12), None);
        let one = Basis::orthonormal([space.restrict(&newton.u[0])], 1e-12);
        let check = Check {
            factor: &rest,
            tolerance_mm: 1e-9,
            max_added: 12,
        };
        let grown = press(&one, Some(&check));
        assert_eq!(grown.stopped, None);
        assert!(grown.added > 0 && grown.rank > 1, "{grown:?}");
        assert!(grown.check_mm.iter().all(|&m| m <= 1e-9));
        for (a, b) in grown.u.iter().zip(&newton.u) {
            let gap = largest_gap(a, b);
            assert!(gap < 1e-8, "{gap} mm");
        }
        // Without the check the one-vector span is not the press.
        let poor = press(&one, None);
        let gap = poor
            .u
            .last()
            .zip(newton.u.last())
            .map_or(f64::INFINITY, |(a, b)| largest_gap(a, b));
        assert!(gap > 1e-4, "{gap} mm");
    }

    /// Broyden's update makes the tangent map the last step to the last change of the
    /// force (the secant condition) and leaves it unchanged across that step.
    #[test]
    fn broyden_meets_the_secant_condition_and_changes_nothing_across_the_step() {
        let mut j = vec![2.0, 0.5, -1.0, 3.0];
        let before = j.clone();
        let (a0, a) = ([0.1, -0.2], [0.4, 0.3]);
        let (f0, f) = ([1.0, 2.0], [1.7, 1.1]);
        broyden(&mut j, &a, &f, &a0, &f0);
        let s = [a[0] - a0[0], a[1] - a0[1]];
        for i in 0..2 {
            let js = j[2 * i] * s[0] + j[2 * i + 1] * s[1];
            assert!((js - (f[i] - f0[i])).abs() < 1e-14);
        }
        // A direction orthogonal to the step is mapped as before.
        let t = [-s[1], s[0]];
        for i in 0..2 {
            let now = j[2 * i] * t[0] + j[2 * i + 1] * t[1];
            let was = before[2 * i] * t[0] + before[2 * i + 1] * t[1];
            assert!((now - was).abs() < 1e-14);
        }
        // No step, no update.
        let kept = j.clone();
        broyden(&mut j, &a, &[9.0, 9.0], &a, &f);
        assert_eq!(j, kept);
    }

    /// Off an equilibrium by a small `e` that keeps the depth, the Krylov correction
    /// with the rest stiffness as preconditioner reaches Newton's step, `−e` to second
    /// order, in the 12 dimensions; its step 0 is the check's chord step, farther off
    /// where the tangent differs from the rest.
    #[test]
    fn the_krylov_correction_reaches_the_newton_step() {
        let (space, shape, probe) = held_tet();
        let material = Material::default();
        let (lambda, mu) = material.lame_n_per_mm2();
        let pattern = SymCsc::pattern(&space);
        let zero = vec![0.0; 3 * space.nodes.len()];
        let rest = tangent(&space, Law::NeoHookean, &pattern, &zero, lambda, mu);
        let factor = Cholesky::factor(&rest, space.fixed_count()).expect("SPD at rest");
        let full = Basis::orthonormal(identity(12), 1e-12);
        let press = reduced_press(
            &space,
            Law::NeoHookean,
            material,
            &full,
            &shape,
            &probe,
            &[0.5, 1.0, 1.5],
            1e-12,
            3,
            None,
        )
        .expect("valid material");
        let (u, force) = (&press.u[2], press.force_n[2]);
        // A perturbation of every free dof but the probed one (so n̂·e = 0).
        let probe_free = space.restrict(&probe);
        let e: Vec<f64> = (0..12)
            .map(|i| {
                if probe_free[i] == 0.0 {
                    1e-4 * ((i as f64) * 0.7).sin()
                } else {
                    0.0
                }
            })
            .collect();
        let moved: Vec<f64> = space
            .restrict(u)
            .iter()
            .zip(&e)
            .map(|(a, b)| a + b)
            .collect();
        let k = krylov_correction(
            &space,
            Law::NeoHookean,
            material,
            &factor,
            &shape,
            &probe,
            &space.expand(&moved),
            force,
            12,
        )
        .expect("valid material");
        assert!(!k.indefinite);
        assert_eq!(k.steps.len(), 13);
        // Newton's bordered step there, with the exact tangent (dense, 13 × 13).
        let kt = tangent(
            &space,
            Law::NeoHookean,
            &pattern,
            &space.expand(&moved),
            lambda,
            mu,
        );
        let load_free = space.restrict(&shape);
        let fint_moved = internal_force(&space, Law::NeoHookean, &space.expand(&moved), lambda, mu);
        let mut m = vec![0.0; 13 * 13];
        let mut col = vec![0.0; 12];
        for j in 0..12 {
            let unit: Vec<f64> = (0..12).map(|i| if i == j { 1.0 } else { 0.0 }).collect();
            kt.mul(&unit, &mut col);
            for i in 0..12 {
                m[i * 13 + j] = col[i];
            }
            m[j * 13 + 12] = -load_free[j];
            m[12 * 13 + j] = probe_free[j];
        }
        let mut rhs: Vec<f64> = fint_moved
            .iter()
            .zip(&load_free)
            .map(|(f, s)| -(f - force * s))
            .collect();
        rhs.push(0.0);
        let newton = solve_dense(m, rhs).expect("regular");
        let miss = |d: &[f64]| {
            d.iter()
                .zip(&newton)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let size = dot(&e, &e).sqrt();
        // Newton's step undoes the perturbation but for its second-order part.
        assert!(miss(&e.iter().map(|x| -x).collect::<Vec<_>>()) < 1e-2 * size);
        let last = miss(k.steps.last().expect("steps"));
        let all: Vec<f64> = k.steps.iter().map(|d| miss(d) / size).collect();
        // To the directional derivative's own accuracy (a step of 1e-4 mm).
        assert!(last < 2e-3 * size, "{last} of {size}: {all:?}");
        assert!(
            miss(&k.steps[0]) > 10.0 * last,
            "{} {last}",
            miss(&k.steps[0])
        );
        assert!(
            k.steps
                .iter()
                .all(|d| dot(d, &probe_free).abs() < 1e-12 * size)
        );
    }

    /// The predictor is exact on states quadratic in the depth once three are known.
    #[test]
    fn the_predictor_is_exact_for_a_quadratic_path() {
        let state = |d: f64| (vec![d * d - 2.0 * d, 0.5 * d], 3.0 * d + d * d);
        let history: Vec<(f64, Vec<f64>, f64)> = [0.0, 1.0, 2.5]
            .iter()
            .map(|&d| {
                let (a, f) = state(d);
                (d, a, f)
            })
            .collect();
        let (a, f) = predict(&history, 4.0);
        let (want_a, want_f) = state(4.0);
        assert!(a.iter().zip(&want_a).all(|(x, y)| (x - y).abs() < 1e-12));
        assert!((f - want_f).abs() < 1e-12);
    }

    #[test]
    fn gram_schmidt_drops_dependent_vectors_and_keeps_an_orthonormal_set() {
        let v = vec![
            vec![1.0, 0.0, 0.0],
            vec![2.0, 0.0, 0.0],
            vec![1.0, 1.0, 0.0],
            vec![0.0, 0.0, 3.0],
        ];
        let basis = Basis::orthonormal(v, 1e-10);
        assert_eq!(basis.rank(), 3);
        for i in 0..3 {
            for k in 0..3 {
                let want = if i == k { 1.0 } else { 0.0 };
                assert!((dot(&basis.cols[i], &basis.cols[k]) - want).abs() < 1e-14);
            }
        }
        let x = [0.5, -2.0, 4.0];
        let back = basis.lift(&basis.project(&x));
        assert!(back.iter().zip(x).all(|(a, b)| (a - b).abs() < 1e-14));
    }
}
