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
//! `J` is kept from depth to depth while the corrections shrink fast enough (a chord in
//! `r + 1` unknowns) and formed again, at the current state, where they do not.
//!
//! Why: the tissue build follows every press to equilibrium on the full mesh (one
//! factored tangent per segment, `fe::path`), which puts the whole coarse surface at
//! hours. A point between presses already made (a split triangle's quarter and inner
//! points lie 2–6 mm from its corners and edge midpoints) may be spanned by their
//! states and its own first orders; then its press needs no factorization at all.
//! This module is the solver that question is measured with (`palpa bench fe --only
//! reduced`); each residual here is still assembled on the whole mesh, so it answers
//! the accuracy question, not yet the cost one.

use super::hyper::Law;
use super::newton::{internal_force, tangent};
use super::series::solve_dense;
use super::space::Space;
use super::sparse::SymCsc;
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
    /// Reduced tangents formed and residuals assembled, over all depths.
    pub tangents: usize,
    pub residuals: usize,
    /// Why it stopped before the last depth, if it did.
    pub stopped: Option<String>,
}

/// Follows the press (load shape `shape`, probe functional `probe`: all-node, as for
/// [`super::series::Expander::expand`]) through `depths_mm` (increasing) in the span
/// of `basis`. A depth is accepted when the last correction moves no node by more than
/// `tolerance_mm` and the force by less than `1e-4` of itself. The reduced tangent is
/// formed at the first depth and again at a depth that needs more than `refresh_after`
/// corrections or whose corrections grow (`0`: at every depth).
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
) -> Result<ReducedPress, FeError> {
    material.validate()?;
    let (lambda, mu) = material.lame_n_per_mm2();
    let r = basis.rank();
    let pattern = SymCsc::pattern(space);
    let b = basis.project(&space.restrict(shape));
    let c = basis.project(&space.restrict(probe));
    let mut out = ReducedPress {
        u: Vec::new(),
        force_n: Vec::new(),
        tangents: 0,
        residuals: 0,
        stopped: None,
    };
    // Coordinates and force at the last two accepted depths (rest first).
    let mut history: Vec<(f64, Vec<f64>, f64)> = vec![(0.0, vec![0.0; r], 0.0)];
    let mut kv = vec![vec![0.0; space.free_dofs]; r];
    let mut jac: Option<Vec<f64>> = None;
    for &d in depths_mm {
        let (a, mut force) = predict(&history, d);
        let mut a = a;
        let mut accepted = false;
        let mut refreshed = false;
        let mut last = f64::INFINITY;
        for step in 0..40 {
            let u_free = basis.lift(&a);
            let u_all = space.expand(&u_free);
            // The reduced tangent is kept from depth to depth (a chord in r + 1
            // unknowns) and formed again where a depth is slow or a correction grows,
            // once a depth.
            let slow = step > refresh_after || (step > 0 && last.is_infinite());
            if jac.is_none() || (refresh_after == 0 && step == 0) || (slow && !refreshed) {
                let kt = tangent(space, law, &pattern, &u_all, lambda, mu);
                for (col, q) in kv.iter_mut().zip(&basis.cols) {
                    kt.mul(q, col);
                }
                let mut j = vec![0.0; r * r];
                for i in 0..r {
                    for k in 0..r {
                        j[i * r + k] = dot(&basis.cols[i], &kv[k]);
                    }
                }
                jac = Some(j);
                refreshed = true;
                out.tangents += 1;
            }
            let fint = internal_force(space, law, &u_all, lambda, mu);
            out.residuals += 1;
            let mut rhs: Vec<f64> = basis.project(&fint);
            rhs.iter_mut()
                .zip(&b)
                .for_each(|(x, bi)| *x = -(*x - force * bi));
            rhs.push(d - dot(&c, &a));
            let j = jac.as_ref().map_or(&[][..], Vec::as_slice);
            let mut m = vec![0.0; (r + 1) * (r + 1)];
            for i in 0..r {
                m[i * (r + 1)..i * (r + 1) + r].copy_from_slice(&j[i * r..i * r + r]);
                m[i * (r + 1) + r] = -b[i];
                m[r * (r + 1) + i] = c[i];
            }
            let Some(delta) = solve_dense(m, rhs) else {
                out.stopped = Some(format!("singular reduced tangent at {d} mm"));
                return Ok(out);
            };
            let du = basis.lift(&delta[..r]);
            let largest = du
                .chunks_exact(3)
                .map(|n| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt())
                .fold(0.0, f64::max);
            if !largest.is_finite() {
                break;
            }
            a.iter_mut().zip(&delta).for_each(|(x, dx)| *x += dx);
            force += delta[r];
            if largest <= tolerance_mm && delta[r].abs() <= 1e-4 * force.abs().max(1e-9) {
                accepted = true;
                break;
            }
            // A growing correction marks the chord as diverging: refresh next step.
            last = if step > 0 && largest > last {
                f64::INFINITY
            } else {
                largest
            };
        }
        if !accepted {
            out.stopped = Some(format!("no reduced equilibrium at {d} mm"));
            return Ok(out);
        }
        out.u.push(space.expand(&basis.lift(&a)));
        out.force_n.push(force);
        history.push((d, a, force));
    }
    Ok(out)
}

/// The state at `d` extrapolated linearly from the last two accepted ones.
fn predict(history: &[(f64, Vec<f64>, f64)], d: f64) -> (Vec<f64>, f64) {
    let (d1, a1, f1) = &history[history.len() - 1];
    if history.len() < 2 {
        return (a1.clone(), *f1);
    }
    let (d0, a0, f0) = &history[history.len() - 2];
    let t = (d - d1) / (d1 - d0);
    let a = a1.iter().zip(a0).map(|(x, y)| x + t * (x - y)).collect();
    (a, f1 + t * (f1 - f0))
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
                &space, law, material, &full, &shape, &probe, &depths, 1e-9, 3,
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
                &space, law, material, &span, &shape, &probe, &depths, 1e-9, 3,
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
