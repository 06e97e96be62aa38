//! Greedy minimal-residual PGD for linear systems in separated (Kronecker) form.
//!
//! Solves `L u = F` on a tensor grid `Π_k [0, m_k)` with
//!
//! `L = Σ_a c_a ⊗_k B_a^k` (sparse 1-D factors), `F = Σ_f s_f ⊗_k f_f^k`,
//!
//! for `u ≈ Σ_j α_j ⊗_k w_j^k` (unit-norm factors), one rank-one term at a time:
//!
//! 1. **Enrichment.** The new term `w = ⊗_k w_k` minimizes `‖F − L(u_n + w)‖₂`. That is
//!    quadratic in each factor with the others fixed, so alternating directions solve,
//!    for one axis `k` at a time, the `m_k × m_k` normal equations
//!    `[Σ_{a,b} c_a c_b Π_{o≠k} ⟨B_a^o w_o, B_b^o w_o⟩ (B_a^k)ᵀ B_b^k] w_k
//!       = Σ_a c_a (B_a^k)ᵀ Σ_ρ s_ρ Π_{o≠k} ⟨B_a^o w_o, ρ_o⟩ ρ_k`,
//!    `ρ` running over the residual's rank-one terms (those of `F` and of `−α_j L u_j`).
//!    The matrix is symmetric positive (semi)definite and banded (every factor here is
//!    banded), so a banded Cholesky solves it in `O(m b²)`.
//! 2. **Update.** All weights `α` are re-fitted together: `G α = g` with
//!    `G_ij = ⟨L u_i, L u_j⟩`, `g_i = ⟨L u_i, F⟩` (the residual's minimum over the span).
//!
//! The minimal-residual form (not Galerkin) is used because the CME operator is not
//! symmetric: the residual then falls monotonically with every term. Its price is the
//! squared number of operator terms in the normal equations. The residual norm is
//! tracked exactly from `G` and `g`, relative to `‖F‖`.

use crate::rng::Rng;
use crate::tensor::Sparse1d;

/// `coef · ⊗_k factors[k]`.
#[derive(Debug, Clone, PartialEq)]
pub struct OpTerm {
    pub coef: f64,
    pub factors: Vec<Sparse1d>,
}

/// `scale · ⊗_k factors[k]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RankOne {
    pub scale: f64,
    pub factors: Vec<Vec<f64>>,
}

/// When the greedy solver stops and how hard each term is worked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub max_modes: usize,
    /// Stop when `‖F − L u‖ / ‖F‖` falls below this.
    pub tol: f64,
    /// Alternating-direction sweeps per term (at most).
    pub max_sweeps: usize,
    /// A term's sweeps stop when its factors change less than this (relative).
    pub sweep_tol: f64,
    pub seed: u64,
    /// For approximation problems (`L` = identity): every this many terms, re-fit one
    /// axis's factors of all terms together (the others fixed), a linear least-squares
    /// problem: the PGD *update* applied to a whole axis, e.g. the time functions.
    pub refit: Option<(usize, usize)>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            max_modes: 100,
            tol: 1e-6,
            max_sweeps: 12,
            sweep_tol: 1e-4,
            seed: 1,
            refit: None,
        }
    }
}

/// The computed terms and the relative residual after each one.
#[derive(Debug, Clone)]
pub struct Solution {
    pub terms: Vec<RankOne>,
    pub residual_per_mode: Vec<f64>,
}

/// `‖Σ_r r‖₂²` of a sum of rank-one tensors.
pub fn norm_sq(terms: &[RankOne]) -> f64 {
    let mut s = 0.0;
    for (i, a) in terms.iter().enumerate() {
        for b in &terms[i..] {
            let p: f64 = a
                .factors
                .iter()
                .zip(&b.factors)
                .map(|(x, y)| dot(x, y))
                .product();
            let w = if std::ptr::eq(a, b) { 1.0 } else { 2.0 };
            s += w * a.scale * b.scale * p;
        }
    }
    s
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    crate::kernels::dot(a, b)
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// Product over all axes but `skip` of `table[o]`.
fn product_except(values: impl Iterator<Item = f64>, skip: usize) -> f64 {
    values
        .enumerate()
        .filter(|&(o, _)| o != skip)
        .map(|(_, v)| v)
        .product()
}

/// A mode with its images under each operator term: `lw[a][k] = B_a^k w_k`.
struct Mode {
    factors: Vec<Vec<f64>>,
    lw: Vec<Vec<Vec<f64>>>,
}

impl Mode {
    fn new(ops: &[OpTerm], factors: Vec<Vec<f64>>) -> Self {
        let lw = ops
            .iter()
            .map(|t| {
                t.factors
                    .iter()
                    .zip(&factors)
                    .map(|(b, w)| b.applied(w))
                    .collect()
            })
            .collect();
        Mode { factors, lw }
    }
}

/// `⟨L u, L v⟩` for two modes (unit weights).
fn op_inner(ops: &[OpTerm], u: &Mode, v: &Mode) -> f64 {
    let mut s = 0.0;
    for (a, ta) in ops.iter().enumerate() {
        for (b, tb) in ops.iter().enumerate() {
            let p: f64 = u.lw[a]
                .iter()
                .zip(&v.lw[b])
                .map(|(x, y)| dot(x, y))
                .product();
            s += ta.coef * tb.coef * p;
        }
    }
    s
}

/// `⟨L u, F⟩`.
fn op_rhs_inner(ops: &[OpTerm], u: &Mode, rhs: &[RankOne]) -> f64 {
    let mut s = 0.0;
    for (a, ta) in ops.iter().enumerate() {
        for f in rhs {
            let p: f64 = u.lw[a]
                .iter()
                .zip(&f.factors)
                .map(|(x, y)| dot(x, y))
                .product();
            s += ta.coef * f.scale * p;
        }
    }
    s
}

/// Solves `L u = F` greedily; `progress(modes, relative residual)` after each term.
pub fn solve(
    ops: &[OpTerm],
    rhs: &[RankOne],
    settings: &Settings,
    progress: &mut dyn FnMut(usize, f64),
) -> Solution {
    solve_from(ops, rhs, settings, &[], progress)
}

/// [`solve`], starting the j-th term's alternating directions from `guesses[j]` (e.g.
/// the previous time step's terms, which the new ones resemble) instead of a random
/// positive vector: a good start converges in one or two sweeps.
pub fn solve_from(
    ops: &[OpTerm],
    rhs: &[RankOne],
    settings: &Settings,
    guesses: &[Vec<Vec<f64>>],
    progress: &mut dyn FnMut(usize, f64),
) -> Solution {
    let d = rhs.first().map_or(0, |f| f.factors.len());
    let dims: Vec<usize> = rhs
        .first()
        .map(|f| f.factors.iter().map(Vec::len).collect())
        .unwrap_or_default();
    let rhs_sq: f64 = rhs
        .iter()
        .flat_map(|f| {
            rhs.iter().map(move |g| {
                f.scale
                    * g.scale
                    * f.factors
                        .iter()
                        .zip(&g.factors)
                        .map(|(x, y)| dot(x, y))
                        .product::<f64>()
            })
        })
        .sum();
    let mut out = Solution {
        terms: Vec::new(),
        residual_per_mode: Vec::new(),
    };
    if d == 0 || rhs_sq <= 0.0 {
        return out;
    }
    let rhs_norm = rhs_sq.sqrt();
    let mut rng = Rng::seed(settings.seed);
    let mut modes: Vec<Mode> = Vec::new();
    let mut alpha: Vec<f64> = Vec::new();
    let mut gram: Vec<Vec<f64>> = Vec::new();
    let mut g: Vec<f64> = Vec::new();
    while modes.len() < settings.max_modes {
        let guess = guesses.get(modes.len());
        let w = enrich(ops, rhs, &modes, &alpha, &dims, settings, guess, &mut rng);
        let mode = Mode::new(ops, w);
        let row: Vec<f64> = modes.iter().map(|m| op_inner(ops, &mode, m)).collect();
        let diag = op_inner(ops, &mode, &mode);
        if diag.is_nan() || diag <= 1e-300 {
            break;
        }
        for (r, v) in gram.iter_mut().zip(&row) {
            r.push(*v);
        }
        let mut new_row = row;
        new_row.push(diag);
        gram.push(new_row);
        g.push(op_rhs_inner(ops, &mode, rhs));
        modes.push(mode);
        alpha = solve_spd(&gram, &g);
        if let Some((axis, every)) = settings.refit
            && every > 0
            && modes.len().is_multiple_of(every)
            && ops.len() == 1
            && ops[0].factors.iter().all(|f| f.is_identity())
            && axis < d
        {
            refit_axis(ops, rhs, &mut modes, axis);
            gram = modes
                .iter()
                .map(|u| modes.iter().map(|v| op_inner(ops, u, v)).collect())
                .collect();
            g = modes.iter().map(|u| op_rhs_inner(ops, u, rhs)).collect();
            alpha = solve_spd(&gram, &g);
        }
        // ‖F − Lu‖² = ‖F‖² − 2αᵀg + αᵀGα = ‖F‖² − αᵀg at the least-squares optimum.
        let res_sq = rhs_sq - dot(&alpha, &g);
        let rel = (res_sq.max(0.0)).sqrt() / rhs_norm;
        out.residual_per_mode.push(rel);
        progress(modes.len(), rel);
        if rel < settings.tol {
            break;
        }
        // Stagnation: twelve terms that together gain less than 0.1 %.
        let n = out.residual_per_mode.len();
        if n > 12 && out.residual_per_mode[n - 1] > 0.999 * out.residual_per_mode[n - 13] {
            break;
        }
    }
    out.terms = modes
        .into_iter()
        .zip(alpha)
        .map(|(m, a)| RankOne {
            scale: a,
            factors: m.factors,
        })
        .collect();
    out
}

/// Re-fits axis `a` of every term together for `min ‖F − Σ_j ⊗_k w_j^k‖` (identity
/// operator), the other axes fixed: `Σ_j G_ij v_j = Σ_f s_f Π_{o≠a}⟨w_i^o, f^o⟩ f^a`,
/// `G_ij = Π_{o≠a}⟨w_i^o, w_j^o⟩`. The weights are folded in afterwards by the caller's
/// weight update; here each new factor is normalized.
fn refit_axis(ops: &[OpTerm], rhs: &[RankOne], modes: &mut [Mode], a: usize) {
    let n = modes.len();
    let d = modes[0].factors.len();
    let ma = modes[0].factors[a].len();
    let others = |x: &[Vec<f64>], y: &[Vec<f64>]| -> f64 {
        (0..d)
            .filter(|&o| o != a)
            .map(|o| dot(&x[o], &y[o]))
            .product()
    };
    let mut gm = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let v = others(&modes[i].factors, &modes[j].factors);
            gm[i * n + j] = v;
            gm[j * n + i] = v;
        }
    }
    // R (n × m_a), row i = Σ_f s_f Π_{o≠a}⟨w_i^o, f^o⟩ f^a.
    let mut r = vec![0.0; n * ma];
    for (i, m) in modes.iter().enumerate() {
        let row = &mut r[i * ma..(i + 1) * ma];
        for f in rhs {
            let c = f.scale * others(&m.factors, &f.factors);
            for (x, y) in row.iter_mut().zip(&f.factors[a]) {
                *x += c * y;
            }
        }
    }
    let Some(chol) = cholesky(&gm, n) else {
        return;
    };
    let mut col = vec![0.0; n];
    let mut v = vec![0.0; n * ma];
    for z in 0..ma {
        for i in 0..n {
            col[i] = r[i * ma + z];
        }
        chol_solve(&chol, n, &mut col);
        for i in 0..n {
            v[i * ma + z] = col[i];
        }
    }
    for (j, m) in modes.iter_mut().enumerate() {
        let vj = &v[j * ma..(j + 1) * ma];
        let nv = norm(vj);
        if nv > 0.0 && nv.is_finite() {
            m.factors[a] = vj.iter().map(|x| x / nv).collect();
            *m = Mode::new(ops, std::mem::take(&mut m.factors));
        }
    }
}

/// Dense Cholesky `G = L Lᵀ` (row-major lower factor), with a tiny diagonal shift.
fn cholesky(g: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut l = g.to_vec();
    let scale = (0..n).map(|i| g[i * n + i].abs()).fold(0.0, f64::max);
    for i in 0..n {
        l[i * n + i] += 1e-12 * scale;
    }
    for j in 0..n {
        let mut s = l[j * n + j];
        for k in 0..j {
            s -= l[j * n + k] * l[j * n + k];
        }
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let djj = s.sqrt();
        l[j * n + j] = djj;
        for i in j + 1..n {
            let mut s = l[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = s / djj;
        }
    }
    Some(l)
}

fn chol_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let s: f64 = (0..i).map(|k| l[i * n + k] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| l[k * n + i] * b[k]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
}

/// One new rank-one term by alternating directions on the minimal-residual problem.
#[allow(clippy::too_many_arguments)]
fn enrich(
    ops: &[OpTerm],
    rhs: &[RankOne],
    modes: &[Mode],
    alpha: &[f64],
    dims: &[usize],
    settings: &Settings,
    guess: Option<&Vec<Vec<f64>>>,
    rng: &mut Rng,
) -> Vec<Vec<f64>> {
    let d = dims.len();
    let nops = ops.len();
    // Start: the guess, or positive random factors (a CME solution is non-negative).
    let mut w: Vec<Vec<f64>> = dims
        .iter()
        .enumerate()
        .map(|(k, &m)| {
            let v: Vec<f64> = match guess.map(|g| &g[k]) {
                Some(g) if g.len() == m && norm(g) > 0.0 => g.clone(),
                _ => (0..m).map(|_| 0.5 + rng.uniform()).collect(),
            };
            let n = norm(&v);
            v.into_iter().map(|x| x / n).collect()
        })
        .collect();
    // lw[a][o] = B_a^o w_o, and the dot tables against every residual term per axis.
    let mut lw: Vec<Vec<Vec<f64>>> = ops
        .iter()
        .map(|t| {
            t.factors
                .iter()
                .zip(&w)
                .map(|(b, x)| b.applied(x))
                .collect()
        })
        .collect();
    // Residual terms: F's, then −α_j c_b B_b u_j for every mode j and operator term b.
    let res_count = rhs.len() + modes.len() * nops;
    let res_factor = |r: usize, o: usize| -> &[f64] {
        if r < rhs.len() {
            &rhs[r].factors[o]
        } else {
            let j = (r - rhs.len()) / nops;
            let b = (r - rhs.len()) % nops;
            &modes[j].lw[b][o]
        }
    };
    let res_scale = |r: usize| -> f64 {
        if r < rhs.len() {
            rhs[r].scale
        } else {
            let j = (r - rhs.len()) / nops;
            let b = (r - rhs.len()) % nops;
            -alpha[j] * ops[b].coef
        }
    };
    // rdot[o][a][r] = ⟨B_a^o w_o, ρ_r^o⟩; wdot[o][a][b] = ⟨B_a^o w_o, B_b^o w_o⟩.
    let mut rdot = vec![vec![vec![0.0; res_count]; nops]; d];
    let mut wdot = vec![vec![vec![0.0; nops]; nops]; d];
    let refresh = |o: usize,
                   lw: &Vec<Vec<Vec<f64>>>,
                   rdot: &mut Vec<Vec<Vec<f64>>>,
                   wdot: &mut Vec<Vec<Vec<f64>>>| {
        for a in 0..nops {
            for r in 0..res_count {
                rdot[o][a][r] = dot(&lw[a][o], res_factor(r, o));
            }
            for b in 0..nops {
                wdot[o][a][b] = dot(&lw[a][o], &lw[b][o]);
            }
        }
    };
    for o in 0..d {
        refresh(o, &lw, &mut rdot, &mut wdot);
    }
    for _sweep in 0..settings.max_sweeps {
        let mut change = 0.0f64;
        for k in 0..d {
            let m = dims[k];
            // Normal matrix, banded.
            let mut mat = Banded::new(m);
            for (a, ta) in ops.iter().enumerate() {
                for (b, tb) in ops.iter().enumerate() {
                    let gab = ta.coef * tb.coef * product_except((0..d).map(|o| wdot[o][a][b]), k);
                    if gab == 0.0 {
                        continue;
                    }
                    let (ba, bb) = (&ta.factors[k], &tb.factors[k]);
                    for row in 0..ba.rows {
                        for (i, va) in ba.row(row) {
                            for (j, vb) in bb.row(row) {
                                mat.add(i, j, gab * va * vb);
                            }
                        }
                    }
                }
            }
            // Right-hand side.
            let mut rvec = vec![0.0; m];
            let mut acc = vec![0.0; m];
            for (a, ta) in ops.iter().enumerate() {
                acc.fill(0.0);
                for r in 0..res_count {
                    let s = res_scale(r) * product_except((0..d).map(|o| rdot[o][a][r]), k);
                    if s != 0.0 {
                        for (x, y) in acc.iter_mut().zip(res_factor(r, k)) {
                            *x += s * y;
                        }
                    }
                }
                ta.factors[k].add_transposed(ta.coef, &acc, &mut rvec);
            }
            let Some(sol) = mat.solve(&rvec) else {
                continue;
            };
            let n = norm(&sol);
            if !(n > 0.0 && n.is_finite()) {
                continue;
            }
            let new: Vec<f64> = sol.iter().map(|x| x / n).collect();
            // Sign: keep the factor's largest entry positive so sweeps can converge.
            let sign = if new
                .iter()
                .copied()
                .fold(0.0, |s: f64, x| if x.abs() > s.abs() { x } else { s })
                < 0.0
            {
                -1.0
            } else {
                1.0
            };
            let new: Vec<f64> = new.into_iter().map(|x| sign * x).collect();
            let diff: f64 = new
                .iter()
                .zip(&w[k])
                .map(|(x, y)| (x - y) * (x - y))
                .sum::<f64>()
                .sqrt();
            change = change.max(diff);
            w[k] = new;
            for (a, t) in ops.iter().enumerate() {
                lw[a][k] = t.factors[k].applied(&w[k]);
            }
            refresh(k, &lw, &mut rdot, &mut wdot);
        }
        if change < settings.sweep_tol {
            break;
        }
    }
    w
}

/// A symmetric banded matrix stored densely by rows within its band, solved by
/// Cholesky (with a tiny diagonal shift if it is only semidefinite).
struct Banded {
    m: usize,
    entries: Vec<(usize, usize, f64)>,
}

impl Banded {
    fn new(m: usize) -> Self {
        Banded {
            m,
            entries: Vec::new(),
        }
    }

    fn add(&mut self, i: usize, j: usize, v: f64) {
        self.entries.push((i, j, v));
    }

    fn solve(&self, b: &[f64]) -> Option<Vec<f64>> {
        let m = self.m;
        let bw = self
            .entries
            .iter()
            .map(|&(i, j, _)| i.abs_diff(j))
            .max()
            .unwrap_or(0);
        let w = bw + 1;
        // band[i][k] = A[i][i − bw + k] for the lower triangle.
        let mut band = vec![0.0; m * w];
        for &(i, j, v) in &self.entries {
            if j <= i {
                band[i * w + (j + bw - i)] += v;
            }
        }
        let scale = (0..m).map(|i| band[i * w + bw].abs()).fold(0.0, f64::max);
        if scale.is_nan() || scale <= 0.0 {
            return None;
        }
        for i in 0..m {
            band[i * w + bw] += 1e-13 * scale;
        }
        for i in 0..m {
            let j0 = i.saturating_sub(bw);
            for j in j0..=i {
                let mut s = band[i * w + (j + bw - i)];
                let k0 = j0.max(j.saturating_sub(bw));
                for k in k0..j {
                    s -= band[i * w + (k + bw - i)] * band[j * w + (k + bw - j)];
                }
                if j == i {
                    if s.is_nan() || s <= 0.0 {
                        return None;
                    }
                    band[i * w + bw] = s.sqrt();
                } else {
                    band[i * w + (j + bw - i)] = s / band[j * w + bw];
                }
            }
        }
        let mut y = b.to_vec();
        for i in 0..m {
            let j0 = i.saturating_sub(bw);
            for k in j0..i {
                y[i] -= band[i * w + (k + bw - i)] * y[k];
            }
            y[i] /= band[i * w + bw];
        }
        for i in (0..m).rev() {
            for k in i + 1..(i + w).min(m) {
                y[i] -= band[k * w + (i + bw - k)] * y[k];
            }
            y[i] /= band[i * w + bw];
        }
        y.iter().all(|v| v.is_finite()).then_some(y)
    }
}

/// Solves the small dense SPD system `G x = g` (Cholesky, tiny shift for safety).
fn solve_spd(gm: &[Vec<f64>], g: &[f64]) -> Vec<f64> {
    let n = g.len();
    let mut b = Banded::new(n);
    for (i, row) in gm.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            b.add(i, j, v);
        }
    }
    b.solve(g).unwrap_or_else(|| vec![0.0; n])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2-D Poisson-like problem `(T ⊗ I + I ⊗ T) u = f ⊗ f` against a dense solve.
    #[test]
    fn greedy_solves_a_kronecker_sum() {
        let m = 12;
        let t = Sparse1d::from_triplets(
            m,
            m,
            (0..m).flat_map(|i| {
                let mut v = vec![(i, i, 2.5)];
                if i > 0 {
                    v.push((i, i - 1, -1.0));
                }
                if i + 1 < m {
                    v.push((i, i + 1, -0.7));
                }
                v
            }),
        );
        let ops = vec![
            OpTerm {
                coef: 1.0,
                factors: vec![t.clone(), Sparse1d::identity(m)],
            },
            OpTerm {
                coef: 1.0,
                factors: vec![Sparse1d::identity(m), t.clone()],
            },
        ];
        let f: Vec<f64> = (0..m).map(|i| 1.0 + (i as f64).sin()).collect();
        let rhs = vec![RankOne {
            scale: 1.0,
            factors: vec![f.clone(), f.clone()],
        }];
        let sol = solve(
            &ops,
            &rhs,
            &Settings {
                max_modes: 40,
                tol: 1e-5,
                ..Settings::default()
            },
            &mut |_, _| {},
        );
        let res = &sol.residual_per_mode;
        assert!(
            res.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-9)),
            "{res:?}"
        );
        // Dense check: apply L to u and compare with F.
        let full = |terms: &[RankOne]| -> Vec<f64> {
            let mut u = vec![0.0; m * m];
            for r in terms {
                for i in 0..m {
                    for j in 0..m {
                        u[i * m + j] += r.scale * r.factors[0][i] * r.factors[1][j];
                    }
                }
            }
            u
        };
        let u = full(&sol.terms);
        let mut lu = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                let mut s = 0.0;
                for (c, v) in t.row(i) {
                    s += v * u[c * m + j];
                }
                for (c, v) in t.row(j) {
                    s += v * u[i * m + c];
                }
                lu[i * m + j] = s;
            }
        }
        let fu = full(&rhs);
        let err: f64 = lu
            .iter()
            .zip(&fu)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            err < 2e-5 * norm(&fu),
            "residual {err}, reported {:?}",
            sol.residual_per_mode.last()
        );
    }

    #[test]
    fn banded_cholesky_matches_a_dense_solution() {
        let mut b = Banded::new(5);
        let a = [
            [4.0, 1.0, 0.5, 0.0, 0.0],
            [1.0, 5.0, 1.0, 0.2, 0.0],
            [0.5, 1.0, 6.0, 1.0, 0.3],
            [0.0, 0.2, 1.0, 7.0, 1.0],
            [0.0, 0.0, 0.3, 1.0, 8.0],
        ];
        for (i, row) in a.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                if v != 0.0 {
                    b.add(i, j, v);
                }
            }
        }
        let x_true = [1.0, -2.0, 0.5, 3.0, -1.0];
        let rhs: Vec<f64> = a.iter().map(|r| dot(r, &x_true)).collect();
        let x = b.solve(&rhs).expect("positive definite");
        for (u, v) in x.iter().zip(x_true) {
            assert!((u - v).abs() < 1e-9, "{x:?}");
        }
    }
}
