//! Cluster trees, the hierarchical block partition and the nested-basis compression of
//! the nodal vademecum's remainder into a [`NestedFar`] plus a dense near part.
//!
//! Both point sets (surface nodes for the rows, load nodes for the columns) are split
//! recursively at the median of their bounding box's longest side until a cluster holds
//! at most `row_leaf` / `leaf` nodes. A pair of clusters `(ρ, γ)` is *admissible* when
//! `max(diam ρ, diam γ) ≤ η · dist(ρ, γ)` (bounding boxes): the kernel is smooth across
//! it, and the block becomes low rank. Requiring both patches to be small against
//! their distance (rather than the smaller one) keeps a tiny row patch from pairing
//! with a huge load patch next to it, whose coupling to the patch's basis would cost
//! more than it saves. Pairs of leaves that are never admissible are the
//! dense near field.
//!
//! The column bases are built bottom-up. `F*(γ)` is the set of rows of every admissible
//! block of `γ` and of its ancestors (it only shrinks going up). For a leaf,
//! `V_γ` is the right singular basis of `R[F*(γ), γ]` above the tolerance; for an inner
//! cluster with children `a`, `b`, `E_γ` is that of
//! `[R[F*(γ), a] V_a, R[F*(γ), b] V_b]` and `V_γ = diag(V_a, V_b) E_γ`. The products
//! `P_γ = R[F*(γ), γ] V_γ` are carried up the recursion, so `R` is read once per leaf.
//! Each block `(ρ, γ)` is then the truncated SVD of `P_γ[ρ]` (`A Bᵀ`-form, see
//! [`crate::farfield`]). The map's columns are scaled to unit norm first, so every
//! tolerance is relative to one load's response; a dropped basis direction carries at
//! most the tolerance into any block of the patch, once per level.
//!
//! Last, the blocks of one row cluster (a row group) share a row basis where that
//! saves numbers: the left singular basis `U_ρ` of `[A_b …]` over the group's blocks,
//! with each block keeping `U_ρᵀ A_b` (`share_row_bases`).

use faer::{Mat, MatRef};

use crate::farfield::{MAX_BASIS, NestedFar};
use crate::mesh::bounds_of;
use crate::tensor::dense::thin_svd;

/// Options of the compression.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FarSettings {
    /// Admissibility parameter η (`max(diam) ≤ η · dist`).
    pub eta: f64,
    /// Largest load-node (column) cluster that is not split.
    pub leaf: usize,
    /// Largest surface-node (row) cluster that is not split. Small row leaves keep the
    /// dense band narrow (a load node couples densely only with the row leaves that are
    /// never admissible against its leaf); the nested column bases keep the many small
    /// blocks this makes cheap.
    pub row_leaf: usize,
    /// Singular values at or below this (unit-column scale) are dropped.
    pub tolerance: f64,
}

impl FarSettings {
    /// The defaults for a tool of `radius_mm`: tolerance 0.01 from 5 mm up, scaled
    /// down with the radius to 0.006 (measured on coarse P2: a 2 mm tool's held-out max
    /// nodal error is 4.0 % at 0.01 and 2.3 % at 0.007; a concentrated load's peak sits
    /// closer to the far blocks, which carry more of its error).
    pub fn for_tool(radius_mm: f64) -> FarSettings {
        let scale = if radius_mm.is_finite() {
            (radius_mm / 5.0).clamp(0.6, 1.0)
        } else {
            1.0
        };
        FarSettings {
            tolerance: 1e-2 * scale,
            ..FarSettings::default()
        }
    }
}

impl Default for FarSettings {
    fn default() -> Self {
        FarSettings {
            eta: 5.0,
            leaf: 16,
            row_leaf: 4,
            tolerance: 1e-2,
        }
    }
}

#[derive(Debug, Clone)]
struct Cluster {
    lo: usize,
    hi: usize,
    min: [f64; 3],
    max: [f64; 3],
    kids: Option<(usize, usize)>,
}

#[derive(Debug)]
struct Tree {
    /// Point indices, permuted so that every cluster is a contiguous range.
    perm: Vec<usize>,
    nodes: Vec<Cluster>,
}

impl Tree {
    fn new(points: &[[f64; 3]], ids: Vec<usize>, leaf: usize) -> Tree {
        let mut t = Tree {
            perm: ids,
            nodes: Vec::new(),
        };
        let n = t.perm.len();
        t.split(points, 0, n, leaf.max(1));
        t
    }

    /// Builds the cluster of `perm[lo..hi]` and its descendants; returns its index.
    fn split(&mut self, points: &[[f64; 3]], lo: usize, hi: usize, leaf: usize) -> usize {
        let (min, max) = bounds_of(self.perm[lo..hi].iter().map(|&i| &points[i]));
        let me = self.nodes.len();
        self.nodes.push(Cluster {
            lo,
            hi,
            min,
            max,
            kids: None,
        });
        if hi - lo > leaf {
            let axis = (0..3)
                .max_by(|&a, &b| (max[a] - min[a]).total_cmp(&(max[b] - min[b])))
                .unwrap_or(0);
            self.perm[lo..hi].sort_by(|&a, &b| points[a][axis].total_cmp(&points[b][axis]));
            let mid = lo + (hi - lo) / 2;
            let a = self.split(points, lo, mid, leaf);
            let b = self.split(points, mid, hi, leaf);
            self.nodes[me].kids = Some((a, b));
        }
        me
    }

    fn diam(&self, c: usize) -> f64 {
        let n = &self.nodes[c];
        (0..3)
            .map(|d| (n.max[d] - n.min[d]).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    fn members(&self, c: usize) -> &[usize] {
        &self.perm[self.nodes[c].lo..self.nodes[c].hi]
    }
}

fn box_distance(a: &Cluster, b: &Cluster) -> f64 {
    (0..3)
        .map(|d| {
            let gap = (b.min[d] - a.max[d]).max(a.min[d] - b.max[d]).max(0.0);
            gap * gap
        })
        .sum::<f64>()
        .sqrt()
}

/// Per column cluster, the row clusters of its admissible blocks; and the pairs of
/// leaves that are never admissible.
struct Partition {
    admissible: Vec<Vec<usize>>,
    dense: Vec<(usize, usize)>,
}

fn partition(rt: &Tree, ct: &Tree, eta: f64) -> Partition {
    let mut p = Partition {
        admissible: vec![Vec::new(); ct.nodes.len()],
        dense: Vec::new(),
    };
    let mut stack = vec![(0usize, 0usize)];
    while let Some((r, c)) = stack.pop() {
        let (rn, cn) = (&rt.nodes[r], &ct.nodes[c]);
        let dist = box_distance(rn, cn);
        if dist > 0.0 && rt.diam(r).max(ct.diam(c)) <= eta * dist {
            p.admissible[c].push(r);
            continue;
        }
        match (rn.kids, cn.kids) {
            (None, None) => p.dense.push((r, c)),
            (Some((a, b)), None) => stack.extend([(a, c), (b, c)]),
            (None, Some((a, b))) => stack.extend([(r, a), (r, b)]),
            (Some((ra, rb)), Some((ca, cb))) => {
                stack.extend([(ra, ca), (ra, cb), (rb, ca), (rb, cb)]);
            }
        }
    }
    p
}

/// One low-rank block: its row cluster, `A` (3·|ρ| × r, f64 until the row bases are
/// chosen) and `B` (row-major).
struct BlockOut {
    row_cluster: usize,
    a: Mat<f64>,
    b: Vec<f32>,
}

/// What one column cluster contributes to the stored far field.
#[derive(Default)]
struct PatchOut {
    basis_rows: usize,
    rank: usize,
    basis: Vec<f32>,
    blocks: Vec<BlockOut>,
}

struct Ctx<'a> {
    res: MatRef<'a, f64>,
    scale: &'a [f64],
    rt: &'a Tree,
    ct: &'a Tree,
    /// Per column cluster: the row clusters of its admissible blocks.
    admissible: &'a [Vec<usize>],
    /// Per column cluster: sorted row points of its and its ancestors' far blocks.
    far_rows: &'a [Vec<usize>],
    tolerance: f64,
}

/// The terms of `m`'s SVD above the tolerance, at most `cap`: `(U S, V)`.
fn truncate(m: MatRef<'_, f64>, tolerance: f64, cap: usize) -> (Mat<f64>, Mat<f64>) {
    let Some(svd) = thin_svd(m) else {
        return (Mat::zeros(m.nrows(), 0), Mat::zeros(m.ncols(), 0));
    };
    let k = svd
        .s
        .iter()
        .take_while(|&&s| s > tolerance)
        .count()
        .min(cap);
    (
        Mat::from_fn(m.nrows(), k, |i, j| svd.u[(i, j)] * svd.s[j]),
        Mat::from_fn(m.ncols(), k, |i, j| svd.v[(i, j)]),
    )
}

impl Ctx<'_> {
    /// Builds cluster `c` and its subtree bottom-up. Returns `P_c = R[F*(c), c] V_c`
    /// (rows: `far_rows[c]`, three per point) and every cluster's output, by index.
    fn build(&self, c: usize) -> (Mat<f64>, Vec<(usize, PatchOut)>) {
        let fr = &self.far_rows[c];
        let (p, mut outs, mut me) = match self.ct.nodes[c].kids {
            None => {
                let cols = self.ct.members(c);
                let m = Mat::from_fn(3 * fr.len(), 3 * cols.len(), |i, j| {
                    self.res[(3 * fr[i / 3] + i % 3, 3 * cols[j / 3] + j % 3)]
                });
                let (p, v) = truncate(m.as_ref(), self.tolerance, MAX_BASIS);
                let k = v.ncols();
                // The stored basis carries the column scaling: coefficients of a true load.
                let mut basis = Vec::with_capacity(v.nrows() * k);
                for (l, &j) in cols.iter().enumerate() {
                    for d in 0..3 {
                        let sc = self.scale[3 * j + d];
                        basis.extend((0..k).map(|kk| (v[(3 * l + d, kk)] * sc) as f32));
                    }
                }
                let me = PatchOut {
                    basis_rows: 3 * cols.len(),
                    rank: k,
                    basis,
                    blocks: Vec::new(),
                };
                (p, Vec::new(), me)
            }
            Some((a, b)) => {
                let ((pa, mut oa), (pb, ob)) = rayon::join(|| self.build(a), || self.build(b));
                let (ka, kb) = (pa.ncols(), pb.ncols());
                let (fa, fb) = (&self.far_rows[a], &self.far_rows[b]);
                // F*(c) ⊆ F*(kid): pick the kids' rows at c's far rows.
                let at = |f: &[usize], x: usize| f.binary_search(&x).expect("F*(c) ⊆ F*(kid)");
                let m = Mat::from_fn(3 * fr.len(), ka + kb, |i, j| {
                    let x = fr[i / 3];
                    if j < ka {
                        pa[(3 * at(fa, x) + i % 3, j)]
                    } else {
                        pb[(3 * at(fb, x) + i % 3, j - ka)]
                    }
                });
                let (p, e) = truncate(m.as_ref(), self.tolerance, MAX_BASIS);
                let k = e.ncols();
                let basis = (0..ka + kb)
                    .flat_map(|i| (0..k).map(move |kk| (i, kk)))
                    .map(|(i, kk)| e[(i, kk)] as f32)
                    .collect();
                oa.extend(ob);
                let me = PatchOut {
                    basis_rows: ka + kb,
                    rank: k,
                    basis,
                    blocks: Vec::new(),
                };
                (p, oa, me)
            }
        };
        let k = p.ncols();
        if k > 0 {
            for &r in &self.admissible[c] {
                let rows = self.rt.members(r);
                let cb = Mat::from_fn(3 * rows.len(), k, |i, j| {
                    let at = fr.binary_search(&rows[i / 3]).expect("block rows ⊆ F*(c)");
                    p[(3 * at + i % 3, j)]
                });
                let (a, bt) = truncate(cb.as_ref(), self.tolerance, MAX_BASIS);
                let rank = a.ncols();
                if rank == 0 {
                    continue;
                }
                let b_rm = (0..rank)
                    .flat_map(|rr| (0..k).map(move |kk| (rr, kk)))
                    .map(|(rr, kk)| bt[(kk, rr)] as f32)
                    .collect();
                me.blocks.push(BlockOut {
                    row_cluster: r,
                    a,
                    b: b_rm,
                });
            }
        }
        outs.push((c, me));
        (p, outs)
    }
}

/// The row bases' cut as a share of the blocks' tolerance. Measured (held-out L2 /
/// max nodal, f32 scene): coarse P2 without row bases 1.12 % / 1.75 %, 7.0 MB; at half
/// the tolerance 1.15 % / 1.75 %, 6.4 MB; at the tolerance 1.21 % / 1.73 %, 6.2 MB.
/// Medium P2 at the tolerance: 0.84 % / 2.96 %, 18.3 MB, too close to the 3 % goal;
/// half of it is the default.
const ROW_BASIS_SHARE: f64 = 0.5;

/// Groups the blocks by row cluster (numbered by first appearance) and gives each group
/// whose blocks' `A`s span few directions a shared orthonormal basis `U` (the left
/// singular vectors of `[A_b …]` above `tolerance`), storing `Uᵀ A_b` per block; a
/// group keeps its `A`s explicit where the basis would cost more than it saves.
///
/// The row cut moves each `A_b B_b` by at most `tolerance` in the 2-norm (`B_b` has
/// orthonormal rows).
fn share_row_bases(
    far: &mut NestedFar,
    blocks: Vec<BlockOut>,
    nodes_of: impl Fn(usize) -> Vec<u32>,
    tolerance: f64,
) {
    use rayon::prelude::*;
    let mut group_of = std::collections::HashMap::new();
    let mut members: Vec<Vec<usize>> = Vec::new();
    for (b, blk) in blocks.iter().enumerate() {
        let q = *group_of.entry(blk.row_cluster).or_insert_with(|| {
            members.push(Vec::new());
            members.len() - 1
        });
        members[q].push(b);
        far.block_group.push(q as u32);
    }
    let mut cluster_of = vec![0; members.len()];
    for (&c, &q) in &group_of {
        cluster_of[q] = c;
    }
    let bases: Vec<Option<Mat<f64>>> = members
        .par_iter()
        .map(|bs| {
            let n = blocks[bs[0]].a.nrows();
            let sum_r: usize = bs.iter().map(|&b| blocks[b].a.ncols()).sum();
            if bs.len() < 2 || sum_r == 0 {
                return None;
            }
            let mut w = Mat::zeros(n, sum_r);
            let mut at = 0;
            for &b in bs {
                let a = &blocks[b].a;
                w.as_mut().submatrix_mut(0, at, n, a.ncols()).copy_from(a);
                at += a.ncols();
            }
            let svd = thin_svd(w.as_ref())?;
            let k = svd
                .s
                .iter()
                .take_while(|&&s| s > tolerance)
                .count()
                .min(MAX_BASIS);
            (k > 0 && n * k + k * sum_r < n * sum_r)
                .then(|| svd.u.as_ref().subcols(0, k).to_owned())
        })
        .collect();
    for (q, basis) in bases.iter().enumerate() {
        far.group_rows.extend(nodes_of(cluster_of[q]));
        far.group_ptr.push(far.group_rows.len() as u32);
        let k = basis.as_ref().map_or(0, |u| u.ncols());
        far.group_rank.push(k as u32);
        if let Some(u) = basis {
            far.group_basis
                .extend((0..u.nrows()).flat_map(|i| (0..k).map(move |kk| u[(i, kk)] as f32)));
        }
        far.group_basis_ptr.push(far.group_basis.len() as u32);
    }
    for (blk, &q) in blocks.into_iter().zip(&far.block_group) {
        let a = match &bases[q as usize] {
            Some(u) => u.transpose() * &blk.a,
            None => blk.a,
        };
        far.rank.push(a.ncols() as u32);
        far.a.extend(
            (0..a.nrows())
                .flat_map(|i| (0..a.ncols()).map(move |rr| (i, rr)))
                .map(|(i, rr)| a[(i, rr)] as f32),
        );
        far.a_ptr.push(far.a.len() as u32);
        far.b.extend(blk.b);
        far.b_ptr.push(far.b.len() as u32);
    }
}

/// The compressed remainder.
#[derive(Debug)]
pub struct Compressed {
    pub far: NestedFar,
    /// Per load node: the surface rows (indices into the row points) it couples with
    /// densely.
    pub dense: Vec<Vec<usize>>,
}

/// Compresses `res` (3·rows × 3·cols, columns scaled: the true remainder is
/// `res · diag(scale)`). `row_nodes` are the field nodes of the rows; `col_free`
/// marks the load nodes that carry a load (the others are skipped).
pub fn compress(
    res: MatRef<'_, f64>,
    scale: &[f64],
    row_points: &[[f64; 3]],
    row_nodes: &[u32],
    col_points: &[[f64; 3]],
    col_free: &[bool],
    settings: FarSettings,
) -> Compressed {
    let mut dense = vec![Vec::new(); col_points.len()];
    let mut far = NestedFar {
        tolerance: settings.tolerance,
        eta: settings.eta,
        leaf_of: vec![u32::MAX; col_points.len()],
        leaf_slot: vec![0; col_points.len()],
        basis_ptr: vec![0],
        block_ptr: vec![0],
        group_ptr: vec![0],
        group_basis_ptr: vec![0],
        a_ptr: vec![0],
        b_ptr: vec![0],
        ..NestedFar::default()
    };
    let free: Vec<usize> = (0..col_points.len()).filter(|&j| col_free[j]).collect();
    if row_points.is_empty() || free.is_empty() {
        return Compressed { far, dense };
    }
    let rt = Tree::new(
        row_points,
        (0..row_points.len()).collect(),
        settings.row_leaf,
    );
    let ct = Tree::new(col_points, free, settings.leaf);
    let part = partition(&rt, &ct, settings.eta);
    for &(r, c) in &part.dense {
        for &j in ct.members(c) {
            dense[j].extend_from_slice(rt.members(r));
        }
    }
    for d in &mut dense {
        d.sort_unstable();
    }
    // F*(c): the rows of c's far blocks and of its ancestors' (a parent comes first).
    let mut parent = vec![u32::MAX; ct.nodes.len()];
    let mut far_rows: Vec<Vec<usize>> = vec![Vec::new(); ct.nodes.len()];
    for c in 0..ct.nodes.len() {
        let mut f = if parent[c] == u32::MAX {
            Vec::new()
        } else {
            far_rows[parent[c] as usize].clone()
        };
        for &r in &part.admissible[c] {
            f.extend_from_slice(rt.members(r));
        }
        f.sort_unstable();
        f.dedup();
        far_rows[c] = f;
        if let Some((a, b)) = ct.nodes[c].kids {
            parent[a] = c as u32;
            parent[b] = c as u32;
        }
    }
    let ctx = Ctx {
        res,
        scale,
        rt: &rt,
        ct: &ct,
        admissible: &part.admissible,
        far_rows: &far_rows,
        tolerance: settings.tolerance,
    };
    let (_, mut outs) = ctx.build(0);
    outs.sort_unstable_by_key(|(c, _)| *c);
    far.parent = parent;
    far.kid_offset = vec![0; ct.nodes.len()];
    for (c, node) in ct.nodes.iter().enumerate() {
        if let Some((a, b)) = node.kids {
            far.kid_offset[b] = outs[a].1.rank as u32;
        } else {
            for (slot, &j) in ct.members(c).iter().enumerate() {
                far.leaf_of[j] = c as u32;
                far.leaf_slot[j] = slot as u32;
            }
        }
    }
    let mut blocks = Vec::new();
    for (_, out) in outs {
        far.basis_rank.push(out.rank as u32);
        far.basis_rows.push(out.basis_rows as u32);
        far.basis.extend(out.basis);
        far.basis_ptr.push(far.basis.len() as u32);
        blocks.extend(out.blocks);
        far.block_ptr.push(blocks.len() as u32);
    }
    share_row_bases(
        &mut far,
        blocks,
        |r| rt.members(r).iter().map(|&i| row_nodes[i]).collect(),
        settings.tolerance * ROW_BASIS_SHARE,
    );
    Compressed { far, dense }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A smooth kernel on random points: the dense part plus the low-rank blocks give
    /// the matrix back to about the tolerance, with fewer numbers than the matrix.
    #[test]
    fn a_smooth_kernel_is_reproduced_to_the_tolerance_from_fewer_numbers() {
        let mut rng = Rng::seed(17);
        let mut pts = |n: usize| -> Vec<[f64; 3]> {
            (0..n)
                .map(|_| {
                    [
                        rng.range(0.0, 100.0),
                        rng.range(0.0, 100.0),
                        rng.range(0.0, 10.0),
                    ]
                })
                .collect()
        };
        let (rp, cp) = (pts(150), pts(260));
        let kernel = |a: [f64; 3], b: [f64; 3], d: usize, c: usize| {
            let r2: f64 = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum();
            (1.0 + if d == c { 1.0 } else { 0.3 }) / (1.0 + r2).sqrt()
        };
        let a = Mat::from_fn(3 * rp.len(), 3 * cp.len(), |i, j| {
            kernel(rp[i / 3], cp[j / 3], i % 3, j % 3)
        });
        let scale = vec![2.0; 3 * cp.len()];
        let res = Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] / scale[j]);
        let row_nodes: Vec<u32> = (0..rp.len() as u32).collect();
        let free = vec![true; cp.len()];
        let tol = 1e-3;
        let c = compress(
            res.as_ref(),
            &scale,
            &rp,
            &row_nodes,
            &cp,
            &free,
            FarSettings {
                tolerance: tol,
                ..FarSettings::default()
            },
        );
        c.far.validate(cp.len(), rp.len()).expect("valid");
        assert!(c.far.blocks() > 0);
        let dense_entries: usize = c.dense.iter().map(Vec::len).sum();
        let stored = 9 * dense_entries + c.far.a.len() + c.far.b.len() + c.far.basis.len();
        assert!(
            stored < a.nrows() * a.ncols() * 3 / 4,
            "{stored} of {}",
            a.nrows() * a.ncols()
        );
        // Rebuild each column from the blocks and the dense rows.
        let mut worst = 0.0f64;
        for j in 0..cp.len() {
            for t in 0..3 {
                let mut dir = [0.0; 3];
                dir[t] = 1.0;
                let mut col = vec![0.0; a.nrows()];
                c.far.add(&[(j as u32, 1.0)], dir, &mut col);
                for &i in &c.dense[j] {
                    for d in 0..3 {
                        col[3 * i + d] += a[(3 * i + d, 3 * j + t)];
                    }
                }
                let err: f64 = (0..a.nrows())
                    .map(|i| (col[i] - a[(i, 3 * j + t)]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let norm: f64 = (0..a.nrows())
                    .map(|i| a[(i, 3 * j + t)].powi(2))
                    .sum::<f64>()
                    .sqrt();
                worst = worst.max(err / norm);
            }
        }
        // Each column is in a few dozen blocks, each off by at most `tol` (unit-column
        // scale); f32 storage adds 1e-7.
        assert!(worst < 30.0 * tol, "worst column error {worst}");
    }
}
