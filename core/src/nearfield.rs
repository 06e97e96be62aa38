//! The near field of a nodal-load vademecum: what its separated modes cannot carry.
//!
//! With unit nodal loads on the parametric axis, the exact discrete map is
//! `G = K⁻¹E` and a probe at `s` along `t` is `u(s) = G (w(s) ⊗ t)` exactly (see
//! [`crate::disk`]). A rank-N separated form `G ≈ Σ_k X_k Y_kᵀ` is accurate in the far
//! field, but the response to a local load is concentrated under the tool (the
//! diagonal of a Green's function) and is not low rank. Two small stored parts close
//! that gap:
//!
//! - **Band.** For each load node `j` and each field node `x` within `band_radius_mm`
//!   of it, the 3×3 block `E_N[x, j] = G[x, j] − Σ_k X_k[x] Y_k[j]`. A probe adds
//!   `Σ_j w_j(s) E_N[x, j] t` to the modes' answer, so every node within the band radius
//!   of the loaded nodes is exact; farther nodes carry the (smooth) truncation error.
//!   The band completes the first `band_modes` modes; a truncation to fewer modes keeps
//!   the band and carries the dropped terms' error.
//! - **Compliance table.** The force law needs the compliance tensor
//!   `C(s) = Σ_a N_a(s) G[a, ·] (w(s) ⊗ I₃)` (3×3, mm/N: displacement of the contact
//!   point per newton along each axis), exact from the off-line solves at the points of
//!   a degree-q lattice on every palpable face and interpolated on-line by the degree-q
//!   Lagrange basis ([`crate::disk::lagrange_tri`]). `c(s) = tᵀ C(s) t` then costs a
//!   few dozen multiplications and does not depend on the number of modes.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::disk::lagrange_tri;
use crate::farfield::{FarFieldError, NestedFar};

/// Why a near-field part is inconsistent with its model.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NearFieldError {
    #[error("near field: {what} has {found} entries, expected {expected}")]
    Length {
        what: &'static str,
        found: usize,
        expected: usize,
    },
    #[error("near field: band entry {entry} names field node {node}, the model has {nodes}")]
    NoSuchNode {
        entry: usize,
        node: u32,
        nodes: usize,
    },
    #[error("near field: band pointers must rise from 0 to the entry count (at load node {at})")]
    Pointers { at: usize },
    #[error("near field: {what} holds a non-finite value")]
    NotFinite { what: &'static str },
    #[error("near field: table degree {0} (expected 1 to 8)")]
    Degree(u32),
    #[error(transparent)]
    Far(#[from] FarFieldError),
}

/// The stored near field (f32: it is a correction to the modes' answer).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NearField {
    pub band_radius_mm: f64,
    pub band_modes: u32,
    /// CSR over load nodes: entries `band_ptr[j]..band_ptr[j + 1]`.
    pub band_ptr: Vec<u32>,
    /// Field node of each entry.
    pub band_nodes: Vec<u32>,
    /// 3×3 block per entry, row-major `[d][c]`: row `3x + d`, load direction `c`.
    pub band_values: Vec<f32>,
    /// Degree q of the compliance lattice.
    pub table_degree: u32,
    /// Per face of the load axis: its block in `table_values`, `u32::MAX` if none.
    pub table_block: Vec<u32>,
    /// Blocks of `(q+1)(q+2)/2` lattice points × 9 tensor entries `[d][c]`.
    pub table_values: Vec<f32>,
    /// The hierarchical far field, if the model has one (the file stores it in its
    /// own layout part, beside the near field).
    #[serde(skip)]
    pub far: Option<Box<NestedFar>>,
}

impl NearField {
    /// Lattice points per face.
    pub fn table_points(&self) -> usize {
        let q = self.table_degree as usize;
        (q + 1) * (q + 2) / 2
    }

    /// Stored bytes (what a scene carries for it).
    pub fn bytes(&self) -> usize {
        4 * (self.band_ptr.len()
            + self.band_nodes.len()
            + self.band_values.len()
            + self.table_block.len()
            + self.table_values.len())
            + self.far.as_ref().map_or(0, |f| f.bytes())
    }

    /// Checks the shapes against a load axis of `load_nodes` nodes and `faces` faces
    /// and a model of `field_nodes` nodes.
    pub fn validate(
        &self,
        load_nodes: usize,
        faces: usize,
        field_nodes: usize,
    ) -> Result<(), NearFieldError> {
        let len = |what, found, expected| {
            if found == expected {
                Ok(())
            } else {
                Err(NearFieldError::Length {
                    what,
                    found,
                    expected,
                })
            }
        };
        len("band pointers", self.band_ptr.len(), load_nodes + 1)?;
        if self.band_ptr[0] != 0 {
            return Err(NearFieldError::Pointers { at: 0 });
        }
        if let Some(at) = self.band_ptr.windows(2).position(|w| w[0] > w[1]) {
            return Err(NearFieldError::Pointers { at });
        }
        let entries = self.band_ptr[load_nodes] as usize;
        len("band nodes", self.band_nodes.len(), entries)?;
        len("band values", self.band_values.len(), 9 * entries)?;
        if let Some((entry, &node)) = self
            .band_nodes
            .iter()
            .enumerate()
            .find(|(_, n)| **n as usize >= field_nodes)
        {
            return Err(NearFieldError::NoSuchNode {
                entry,
                node,
                nodes: field_nodes,
            });
        }
        if !(1..=8).contains(&self.table_degree) {
            return Err(NearFieldError::Degree(self.table_degree));
        }
        len("table faces", self.table_block.len(), faces)?;
        let per = 9 * self.table_points();
        if !self.table_values.len().is_multiple_of(per) {
            return Err(NearFieldError::Length {
                what: "table values",
                found: self.table_values.len(),
                expected: self.table_values.len() / per * per,
            });
        }
        let blocks = self.table_values.len() / per;
        if self
            .table_block
            .iter()
            .any(|&b| b != u32::MAX && b as usize >= blocks)
        {
            return Err(NearFieldError::Length {
                what: "table blocks",
                found: blocks,
                expected: self.table_block.iter().filter(|&&b| b != u32::MAX).count(),
            });
        }
        if let Some(far) = &self.far {
            far.validate(load_nodes, field_nodes)?;
        }
        if self.band_values.iter().any(|v| !v.is_finite()) {
            return Err(NearFieldError::NotFinite { what: "the band" });
        }
        if self.table_values.iter().any(|v| !v.is_finite()) {
            return Err(NearFieldError::NotFinite {
                what: "the compliance table",
            });
        }
        Ok(())
    }

    /// Adds the remainder `Σ_j w_j E_N[x, j] t` to `out` (rows `3x + d` of the model's
    /// field nodes): the band, then the far field's blocks. Allocation-free.
    pub fn add(&self, shares: &[(u32, f64)], mix: [f64; 3], out: &mut [f64]) {
        self.add_band(shares, mix, out);
        if let Some(far) = &self.far {
            far.add(shares, mix, out);
        }
    }

    /// The band's part of [`Self::add`].
    pub fn add_band(&self, shares: &[(u32, f64)], mix: [f64; 3], out: &mut [f64]) {
        for &(j, w) in shares {
            let j = j as usize;
            let (a, b) = (self.band_ptr[j] as usize, self.band_ptr[j + 1] as usize);
            for e in a..b {
                let x = self.band_nodes[e] as usize;
                let blk = &self.band_values[9 * e..9 * e + 9];
                for d in 0..3 {
                    let v = f64::from(blk[3 * d]) * mix[0]
                        + f64::from(blk[3 * d + 1]) * mix[1]
                        + f64::from(blk[3 * d + 2]) * mix[2];
                    if let Some(o) = out.get_mut(3 * x + d) {
                        *o += w * v;
                    }
                }
            }
        }
    }

    /// The compliance tensor `C[d][c]` (mm/N) at barycentric `bary` of load face
    /// `face`, or `None` where the table has no block (outside the palpable region).
    /// Allocation-free.
    pub fn compliance_tensor(&self, face: u32, bary: [f64; 3]) -> Option<[[f64; 3]; 3]> {
        let blk = *self.table_block.get(face as usize)?;
        if blk == u32::MAX {
            return None;
        }
        let q = self.table_degree as usize;
        let np = self.table_points();
        let mut basis = [0.0; 45]; // (8+1)(8+2)/2 = 45 points at most
        lagrange_tri(q, bary, &mut basis[..np]);
        let vals = &self.table_values[blk as usize * 9 * np..(blk as usize + 1) * 9 * np];
        let mut c = [[0.0; 3]; 3];
        for (p, &l) in basis[..np].iter().enumerate() {
            for d in 0..3 {
                for e in 0..3 {
                    c[d][e] += l * f64::from(vals[9 * p + 3 * d + e]);
                }
            }
        }
        Some(c)
    }

    /// Renumbers the band's field nodes (`new_index[old]`, `u32::MAX` = dropped), e.g.
    /// when a scene keeps only the surface rows.
    pub fn remap_nodes(&mut self, new_index: &[u32]) {
        let mut ptr = Vec::with_capacity(self.band_ptr.len());
        let mut nodes = Vec::new();
        let mut vals = Vec::new();
        ptr.push(0u32);
        for j in 0..self.band_ptr.len() - 1 {
            for e in self.band_ptr[j] as usize..self.band_ptr[j + 1] as usize {
                let to = new_index
                    .get(self.band_nodes[e] as usize)
                    .copied()
                    .unwrap_or(u32::MAX);
                if to != u32::MAX {
                    nodes.push(to);
                    vals.extend_from_slice(&self.band_values[9 * e..9 * e + 9]);
                }
            }
            ptr.push(nodes.len() as u32);
        }
        self.band_ptr = ptr;
        self.band_nodes = nodes;
        self.band_values = vals;
        if let Some(far) = &mut self.far {
            far.remap_nodes(new_index);
        }
    }
}
