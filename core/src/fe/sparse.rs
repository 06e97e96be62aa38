//! A symmetric sparse matrix stored as its lower triangle in compressed columns, with a
//! pattern built once from the cells, element scatter-add, and faer's sparse Cholesky
//! under a nested-dissection ordering ([`super::ordering`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Conj, Mat, Par, Side};

use super::FeError;
use super::space::Space;

/// Lower triangle (row ≥ col) of a symmetric matrix on the free dofs, CSC.
#[derive(Debug, Clone)]
pub struct SymCsc {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
    pub val: Vec<f64>,
}

impl SymCsc {
    /// The lower triangle's pattern, as the fill-reducing ordering reads it.
    pub fn pattern_ref(&self) -> super::ordering::Pattern<'_> {
        super::ordering::Pattern {
            n: self.n,
            col_ptr: &self.col_ptr,
            row_idx: &self.row_idx,
        }
    }

    /// The pattern coupling every pair of free dofs that share a cell.
    pub fn pattern(space: &Space) -> SymCsc {
        let n = space.free_dofs;
        let nn = space.nodes.len();
        // Node adjacency (free nodes only), then expanded to 3×3 dof blocks.
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); nn];
        for c in 0..space.cell_count() {
            let cell = space.cell(c);
            for &a in cell {
                if space.dof[a as usize] == u32::MAX {
                    continue;
                }
                for &b in cell {
                    if space.dof[b as usize] != u32::MAX {
                        adj[a as usize].push(b);
                    }
                }
            }
        }
        for a in &mut adj {
            a.sort_unstable();
            a.dedup();
        }
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::new();
        // Columns in dof order: node-major, so iterate nodes by their dof index.
        let mut by_dof: Vec<(u32, usize)> = space
            .dof
            .iter()
            .enumerate()
            .filter(|(_, d)| **d != u32::MAX)
            .map(|(nd, &d)| (d, nd))
            .collect();
        by_dof.sort_unstable();
        for &(d, nd) in &by_dof {
            let mut rows: Vec<usize> = adj[nd]
                .iter()
                .flat_map(|&m| {
                    let base = space.dof[m as usize] as usize;
                    [base, base + 1, base + 2]
                })
                .collect();
            rows.sort_unstable();
            for c in 0..3 {
                let col = d as usize + c;
                row_idx.extend(rows.iter().copied().filter(|&r| r >= col));
                col_ptr[col + 1] = row_idx.len();
            }
        }
        let nnz = row_idx.len();
        SymCsc {
            n,
            col_ptr,
            row_idx,
            val: vec![0.0; nnz],
        }
    }

    /// Adds `v` at (row, col), row ≥ col, which must be in the pattern.
    #[inline]
    /// Whether `(row, col)` (lower triangle) is in the pattern.
    pub fn has(&self, row: usize, col: usize) -> bool {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        let k = lo + self.row_idx[lo..hi].partition_point(|&r| r < row);
        k < hi && self.row_idx[k] == row
    }

    pub fn add(&mut self, row: usize, col: usize, v: f64) {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        let k = lo + self.row_idx[lo..hi].partition_point(|&r| r < row);
        debug_assert!(
            k < hi && self.row_idx[k] == row,
            "({row}, {col}) not in the pattern"
        );
        self.val[k] += v;
    }

    /// Scatter-adds an element matrix (`dofs.len()` square, row-major); entries whose
    /// dof is `usize::MAX` (fixed) are skipped, as is the upper triangle.
    ///
    /// Column by column: a node's three dofs are consecutive rows of a column, so after
    /// one search the next two rows are the next two entries (checked; a search
    /// otherwise). Each entry of the pattern gets one addition a cell either way, so
    /// the sums are those of an entry-by-entry search.
    pub fn scatter(&mut self, dofs: &[usize], ke: &[f64]) {
        let m = dofs.len();
        for (j, &cj) in dofs.iter().enumerate() {
            if cj == usize::MAX {
                continue;
            }
            let (lo, hi) = (self.col_ptr[cj], self.col_ptr[cj + 1]);
            let rows = &self.row_idx[lo..hi];
            let mut last: Option<(usize, usize)> = None;
            for (i, &ri) in dofs.iter().enumerate() {
                if ri == usize::MAX || ri < cj {
                    last = None;
                    continue;
                }
                let k = match last {
                    Some((r, k)) if r + 1 == ri && rows.get(k + 1) == Some(&ri) => k + 1,
                    _ => rows.partition_point(|&r| r < ri),
                };
                debug_assert!(rows.get(k) == Some(&ri), "({ri}, {cj}) not in the pattern");
                self.val[lo + k] += ke[i * m + j];
                last = Some((ri, k));
            }
        }
    }

    /// `y = A x` using the symmetric lower storage.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k];
                let v = self.val[k];
                y[r] += v * x[c];
                if r != c {
                    y[c] += v * x[r];
                }
            }
        }
    }

    pub fn to_faer(&self) -> SparseColMat<usize, f64> {
        let sym = SymbolicSparseColMat::new_checked(
            self.n,
            self.n,
            self.col_ptr.clone(),
            None,
            self.row_idx.clone(),
        );
        SparseColMat::new(sym, self.val.clone())
    }
}

/// Memory the numeric factorization may use, in bytes (default: unlimited). The app
/// sets it from the memory available, so an impossible factorization is refused with a
/// message instead of the process being killed.
static FACTOR_BUDGET_BYTES: AtomicU64 = AtomicU64::new(u64::MAX);

/// Sets the factorization memory budget (bytes).
pub fn set_factor_budget_bytes(bytes: u64) {
    FACTOR_BUDGET_BYTES.store(bytes, Ordering::Relaxed);
}

/// Bytes the Cholesky factor of `a` needs (from its symbolic analysis: fill-in under
/// the same ordering the numeric factorization uses), plus the factorization's
/// workspace, estimated as the factor again.
pub fn factor_bytes_estimate(a: &SymCsc) -> Result<u64, FeError> {
    Ok(2 * 8 * symbolic(a)?.len_val() as u64)
}

/// Entries of the Cholesky factor of `a` (its fill-in under the ordering the numeric
/// factorization uses): what a factor's memory scales with.
pub fn factor_entries(a: &SymCsc) -> Result<u64, FeError> {
    Ok(symbolic(a)?.len_val() as u64)
}

/// Symbolic analyses already made, newest last. A press factors the tangent of one
/// pattern many times; its ordering and fill-in (about 3 % of a tissue build's time when
/// recomputed at each factorization) depend on the pattern only, so they are kept. The
/// pattern itself is kept beside its analysis and compared whole, so a hit is exact.
static ANALYSES: Mutex<Vec<Analysis>> = Mutex::new(Vec::new());

/// How many patterns' analyses are kept: a build uses one, a test run a few.
const ANALYSES_KEPT: usize = 3;

struct Analysis {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    symbolic: Arc<SymbolicCholesky<usize>>,
}

/// The symbolic Cholesky analysis of `a` (ordering and fill-in): nested dissection
/// where [`super::ordering`] gives one, else faer's AMD; made once for each pattern
/// (see [`ANALYSES`]).
fn symbolic(a: &SymCsc) -> Result<Arc<SymbolicCholesky<usize>>, FeError> {
    let same = |e: &Analysis| e.n == a.n && e.col_ptr == a.col_ptr && e.row_idx == a.row_idx;
    {
        // A panic elsewhere while the lock was held leaves only whole entries behind.
        let kept = ANALYSES.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(hit) = kept.iter().find(|e| same(e)) {
            return Ok(Arc::clone(&hit.symbolic));
        }
    }
    let symbolic = Arc::new(analyse(a, true)?);
    let mut kept = ANALYSES.lock().unwrap_or_else(PoisonError::into_inner);
    if !kept.iter().any(same) {
        if kept.len() == ANALYSES_KEPT {
            kept.remove(0);
        }
        kept.push(Analysis {
            n: a.n,
            col_ptr: a.col_ptr.clone(),
            row_idx: a.row_idx.clone(),
            symbolic: Arc::clone(&symbolic),
        });
    }
    Ok(symbolic)
}

/// `a`'s symbolic analysis under nested dissection where `nested` and
/// [`super::ordering`] gives one, else under faer's AMD.
fn analyse(a: &SymCsc, nested: bool) -> Result<SymbolicCholesky<usize>, FeError> {
    let nd = nested
        .then(|| super::ordering::nested_dissection(a.pattern_ref()))
        .flatten();
    let ordering = match &nd {
        Some((fwd, inv)) => SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, a.n)),
        None => SymmetricOrdering::Amd,
    };
    factorize_symbolic_cholesky(
        a.to_faer().symbolic(),
        Side::Lower,
        ordering,
        Default::default(),
    )
    .map_err(|e| FeError::NotPositiveDefinite {
        fixed_nodes: 0,
        detail: format!("symbolic analysis failed: {e:?}"),
    })
}

/// `a` rounded to single precision, in faer's form.
fn to_single(a: &SymCsc) -> Result<SparseColMat<usize, f32>, String> {
    let m = a.to_faer();
    Ok(SparseColMat::new(
        m.symbolic().to_owned().map_err(|e| format!("{e:?}"))?,
        a.val.iter().map(|&v| v as f32).collect(),
    ))
}

/// A factored symmetric positive-definite matrix, in double or single precision.
#[derive(Debug)]
pub struct Cholesky {
    llt: Factor,
    n: usize,
}

/// The symbolic analysis and the factor's values. A double factor is factored and
/// solved on [`double_par`]'s threads, a single one sequentially (see
/// [`Cholesky::factor_single`]).
#[derive(Debug)]
enum Factor {
    Double(Arc<SymbolicCholesky<usize>>, Vec<f64>),
    Single(Arc<SymbolicCholesky<usize>>, Vec<f32>),
}

/// The parallelism of double-precision factorizations and solves: one task per core of
/// the machine, whatever pool the caller runs in. faer's rounding depends on how many
/// tasks it splits the work into, and its default takes that from the calling pool: a
/// tissue build presses inside a pool of `--jobs` threads, so its law changed with the
/// number of presses at once (the same three-press region, coarse P2: bound
/// 0.0949400 mm one at a time, 0.0949394 mm two at a time). The core count is fixed for
/// a machine, so a build gives one law however many presses run at once; where the
/// pool has fewer threads, the tasks simply run in turn.
fn double_par() -> Par {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    Par::rayon(*CORES.get_or_init(|| {
        std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
    }))
}

/// The numeric factor of `m` (lower triangle) under `symbolic`, with `par`, or faer's
/// reason it is not positive definite.
fn numeric<T: faer::traits::ComplexField>(
    symbolic: &SymbolicCholesky<usize>,
    m: faer::sparse::SparseColMatRef<'_, usize, T>,
    par: Par,
) -> Result<Vec<T>, String> {
    let mut values = vec![T::zero_impl(); symbolic.len_val()];
    let mut scratch =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default()));
    let numeric = symbolic.factorize_numeric_llt(
        &mut values,
        m,
        Side::Lower,
        Default::default(),
        par,
        MemStack::new(&mut scratch),
        Default::default(),
    );
    crate::cpu::clear_upper_halves();
    numeric.map(|_| ()).map_err(|e| format!("{e:?}"))?;
    Ok(values)
}

impl Cholesky {
    pub fn factor(a: &SymCsc, fixed_nodes: usize) -> Result<Cholesky, FeError> {
        Cholesky::check_budget(a)?;
        let err = |e: String| FeError::NotPositiveDefinite {
            fixed_nodes,
            detail: e,
        };
        let symbolic = symbolic(a)?;
        let values = numeric(&symbolic, a.to_faer().as_ref(), double_par()).map_err(err)?;
        Ok(Cholesky {
            llt: Factor::Double(symbolic, values),
            n: a.n,
        })
    }

    /// Refuses, as [`FeError::TooLarge`], a double-precision factor of `a`'s pattern
    /// larger than the budget: called on the bare pattern, it refuses before any
    /// assembly (its symbolic analysis is kept for the factorization that follows).
    pub fn check_budget(a: &SymCsc) -> Result<(), FeError> {
        let budget = FACTOR_BUDGET_BYTES.load(Ordering::Relaxed);
        if budget != u64::MAX {
            let need = factor_bytes_estimate(a)?;
            if need > budget {
                return Err(FeError::TooLarge {
                    dofs: a.n,
                    need_gb: need as f64 / 1e9,
                    budget_gb: budget as f64 / 1e9,
                });
            }
        }
        Ok(())
    }

    /// [`factor`](Self::factor) in single precision: half the memory traffic of the
    /// factorization and of each solve, for a factor used only as an approximate
    /// inverse whose answers are corrected against double-precision residuals.
    /// Factored and solved sequentially: faer's parallel single-precision kernels
    /// round differently with the number of threads, and a build must give the same
    /// law on one core as on all (its presses already run in parallel).
    pub fn factor_single(a: &SymCsc, fixed_nodes: usize) -> Result<Cholesky, FeError> {
        let err = |e: String| FeError::NotPositiveDefinite {
            fixed_nodes,
            detail: e,
        };
        let symbolic = symbolic(a)?;
        // The budget as for `factor`: the factor and its workspace, in four bytes.
        let need = 2 * 4 * symbolic.len_val() as u64;
        let budget = FACTOR_BUDGET_BYTES.load(Ordering::Relaxed);
        if need > budget {
            return Err(FeError::TooLarge {
                dofs: a.n,
                need_gb: need as f64 / 1e9,
                budget_gb: budget as f64 / 1e9,
            });
        }
        let single = to_single(a).map_err(err)?;
        let values = numeric(&symbolic, single.as_ref(), Par::Seq).map_err(err)?;
        Ok(Cholesky {
            llt: Factor::Single(symbolic, values),
            n: a.n,
        })
    }

    /// Solves the factor `(symbolic, values)` for the columns of `rhs` with `par`.
    fn solve_with<T: faer::traits::ComplexField>(
        symbolic: &SymbolicCholesky<usize>,
        values: &[T],
        rhs: &mut Mat<T>,
        par: Par,
    ) {
        let mut scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<T>(rhs.ncols(), par));
        LltRef::new(symbolic, values).solve_in_place_with_conj(
            Conj::No,
            rhs.as_mut(),
            par,
            MemStack::new(&mut scratch),
        );
        crate::cpu::clear_upper_halves();
    }

    /// Solves A x = b for one right-hand side.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        match &self.llt {
            Factor::Double(symbolic, values) => {
                let mut rhs = Mat::<f64>::from_fn(self.n, 1, |i, _| b[i]);
                Self::solve_with(symbolic, values, &mut rhs, double_par());
                (0..self.n).map(|i| rhs[(i, 0)]).collect()
            }
            Factor::Single(symbolic, values) => {
                let mut rhs = Mat::<f32>::from_fn(self.n, 1, |i, _| b[i] as f32);
                Self::solve_with(symbolic, values, &mut rhs, Par::Seq);
                (0..self.n).map(|i| f64::from(rhs[(i, 0)])).collect()
            }
        }
    }

    /// Solves for several right-hand sides at once (columns of `b`, n × k, column-major).
    pub fn solve_many(&self, b: &mut Mat<f64>) {
        match &self.llt {
            Factor::Double(symbolic, values) => {
                Self::solve_with(symbolic, values, b, double_par());
            }
            Factor::Single(symbolic, values) => {
                let mut single = Mat::<f32>::from_fn(b.nrows(), b.ncols(), |i, j| b[(i, j)] as f32);
                Self::solve_with(symbolic, values, &mut single, Par::Seq);
                for j in 0..b.ncols() {
                    for i in 0..b.nrows() {
                        b[(i, j)] = f64::from(single[(i, j)]);
                    }
                }
            }
        }
    }
}

/// What one ordering costs on one matrix, measured on one thread: the factor's entries,
/// the analysis, a numeric factorization and one solve in double and in single precision.
/// `palpa lab bench fe --only ordering` prints it for AMD and nested dissection side by side.
#[derive(Debug, Clone, Copy)]
pub struct OrderingCost {
    pub factor_entries: usize,
    pub analysis_s: f64,
    pub double_factor_s: f64,
    pub double_solve_s: f64,
    pub single_factor_s: f64,
    pub single_solve_s: f64,
    /// `‖A x − b‖ / ‖b‖` of the double solve: both orders factor the same matrix.
    pub double_residual: f64,
}

/// Measures [`OrderingCost`] for `a` under nested dissection (`nested`, where
/// [`super::ordering`] gives one) or AMD, bypassing the kept analyses.
pub fn ordering_cost(a: &SymCsc, nested: bool) -> Result<OrderingCost, FeError> {
    use std::time::Instant;
    let err = |e: String| FeError::NotPositiveDefinite {
        fixed_nodes: 0,
        detail: e,
    };
    let t = Instant::now();
    let symbolic = analyse(a, nested)?;
    let analysis_s = t.elapsed().as_secs_f64();
    let m = a.to_faer();
    let b: Vec<f64> = (0..a.n).map(|i| ((i % 7) as f64 - 3.0) / 3.0).collect();
    let t = Instant::now();
    let double = numeric(&symbolic, m.as_ref(), Par::Seq).map_err(err)?;
    let double_factor_s = t.elapsed().as_secs_f64();
    let mut x = Mat::<f64>::from_fn(a.n, 1, |i, _| b[i]);
    let t = Instant::now();
    Cholesky::solve_with(&symbolic, &double, &mut x, Par::Seq);
    let double_solve_s = t.elapsed().as_secs_f64();
    let x: Vec<f64> = (0..a.n).map(|i| x[(i, 0)]).collect();
    let mut ax = vec![0.0; a.n];
    a.mul(&x, &mut ax);
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|q| q * q).sum::<f64>().sqrt();
    let double_residual =
        norm(&mut ax.iter().zip(&b).map(|(p, q)| p - q)) / norm(&mut b.iter().copied());
    drop(double);
    let single_m = to_single(a).map_err(err)?;
    let t = Instant::now();
    let single = numeric(&symbolic, single_m.as_ref(), Par::Seq).map_err(err)?;
    let single_factor_s = t.elapsed().as_secs_f64();
    let mut xs = Mat::<f32>::from_fn(a.n, 1, |i, _| b[i] as f32);
    let t = Instant::now();
    Cholesky::solve_with(&symbolic, &single, &mut xs, Par::Seq);
    let single_solve_s = t.elapsed().as_secs_f64();
    Ok(OrderingCost {
        factor_entries: symbolic.len_val(),
        analysis_s,
        double_factor_s,
        double_solve_s,
        single_factor_s,
        single_solve_s,
        double_residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The column-by-column scatter adds what an entry-by-entry search adds, bit for
    /// bit, on a P2 mesh with fixed nodes (cells of the coarse liver, random element
    /// matrices).
    #[test]
    fn scatter_adds_what_entry_by_entry_adds() {
        let organ = crate::organ::catalogue::mesh(
            crate::organ::catalogue::OrganName::Liver,
            crate::organ::Level::Coarse,
        );
        let space = crate::fe::probe::organ_space(&organ, crate::fe::Element::P2);
        let pattern = SymCsc::pattern(&space);
        let (mut fast, mut plain) = (pattern.clone(), pattern);
        let mut rng = Rng::seed(41);
        let mut dofs = Vec::new();
        let mut fixed_seen = 0;
        for c in (0..space.cell_count()).step_by(7) {
            crate::fe::elasticity::cell_dofs(&space, c, &mut dofs);
            fixed_seen += dofs.iter().filter(|&&d| d == usize::MAX).count();
            let m = dofs.len();
            let ke: Vec<f64> = (0..m * m).map(|_| rng.range(-1.0, 1.0)).collect();
            fast.scatter(&dofs, &ke);
            for (i, &ri) in dofs.iter().enumerate() {
                for (j, &cj) in dofs.iter().enumerate() {
                    if ri != usize::MAX && cj != usize::MAX && ri >= cj {
                        plain.add(ri, cj, ke[i * m + j]);
                    }
                }
            }
        }
        assert!(fixed_seen > 0, "some cells touch the fixed region");
        assert!(
            fast.val
                .iter()
                .zip(&plain.val)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    /// A tridiagonal SPD matrix (4 on the diagonal, −1 beside it), lower triangle.
    fn tridiagonal(n: usize) -> SymCsc {
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for c in 0..n {
            row_idx.push(c);
            val.push(4.0);
            if c + 1 < n {
                row_idx.push(c + 1);
                val.push(-1.0);
            }
            col_ptr.push(row_idx.len());
        }
        SymCsc {
            n,
            col_ptr,
            row_idx,
            val,
        }
    }

    /// Double precision solves to rounding; single to single's rounding (this matrix's
    /// condition number is below 3); one right-hand side or several give the same.
    #[test]
    fn single_and_double_factors_solve_to_their_precision() {
        let a = tridiagonal(60);
        let mut rng = Rng::seed(3);
        let b: Vec<f64> = (0..a.n).map(|_| rng.range(-1.0, 1.0)).collect();
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (single, tol) in [(false, 1e-14), (true, 1e-6)] {
            let f = if single {
                Cholesky::factor_single(&a, 0)
            } else {
                Cholesky::factor(&a, 0)
            }
            .expect("SPD");
            let x = f.solve(&b);
            let mut ax = vec![0.0; a.n];
            a.mul(&x, &mut ax);
            let r: Vec<f64> = ax.iter().zip(&b).map(|(p, q)| p - q).collect();
            assert!(norm(&r) <= tol * norm(&b), "single {single}: {}", norm(&r));
            let mut many = Mat::<f64>::from_fn(a.n, 2, |i, j| b[i] * (j + 1) as f64);
            f.solve_many(&mut many);
            for i in 0..a.n {
                assert_eq!(many[(i, 0)], x[i]);
                assert!((many[(i, 1)] - 2.0 * x[i]).abs() <= 2.0 * tol * x[i].abs().max(1.0));
            }
        }
    }

    /// The analysis kept for one pattern is never used for another of the same size
    /// and count of entries: each matrix, factored in turn and again, solves itself.
    #[test]
    fn a_kept_analysis_serves_only_its_own_pattern() {
        let near = tridiagonal(40);
        let mut far = tridiagonal(40);
        // Couple each dof with the one two away instead of the next: same n, same nnz.
        far.row_idx.clear();
        far.col_ptr = vec![0];
        for c in 0..far.n {
            far.row_idx.push(c);
            if c + 1 < far.n {
                far.row_idx.push((c + 2).min(far.n - 1).max(c + 1));
            }
            far.col_ptr.push(far.row_idx.len());
        }
        let mut rng = Rng::seed(5);
        let b: Vec<f64> = (0..40).map(|_| rng.range(-1.0, 1.0)).collect();
        let mut first = Vec::new();
        for round in 0..2 {
            for (i, a) in [&near, &far].into_iter().enumerate() {
                let x = Cholesky::factor_single(a, 0).expect("SPD").solve(&b);
                let mut ax = vec![0.0; a.n];
                a.mul(&x, &mut ax);
                let worst = ax
                    .iter()
                    .zip(&b)
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-5, "pattern {i}, round {round}: residual {worst}");
                if round == 0 {
                    first.push(x);
                } else {
                    assert_eq!(
                        first[i], x,
                        "pattern {i}: the kept analysis changed the factor"
                    );
                }
            }
        }
    }

    /// A matrix that is not positive definite is refused in either precision.
    #[test]
    fn an_indefinite_matrix_is_refused_in_single_precision_too() {
        let mut a = tridiagonal(10);
        a.val[0] = -4.0;
        assert!(Cholesky::factor(&a, 0).is_err());
        assert!(Cholesky::factor_single(&a, 0).is_err());
    }
}
