//! Block enrichment: `b` PGD terms per alternating-directions fixed point, so every
//! spatial solve is a multi-right-hand-side pass over the factored stiffness.
//!
//! The single-term fixed point of [`linear`](super::linear) costs one single-RHS solve
//! per iteration, and a single-RHS solve streams the whole Cholesky factor: on the
//! medium liver that is ≈0.3 s for one column against ≈0.02 s per column when 64 go
//! together. Here the new terms form a block `R Sᵀ` (R: n × q, S: m × q, q = b + p with
//! p extra columns that speed up convergence and are dropped), and the same two
//! least-squares steps act on blocks:
//!
//! ```text
//! S fixed:  R = K⁻¹ F (Ms S) − X (Yᵀ Ms S)        (one q-column solve; by linearity the
//!                                                 K X_k of the single-term RHS cancel)
//!           then R ← R (RᵀKR)^{-1/2}              (K-orthonormal columns)
//! R fixed:  S = Fᵀ R − Y (XᵀK R)
//! ```
//!
//! followed by a Rayleigh–Ritz rotation that diagonalizes `Sᵀ Ms S`, so the columns
//! come out ordered by their share of the residual map and the block's first terms are
//! the best ones (a truncated model keeps the leading terms). This is subspace
//! iteration on the residual map `G − U_n`; with `b = 1, p = 0` it is the classic
//! greedy fixed point. The iteration stops when the change of the kept part
//! `Σ_{i<b} R_i S_iᵀ`, in the natural norm, is below `fixed_point_tol` relative.
//! Accepted terms get the same Galerkin update as the single-term solver.

use std::time::Instant;

use faer::{Mat, Side};
use rayon::prelude::*;

use super::linear::{Operators, Settings, Terms, update};
use crate::rng::Rng;

/// Extra columns iterated along with each block and then dropped.
pub fn oversampling(block: usize) -> usize {
    if block <= 1 {
        0
    } else {
        (block / 2).clamp(2, 8)
    }
}

fn col(m: &Mat<f64>, j: usize) -> &[f64] {
    m.col(j)
        .try_as_col_major()
        .expect("faer allocates owned matrices column-major and contiguous")
        .as_slice()
}

/// `out[:, j] = A x[:, j]` for a symmetric CSC matrix, columns in parallel.
fn sym_mul_cols(a: &crate::fe::sparse::SymCsc, x: &Mat<f64>) -> Mat<f64> {
    let cols: Vec<Vec<f64>> = (0..x.ncols())
        .into_par_iter()
        .map(|j| {
            let mut y = vec![0.0; x.nrows()];
            a.mul(col(x, j), &mut y);
            y
        })
        .collect();
    Mat::from_fn(x.nrows(), x.ncols(), |i, j| cols[j][i])
}

/// Dense n × N matrix of stored vectors (columns).
fn stack(v: &[Vec<f64>], rows: usize) -> Mat<f64> {
    Mat::from_fn(rows, v.len(), |i, j| v[j][i])
}

/// Eigen-decomposition of a small symmetric matrix, eigenvalues descending.
fn eigen_desc(a: &Mat<f64>) -> Option<(Vec<f64>, Mat<f64>)> {
    let sym = Mat::from_fn(a.nrows(), a.ncols(), |i, j| 0.5 * (a[(i, j)] + a[(j, i)]));
    let evd = sym.self_adjoint_eigen(Side::Lower).ok()?;
    let s = evd.S().column_vector();
    let u = evd.U();
    let n = a.nrows();
    let order: Vec<usize> = (0..n).rev().collect(); // faer returns them ascending
    let vals = order.iter().map(|&i| s[i]).collect();
    let vecs = Mat::from_fn(n, n, |i, j| u[(i, order[j])]);
    Some((vals, vecs))
}

/// Runs block enrichment from `start`; `progress` is called after each accepted
/// block (the new terms are the ones past the previous call's count).
pub fn solve(
    ops: &Operators,
    settings: &Settings,
    start: Terms,
    mut progress: impl FnMut(&Terms),
) -> Terms {
    let block = settings.block.max(1);
    let n = ops.f.rows;
    let m = ops.f.cols.len();
    let mut t = start;
    while t.x.len() < settings.max_modes {
        let t0 = Instant::now();
        let nb = block.min(settings.max_modes - t.x.len()).min(m);
        let q = (nb + oversampling(block)).min(m);
        let have = t.x.len();
        let xm = stack(&t.x, n);
        let ym = stack(&t.y, m);
        // Seeded per first term index: a resumed run reproduces the same blocks.
        let mut rng = Rng::seed(settings.seed.wrapping_add(have as u64));
        let mut s = Mat::from_fn(m, q, |_, _| rng.range(-1.0, 1.0));
        let mut r = Mat::<f64>::zeros(n, 0);
        let mut kr = Mat::<f64>::zeros(n, 0);
        let mut lambda: Vec<f64> = Vec::new();
        // Ms S of the current S, carried from the Rayleigh–Ritz step to the next R-step.
        let mut ms_s_cur: Option<Mat<f64>> = None;
        let mut iters = 0;
        for it in 0..settings.fixed_point_max_iter {
            iters = it + 1;
            // S fixed → R.
            let b = ms_s_cur.take().unwrap_or_else(|| sym_mul_cols(ops.ms, &s));
            let mut r_new = Mat::<f64>::zeros(n, b.ncols());
            for j in 0..b.ncols() {
                let bj = col(&b, j);
                for (p, colp) in ops.f.cols.iter().enumerate() {
                    let v = bj[p];
                    if v != 0.0 {
                        for &(row, x) in colp {
                            r_new[(row as usize, j)] += x * v;
                        }
                    }
                }
            }
            ops.k_factor.solve_many(&mut r_new);
            if have > 0 {
                let c = ym.transpose() * &b;
                r_new -= &xm * &c;
            }
            let kr_raw = sym_mul_cols(ops.k, &r_new);
            // K-orthonormalize through the eigen-decomposition of RᵀKR, dropping
            // directions the residual map no longer has.
            let g = r_new.transpose() * &kr_raw;
            let Some((gv, gw)) = eigen_desc(&g) else {
                break;
            };
            let gmax = gv.first().copied().unwrap_or(0.0);
            let keep: Vec<usize> = (0..gv.len())
                .filter(|&i| gmax > 0.0 && gv[i] > 1e-12 * gmax)
                .collect();
            if keep.is_empty() {
                break; // The load is fully represented: nothing left to add.
            }
            let tr = Mat::from_fn(gv.len(), keep.len(), |i, j| {
                gw[(i, keep[j])] / gv[keep[j]].sqrt()
            });
            let r_on = &r_new * &tr;
            let kr_on = &kr_raw * &tr;
            // R fixed → S.
            let mut s_new = Mat::from_fn(m, keep.len(), |p, j| {
                ops.f.cols[p]
                    .iter()
                    .map(|&(row, x)| x * r_on[(row as usize, j)])
                    .sum::<f64>()
            });
            if have > 0 {
                let c = xm.transpose() * &kr_on;
                s_new -= &ym * &c;
            }
            // Rayleigh–Ritz: order the columns by their share of the residual map.
            let ms_s = sym_mul_cols(ops.ms, &s_new);
            let h = s_new.transpose() * &ms_s;
            let Some((hv, hw)) = eigen_desc(&h) else {
                break;
            };
            let r_new = &r_on * &hw;
            let kr_new = &kr_on * &hw;
            let s_new = &s_new * &hw;
            // Change of the kept part Σ_{i<nb} R_i S_iᵀ in the natural norm.
            let k = nb.min(hv.len());
            let new2: f64 = hv[..k].iter().sum();
            let converged = if r.ncols() >= k && k > 0 {
                let old2: f64 = lambda[..k].iter().sum();
                let rk = r.subcols(0, k).transpose() * kr_new.subcols(0, k);
                let sm = s_new.subcols(0, k).transpose() * b.subcols(0, k);
                let mut cross = 0.0;
                for a in 0..k {
                    for c in 0..k {
                        cross += rk[(a, c)] * sm[(c, a)];
                    }
                }
                let change2 = (new2 + old2 - 2.0 * cross).max(0.0);
                change2 <= settings.fixed_point_tol.powi(2) * new2
            } else {
                false
            };
            r = r_new;
            kr = kr_new;
            s = s_new;
            ms_s_cur = Some(&ms_s * &hw);
            lambda = hv;
            if converged {
                break;
            }
        }
        let k = nb.min(r.ncols());
        if k == 0 {
            break;
        }
        for j in 0..k {
            let x = col(&r, j).to_vec();
            t.ftx.push(ops.f.mul_t(&x));
            t.x.push(x);
            t.kx.push(col(&kr, j).to_vec());
            t.y.push(col(&s, j).to_vec());
        }
        t.extend_gram();
        if settings.update {
            update(ops, &mut t);
        }
        // Per-term residual: the term's norm relative to the sum up to it,
        // ‖U_i‖² = Σ_{k,l≤i} (X_kᵀKX_l)(y_kᵀ Ms y_l) by growing leading blocks.
        let seconds = t0.elapsed().as_secs_f64() / k as f64;
        let total = have + k;
        let msy: Vec<Vec<f64>> = t.y[..total]
            .par_iter()
            .map(|y| {
                let mut v = vec![0.0; m];
                ops.ms.mul(y, &mut v);
                v
            })
            .collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let mut norm2_lead = 0.0;
        let mut last = f64::INFINITY;
        for i in 0..total {
            norm2_lead += t.gram[i][i] * dot(&t.y[i], &msy[i]);
            for l in 0..i {
                norm2_lead += 2.0 * t.gram[i][l] * dot(&t.y[i], &msy[l]);
            }
            if i >= have {
                let term2 = dot(&t.y[i], &msy[i]);
                last = (term2 / norm2_lead.max(f64::MIN_POSITIVE)).sqrt();
                t.residual_per_mode.push(last);
                t.fixed_point_iterations.push(iters);
                t.seconds_per_mode.push(seconds);
            }
        }
        progress(&t);
        if last < settings.tol {
            break;
        }
    }
    t
}
