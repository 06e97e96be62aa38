//! On-line evaluation of a CME meta-model: marginals and moments at any `(t, p)`
//! without solving anything.
//!
//! With `c_j = α_j F_t^j(t) Π_q F_q^j(p_q)` (the time and parameter stencils) and the
//! per-term sums `s_i^j = Σ_z F_i^j(z)`, the marginal of species `i` is
//!
//! `P_i(z) = Σ_j F_i^j(z) · c_j · Π_{k≠i} s_k^j`,
//!
//! and the covariance of species 0 and 1 uses the first moments `μ_i^j = Σ_z z F_i^j(z)`.
//! Cost: `O(N Σ_i m_i)` for N terms, no allocation beyond the output.

use thiserror::Error;

use super::moments::Moments;
use super::pgd::KIND;
use crate::axis::{Discretization, ParamValue};
use crate::separated::SeparatedModel;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum CmeModelError {
    #[error("the file holds a {0:?} model, not a gene-network (cme-probability) model")]
    WrongKind(String),
    #[error("the model has no time axis \"t\"")]
    NoTime,
    #[error("time {0} is not a finite value ≥ 0")]
    BadTime(f64),
    #[error("no parameter {name:?}; the model's parameters are {known}")]
    UnknownParameter { name: String, known: String },
    #[error("parameter {name} = {value}: expected a finite value")]
    BadParameter { name: String, value: f64 },
    #[error("evaluating: {0}")]
    Eval(String),
}

/// A loaded CME meta-model, ready to evaluate.
#[derive(Debug, Clone)]
pub struct CmeModel {
    model: SeparatedModel<f64>,
    /// Number of species axes (the first axes).
    species: usize,
    /// `sums[i][j]`, `firsts[i][j]`: Σ_z F_i^j(z) and Σ_z z F_i^j(z).
    sums: Vec<Vec<f64>>,
    firsts: Vec<Vec<f64>>,
}

/// What one evaluation gives.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    pub moments: Moments,
    /// The most negative marginal probability (0 if none is negative).
    pub most_negative: f64,
    /// Names of the values that lay outside the trained range and were clamped.
    pub clamped: Vec<String>,
}

impl CmeModel {
    pub fn new(model: SeparatedModel<f64>) -> Result<Self, CmeModelError> {
        if model.kind() != KIND {
            return Err(CmeModelError::WrongKind(model.kind().to_string()));
        }
        let species = model
            .axes()
            .iter()
            .position(|a| a.info.name == "t")
            .ok_or(CmeModelError::NoTime)?;
        let n = model.modes();
        let mut sums = Vec::new();
        let mut firsts = Vec::new();
        for axis in &model.axes()[..species] {
            let v = axis.values();
            let m = v.len() / n.max(1);
            let mut s = vec![0.0; n];
            let mut f = vec![0.0; n];
            for z in 0..m {
                for j in 0..n {
                    s[j] += v[z * n + j];
                    f[j] += z as f64 * v[z * n + j];
                }
            }
            sums.push(s);
            firsts.push(f);
        }
        Ok(CmeModel {
            model,
            species,
            sums,
            firsts,
        })
    }

    pub fn model(&self) -> &SeparatedModel<f64> {
        &self.model
    }

    pub fn species_names(&self) -> Vec<String> {
        self.model.axes()[..self.species]
            .iter()
            .map(|a| a.info.name.clone())
            .collect()
    }

    /// The truncation box: states per species axis (what an FSP check must use).
    pub fn box_sizes(&self) -> Vec<usize> {
        self.model.axes()[..self.species]
            .iter()
            .map(|a| a.info.discretization.node_count())
            .collect()
    }

    /// Names and ranges of the parameter coordinates.
    pub fn parameters(&self) -> Vec<(String, f64, f64)> {
        self.model.axes()[self.species + 1..]
            .iter()
            .map(|a| {
                let (lo, hi) = match &a.info.discretization {
                    Discretization::Grid { nodes } => (nodes[0], nodes[nodes.len() - 1]),
                    _ => (f64::NAN, f64::NAN),
                };
                (a.info.name.clone(), lo, hi)
            })
            .collect()
    }

    /// The trained time range's end.
    pub fn t_end(&self) -> f64 {
        match &self.model.axes()[self.species].info.discretization {
            Discretization::Grid { nodes } => nodes[nodes.len() - 1],
            _ => f64::NAN,
        }
    }

    /// Term coefficients `c_j` at time `t` and parameters `set` (name, value); parameters
    /// not given take the middle of their range. Uses the first `n` terms.
    fn coefficients(
        &self,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<(Vec<f64>, Vec<String>), CmeModelError> {
        if !(t.is_finite() && t >= 0.0) {
            return Err(CmeModelError::BadTime(t));
        }
        let params = self.parameters();
        for (name, value) in set {
            if !params.iter().any(|(p, _, _)| p == name) {
                return Err(CmeModelError::UnknownParameter {
                    name: name.clone(),
                    known: params
                        .iter()
                        .map(|p| p.0.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            }
            if !value.is_finite() {
                return Err(CmeModelError::BadParameter {
                    name: name.clone(),
                    value: *value,
                });
            }
        }
        // Time, then each parameter (the species axes are summed, not particularized).
        let mut values = vec![ParamValue::Scalar(t)];
        for (name, lo, hi) in &params {
            let v = set
                .iter()
                .rev()
                .find(|(p, _)| p == name)
                .map_or(0.5 * (lo + hi), |(_, v)| *v);
            values.push(ParamValue::Scalar(v));
        }
        let n = n.min(self.model.modes());
        let modes = self.model.modes();
        let mut c: Vec<f64> = self.model.spatial()[..n].to_vec();
        let mut clamped = Vec::new();
        for (axis, value) in self.model.axes()[self.species..].iter().zip(&values) {
            let st = axis
                .info
                .discretization
                .stencil(*value)
                .map_err(|e| CmeModelError::Eval(format!("{}: {e}", axis.info.name)))?;
            if st.clamped {
                clamped.push(axis.info.name.clone());
            }
            let v = axis.values();
            for (j, cj) in c.iter_mut().enumerate() {
                *cj *= (0..st.len)
                    .map(|s| st.weights[s] * v[st.nodes[s] as usize * modes + j])
                    .sum::<f64>();
            }
        }
        Ok((c, clamped))
    }

    /// Marginals and moments at time `t` and parameters `set`, from the first `n` terms.
    pub fn evaluate(
        &self,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<Evaluation, CmeModelError> {
        let (c, clamped) = self.coefficients(t, set, n)?;
        let n = c.len();
        let d = self.species;
        let modes = self.model.modes();
        let axes = self.model.axes();
        let mut marginals = Vec::with_capacity(d);
        let mut weight = vec![0.0; n];
        for i in 0..d {
            for (j, w) in weight.iter_mut().enumerate() {
                *w = c[j]
                    * (0..d)
                        .filter(|&k| k != i)
                        .map(|k| self.sums[k][j])
                        .product::<f64>();
            }
            let v = axes[i].values();
            let m = v.len() / modes;
            let marginal: Vec<f64> = (0..m)
                .map(|z| {
                    let row = &v[z * modes..z * modes + n];
                    row.iter().zip(&weight).map(|(a, b)| a * b).sum()
                })
                .collect();
            marginals.push(marginal);
        }
        let e01 = if d >= 2 {
            (0..n)
                .map(|j| {
                    c[j] * self.firsts[0][j]
                        * self.firsts[1][j]
                        * (2..d).map(|k| self.sums[k][j]).product::<f64>()
                })
                .sum()
        } else {
            0.0
        };
        let mass: f64 = marginals.first().map_or(0.0, |m| m.iter().sum());
        let most_negative = marginals.iter().flatten().copied().fold(0.0, f64::min);
        Ok(Evaluation {
            moments: Moments::from_marginals(t, marginals, e01, mass),
            most_negative,
            clamped,
        })
    }

    /// The joint distribution at `(t, p)` on the whole box (species 0 fastest), for
    /// checks against FSP on small boxes.
    pub fn joint(
        &self,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<Vec<f64>, CmeModelError> {
        let (c, _) = self.coefficients(t, set, n)?;
        let modes = self.model.modes();
        let axes = &self.model.axes()[..self.species];
        let sizes: Vec<usize> = axes.iter().map(|a| a.values().len() / modes).collect();
        let total: usize = sizes.iter().product();
        let mut out = vec![0.0; total];
        let mut z = vec![0usize; sizes.len()];
        for p in out.iter_mut() {
            *p = (0..c.len())
                .map(|j| {
                    c[j] * axes
                        .iter()
                        .zip(&z)
                        .map(|(a, &zi)| a.values()[zi * modes + j])
                        .product::<f64>()
                })
                .sum();
            for (zi, &m) in z.iter_mut().zip(&sizes) {
                *zi += 1;
                if *zi < m {
                    break;
                }
                *zi = 0;
            }
        }
        Ok(out)
    }
}
