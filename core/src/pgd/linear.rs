//! Greedy PGD for `K U Ms = F Ms` (docs/methods.md §1).
//!
//! Given `U_n = Σ_{k≤n} X_k y_kᵀ`, the next pair (R, S) solves, alternately,
//!
//! ```text
//! S fixed:  (Sᵀ Ms S) K R = F (Ms S) − Σ_k (y_kᵀ Ms S) K X_k      (one solve with factored K)
//! R fixed:  (Rᵀ K R) S    = Fᵀ R     − Σ_k (X_kᵀ K R) y_k
//! ```
//!
//! with R normalized to ‖R‖_K = 1, until the change of `R Sᵀ` is below `fixed_point_tol`
//! (relative, in the natural norm `‖E‖² = tr(Eᵀ K E Ms)`). `K X_k` is kept, so no
//! right-hand side costs an extra solve. The enrichment stops when
//! `‖R Sᵀ‖ / ‖U_n‖ < tol` or at `max_modes`.
//!
//! Update (optional, after each enrichment): Galerkin projection on the spatial basis,
//! `(XᵀKX) Yᵀ = XᵀF`, re-solves all parametric functions at once (n × n system).
//!
//! Errors over the whole solution map `G = K⁻¹F` in the natural norm need no extra
//! solves: `‖G − U‖² = ‖G‖² − 2 Σ_k y_kᵀ Ms (Fᵀ X_k) + Σ_kl (X_kᵀKX_l)(y_kᵀ Ms y_l)`.

use std::time::Instant;

use crate::fe::sparse::{Cholesky, SymCsc};
use crate::rng::Rng;

/// A sparse n × m matrix by columns (the load operator F).
#[derive(Debug, Clone)]
pub struct ColSparse {
    pub rows: usize,
    pub cols: Vec<Vec<(u32, f64)>>,
}

impl ColSparse {
    /// `F v`.
    pub fn mul(&self, v: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.rows];
        for (col, &vj) in self.cols.iter().zip(v) {
            if vj != 0.0 {
                for &(r, x) in col {
                    out[r as usize] += x * vj;
                }
            }
        }
        out
    }
    /// `Fᵀ w`.
    pub fn mul_t(&self, w: &[f64]) -> Vec<f64> {
        self.cols
            .iter()
            .map(|col| col.iter().map(|&(r, x)| x * w[r as usize]).sum())
            .collect()
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub max_modes: usize,
    /// Stop when the new term's norm relative to the sum's falls below this.
    pub tol: f64,
    pub fixed_point_tol: f64,
    pub fixed_point_max_iter: usize,
    /// Galerkin update of all parametric functions after each enrichment.
    pub update: bool,
    pub seed: u64,
    /// Terms found together per fixed point (multi-RHS solves, see
    /// [`block`](super::block)); 1 is the classic one-term greedy enrichment.
    pub block: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            max_modes: 100,
            tol: 1e-4,
            fixed_point_tol: 1e-3,
            fixed_point_max_iter: 15,
            update: true,
            seed: 1,
            block: 1,
        }
    }
}

/// The computed terms.
#[derive(Debug, Clone, Default)]
pub struct Terms {
    pub x: Vec<Vec<f64>>,
    pub kx: Vec<Vec<f64>>,
    /// `Fᵀ X_k`, kept for the update and the map error.
    pub ftx: Vec<Vec<f64>>,
    pub y: Vec<Vec<f64>>,
    /// ‖R Sᵀ‖ / ‖U_n‖ when term n was added.
    pub residual_per_mode: Vec<f64>,
    pub fixed_point_iterations: Vec<usize>,
    pub seconds_per_mode: Vec<f64>,
    /// `X_kᵀ K X_l`, grown one row per term (O(N·n) per term instead of O(N²·n)).
    pub gram: Vec<Vec<f64>>,
}

impl Terms {
    /// Appends the Gram row of the newest term (call after pushing x and kx).
    pub fn extend_gram(&mut self) {
        let n = self.x.len();
        while self.gram.len() < n {
            let k = self.gram.len();
            let row: Vec<f64> = (0..=k).map(|l| dot(&self.x[l], &self.kx[k])).collect();
            for (l, v) in row.iter().enumerate().take(k) {
                self.gram[l].push(*v);
            }
            self.gram.push(row);
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    crate::kernels::dot(a, b)
}

/// The problem's operators: factored K (and K itself for products), F, Ms.
#[derive(Debug)]
pub struct Operators<'a> {
    pub k: &'a SymCsc,
    pub k_factor: &'a Cholesky,
    pub f: &'a ColSparse,
    pub ms: &'a SymCsc,
}

impl Operators<'_> {
    fn kmul(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        self.k.mul(x, &mut y);
        y
    }
    fn msmul(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        self.ms.mul(x, &mut y);
        y
    }
}

/// `‖U‖²` in the natural norm for the first `n` stored terms (Gram matrix required).
pub fn norm2(ops: &Operators, t: &Terms, n: usize) -> f64 {
    let msy: Vec<Vec<f64>> = t.y[..n].iter().map(|y| ops.msmul(y)).collect();
    let mut s = 0.0;
    for k in 0..n {
        for l in 0..n {
            s += t.gram[k][l] * dot(&t.y[k], &msy[l]);
        }
    }
    s
}

/// Runs greedy enrichment, calling `progress(modes, residual)` after each term;
/// `start` resumes from earlier terms (a checkpoint).
pub fn solve(
    ops: &Operators,
    settings: &Settings,
    start: Terms,
    mut progress: impl FnMut(&Terms),
) -> Terms {
    let n = ops.f.rows;
    let m = ops.f.cols.len();
    let mut t = start;
    while t.x.len() < settings.max_modes {
        let t0 = Instant::now();
        // Seeded per term, so a resumed run computes the same terms as an
        // uninterrupted one.
        let mut rng = Rng::seed(settings.seed.wrapping_add(t.x.len() as u64));
        let mut s: Vec<f64> = (0..m).map(|_| rng.range(0.5, 1.5)).collect();
        let mut r = vec![0.0; n];
        let mut kr = vec![0.0; n];
        let mut iters = 0;
        for it in 0..settings.fixed_point_max_iter {
            iters = it + 1;
            // S fixed → R.
            let b = ops.msmul(&s);
            let beta = dot(&s, &b);
            let mut rhs = ops.f.mul(&b);
            for (yk, kxk) in t.y.iter().zip(&t.kx) {
                let c = dot(yk, &b);
                for (r, v) in rhs.iter_mut().zip(kxk) {
                    *r -= c * v;
                }
            }
            let mut r_new = ops.k_factor.solve(&rhs);
            r_new.iter_mut().for_each(|v| *v /= beta);
            let mut kr_new = ops.kmul(&r_new);
            let alpha = dot(&r_new, &kr_new);
            if alpha.is_nan() || alpha <= 0.0 {
                break; // The load is fully represented: nothing left to add.
            }
            // R fixed → S.
            let mut s_new = ops.f.mul_t(&r_new);
            for (yk, xk) in t.y.iter().zip(&t.x) {
                let c = dot(xk, &kr_new);
                for (sv, v) in s_new.iter_mut().zip(yk) {
                    *sv -= c * v;
                }
            }
            s_new.iter_mut().for_each(|v| *v /= alpha);
            // Normalize ‖R‖_K = 1, scale into S.
            let scale = alpha.sqrt();
            r_new.iter_mut().for_each(|v| *v /= scale);
            kr_new.iter_mut().for_each(|v| *v /= scale);
            s_new.iter_mut().for_each(|v| *v *= scale);
            // Change of R Sᵀ in the natural norm.
            let ms_new = ops.msmul(&s_new);
            let a = dot(&s_new, &ms_new);
            let b0 = dot(&s, &ops.msmul(&s)) * dot(&r, &kr);
            let cross = dot(&r_new, &kr) * dot(&s, &ms_new);
            let change2 = (a + b0 - 2.0 * cross).max(0.0);
            r = r_new;
            kr = kr_new;
            s = s_new;
            if it > 0 && change2 <= settings.fixed_point_tol.powi(2) * a {
                break;
            }
        }
        let ftx = ops.f.mul_t(&r);
        t.x.push(r);
        t.kx.push(kr);
        t.ftx.push(ftx);
        t.y.push(s.clone());
        t.extend_gram();
        if settings.update {
            update(ops, &mut t);
        }
        let term2 = dot(&t.y[t.y.len() - 1], &ops.msmul(&t.y[t.y.len() - 1]));
        let total2 = norm2(ops, &t, t.x.len()).max(f64::MIN_POSITIVE);
        let rel = (term2 / total2).sqrt();
        t.residual_per_mode.push(rel);
        t.fixed_point_iterations.push(iters);
        t.seconds_per_mode.push(t0.elapsed().as_secs_f64());
        progress(&t);
        if rel < settings.tol {
            break;
        }
    }
    t
}

/// Galerkin update: `(XᵀKX) Yᵀ = XᵀF`.
pub fn update(ops: &Operators, t: &mut Terms) {
    let n = t.x.len();
    let m = ops.f.cols.len();
    t.extend_gram();
    let a = faer::Mat::<f64>::from_fn(n, n, |i, j| t.gram[i][j]);
    let mut b = faer::Mat::<f64>::from_fn(n, m, |i, j| t.ftx[i][j]);
    // X is K-orthogonal up to round-off only when updated; use a symmetric solve.
    let llt = match a.llt(faer::Side::Lower) {
        Ok(l) => l,
        Err(_) => return, // Dependent modes: keep the greedy functions.
    };
    use faer::linalg::solvers::Solve;
    llt.solve_in_place(b.as_mut());
    for i in 0..n {
        for j in 0..m {
            t.y[i][j] = b[(i, j)];
        }
    }
}

/// Relative error of `U` over the whole map in the natural norm, given ‖G‖².
pub fn map_error(ops: &Operators, t: &Terms, n_modes: usize, g_norm2: f64) -> f64 {
    let mut cross = 0.0;
    for k in 0..n_modes {
        cross += dot(&t.y[k], &ops.msmul(&t.ftx[k]));
    }
    let e2 = g_norm2 - 2.0 * cross + norm2(ops, t, n_modes);
    (e2.max(0.0) / g_norm2).sqrt()
}
