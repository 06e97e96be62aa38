//! Fast on-line evaluation of a tensor-train history: marginals and moments at `(t, p)`
//! without forming the species train.
//!
//! With `l_k` the row vector entering core `k` from the left (time weights, then each
//! core summed over its index, or weighted by the Lagrange weights of its parameter) and
//! `r_k` the column vector leaving it to the right, species `k` has the marginal
//! `π_k(z) = l_k G_k[z] r_k`. Evaluated directly this costs `r_{k−1}·m_k·r_k` per call:
//! 46 × 220 × 203 ≈ 2·10⁶ for the cascade's z1, about 2 ms. But `r_k` depends only on the
//! parameter axes to the right of `k` (the time core is the first), and is linear in
//! each of their weight vectors; so for every combination `c` of their grid nodes the
//! load precomputes `H_c = G_k ×₃ r_k(c)` (`r_{k−1} × m_k`), and a call sums the few
//! combinations whose cubic Lagrange weights are nonzero:
//! `π_k(z) = Σ_c w_c · l_k H_c[·, z]`, 4 × 46 × 220 for z1. Cores whose combinations
//! would exceed the memory budget fall back to the direct contraction.
//!
//! The left vectors are tabled the same way from the other end: `l_k` depends only on
//! the time and parameter cores before `k`, linearly in each weight vector, so with the
//! budget left the load stores `l_k(c)` for every node combination `c` of those cores,
//! and a call sums the active ones instead of crossing each parameter core (on the
//! cascade: 16 vectors of 34 in place of 4 × 203 × 34, which halves the call).
//!
//! The species tables `H_c` are stored in f32 (sums in f64). A scene evaluates right
//! after drawing a frame, which on a software rasterizer has pushed them out of cache,
//! so their bytes set the cost: measured in the cascade scene at 1280×720, the median
//! evaluation went from 44–48 µs to 37–42 µs, and the marginals moved by at most
//! 1.4·10⁻⁸ (the model's own error is 10⁻⁴).

use super::history::{History, Slot, lagrange_weights};
use crate::tensor::tt::Core;

/// Largest number of precomputed values over all cores (32 MB of f64).
const BUDGET_VALUES: usize = 4 << 20;

/// Precomputed contractions of one species core with every right vector.
#[derive(Debug, Clone)]
struct Fixed {
    /// Parameter cores right of this one: (core index, nodes, combination stride).
    params: Vec<(usize, usize, usize)>,
    /// `h[c]`: an `r0 × n` block per node combination `c = Σ j_q·stride_q`, in f32
    /// (see the module doc).
    h: Vec<f32>,
}

/// The left vectors entering one core (and the `E[z_0 z_1]` chain beside them) for
/// every node combination of the time and parameter cores before it.
#[derive(Debug, Clone)]
struct Prefix {
    /// Time and parameter cores left of this one: (core index, nodes, stride).
    params: Vec<(usize, usize, usize)>,
    /// Length of each vector.
    r: usize,
    left: Vec<f64>,
    cross: Vec<f64>,
}

/// `Σ_c w_c · table[c]` over the active node combinations `c = Σ j_q·stride_q` of
/// `params` (each a core index, its node count and stride), blocks of `r` values.
fn combine(
    params: &[(usize, usize, usize)],
    weights: &[Vec<(usize, f64)>],
    table: &[f64],
    r: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; r];
    let mut idx = vec![0usize; params.len()];
    loop {
        let (mut combo, mut w) = (0, 1.0);
        for (q, &(core, _, stride)) in params.iter().enumerate() {
            let (j, wj) = weights[core][idx[q]];
            combo += j * stride;
            w *= wj;
        }
        for (o, y) in out.iter_mut().zip(&table[combo * r..(combo + 1) * r]) {
            *o += w * y;
        }
        let mut q = 0;
        while q < idx.len() {
            idx[q] += 1;
            if idx[q] < weights[params[q].0].len() {
                break;
            }
            idx[q] = 0;
            q += 1;
        }
        if q == idx.len() {
            return out;
        }
    }
}

/// A history with its evaluation tables.
#[derive(Debug, Clone)]
pub struct TrainEvaluator {
    /// `Σ_z G_k[z]` (`r0 × r1`, row-major) of each species core; empty for others.
    sums: Vec<Vec<f64>>,
    /// `Σ_z z·G_k[z]` of each species core.
    firsts: Vec<Vec<f64>>,
    fixed: Vec<Option<Fixed>>,
    /// `prefix[k]`: the vectors entering core `k` (`k = d`: the whole contraction).
    prefix: Vec<Option<Prefix>>,
}

/// Marginals (network species order), `E[z_0 z_1]` and the total mass.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainValues {
    pub marginals: Vec<Vec<f64>>,
    pub e01: f64,
    pub mass: f64,
}

/// `m · v` for an `rows × cols` row-major `m`.
fn mat_vec(m: &[f64], rows: usize, cols: usize, v: &[f64]) -> Vec<f64> {
    (0..rows)
        .map(|a| {
            m[a * cols..(a + 1) * cols]
                .iter()
                .zip(v)
                .map(|(x, y)| x * y)
                .sum()
        })
        .collect()
}

/// `v · m` for an `rows × cols` row-major `m`.
fn vec_mat(v: &[f64], m: &[f64], rows: usize, cols: usize) -> Vec<f64> {
    let mut out = vec![0.0; cols];
    for (a, &x) in v.iter().enumerate().take(rows) {
        if x == 0.0 {
            continue;
        }
        for (o, y) in out.iter_mut().zip(&m[a * cols..(a + 1) * cols]) {
            *o += x * y;
        }
    }
    out
}

/// `v · G[·, j, ·]` summed over the nonzero weights.
fn vec_core(v: &[f64], c: &Core, w: &[(usize, f64)]) -> Vec<f64> {
    let mut out = vec![0.0; c.r1];
    for &(j, wj) in w {
        for (a, &x) in v.iter().enumerate() {
            let s = wj * x;
            if s == 0.0 {
                continue;
            }
            let row = &c.v[(a * c.n + j) * c.r1..(a * c.n + j + 1) * c.r1];
            for (o, y) in out.iter_mut().zip(row) {
                *o += s * y;
            }
        }
    }
    out
}

/// `Σ_j w_j G[·, j, ·] · v`.
fn core_vec(c: &Core, w: &[(usize, f64)], v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; c.r0];
    for &(j, wj) in w {
        for (a, o) in out.iter_mut().enumerate() {
            let row = &c.v[(a * c.n + j) * c.r1..(a * c.n + j + 1) * c.r1];
            *o += wj * row.iter().zip(v).map(|(x, y)| x * y).sum::<f64>();
        }
    }
    out
}

fn nonzero(w: &[f64]) -> Vec<(usize, f64)> {
    w.iter()
        .enumerate()
        .filter(|(_, x)| **x != 0.0)
        .map(|(j, x)| (j, *x))
        .collect()
}

impl TrainEvaluator {
    /// Builds the tables for `h` (see the module docs).
    pub fn new(h: &History) -> Self {
        Self::with_budget(h, BUDGET_VALUES)
    }

    /// As [`Self::new`], with at most `budget` precomputed values.
    pub fn with_budget(h: &History, budget: usize) -> Self {
        let cores = &h.tt.cores;
        let d = cores.len();
        let mut sums = vec![Vec::new(); d];
        let mut firsts = vec![Vec::new(); d];
        for (k, slot) in h.order.iter().enumerate() {
            if let Slot::Species(_) = slot {
                let c = &cores[k + 1];
                sums[k + 1] = c.contract(&vec![1.0; c.n]);
                firsts[k + 1] = c.contract(&(0..c.n).map(|z| z as f64).collect::<Vec<_>>());
            }
        }
        // Walk from the right end with every node combination's right vector.
        let mut fixed = vec![None; d];
        let mut right: Vec<Vec<f64>> = vec![vec![1.0]];
        let mut params: Vec<(usize, usize, usize)> = Vec::new();
        let mut budget = budget;
        for k in (1..d).rev() {
            let c = &cores[k];
            match h.order[k - 1] {
                Slot::Species(_) => {
                    let size = right.len() * c.r0 * c.n;
                    if size <= budget {
                        budget -= size;
                        let mut hv = Vec::with_capacity(size);
                        for r in &right {
                            hv.extend(c.contract_right(r).into_iter().map(|x| x as f32));
                        }
                        fixed[k] = Some(Fixed {
                            params: params.clone(),
                            h: hv,
                        });
                    }
                    right = right
                        .iter()
                        .map(|r| mat_vec(&sums[k], c.r0, c.r1, r))
                        .collect();
                }
                Slot::Param(_) => {
                    let stride = right.len();
                    if stride * c.n * c.r0 > budget {
                        // Too many combinations to the left of here: stop precomputing.
                        break;
                    }
                    let mut next = Vec::with_capacity(stride * c.n);
                    for j in 0..c.n {
                        for r in &right {
                            next.push(core_vec(c, &[(j, 1.0)], r));
                        }
                    }
                    right = next;
                    params.insert(0, (k, c.n, stride));
                }
            }
        }
        let prefix = prefixes(cores, &sums, &firsts, budget);
        TrainEvaluator {
            sums,
            firsts,
            fixed,
            prefix,
        }
    }

    /// Values kept in the tables.
    pub fn table_values(&self) -> usize {
        self.fixed
            .iter()
            .flatten()
            .map(|f| f.h.len())
            .chain(
                self.prefix
                    .iter()
                    .flatten()
                    .map(|p| p.left.len() + p.cross.len()),
            )
            .chain(self.sums.iter().chain(&self.firsts).map(Vec::len))
            .sum()
    }

    /// Marginals and moments at `t` and parameter values `p` (one per parameter axis,
    /// already checked), with cubic Lagrange interpolation clamped to the grids.
    pub fn evaluate(&self, h: &History, t: f64, p: &[f64]) -> TrainValues {
        let cores = &h.tt.cores;
        let d = cores.len();
        // Nonzero weights of each parameter core.
        let mut weights: Vec<Vec<(usize, f64)>> = vec![Vec::new(); d];
        weights[0] = nonzero(&lagrange_weights(&h.t, t, 4).0);
        for (k, slot) in h.order.iter().enumerate() {
            if let Slot::Param(q) = *slot {
                weights[k + 1] = nonzero(&lagrange_weights(&h.params[q].1, p[q], 4).0);
            }
        }
        // Left vectors: left[k] enters core k; the E[z0 z1] chain alongside.
        let mut left = vec![vec![1.0]];
        let mut cross = vec![1.0];
        let mut species_seen = 0;
        for k in 0..d {
            let c = &cores[k];
            if let Some(pre) = &self.prefix[k + 1] {
                // Precomputed for every combination of the nodes to the left.
                species_seen += usize::from(!self.sums[k].is_empty());
                left.push(combine(&pre.params, &weights, &pre.left, pre.r));
                cross = combine(&pre.params, &weights, &pre.cross, pre.r);
                continue;
            }
            let (l, x) = if self.sums[k].is_empty() {
                (
                    vec_core(&left[k], c, &weights[k]),
                    vec_core(&cross, c, &weights[k]),
                )
            } else {
                let m = if species_seen < 2 {
                    &self.firsts[k]
                } else {
                    &self.sums[k]
                };
                species_seen += 1;
                (
                    vec_mat(&left[k], &self.sums[k], c.r0, c.r1),
                    vec_mat(&cross, m, c.r0, c.r1),
                )
            };
            left.push(l);
            cross = x;
        }
        let e01 = if species_seen >= 2 { cross[0] } else { 0.0 };
        // Right vectors, only where a core has no table.
        let need_right = (1..d).any(|k| !self.sums[k].is_empty() && self.fixed[k].is_none());
        let right: Vec<Vec<f64>> = if need_right {
            let mut right = vec![vec![1.0]; d];
            for k in (1..d - 1).rev() {
                let c = &cores[k + 1];
                right[k] = if self.sums[k + 1].is_empty() {
                    core_vec(c, &weights[k + 1], &right[k + 1])
                } else {
                    mat_vec(&self.sums[k + 1], c.r0, c.r1, &right[k + 1])
                };
            }
            right
        } else {
            Vec::new()
        };
        let mut marginals = Vec::new();
        for k in 1..d {
            if self.sums[k].is_empty() {
                continue;
            }
            let c = &cores[k];
            let l = &left[k];
            let mut m = vec![0.0; c.n];
            match &self.fixed[k] {
                Some(f) => {
                    // Every active node combination: odometer over the parameters' weights.
                    let mut idx = vec![0usize; f.params.len()];
                    loop {
                        let (mut combo, mut w) = (0, 1.0);
                        for (q, &(core, _, stride)) in f.params.iter().enumerate() {
                            let (j, wj) = weights[core][idx[q]];
                            combo += j * stride;
                            w *= wj;
                        }
                        let block = &f.h[combo * c.r0 * c.n..(combo + 1) * c.r0 * c.n];
                        for (a, &la) in l.iter().enumerate() {
                            let s = w * la;
                            if s == 0.0 {
                                continue;
                            }
                            for (o, &y) in m.iter_mut().zip(&block[a * c.n..(a + 1) * c.n]) {
                                *o += s * f64::from(y);
                            }
                        }
                        let mut q = 0;
                        while q < idx.len() {
                            idx[q] += 1;
                            if idx[q] < weights[f.params[q].0].len() {
                                break;
                            }
                            idx[q] = 0;
                            q += 1;
                        }
                        if q == idx.len() {
                            break;
                        }
                    }
                }
                None => {
                    let g = c.contract_right(&right[k]);
                    m = vec_mat(l, &g, c.r0, c.n);
                }
            }
            marginals.push(m);
        }
        let mass = marginals.first().map_or(0.0, |m| m.iter().sum());
        TrainValues {
            marginals,
            e01,
            mass,
        }
    }
}

/// The left tables from core 0 rightwards while they fit in `budget` values: at a
/// time or parameter core the combinations multiply by its nodes, at a species core
/// each vector is multiplied by the core's sum (the chain by its first moments for the
/// first two species). The cascade (ranks 45, 203, 34) keeps 2.3·10⁶ values, and an
/// evaluation then adds 16 vectors of 34 instead of crossing the 203 × 64 × 34
/// parameter core.
fn prefixes(
    cores: &[Core],
    sums: &[Vec<f64>],
    firsts: &[Vec<f64>],
    mut budget: usize,
) -> Vec<Option<Prefix>> {
    let d = cores.len();
    let mut out = vec![None; d + 1];
    let (mut lefts, mut crosses) = (vec![vec![1.0]], vec![vec![1.0]]);
    let mut params: Vec<(usize, usize, usize)> = Vec::new();
    let mut species_seen = 0;
    for k in 0..d {
        let c = &cores[k];
        let combos = if sums[k].is_empty() {
            lefts.len() * c.n
        } else {
            lefts.len()
        };
        let size = 2 * combos * c.r1;
        if size > budget {
            break;
        }
        budget -= size;
        if sums[k].is_empty() {
            let stride = lefts.len();
            let step = |vs: &[Vec<f64>]| -> Vec<Vec<f64>> {
                (0..c.n)
                    .flat_map(|j| vs.iter().map(move |v| vec_core(v, c, &[(j, 1.0)])))
                    .collect()
            };
            lefts = step(&lefts);
            crosses = step(&crosses);
            params.push((k, c.n, stride));
        } else {
            let m = if species_seen < 2 {
                &firsts[k]
            } else {
                &sums[k]
            };
            species_seen += 1;
            lefts = lefts
                .iter()
                .map(|v| vec_mat(v, &sums[k], c.r0, c.r1))
                .collect();
            crosses = crosses.iter().map(|v| vec_mat(v, m, c.r0, c.r1)).collect();
        }
        out[k + 1] = Some(Prefix {
            params: params.clone(),
            r: c.r1,
            left: lefts.concat(),
            cross: crosses.concat(),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cme::history::slot_order;
    use crate::rng::Rng;
    use crate::tensor::tt::Tt;

    /// The same values from the particularized train, for checks.
    fn reference(h: &History, t: f64, p: &[f64]) -> TrainValues {
        let x: Tt = h.particularize(t, p);
        let marginals = x.marginals();
        let w: Vec<Vec<f64>> = x
            .cores
            .iter()
            .enumerate()
            .map(|(k, c)| {
                (0..c.n)
                    .map(|z| if k < 2 { z as f64 } else { 1.0 })
                    .collect()
            })
            .collect();
        let w: Vec<&[f64]> = w.iter().map(|v| v.as_slice()).collect();
        let e01 = if x.cores.len() >= 2 {
            x.contract_all(&w)
        } else {
            0.0
        };
        let mass = marginals[0].iter().sum();
        TrainValues {
            marginals,
            e01,
            mass,
        }
    }

    /// A random history over (t, 3 species, 2 parameters) in solver order.
    fn history(seed: u64) -> History {
        let mut rng = Rng::seed(seed);
        let sizes = vec![7, 5, 6];
        let order = slot_order(3, 2);
        let grids = vec![
            (0, vec![0.1, 0.2, 0.35, 0.5, 0.6]),
            (2, vec![1.0, 2.0, 4.0, 8.0]),
        ];
        let t: Vec<f64> = (0..9).map(|i| f64::from(i) * 0.5).collect();
        let mut dims = vec![t.len()];
        dims.extend(order.iter().map(|s| match *s {
            Slot::Species(i) => sizes[i],
            Slot::Param(q) => grids[q].1.len(),
        }));
        let ranks = [3, 4, 2, 5, 3];
        let cores = (0..dims.len())
            .map(|k| {
                let r0 = if k == 0 { 1 } else { ranks[k - 1] };
                let r1 = if k + 1 == dims.len() { 1 } else { ranks[k] };
                let mut c = Core::zeros(r0, dims[k], r1);
                for x in &mut c.v {
                    *x = rng.uniform() - 0.3;
                }
                c
            })
            .collect();
        History {
            sizes,
            t,
            params: grids,
            order,
            tt: Tt { cores },
        }
    }

    /// `E[z_0 z_1]` to round-off (f64 sums); marginals and the mass (the first
    /// marginal's sum) to the f32 tables' precision, a few units of 2⁻²⁴ of the
    /// largest value.
    fn close(a: &TrainValues, b: &TrainValues) -> bool {
        let scale = b.mass.abs().max(1.0);
        let near = |x: f64, y: f64| (x - y).abs() <= 1e-11 * scale.max(y.abs());
        a.marginals.len() == b.marginals.len()
            && a.marginals.iter().zip(&b.marginals).all(|(x, y)| {
                let peak = y.iter().fold(scale, |m, v| m.max(v.abs()));
                x.len() == y.len() && x.iter().zip(y).all(|(p, q)| (p - q).abs() <= 1e-6 * peak)
            })
            && near(a.e01, b.e01)
            && (a.mass - b.mass).abs() <= 1e-6 * scale
    }

    #[test]
    fn tables_match_the_particularized_train_on_and_off_nodes() {
        let h = history(11);
        let full = TrainEvaluator::new(&h);
        // A budget that fits the right-hand cores only, and none at all.
        let partial = TrainEvaluator::with_budget(&h, 40);
        let none = TrainEvaluator::with_budget(&h, 0);
        assert!(full.table_values() > partial.table_values());
        assert!(partial.table_values() > none.table_values());
        let mut rng = Rng::seed(5);
        let mut points = vec![
            (0.0, vec![0.1, 1.0]),
            (4.0, vec![0.6, 8.0]),
            (1.5, vec![0.35, 2.0]),
        ];
        for _ in 0..20 {
            points.push((
                rng.range(-0.5, 4.5),
                vec![rng.range(0.0, 0.7), rng.range(0.5, 9.0)],
            ));
        }
        for (t, p) in points {
            let want = reference(&h, t, &p);
            for e in [&full, &partial, &none] {
                let got = e.evaluate(&h, t, &p);
                assert!(close(&got, &want), "t {t}, p {p:?}: {got:?} vs {want:?}");
            }
        }
    }
}
