//! A meta-model that keeps only what a scene shows: every species' marginal and a few
//! chosen pairwise joints, as functions of time.
//!
//! For a network with many species the whole history `P(t, z_1…z_d)` is a large train
//! (hundreds of MB for twenty species, because the history's ranks grow with the
//! spread of times it must hold), while the scene draws only a species × copy-number
//! strip and one pair's landscape. So the solver ([`super::ttsolve::solve_views`])
//! reads, at every time step, the marginals `π_i(t_j, z)` and the chosen joints
//! `π_ab(t_j, z_a, z_b)` from the step's state (contractions of its train with ones,
//! never a dense array), and stores each *view* `S` (time nodes × values) in low rank:
//!
//! `S ≈ diag(ν) Ũ Σ Vᵀ`, with `ν_j = ‖S_j‖₂` the norm of time row `j`,
//!
//! the SVD of the row-normalized `diag(1/ν) S` cut where the dropped singular values
//! give a root-mean-square relative row error of at most `eps`. Normalizing first keeps
//! the early, sharply peaked rows (a point mass at `t = 0`) as accurate as the late,
//! spread ones. On-line, a time `t` becomes the cubic Lagrange weights `w_j` of its four
//! nearest nodes and a view is `Vᵀ (Σ_j w_j T_j)` with `T = diag(ν) Ũ Σ`: `4r + m r`
//! operations for `m` values and rank `r`, and nothing solved.

use super::history::lagrange_weights;
use crate::tensor::dense::thin_svd;
use crate::tensor::tt::Tt;
use faer::Mat;

/// One stored view: the marginal of one species or the joint of two (the first
/// fastest), over the time nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// Network indices of the species (one, or two with `a < b`).
    pub species: Vec<usize>,
    pub rank: usize,
    /// `T` (time nodes × rank, row-major).
    pub time: Vec<f64>,
    /// `Vᵀ` (rank × values, row-major).
    pub values: Vec<f64>,
}

impl View {
    /// The time coefficients `Σ_j w_j T_j` into `coef[..rank]`.
    pub fn coefficients(&self, w: &[(usize, f64)], coef: &mut [f64]) {
        let r = self.rank;
        let coef = &mut coef[..r];
        coef.fill(0.0);
        for &(j, wj) in w {
            for (c, x) in coef.iter_mut().zip(&self.time[j * r..(j + 1) * r]) {
                *c += wj * x;
            }
        }
    }

    /// The number of values one evaluation gives.
    pub fn len(&self) -> usize {
        self.values.len().checked_div(self.rank).unwrap_or(0)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes the view at the time weights `w` (nonzero `(node, weight)` pairs) into
    /// `out` (its length), using `coef` (at least `rank` long) as scratch.
    pub fn eval_into(&self, w: &[(usize, f64)], coef: &mut [f64], out: &mut [f64]) {
        self.coefficients(w, coef);
        let coef = &coef[..self.rank];
        out.fill(0.0);
        let m = out.len();
        for (k, &c) in coef.iter().enumerate() {
            for (o, v) in out.iter_mut().zip(&self.values[k * m..(k + 1) * m]) {
                *o += c * v;
            }
        }
    }
}

/// The stored views over a time grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Views {
    pub t: Vec<f64>,
    /// States per species (the box).
    pub sizes: Vec<usize>,
    /// The marginals first (one per species, network order), then the joints.
    pub views: Vec<View>,
}

impl Views {
    /// The nonzero cubic Lagrange weights of `t` on the time nodes, and whether `t`
    /// lay beyond them (clamped).
    pub fn time_weights(&self, t: f64) -> (Vec<(usize, f64)>, bool) {
        let (w, clamped) = lagrange_weights(&self.t, t, 4);
        (
            w.into_iter()
                .enumerate()
                .filter(|(_, x)| *x != 0.0)
                .collect(),
            clamped,
        )
    }

    /// The largest rank of a view (the scratch an evaluation needs).
    pub fn max_rank(&self) -> usize {
        self.views.iter().map(|v| v.rank).max().unwrap_or(0)
    }

    /// The stored joints' species pairs `(a, b)`, `a < b`.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        self.views
            .iter()
            .filter(|v| v.species.len() == 2)
            .map(|v| (v.species[0], v.species[1]))
            .collect()
    }

    /// The view of the joint of `a < b`, if stored.
    pub fn pair_view(&self, a: usize, b: usize) -> Option<&View> {
        self.views.iter().find(|v| v.species == [a, b])
    }

    /// Numbers stored.
    pub fn stored_values(&self) -> usize {
        self.views
            .iter()
            .map(|v| v.time.len() + v.values.len())
            .sum()
    }

    /// Checks shapes and values; the reason names the first view that is wrong.
    pub fn check(&self) -> Result<(), String> {
        let n = self.t.len();
        if n == 0 || !self.t.windows(2).all(|w| w[0] < w[1]) || !self.t[0].is_finite() {
            return Err(format!(
                "time nodes must be finite and increasing ({n} given)"
            ));
        }
        let d = self.sizes.len();
        for (k, v) in self.views.iter().enumerate() {
            let want = match v.species[..] {
                [i] if k == i && i < d => self.sizes[i],
                [a, b] if k >= d && a < b && b < d => self.sizes[a] * self.sizes[b],
                _ => {
                    return Err(format!(
                        "view {k} is of species {:?}: expected the {d} marginals in order, \
                         then pairs a < b",
                        v.species
                    ));
                }
            };
            if v.time.len() != n * v.rank || v.values.len() != v.rank * want {
                return Err(format!(
                    "view {k} ({:?}) holds {} time and {} value numbers for rank {}, {n} \
                     nodes and {want} values",
                    v.species,
                    v.time.len(),
                    v.values.len(),
                    v.rank
                ));
            }
            if v.time.iter().chain(&v.values).any(|x| !x.is_finite()) {
                return Err(format!(
                    "view {k} ({:?}) holds a non-finite value",
                    v.species
                ));
            }
        }
        if self.views.len() < d {
            return Err(format!(
                "{} views for {d} species: every marginal must be stored",
                self.views.len()
            ));
        }
        Ok(())
    }
}

impl Views {
    /// Each view's file shape and blocks, for [`crate::file::save_views`].
    pub fn file_blocks(&self) -> Vec<(crate::file::ViewShape, &[f64], &[f64])> {
        self.views
            .iter()
            .map(|v| {
                (
                    crate::file::ViewShape {
                        species: v.species.iter().map(|&i| i as u32).collect(),
                        rank: v.rank as u64,
                    },
                    &v.time[..],
                    &v.values[..],
                )
            })
            .collect()
    }
}

/// The views read from each step's state while the solver runs.
pub(crate) struct Samples {
    /// Core index of each species in the state's train.
    core_of: Vec<usize>,
    sizes: Vec<usize>,
    pairs: Vec<(usize, usize)>,
    t: Vec<f64>,
    /// Per view, its rows appended (time-major).
    rows: Vec<Vec<f64>>,
}

impl Samples {
    pub(crate) fn new(core_of: Vec<usize>, sizes: Vec<usize>, pairs: Vec<(usize, usize)>) -> Self {
        let n = sizes.len() + pairs.len();
        Samples {
            core_of,
            sizes,
            pairs,
            t: Vec::new(),
            rows: vec![Vec::new(); n],
        }
    }

    /// Reads the views of state `x` at time `t` (after the last one pushed).
    pub(crate) fn push(&mut self, t: f64, x: &Tt) {
        let marginals = x.marginals();
        for (i, &k) in self.core_of.iter().enumerate() {
            self.rows[i].extend_from_slice(&marginals[k]);
        }
        let d = self.sizes.len();
        for (p, &(a, b)) in self.pairs.iter().enumerate() {
            let (ka, kb) = (self.core_of[a], self.core_of[b]);
            let joint = x.keep_pair(ka.min(kb), ka.max(kb)).full();
            if ka < kb {
                self.rows[d + p].extend_from_slice(&joint);
            } else {
                // The train holds b's core first: transpose so that a is fastest.
                let (na, nb) = (self.sizes[a], self.sizes[b]);
                let row = &mut self.rows[d + p];
                for zb in 0..nb {
                    for za in 0..na {
                        row.push(joint[za * nb + zb]);
                    }
                }
            }
        }
        self.t.push(t);
    }

    pub(crate) fn nodes(&self) -> usize {
        self.t.len()
    }

    /// Compresses every view to `eps` (see the module doc).
    pub(crate) fn finish(self, eps: f64) -> Views {
        let d = self.sizes.len();
        let n = self.t.len();
        let views = self
            .rows
            .into_iter()
            .enumerate()
            .map(|(k, rows)| {
                let species = if k < d {
                    vec![k]
                } else {
                    let (a, b) = self.pairs[k - d];
                    vec![a, b]
                };
                compress(species, &rows, n, eps)
            })
            .collect();
        Views {
            t: self.t,
            sizes: self.sizes,
            views,
        }
    }
}

/// The low-rank form of the `n × m` row-major `rows` (see the module doc).
fn compress(species: Vec<usize>, rows: &[f64], n: usize, eps: f64) -> View {
    let m = rows.len() / n.max(1);
    let norms: Vec<f64> = rows
        .chunks_exact(m)
        .map(|r| r.iter().map(|x| x * x).sum::<f64>().sqrt())
        .collect();
    let scaled = Mat::from_fn(n, m, |j, z| {
        if norms[j] > 0.0 {
            rows[j * m + z] / norms[j]
        } else {
            0.0
        }
    });
    // Transposed when wide: the SVD of an m × n matrix with m ≫ n is the cheaper way
    // round, and the factors just swap.
    let (u, s, v) = if m > n {
        let f = thin_svd(scaled.transpose()).unwrap_or_else(|| exact_rank(&scaled));
        (f.v, f.s, f.u)
    } else {
        let f = thin_svd(scaled.as_ref()).unwrap_or_else(|| exact_rank(&scaled));
        (f.u, f.s, f.v)
    };
    // Smallest rank whose dropped tail is at most eps·√n (RMS row error ≤ eps).
    let budget = eps * eps * n as f64;
    let mut tail = 0.0;
    let mut rank = s.len();
    while rank > 0 && tail + s[rank - 1] * s[rank - 1] <= budget {
        tail += s[rank - 1] * s[rank - 1];
        rank -= 1;
    }
    let rank = rank.max(1).min(s.len());
    let time = (0..n)
        .flat_map(|j| (0..rank).map(move |q| (j, q)))
        .map(|(j, q)| norms[j] * u[(j, q)] * s[q])
        .collect();
    let values = (0..rank)
        .flat_map(|q| (0..m).map(move |z| (q, z)))
        .map(|(q, z)| v[(z, q)])
        .collect();
    View {
        species,
        rank,
        time,
        values,
    }
}

/// The full-rank fallback when the SVD iteration fails: `I · A` (rank n).
fn exact_rank(a: &Mat<f64>) -> crate::tensor::dense::Svd {
    let (n, m) = (a.nrows(), a.ncols());
    let k = n.min(m);
    crate::tensor::dense::Svd {
        u: Mat::from_fn(n, k, |i, j| if i == j { 1.0 } else { 0.0 }),
        s: vec![1.0; k],
        v: Mat::from_fn(m, k, |z, j| if j < n { a[(j, z)] } else { 0.0 }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth family of distributions over time is kept to the tolerance at the
    /// nodes, and read back between them by the cubic weights.
    #[test]
    fn compressed_views_reproduce_the_rows() {
        let m = 40;
        let t: Vec<f64> = (0..60).map(|j| 0.5 * j as f64).collect();
        let poisson = |lam: f64| -> Vec<f64> {
            let mut p = vec![(-lam).exp(); m];
            for z in 1..m {
                p[z] = p[z - 1] * lam / z as f64;
            }
            p
        };
        let rows: Vec<f64> = t.iter().flat_map(|&s| poisson(s * 0.6)).collect();
        let view = compress(vec![0], &rows, t.len(), 1e-7);
        assert!(view.rank < 30, "rank {}", view.rank);
        let views = Views {
            t: t.clone(),
            sizes: vec![m],
            views: vec![view],
        };
        views.check().expect("consistent");
        let mut coef = vec![0.0; views.max_rank()];
        let mut out = vec![0.0; m];
        for (j, &s) in t.iter().enumerate() {
            let (w, clamped) = views.time_weights(s);
            assert!(!clamped);
            views.views[0].eval_into(&w, &mut coef, &mut out);
            let err: f64 = out
                .iter()
                .zip(&rows[j * m..(j + 1) * m])
                .map(|(a, b)| (a - b).abs())
                .sum();
            assert!(err < 1e-5, "t = {s}: L1 {err}");
        }
        // Between nodes: the cubic interpolation of a smooth family.
        let (w, _) = views.time_weights(7.25);
        views.views[0].eval_into(&w, &mut coef, &mut out);
        let err: f64 = out
            .iter()
            .zip(poisson(7.25 * 0.6))
            .map(|(a, b)| (a - b).abs())
            .sum();
        assert!(err < 1e-3, "between nodes: L1 {err}");
        let (_, clamped) = views.time_weights(40.0);
        assert!(clamped);
    }

    #[test]
    fn check_names_the_wrong_view() {
        let views = Views {
            t: vec![0.0, 1.0],
            sizes: vec![3],
            views: vec![View {
                species: vec![0],
                rank: 1,
                time: vec![1.0, 1.0],
                values: vec![1.0, 0.0],
            }],
        };
        let e = views.check().expect_err("the values are short");
        assert!(e.contains("view 0"), "{e}");
    }
}
