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

use super::greedy::KIND;
use super::history::{History, Slot};
use super::moments::Moments;
use super::tteval::TrainEvaluator;
use super::views::Views;
use crate::axis::{Discretization, ParamValue};
use crate::separated::{AxisInfo, FieldInfo, ModelMeta, Provenance, SeparatedModel};
use crate::tensor::tt::{Core, Tt};

/// The kind string of a tensor-train CME meta-model file.
pub const TRAIN_KIND: &str = "cme-tensor-train";
/// The kind string of a views model (marginals and chosen joints over time).
pub const VIEWS_KIND: &str = "cme-views";

/// The provenance of a tensor-train meta-model: method, network, box, steps and the
/// options, hashed so a later run can tell whether its inputs changed.
pub fn train_provenance(
    network: &super::network::Network,
    history: &History,
    steps: usize,
    options: &super::ttsolve::Options,
) -> Provenance {
    let mut prov = Provenance::now(
        "cme tensor train: BDF2 steps by ALS with enrichment, mass balanced, history rounded",
        &format!(
            "network {}; box {:?}; {} steps to t = {}; {options:?}",
            network.name, history.sizes, steps, options.t_end
        ),
        options.compress_eps,
        Vec::new(),
    );
    prov.input_hash = format!(
        "{:016x}",
        xxhash_rust::xxh3::xxh3_64(format!("{network:?}{options:?}").as_bytes())
    );
    prov
}

/// The file description of a solved history: axes in core order (t, then species as
/// discrete axes and parameters as grids, in the solver's slot order).
pub fn train_meta(
    network: &super::Network,
    history: &History,
    provenance: Provenance,
) -> ModelMeta {
    let mut axes = Vec::new();
    for slot in &history.order {
        axes.push(match *slot {
            Slot::Species(i) => AxisInfo {
                name: network.species[i].name.clone(),
                unit: "copies".into(),
                discretization: Discretization::Discrete {
                    labels: (0..history.sizes[i]).map(|z| z.to_string()).collect(),
                },
            },
            Slot::Param(q) => {
                let (index, grid) = &history.params[q];
                AxisInfo {
                    name: network.parameters[*index].name.clone(),
                    unit: String::new(),
                    discretization: Discretization::Grid {
                        nodes: grid.clone(),
                    },
                }
            }
        });
    }
    probability_meta(TRAIN_KIND, &history.t, axes, provenance)
}

/// A CME model's description: the probability field over the time grid `t` and
/// `axes` after it.
fn probability_meta(
    kind: &str,
    t: &[f64],
    axes: Vec<AxisInfo>,
    provenance: Provenance,
) -> ModelMeta {
    let time = AxisInfo {
        name: "t".into(),
        unit: "time".into(),
        discretization: Discretization::Grid { nodes: t.to_vec() },
    };
    ModelMeta {
        kind: kind.into(),
        field: FieldInfo {
            name: "probability".into(),
            unit: "1".into(),
            components: 1,
            node_ids: Vec::new(),
        },
        axes: std::iter::once(time).chain(axes).collect(),
        provenance,
        tradeoff: Vec::new(),
        geometry: Default::default(),
    }
}

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
    #[error("tensor-train model: {0}")]
    BadTrain(&'static str),
    #[error("tensor-train model: axis {0} is neither species nor grid")]
    TrainAxis(String),
    #[error("a tensor-train model needs CmeModel::from_train")]
    NeedsTrain,
    #[error("views model: {0}")]
    BadViews(String),
    #[error(
        "the joint of species {a} and {b} is not stored in this views model; it holds {stored}"
    )]
    PairNotStored { a: usize, b: usize, stored: String },
    #[error("a views model keeps marginals and chosen joints, not the joint over every species")]
    NoJoint,
    #[error("species pair ({a}, {b}): expected two different species of the {species}")]
    Pair { a: usize, b: usize, species: usize },
    #[error("evaluating parameter {name}: {error}")]
    Axis {
        name: String,
        error: crate::axis::AxisError,
    },
}

/// A loaded CME meta-model, ready to evaluate: a separated sum (greedy PGD) or a
/// tensor train ([`super::ttsolve`]).
#[derive(Debug, Clone)]
pub struct CmeModel {
    repr: Repr,
}

#[derive(Debug, Clone)]
enum Repr {
    Separated(Separated),
    Train(Train),
    Views(ViewsModel),
}

#[derive(Debug, Clone)]
struct ViewsModel {
    meta: ModelMeta,
    views: Views,
    species: Vec<String>,
    /// `Σ z_0 z_1 Vᵀ[k, ·]` of the (0, 1) joint's rows: `E[z_0 z_1]` is its product
    /// with the time coefficients.
    e01_rows: Vec<f64>,
}

#[derive(Debug, Clone)]
struct Separated {
    model: SeparatedModel<f64>,
    /// Number of species axes (the first axes).
    species: usize,
    /// `sums[i][j]`, `firsts[i][j]`: Σ_z F_i^j(z) and Σ_z z F_i^j(z).
    sums: Vec<Vec<f64>>,
    firsts: Vec<Vec<f64>>,
}

#[derive(Debug, Clone)]
struct Train {
    meta: ModelMeta,
    history: History,
    tables: TrainEvaluator,
    species: Vec<String>,
    params: Vec<String>,
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
    /// A tensor-train model as [`super::ttsolve::solve`] leaves it, described by `meta`
    /// (see [`train_meta`]).
    pub fn from_train(meta: ModelMeta, cores: Vec<Core>) -> Result<Self, CmeModelError> {
        if meta.kind != TRAIN_KIND {
            return Err(CmeModelError::WrongKind(meta.kind.clone()));
        }
        if meta.axes.first().map(|a| a.name.as_str()) != Some("t") || cores.len() != meta.axes.len()
        {
            return Err(CmeModelError::NoTime);
        }
        let nodes = |a: &AxisInfo| match &a.discretization {
            Discretization::Grid { nodes } => Some(nodes.clone()),
            _ => None,
        };
        let t = nodes(&meta.axes[0]).ok_or(CmeModelError::BadTrain("time axis is not a grid"))?;
        let (mut order, mut sizes, mut species, mut params, mut grids) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for a in &meta.axes[1..] {
            match &a.discretization {
                Discretization::Discrete { labels } => {
                    order.push(Slot::Species(species.len()));
                    sizes.push(labels.len());
                    species.push(a.name.clone());
                }
                Discretization::Grid { nodes } => {
                    order.push(Slot::Param(params.len()));
                    grids.push((params.len(), nodes.clone()));
                    params.push(a.name.clone());
                }
                _ => return Err(CmeModelError::TrainAxis(a.name.clone())),
            }
        }
        if species.is_empty() {
            return Err(CmeModelError::BadTrain("no species axis"));
        }
        let history = History {
            sizes,
            t,
            params: grids,
            order,
            tt: Tt { cores },
        };
        Ok(CmeModel {
            repr: Repr::Train(Train {
                meta,
                tables: TrainEvaluator::new(&history),
                history,
                species,
                params,
            }),
        })
    }

    /// A views model (see [`super::views`]), described by `meta` (see [`views_meta`]).
    pub fn from_views(meta: ModelMeta, views: Views) -> Result<Self, CmeModelError> {
        if meta.kind != VIEWS_KIND {
            return Err(CmeModelError::WrongKind(meta.kind.clone()));
        }
        views.check().map_err(CmeModelError::BadViews)?;
        let species: Vec<String> = meta.axes.iter().skip(1).map(|a| a.name.clone()).collect();
        if meta.axes.first().map(|a| a.name.as_str()) != Some("t") {
            return Err(CmeModelError::NoTime);
        }
        if species.len() != views.sizes.len() {
            return Err(CmeModelError::BadViews(format!(
                "{} species axes for {} species in the views",
                species.len(),
                views.sizes.len()
            )));
        }
        let e01_rows = match views.pair_view(0, 1) {
            Some(v) => {
                let (n0, m) = (views.sizes[0], v.len());
                v.values
                    .chunks_exact(m)
                    .map(|row| {
                        row.iter()
                            .enumerate()
                            .map(|(z, x)| ((z % n0) * (z / n0)) as f64 * x)
                            .sum()
                    })
                    .collect()
            }
            None => Vec::new(),
        };
        Ok(CmeModel {
            repr: Repr::Views(ViewsModel {
                meta,
                views,
                species,
                e01_rows,
            }),
        })
    }

    /// The species pairs whose joint the model can give: `None` for any pair (a
    /// separated sum or a train), the stored ones for a views model.
    pub fn pairs(&self) -> Option<Vec<(usize, usize)>> {
        match &self.repr {
            Repr::Views(v) => Some(v.views.pairs()),
            _ => None,
        }
    }

    /// The tensor-train history, for a model that keeps one (what a fit reads).
    pub fn history(&self) -> Option<&History> {
        match &self.repr {
            Repr::Train(t) => Some(&t.history),
            _ => None,
        }
    }

    /// The numbers stored (terms × axis sizes, or the train's cores).
    pub fn stored_values(&self) -> usize {
        match &self.repr {
            Repr::Separated(s) => s.model.array_bytes() / 8,
            Repr::Train(t) => t.history.tt.len(),
            Repr::Views(v) => v.views.stored_values(),
        }
    }

    /// "separated, N terms" or "tensor train, ranks […]".
    pub fn describe(&self) -> String {
        match &self.repr {
            Repr::Separated(s) => format!("separated, {} terms", s.model.modes()),
            Repr::Train(t) => format!("tensor train, ranks {:?}", t.history.tt.ranks()),
            Repr::Views(v) => format!(
                "views over {} times: {} marginals, {} joints, ranks ≤ {}",
                v.views.t.len(),
                v.views.sizes.len(),
                v.views.pairs().len(),
                v.views.max_rank()
            ),
        }
    }

    pub fn new(model: SeparatedModel<f64>) -> Result<Self, CmeModelError> {
        if model.kind() != KIND {
            if model.kind() == TRAIN_KIND {
                return Err(CmeModelError::NeedsTrain);
            }
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
            repr: Repr::Separated(Separated {
                model,
                species,
                sums,
                firsts,
            }),
        })
    }

    pub fn meta(&self) -> ModelMeta {
        match &self.repr {
            Repr::Separated(s) => s.model.meta(),
            Repr::Train(t) => t.meta.clone(),
            Repr::Views(v) => v.meta.clone(),
        }
    }

    pub fn species_names(&self) -> Vec<String> {
        match &self.repr {
            Repr::Separated(s) => s.model.axes()[..s.species]
                .iter()
                .map(|a| a.info.name.clone())
                .collect(),
            Repr::Train(t) => t.species.clone(),
            Repr::Views(v) => v.species.clone(),
        }
    }

    /// The truncation box: states per species axis (what an FSP check must use).
    pub fn box_sizes(&self) -> Vec<usize> {
        match &self.repr {
            Repr::Separated(s) => s.model.axes()[..s.species]
                .iter()
                .map(|a| a.info.discretization.node_count())
                .collect(),
            Repr::Train(t) => t.history.sizes.clone(),
            Repr::Views(v) => v.views.sizes.clone(),
        }
    }

    /// Names and ranges of the parameter coordinates.
    pub fn parameters(&self) -> Vec<(String, f64, f64)> {
        let range = |d: &Discretization| match d {
            Discretization::Grid { nodes } => (nodes[0], nodes[nodes.len() - 1]),
            _ => (f64::NAN, f64::NAN),
        };
        match &self.repr {
            Repr::Separated(s) => s.model.axes()[s.species + 1..]
                .iter()
                .map(|a| {
                    let (lo, hi) = range(&a.info.discretization);
                    (a.info.name.clone(), lo, hi)
                })
                .collect(),
            Repr::Train(t) => t
                .params
                .iter()
                .zip(&t.history.params)
                .map(|(name, (_, g))| (name.clone(), g[0], g[g.len() - 1]))
                .collect(),
            Repr::Views(_) => Vec::new(),
        }
    }

    /// The trained time range's end.
    pub fn t_end(&self) -> f64 {
        match &self.repr {
            Repr::Separated(s) => match &s.model.axes()[s.species].info.discretization {
                Discretization::Grid { nodes } => nodes[nodes.len() - 1],
                _ => f64::NAN,
            },
            Repr::Train(t) => t.history.t[t.history.t.len() - 1],
            Repr::Views(v) => v.views.t[v.views.t.len() - 1],
        }
    }

    /// Checks `t` and `set`; returns each parameter's value (given, or the middle of its
    /// range) in model order.
    fn resolve(&self, t: f64, set: &[(String, f64)]) -> Result<Vec<f64>, CmeModelError> {
        if !(t.is_finite() && t >= 0.0) {
            return Err(CmeModelError::BadTime(t));
        }
        let params = self.parameters();
        for (name, value) in set {
            if !params.iter().any(|(p, _, _)| p == name) {
                let known = if params.is_empty() {
                    // An empty list would read as a cut-off message.
                    "none: every rate was fixed when it was built (a parameter given a \
                     `range` in the network file becomes a coordinate)"
                        .to_string()
                } else {
                    params
                        .iter()
                        .map(|p| p.0.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                return Err(CmeModelError::UnknownParameter {
                    name: name.clone(),
                    known,
                });
            }
            if !value.is_finite() {
                return Err(CmeModelError::BadParameter {
                    name: name.clone(),
                    value: *value,
                });
            }
        }
        Ok(params
            .iter()
            .map(|(name, lo, hi)| {
                set.iter()
                    .rev()
                    .find(|(p, _)| p == name)
                    .map_or(0.5 * (lo + hi), |(_, v)| *v)
            })
            .collect())
    }

    /// The parameter values at which to evaluate the train, and the names of clamped
    /// values.
    fn train_point(
        &self,
        tr: &Train,
        t: f64,
        set: &[(String, f64)],
    ) -> Result<(Vec<f64>, Vec<String>), CmeModelError> {
        let values = self.resolve(t, set)?;
        let h = &tr.history;
        let mut clamped = Vec::new();
        if t > h.t[h.t.len() - 1] {
            clamped.push("t".to_string());
        }
        for ((name, (_, g)), &v) in tr.params.iter().zip(&h.params).zip(&values) {
            if v < g[0] || v > g[g.len() - 1] {
                clamped.push(name.clone());
            }
        }
        Ok((values, clamped))
    }

    /// Term coefficients `c_j` at time `t` and parameters `set` (name, value); parameters
    /// not given take the middle of their range. Uses the first `n` terms.
    fn coefficients(
        &self,
        sep: &Separated,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<(Vec<f64>, Vec<String>), CmeModelError> {
        // Time, then each parameter (the species axes are summed, not particularized).
        let values: Vec<ParamValue> = std::iter::once(t)
            .chain(self.resolve(t, set)?)
            .map(ParamValue::Scalar)
            .collect();
        let n = n.min(sep.model.modes());
        let modes = sep.model.modes();
        let mut c: Vec<f64> = sep.model.spatial()[..n].to_vec();
        let mut clamped = Vec::new();
        for (axis, value) in sep.model.axes()[sep.species..].iter().zip(&values) {
            let st =
                axis.info
                    .discretization
                    .stencil(*value)
                    .map_err(|error| CmeModelError::Axis {
                        name: axis.info.name.clone(),
                        error,
                    })?;
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

    /// Marginals and moments at time `t` and parameters `set`, from the first `n` terms
    /// (all of a tensor train).
    pub fn evaluate(
        &self,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<Evaluation, CmeModelError> {
        let sep = match &self.repr {
            Repr::Separated(s) => s,
            Repr::Views(v) => return self.evaluate_views(v, t, set),
            Repr::Train(tr) => {
                let (p, clamped) = self.train_point(tr, t, set)?;
                let v = tr.tables.evaluate(&tr.history, t, &p);
                let most_negative = v.marginals.iter().flatten().copied().fold(0.0, f64::min);
                return Ok(Evaluation {
                    moments: Moments::from_marginals(t, v.marginals, v.e01, v.mass),
                    most_negative,
                    clamped,
                });
            }
        };
        let (c, clamped) = self.coefficients(sep, t, set, n)?;
        let n = c.len();
        let d = sep.species;
        let modes = sep.model.modes();
        let axes = sep.model.axes();
        let mut marginals = Vec::with_capacity(d);
        let mut weight = vec![0.0; n];
        for i in 0..d {
            for (j, w) in weight.iter_mut().enumerate() {
                *w = c[j]
                    * (0..d)
                        .filter(|&k| k != i)
                        .map(|k| sep.sums[k][j])
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
                    c[j] * sep.firsts[0][j]
                        * sep.firsts[1][j]
                        * (2..d).map(|k| sep.sums[k][j]).product::<f64>()
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

    fn evaluate_views(
        &self,
        v: &ViewsModel,
        t: f64,
        set: &[(String, f64)],
    ) -> Result<Evaluation, CmeModelError> {
        self.resolve(t, set)?;
        let (w, beyond) = v.views.time_weights(t);
        let mut coef = vec![0.0; v.views.max_rank()];
        let marginals: Vec<Vec<f64>> = v.views.views[..v.views.sizes.len()]
            .iter()
            .map(|view| {
                let mut out = vec![0.0; view.len()];
                view.eval_into(&w, &mut coef, &mut out);
                out
            })
            .collect();
        let e01 = match v.views.pair_view(0, 1) {
            Some(view) => {
                view.coefficients(&w, &mut coef);
                coef[..view.rank]
                    .iter()
                    .zip(&v.e01_rows)
                    .map(|(c, e)| c * e)
                    .sum()
            }
            None => 0.0,
        };
        let mass: f64 = marginals.first().map_or(0.0, |m| m.iter().sum());
        let most_negative = marginals.iter().flatten().copied().fold(0.0, f64::min);
        Ok(Evaluation {
            moments: Moments::from_marginals(t, marginals, e01, mass),
            most_negative,
            clamped: if beyond {
                vec!["t".to_string()]
            } else {
                Vec::new()
            },
        })
    }

    /// The joint distribution of species `a` and `b` at `(t, p)` on their boxes (`a`
    /// fastest), every other species summed out in the meta-model (never a dense array
    /// over all species).
    pub fn pair_joint(
        &self,
        t: f64,
        set: &[(String, f64)],
        a: usize,
        b: usize,
    ) -> Result<Vec<f64>, CmeModelError> {
        let sizes = self.box_sizes();
        if a == b || a >= sizes.len() || b >= sizes.len() {
            return Err(CmeModelError::Pair {
                a,
                b,
                species: sizes.len(),
            });
        }
        let (lo, hi) = (a.min(b), a.max(b));
        let joint = match &self.repr {
            Repr::Views(v) => {
                self.resolve(t, set)?;
                let view =
                    v.views
                        .pair_view(lo, hi)
                        .ok_or_else(|| CmeModelError::PairNotStored {
                            a,
                            b,
                            stored: v
                                .views
                                .pairs()
                                .iter()
                                .map(|&(x, y)| format!("{}–{}", v.species[x], v.species[y]))
                                .collect::<Vec<_>>()
                                .join(", "),
                        })?;
                let (w, _) = v.views.time_weights(t);
                let mut coef = vec![0.0; view.rank];
                let mut out = vec![0.0; view.len()];
                view.eval_into(&w, &mut coef, &mut out);
                out
            }
            Repr::Train(tr) => {
                let (p, _) = self.train_point(tr, t, set)?;
                tr.history.particularize(t, &p).keep_pair(lo, hi).full()
            }
            Repr::Separated(sep) => {
                let (c, _) = self.coefficients(sep, t, set, usize::MAX)?;
                let modes = sep.model.modes();
                let axes = sep.model.axes();
                let (vl, vh) = (axes[lo].values(), axes[hi].values());
                let w: Vec<f64> = (0..c.len())
                    .map(|j| {
                        c[j] * (0..sizes.len())
                            .filter(|&k| k != lo && k != hi)
                            .map(|k| sep.sums[k][j])
                            .product::<f64>()
                    })
                    .collect();
                let mut out = vec![0.0; sizes[lo] * sizes[hi]];
                for zh in 0..sizes[hi] {
                    for zl in 0..sizes[lo] {
                        out[zh * sizes[lo] + zl] = (0..c.len())
                            .map(|j| w[j] * vl[zl * modes + j] * vh[zh * modes + j])
                            .sum();
                    }
                }
                out
            }
        };
        if a < b {
            return Ok(joint);
        }
        // Asked with the higher species first: transpose to make `a` fastest.
        let (nl, nh) = (sizes[lo], sizes[hi]);
        let mut out = vec![0.0; nl * nh];
        for zh in 0..nh {
            for zl in 0..nl {
                out[zl * nh + zh] = joint[zh * nl + zl];
            }
        }
        Ok(out)
    }

    /// The joint distribution at `(t, p)` on the whole box (species 0 fastest), for
    /// checks against FSP on small boxes.
    pub fn joint(
        &self,
        t: f64,
        set: &[(String, f64)],
        n: usize,
    ) -> Result<Vec<f64>, CmeModelError> {
        let sep = match &self.repr {
            Repr::Separated(s) => s,
            Repr::Train(tr) => {
                let (p, _) = self.train_point(tr, t, set)?;
                return Ok(tr.history.particularize(t, &p).full());
            }
            Repr::Views(_) => return Err(CmeModelError::NoJoint),
        };
        let (c, _) = self.coefficients(sep, t, set, n)?;
        let modes = sep.model.modes();
        let axes = &sep.model.axes()[..sep.species];
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

/// Why a CME model file could not be loaded.
#[derive(Debug, Error)]
pub enum CmeLoadError {
    #[error(transparent)]
    File(#[from] crate::file::FileError),
    #[error("{path}: {source}")]
    Model {
        path: std::path::PathBuf,
        source: CmeModelError,
    },
}

/// Loads a CME meta-model file of any layout (separated, tensor train, views).
pub fn load(path: &std::path::Path) -> Result<CmeModel, CmeLoadError> {
    load_from(path, None)
}

/// [`load`] from bytes in memory (an asset bundled into an app, a fuzzer's input).
pub fn load_from_bytes(bytes: &[u8]) -> Result<CmeModel, CmeLoadError> {
    load_from(std::path::Path::new("<memory>"), Some(bytes))
}

fn load_from(path: &std::path::Path, bytes: Option<&[u8]>) -> Result<CmeModel, CmeLoadError> {
    use crate::file::{self, Layout};
    let header = match bytes {
        Some(b) => file::read_header_from_bytes(b)?,
        None => file::read_header(path)?,
    };
    let model = match header.layout {
        Layout::TensorTrain { .. } => {
            let (meta, cores) = match bytes {
                Some(b) => file::load_train_from_bytes(b)?,
                None => file::load_train(path)?,
            };
            CmeModel::from_train(meta, cores)
        }
        Layout::Views { .. } => {
            let (meta, views) = match bytes {
                Some(b) => file::load_views_from_bytes(b)?,
                None => file::load_views(path)?,
            };
            Views::from_file(&meta, views).and_then(|v| CmeModel::from_views(meta, v))
        }
        _ => CmeModel::new(
            match bytes {
                Some(b) => file::load_any_from_bytes(b)?,
                None => file::load_any(path)?,
            }
            .into_f64(),
        ),
    };
    model.map_err(|source| CmeLoadError::Model {
        path: path.to_path_buf(),
        source,
    })
}

/// Saves a solved history (see [`train_meta`]) atomically.
pub fn save_train(
    network: &super::Network,
    history: &History,
    provenance: Provenance,
    path: &std::path::Path,
) -> Result<(), crate::file::FileError> {
    crate::file::save_train(
        &train_meta(network, history, provenance),
        &history.tt.cores,
        path,
    )
}

/// The file description of a views model: the time grid, then each species as a
/// discrete axis (network order).
pub fn views_meta(network: &super::Network, views: &Views, provenance: Provenance) -> ModelMeta {
    let mut axes = Vec::new();
    for (s, &m) in network.species.iter().zip(&views.sizes) {
        axes.push(AxisInfo {
            name: s.name.clone(),
            unit: "copies".into(),
            discretization: Discretization::Discrete {
                labels: (0..m).map(|z| z.to_string()).collect(),
            },
        });
    }
    probability_meta(VIEWS_KIND, &views.t, axes, provenance)
}

/// Reading views back belongs with the model that loads them (`views` knows nothing
/// of files or of this error).
impl Views {
    /// The views of a file's contents (see [`crate::file::load_views`]), checked.
    pub fn from_file(
        meta: &ModelMeta,
        views: Vec<(crate::file::ViewShape, Vec<f64>, Vec<f64>)>,
    ) -> Result<Views, CmeModelError> {
        use crate::axis::Discretization;
        let t = match meta.axes.first().map(|a| &a.discretization) {
            Some(Discretization::Grid { nodes }) => nodes.clone(),
            _ => return Err(CmeModelError::NoTime),
        };
        let sizes = meta.axes[1..]
            .iter()
            .map(|a| a.discretization.node_count())
            .collect();
        let views = Views {
            t,
            sizes,
            views: views
                .into_iter()
                .map(|(shape, time, values)| super::views::View {
                    species: shape.species.iter().map(|&i| i as usize).collect(),
                    rank: shape.rank as usize,
                    time,
                    values,
                })
                .collect(),
        };
        views.check().map_err(CmeModelError::BadViews)?;
        Ok(views)
    }
}
