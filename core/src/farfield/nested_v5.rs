//! The version-5 shape of the nested far field (read only): every block lists its own
//! field nodes and stores its row factor explicitly. Opened files become a
//! [`NestedFar`] with one unshared row group per block, which acts the same.

use serde::{Deserialize, Serialize};

use super::NestedFar;

/// A version-5 nested far field as it is encoded in the file header.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct NestedFarV5 {
    pub tolerance: f64,
    pub eta: f64,
    pub parent: Vec<u32>,
    pub basis_rank: Vec<u32>,
    pub basis_rows: Vec<u32>,
    pub kid_offset: Vec<u32>,
    pub basis_ptr: Vec<u32>,
    pub basis: Vec<f32>,
    pub leaf_of: Vec<u32>,
    pub leaf_slot: Vec<u32>,
    pub block_ptr: Vec<u32>,
    pub row_ptr: Vec<u32>,
    pub rows: Vec<u32>,
    pub rank: Vec<u32>,
    pub a_ptr: Vec<u32>,
    pub a: Vec<f32>,
    pub b_ptr: Vec<u32>,
    pub b: Vec<f32>,
}

impl From<NestedFarV5> for NestedFar {
    fn from(v: NestedFarV5) -> NestedFar {
        let blocks = v.rank.len();
        NestedFar {
            tolerance: v.tolerance,
            eta: v.eta,
            parent: v.parent,
            basis_rank: v.basis_rank,
            basis_rows: v.basis_rows,
            kid_offset: v.kid_offset,
            basis_ptr: v.basis_ptr,
            basis: v.basis,
            leaf_of: v.leaf_of,
            leaf_slot: v.leaf_slot,
            block_ptr: v.block_ptr,
            block_group: (0..blocks as u32).collect(),
            group_ptr: v.row_ptr,
            group_rows: v.rows,
            group_rank: vec![0; blocks],
            group_basis_ptr: vec![0; blocks + 1],
            group_basis: Vec::new(),
            rank: v.rank,
            a_ptr: v.a_ptr,
            a: v.a,
            b_ptr: v.b_ptr,
            b: v.b,
        }
    }
}

impl From<&NestedFar> for NestedFarV5 {
    /// Every block with its own field nodes and explicit `A`.
    fn from(f: &NestedFar) -> NestedFarV5 {
        let mut v = NestedFarV5 {
            tolerance: f.tolerance,
            eta: f.eta,
            parent: f.parent.clone(),
            basis_rank: f.basis_rank.clone(),
            basis_rows: f.basis_rows.clone(),
            kid_offset: f.kid_offset.clone(),
            basis_ptr: f.basis_ptr.clone(),
            basis: f.basis.clone(),
            leaf_of: f.leaf_of.clone(),
            leaf_slot: f.leaf_slot.clone(),
            block_ptr: f.block_ptr.clone(),
            row_ptr: vec![0],
            rank: f.rank.clone(),
            a_ptr: vec![0],
            b_ptr: f.b_ptr.clone(),
            b: f.b.clone(),
            ..NestedFarV5::default()
        };
        for b in 0..f.blocks() {
            v.rows.extend_from_slice(f.block_rows(b));
            v.row_ptr.push(v.rows.len() as u32);
            v.a.extend(f.explicit_a(b));
            v.a_ptr.push(v.a.len() as u32);
        }
        v
    }
}
