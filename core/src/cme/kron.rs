//! The CME generator as a short sum of Kronecker products — the form a separated (PGD)
//! solver works with.
//!
//! For reaction `r` with change vector `ν_r` and propensity `k_r Π_q p_q Π_i f_{r,i}(z_i)`:
//!
//! `A = Σ_r k_r Π_q p_q ( ⊗_i S_{ν_{r,i}} D_{r,i}  −  ⊗_i D_{r,i} )`,
//!
//! `D_{r,i} = diag(f_{r,i}(0..m_i−1))` (the product of reaction r's factors of species
//! i; the identity where it has none) and `S_ν` the shift that moves probability from `z` to `z + ν`, dropping
//! what would leave the box (the FSP leak). Each 1-D factor is an `m_i × m_i` matrix
//! with at most one non-zero per column, stored as (row, value) per column.
//!
//! Parameters on a range (the extra coordinates) multiply their terms by `diag(p_grid)`
//! on the parameter's own axis; that factor is kept in [`KronTerm::params`] for the
//! solver to apply.

use super::network::Network;
use crate::tensor::Sparse1d;

/// One 1-D factor: for each column j, `Some((row, value))` or `None` (a zero column).
#[derive(Debug, Clone, PartialEq)]
pub struct Factor1d {
    pub cols: Vec<Option<(usize, f64)>>,
}

impl Factor1d {
    /// `y = F x`.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for (j, c) in self.cols.iter().enumerate() {
            if let Some((i, v)) = c {
                y[*i] += v * x[j];
            }
        }
    }
}

/// `coef · Π_q p_q · ⊗_i factors[i]`.
#[derive(Debug, Clone, PartialEq)]
pub struct KronTerm {
    pub coef: f64,
    /// Parameters multiplying the term (indices into the network's parameters).
    pub params: Vec<usize>,
    pub factors: Vec<Factor1d>,
}

/// The generator's Kronecker terms on the box `sizes` (two per reaction).
pub fn generator_terms(network: &Network, sizes: &[usize]) -> Vec<KronTerm> {
    let mut out = Vec::with_capacity(2 * network.reactions.len());
    for re in &network.reactions {
        let diag = |i: usize| -> Vec<f64> {
            (0..sizes[i])
                .map(|z| re.species_factor(i, z as f64))
                .collect()
        };
        let shifted: Vec<Factor1d> = (0..sizes.len())
            .map(|i| {
                let d = diag(i);
                let nu = i64::from(re.change[i]);
                Factor1d {
                    cols: (0..sizes[i])
                        .map(|j| {
                            let to = j as i64 + nu;
                            (to >= 0 && to < sizes[i] as i64).then_some((to as usize, d[j]))
                        })
                        .collect(),
                }
            })
            .collect();
        let diagonal: Vec<Factor1d> = (0..sizes.len())
            .map(|i| Factor1d {
                cols: diag(i)
                    .into_iter()
                    .enumerate()
                    .map(|(j, v)| Some((j, v)))
                    .collect(),
            })
            .collect();
        out.push(KronTerm {
            coef: re.constant,
            params: re.params.clone(),
            factors: shifted,
        });
        out.push(KronTerm {
            coef: -re.constant,
            params: re.params.clone(),
            factors: diagonal,
        });
    }
    out
}

/// `y = A x` for a rank-one `x = ⊗_i x_i`, returned as rank-one terms `(scale, ⊗_i y_i)`
/// with the parameters at values `p` (one term per Kronecker term).
pub fn apply_rank_one(terms: &[KronTerm], p: &[f64], x: &[Vec<f64>]) -> Vec<(f64, Vec<Vec<f64>>)> {
    terms
        .iter()
        .map(|t| {
            let scale = t.coef * t.params.iter().map(|&q| p[q]).product::<f64>();
            let ys = t
                .factors
                .iter()
                .zip(x)
                .map(|(f, xi)| {
                    let mut y = vec![0.0; xi.len()];
                    f.apply(xi, &mut y);
                    y
                })
                .collect();
            (scale, ys)
        })
        .collect()
}

/// A 1-D Kronecker factor as a sparse matrix.
pub fn sparse_of(f: &Factor1d) -> Sparse1d {
    let m = f.cols.len();
    Sparse1d::from_triplets(
        m,
        m,
        f.cols
            .iter()
            .enumerate()
            .filter_map(|(j, c)| c.map(|(i, v)| (i, j, v))),
    )
}
