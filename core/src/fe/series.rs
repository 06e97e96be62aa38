//! A press as a power series in its depth: the asymptotic-numerical expansion of the
//! hyperelastic depth-controlled problem ([`super::newton`]) about the rest state.
//!
//! Under depth control the displacement and the tool's force are analytic in the depth
//! `d` near `d = 0`, so
//!
//! ```text
//! u(d) = Σ_{p≥1} d^p u_p,    F(d) = Σ_{p≥1} d^p F_p.
//! ```
//!
//! Put into `f_int(u) = F f̂` and `n̂·u = d` and collect the powers of `d`: since the
//! rest state is unstressed, the part of `f_int`'s `d^p` coefficient that contains
//! `u_p` is `K u_p` with `K` the *linear* stiffness, and the rest, `N_p`, depends on
//! `u_1 … u_{p−1}` only. Each order is one linear solve with the same factorization:
//!
//! ```text
//! K u_p = F_p f̂ − N_p,    n̂·u_p = δ_{p1}
//! x = K⁻¹ N_p,  y = K⁻¹ f̂  (once),  F_p = (δ_{p1} + n̂·x) / (n̂·y),  u_p = F_p y − x
//! ```
//!
//! `N_p` is the `d^p` coefficient of `f_int(Σ_{i<p} d^i u_i)`, computed exactly at
//! each quadrature point by truncated power-series arithmetic on the law's formulas:
//! `F = I + Σ d^i H_i`, `C = FᵀF` (Cauchy products), then for Saint Venant–Kirchhoff
//! `S = λ tr E I + 2μ E`, `E = ½(C − I)` (a polynomial: the series ends), and for the
//! neo-Hookean law `S = μ(I − C⁻¹) + λ ln J C⁻¹` with the series of `C⁻¹`
//! (`Y_k = −Σ_{i=1..k} C_i Y_{k−i}`, since `C_0 = I`), of `J = det F` (a cubic in the
//! entries) and of `ln J` (`L_k = J_k − (1/k) Σ_{m=1..k−1} m L_m J_{k−m}`, since
//! `J_0 = 1`); finally `P = F S` and `N_p[a, i] = ∫ P_p[i, K] ∂_K N_a dV`.
//!
//! This is the route of the paper's authors for real-time hyperelastic palpation
//! (each term a linear problem with the one stiffness): a press at any depth inside
//! the series' radius of convergence is a few vectors summed, and the force law
//! `F(d)` is a polynomial. Its limit is the radius: the nearest singularity of the
//! depth–force path in the complex plane (for SVK, its loss of stability in
//! compression). [`DepthSeries::radius_mm`] estimates it from the coefficients.

use std::time::Instant;

use super::law::{HyperLaw, Law, with_law};
use super::shape::{TET_DEGREE1, TET_DEGREE4, barycentric_gradients, tet_gradients};
use super::space::Space;
use super::sparse::{Cholesky, SymCsc};
use super::{Element, FeError, Material};

use super::m3::{ID, M3, ZERO, add_scaled, mul, mul_tn};

/// The coefficients `0..=p` of the second Piola–Kirchhoff stress for the deformation
/// gradient series `f[0..=p]`, into `s[0..=p]`. `f[0]` is `I` about the rest state, or
/// `I + ∇u_0` about a deformed state `u_0` (then `C_0 ≠ I`, `J_0 ≠ 1` and `S_0 ≠ 0`).
///
/// Runs once per quadrature point and order, so every series lives in a fixed array on
/// the stack (`p ≤ MAX_ORDERS`), and `C` and `C⁻¹` are formed by their symmetry: with
/// both, orders 2–12 over coarse P2's cells took 1.15 s on one thread, 1.58 s before.
fn stress_series(law: Law, f: &[M3], lambda: f64, mu: f64, s: &mut [M3]) {
    let p = f.len() - 1;
    // C_k = Σ_{i+j=k} F_iᵀ F_j: the pairs (i, j) and (j, i) give a matrix and its
    // transpose, so each unordered pair is one product.
    let mut c = [ZERO; SERIES_LEN];
    for (k, ck) in c.iter_mut().enumerate().take(p + 1) {
        let mut acc = ZERO;
        for i in 0..k.div_ceil(2) {
            add_scaled(&mut acc, 1.0, &mul_tn(&f[i], &f[k - i]));
        }
        for a in 0..3 {
            for b in 0..3 {
                ck[a][b] = acc[a][b] + acc[b][a];
            }
        }
        if k % 2 == 0 {
            add_scaled(ck, 1.0, &mul_tn(&f[k / 2], &f[k / 2]));
        }
    }
    with_law!(law, L => L::stress_series(f, &c, p, lambda, mu, s));
}

/// Room for a series of [`MAX_ORDERS`] orders and its constant term.
const SERIES_LEN: usize = MAX_ORDERS + 1;

/// The `a^p` coefficient of cell `c`'s internal force at
/// `u(a) = u_0 + Σ_{i<p} a^i u_i` (`base` = all-node `u_0`, `None` for the rest state;
/// `lower[i − 1]` = all-node `u_i`), into `fe` (3·nodes per cell). The part linear in
/// `u_p` is left out: it is the tangent at `u_0` times `u_p`.
///
/// The plain statement of the arithmetic, one quadrature point at a time: the series
/// run [`super::lanes::element_coefficient`], the same numbers bit for bit four points
/// at a time (a unit test there compares the two).
#[allow(clippy::too_many_arguments)]
pub fn element_coefficient(
    space: &Space,
    law: Law,
    c: usize,
    base: Option<&[f64]>,
    lower: &[Vec<f64>],
    p: usize,
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
) {
    let (lambda, mu) = space.lame_in(c, lambda, mu);
    let p2 = space.element == Element::P2;
    let npc = space.element.nodes_per_cell();
    fe[..3 * npc].fill(0.0);
    let cell = space.cell(c);
    let (gl, vol) =
        barycentric_gradients(space.cell_corners(c)).expect("mesh has no degenerate tetrahedra");
    let rule = if p2 { &TET_DEGREE4 } else { &TET_DEGREE1 };
    assert!(
        p <= MAX_ORDERS,
        "a series of {p} orders (at most {MAX_ORDERS})"
    );
    let mut g = [[0.0; 3]; 10];
    let mut f = [ZERO; SERIES_LEN];
    let mut s = [ZERO; SERIES_LEN];
    for (l, w) in rule.points.iter().zip(rule.weights) {
        tet_gradients(p2, *l, &gl, &mut g);
        f[0] = ID;
        if let Some(u) = base {
            for a in 0..npc {
                let n = cell[a] as usize;
                for i in 0..3 {
                    for j in 0..3 {
                        f[0][i][j] += u[3 * n + i] * g[a][j];
                    }
                }
            }
        }
        for k in 1..=p {
            let mut h = ZERO;
            if k < p {
                let u = &lower[k - 1];
                for a in 0..npc {
                    let n = cell[a] as usize;
                    for i in 0..3 {
                        for j in 0..3 {
                            h[i][j] += u[3 * n + i] * g[a][j];
                        }
                    }
                }
            }
            f[k] = h;
        }
        stress_series(law, &f[..=p], lambda, mu, &mut s);
        let mut pp = ZERO;
        for i in 0..=p {
            add_scaled(&mut pp, 1.0, &mul(&f[i], &s[p - i]));
        }
        let wv = w * vol;
        for a in 0..npc {
            for i in 0..3 {
                fe[3 * a + i] +=
                    wv * (pp[i][0] * g[a][0] + pp[i][1] * g[a][1] + pp[i][2] * g[a][2]);
            }
        }
    }
}

/// `N_p` on the free dofs (see the module doc).
#[allow(clippy::too_many_arguments)]
fn coefficient(
    space: &Space,
    law: Law,
    base: Option<&[f64]>,
    lower: &[Vec<f64>],
    p: usize,
    lambda: f64,
    mu: f64,
    cells: &[usize],
) -> Vec<f64> {
    super::newton::assemble_vector_on(space, cells, |c, fe| {
        super::lanes::element_coefficient(space, law, c, base, lower, p, lambda, mu, fe);
    })
}

/// The cells where the press's first order `u1` (all-node) varies by at least
/// `cutoff` times its largest variation over a cell (`cutoff = 0`: every cell).
///
/// Why this is enough: `N_p` (p ≥ 2) is a sum of products of at least two of the
/// lower orders' gradients, and those orders are driven by `u1`'s; in a cell where
/// `u1` varies by `ε` of its peak, `N_p` is of order `ε²` of its peak there. A cutoff
/// of 1e-2 drops terms of relative size 1e-4 and keeps the cells within a few tool
/// radii of the probe (or the whole lobe, when the press moves a thin lobe as a
/// body), which is where the nonlinearity lives.
pub fn active_cells(space: &Space, u1: &[f64], cutoff: f64) -> Vec<usize> {
    let variation = |c: usize| {
        let cell = space.cell(c);
        let first = cell[0] as usize;
        cell.iter()
            .map(|&n| {
                let n = n as usize;
                (0..3)
                    .map(|i| (u1[3 * n + i] - u1[3 * first + i]).powi(2))
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
            .sqrt()
    };
    let all: Vec<f64> = (0..space.cell_count()).map(variation).collect();
    let top = all.iter().copied().fold(0.0, f64::max);
    (0..space.cell_count())
        .filter(|&c| cutoff <= 0.0 || all[c] >= cutoff * top)
        .collect()
}

/// A press expanded in its depth.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthSeries {
    /// `F_p` (N/mmᵖ), `force[p − 1]`.
    pub force: Vec<f64>,
    /// `u_p` all-node (mm/mmᵖ), `u[p − 1]`.
    pub u: Vec<Vec<f64>>,
    pub factor_s: f64,
    pub seconds: f64,
}

impl DepthSeries {
    /// `F(d) = Σ F_p d^p` with the first `orders` terms (all if more).
    pub fn force_n(&self, depth_mm: f64, orders: usize) -> f64 {
        let n = orders.min(self.force.len());
        // Horner from the highest kept order.
        self.force[..n]
            .iter()
            .rev()
            .fold(0.0, |acc, f| (acc + f) * depth_mm)
    }

    /// `u(d) = Σ u_p d^p` (all-node) with the first `orders` terms.
    pub fn displacement(&self, depth_mm: f64, orders: usize) -> Vec<f64> {
        let n = orders.min(self.u.len());
        let mut out = vec![0.0; self.u.first().map_or(0, Vec::len)];
        let mut dp = 1.0;
        for up in &self.u[..n] {
            dp *= depth_mm;
            for (o, v) in out.iter_mut().zip(up) {
                *o += dp * v;
            }
        }
        out
    }

    /// The radius of convergence estimated from the last coefficients of the force
    /// and displacement series (root test, `|a_p|^{−1/p}`, over the upper half of the
    /// orders), mm.
    pub fn radius_mm(&self) -> f64 {
        let n = self.u.len();
        let norms: Vec<f64> = self
            .u
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .collect();
        (n / 2..n)
            .filter(|&k| norms[k] > 0.0)
            .map(|k| norms[k].powf(-1.0 / (k + 1) as f64))
            .fold(f64::INFINITY, f64::min)
    }
}

/// A rational (Padé) form of a [`DepthSeries`]: `[M+1/M]` in the scaled depth
/// `t = d/ρ`, with one denominator `Q(t) = Σ_j q_j t^j` (`q_0 = 1`) for the force and
/// the displacement alike.
///
/// The power series stops converging at its radius, the distance to the nearest
/// singularity of the depth–force path *in the complex plane*. For the liver's
/// neo-Hookean press that singularity lies off the real axis (the coefficients
/// alternate in pairs): the path itself is smooth well past the radius, and a rational
/// function, whose poles stand in for the singularities, continues it. Measured at the
/// anterior point on coarse P2: the series' radius is about 10 mm, its 20-term sum at
/// 15 mm is 60 % off, and `[7/6]` is 0.15 % off the Newton force.
#[derive(Debug, Clone, PartialEq)]
pub struct Rational {
    /// `ρ` (mm): the depth scale that keeps the scaled coefficients near 1.
    pub scale_mm: f64,
    /// `q_0 … q_M`.
    pub q: Vec<f64>,
    /// `L = M + 1`, the numerator's degree.
    pub degree: usize,
    /// Relative change of the force at the largest depth from `[M−1/M−2]`, the
    /// error indicator (`NaN` for the lowest form).
    pub change: f64,
}

impl Rational {
    /// `(w_1 … w_L)` with `u(d) = Σ_i w_i(d) u_i` and `F(d) = Σ_i w_i(d) F_i`:
    /// `w_i = ρ^i Σ_{k=i..min(L, i+M)} q_{k−i} t^k / Q(t)`.
    pub fn weights(&self, depth_mm: f64) -> Vec<f64> {
        let t = depth_mm / self.scale_mm;
        let m = self.q.len() - 1;
        let den: f64 = self.q.iter().rev().fold(0.0, |acc, q| acc * t + q);
        (1..=self.degree)
            .map(|i| {
                let num: f64 = (i..=self.degree.min(i + m))
                    .map(|k| self.q[k - i] * t.powi(k as i32))
                    .sum();
                self.scale_mm.powi(i as i32) * num / den
            })
            .collect()
    }

    /// Whether `Q` stays positive on `[0, depth_mm]` (no pole where it is used).
    fn pole_free(&self, depth_mm: f64) -> bool {
        (0..=400).all(|j| {
            let t = depth_mm / self.scale_mm * f64::from(j) / 400.0;
            self.q.iter().rev().fold(0.0, |acc, q| acc * t + q) > 1e-3
        })
    }
}

/// Solves the small dense system `a x = b` (row-major `n × n`) by Gaussian elimination
/// with partial pivoting; `None` if singular.
/// Solves the dense `n × n` system `a x = b` (row-major) by Gaussian elimination with
/// partial pivoting; `None` where it is singular or the answer not finite.
pub(super) fn solve_dense(mut a: Vec<f64>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let piv =
            (col..n).max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))?;
        if a[piv * n + col].abs() < 1e-300 {
            return None;
        }
        for k in 0..n {
            a.swap(col * n + k, piv * n + k);
        }
        b.swap(col, piv);
        for row in col + 1..n {
            let f = a[row * n + col] / a[col * n + col];
            for k in col..n {
                a[row * n + k] -= f * a[col * n + k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row * n + k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row * n + row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

impl DepthSeries {
    /// The `[M+1/M]` Padé form of the force series (`M` even, `2M + 1` coefficients),
    /// scaled by `scale_mm`; `None` if its system is singular.
    pub fn pade(&self, m: usize, scale_mm: f64) -> Option<Rational> {
        let l = m + 1;
        if l + m > self.force.len() {
            return None;
        }
        // c'_k = F_k ρ^k, c'_0 = 0.
        let c = |k: usize| -> f64 {
            if k == 0 {
                0.0
            } else {
                self.force[k - 1] * scale_mm.powi(k as i32)
            }
        };
        let a: Vec<f64> = (l + 1..=l + m)
            .flat_map(|k| (1..=m).map(move |j| if k >= j { c(k - j) } else { 0.0 }))
            .collect();
        let b: Vec<f64> = (l + 1..=l + m).map(|k| -c(k)).collect();
        let q = if m == 0 {
            Vec::new()
        } else {
            solve_dense(a, b)?
        };
        Some(Rational {
            scale_mm,
            q: std::iter::once(1.0).chain(q).collect(),
            degree: l,
            change: f64::NAN,
        })
    }

    /// The `[M+1/M]` form whose denominator makes the *displacement* series' next `M`
    /// coefficients vanish in the least-squares sense (a vector Padé form):
    /// `min_q Σ_{k=L+1..L+M} ‖Σ_{j=0..M} q_j U_{k−j}‖²`, `q_0 = 1`, `U_k = ρ^k u_k`,
    /// through the Gram matrix of the scaled coefficients. The force shares it.
    pub fn pade_vector(&self, m: usize, scale_mm: f64) -> Option<Rational> {
        let l = m + 1;
        let n = l + m;
        if n > self.u.len() {
            return None;
        }
        // gram[i][j] = ⟨U_i, U_j⟩ for i, j in 0..=n (U_0 = 0).
        let scaled = |k: usize| scale_mm.powi(k as i32);
        let mut gram = vec![vec![0.0; n + 1]; n + 1];
        for i in 1..=n {
            for j in i..=n {
                let g: f64 = self.u[i - 1]
                    .iter()
                    .zip(&self.u[j - 1])
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    * scaled(i)
                    * scaled(j);
                gram[i][j] = g;
                gram[j][i] = g;
            }
        }
        // Normal equations: Σ_k Σ_j q_j ⟨U_{k−a}, U_{k−j}⟩ = −Σ_k ⟨U_{k−a}, U_k⟩, a = 1..M.
        let at = |i: isize, j: isize| -> f64 {
            if i <= 0 || j <= 0 {
                0.0
            } else {
                gram[i as usize][j as usize]
            }
        };
        let (mut a, mut b) = (vec![0.0; m * m], vec![0.0; m]);
        for k in l + 1..=n {
            let k = k as isize;
            for r in 1..=m {
                for c in 1..=m {
                    a[(r - 1) * m + c - 1] += at(k - r as isize, k - c as isize);
                }
                b[r - 1] -= at(k - r as isize, k);
            }
        }
        let q = if m == 0 {
            Vec::new()
        } else {
            solve_dense(a, b)?
        };
        Some(Rational {
            scale_mm,
            q: std::iter::once(1.0).chain(q).collect(),
            degree: l,
            change: f64::NAN,
        })
    }

    /// The highest-order `[M+1/M]` form (`M` even) with no pole on `[0, depth_max_mm]`,
    /// with its change from the next lower valid one at `depth_max_mm`.
    pub fn rational(&self, depth_max_mm: f64) -> Rational {
        let scale = depth_max_mm.abs().max(1e-9);
        let mut best: Option<Rational> = None;
        let mut m = 0;
        while 2 * m < self.force.len() {
            if let Some(mut r) = self.pade(m, scale).filter(|r| r.pole_free(depth_max_mm)) {
                if let Some(prev) = &best {
                    let f = |x: &Rational| -> f64 {
                        x.weights(depth_max_mm)
                            .iter()
                            .zip(&self.force)
                            .map(|(w, f)| w * f)
                            .sum()
                    };
                    let (now, before) = (f(&r), f(prev));
                    r.change = ((now - before) / now).abs();
                }
                best = Some(r);
            }
            m += 2;
        }
        best.expect("[1/0] is the linear term: always valid")
    }

    /// Force and displacement at `depth_mm` from a rational form.
    pub fn evaluate(&self, r: &Rational, depth_mm: f64) -> (f64, Vec<f64>) {
        let w = r.weights(depth_mm);
        let force = w.iter().zip(&self.force).map(|(w, f)| w * f).sum();
        let mut u = vec![0.0; self.u.first().map_or(0, Vec::len)];
        for (wi, ui) in w.iter().zip(&self.u) {
            for (o, v) in u.iter_mut().zip(ui) {
                *o += wi * v;
            }
        }
        (force, u)
    }
}

impl std::fmt::Debug for Expander<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Expander")
            .field("law", &self.law)
            .field("dofs", &self.space.free_dofs)
            .field("factor_s", &self.factor_s)
            .finish()
    }
}

/// The rest stiffness, factored once, and what every expansion on one mesh shares:
/// expanding presses at many positions costs one factorization in all.
pub struct Expander<'a> {
    space: &'a Space,
    law: Law,
    lambda: f64,
    mu: f64,
    chol: Cholesky,
    /// The rest stiffness factored again in single precision, made on first use: the
    /// first segment's chord solves with it (see [`Self::rest_single`]).
    single: std::sync::OnceLock<Option<Cholesky>>,
    pub factor_s: f64,
}

impl<'a> Expander<'a> {
    pub fn new(space: &'a Space, law: Law, material: Material) -> Result<Self, FeError> {
        material.validate()?;
        let t0 = Instant::now();
        let (lambda, mu) = material.lame_n_per_mm2();
        let chol = super::newton::factor_tangent(
            space,
            law,
            &SymCsc::pattern(space),
            &vec![0.0; 3 * space.nodes.len()],
            lambda,
            mu,
        )?;
        Ok(Expander {
            space,
            law,
            lambda,
            mu,
            chol,
            single: std::sync::OnceLock::new(),
            factor_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// Expands the press with load shape `shape` (all-node, unit force) and probe
    /// functional `probe` (all-node: `probe·u` is the depth) to `orders` terms.
    pub fn expand(
        &self,
        shape: &[f64],
        probe: &[f64],
        orders: usize,
    ) -> Result<DepthSeries, FeError> {
        self.expand_active(shape, probe, orders, 0.0)
    }

    /// [`Self::expand`] with the higher orders' right-hand sides assembled on the
    /// [`active_cells`] of `cutoff` only.
    pub fn expand_active(
        &self,
        shape: &[f64],
        probe: &[f64],
        orders: usize,
        cutoff: f64,
    ) -> Result<DepthSeries, FeError> {
        self.expand_active_batch(&[(shape, probe)], orders, cutoff)?
            .pop()
            .expect("one series for one load")
    }

    /// [`Self::expand_active`] for several presses at once, each series what it would
    /// be alone (bit for bit: see [`rest_orders_batch`]). The outer error is the
    /// request's (too many orders); each press has its own result.
    pub fn expand_active_batch(
        &self,
        loads: &[(&[f64], &[f64])],
        orders: usize,
        cutoff: f64,
    ) -> Result<Vec<Result<DepthSeries, FeError>>, FeError> {
        let t0 = Instant::now();
        let mut out = rest_orders_batch(
            self.space,
            self.law,
            (self.lambda, self.mu),
            &self.chol,
            loads,
            orders,
            cutoff,
        )?;
        let each_s = t0.elapsed().as_secs_f64() / loads.len().max(1) as f64;
        for s in out.iter_mut().flatten() {
            s.factor_s = self.factor_s;
            s.seconds = self.factor_s + each_s;
        }
        Ok(out)
    }

    /// The factored rest stiffness (the rest series' exact solves).
    pub fn rest_factor(&self) -> &Cholesky {
        &self.chol
    }

    /// The rest stiffness in single precision, factored once on first use and shared
    /// by every press: the first segment's chord corrections solve with it. A chord's
    /// factor is only an approximate inverse (every residual and acceptance test is in
    /// double precision), and a single solve reads half the bytes of a double one.
    /// Factored and solved sequentially, so its rounding does not depend on the
    /// threads. `None` where the single-precision factorization fails (then the chord
    /// keeps the double factor).
    pub fn rest_single(&self) -> Option<&Cholesky> {
        self.single
            .get_or_init(|| {
                let n = 3 * self.space.nodes.len();
                let k = super::newton::tangent(
                    self.space,
                    self.law,
                    &SymCsc::pattern(self.space),
                    &vec![0.0; n],
                    self.lambda,
                    self.mu,
                );
                Cholesky::factor_single(&k, self.space.fixed_count()).ok()
            })
            .as_ref()
    }
}

pub use super::lanes::MAX_ORDERS;

/// Checks that a series may have `orders` orders, at least `min`.
pub fn check_orders(orders: usize, min: usize) -> Result<(), FeError> {
    if (min.max(1)..=MAX_ORDERS).contains(&orders) {
        Ok(())
    } else {
        Err(FeError::SeriesOrders {
            orders,
            min: min.max(1),
            max: MAX_ORDERS,
        })
    }
}

/// Checks an [`active_cells`] cutoff: a fraction in `[0, 1)`.
pub fn check_cutoff(cutoff: f64) -> Result<(), FeError> {
    if (0.0..1.0).contains(&cutoff) {
        Ok(())
    } else {
        Err(FeError::ActiveCutoff { cutoff })
    }
}

/// The orders `1..=orders` about `base` (`None`: the rest state) with `chol` the
/// factored tangent there (see the module doc).
#[allow(clippy::too_many_arguments)]
pub(crate) fn orders_about(
    space: &Space,
    law: Law,
    lambda: f64,
    mu: f64,
    chol: &Cholesky,
    shape: &[f64],
    probe: &[f64],
    base: Option<&[f64]>,
    orders: usize,
    cutoff: f64,
    augment: Option<(f64, &[f64])>,
) -> Result<DepthSeries, FeError> {
    check_orders(orders, 1)?;
    let shape = space.restrict(shape);
    let probe = space.restrict(probe);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let y = chol.solve(&shape);
    let compliance = dot(&probe, &y);
    if !(compliance.is_finite() && compliance.abs() > 0.0) {
        return Err(FeError::ProbeNotMoved);
    }
    let mut force = Vec::with_capacity(orders);
    let mut lower: Vec<Vec<f64>> = Vec::with_capacity(orders);
    let mut cells = Vec::new();
    for p in 1..=orders {
        if p == 2 {
            cells = active_cells(space, &lower[0], cutoff);
        }
        let (fp, up) = if p == 1 {
            match augment {
                // `chol` factors `K + α n̂n̂ᵀ` (z = its inverse on n̂): `u₁ = F₁ y + α z`
                // with `n̂·u₁ = 1`.
                Some((alpha, z)) => {
                    let f1 = (1.0 - alpha * dot(&probe, z)) / compliance;
                    (
                        f1,
                        y.iter().zip(z).map(|(a, b)| f1 * a + alpha * b).collect(),
                    )
                }
                None => (
                    1.0 / compliance,
                    y.iter().map(|v| v / compliance).collect::<Vec<_>>(),
                ),
            }
        } else {
            let n = coefficient(space, law, base, &lower, p, lambda, mu, &cells);
            let x = chol.solve(&n);
            let fp = dot(&probe, &x) / compliance;
            (fp, y.iter().zip(&x).map(|(a, b)| fp * a - b).collect())
        };
        if !fp.is_finite() {
            return Err(FeError::ProbeNotMoved);
        }
        force.push(fp);
        lower.push(space.expand(&up));
    }
    Ok(DepthSeries {
        force,
        u: lower,
        factor_s: 0.0,
        seconds: 0.0,
    })
}

/// Columns a rest-series solve always has (padded with zeros): see [`solve_columns`].
pub const SOLVE_WIDTH: usize = 4;

/// Solves `chol` for the columns `cols`, [`SOLVE_WIDTH`] at a time: a solve of several
/// right-hand sides reads the factor once (on coarse P2, four columns cost 1.9 times
/// one). faer rounds a column differently in solves of different widths, so every
/// solve here has the same width, a short one padded with zero columns; then a press's
/// series is the same bit for bit alone or in any batch.
fn solve_columns(chol: &Cholesky, cols: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(cols.len());
    for group in cols.chunks(SOLVE_WIDTH) {
        let n = group[0].len();
        let mut m =
            faer::Mat::<f64>::from_fn(n, SOLVE_WIDTH, |i, j| group.get(j).map_or(0.0, |c| c[i]));
        chol.solve_many(&mut m);
        out.extend((0..group.len()).map(|j| (0..n).map(|i| m[(i, j)]).collect()));
    }
    out
}

/// A press's rest series while it is being expanded.
struct Growing {
    probe_free: Vec<f64>,
    y: Vec<f64>,
    compliance: f64,
    force: Vec<f64>,
    lower: Vec<Vec<f64>>,
    cells: Vec<usize>,
    failed: Option<FeError>,
}

/// The rest series (`orders_about` with no base and no augmentation) of several
/// presses, in lockstep: each order assembles every press's right-hand side, then
/// solves them together with the rest factor ([`solve_columns`]). Every series is the
/// one its press gives alone, to the last bit (a unit test compares them).
#[allow(clippy::too_many_arguments)]
pub(crate) fn rest_orders_batch(
    space: &Space,
    law: Law,
    (lambda, mu): (f64, f64),
    chol: &Cholesky,
    loads: &[(&[f64], &[f64])],
    orders: usize,
    cutoff: f64,
) -> Result<Vec<Result<DepthSeries, FeError>>, FeError> {
    check_orders(orders, 1)?;
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let shapes: Vec<Vec<f64>> = loads.iter().map(|(s, _)| space.restrict(s)).collect();
    let ys = solve_columns(chol, &shapes);
    let mut presses: Vec<Growing> = ys
        .into_iter()
        .zip(loads)
        .map(|(y, (_, probe))| {
            let probe_free = space.restrict(probe);
            let compliance = dot(&probe_free, &y);
            let ok = compliance.is_finite() && compliance.abs() > 0.0;
            Growing {
                probe_free,
                y,
                compliance,
                force: Vec::with_capacity(orders),
                lower: Vec::with_capacity(orders),
                cells: Vec::new(),
                failed: (!ok).then_some(FeError::ProbeNotMoved),
            }
        })
        .collect();
    for p in 1..=orders {
        let alive: Vec<usize> = (0..presses.len())
            .filter(|&i| presses[i].failed.is_none())
            .collect();
        let xs = if p == 1 {
            Vec::new()
        } else {
            let rhs: Vec<Vec<f64>> = alive
                .iter()
                .map(|&i| {
                    let g = &mut presses[i];
                    if p == 2 {
                        g.cells = active_cells(space, &g.lower[0], cutoff);
                    }
                    coefficient(space, law, None, &g.lower, p, lambda, mu, &g.cells)
                })
                .collect();
            solve_columns(chol, &rhs)
        };
        for (slot, &i) in alive.iter().enumerate() {
            let g = &mut presses[i];
            let (fp, up) = if p == 1 {
                (
                    1.0 / g.compliance,
                    g.y.iter().map(|v| v / g.compliance).collect::<Vec<_>>(),
                )
            } else {
                let x = &xs[slot];
                let fp = dot(&g.probe_free, x) / g.compliance;
                (fp, g.y.iter().zip(x).map(|(a, b)| fp * a - b).collect())
            };
            if !fp.is_finite() {
                g.failed = Some(FeError::ProbeNotMoved);
                continue;
            }
            g.force.push(fp);
            g.lower.push(space.expand(&up));
        }
    }
    Ok(presses
        .into_iter()
        .map(|g| match g.failed {
            Some(e) => Err(e),
            None => Ok(DepthSeries {
                force: g.force,
                u: g.lower,
                factor_s: 0.0,
                seconds: 0.0,
            }),
        })
        .collect())
}

/// A press expanded twice: about the rest state up to `split_mm`, then about the
/// state there (ANM continuation). The second expansion starts from the first one's
/// Padé state at the split, brought to equilibrium by one Newton correction with the
/// tangent there; see [`SplitTangent`] for which state it expands about.
#[derive(Debug, Clone, PartialEq)]
pub struct Continued {
    pub first: DepthSeries,
    pub split_mm: f64,
    /// The corrected state at the split (all-node) and its force.
    pub base_u: Vec<f64>,
    pub base_force_n: f64,
    /// The Newton correction's size relative to the Padé state (Euclidean norms):
    /// how far the first series was from equilibrium at the split.
    pub correction_rel: f64,
    /// The series in `a = d − split`.
    pub second: DepthSeries,
    pub seconds: f64,
}

impl Continued {
    /// Force and displacement at `depth_mm` (≥ 0), from the segment that holds it,
    /// each through its highest pole-free Padé form up to `depth_max_mm`.
    pub fn evaluate(&self, depth_mm: f64, depth_max_mm: f64) -> (f64, Vec<f64>) {
        if depth_mm <= self.split_mm {
            let r = self.first.rational(self.split_mm);
            return self.first.evaluate(&r, depth_mm);
        }
        let a = depth_mm - self.split_mm;
        let r = self.second.rational((depth_max_mm - self.split_mm).max(a));
        let (df, du) = self.second.evaluate(&r, a);
        let u = self.base_u.iter().zip(&du).map(|(b, d)| b + d).collect();
        (self.base_force_n + df, u)
    }
}

/// Expands the press about the rest state, then again about its state at `split_mm`
/// (see [`Continued`]): what carries the surface, not only the force, to deep presses.
#[allow(clippy::too_many_arguments)]
pub fn continued_series(
    space: &Space,
    law: Law,
    material: Material,
    shape: &[f64],
    probe: &[f64],
    split_mm: f64,
    orders: usize,
) -> Result<Continued, FeError> {
    let t0 = Instant::now();
    let first = depth_series(space, law, material, shape, probe, orders)?;
    let mut c = continued_from(
        space,
        law,
        material,
        shape,
        probe,
        first,
        split_mm,
        orders,
        SplitTangent::Exact,
        0.0,
    )?;
    c.seconds = t0.elapsed().as_secs_f64();
    Ok(c)
}

/// How the second expansion of a [`Continued`] press gets its tangent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SplitTangent {
    /// Factor the tangent at the Padé state for the Newton correction, then again at
    /// the corrected state for the series: the exact ANM step (two factorizations).
    Exact,
    /// Factor once, at the Padé state, for the correction and for a series about
    /// that same state, then shift the series by the correction (a constant offset;
    /// it is about 1e-3 of the state, and its change along the segment is of second
    /// order): half the factorizations.
    Shared,
}

/// [`continued_series`] from a first series already expanded (with an [`Expander`]
/// shared by many presses): the split state and the second series only.
#[allow(clippy::too_many_arguments)]
pub fn continued_from(
    space: &Space,
    law: Law,
    material: Material,
    shape: &[f64],
    probe: &[f64],
    first: DepthSeries,
    split_mm: f64,
    orders: usize,
    tangent: SplitTangent,
    cutoff: f64,
) -> Result<Continued, FeError> {
    let t0 = Instant::now();
    let (lambda, mu) = material.lame_n_per_mm2();
    let (f0, u0) = first.evaluate(&first.rational(split_mm), split_mm);
    let pattern = SymCsc::pattern(space);
    let factor = |u: &[f64]| super::newton::factor_tangent(space, law, &pattern, u, lambda, mu);
    // One Newton correction of the bordered system at the split.
    let chol = factor(&u0)?;
    let fi = super::newton::internal_force(space, law, &u0, lambda, mu);
    let shape_free = space.restrict(shape);
    let probe_free = space.restrict(probe);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let r: Vec<f64> = fi
        .iter()
        .zip(&shape_free)
        .map(|(a, b)| a - f0 * b)
        .collect();
    let g = dot(&probe_free, &space.restrict(&u0)) - split_mm;
    let x1 = chol.solve(&r);
    let x2 = chol.solve(&shape_free);
    let df = (dot(&probe_free, &x1) - g) / dot(&probe_free, &x2);
    let du: Vec<f64> = x2.iter().zip(&x1).map(|(a, b)| df * a - b).collect();
    let du = space.expand(&du);
    let correction_rel = dot(&du, &du).sqrt() / dot(&u0, &u0).sqrt().max(f64::MIN_POSITIVE);
    let base_u: Vec<f64> = u0.iter().zip(&du).map(|(a, b)| a + b).collect();
    let base_force_n = f0 + df;
    // The series must expand about the state its tangent belongs to: with the
    // tangent of another state (even one 1e-3 away) the orders' errors compound and
    // the Padé forms stop converging. `Shared` expands about the Padé state, the
    // equilibrium path of a load off by that state's small residual, and carries the
    // correction along as a constant offset (in `base_u`).
    let (chol, about) = match tangent {
        SplitTangent::Exact => (factor(&base_u)?, &base_u),
        SplitTangent::Shared => (chol, &u0),
    };
    let second = orders_about(
        space,
        law,
        lambda,
        mu,
        &chol,
        shape,
        probe,
        Some(about),
        orders,
        cutoff,
        None,
    )?;
    Ok(Continued {
        first,
        split_mm,
        base_u,
        base_force_n,
        correction_rel,
        second,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Expands one press (factoring the stiffness for it alone; see [`Expander`] for
/// many).
pub fn depth_series(
    space: &Space,
    law: Law,
    material: Material,
    shape: &[f64],
    probe: &[f64],
    orders: usize,
) -> Result<DepthSeries, FeError> {
    Expander::new(space, law, material)?.expand(shape, probe, orders)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::hyper::element;
    use crate::fe::hyper::tests::one_tet_space;
    use crate::rng::Rng;

    /// The series coefficients of the internal force along `d ↦ Σ d^i u_i` against
    /// the force itself: summed to the order of the path's truncation they reproduce
    /// `f_int(u(d))` to O(d^{p+1}) — here p = 6 at d = 0.05, far below round-off
    /// relative to the linear term — for both laws and both elements.
    /// A press's rest series is the same, bit for bit, expanded alone or in a batch
    /// with others, at any place in the batch: a build's presses do not depend on how
    /// its tasks group them (or on which were taken from a log).
    #[test]
    fn a_series_in_a_batch_is_the_series_alone() {
        use crate::fe::load::{probe_functional, probe_load};
        use crate::fe::probe::{ProbeRequest, locate, organ_vertex_normals};
        let organ = crate::organ::catalogue::mesh(
            crate::organ::catalogue::OrganName::Liver,
            crate::organ::Level::Coarse,
        );
        let space = crate::fe::probe::organ_space(&organ, Element::P2);
        let expander =
            Expander::new(&space, Law::NeoHookean, Material::default()).expect("rest factor");
        let normals = organ_vertex_normals(&organ);
        let pressable = organ.pressable_vertices();
        // Three vertices pressed along their inward normals by a 5 mm tool, as the
        // tissue build presses them.
        let loads: Vec<(Vec<f64>, Vec<f64>)> = [0, pressable.len() / 3, pressable.len() / 2]
            .iter()
            .map(|&i| {
                let v = pressable[i] as usize;
                let req = ProbeRequest {
                    at: organ.mesh.vertices[v],
                    force_n: 1.0,
                    dir: Some(normals[v].map(|c| -f64::from(c))),
                    radius_mm: 5.0,
                    nodule: None,
                };
                let (probe, dir) = locate(&space, &organ, &req).expect("on the surface");
                let shape = probe_load(&space, &probe, dir, 1.0, 5.0).expect("a load");
                (shape, probe_functional(&space, &probe, dir))
            })
            .collect();
        let cutoff = 1e-2;
        let refs: Vec<(&[f64], &[f64])> = loads
            .iter()
            .map(|(s, p)| (s.as_slice(), p.as_slice()))
            .collect();
        let orders = 5;
        let batch = expander
            .expand_active_batch(&refs, orders, cutoff)
            .expect("orders in range");
        let reversed = expander
            .expand_active_batch(&[refs[2], refs[1]], orders, cutoff)
            .expect("orders in range");
        for (i, (s, p)) in refs.iter().enumerate() {
            let alone = expander
                .expand_active(s, p, orders, cutoff)
                .expect("a series");
            let mut others = vec![batch[i].as_ref().expect("a series")];
            if i > 0 {
                others.push(reversed[2 - i].as_ref().expect("a series"));
            }
            for other in others {
                assert_eq!(alone.force.len(), orders);
                for (a, b) in alone.force.iter().zip(&other.force) {
                    assert_eq!(a.to_bits(), b.to_bits(), "press {i}: force {a} against {b}");
                }
                for (ua, ub) in alone.u.iter().zip(&other.u) {
                    assert!(
                        ua.iter().zip(ub).all(|(a, b)| a.to_bits() == b.to_bits()),
                        "press {i}: an order differs"
                    );
                }
            }
        }
    }

    #[test]
    fn coefficients_sum_to_the_internal_force_along_the_path() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        for law in [Law::Svk, Law::NeoHookean] {
            for kind in [Element::P1, Element::P2] {
                let space = one_tet_space(kind);
                let m = 3 * kind.nodes_per_cell();
                let mut rng = Rng::seed(9);
                let orders = 6;
                let path: Vec<Vec<f64>> = (0..orders)
                    .map(|_| (0..m).map(|_| rng.range(-0.6, 0.6)).collect())
                    .collect();
                // About the rest state, and about a deformed one.
                let deformed: Vec<f64> = (0..m).map(|_| rng.range(-0.5, 0.5)).collect();
                for base in [None, Some(&deformed[..])] {
                    let u0 = base.map_or_else(|| vec![0.0; m], <[f64]>::to_vec);
                    // N_p with all of u_1..u_{p−1}, plus K(u_0) u_p (the tangent there).
                    let mut k0 = vec![0.0; m * m];
                    let mut f0 = vec![0.0; m];
                    element(&space, law, 0, &u0, lambda, mu, &mut f0, Some(&mut k0));
                    let mut coef = vec![vec![0.0; m]; orders + 1];
                    for p in 1..=orders {
                        let mut fe = vec![0.0; m];
                        element_coefficient(
                            &space,
                            law,
                            0,
                            base,
                            &path[..p - 1],
                            p,
                            lambda,
                            mu,
                            &mut fe,
                        );
                        for r in 0..m {
                            let ku: f64 = (0..m).map(|c| k0[r * m + c] * path[p - 1][c]).sum();
                            coef[p][r] = fe[r] + ku;
                        }
                    }
                    let d: f64 = 0.05;
                    let u: Vec<f64> = (0..m)
                        .map(|r| {
                            u0[r]
                                + (0..orders)
                                    .map(|i| d.powi(i as i32 + 1) * path[i][r])
                                    .sum::<f64>()
                        })
                        .collect();
                    let mut want = vec![0.0; m];
                    element(&space, law, 0, &u, lambda, mu, &mut want, None);
                    let scale = want
                        .iter()
                        .zip(&f0)
                        .fold(0.0f64, |a, (w, z)| a.max((w - z).abs()));
                    for r in 0..m {
                        let got: f64 = f0[r]
                            + (1..=orders)
                                .map(|p| d.powi(p as i32) * coef[p][r])
                                .sum::<f64>();
                        assert!(
                            (got - want[r]).abs() < 1e-7 * scale,
                            "{law:?} {kind:?} base {}: row {r}: {got} against {}",
                            base.is_some(),
                            want[r]
                        );
                    }
                }
            }
        }
    }
}
