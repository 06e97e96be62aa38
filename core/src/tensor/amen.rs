//! Linear systems `M x = b` in tensor-train form, for one implicit time step of the CME.
//!
//! **Operator.** `M = Σ_t c_t ⊗_k F_{t,k}` with each `F_{t,k}` sparse and the identity
//! outside a span of axes `[f_t, l_t]`. As a matrix product operator (MPO) its bond `k`
//! carries one channel "not started" (identity so far), one "done" (identity from here),
//! and one per term whose span crosses the bond: rank `2 + #crossing`, which for the
//! CME's nearest-neighbour reactions stays at 4–8 however many species there are.
//!
//! **Solver** (one-site alternating least squares with residual enrichment, after Dolgov
//! & Savostyanov 2014, "AMEn"). With every core but `k` orthonormal, `x = X_{≠k} x_k` and
//! the Galerkin projection `X_{≠k}ᵀ M X_{≠k} x_k = X_{≠k}ᵀ b` is a small system of size
//! `r_{k−1} n_k r_k`, solved directly by banded elimination where its band is small (the
//! 1-D factors are banded, so with the mode index outermost the system is
//! block-banded) and by GMRES with a Jacobi preconditioner otherwise. A forward sweep adds
//! to core `k` the `ρ` leading directions of the residual's left part that the core
//! cannot represent (the span of `X_{<k}ᵀ b` and `X_{<k}ᵀ M x` minus the core's own
//! span), so ranks grow where the residual needs them; the backward sweep truncates each
//! core by SVD to the tolerance. Sweeps stop when every local system's residual at the
//! start of its solve is below `tol` relative to its right-hand side.

use faer::{Mat, MatMut, MatRef};

use super::Sparse1d;
use super::dense::{thin_qr, thin_svd};
use super::tt::{Core, Tt, gemm, left_qr, mul, times_left};

/// One core of the operator: `r0 × r1` channels, each non-zero block a sparse `n × n`.
#[derive(Debug, Clone)]
pub struct MpoCore {
    pub r0: usize,
    pub r1: usize,
    pub n: usize,
    pub blocks: Vec<(usize, usize, Sparse1d)>,
}

/// A matrix product operator.
#[derive(Debug, Clone)]
pub struct Mpo {
    pub cores: Vec<MpoCore>,
}

/// `coef · ⊗_k factors[k]`, `None` for the identity.
#[derive(Debug, Clone)]
pub struct LocalTerm {
    pub coef: f64,
    pub factors: Vec<Option<Sparse1d>>,
}

impl Mpo {
    /// The automaton construction described in the module docs.
    pub fn from_terms(sizes: &[usize], terms: &[LocalTerm]) -> Mpo {
        let d = sizes.len();
        const NS: usize = 0;
        const DONE: usize = 1;
        // (first, last) non-identity axis of each term (axis 0 for a pure identity).
        let spans: Vec<(usize, usize)> = terms
            .iter()
            .map(|t| {
                let used: Vec<usize> = (0..d).filter(|&k| t.factors[k].is_some()).collect();
                (
                    used.first().copied().unwrap_or(0),
                    used.last().copied().unwrap_or(0),
                )
            })
            .collect();
        // Channel of term j on bond k (between axes k and k+1).
        let channel: Vec<Vec<Option<usize>>> = (0..d.saturating_sub(1))
            .map(|k| {
                let mut next = 2;
                spans
                    .iter()
                    .map(|&(f, l)| {
                        (f <= k && k < l).then(|| {
                            next += 1;
                            next - 1
                        })
                    })
                    .collect()
            })
            .collect();
        let bond_rank = |k: usize| 2 + channel[k].iter().filter(|c| c.is_some()).count();
        let mut cores = Vec::with_capacity(d);
        for k in 0..d {
            let n = sizes[k];
            let r0 = if k == 0 { 1 } else { bond_rank(k - 1) };
            let r1 = if k + 1 == d { 1 } else { bond_rank(k) };
            // Boundary bonds have a single channel: "not started" on the left, "done" on
            // the right.
            let left = |ch: usize| {
                if k == 0 {
                    (ch == NS).then_some(0)
                } else {
                    Some(ch)
                }
            };
            let right = |ch: usize| {
                if k + 1 == d {
                    (ch == DONE).then_some(0)
                } else {
                    Some(ch)
                }
            };
            let mut blocks = Vec::new();
            if let (Some(a), Some(b)) = (left(NS), right(NS)) {
                blocks.push((a, b, Sparse1d::identity(n)));
            }
            if let (Some(a), Some(b)) = (left(DONE), right(DONE)) {
                blocks.push((a, b, Sparse1d::identity(n)));
            }
            for (j, t) in terms.iter().enumerate() {
                let (f, l) = spans[j];
                if k < f || k > l {
                    continue;
                }
                let from = if k == f {
                    left(NS)
                } else {
                    left(channel[k - 1][j].expect(
                        "crossing terms are computed for every core before the sweep reads them",
                    ))
                };
                let to = if k == l {
                    right(DONE)
                } else {
                    right(channel[k][j].expect(
                        "crossing terms are computed for every core before the sweep reads them",
                    ))
                };
                let mut m = t.factors[k]
                    .clone()
                    .unwrap_or_else(|| Sparse1d::identity(n));
                if k == f {
                    m = m.scaled(t.coef);
                }
                if let (Some(a), Some(b)) = (from, to) {
                    blocks.push((a, b, m));
                }
            }
            cores.push(MpoCore { r0, r1, n, blocks });
        }
        Mpo { cores }
    }

    /// `M x` exactly (ranks multiply).
    pub fn apply(&self, x: &Tt) -> Tt {
        let cores = self
            .cores
            .iter()
            .zip(&x.cores)
            .map(|(w, c)| {
                let (r0, r1, n) = (w.r0 * c.r0, w.r1 * c.r1, c.n);
                let mut out = Core::zeros(r0, n, r1);
                for (al, be, s) in &w.blocks {
                    for a in 0..c.r0 {
                        for i in 0..n {
                            for (ip, v) in s.row(i) {
                                for b in 0..c.r1 {
                                    out.v[((al * c.r0 + a) * n + i) * r1 + be * c.r1 + b] +=
                                        v * c.at(a, ip, b);
                                }
                            }
                        }
                    }
                }
                out
            })
            .collect();
        Tt { cores }
    }
}

/// `‖b − M x‖ / ‖b‖`, exactly.
pub fn residual(op: &Mpo, b: &Tt, x: &Tt) -> f64 {
    let mx = op.apply(x);
    let bb = b.dot(b);
    let r2 = bb - 2.0 * b.dot(&mx) + mx.dot(&mx);
    (r2.max(0.0) / bb.max(f64::MIN_POSITIVE)).sqrt()
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Stop when every local system's starting residual is below this (relative).
    pub tol: f64,
    /// Relative SVD truncation of each core in the backward sweep.
    pub eps: f64,
    pub max_rank: usize,
    /// Enrichment directions per core and forward sweep.
    pub enrich: usize,
    pub max_sweeps: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tol: 1e-7,
            eps: 1e-8,
            max_rank: 200,
            enrich: 4,
            max_sweeps: 12,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Report {
    pub sweeps: usize,
    /// The largest starting local residual of the last sweep.
    pub local_residual: f64,
    pub max_rank: usize,
    /// GMRES iterations over all local solves.
    pub gmres_iterations: usize,
}

/// `out[a, i, :] += Σ_{i'} S[i, i'] · input[a, i', :]` on `(r0, n, c)` row-major buffers.
fn apply_mode(s: &Sparse1d, r0: usize, n: usize, c: usize, input: &[f64], out: &mut [f64]) {
    for a in 0..r0 {
        for i in 0..n {
            let dst = (a * n + i) * c;
            for (ip, v) in s.row(i) {
                let src = (a * n + ip) * c;
                for q in 0..c {
                    out[dst + q] += v * input[src + q];
                }
            }
        }
    }
}

fn rm(v: &[f64], rows: usize, cols: usize) -> MatRef<'_, f64> {
    MatRef::from_row_major_slice(v, rows, cols)
}

fn rm_mut(v: &mut [f64], rows: usize, cols: usize) -> MatMut<'_, f64> {
    MatMut::from_row_major_slice_mut(v, rows, cols)
}

fn gemm_rm(
    dst: &mut [f64],
    rows: usize,
    cols: usize,
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    add: bool,
) {
    faer::linalg::matmul::matmul(
        rm_mut(dst, rows, cols),
        if add {
            faer::Accum::Add
        } else {
            faer::Accum::Replace
        },
        a,
        b,
        1.0,
        faer::Par::Seq,
    );
    crate::cpu::clear_upper_halves();
}

/// The local operator of core `k`: channels' interfaces on both sides.
struct Local<'a> {
    w: &'a MpoCore,
    left: &'a [Mat<f64>],
    right: &'a [Mat<f64>],
    r0: usize,
    n: usize,
    r1: usize,
}

impl Local<'_> {
    fn len(&self) -> usize {
        self.r0 * self.n * self.r1
    }

    /// `out = M_loc y`.
    fn apply(&self, y: &[f64], out: &mut [f64]) {
        let (r0, n, r1) = (self.r0, self.n, self.r1);
        let len = self.len();
        let mut z: Vec<Option<Vec<f64>>> = vec![None; self.w.r1];
        for (_, be, _) in &self.w.blocks {
            if z[*be].is_none() {
                let mut buf = vec![0.0; len];
                gemm_rm(
                    &mut buf,
                    r0 * n,
                    r1,
                    rm(y, r0 * n, r1),
                    self.right[*be].transpose(),
                    false,
                );
                z[*be] = Some(buf);
            }
        }
        out.fill(0.0);
        let mut acc = vec![0.0; len];
        for al in 0..self.w.r0 {
            let mut any = false;
            acc.fill(0.0);
            for (a, be, s) in &self.w.blocks {
                if *a == al {
                    any = true;
                    apply_mode(
                        s,
                        r0,
                        n,
                        r1,
                        z[*be]
                            .as_ref()
                            .expect("computed earlier in this sweep, in the same order"),
                        &mut acc,
                    );
                }
            }
            if any {
                gemm_rm(
                    out,
                    r0,
                    n * r1,
                    self.left[al].as_ref(),
                    rm(&acc, r0, n * r1),
                    true,
                );
            }
        }
    }

    fn diagonal(&self) -> Vec<f64> {
        let (r0, n, r1) = (self.r0, self.n, self.r1);
        let mut d = vec![0.0; self.len()];
        for (al, be, s) in &self.w.blocks {
            let sd: Vec<f64> = (0..n)
                .map(|i| s.row(i).find(|&(j, _)| j == i).map_or(0.0, |(_, v)| v))
                .collect();
            let (l, r) = (&self.left[*al], &self.right[*be]);
            for a in 0..r0 {
                for (i, &si) in sd.iter().enumerate() {
                    if si == 0.0 {
                        continue;
                    }
                    for b in 0..r1 {
                        d[(a * n + i) * r1 + b] += l[(a, a)] * si * r[(b, b)];
                    }
                }
            }
        }
        let big = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for x in &mut d {
            if x.abs() <= 1e-12 * big {
                *x = if big > 0.0 { big } else { 1.0 };
            }
        }
        d
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Restarted GMRES with a right Jacobi preconditioner: improves `x` until
/// `‖f − A x‖ ≤ tol ‖f‖` or `max_iter` iterations. Returns the iterations used.
fn gmres(
    apply: &dyn Fn(&[f64], &mut [f64]),
    diag: &[f64],
    f: &[f64],
    x: &mut [f64],
    tol: f64,
    restart: usize,
    max_iter: usize,
) -> usize {
    let n = f.len();
    let fnorm = norm(f);
    if fnorm == 0.0 {
        x.fill(0.0);
        return 0;
    }
    let mut iters = 0;
    let mut r = vec![0.0; n];
    let mut tmp = vec![0.0; n];
    while iters < max_iter {
        apply(x, &mut tmp);
        for i in 0..n {
            r[i] = f[i] - tmp[i];
        }
        let beta = norm(&r);
        if beta <= tol * fnorm {
            break;
        }
        let m = restart.min(max_iter - iters).min(n);
        let mut v: Vec<Vec<f64>> = Vec::with_capacity(m + 1);
        v.push(r.iter().map(|x| x / beta).collect());
        let mut h = vec![vec![0.0; m]; m + 1];
        let (mut cs, mut sn) = (vec![0.0; m], vec![0.0; m]);
        let mut g = vec![0.0; m + 1];
        g[0] = beta;
        let mut used = 0;
        for j in 0..m {
            let pre: Vec<f64> = v[j].iter().zip(diag).map(|(a, d)| a / d).collect();
            let mut w = vec![0.0; n];
            apply(&pre, &mut w);
            for (i, vi) in v.iter().enumerate() {
                let hij: f64 = w.iter().zip(vi).map(|(a, b)| a * b).sum();
                h[i][j] = hij;
                for (wq, vq) in w.iter_mut().zip(vi) {
                    *wq -= hij * vq;
                }
            }
            let hn = norm(&w);
            h[j + 1][j] = hn;
            for i in 0..j {
                let t = cs[i] * h[i][j] + sn[i] * h[i + 1][j];
                h[i + 1][j] = -sn[i] * h[i][j] + cs[i] * h[i + 1][j];
                h[i][j] = t;
            }
            let rho = (h[j][j] * h[j][j] + h[j + 1][j] * h[j + 1][j]).sqrt();
            if rho == 0.0 {
                break;
            }
            cs[j] = h[j][j] / rho;
            sn[j] = h[j + 1][j] / rho;
            h[j][j] = rho;
            h[j + 1][j] = 0.0;
            g[j + 1] = -sn[j] * g[j];
            g[j] *= cs[j];
            used = j + 1;
            iters += 1;
            if g[j + 1].abs() <= tol * fnorm || hn == 0.0 {
                break;
            }
            v.push(w.iter().map(|x| x / hn).collect());
        }
        // Back substitution, then x += D⁻¹ V y.
        let mut y = vec![0.0; used];
        for i in (0..used).rev() {
            let mut s = g[i];
            for k in i + 1..used {
                s -= h[i][k] * y[k];
            }
            y[i] = s / h[i][i];
        }
        for (k, yk) in y.iter().enumerate() {
            for i in 0..n {
                x[i] += yk * v[k][i] / diag[i];
            }
        }
        if used == 0 || g[used].abs() <= tol * fnorm {
            break;
        }
    }
    iters
}

/// Interfaces of one sweep position.
struct Frames {
    /// `left[k][α]`: `r_{k−1} × r_{k−1}` (test × trial) for core k's left bond.
    left: Vec<Vec<Mat<f64>>>,
    right: Vec<Vec<Mat<f64>>>,
    /// `b_left[k]`: `r_{k−1} × s_{k−1}`; `b_right[k]`: `r_k × s_k`.
    b_left: Vec<Mat<f64>>,
    b_right: Vec<Mat<f64>>,
}

fn one() -> Mat<f64> {
    Mat::from_fn(1, 1, |_, _| 1.0)
}

/// Left interface after a left-orthonormal core `x` (next core's left frame).
fn next_left(w: &MpoCore, left: &[Mat<f64>], x: &Core) -> Vec<Mat<f64>> {
    let (r0, n, r1) = (x.r0, x.n, x.r1);
    let len = r0 * n * r1;
    let mut t: Vec<Option<Vec<f64>>> = vec![None; w.r0];
    for (al, _, _) in &w.blocks {
        if t[*al].is_none() {
            let mut buf = vec![0.0; len];
            gemm_rm(&mut buf, r0, n * r1, left[*al].as_ref(), x.right(), false);
            t[*al] = Some(buf);
        }
    }
    let mut out = Vec::with_capacity(w.r1);
    for be in 0..w.r1 {
        let mut u = vec![0.0; len];
        for (al, b, s) in &w.blocks {
            if *b == be {
                apply_mode(
                    s,
                    r0,
                    n,
                    r1,
                    t[*al]
                        .as_ref()
                        .expect("computed earlier in this sweep, in the same order"),
                    &mut u,
                );
            }
        }
        out.push(mul(x.left().transpose(), rm(&u, r0 * n, r1)));
    }
    out
}

/// Right interface before a right-orthonormal core `x` (previous core's right frame).
fn prev_right(w: &MpoCore, right: &[Mat<f64>], x: &Core) -> Vec<Mat<f64>> {
    let (r0, n, r1) = (x.r0, x.n, x.r1);
    let len = r0 * n * r1;
    let mut g: Vec<Option<Vec<f64>>> = vec![None; w.r1];
    for (_, be, _) in &w.blocks {
        if g[*be].is_none() {
            let mut buf = vec![0.0; len];
            gemm_rm(
                &mut buf,
                r0 * n,
                r1,
                x.left(),
                right[*be].transpose(),
                false,
            );
            g[*be] = Some(buf);
        }
    }
    let mut out = Vec::with_capacity(w.r0);
    for al in 0..w.r0 {
        let mut h = vec![0.0; len];
        for (a, be, s) in &w.blocks {
            if *a == al {
                apply_mode(
                    s,
                    r0,
                    n,
                    r1,
                    g[*be]
                        .as_ref()
                        .expect("computed earlier in this sweep, in the same order"),
                    &mut h,
                );
            }
        }
        out.push(mul(x.right(), rm(&h, r0, n * r1).transpose()));
    }
    out
}

fn next_b_left(b_left: &Mat<f64>, b: &Core, x: &Core) -> Mat<f64> {
    let t = row_major_mul(b_left.as_ref(), b.right());
    mul(x.left().transpose(), rm(&t, x.r0 * x.n, b.r1))
}

fn prev_b_right(b_right: &Mat<f64>, b: &Core, x: &Core) -> Mat<f64> {
    let g = row_major_mul(b.left(), b_right.transpose());
    mul(x.right(), rm(&g, b.r0, b.n * x.r1).transpose())
}

fn row_major_mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Vec<f64> {
    let mut out = vec![0.0; a.nrows() * b.ncols()];
    gemm_rm(&mut out, a.nrows(), b.ncols(), a, b, false);
    out
}

/// Solves `op · x = b`, starting from (and overwriting) `x`.
pub fn solve(op: &Mpo, b: &Tt, x: &mut Tt, s: &Settings) -> Report {
    let d = x.cores.len();
    let mut b = b.clone();
    b.orthogonalize_right();
    x.orthogonalize_right();
    let mut fr = Frames {
        left: vec![vec![one()]; d],
        right: vec![vec![one()]; d],
        b_left: vec![one(); d],
        b_right: vec![one(); d],
    };
    for k in (1..d).rev() {
        fr.right[k - 1] = prev_right(&op.cores[k], &fr.right[k], &x.cores[k]);
        fr.b_right[k - 1] = prev_b_right(&fr.b_right[k], &b.cores[k], &x.cores[k]);
    }
    let mut report = Report::default();
    let local_tol = 0.1 * s.tol;
    for sweep in 0..s.max_sweeps {
        let mut worst: f64 = 0.0;
        // Forward: solve, enrich, move the orthogonality centre right.
        for k in 0..d.saturating_sub(1) {
            let (y, res, it) = solve_local(op, &b, x, &fr, k, local_tol);
            worst = worst.max(res);
            report.gmres_iterations += it;
            let (core, next) = enrich(op, &b, x, &fr, k, &y, s);
            x.cores[k] = core;
            x.cores[k + 1] = next;
            fr.left[k + 1] = next_left(&op.cores[k], &fr.left[k], &x.cores[k]);
            fr.b_left[k + 1] = next_b_left(&fr.b_left[k], &b.cores[k], &x.cores[k]);
        }
        // Backward: solve, truncate, move the centre left.
        for k in (0..d).rev() {
            let (y, res, it) = solve_local(op, &b, x, &fr, k, local_tol);
            worst = worst.max(res);
            report.gmres_iterations += it;
            let c = &x.cores[k];
            let y = Core {
                r0: c.r0,
                n: c.n,
                r1: c.r1,
                v: y,
            };
            if k == 0 {
                x.cores[0] = y;
                break;
            }
            let (q, us) = truncate_right(&y, s.eps, s.max_rank);
            x.cores[k] = q;
            let prev = &x.cores[k - 1];
            x.cores[k - 1] = super::tt::times_right(prev, us.as_ref());
            fr.right[k - 1] = prev_right(&op.cores[k], &fr.right[k], &x.cores[k]);
            fr.b_right[k - 1] = prev_b_right(&fr.b_right[k], &b.cores[k], &x.cores[k]);
        }
        report.sweeps = sweep + 1;
        report.local_residual = worst;
        if worst < s.tol {
            break;
        }
    }
    report.max_rank = x.max_rank();
    report
}

/// Local solve at core k: returns (new core values, starting residual, iterations).
fn solve_local(
    op: &Mpo,
    b: &Tt,
    x: &Tt,
    fr: &Frames,
    k: usize,
    tol: f64,
) -> (Vec<f64>, f64, usize) {
    let c = &x.cores[k];
    let local = Local {
        w: &op.cores[k],
        left: &fr.left[k],
        right: &fr.right[k],
        r0: c.r0,
        n: c.n,
        r1: c.r1,
    };
    let bc = &b.cores[k];
    let g = row_major_mul(bc.left(), fr.b_right[k].transpose());
    let f = row_major_mul(fr.b_left[k].as_ref(), rm(&g, bc.r0, bc.n * c.r1));
    let mut y = c.v.clone();
    let mut my = vec![0.0; y.len()];
    local.apply(&y, &mut my);
    let fnorm = norm(&f).max(f64::MIN_POSITIVE);
    let res = f
        .iter()
        .zip(&my)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
        / fnorm;
    if res <= tol {
        return (y, res, 0);
    }
    if local.r0 * local.r1 == 1
        && let Some(direct) = local.solve_banded(&f)
    {
        return (direct, res, 1);
    }
    let diag = local.diagonal();
    let it = gmres(&|v, o| local.apply(v, o), &diag, &f, &mut y, tol, 40, 600);
    (y, res, it)
}

/// The largest banded factorization [`Local::solve_banded`] takes on, in
/// multiply–adds (`N · k_l · (k_l + k_u)`) and in stored entries (`N · (2k_l + k_u + 1)`):
/// about 0.1 s and 160 MB. Larger local systems go to GMRES.
const BANDED_MAX_FLOPS: f64 = 2e8;
const BANDED_MAX_ENTRIES: usize = 20_000_000;

impl Local<'_> {
    /// The local system solved directly, where it is small enough: with the unknowns
    /// ordered mode index first, `(i, a, b) ↦ i·r0·r1 + a·r1 + b`, the matrix
    /// `Σ L_α ⊗ S ⊗ R_β` is block-banded (blocks of `r0·r1`, as many off-diagonal
    /// blocks as the 1-D factors have diagonals), and Gaussian elimination with partial
    /// pivoting inside the band solves it exactly. This is what one implicit step of a
    /// one-species network (`r0 = r1 = 1`, a tridiagonal system) needs: GMRES with a
    /// Jacobi preconditioner took hundreds of iterations on a birth–death box of
    /// 16 384 states, whose stiffness grows with the box. `None` when the band is too
    /// large or a pivot vanishes (the caller falls back to GMRES). `solve_local` calls
    /// it for one-core trains only: with rank × rank blocks it was slower than GMRES
    /// (a two-species DSMTS case, 72 s by GMRES, 476 s by the band).
    fn solve_banded(&self, f: &[f64]) -> Option<Vec<f64>> {
        let (r0, n, r1) = (self.r0, self.n, self.r1);
        let m = r0 * r1;
        let (mut below, mut above) = (0usize, 0usize);
        for (_, _, s) in &self.w.blocks {
            for i in 0..n {
                for (j, _) in s.row(i) {
                    below = below.max(i.saturating_sub(j));
                    above = above.max(j.saturating_sub(i));
                }
            }
        }
        let size = n * m;
        let kl = (below + 1) * m - 1;
        let ku = (above + 1) * m - 1;
        let width = 2 * kl + ku + 1;
        let flops = size as f64 * kl as f64 * (kl + ku) as f64;
        if flops > BANDED_MAX_FLOPS || size.checked_mul(width)? > BANDED_MAX_ENTRIES {
            return None;
        }
        // Row `p`'s column `c` lives at `band[p · width + c + kl − p]` (room for the
        // fill that row exchanges bring, up to `kl + ku` right of the diagonal).
        let mut band = vec![0.0; size * width];
        let at = |p: usize, c: usize| p * width + c + kl - p;
        for (al, be, s) in &self.w.blocks {
            let (l, r) = (&self.left[*al], &self.right[*be]);
            if m == 1 {
                // One-by-one frames (a one-core train): the block is its 1-D factor
                // times one number. Indexing the frames entry by entry for each of the
                // factor's entries was most of a one-species step's time.
                let lr = l[(0, 0)] * r[(0, 0)];
                if lr != 0.0 {
                    for i in 0..n {
                        for (j, v) in s.row(i) {
                            band[at(i, j)] += lr * v;
                        }
                    }
                }
                continue;
            }
            for i in 0..n {
                for (j, v) in s.row(i) {
                    for a in 0..r0 {
                        for ap in 0..r0 {
                            let la = v * l[(a, ap)];
                            if la == 0.0 {
                                continue;
                            }
                            for b in 0..r1 {
                                let p = i * m + a * r1 + b;
                                for bp in 0..r1 {
                                    band[at(p, j * m + ap * r1 + bp)] += la * r[(b, bp)];
                                }
                            }
                        }
                    }
                }
            }
        }
        // The right-hand side in the banded order.
        let mut x = vec![0.0; size];
        for a in 0..r0 {
            for i in 0..n {
                for b in 0..r1 {
                    x[i * m + a * r1 + b] = f[(a * n + i) * r1 + b];
                }
            }
        }
        let scale = band.iter().fold(0.0f64, |mx, v| mx.max(v.abs()));
        for j in 0..size {
            let last_row = (j + kl).min(size - 1);
            let last_col = (j + kl + ku).min(size - 1);
            let pivot = (j..=last_row)
                .max_by(|&p, &q| band[at(p, j)].abs().total_cmp(&band[at(q, j)].abs()))?;
            if band[at(pivot, j)].abs() <= 1e-14 * scale {
                return None;
            }
            if pivot != j {
                for c in j..=last_col {
                    band.swap(at(j, c), at(pivot, c));
                }
                x.swap(j, pivot);
            }
            let d = band[at(j, j)];
            for p in j + 1..=last_row {
                let factor = band[at(p, j)] / d;
                if factor == 0.0 {
                    continue;
                }
                band[at(p, j)] = 0.0;
                for c in j + 1..=last_col {
                    band[at(p, c)] -= factor * band[at(j, c)];
                }
                x[p] -= factor * x[j];
            }
        }
        for j in (0..size).rev() {
            let last_col = (j + kl + ku).min(size - 1);
            let mut v = x[j];
            for c in j + 1..=last_col {
                v -= band[at(j, c)] * x[c];
            }
            x[j] = v / band[at(j, j)];
        }
        if x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut y = vec![0.0; f.len()];
        for a in 0..r0 {
            for i in 0..n {
                for b in 0..r1 {
                    y[(a * n + i) * r1 + b] = x[i * m + a * r1 + b];
                }
            }
        }
        Some(y)
    }
}

/// Adds up to `s.enrich` residual directions to the solved core `y` and makes it
/// left-orthonormal; returns (core k, core k+1 carrying y's weight).
fn enrich(
    op: &Mpo,
    b: &Tt,
    x: &Tt,
    fr: &Frames,
    k: usize,
    y: &[f64],
    s: &Settings,
) -> (Core, Core) {
    let c = &x.cores[k];
    let (r0, n, r1) = (c.r0, c.n, c.r1);
    let rows = r0 * n;
    let ycore = Core {
        r0,
        n,
        r1,
        v: y.to_vec(),
    };
    let room = s.max_rank.saturating_sub(r1).min(s.enrich);
    let mut z_cols: Vec<Vec<f64>> = Vec::new(); // each a column of length rows
    if room > 0 {
        let bc = &b.cores[k];
        // X_{<k}ᵀ b, left part: (r0 n) × s1.
        let ub = row_major_mul(fr.b_left[k].as_ref(), bc.right());
        for q in 0..bc.r1 {
            z_cols.push((0..rows).map(|row| ub[row * bc.r1 + q]).collect());
        }
        // X_{<k}ᵀ M x, left part, per outgoing channel: (r0 n) × r1 each.
        let w = &op.cores[k];
        let mut t: Vec<Option<Vec<f64>>> = vec![None; w.r0];
        for (al, _, _) in &w.blocks {
            if t[*al].is_none() {
                t[*al] = Some(row_major_mul(fr.left[k][*al].as_ref(), ycore.right()));
            }
        }
        for be in 0..w.r1 {
            let mut u = vec![0.0; rows * r1];
            let mut any = false;
            for (al, bb, sp) in &w.blocks {
                if *bb == be {
                    any = true;
                    apply_mode(
                        sp,
                        r0,
                        n,
                        r1,
                        t[*al]
                            .as_ref()
                            .expect("computed earlier in this sweep, in the same order"),
                        &mut u,
                    );
                }
            }
            if any {
                for q in 0..r1 {
                    z_cols.push((0..rows).map(|row| u[row * r1 + q]).collect());
                }
            }
        }
    }
    let mut stacked: Mat<f64>;
    if !z_cols.is_empty() {
        // Remove the core's own span, keep the leading `room` directions of the rest.
        let (q, _) = left_qr(&ycore);
        let qm = q.left();
        let z = Mat::<f64>::from_fn(rows, z_cols.len(), |i, j| z_cols[j][i]);
        let proj = mul(qm.transpose(), z.as_ref());
        let mut rest = z.clone();
        gemm(&mut rest, qm, proj.as_ref(), -1.0, true);
        let extra = thin_svd(rest.as_ref()).map(|svd| {
            let top = svd.s.first().copied().unwrap_or(0.0);
            let keep = (0..svd.s.len().min(room))
                .take_while(|&j| svd.s[j] > 1e-12 * top && top > 0.0)
                .count();
            svd.u.subcols(0, keep).to_owned()
        });
        stacked = Mat::from_fn(rows, r1, |i, j| ycore.left()[(i, j)]);
        if let Some(e) = extra
            && e.ncols() > 0
            && rows > r1
        {
            let add = e.ncols().min(rows - r1);
            stacked = Mat::from_fn(rows, r1 + add, |i, j| {
                if j < r1 {
                    ycore.left()[(i, j)]
                } else {
                    e[(i, j - r1)]
                }
            });
        }
    } else {
        stacked = Mat::from_fn(rows, r1, |i, j| ycore.left()[(i, j)]);
    }
    // [Y | Z] = Q R; the next core becomes R[:, :r1] · X_{k+1} (the directions added
    // carry zero weight until the next solve gives them some).
    let (q, r) = thin_qr(stacked.as_ref());
    let new_rank = q.ncols();
    let core = Core::from_mat(r0, n, new_rank, q.as_ref());
    let r_y = r.subcols(0, r1);
    let next = times_left(r_y, &x.cores[k + 1]);
    (core, next)
}

/// `y = (U S) · Vᵀ` over the right unfolding, truncated: returns (Vᵀ as a
/// right-orthonormal core, U·S to multiply into the previous core).
fn truncate_right(y: &Core, eps: f64, max_rank: usize) -> (Core, Mat<f64>) {
    let m = y.right();
    let Some(svd) = thin_svd(m) else {
        // No SVD: keep the core as it is (untruncated, and not orthonormal).
        return (y.clone(), Mat::identity(y.r0, y.r0));
    };
    let s = &svd.s;
    let total: f64 = s.iter().map(|x| x * x).sum();
    let mut keep = s.len();
    let mut tail = 0.0;
    while keep > 1 {
        let x = s[keep - 1];
        if tail + x * x > eps * eps * total {
            break;
        }
        tail += x * x;
        keep -= 1;
    }
    keep = keep.min(max_rank).max(1);
    let vt = svd.v.subcols(0, keep).transpose().to_owned();
    let us = Mat::from_fn(y.r0, keep, |i, j| svd.u[(i, j)] * s[j]);
    (Core::from_mat(keep, y.n, y.r1, vt.as_ref()), us)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1-D birth–death generator on 0..m (rates λ, μz), reflecting at the top.
    fn birth_death(m: usize, birth: f64, death: f64) -> Sparse1d {
        let mut e = Vec::new();
        for z in 0..m {
            if z + 1 < m {
                e.push((z + 1, z, birth));
                e.push((z, z, -birth));
            }
            if z > 0 {
                e.push((z - 1, z, death * z as f64));
                e.push((z, z, -death * z as f64));
            }
        }
        Sparse1d::from_triplets(m, m, e)
    }

    #[test]
    fn the_banded_local_solve_inverts_the_local_operator() {
        // Random frames (r0 = 2, r1 = 3) around a tridiagonal factor and a diagonal
        // one on two channels: the direct solve must satisfy M y = f, and a band that
        // is too wide must be handed back.
        let mut rng = crate::rng::Rng::seed(11);
        let n = 9;
        let frame = |rng: &mut crate::rng::Rng, r: usize, shift: f64| {
            Mat::from_fn(r, r, |i, j| {
                rng.uniform() - 0.5 + if i == j { shift } else { 0.0 }
            })
        };
        let left = vec![frame(&mut rng, 2, 2.0), frame(&mut rng, 2, 0.0)];
        let right = vec![frame(&mut rng, 3, 2.0), frame(&mut rng, 3, 0.0)];
        let core = MpoCore {
            r0: 2,
            r1: 2,
            n,
            blocks: vec![
                (0, 0, Sparse1d::identity(n)),
                (1, 1, birth_death(n, 1.0, 0.4)),
                (
                    0,
                    1,
                    Sparse1d::diagonal(&(0..n).map(|z| 0.1 * z as f64).collect::<Vec<_>>()),
                ),
            ],
        };
        let local = Local {
            w: &core,
            left: &left,
            right: &right,
            r0: 2,
            n,
            r1: 3,
        };
        // Solves `M y = f` for a random `f` and returns max |M y − f|.
        let residual = |local: &Local, rng: &mut crate::rng::Rng| {
            let f: Vec<f64> = (0..local.len()).map(|_| rng.uniform() - 0.5).collect();
            let y = local
                .solve_banded(&f)
                .expect("a small band is solved directly");
            let mut my = vec![0.0; y.len()];
            local.apply(&y, &mut my);
            my.iter()
                .zip(&f)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        let err = residual(&local, &mut rng);
        assert!(err < 1e-10, "|M y − f| = {err:.2e}");
        // One-by-one frames (a one-core train, the band built without them): the same.
        let scalar = |rng: &mut crate::rng::Rng, shift: f64| frame(rng, 1, shift);
        let left = vec![scalar(&mut rng, 2.0), scalar(&mut rng, 0.0)];
        let right = vec![scalar(&mut rng, 2.0), scalar(&mut rng, 0.0)];
        let local = Local {
            w: &core,
            left: &left,
            right: &right,
            r0: 1,
            n,
            r1: 1,
        };
        let err = residual(&local, &mut rng);
        assert!(err < 1e-10, "one-core: |M y − f| = {err:.2e}");
        // A dense 1-D factor on a long axis is past the budget: GMRES's job.
        let wide = 3_000;
        let dense = Sparse1d::from_triplets(
            wide,
            wide,
            (0..wide).flat_map(|i| [(i, 0, 1.0), (i, wide - 1, 1.0), (i, i, 4.0)]),
        );
        let one = vec![Mat::from_fn(1, 1, |_, _| 1.0)];
        let core = MpoCore {
            r0: 1,
            r1: 1,
            n: wide,
            blocks: vec![(0, 0, dense)],
        };
        let local = Local {
            w: &core,
            left: &one,
            right: &one,
            r0: 1,
            n: wide,
            r1: 1,
        };
        assert!(local.solve_banded(&vec![1.0; wide]).is_none());
    }

    #[test]
    fn als_solves_a_kronecker_sum_system_to_the_tolerance() {
        // (I − h Σ_k A_k) x = b for independent birth–death axes: the exact solution
        // is known to be low-rank only approximately; check against the full solve.
        let sizes = [12, 10, 8, 6];
        let h = 0.7;
        let mut terms = vec![LocalTerm {
            coef: 1.0,
            factors: vec![None; 4],
        }];
        for (k, &m) in sizes.iter().enumerate() {
            let mut f = vec![None; 4];
            f[k] = Some(birth_death(m, 1.0 + k as f64, 0.3));
            terms.push(LocalTerm {
                coef: -h,
                factors: f,
            });
        }
        // A coupling term between axes 0 and 2 (crossing two bonds).
        let mut f = vec![None; 4];
        f[0] = Some(Sparse1d::diagonal(
            &(0..12).map(|z| 0.1 * z as f64).collect::<Vec<_>>(),
        ));
        f[2] = Some(birth_death(8, 0.5, 0.0));
        terms.push(LocalTerm {
            coef: -h,
            factors: f,
        });
        let op = Mpo::from_terms(&sizes, &terms);
        assert_eq!(op.cores[1].r0, 3);
        assert_eq!(op.cores[1].r1, 3);
        let b = Tt::rank_one(
            &sizes
                .iter()
                .map(|&m| (0..m).map(|z| if z == 2 { 1.0 } else { 0.1 }).collect())
                .collect::<Vec<Vec<f64>>>(),
        );
        let mut x = b.clone();
        let report = solve(
            &op,
            &b,
            &mut x,
            &Settings {
                tol: 1e-9,
                eps: 1e-11,
                ..Settings::default()
            },
        );
        let res = residual(&op, &b, &x);
        assert!(res < 1e-7, "residual {res}, {report:?}");
        assert!(report.max_rank > 1, "{report:?}");
        // The MPO applied to a rank-one tensor matches the terms applied one by one.
        let y = op.apply(&b).full();
        let mut direct = vec![0.0; y.len()];
        for t in &terms {
            let factors: Vec<Vec<f64>> = b
                .cores
                .iter()
                .zip(&t.factors)
                .map(|(c, f)| f.as_ref().map_or(c.v.clone(), |f| f.applied(&c.v)))
                .collect();
            for (o, v) in direct.iter_mut().zip(Tt::rank_one(&factors).full()) {
                *o += t.coef * v;
            }
        }
        let err: f64 = y.iter().zip(&direct).map(|(a, b)| (a - b).abs()).sum();
        assert!(err < 1e-12, "MPO vs terms: {err}");
    }
}
