//! Tensor trains: `X(i_1, …, i_d) = G_1[i_1] G_2[i_2] ⋯ G_d[i_d]`, each `G_k[i]` an
//! `r_{k−1} × r_k` matrix (`r_0 = r_d = 1`).
//!
//! A tensor train is a separated representation whose terms share factors: expanded, it
//! is `Σ_{a_1…a_{d−1}} Π_k G_k(a_{k−1}, i_k, a_k)`, a sum of products of one-variable
//! functions, like a PGD sum, but its ranks `r_k` are set by SVDs (`round`) instead of
//! greedy enrichment, which is what lets the CME solver keep the error of every time step
//! below a tolerance (Oseledets 2011, "Tensor-train decomposition").
//!
//! Storage: core `k` is row-major `[a][i][b]` (`(a·n + i)·r1 + b`); read as an
//! `(r0·n) × r1` matrix it is the core's *left* unfolding, as an `r0 × (n·r1)` matrix
//! its *right* unfolding.

use faer::{Accum, Mat, MatRef, Par};

use super::dense::{thin_qr, thin_svd};

/// One core, `r0 × n × r1`.
#[derive(Debug, Clone, PartialEq)]
pub struct Core {
    pub r0: usize,
    pub n: usize,
    pub r1: usize,
    pub v: Vec<f64>,
}

impl Core {
    pub fn zeros(r0: usize, n: usize, r1: usize) -> Self {
        Core {
            r0,
            n,
            r1,
            v: vec![0.0; r0 * n * r1],
        }
    }

    pub fn at(&self, a: usize, i: usize, b: usize) -> f64 {
        self.v[(a * self.n + i) * self.r1 + b]
    }

    /// The `(r0·n) × r1` unfolding.
    pub fn left(&self) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice(&self.v, self.r0 * self.n, self.r1)
    }

    /// The `r0 × (n·r1)` unfolding.
    pub fn right(&self) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice(&self.v, self.r0, self.n * self.r1)
    }

    /// `v` of a row-major `rows × cols` matrix.
    pub fn from_mat(r0: usize, n: usize, r1: usize, m: MatRef<'_, f64>) -> Self {
        debug_assert_eq!(m.nrows() * m.ncols(), r0 * n * r1);
        let cols = m.ncols();
        let mut v = vec![0.0; r0 * n * r1];
        for (idx, x) in v.iter_mut().enumerate() {
            *x = m[(idx / cols, idx % cols)];
        }
        Core { r0, n, r1, v }
    }

    /// `v[a][i][b] · w_i` summed over `i`: an `r0 × r1` matrix (row-major).
    pub fn contract(&self, w: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.r0 * self.r1];
        for a in 0..self.r0 {
            for (i, &wi) in w.iter().enumerate() {
                if wi == 0.0 {
                    continue;
                }
                let row = &self.v[(a * self.n + i) * self.r1..][..self.r1];
                for (o, x) in out[a * self.r1..][..self.r1].iter_mut().zip(row) {
                    *o += wi * x;
                }
            }
        }
        out
    }

    /// `v[a][i][b] · r_b` summed over `b`: an `r0 × n` matrix (row-major).
    pub fn contract_right(&self, r: &[f64]) -> Vec<f64> {
        self.v
            .chunks_exact(self.r1)
            .map(|row| row.iter().zip(r).map(|(x, y)| x * y).sum())
            .collect()
    }
}

/// `dst (m×n) = α·a·b (+ dst)`, sequential (the callers run in parallel over steps or
/// are small).
pub fn gemm(dst: &mut Mat<f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64, add: bool) {
    faer::linalg::matmul::matmul(
        dst.as_mut(),
        if add { Accum::Add } else { Accum::Replace },
        a,
        b,
        alpha,
        Par::Seq,
    );
    crate::cpu::clear_upper_halves();
}

pub fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    gemm(&mut out, a, b, 1.0, false);
    out
}

/// Row-major values of a matrix.
pub fn row_major(m: MatRef<'_, f64>) -> Vec<f64> {
    let mut v = Vec::with_capacity(m.nrows() * m.ncols());
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            v.push(m[(i, j)]);
        }
    }
    v
}

/// A tensor train.
#[derive(Debug, Clone, PartialEq)]
pub struct Tt {
    pub cores: Vec<Core>,
}

impl Tt {
    /// `⊗_k factors[k]`.
    pub fn rank_one(factors: &[Vec<f64>]) -> Self {
        Tt {
            cores: factors
                .iter()
                .map(|f| Core {
                    r0: 1,
                    n: f.len(),
                    r1: 1,
                    v: f.clone(),
                })
                .collect(),
        }
    }

    pub fn zeros(sizes: &[usize]) -> Self {
        Tt {
            cores: sizes.iter().map(|&n| Core::zeros(1, n, 1)).collect(),
        }
    }

    pub fn sizes(&self) -> Vec<usize> {
        self.cores.iter().map(|c| c.n).collect()
    }

    /// Bond ranks `r_1 … r_{d−1}`.
    pub fn ranks(&self) -> Vec<usize> {
        self.cores[..self.cores.len() - 1]
            .iter()
            .map(|c| c.r1)
            .collect()
    }

    pub fn max_rank(&self) -> usize {
        self.ranks().into_iter().max().unwrap_or(1)
    }

    /// Stored numbers.
    pub fn len(&self) -> usize {
        self.cores.iter().map(|c| c.v.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.cores.is_empty()
    }

    pub fn scale(&mut self, s: f64) {
        for x in &mut self.cores[0].v {
            *x *= s;
        }
    }

    /// `⟨self, other⟩`, left to right in `O(d n r³)`.
    pub fn dot(&self, other: &Tt) -> f64 {
        let mut l = Mat::<f64>::from_fn(1, 1, |_, _| 1.0);
        for (a, b) in self.cores.iter().zip(&other.cores) {
            l = dot_step(&l, a, b);
        }
        l[(0, 0)]
    }

    pub fn norm(&self) -> f64 {
        self.dot(self).max(0.0).sqrt()
    }

    /// `Σ_j c_j X_j` exactly (ranks add).
    pub fn sum(terms: &[(f64, &Tt)]) -> Tt {
        let d = terms[0].1.cores.len();
        let mut cores = Vec::with_capacity(d);
        for k in 0..d {
            let n = terms[0].1.cores[k].n;
            let r0: usize = if k == 0 {
                1
            } else {
                terms.iter().map(|t| t.1.cores[k].r0).sum()
            };
            let r1: usize = if k + 1 == d {
                1
            } else {
                terms.iter().map(|t| t.1.cores[k].r1).sum()
            };
            let mut core = Core::zeros(r0, n, r1);
            let (mut off0, mut off1) = (0, 0);
            for (c, x) in terms {
                let g = &x.cores[k];
                let s = if k == 0 { *c } else { 1.0 };
                for a in 0..g.r0 {
                    for i in 0..n {
                        for b in 0..g.r1 {
                            core.v[((off0 + a) * n + i) * r1 + off1 + b] += s * g.at(a, i, b);
                        }
                    }
                }
                if k > 0 {
                    off0 += g.r0;
                }
                if k + 1 < d {
                    off1 += g.r1;
                }
            }
            cores.push(core);
        }
        Tt { cores }
    }

    /// Makes cores `1…d−1` right-orthonormal (`Σ_{i,b} G[a,i,b] G[a',i,b] = δ_aa'`);
    /// the norm moves into core 0.
    pub fn orthogonalize_right(&mut self) {
        for k in (1..self.cores.len()).rev() {
            let (q, r) = right_qr(&self.cores[k]);
            self.cores[k] = q;
            self.cores[k - 1] = times_right(&self.cores[k - 1], r.as_ref());
        }
    }

    /// TT-SVD rounding: the result differs from `self` by at most `rel_eps·‖self‖`
    /// (Frobenius), and no rank exceeds `max_rank` (which may add more error).
    /// Returns the relative error committed (from the discarded singular values).
    pub fn round(&mut self, rel_eps: f64, max_rank: usize) -> f64 {
        let d = self.cores.len();
        if d == 1 {
            return 0.0;
        }
        self.orthogonalize_right();
        self.round_orthogonal(rel_eps, max_rank)
    }

    /// The SVD sweep of [`Self::round`], for a train already right-orthogonalized.
    pub fn round_orthogonal(&mut self, rel_eps: f64, max_rank: usize) -> f64 {
        let d = self.cores.len();
        if d == 1 {
            return 0.0;
        }
        let norm = frob(&self.cores[0].v);
        let per_bond = rel_eps * norm / ((d - 1) as f64).sqrt();
        let mut discarded_sq = 0.0;
        for k in 0..d - 1 {
            let c = &self.cores[k];
            let Some(svd) = thin_svd(c.left()) else {
                continue;
            };
            let s = &svd.s;
            let mut keep = s.len();
            let mut tail = 0.0;
            while keep > 1 {
                let x = s[keep - 1];
                if tail + x * x > per_bond * per_bond {
                    break;
                }
                tail += x * x;
                keep -= 1;
            }
            if keep > max_rank {
                for j in max_rank..keep {
                    tail += s[j] * s[j];
                }
                keep = max_rank;
            }
            discarded_sq += tail;
            let u = svd.u.subcols(0, keep);
            let sv = Mat::<f64>::from_fn(keep, c.r1, |i, j| s[i] * svd.v[(j, i)]);
            let (r0, n) = (c.r0, c.n);
            self.cores[k] = Core::from_mat(r0, n, keep, u);
            self.cores[k + 1] = times_left(sv.as_ref(), &self.cores[k + 1]);
        }
        if norm > 0.0 {
            discarded_sq.sqrt() / norm
        } else {
            0.0
        }
    }

    /// Multiplies core `k` by `w` along its index (`w.len() == n_k`).
    pub fn scale_axis(&mut self, k: usize, w: &[f64]) {
        let c = &mut self.cores[k];
        for a in 0..c.r0 {
            for (i, &s) in w.iter().enumerate() {
                for v in &mut c.v[(a * c.n + i) * c.r1..(a * c.n + i + 1) * c.r1] {
                    *v *= s;
                }
            }
        }
    }

    /// Contracts core `k` with `w_k` where given, leaving the other indices open; with
    /// every core contracted, the value `Σ X(i) Π_k w_k(i_k)`.
    pub fn contract_all(&self, w: &[&[f64]]) -> f64 {
        let mut v = vec![1.0];
        for (c, wk) in self.cores.iter().zip(w) {
            let m = c.contract(wk);
            let mut next = vec![0.0; c.r1];
            for (a, &va) in v.iter().enumerate() {
                for (b, x) in next.iter_mut().enumerate() {
                    *x += va * m[a * c.r1 + b];
                }
            }
            v = next;
        }
        v[0]
    }

    /// Every marginal: `out[k][i] = Σ_{all indices but k} X(…, i_k = i, …)`, from one
    /// left and one right pass of partial sums (`O(d n r²)`).
    pub fn marginals(&self) -> Vec<Vec<f64>> {
        let d = self.cores.len();
        let sums: Vec<Vec<f64>> = self
            .cores
            .iter()
            .map(|c| c.contract(&vec![1.0; c.n]))
            .collect();
        // left[k]: row vector of length r_{k−1}; right[k]: column vector of length r_k.
        let mut left = vec![vec![1.0]];
        for k in 0..d - 1 {
            let c = &self.cores[k];
            let l = &left[k];
            left.push(
                (0..c.r1)
                    .map(|b| (0..c.r0).map(|a| l[a] * sums[k][a * c.r1 + b]).sum())
                    .collect(),
            );
        }
        let mut right = vec![vec![1.0]; d];
        for k in (0..d - 1).rev() {
            let c = &self.cores[k + 1];
            right[k] = (0..c.r0)
                .map(|a| {
                    (0..c.r1)
                        .map(|b| sums[k + 1][a * c.r1 + b] * right[k + 1][b])
                        .sum()
                })
                .collect();
        }
        (0..d)
            .map(|k| {
                let c = &self.cores[k];
                (0..c.n)
                    .map(|i| {
                        let mut s = 0.0;
                        for a in 0..c.r0 {
                            if left[k][a] == 0.0 {
                                continue;
                            }
                            for b in 0..c.r1 {
                                s += left[k][a] * c.at(a, i, b) * right[k][b];
                            }
                        }
                        s
                    })
                    .collect()
            })
            .collect()
    }

    /// The full tensor, first index fastest (for checks on small boxes).
    /// The train of cores `a < b` alone, every other core summed over its index
    /// (contracted with ones): the joint of two coordinates, the rest summed out
    /// without forming the whole tensor.
    pub fn keep_pair(&self, a: usize, b: usize) -> Tt {
        debug_assert!(a < b && b < self.cores.len());
        let mut kept: Vec<Core> = Vec::with_capacity(2);
        // `pending`: a matrix (rows × r) to multiply into the next kept core.
        let mut pending: Option<(usize, Vec<f64>)> = None;
        for (k, c) in self.cores.iter().enumerate() {
            if k == a || k == b {
                let core = match pending.take() {
                    Some((rows, l)) => times_left(MatRef::from_row_major_slice(&l, rows, c.r0), c),
                    None => c.clone(),
                };
                kept.push(core);
            } else {
                let m = c.contract(&vec![1.0; c.n]);
                pending = Some(match pending.take() {
                    Some((rows, l)) => {
                        let lm = MatRef::from_row_major_slice(&l, rows, c.r0)
                            * MatRef::from_row_major_slice(&m, c.r0, c.r1);
                        (
                            rows,
                            (0..rows)
                                .flat_map(|i| (0..c.r1).map(move |j| (i, j)))
                                .map(|(i, j)| lm[(i, j)])
                                .collect(),
                        )
                    }
                    None => (c.r0, m),
                });
            }
        }
        if let Some((rows, l)) = pending {
            let last = kept.len() - 1;
            let cols = l.len() / rows;
            kept[last] = times_right(&kept[last], MatRef::from_row_major_slice(&l, rows, cols));
        }
        Tt { cores: kept }
    }

    pub fn full(&self) -> Vec<f64> {
        // Right to left: t[(i_k…i_d), a_{k−1}] built as rows over the trailing indices.
        // Each step is one matrix product, `M = T · C_(r0·n, r1)ᵀ` (count × r0·n, column
        // `(a, i)`), then `next[(rest, i), a] = M[rest, (a, i)]`.
        let d = self.cores.len();
        let mut t: Vec<f64> = vec![1.0];
        let mut count = 1usize;
        for k in (0..d).rev() {
            let c = &self.cores[k];
            let tm = MatRef::from_row_major_slice(&t, count, c.r1);
            let cm = MatRef::from_row_major_slice(&c.v, c.r0 * c.n, c.r1);
            let m = tm * cm.transpose();
            let mut next = vec![0.0; c.n * count * c.r0];
            for rest in 0..count {
                for a in 0..c.r0 {
                    for i in 0..c.n {
                        next[(rest * c.n + i) * c.r0 + a] = m[(rest, a * c.n + i)];
                    }
                }
            }
            t = next;
            count *= c.n;
        }
        t
    }
}

fn frob(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `l' = Σ_{a,c,i} l[a,c] A[a,i,·] B[c,i,·]`: `t = lᵀ A` laid out row-major as an
/// `(rb0·n) × ra1` matrix, then `l' = tᵀ B_left`.
fn dot_step(l: &Mat<f64>, a: &Core, b: &Core) -> Mat<f64> {
    let mut t = vec![0.0; b.r0 * a.n * a.r1];
    faer::linalg::matmul::matmul(
        faer::MatMut::from_row_major_slice_mut(&mut t, b.r0, a.n * a.r1),
        Accum::Replace,
        l.transpose(),
        a.right(),
        1.0,
        Par::Seq,
    );
    crate::cpu::clear_upper_halves();
    mul(
        MatRef::from_row_major_slice(&t, b.r0 * a.n, a.r1).transpose(),
        b.left(),
    )
}

/// Core = R·Q with Q right-orthonormal: returns (Q as a core, R: r0 × r0').
fn right_qr(c: &Core) -> (Core, Mat<f64>) {
    // QR of the transpose of the right unfolding: Gᵀ = Q̃ R̃ → G = R̃ᵀ Q̃ᵀ.
    let (q, r) = thin_qr(c.right().transpose());
    let rank = q.ncols();
    let qt = q.transpose().to_owned();
    (
        Core::from_mat(rank, c.n, c.r1, qt.as_ref()),
        r.transpose().to_owned(),
    )
}

/// Core = Q·R with Q left-orthonormal: returns (Q as a core, R: r1' × r1).
pub fn left_qr(c: &Core) -> (Core, Mat<f64>) {
    let (q, r) = thin_qr(c.left());
    (Core::from_mat(c.r0, c.n, q.ncols(), q.as_ref()), r)
}

/// `core · m` over the right index (m: r1 × r1').
pub fn times_right(c: &Core, m: MatRef<'_, f64>) -> Core {
    let out = mul(c.left(), m);
    Core::from_mat(c.r0, c.n, m.ncols(), out.as_ref())
}

/// `m · core` over the left index (m: r0' × r0).
pub fn times_left(m: MatRef<'_, f64>, c: &Core) -> Core {
    let out = mul(m, c.right());
    Core::from_mat(m.nrows(), c.n, c.r1, out.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random(sizes: &[usize], ranks: &[usize], seed: u64) -> Tt {
        let mut rng = Rng::seed(seed);
        let d = sizes.len();
        Tt {
            cores: (0..d)
                .map(|k| {
                    let r0 = if k == 0 { 1 } else { ranks[k - 1] };
                    let r1 = if k + 1 == d { 1 } else { ranks[k] };
                    let mut c = Core::zeros(r0, sizes[k], r1);
                    for x in &mut c.v {
                        *x = rng.uniform() - 0.5;
                    }
                    c
                })
                .collect(),
        }
    }

    fn dist(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt()
    }

    #[test]
    fn dot_sum_and_round_agree_with_the_full_tensor() {
        let sizes = [4, 5, 3, 6];
        let x = random(&sizes, &[2, 3, 2], 1);
        let y = random(&sizes, &[3, 2, 4], 2);
        let (fx, fy) = (x.full(), y.full());
        let dot: f64 = fx.iter().zip(&fy).map(|(a, b)| a * b).sum();
        assert!((x.dot(&y) - dot).abs() < 1e-12 * dot.abs().max(1.0));
        let s = Tt::sum(&[(2.0, &x), (-0.5, &y)]);
        let fs: Vec<f64> = fx.iter().zip(&fy).map(|(a, b)| 2.0 * a - 0.5 * b).collect();
        assert!(dist(&s.full(), &fs) < 1e-12);
        // x + x has rank 2·r but represents a rank-r tensor: rounding recovers r.
        let mut xx = Tt::sum(&[(1.0, &x), (1.0, &x)]);
        let err = xx.round(1e-12, 100);
        assert_eq!(xx.ranks(), vec![2, 3, 2]);
        let f2: Vec<f64> = fx.iter().map(|a| 2.0 * a).collect();
        assert!(dist(&xx.full(), &f2) < 1e-10 * frob(&f2));
        assert!(err < 1e-12);
        // Truncation to rank 1 reports the error it commits.
        let mut r1 = s.clone();
        let err = r1.round(0.0, 1);
        let actual = dist(&r1.full(), &fs) / frob(&fs);
        assert!(
            (err - actual).abs() < 0.5 * actual,
            "estimate {err}, actual {actual}"
        );
    }

    #[test]
    fn contract_all_sums_the_tensor() {
        let sizes = [3, 4, 2];
        let x = random(&sizes, &[2, 2], 3);
        let ones: Vec<Vec<f64>> = sizes.iter().map(|&n| vec![1.0; n]).collect();
        let w: Vec<&[f64]> = ones.iter().map(|v| v.as_slice()).collect();
        let total: f64 = x.full().iter().sum();
        assert!((x.contract_all(&w) - total).abs() < 1e-12);
    }
}
