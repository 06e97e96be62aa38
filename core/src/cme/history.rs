//! The tensor-train CME solution over (time, species…, parameters…) and how it is read:
//! what each core holds and the Lagrange weights of a point on a grid. Shared by the
//! off-line solver ([`super::ttsolve`]) and the on-line evaluator ([`super::tteval`]).

use crate::tensor::tt::Tt;

/// What a core of the state's train holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// Species `i` (network order).
    Species(usize),
    /// Parameter axis `q` (index into [`History::params`]).
    Param(usize),
}

/// Core order of the state: the parameter axes sit between the first half of the
/// species and the rest. A parameter usually multiplies reactions of several species
/// (the cascade's δ degrades z1 and z2); in the middle it couples to both through short
/// bonds, and the big species cores stay at the ends, where their local systems are
/// `n × r` instead of `r × n × r`.
pub fn slot_order(species: usize, params: usize) -> Vec<Slot> {
    let half = species.div_ceil(2);
    (0..half)
        .map(Slot::Species)
        .chain((0..params).map(Slot::Param))
        .chain((half..species).map(Slot::Species))
        .collect()
}

/// The solution: a tensor train over (t, slots…).
#[derive(Debug, Clone, PartialEq)]
pub struct History {
    pub sizes: Vec<usize>,
    pub t: Vec<f64>,
    /// `(parameter index in the network, grid)` of each parameter axis.
    pub params: Vec<(usize, Vec<f64>)>,
    /// What cores `1…` of `tt` hold (core 0 is time).
    pub order: Vec<Slot>,
    pub tt: Tt,
}

/// Local Lagrange weights of `x` on `nodes` through the `points` nodes nearest the
/// interval holding `x` (2: linear, 4: cubic); clamped to the ends, `true` if `x` lay
/// outside. Cubic interpolation turns the O(h²) error of hat functions into O(h⁴), which
/// is what the parameter axes need: at δ = 0.02 the cascade's stationary z1 ~ 50 ± 7
/// moves by 1.1 copies between neighbouring grid points.
pub fn lagrange_weights(nodes: &[f64], x: f64, points: usize) -> (Vec<f64>, bool) {
    let n = nodes.len();
    let outside = n > 1 && (x < nodes[0] || x > nodes[n - 1]);
    let x = x.clamp(nodes[0], nodes[n - 1]);
    let p = points.clamp(1, n);
    let mut w = vec![0.0; n];
    if let Some(j) = nodes.iter().position(|&v| v == x) {
        w[j] = 1.0;
        return (w, outside);
    }
    let i = nodes.partition_point(|&v| v <= x).clamp(1, n - 1) - 1; // x in [i, i+1]
    let first = (i + 1).saturating_sub(p / 2).min(n - p);
    let idx: Vec<usize> = (first..first + p).collect();
    for &j in &idx {
        w[j] = idx
            .iter()
            .filter(|&&m| m != j)
            .map(|&m| (x - nodes[m]) / (nodes[j] - nodes[m]))
            .product();
    }
    (w, outside)
}
