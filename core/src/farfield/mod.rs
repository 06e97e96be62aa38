//! The far field of a nodal-load vademecum: hierarchical low-rank blocks of what the
//! separated modes leave.
//!
//! The surface response map `G_S` of an elastic body is the discrete form of an
//! operator of order −1 on a 2-D surface: its singular values decay only like
//! `k^{-1/2}`, so a global rank-N sum carries a truncation error that falls slowly with
//! N, spread over the whole surface (it is not only under the tool). The same map is
//! nevertheless *locally* low rank: the block coupling a patch of load nodes with a
//! patch of surface nodes far from it (relative to the patches' sizes) is the restriction
//! of a smooth kernel and is compressed to a few terms (the hierarchical-matrix
//! argument). So the remainder `R = G_S − X_S Yᵀ` is stored as
//!
//! - dense 3×3 blocks where the patches are close (the near field's band), and
//! - for each well-separated pair of patches `(ρ, γ)`, a low-rank block,
//!
//! over cluster trees of the surface nodes and of the load nodes. Two forms exist:
//!
//! - [`FarBlocks`] (format version 4): every block stores its own `R[ρ, γ] ≈ U Vᵀ`;
//! - [`NestedFar`] (version 6, what the builder writes): the load side of every block
//!   is expressed in a basis of its column patch, and a patch's basis is its children's
//!   bases times a small transfer matrix, so a load node's coefficients are stored once
//!   instead of once per block on its path; the blocks of one row patch share a basis
//!   of their row side where that saves numbers. Version 5 ([`NestedFarV5`]) had the
//!   column bases only and opens as a `NestedFar` without shared row bases.
//!
//! A probe touches the few load nodes under its disk; both forms add the blocks of the
//! patches holding them to the rows of their row patches, allocation-free.

mod flat;
mod nested;
mod nested_v5;

use thiserror::Error;

pub use flat::FarBlocks;
pub use nested::{MAX_BASIS, NestedFar};
pub use nested_v5::NestedFarV5;

/// Why stored far-field blocks are inconsistent with their model.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FarFieldError {
    #[error("far field: {what} has {found} entries, expected {expected}")]
    Length {
        what: &'static str,
        found: usize,
        expected: usize,
    },
    #[error("far field: row {entry} names field node {node}, the model has {nodes}")]
    NoSuchNode {
        entry: usize,
        node: u32,
        nodes: usize,
    },
    #[error("far field: {what} pointers must rise from 0 (at {at})")]
    Pointers { what: &'static str, at: usize },
    #[error("far field: cluster {cluster} names parent {parent}; a parent must come first")]
    Parent { cluster: usize, parent: u32 },
    #[error("far field: a stored factor holds a non-finite value")]
    NotFinite,
}

/// Largest rank of one block of the flat form (its on-line accumulator's width).
pub const MAX_RANK: usize = 32;

/// A stored far field in either form.
#[derive(Debug, Clone, PartialEq)]
pub enum FarField {
    Flat(Box<FarBlocks>),
    Nested(Box<NestedFar>),
}

impl FarField {
    /// Truncation tolerance the blocks were built with (unit-column scale).
    pub fn tolerance(&self) -> f64 {
        match self {
            FarField::Flat(f) => f.tolerance,
            FarField::Nested(f) => f.tolerance,
        }
    }

    pub fn blocks(&self) -> usize {
        match self {
            FarField::Flat(f) => f.blocks(),
            FarField::Nested(f) => f.blocks(),
        }
    }

    /// Stored bytes.
    pub fn bytes(&self) -> usize {
        match self {
            FarField::Flat(f) => f.bytes(),
            FarField::Nested(f) => f.bytes(),
        }
    }

    /// Checks every length and index against `load_nodes` and `field_nodes`.
    pub fn validate(&self, load_nodes: usize, field_nodes: usize) -> Result<(), FarFieldError> {
        match self {
            FarField::Flat(f) => f.validate(load_nodes, field_nodes),
            FarField::Nested(f) => f.validate(load_nodes, field_nodes),
        }
    }

    /// Adds `Σ_j w_j R[·, j] t` to `out` (rows `3x + d` of the model's field nodes).
    /// Allocation-free.
    pub fn add(&self, shares: &[(u32, f64)], mix: [f64; 3], out: &mut [f64]) {
        match self {
            FarField::Flat(f) => f.add(shares, mix, out),
            FarField::Nested(f) => f.add(shares, mix, out),
        }
    }

    /// The blocks without their terms at or below `tolerance` (the accuracy knob).
    pub fn truncated(&self, tolerance: f64) -> FarField {
        match self {
            FarField::Flat(f) => FarField::Flat(Box::new(f.truncated(tolerance))),
            FarField::Nested(f) => FarField::Nested(Box::new(f.truncated(tolerance))),
        }
    }

    /// Renumbers the field nodes (`new_index[old]`, `u32::MAX` = dropped).
    pub fn remap_nodes(&mut self, new_index: &[u32]) {
        match self {
            FarField::Flat(f) => f.remap_nodes(new_index),
            FarField::Nested(f) => f.remap_nodes(new_index),
        }
    }
}

/// Renumbers the field nodes of low-rank blocks whose row factor (3 rows per field
/// node, `rank[b]` columns, row-major) sits at `factor[factor_ptr[b]..]`; rows whose
/// `new_index` is `u32::MAX` leave their blocks. Shared by both forms.
fn remap_block_rows(
    new_index: &[u32],
    rank: &[u32],
    row_ptr: &mut Vec<u32>,
    rows: &mut Vec<u32>,
    factor_ptr: &mut Vec<u32>,
    factor: &mut Vec<f32>,
) {
    let mut new_row_ptr = vec![0u32];
    let mut new_rows = Vec::new();
    let mut new_ptr = vec![0u32];
    let mut new_factor = Vec::new();
    for (b, &k) in rank.iter().enumerate() {
        let k = k as usize;
        let fb = &factor[factor_ptr[b] as usize..factor_ptr[b + 1] as usize];
        let rb = &rows[row_ptr[b] as usize..row_ptr[b + 1] as usize];
        for (i, &x) in rb.iter().enumerate() {
            let to = new_index.get(x as usize).copied().unwrap_or(u32::MAX);
            if to != u32::MAX {
                new_rows.push(to);
                new_factor.extend_from_slice(&fb[3 * i * k..3 * (i + 1) * k]);
            }
        }
        new_row_ptr.push(new_rows.len() as u32);
        new_ptr.push(new_factor.len() as u32);
    }
    *row_ptr = new_row_ptr;
    *rows = new_rows;
    *factor_ptr = new_ptr;
    *factor = new_factor;
}
