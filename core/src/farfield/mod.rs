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
//! over cluster trees of the surface nodes and of the load nodes. The load side of every
//! block is expressed in a basis of its column patch, and a patch's basis is its
//! children's bases times a small transfer matrix, so a load node's coefficients are
//! stored once instead of once per block on its path; the blocks of one row patch
//! share a basis of their row side where that saves numbers ([`NestedFar`]).
//!
//! A probe touches the few load nodes under its disk; the far field adds the blocks of
//! the patches holding them to the rows of their row patches, allocation-free.

mod nested;

use thiserror::Error;

pub use nested::{MAX_BASIS, NestedFar};

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
