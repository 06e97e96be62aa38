//! The far field with nested column bases and shared row bases.
//!
//! Every column patch (cluster of load nodes) `γ` that takes part in a low-rank block
//! carries a basis `V_γ` (3·|γ| × k_γ, f32) of the load side of all its far blocks,
//! and of those of its ancestors:
//!
//! - a leaf stores `V_γ` itself, row `3·slot + c` for its load node `slot` and load
//!   direction `c` (the map's column scaling folded in);
//! - an inner patch with children `a`, `b` stores only a transfer `E_γ`
//!   ((k_a + k_b) × k_γ), meaning `V_γ = diag(V_a, V_b) E_γ`.
//!
//! A block `(ρ, γ)` stores `R[ρ, γ] ≈ A B V_γᵀ` with `A` (3·|ρ| × r, carrying the
//! singular values, columns in decreasing order) and `B` (r × k_γ). On-line, a probe
//! with nodal shares `w_j` along `t` gathers the leaf coefficients
//! `c_λ = Σ_j w_j V_λ[3 slot_j + ·, ·]ᵀ t`, lifts them up the tree
//! (`c_γ += E_γ[rows of child]ᵀ c_child`, children before parents: clusters are
//! numbered so that a parent comes first), and adds `A (B c_γ)` for every block of
//! every patch reached. A load node's `V` rows are stored once, not once per block on
//! its path; the on-line work stays about `rows × r` per block.
//!
//! The row side is shared too. The blocks of one row patch `ρ` (one per column patch
//! it is admissible against, five or so) form a *row group*. Where it saves numbers, the
//! group stores an orthonormal basis `U_ρ` (3·|ρ| × k_ρ) of the span of its blocks'
//! `A`s, and each block stores only `Ã = U_ρᵀ A` (k_ρ × r), so `A ≈ U_ρ Ã`; a group
//! whose blocks are too few or too different keeps its `A`s explicit (`k_ρ = 0`).
//! The group also lists the field nodes once for all its blocks.

use serde::{Deserialize, Serialize};

use super::FarFieldError;

/// `Ok` if `found == expected`, else the length error naming `what`.
fn len(what: &'static str, found: usize, expected: usize) -> Result<(), FarFieldError> {
    if found == expected {
        Ok(())
    } else {
        Err(FarFieldError::Length {
            what,
            found,
            expected,
        })
    }
}

/// Largest rank of a patch's basis (the on-line coefficient width).
pub const MAX_BASIS: usize = 64;

/// Patches gathered before they are lifted and applied (a probe reaches a few leaves
/// and their ancestors, a few dozen in all).
const ACC: usize = 96;

/// Nested-basis far field (f32: a correction to the modes' answer).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct NestedFar {
    /// Truncation tolerance of the bases and blocks (relative to a unit column).
    pub tolerance: f64,
    /// Admissibility: a block is low rank where `max(diam) ≤ eta · distance`.
    pub eta: f64,
    /// Per column patch: its parent (`u32::MAX` for the root); always `< ` itself.
    pub parent: Vec<u32>,
    /// Per patch: rank `k_γ` of its basis.
    pub basis_rank: Vec<u32>,
    /// Per patch: rows of its stored basis (a leaf: 3 × its nodes; an inner patch: the
    /// sum of its children's ranks).
    pub basis_rows: Vec<u32>,
    /// Per patch: the first row of its coefficients in its parent's transfer.
    pub kid_offset: Vec<u32>,
    /// Per patch: its basis or transfer at `basis[basis_ptr[γ]..]`, row-major.
    pub basis_ptr: Vec<u32>,
    pub basis: Vec<f32>,
    /// Per load node: its leaf patch (`u32::MAX`: in no far block) and its slot there.
    pub leaf_of: Vec<u32>,
    pub leaf_slot: Vec<u32>,
    /// Blocks grouped by column patch: patch `γ`'s are `block_ptr[γ]..block_ptr[γ + 1]`.
    pub block_ptr: Vec<u32>,
    /// Per block: its row group.
    pub block_group: Vec<u32>,
    /// Per row group `ρ`: its field nodes `group_rows[group_ptr[ρ]..group_ptr[ρ + 1]]`.
    pub group_ptr: Vec<u32>,
    pub group_rows: Vec<u32>,
    /// Per row group: the rank `k_ρ` of its shared basis (0: its blocks store `A`).
    pub group_rank: Vec<u32>,
    /// Per row group: `U_ρ` at `group_basis[group_basis_ptr[ρ]..]`, row-major
    /// `(3·local row + d, k_ρ)`, orthonormal columns.
    pub group_basis_ptr: Vec<u32>,
    pub group_basis: Vec<f32>,
    /// Per block: its rank `r_b`.
    pub rank: Vec<u32>,
    /// Per block: `A` at `a[a_ptr[b]..]`, row-major `(3·local row + d, r)`, or `Ã`
    /// (`(k_ρ, r)`) where its group shares a basis.
    pub a_ptr: Vec<u32>,
    pub a: Vec<f32>,
    /// Per block: `B` at `b[b_ptr[b]..]`, row-major `(r, k_γ)`.
    pub b_ptr: Vec<u32>,
    pub b: Vec<f32>,
}

impl NestedFar {
    pub fn blocks(&self) -> usize {
        self.rank.len()
    }

    pub fn patches(&self) -> usize {
        self.parent.len()
    }

    /// The field nodes of row group `q`.
    pub fn group_nodes(&self, q: usize) -> &[u32] {
        &self.group_rows[self.group_ptr[q] as usize..self.group_ptr[q + 1] as usize]
    }

    /// The field nodes of block `b`'s rows.
    pub fn block_rows(&self, b: usize) -> &[u32] {
        self.group_nodes(self.block_group[b] as usize)
    }

    /// Rows of block `b`'s stored row factor: `k_ρ` if its group shares a basis, else
    /// three per field node.
    fn a_rows(&self, b: usize) -> usize {
        let q = self.block_group[b] as usize;
        match self.group_rank[q] as usize {
            0 => 3 * self.group_nodes(q).len(),
            k => k,
        }
    }

    /// Block `b`'s row factor `A` written out (`U_ρ Ã` where its group shares a
    /// basis), row-major `(3·local row + d, r)`.
    pub fn explicit_a(&self, b: usize) -> Vec<f32> {
        let q = self.block_group[b] as usize;
        let (k, r) = (self.group_rank[q] as usize, self.rank[b] as usize);
        let a = &self.a[self.a_ptr[b] as usize..self.a_ptr[b + 1] as usize];
        if k == 0 {
            return a.to_vec();
        }
        let u = &self.group_basis
            [self.group_basis_ptr[q] as usize..self.group_basis_ptr[q + 1] as usize];
        u.chunks_exact(k)
            .flat_map(|urow| {
                (0..r).map(move |rr| {
                    urow.iter()
                        .enumerate()
                        .map(|(kk, &x)| f64::from(x) * f64::from(a[kk * r + rr]))
                        .sum::<f64>() as f32
                })
            })
            .collect()
    }

    /// Stored bytes.
    pub fn bytes(&self) -> usize {
        4 * [
            self.parent.len(),
            self.basis_rank.len(),
            self.basis_rows.len(),
            self.kid_offset.len(),
            self.basis_ptr.len(),
            self.basis.len(),
            self.leaf_of.len(),
            self.leaf_slot.len(),
            self.block_ptr.len(),
            self.block_group.len(),
            self.group_ptr.len(),
            self.group_rows.len(),
            self.group_rank.len(),
            self.group_basis_ptr.len(),
            self.group_basis.len(),
            self.rank.len(),
            self.a_ptr.len(),
            self.a.len(),
            self.b_ptr.len(),
            self.b.len(),
        ]
        .iter()
        .sum::<usize>()
    }

    /// Checks every length, index and the parent order against `load_nodes` and
    /// `field_nodes`, so that [`Self::add`] never reads out of bounds or loops.
    pub fn validate(&self, load_nodes: usize, field_nodes: usize) -> Result<(), FarFieldError> {
        self.validate_shapes(load_nodes)?;
        self.validate_groups()?;
        self.validate_patches()?;
        self.validate_leaves(load_nodes)?;
        if let Some(entry) = self
            .group_rows
            .iter()
            .position(|&x| x as usize >= field_nodes)
        {
            return Err(FarFieldError::NoSuchNode {
                entry,
                node: self.group_rows[entry],
                nodes: field_nodes,
            });
        }
        if self
            .basis
            .iter()
            .chain(&self.a)
            .chain(&self.b)
            .chain(&self.group_basis)
            .any(|v| !v.is_finite())
        {
            return Err(FarFieldError::NotFinite);
        }
        Ok(())
    }

    /// Array lengths and pointer sequences.
    fn validate_shapes(&self, load_nodes: usize) -> Result<(), FarFieldError> {
        let np = self.parent.len();
        let nb = self.rank.len();
        len("far-field basis ranks", self.basis_rank.len(), np)?;
        len("far-field basis rows", self.basis_rows.len(), np)?;
        len("far-field child offsets", self.kid_offset.len(), np)?;
        len("far-field basis pointers", self.basis_ptr.len(), np + 1)?;
        len(
            "far-field leaf of each load node",
            self.leaf_of.len(),
            load_nodes,
        )?;
        len("far-field leaf slots", self.leaf_slot.len(), load_nodes)?;
        len("far-field block pointers", self.block_ptr.len(), np + 1)?;
        let ng = self.group_rank.len();
        len(
            "far-field row group of each block",
            self.block_group.len(),
            nb,
        )?;
        len("far-field row group pointers", self.group_ptr.len(), ng + 1)?;
        len(
            "far-field row group basis pointers",
            self.group_basis_ptr.len(),
            ng + 1,
        )?;
        len("far-field A pointers", self.a_ptr.len(), nb + 1)?;
        len("far-field B pointers", self.b_ptr.len(), nb + 1)?;
        for (what, ptr) in [
            ("basis", &self.basis_ptr),
            ("block", &self.block_ptr),
            ("row group", &self.group_ptr),
            ("row group basis", &self.group_basis_ptr),
            ("A", &self.a_ptr),
            ("B", &self.b_ptr),
        ] {
            if ptr.first() != Some(&0) {
                return Err(FarFieldError::Pointers { what, at: 0 });
            }
            if let Some(at) = ptr.windows(2).position(|w| w[0] > w[1]) {
                return Err(FarFieldError::Pointers { what, at });
            }
        }
        len("far-field blocks", self.block_ptr[np] as usize, nb)?;
        len(
            "far-field basis",
            self.basis.len(),
            self.basis_ptr[np] as usize,
        )?;
        len(
            "far-field rows",
            self.group_rows.len(),
            self.group_ptr[ng] as usize,
        )?;
        len(
            "far-field row bases",
            self.group_basis.len(),
            self.group_basis_ptr[ng] as usize,
        )?;
        len("far-field A", self.a.len(), self.a_ptr[nb] as usize)?;
        len("far-field B", self.b.len(), self.b_ptr[nb] as usize)?;
        Ok(())
    }

    /// Each row group's basis size, and every block's group index.
    fn validate_groups(&self) -> Result<(), FarFieldError> {
        let ng = self.group_rank.len();
        for q in 0..ng {
            let (n, k) = (self.group_nodes(q).len(), self.group_rank[q] as usize);
            if k > MAX_BASIS {
                return Err(FarFieldError::Length {
                    what: "far-field row basis rank",
                    found: k,
                    expected: MAX_BASIS,
                });
            }
            len(
                "far-field row basis of a group",
                (self.group_basis_ptr[q + 1] - self.group_basis_ptr[q]) as usize,
                3 * n * k,
            )?;
        }
        if let Some(b) = self.block_group.iter().position(|&q| q as usize >= ng) {
            return Err(FarFieldError::Length {
                what: "far-field row group index",
                found: self.block_group[b] as usize,
                expected: ng,
            });
        }
        Ok(())
    }

    /// Each patch's basis, its place in its parent's transfer, and its blocks' factors.
    fn validate_patches(&self) -> Result<(), FarFieldError> {
        let np = self.parent.len();
        for g in 0..np {
            let (k, rows) = (self.basis_rank[g] as usize, self.basis_rows[g] as usize);
            if k > MAX_BASIS {
                return Err(FarFieldError::Length {
                    what: "far-field basis rank",
                    found: k,
                    expected: MAX_BASIS,
                });
            }
            len(
                "far-field basis of a patch",
                (self.basis_ptr[g + 1] - self.basis_ptr[g]) as usize,
                rows * k,
            )?;
            let p = self.parent[g];
            if p != u32::MAX {
                if p as usize >= g {
                    return Err(FarFieldError::Parent {
                        cluster: g,
                        parent: p,
                    });
                }
                let end = self.kid_offset[g] as usize + k;
                if k > 0 && end > self.basis_rows[p as usize] as usize {
                    return Err(FarFieldError::Length {
                        what: "far-field transfer rows",
                        found: self.basis_rows[p as usize] as usize,
                        expected: end,
                    });
                }
            }
            for b in self.block_ptr[g] as usize..self.block_ptr[g + 1] as usize {
                let r = self.rank[b] as usize;
                len(
                    "far-field A block",
                    (self.a_ptr[b + 1] - self.a_ptr[b]) as usize,
                    self.a_rows(b) * r,
                )?;
                len(
                    "far-field B block",
                    (self.b_ptr[b + 1] - self.b_ptr[b]) as usize,
                    r * k,
                )?;
            }
        }
        Ok(())
    }

    /// Each load node's leaf and slot.
    fn validate_leaves(&self, load_nodes: usize) -> Result<(), FarFieldError> {
        let np = self.parent.len();
        for j in 0..load_nodes {
            let leaf = self.leaf_of[j];
            if leaf == u32::MAX {
                continue;
            }
            let Some(&rows) = self.basis_rows.get(leaf as usize) else {
                return Err(FarFieldError::Length {
                    what: "far-field leaf index",
                    found: leaf as usize,
                    expected: np,
                });
            };
            if 3 * self.leaf_slot[j] as usize + 3 > rows as usize {
                return Err(FarFieldError::Length {
                    what: "far-field leaf basis rows",
                    found: rows as usize,
                    expected: 3 * self.leaf_slot[j] as usize + 3,
                });
            }
        }
        Ok(())
    }

    /// The patch `g` and its ancestors, nearest first.
    fn chain(&self, g: u32) -> impl Iterator<Item = u32> + '_ {
        std::iter::successors(Some(g), move |&c| {
            let p = self.parent[c as usize];
            (p != u32::MAX).then_some(p)
        })
    }

    /// Adds `Σ_j w_j R[·, j] t` to `out` (rows `3x + d` of the model's field nodes).
    /// Allocation-free: the coefficients of up to 96 patches live on the stack; a probe
    /// reaching more is split into groups (the map is linear).
    pub fn add(&self, shares: &[(u32, f64)], mix: [f64; 3], out: &mut [f64]) {
        let mut ids = [u32::MAX; ACC];
        let mut coef = [[0.0f64; MAX_BASIS]; ACC];
        let mut used = 0;
        for &(j, w) in shares {
            let Some(&leaf) = self.leaf_of.get(j as usize) else {
                continue;
            };
            if leaf == u32::MAX || self.basis_rank[leaf as usize] == 0 {
                continue;
            }
            let missing = self
                .chain(leaf)
                .filter(|g| !ids[..used].contains(g))
                .count();
            if used + missing > ACC {
                self.flush(&mut ids[..used], &mut coef[..used], out);
                used = 0;
            }
            for g in self.chain(leaf) {
                if !ids[..used].contains(&g) {
                    ids[used] = g;
                    coef[used] = [0.0; MAX_BASIS];
                    used += 1;
                }
            }
            let Some(slot) = ids[..used].iter().position(|&g| g == leaf) else {
                continue;
            };
            let k = self.basis_rank[leaf as usize] as usize;
            let base = self.basis_ptr[leaf as usize] as usize
                + 3 * self.leaf_slot[j as usize] as usize * k;
            let v = &self.basis[base..base + 3 * k];
            for (kk, c) in coef[slot][..k].iter_mut().enumerate() {
                *c += w
                    * (f64::from(v[kk]) * mix[0]
                        + f64::from(v[k + kk]) * mix[1]
                        + f64::from(v[2 * k + kk]) * mix[2]);
            }
        }
        self.flush(&mut ids[..used], &mut coef[..used], out);
    }

    /// Lifts the gathered coefficients to the parents (children first: they have the
    /// larger numbers), then applies every block of every gathered patch.
    fn flush(&self, ids: &mut [u32], coef: &mut [[f64; MAX_BASIS]], out: &mut [f64]) {
        let n = ids.len();
        let mut order = [0u8; ACC];
        for (i, o) in order[..n].iter_mut().enumerate() {
            *o = i as u8;
        }
        order[..n].sort_unstable_by(|&a, &b| ids[b as usize].cmp(&ids[a as usize]));
        for &s in &order[..n] {
            let s = s as usize;
            let g = ids[s] as usize;
            let p = self.parent[g];
            let kg = self.basis_rank[g] as usize;
            if p == u32::MAX || kg == 0 {
                continue;
            }
            let kp = self.basis_rank[p as usize] as usize;
            let Some(ps) = ids.iter().position(|&x| x == p) else {
                continue;
            };
            if kp == 0 {
                continue;
            }
            let mine = coef[s];
            let e = &self.basis[self.basis_ptr[p as usize] as usize..];
            let off = self.kid_offset[g] as usize;
            for (i, &ci) in mine[..kg].iter().enumerate() {
                if ci == 0.0 {
                    continue;
                }
                let row = &e[(off + i) * kp..(off + i + 1) * kp];
                for (c, &x) in coef[ps][..kp].iter_mut().zip(row) {
                    *c += f64::from(x) * ci;
                }
            }
        }
        for (s, &g) in ids.iter().enumerate() {
            let g = g as usize;
            let k = self.basis_rank[g] as usize;
            for b in self.block_ptr[g] as usize..self.block_ptr[g + 1] as usize {
                self.apply(b, &coef[s][..k], out);
            }
        }
    }

    /// `out[rows of b] += A_b (B_b c)`, with `A_b = U_ρ Ã_b` where its group shares a
    /// basis.
    fn apply(&self, b: usize, c: &[f64], out: &mut [f64]) {
        let (r, k) = (self.rank[b] as usize, c.len());
        if r == 0 {
            return;
        }
        let bm = &self.b[self.b_ptr[b] as usize..self.b_ptr[b + 1] as usize];
        let mut t = [0.0f64; MAX_BASIS];
        for (rr, tv) in t[..r].iter_mut().enumerate() {
            *tv = bm[rr * k..(rr + 1) * k]
                .iter()
                .zip(c)
                .map(|(&x, &y)| f64::from(x) * y)
                .sum();
        }
        let q = self.block_group[b] as usize;
        let a = &self.a[self.a_ptr[b] as usize..self.a_ptr[b + 1] as usize];
        let kq = self.group_rank[q] as usize;
        if kq == 0 {
            add_rows(self.group_nodes(q), a, &t[..r], out);
            return;
        }
        let mut y = [0.0f64; MAX_BASIS];
        for (yv, arow) in y[..kq].iter_mut().zip(a.chunks_exact(r)) {
            *yv = arow
                .iter()
                .zip(&t[..r])
                .map(|(&u, &v)| f64::from(u) * v)
                .sum();
        }
        let u = &self.group_basis
            [self.group_basis_ptr[q] as usize..self.group_basis_ptr[q + 1] as usize];
        add_rows(self.group_nodes(q), u, &y[..kq], out);
    }

    /// The blocks with every term whose singular value (the norm of its column of `A`,
    /// unit-column scale) is at or below `tolerance` dropped; the bases are kept.
    ///
    /// At or below the build tolerance this is the far field as built: the build kept
    /// exactly the terms above it (a shared row basis can shrink a kept term's stored
    /// norm slightly below it, which must not drop the term).
    pub fn truncated(&self, tolerance: f64) -> NestedFar {
        if tolerance <= self.tolerance {
            return self.clone();
        }
        let mut out = NestedFar {
            tolerance: tolerance.max(self.tolerance),
            a_ptr: vec![0],
            b_ptr: vec![0],
            a: Vec::new(),
            b: Vec::new(),
            rank: Vec::with_capacity(self.rank.len()),
            ..self.clone()
        };
        for g in 0..self.patches() {
            let k = self.basis_rank[g] as usize;
            for b in self.block_ptr[g] as usize..self.block_ptr[g + 1] as usize {
                let r = self.rank[b] as usize;
                let a = &self.a[self.a_ptr[b] as usize..self.a_ptr[b + 1] as usize];
                let n = a.len() / r.max(1);
                let kept = (0..r)
                    .take_while(|&rr| {
                        let s2: f64 = (0..n).map(|i| f64::from(a[i * r + rr]).powi(2)).sum();
                        s2.sqrt() > tolerance
                    })
                    .count();
                for row in a.chunks_exact(r.max(1)) {
                    out.a.extend_from_slice(&row[..kept]);
                }
                let bm = &self.b[self.b_ptr[b] as usize..self.b_ptr[b + 1] as usize];
                out.b.extend_from_slice(&bm[..kept * k]);
                out.rank.push(kept as u32);
                out.a_ptr.push(out.a.len() as u32);
                out.b_ptr.push(out.b.len() as u32);
            }
        }
        out
    }

    /// Renumbers the field nodes (`new_index[old]`, `u32::MAX` = dropped); dropped
    /// rows leave their groups (and the rows of the bases or `A`s that hold them).
    pub fn remap_nodes(&mut self, new_index: &[u32]) {
        let to = |x: u32| new_index.get(x as usize).copied().unwrap_or(u32::MAX);
        // Per group: the local rows it keeps.
        let kept: Vec<Vec<usize>> = (0..self.group_rank.len())
            .map(|q| {
                let nodes = self.group_nodes(q);
                (0..nodes.len())
                    .filter(|&i| to(nodes[i]) != u32::MAX)
                    .collect()
            })
            .collect();
        let keep_rows = |m: &[f32], width: usize, rows: &[usize], into: &mut Vec<f32>| {
            for &i in rows {
                into.extend_from_slice(&m[3 * i * width..3 * (i + 1) * width]);
            }
        };
        let (mut ptr, mut rows, mut bptr, mut basis) =
            (vec![0u32], Vec::new(), vec![0u32], Vec::new());
        for (q, keep) in kept.iter().enumerate() {
            let nodes = self.group_nodes(q);
            rows.extend(keep.iter().map(|&i| to(nodes[i])));
            ptr.push(rows.len() as u32);
            let u = &self.group_basis
                [self.group_basis_ptr[q] as usize..self.group_basis_ptr[q + 1] as usize];
            keep_rows(u, self.group_rank[q] as usize, keep, &mut basis);
            bptr.push(basis.len() as u32);
        }
        let (mut aptr, mut a) = (vec![0u32], Vec::new());
        for b in 0..self.rank.len() {
            let q = self.block_group[b] as usize;
            let ab = &self.a[self.a_ptr[b] as usize..self.a_ptr[b + 1] as usize];
            if self.group_rank[q] == 0 {
                keep_rows(ab, self.rank[b] as usize, &kept[q], &mut a);
            } else {
                a.extend_from_slice(ab);
            }
            aptr.push(a.len() as u32);
        }
        self.group_ptr = ptr;
        self.group_rows = rows;
        self.group_basis_ptr = bptr;
        self.group_basis = basis;
        self.a_ptr = aptr;
        self.a = a;
    }
}

/// `out[3x + d] += M[3i + d, ·] · v` for the `i`-th field node `x` of `nodes`.
fn add_rows(nodes: &[u32], m: &[f32], v: &[f64], out: &mut [f64]) {
    let w = v.len();
    for (i, &x) in nodes.iter().enumerate() {
        for d in 0..3 {
            let row = &m[(3 * i + d) * w..(3 * i + d + 1) * w];
            let s: f64 = row.iter().zip(v).map(|(&u, &y)| f64::from(u) * y).sum();
            if let Some(o) = out.get_mut(3 * x as usize + d) {
                *o += s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Root patch 0 (inner, rank 1) with leaves 1 (load node 0) and 2 (load node 1),
    /// rank 1 each; one block on the root over field node 1, one on leaf 2 over field
    /// node 0.
    fn two_level() -> NestedFar {
        NestedFar {
            tolerance: 0.1,
            eta: 1.0,
            parent: vec![u32::MAX, 0, 0],
            basis_rank: vec![1, 1, 1],
            basis_rows: vec![2, 3, 3],
            kid_offset: vec![0, 0, 1],
            basis_ptr: vec![0, 2, 5, 8],
            // Root transfer E = [2, 3]ᵀ; leaf 1: V = [1, 0, 0]ᵀ; leaf 2: V = [0, 0, 1]ᵀ.
            basis: vec![2.0, 3.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            leaf_of: vec![1, 2],
            leaf_slot: vec![0, 0],
            block_ptr: vec![0, 1, 1, 2],
            block_group: vec![0, 1],
            group_ptr: vec![0, 1, 2],
            group_rows: vec![1, 0],
            group_rank: vec![0, 0],
            group_basis_ptr: vec![0, 0, 0],
            group_basis: Vec::new(),
            rank: vec![1, 1],
            a_ptr: vec![0, 3, 6],
            // Root block: A = [1, 0, 2]ᵀ (norm √5); leaf-2 block: A = [0, 0.05, 0]ᵀ.
            a: vec![1.0, 0.0, 2.0, 0.0, 0.05, 0.0],
            b_ptr: vec![0, 1, 2],
            b: vec![0.5, 4.0],
        }
    }

    #[test]
    fn coefficients_climb_through_the_transfers_to_the_blocks() {
        let f = two_level();
        f.validate(2, 2).expect("valid");
        let mut out = vec![0.0; 6];
        // Load node 0 along x (w 2), load node 1 along z (w 1).
        f.add(&[(0, 2.0)], [1.0, 0.0, 0.0], &mut out);
        f.add(&[(1, 1.0)], [0.0, 0.0, 1.0], &mut out);
        // Node 0: leaf coef 2 → root 2·2 = 4 → root block 0.5·4 = 2 → rows of node 1.
        // Node 1: leaf coef 1 → root 3 → 1.5 on node 1; leaf block 4·1 → node 0.
        let root = 2.0 + 1.5;
        let expect = [0.0, 0.2, 0.0, root, 0.0, 2.0 * root];
        for (o, e) in out.iter().zip(expect) {
            assert!((o - e).abs() < 1e-6, "{out:?}");
        }
        // Both at once: the same (linear, one pass).
        let mut both = vec![0.0; 6];
        f.add(&[(0, 2.0), (1, 1.0)], [1.0, 0.0, 1.0], &mut both);
        let mut apart = vec![0.0; 6];
        f.add(&[(0, 2.0)], [1.0, 0.0, 1.0], &mut apart);
        f.add(&[(1, 1.0)], [1.0, 0.0, 1.0], &mut apart);
        for (a, b) in both.iter().zip(&apart) {
            assert!((a - b).abs() < 1e-9);
        }
    }

    /// The root block's `A = [1, 0, 2]ᵀ` as `U Ã` with `U = A/√5`, `Ã = √5`.
    fn shared() -> NestedFar {
        let mut f = two_level();
        let n = 5.0f32.sqrt();
        f.group_rank[0] = 1;
        f.group_basis_ptr = vec![0, 3, 3];
        f.group_basis = vec![1.0 / n, 0.0, 2.0 / n];
        f.a_ptr = vec![0, 1, 4];
        f.a = vec![n, 0.0, 0.05, 0.0];
        f
    }

    #[test]
    fn a_shared_row_basis_acts_as_the_explicit_factor() {
        let (f, g) = (two_level(), shared());
        g.validate(2, 2).expect("valid");
        assert!(g.bytes() < f.bytes() + 16);
        for (j, mix) in [(0u32, [1.0, 0.0, 0.0]), (1, [0.3, -1.0, 2.0])] {
            let (mut a, mut b) = (vec![0.0; 6], vec![0.0; 6]);
            f.add(&[(j, 1.5)], mix, &mut a);
            g.add(&[(j, 1.5)], mix, &mut b);
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-6, "{a:?} vs {b:?}");
            }
        }
        let ex = g.explicit_a(0);
        for (x, y) in ex.iter().zip([1.0, 0.0, 2.0]) {
            assert!((x - y).abs() < 1e-6);
        }
        // Dropping the group's only node empties its basis and keeps the blocks whole.
        let mut h = shared();
        h.remap_nodes(&[0, u32::MAX]);
        h.validate(2, 1).expect("valid");
        assert!(h.group_basis.is_empty());
        assert_eq!(h.a.len(), 4);
        // A basis of the wrong size is named.
        let mut bad = shared();
        bad.group_basis.pop();
        bad.group_basis_ptr[1] = 2;
        bad.group_basis_ptr[2] = 2;
        assert!(matches!(
            bad.validate(2, 2),
            Err(FarFieldError::Length { .. })
        ));
    }

    #[test]
    fn truncation_drops_small_block_terms_and_keeps_the_bases() {
        assert_eq!(
            two_level().truncated(0.1),
            two_level(),
            "the build tolerance keeps all"
        );
        let f = two_level().truncated(0.2);
        f.validate(2, 2).expect("valid");
        assert_eq!(f.rank, vec![1, 0]);
        assert_eq!(f.basis, two_level().basis);
        let mut out = vec![0.0; 6];
        f.add(&[(1, 1.0)], [0.0, 0.0, 1.0], &mut out);
        assert!(out[..3].iter().all(|&v| v == 0.0));
        // The same with a shared row basis: a block truncated to rank 0 adds nothing.
        let g = shared().truncated(10.0);
        g.validate(2, 2).expect("valid");
        assert_eq!(g.rank, vec![0, 0]);
        let mut out = vec![0.0; 6];
        g.add(&[(0, 1.0), (1, 1.0)], [1.0, 1.0, 1.0], &mut out);
        assert!(out.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn remapping_drops_rows_and_keeps_the_rest() {
        let mut f = two_level();
        f.remap_nodes(&[u32::MAX, 0]);
        f.validate(2, 1).expect("valid");
        assert_eq!(f.group_rows, vec![0]);
        assert_eq!(f.a, vec![1.0, 0.0, 2.0]);
    }

    #[test]
    fn bad_parents_and_indices_are_named() {
        let mut f = two_level();
        f.parent[0] = 2;
        assert!(matches!(
            f.validate(2, 2),
            Err(FarFieldError::Parent { cluster: 0, .. })
        ));
        let mut f = two_level();
        f.leaf_slot[1] = 4;
        assert!(f.validate(2, 2).is_err());
        let mut f = two_level();
        f.group_rows[0] = 7;
        assert!(matches!(
            f.validate(2, 2),
            Err(FarFieldError::NoSuchNode { node: 7, .. })
        ));
        let mut f = two_level();
        f.b[0] = f32::INFINITY;
        assert!(matches!(f.validate(2, 2), Err(FarFieldError::NotFinite)));
    }
}
