//! The far field as independent low-rank blocks (file format version 4).
//!
//! Each admissible pair of patches `(ρ, γ)` stores its own `R[ρ, γ] ≈ U Vᵀ`; the rows
//! of `V` of a load node are repeated in every block on its path through the tree. The
//! nested form ([`super::nested`]) shares them; this one is kept so that version-4
//! files open and evaluate as they were built.

use serde::{Deserialize, Serialize};

use super::{FarFieldError, MAX_RANK};

/// The low-rank blocks (f32: a correction to the modes' answer).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct FarBlocks {
    /// Truncation tolerance the blocks were built with (relative to a unit column).
    pub tolerance: f64,
    /// Admissibility: a block is low rank where `min(diam) ≤ eta · distance`.
    pub eta: f64,
    /// Per block `b`: its field nodes are `rows[row_ptr[b]..row_ptr[b + 1]]`.
    pub row_ptr: Vec<u32>,
    pub rows: Vec<u32>,
    /// Per block: its rank `k_b` (≤ [`MAX_RANK`]).
    pub rank: Vec<u32>,
    /// Per block: `U` at `u[u_ptr[b]..]`, row-major `(3·local row + d, k)`.
    pub u_ptr: Vec<u32>,
    pub u: Vec<f32>,
    /// CSR over load nodes: entries `col_ptr[j]..col_ptr[j + 1]`, each naming a block
    /// whose column patch holds `j` and where its `3 × k` rows of `V` start in `v`
    /// (`[c][k]`, load direction `c`).
    pub col_ptr: Vec<u32>,
    pub col_block: Vec<u32>,
    pub v_off: Vec<u32>,
    pub v: Vec<f32>,
}

/// Blocks accumulated before they are applied (a probe touches a few dozen).
const ACC_BLOCKS: usize = 64;

impl FarBlocks {
    pub fn blocks(&self) -> usize {
        self.rank.len()
    }

    /// Stored bytes.
    pub fn bytes(&self) -> usize {
        4 * (self.row_ptr.len()
            + self.rows.len()
            + self.rank.len()
            + self.u_ptr.len()
            + self.u.len()
            + self.col_ptr.len()
            + self.col_block.len()
            + self.v_off.len()
            + self.v.len())
    }

    /// Checks every length and index against `load_nodes` and `field_nodes`.
    pub fn validate(&self, load_nodes: usize, field_nodes: usize) -> Result<(), FarFieldError> {
        let len = |what, found: usize, expected: usize| {
            if found == expected {
                Ok(())
            } else {
                Err(FarFieldError::Length {
                    what,
                    found,
                    expected,
                })
            }
        };
        let nb = self.rank.len();
        len("far-field row pointers", self.row_ptr.len(), nb + 1)?;
        len("far-field U pointers", self.u_ptr.len(), nb + 1)?;
        len(
            "far-field column pointers",
            self.col_ptr.len(),
            load_nodes + 1,
        )?;
        for (what, ptr) in [
            ("row", &self.row_ptr),
            ("U", &self.u_ptr),
            ("column", &self.col_ptr),
        ] {
            if ptr.first() != Some(&0) {
                return Err(FarFieldError::Pointers { what, at: 0 });
            }
            if let Some(at) = ptr.windows(2).position(|w| w[0] > w[1]) {
                return Err(FarFieldError::Pointers { what, at });
            }
        }
        len("far-field rows", self.rows.len(), self.row_ptr[nb] as usize)?;
        len("far-field U", self.u.len(), self.u_ptr[nb] as usize)?;
        for b in 0..nb {
            let k = self.rank[b] as usize;
            if k > MAX_RANK {
                return Err(FarFieldError::Length {
                    what: "far-field block rank",
                    found: k,
                    expected: MAX_RANK,
                });
            }
            let r = (self.row_ptr[b + 1] - self.row_ptr[b]) as usize;
            len(
                "far-field U block",
                (self.u_ptr[b + 1] - self.u_ptr[b]) as usize,
                3 * r * k,
            )?;
        }
        let entries = self.col_ptr[load_nodes] as usize;
        len("far-field column blocks", self.col_block.len(), entries)?;
        len("far-field V offsets", self.v_off.len(), entries)?;
        for e in 0..entries {
            let b = self.col_block[e] as usize;
            if b >= nb {
                return Err(FarFieldError::Length {
                    what: "far-field column block index",
                    found: b,
                    expected: nb,
                });
            }
            let end = self.v_off[e] as usize + 3 * self.rank[b] as usize;
            if end > self.v.len() {
                return Err(FarFieldError::Length {
                    what: "far-field V",
                    found: self.v.len(),
                    expected: end,
                });
            }
        }
        if let Some(entry) = self.rows.iter().position(|&x| x as usize >= field_nodes) {
            return Err(FarFieldError::NoSuchNode {
                entry,
                node: self.rows[entry],
                nodes: field_nodes,
            });
        }
        if self.u.iter().chain(&self.v).any(|v| !v.is_finite()) {
            return Err(FarFieldError::NotFinite);
        }
        Ok(())
    }

    /// Adds `Σ_j w_j R[·, j] t` to `out` (rows `3x + d` of the model's field nodes).
    /// Allocation-free: coefficients of up to 64 blocks are gathered on the
    /// stack, then applied.
    pub fn add(&self, shares: &[(u32, f64)], mix: [f64; 3], out: &mut [f64]) {
        let mut ids = [u32::MAX; ACC_BLOCKS];
        let mut acc = [[0.0f64; MAX_RANK]; ACC_BLOCKS];
        let mut used = 0;
        for &(j, w) in shares {
            let j = j as usize;
            if j + 1 >= self.col_ptr.len() {
                continue;
            }
            for e in self.col_ptr[j] as usize..self.col_ptr[j + 1] as usize {
                let b = self.col_block[e];
                let k = self.rank[b as usize] as usize;
                let slot = match ids[..used].iter().position(|&x| x == b) {
                    Some(s) => s,
                    None => {
                        if used == ACC_BLOCKS {
                            self.apply(&ids[..used], &mut acc[..used], out);
                            used = 0;
                        }
                        ids[used] = b;
                        acc[used] = [0.0; MAX_RANK];
                        used += 1;
                        used - 1
                    }
                };
                let v = &self.v[self.v_off[e] as usize..self.v_off[e] as usize + 3 * k];
                for (kk, a) in acc[slot][..k].iter_mut().enumerate() {
                    *a += w
                        * (f64::from(v[kk]) * mix[0]
                            + f64::from(v[k + kk]) * mix[1]
                            + f64::from(v[2 * k + kk]) * mix[2]);
                }
            }
        }
        self.apply(&ids[..used], &mut acc[..used], out);
    }

    fn apply(&self, ids: &[u32], acc: &mut [[f64; MAX_RANK]], out: &mut [f64]) {
        for (&b, coef) in ids.iter().zip(acc.iter()) {
            let b = b as usize;
            let k = self.rank[b] as usize;
            let rows = &self.rows[self.row_ptr[b] as usize..self.row_ptr[b + 1] as usize];
            let u = &self.u[self.u_ptr[b] as usize..self.u_ptr[b + 1] as usize];
            for (r, &x) in rows.iter().enumerate() {
                for d in 0..3 {
                    let urow = &u[(3 * r + d) * k..(3 * r + d + 1) * k];
                    let s: f64 = urow
                        .iter()
                        .zip(&coef[..k])
                        .map(|(&a, &c)| f64::from(a) * c)
                        .sum();
                    if let Some(o) = out.get_mut(3 * x as usize + d) {
                        *o += s;
                    }
                }
            }
        }
    }

    /// The blocks with every term whose singular value (the norm of its column of `U`,
    /// unit-column scale) is at or below `tolerance` dropped: the far field's
    /// accuracy knob, applied at load time.
    pub fn truncated(&self, tolerance: f64) -> FarBlocks {
        let nb = self.rank.len();
        let mut keep = Vec::with_capacity(nb);
        for b in 0..nb {
            let k = self.rank[b] as usize;
            let u = &self.u[self.u_ptr[b] as usize..self.u_ptr[b + 1] as usize];
            let rows = u.len() / k.max(1);
            let kept = (0..k)
                .take_while(|&kk| {
                    let s2: f64 = (0..rows).map(|r| f64::from(u[r * k + kk]).powi(2)).sum();
                    s2.sqrt() > tolerance
                })
                .count();
            keep.push(kept);
        }
        let mut out = FarBlocks {
            tolerance: tolerance.max(self.tolerance),
            eta: self.eta,
            row_ptr: self.row_ptr.clone(),
            rows: self.rows.clone(),
            rank: keep.iter().map(|&k| k as u32).collect(),
            u_ptr: vec![0],
            col_ptr: vec![0],
            ..FarBlocks::default()
        };
        for b in 0..nb {
            let (k, kept) = (self.rank[b] as usize, keep[b]);
            let u = &self.u[self.u_ptr[b] as usize..self.u_ptr[b + 1] as usize];
            for row in u.chunks_exact(k.max(1)) {
                out.u.extend_from_slice(&row[..kept]);
            }
            out.u_ptr.push(out.u.len() as u32);
        }
        for j in 0..self.col_ptr.len().saturating_sub(1) {
            for e in self.col_ptr[j] as usize..self.col_ptr[j + 1] as usize {
                let b = self.col_block[e] as usize;
                let (k, kept) = (self.rank[b] as usize, keep[b]);
                out.col_block.push(b as u32);
                out.v_off.push(out.v.len() as u32);
                let v = &self.v[self.v_off[e] as usize..self.v_off[e] as usize + 3 * k];
                for c in 0..3 {
                    out.v.extend_from_slice(&v[c * k..c * k + kept]);
                }
            }
            out.col_ptr.push(out.col_block.len() as u32);
        }
        out
    }

    /// Renumbers the field nodes (`new_index[old]`, `u32::MAX` = dropped); dropped
    /// rows leave their blocks.
    pub fn remap_nodes(&mut self, new_index: &[u32]) {
        super::remap_block_rows(
            new_index,
            &self.rank,
            &mut self.row_ptr,
            &mut self.rows,
            &mut self.u_ptr,
            &mut self.u,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One block over field nodes {1, 3} and load node 0, rank 2.
    fn one_block() -> FarBlocks {
        FarBlocks {
            tolerance: 0.1,
            eta: 1.0,
            row_ptr: vec![0, 2],
            rows: vec![1, 3],
            rank: vec![2],
            u_ptr: vec![0, 12],
            // (3·2 rows) × 2: column norms 3 and 0.5.
            u: vec![1.0, 0.2, 2.0, 0.0, 2.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            col_ptr: vec![0, 1, 1],
            col_block: vec![0],
            v_off: vec![0],
            v: vec![1.0, 2.0, 0.0, 1.0, 0.5, 0.5],
        }
    }

    #[test]
    fn a_block_adds_u_times_v_transpose_of_the_load() {
        let f = one_block();
        f.validate(2, 4).expect("valid");
        let mut out = vec![0.0; 12];
        let (w, t) = (0.5, [0.0, 0.0, 1.0]);
        f.add(&[(0, w), (1, 3.0)], t, &mut out);
        // Coefficients: w · V[c = 2] = 0.5 · [0.5, 0.5].
        let c = [0.25, 0.25];
        let u: Vec<f64> = f.u.iter().map(|&v| f64::from(v)).collect();
        for d in 0..3 {
            let expect = u[2 * d] * c[0] + u[2 * d + 1] * c[1];
            assert!((out[3 + d] - expect).abs() < 1e-12, "{d}: {out:?}");
        }
        assert!(out[..3].iter().chain(&out[6..9]).all(|&v| v == 0.0));
    }

    #[test]
    fn truncation_drops_the_small_terms_and_stays_valid() {
        let f = one_block().truncated(1.0);
        f.validate(2, 4).expect("valid");
        assert_eq!(f.rank, vec![1]);
        assert_eq!(f.v, vec![1.0, 0.0, 0.5]);
        let g = one_block().truncated(10.0);
        g.validate(2, 4).expect("valid");
        let mut out = vec![0.0; 12];
        g.add(&[(0, 1.0)], [1.0; 3], &mut out);
        assert!(out.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn bad_blocks_are_named() {
        let mut f = one_block();
        f.rows[1] = 9;
        assert!(matches!(
            f.validate(2, 4),
            Err(FarFieldError::NoSuchNode { node: 9, .. })
        ));
        let mut f = one_block();
        f.u.pop();
        assert!(f.validate(2, 4).is_err());
        let mut f = one_block();
        f.v[0] = f32::NAN;
        assert!(matches!(f.validate(2, 4), Err(FarFieldError::NotFinite)));
    }
}
