//! Cluster trees and the hierarchical block partition that compresses the nodal
//! vademecum's remainder into [`FarBlocks`] plus a dense near part.
//!
//! Both point sets (surface nodes for the rows, load nodes for the columns) are split
//! recursively at the median of their bounding box's longest side until a cluster holds
//! at most `leaf` nodes. A pair of clusters `(ρ, γ)` is *admissible* when
//! `min(diam ρ, diam γ) ≤ η · dist(ρ, γ)` (bounding boxes): the kernel is smooth across
//! it. An admissible block is replaced by its truncated SVD, keeping singular values
//! above the tolerance (the map's columns are scaled to unit norm first, so the
//! tolerance is relative to one load's response), as long as the rank stays at most
//! [`MAX_RANK`] and the factors are smaller than the block; otherwise both clusters are
//! split and the children are tried. Pairs of leaves that are never admissible are the
//! dense near field.

use faer::{Mat, MatRef};

use crate::farfield::{FarBlocks, MAX_RANK};
use crate::mesh::bounds_of;
use crate::tensor::dense::thin_svd;

/// Options of the compression.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FarSettings {
    /// Admissibility parameter η.
    pub eta: f64,
    /// Largest cluster that is not split.
    pub leaf: usize,
    /// Singular values at or below this (unit-column scale) are dropped.
    pub tolerance: f64,
}

impl Default for FarSettings {
    fn default() -> Self {
        FarSettings {
            eta: 3.0,
            leaf: 16,
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

enum Leaf {
    /// `R[ρ, γ] ≈ U Wᵀ` (scaled columns); U already carries the singular values.
    LowRank {
        rows: usize,
        cols: usize,
        u: Mat<f64>,
        w: Mat<f64>,
    },
    Dense {
        rows: usize,
        cols: usize,
    },
}

struct Ctx<'a> {
    res: MatRef<'a, f64>,
    rt: &'a Tree,
    ct: &'a Tree,
    s: FarSettings,
}

impl Ctx<'_> {
    fn block(&self, r: usize, c: usize) -> Mat<f64> {
        let (rm, cm) = (self.rt.members(r), self.ct.members(c));
        Mat::from_fn(3 * rm.len(), 3 * cm.len(), |i, j| {
            self.res[(3 * rm[i / 3] + i % 3, 3 * cm[j / 3] + j % 3)]
        })
    }

    fn go(&self, r: usize, c: usize) -> Vec<Leaf> {
        let (rn, cn) = (&self.rt.nodes[r], &self.ct.nodes[c]);
        let dist = box_distance(rn, cn);
        let admissible = dist > 0.0 && self.rt.diam(r).min(self.ct.diam(c)) <= self.s.eta * dist;
        if admissible {
            let b = self.block(r, c);
            let (m, n) = (b.nrows(), b.ncols());
            if let Some(svd) = thin_svd(b.as_ref()) {
                let k = svd.s.iter().take_while(|&&s| s > self.s.tolerance).count();
                if k <= MAX_RANK && k * (m + n) < m * n {
                    let u = Mat::from_fn(m, k, |i, j| svd.u[(i, j)] * svd.s[j]);
                    let w = Mat::from_fn(n, k, |i, j| svd.v[(i, j)]);
                    return vec![Leaf::LowRank {
                        rows: r,
                        cols: c,
                        u,
                        w,
                    }];
                }
            }
        }
        match (rn.kids, cn.kids) {
            (None, None) => vec![Leaf::Dense { rows: r, cols: c }],
            (Some((a, b)), None) => {
                let (mut x, y) = rayon::join(|| self.go(a, c), || self.go(b, c));
                x.extend(y);
                x
            }
            (None, Some((a, b))) => {
                let (mut x, y) = rayon::join(|| self.go(r, a), || self.go(r, b));
                x.extend(y);
                x
            }
            (Some((ra, rb)), Some((ca, cb))) => {
                let ((mut x1, x2), (x3, x4)) = rayon::join(
                    || rayon::join(|| self.go(ra, ca), || self.go(ra, cb)),
                    || rayon::join(|| self.go(rb, ca), || self.go(rb, cb)),
                );
                x1.extend(x2);
                x1.extend(x3);
                x1.extend(x4);
                x1
            }
        }
    }
}

/// The compressed remainder.
#[derive(Debug)]
pub struct Compressed {
    pub far: FarBlocks,
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
    let rt = Tree::new(row_points, (0..row_points.len()).collect(), settings.leaf);
    let ct = Tree::new(
        col_points,
        (0..col_points.len()).filter(|&j| col_free[j]).collect(),
        settings.leaf,
    );
    let mut dense = vec![Vec::new(); col_points.len()];
    let mut far = FarBlocks {
        tolerance: settings.tolerance,
        eta: settings.eta,
        row_ptr: vec![0],
        u_ptr: vec![0],
        ..FarBlocks::default()
    };
    if rt.perm.is_empty() || ct.perm.is_empty() {
        far.col_ptr = vec![0; col_points.len() + 1];
        return Compressed { far, dense };
    }
    let ctx = Ctx {
        res,
        rt: &rt,
        ct: &ct,
        s: settings,
    };
    let leaves = ctx.go(0, 0);
    // Per load node: (block, its 3 × k rows of V, [c][k]).
    let mut per_col: Vec<Vec<(u32, Vec<f32>)>> = vec![Vec::new(); col_points.len()];
    for leaf in leaves {
        match leaf {
            Leaf::Dense { rows, cols } => {
                for &j in ct.members(cols) {
                    dense[j].extend_from_slice(rt.members(rows));
                }
            }
            Leaf::LowRank { rows, cols, u, w } => {
                let b = far.rank.len() as u32;
                let k = u.ncols();
                far.rank.push(k as u32);
                for (r, &i) in rt.members(rows).iter().enumerate() {
                    far.rows.push(row_nodes[i]);
                    for d in 0..3 {
                        far.u.extend((0..k).map(|kk| u[(3 * r + d, kk)] as f32));
                    }
                }
                far.row_ptr.push(far.rows.len() as u32);
                far.u_ptr.push(far.u.len() as u32);
                for (cl, &j) in ct.members(cols).iter().enumerate() {
                    let mut v = Vec::with_capacity(3 * k);
                    for c in 0..3 {
                        let sc = scale[3 * j + c];
                        v.extend((0..k).map(|kk| (w[(3 * cl + c, kk)] * sc) as f32));
                    }
                    per_col[j].push((b, v));
                }
            }
        }
    }
    far.col_ptr.push(0);
    for list in per_col {
        for (b, v) in list {
            far.col_block.push(b);
            far.v_off.push(far.v.len() as u32);
            far.v.extend(v);
        }
        far.col_ptr.push(far.col_block.len() as u32);
    }
    for d in &mut dense {
        d.sort_unstable();
    }
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
        let stored = 9 * dense_entries + c.far.u.len() + c.far.v.len();
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
