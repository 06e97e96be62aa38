//! The log-likelihood of snapshot data at given rates: from a tensor-train meta-model
//! without solving, or by exact FSP.
//!
//! With `n_k(y)` cells seen in the observed state `y` at time `t_k` and `P_S(y; t, θ)`
//! the joint law of the observed species `S` (the others summed out),
//!
//! `ℓ(θ) = Σ_k Σ_y n_k(y) · ln P_S(y; t_k, θ)`.
//!
//! The meta-model's train runs `time · left species · parameters · right species`
//! ([`super::super::history::slot_order`]). The data fix the times and the states, so
//! everything but the parameter cores is contracted once per data set: each distinct
//! `(t_k, y_left)` gives a row vector `a` (time weights, then each left species' core at
//! its count, or summed over its box when unobserved), each distinct `y_right` a column
//! vector `b`. What is left at `θ` is `P = a · Π_q G_q(θ) · b` with every parameter core
//! `G_q(θ) = Σ_j w_j(θ_q) G_q[j]` a cubic Lagrange blend of four grid nodes.
//!
//! Where it fits the memory budget, the load goes one step further ([`Form::Table`]):
//! for every combination `c` of grid nodes it stores `Q[o, c] = a_o Π_q G_q[c_q] b_o`,
//! and an evaluation is `P_o = Σ_c W_c(θ) Q[o, c]` over the `4^m` combinations with
//! nonzero weight: 16 products an observation for two rates, a few microseconds for a
//! data set of a few hundred distinct states. Otherwise ([`Form::Direct`]) the
//! parameter cores are blended and multiplied at each `θ`.
//!
//! A meta-model's probability may be slightly negative or zero far in a tail where a
//! cell was seen: it is floored at [`FLOOR`], and the number of cells at the floor is
//! reported (many means the data lie where the model is not accurate).

use std::collections::HashMap;

use super::FitError;
use super::data::Snapshots;
use crate::cme::history::{History, Slot, lagrange_weights};
use crate::cme::network::Network;
use crate::tensor::tt::Core;

/// The smallest probability a likelihood term takes.
pub const FLOOR: f64 = 1e-12;

/// Largest number of precomputed values of a [`Form::Table`] (128 MB of f64).
const TABLE_BUDGET: usize = 16 << 20;

/// Data matched to a model's species and box: at each time, each distinct observed
/// state and its number of cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Observations {
    /// The network species index of each data column.
    pub columns: Vec<usize>,
    pub times: Vec<f64>,
    /// `hist[k]`: (state in column order, cells) at `times[k]`.
    pub hist: Vec<Vec<(Vec<u32>, u32)>>,
}

impl Observations {
    /// Matches `data` to a model with species `names` (network order), box `sizes`
    /// and time range `[0, t_end]`: every column a species, every count inside the
    /// box, every time inside the range.
    pub fn new(
        data: &Snapshots,
        names: &[String],
        sizes: &[usize],
        t_end: f64,
    ) -> Result<Self, FitError> {
        let columns = data
            .species
            .iter()
            .map(|s| {
                names
                    .iter()
                    .position(|n| n == s)
                    .ok_or_else(|| FitError::UnknownSpecies {
                        name: s.clone(),
                        known: names.join(", "),
                    })
            })
            .collect::<Result<Vec<usize>, _>>()?;
        for &t in &data.times {
            if t > t_end * (1.0 + 1e-12) {
                return Err(FitError::BeyondTime { t, t_end });
            }
        }
        let hist = data.histograms();
        for (k, h) in hist.iter().enumerate() {
            for (state, _) in h {
                for (c, (&z, &i)) in state.iter().zip(&columns).enumerate() {
                    if z as usize >= sizes[i] {
                        return Err(FitError::BeyondBox {
                            species: data.species[c].clone(),
                            count: z,
                            size: sizes[i],
                            t: data.times[k],
                        });
                    }
                }
            }
        }
        Ok(Observations {
            columns,
            times: data.times.clone(),
            hist,
        })
    }

    /// Cells in all.
    pub fn cells(&self) -> u64 {
        self.hist.iter().flatten().map(|(_, n)| u64::from(*n)).sum()
    }

    /// Distinct (time, state) pairs.
    pub fn distinct(&self) -> usize {
        self.hist.iter().map(Vec::len).sum()
    }

    /// The count of network species `i` in `state`, if observed.
    fn count(&self, state: &[u32], i: usize) -> Option<u32> {
        self.columns.iter().position(|&c| c == i).map(|c| state[c])
    }
}

/// A log-likelihood value and how many cells sat at [`FLOOR`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogLikelihood {
    pub value: f64,
    pub floored_cells: u64,
}

/// The data's log-likelihood as a function of a train's parameters (see the module
/// doc).
#[derive(Debug, Clone)]
pub struct MetaLikelihood {
    grids: Vec<Vec<f64>>,
    counts: Vec<f64>,
    form: Form,
}

#[derive(Debug, Clone)]
enum Form {
    /// `q[o · combos + c]`, combination `c = Σ_q j_q · strides[q]`.
    Table {
        strides: Vec<usize>,
        combos: usize,
        q: Vec<f64>,
    },
    /// Row vectors `left` (`rl` each), column vectors `right` (`rr` each), each
    /// observation's pair of them, and the parameter cores.
    Direct {
        rl: usize,
        rr: usize,
        left: Vec<f64>,
        right: Vec<f64>,
        pairs: Vec<(usize, usize)>,
        cores: Vec<Core>,
    },
}

/// The indices `z` of a core, or all of them (`None`: summed over).
fn indices(c: &Core, z: Option<u32>) -> std::ops::Range<usize> {
    match z {
        Some(z) => z as usize..z as usize + 1,
        None => 0..c.n,
    }
}

/// `v · G[z]` (or `v · Σ_z G[z]` with `z = None`): a row vector through a core.
fn row_through(v: &[f64], c: &Core, z: Option<u32>) -> Vec<f64> {
    let mut out = vec![0.0; c.r1];
    for z in indices(c, z) {
        for (a, &va) in v.iter().enumerate() {
            let row = &c.v[(a * c.n + z) * c.r1..][..c.r1];
            for (o, x) in out.iter_mut().zip(row) {
                *o += va * x;
            }
        }
    }
    out
}

/// `G[z] · v` (or `Σ_z G[z] · v`): a column vector through a core.
fn column_through(c: &Core, z: Option<u32>, v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; c.r0];
    for (a, o) in out.iter_mut().enumerate() {
        for z in indices(c, z) {
            let row = &c.v[(a * c.n + z) * c.r1..][..c.r1];
            *o += row.iter().zip(v).map(|(x, y)| x * y).sum::<f64>();
        }
    }
    out
}

/// The nonzero cubic Lagrange weights of `x` on `grid`.
fn weights(grid: &[f64], x: f64) -> Vec<(usize, f64)> {
    lagrange_weights(grid, x, 4)
        .0
        .into_iter()
        .enumerate()
        .filter(|(_, w)| *w != 0.0)
        .collect()
}

impl MetaLikelihood {
    /// Prepares `obs` on the train `h` (see the module doc for what is contracted).
    pub fn new(h: &History, obs: &Observations) -> Result<Self, FitError> {
        Self::with_budget(h, obs, TABLE_BUDGET)
    }

    /// As [`Self::new`], tabling only when the table holds at most `budget` values.
    pub fn with_budget(h: &History, obs: &Observations, budget: usize) -> Result<Self, FitError> {
        let cores = &h.tt.cores;
        let params: Vec<usize> = h
            .order
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s, Slot::Param(_)))
            .map(|(k, _)| k + 1)
            .collect();
        let (Some(&first), Some(&last)) = (params.first(), params.last()) else {
            return Err(FitError::NoParameters);
        };
        if last - first + 1 != params.len() {
            return Err(FitError::Layout);
        }
        // Outside `first..=last` every core is a species.
        let species_at = |k: usize| match h.order[k - 1] {
            Slot::Species(i) => Some(i),
            Slot::Param(_) => None,
        };
        // Row vectors of each (time, left state), column vectors of each right state.
        let (mut left, mut left_keys) = (Vec::new(), HashMap::new());
        let (mut right, mut right_keys) = (Vec::new(), HashMap::new());
        let mut pairs = Vec::new();
        let mut counts = Vec::new();
        for (k, hist) in obs.hist.iter().enumerate() {
            let time = cores[0].contract(&lagrange_weights(&h.t, obs.times[k], 4).0);
            for (state, n) in hist {
                let lkey: (usize, Vec<Option<u32>>) = (
                    k,
                    (1..first)
                        .map(|c| species_at(c).and_then(|i| obs.count(state, i)))
                        .collect(),
                );
                let next = left_keys.len();
                let li = *left_keys.entry(lkey.clone()).or_insert(next);
                if li == next {
                    let mut v = time.clone();
                    for (c, z) in (1..first).zip(&lkey.1) {
                        v = row_through(&v, &cores[c], *z);
                    }
                    left.push(v);
                }
                let rkey: Vec<Option<u32>> = (last + 1..cores.len())
                    .map(|c| species_at(c).and_then(|i| obs.count(state, i)))
                    .collect();
                let next = right_keys.len();
                let ri = *right_keys.entry(rkey.clone()).or_insert(next);
                if ri == next {
                    let mut v = vec![1.0];
                    for (c, z) in (last + 1..cores.len()).zip(&rkey).rev() {
                        v = column_through(&cores[c], *z, &v);
                    }
                    right.push(v);
                }
                pairs.push((li, ri));
                counts.push(f64::from(*n));
            }
        }
        let grids: Vec<Vec<f64>> = h.params.iter().map(|(_, g)| g.clone()).collect();
        let pcores: Vec<Core> = params.iter().map(|&k| cores[k].clone()).collect();
        let combos: usize = pcores.iter().map(|c| c.n).product();
        let rl = pcores[0].r0;
        let rr = pcores[pcores.len() - 1].r1;
        // Meet in the middle: the left vectors go through the parameter cores before a
        // split, the right vectors through those after it, and each table entry is one
        // dot product across the split's bond. The split is the cheapest by count.
        let m = pcores.len();
        let bond = |s: usize| if s == m { rr } else { pcores[s].r0 };
        let nodes =
            |r: std::ops::Range<usize>| -> usize { pcores[r].iter().map(|c| c.n).product() };
        let cost = |s: usize| -> f64 {
            let through_left: f64 = (0..s)
                .map(|q| (left.len() * nodes(0..q + 1) * pcores[q].r0 * pcores[q].r1) as f64)
                .sum();
            let through_right: f64 = (s..m)
                .map(|q| (right.len() * nodes(q..m) * pcores[q].r0 * pcores[q].r1) as f64)
                .sum();
            through_left + through_right + (pairs.len() * combos * bond(s)) as f64
        };
        let split = (0..=m)
            .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
            .unwrap_or(0);
        let table_values = combos * pairs.len()
            + bond(split) * (left.len() * nodes(0..split) + right.len() * nodes(split..m));
        let form = if table_values <= budget {
            // Combination index: earlier cores slower, `c = c_left · nodes(split..) + c_right`.
            let mut lefts: Vec<Vec<Vec<f64>>> = left.iter().map(|a| vec![a.clone()]).collect();
            for c in &pcores[..split] {
                for list in &mut lefts {
                    *list = list
                        .iter()
                        .flat_map(|v| (0..c.n).map(move |j| row_through(v, c, Some(j as u32))))
                        .collect();
                }
            }
            let mut rights: Vec<Vec<Vec<f64>>> = right.iter().map(|b| vec![b.clone()]).collect();
            for c in pcores[split..].iter().rev() {
                for list in &mut rights {
                    let mut next = Vec::with_capacity(c.n * list.len());
                    for j in 0..c.n {
                        for v in list.iter() {
                            next.push(column_through(c, Some(j as u32), v));
                        }
                    }
                    *list = next;
                }
            }
            let strides: Vec<usize> = (0..m).map(|q| nodes(q + 1..m)).collect();
            let mut q = Vec::with_capacity(pairs.len() * combos);
            for &(li, ri) in &pairs {
                for a in &lefts[li] {
                    q.extend(
                        rights[ri]
                            .iter()
                            .map(|v| a.iter().zip(v).map(|(x, y)| x * y).sum::<f64>()),
                    );
                }
            }
            Form::Table { strides, combos, q }
        } else {
            Form::Direct {
                rl,
                rr,
                left: left.concat(),
                right: right.concat(),
                pairs,
                cores: pcores,
            }
        };
        Ok(MetaLikelihood {
            grids,
            counts,
            form,
        })
    }

    /// Whether every node combination is tabled (the fast form).
    pub fn tabled(&self) -> bool {
        matches!(self.form, Form::Table { .. })
    }

    /// The joint probability of each (time, state) observation at `theta` (one value
    /// per parameter axis, model order), into `out`.
    pub fn probabilities(&self, theta: &[f64], out: &mut Vec<f64>) {
        let w: Vec<Vec<(usize, f64)>> = self
            .grids
            .iter()
            .zip(theta)
            .map(|(g, &x)| weights(g, x))
            .collect();
        out.clear();
        match &self.form {
            Form::Table { strides, combos, q } => {
                // The active combinations and their weights.
                let mut active: Vec<(usize, f64)> = vec![(0, 1.0)];
                for (wq, &s) in w.iter().zip(strides) {
                    active = active
                        .iter()
                        .flat_map(|&(c, x)| wq.iter().map(move |&(j, y)| (c + j * s, x * y)))
                        .collect();
                }
                out.extend(
                    q.chunks_exact(*combos)
                        .map(|row| active.iter().map(|&(c, x)| x * row[c]).sum::<f64>()),
                );
            }
            Form::Direct {
                rl,
                rr,
                left,
                right,
                pairs,
                cores,
            } => {
                // M = Π_q G_q(θ), rl × rr, row-major.
                let mut m: Vec<f64> = Vec::new();
                let mut rows = 0;
                for (c, wq) in cores.iter().zip(&w) {
                    let mut blend = vec![0.0; c.r0 * c.r1];
                    for &(j, x) in wq {
                        for a in 0..c.r0 {
                            let src = &c.v[(a * c.n + j) * c.r1..][..c.r1];
                            for (o, y) in blend[a * c.r1..][..c.r1].iter_mut().zip(src) {
                                *o += x * y;
                            }
                        }
                    }
                    if m.is_empty() {
                        m = blend;
                        rows = c.r0;
                    } else {
                        let inner = c.r0;
                        let mut next = vec![0.0; rows * c.r1];
                        for r in 0..rows {
                            for i in 0..inner {
                                let x = m[r * inner + i];
                                for (o, y) in next[r * c.r1..][..c.r1]
                                    .iter_mut()
                                    .zip(&blend[i * c.r1..][..c.r1])
                                {
                                    *o += x * y;
                                }
                            }
                        }
                        m = next;
                    }
                }
                let mut am: HashMap<usize, Vec<f64>> = HashMap::new();
                for &(li, ri) in pairs {
                    let row = am.entry(li).or_insert_with(|| {
                        let a = &left[li * rl..][..*rl];
                        (0..*rr)
                            .map(|b| (0..*rl).map(|i| a[i] * m[i * rr + b]).sum())
                            .collect()
                    });
                    let b = &right[ri * rr..][..*rr];
                    out.push(row.iter().zip(b).map(|(x, y)| x * y).sum());
                }
            }
        }
    }

    /// `ℓ(θ)` with `scratch` for the probabilities.
    pub fn log_likelihood(&self, theta: &[f64], scratch: &mut Vec<f64>) -> LogLikelihood {
        self.probabilities(theta, scratch);
        sum_logs(scratch, &self.counts)
    }
}

fn sum_logs(p: &[f64], counts: &[f64]) -> LogLikelihood {
    let (mut value, mut floored_cells) = (0.0, 0);
    for (&p, &n) in p.iter().zip(counts) {
        if p < FLOOR || p.is_nan() {
            floored_cells += n as u64;
            value += n * FLOOR.ln();
        } else {
            value += n * p.ln();
        }
    }
    LogLikelihood {
        value,
        floored_cells,
    }
}

/// `ℓ` by exact FSP on the box `sizes` at the network's parameter values `p` (every
/// parameter of the network, in its order): one solve to the last data time.
pub fn exact_log_likelihood(
    network: &Network,
    p: &[f64],
    sizes: &[usize],
    obs: &Observations,
) -> Result<LogLikelihood, FitError> {
    let solved = crate::cme::fsp::solve_on(network, p, sizes, &obs.times)?;
    let (mut probs, mut counts) = (Vec::new(), Vec::new());
    for (joint, hist) in solved.joint.iter().zip(&obs.hist) {
        // The observed species' marginal (first column fastest), then a lookup.
        let observed: Vec<usize> = obs.columns.iter().map(|&i| sizes[i]).collect();
        let mut marginal = vec![0.0; observed.iter().product()];
        let mut z = vec![0usize; sizes.len()];
        for &p in joint {
            let mut idx = 0;
            for (&i, &m) in obs.columns.iter().zip(&observed).rev() {
                idx = idx * m + z[i];
            }
            marginal[idx] += p;
            for (zi, &m) in z.iter_mut().zip(sizes) {
                *zi += 1;
                if *zi < m {
                    break;
                }
                *zi = 0;
            }
        }
        for (state, n) in hist {
            let mut idx = 0;
            for (&y, &m) in state.iter().zip(&observed).rev() {
                idx = idx * m + y as usize;
            }
            probs.push(marginal[idx]);
            counts.push(f64::from(*n));
        }
    }
    Ok(sum_logs(&probs, &counts))
}
