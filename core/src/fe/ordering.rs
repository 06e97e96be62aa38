//! The fill-reducing ordering of the sparse Cholesky factors: nested dissection.
//!
//! A Cholesky factor `L` of `P A Pᵀ` fills in where the elimination of an unknown
//! couples its neighbours. How much depends on the order `P`. faer's default,
//! approximate minimum degree (AMD), eliminates greedily the unknown with the fewest
//! neighbours; *nested dissection* splits the graph of `A` by a small separator `S`
//! into two halves, orders each half recursively, and `S` last, so no fill crosses
//! between the halves. On a 3-D mesh of `n` unknowns a plane separator has about
//! `n^{2/3}` of them, which bounds the factor's entries by `O(n^{4/3})` and its work by
//! `O(n²)`; minimum degree carries no such bound, and on these meshes fills more.
//!
//! The separators come from METIS (`METIS_NodeND`: multilevel coarsening, bisection
//! of the coarse graph, refinement on the way back), on the graph of the *nodes*: the
//! pattern of a finite-element matrix is made of 3 × 3 blocks (a node's three
//! displacement components couple to the same neighbours), and each node's three
//! unknowns are kept together, which also keeps faer's supernodes whole. The node
//! order is expanded to the unknowns, `3i, 3i + 1, 3i + 2`.
//!
//! Measured on the liver's rest stiffness, P2, one thread, on the otherwise idle
//! two-core machine (`palpa lab bench fe --only ordering`):
//!
//! | mesh | unknowns | factor entries, AMD → ND | double factorization | one solve |
//! |---|---|---|---|---|
//! | coarse | 38 247 | 41.5 M → 25.7 M | 1.21 → 0.58 s | 35 → 25 ms |
//! | medium | 178 869 | 520 M → 265 M | 47.9 → 14.7 s | 337 → 188 ms |
//!
//! A tissue build's presses are about a quarter cheaper on coarse and two and a half
//! times on medium, in about half the memory (docs/lab/tissue-measurements.md §4).
//!
//! The ordering is deterministic: METIS seeds its own generator with a fixed seed
//! (4321 where none is set), so the same pattern always gets the same order, and a
//! build the same factors (a unit test orders a pattern twice).
//!
//! Matrices of fewer than [`MIN_NODES`] nodes keep AMD, as does a build without the
//! `metis` feature (the mobile libraries, which evaluate meta-models and factor
//! nothing large).

/// The lower triangle's pattern of a symmetric matrix in compressed columns: column
/// `c`'s rows are `row_idx[col_ptr[c]..col_ptr[c + 1]]`, sorted, the diagonal first.
/// (`fe::sparse::SymCsc` lends its own; the ordering needs nothing else of a matrix.)
#[derive(Debug, Clone, Copy)]
pub struct Pattern<'a> {
    pub n: usize,
    pub col_ptr: &'a [usize],
    pub row_idx: &'a [usize],
}

/// Below this many nodes (blocks) a matrix keeps faer's AMD: its factor is small
/// whatever the order, and the unit tests' tiny matrices stay as they were.
pub const MIN_NODES: usize = 200;

/// A nested-dissection order of `a`'s unknowns, as `(fwd, inv)`: the factored matrix's
/// `i`-th unknown is `a`'s `fwd[i]`, and `inv` is its inverse (faer's convention). `None`
/// where AMD is kept: a matrix under [`MIN_NODES`] nodes, a build without METIS, or a
/// METIS failure (then AMD is still a correct order, only a denser one).
pub fn nested_dissection(a: Pattern) -> Option<(Vec<usize>, Vec<usize>)> {
    let block = block_size(a);
    let nodes = a.n / block;
    if nodes < MIN_NODES {
        return None;
    }
    let (xadj, adjncy) = node_graph(a, block);
    let node_fwd = metis::node_nd(&xadj, &adjncy)?;
    let fwd: Vec<usize> = node_fwd
        .iter()
        .flat_map(|&v| (0..block).map(move |c| block * v + c))
        .collect();
    let mut inv = vec![usize::MAX; a.n];
    for (i, &f) in fwd.iter().enumerate() {
        inv[f] = i;
    }
    // `node_nd` checked that its answer is a permutation of the nodes.
    debug_assert!(inv.iter().all(|&i| i != usize::MAX));
    Some((fwd, inv))
}

/// 3 when `a`'s pattern is made of 3 × 3 node blocks (every node's three columns hold
/// the same rows below their diagonal block, as `SymCsc::pattern` makes them), else 1.
fn block_size(a: Pattern) -> usize {
    if !a.n.is_multiple_of(3) || a.n == 0 {
        return 1;
    }
    let rows = |c: usize| &a.row_idx[a.col_ptr[c]..a.col_ptr[c + 1]];
    let beyond = |c: usize, first: usize| {
        let r = rows(c);
        &r[r.partition_point(|&x| x < first)..]
    };
    let blocked = (0..a.n / 3).all(|j| {
        let (c, next) = (3 * j, 3 * j + 3);
        let own = beyond(c, next);
        // The diagonal block's lower triangle, then the same rows in all three columns.
        rows(c).starts_with(&[c, c + 1, c + 2])
            && rows(c + 1).starts_with(&[c + 1, c + 2])
            && rows(c + 2).first() == Some(&(c + 2))
            && beyond(c + 1, next) == own
            && beyond(c + 2, next) == own
    });
    if blocked { 3 } else { 1 }
}

/// The graph of `a`'s blocks in METIS's compressed form: `adjncy[xadj[v]..xadj[v+1]]`
/// are `v`'s neighbours, each edge both ways, no self-loops.
fn node_graph(a: Pattern, block: usize) -> (Vec<usize>, Vec<usize>) {
    let nodes = a.n / block;
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for c in (0..a.n).step_by(block) {
        for &r in &a.row_idx[a.col_ptr[c]..a.col_ptr[c + 1]] {
            let (u, v) = (r / block, c / block);
            if u != v {
                adj[u].push(v);
                adj[v].push(u);
            }
        }
    }
    let mut xadj = Vec::with_capacity(nodes + 1);
    xadj.push(0);
    let mut adjncy = Vec::new();
    for list in &mut adj {
        list.sort_unstable();
        list.dedup();
        adjncy.extend_from_slice(list);
        xadj.push(adjncy.len());
    }
    (xadj, adjncy)
}

#[cfg(feature = "metis")]
#[allow(unsafe_code)]
mod metis {
    use std::sync::{Mutex, PoisonError};

    use metis_sys::{
        METIS_NOPTIONS, METIS_NodeND, METIS_SetDefaultOptions, idx_t, rstatus_et_METIS_OK,
    };

    /// METIS keeps its random generator's state in a global (GKlib's `mt`), and swaps
    /// the process's SIGABRT and SIGTERM handlers while it runs: one call at a time.
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

    /// METIS's nested-dissection order of the graph (`fwd[i]`: the node placed `i`-th),
    /// or `None` where the graph does not fit METIS's 32-bit indices or METIS fails.
    pub fn node_nd(xadj: &[usize], adjncy: &[usize]) -> Option<Vec<usize>> {
        let to_idx = |v: &[usize]| -> Option<Vec<idx_t>> {
            v.iter().map(|&x| idx_t::try_from(x).ok()).collect()
        };
        let (mut xadj, mut adjncy) = (to_idx(xadj)?, to_idx(adjncy)?);
        let mut nvtxs = idx_t::try_from(xadj.len().checked_sub(1)?).ok()?;
        let n = xadj.len() - 1;
        let (mut perm, mut iperm) = (vec![0 as idx_t; n], vec![0 as idx_t; n]);
        let mut options = [0 as idx_t; METIS_NOPTIONS as usize];
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(PoisonError::into_inner);
        // SAFETY: `options` has METIS_NOPTIONS entries, which METIS_SetDefaultOptions
        // writes. METIS_NodeND reads `nvtxs`, `xadj` (nvtxs + 1 entries), `adjncy`
        // (xadj[nvtxs] entries, each a vertex below nvtxs: the graph is built from a
        // pattern's own indices) and `options`, and writes nvtxs entries into each of
        // `perm` and `iperm`, both that long. A null `vwgt` means unit weights. The
        // buffers outlive the calls, and METIS keeps no pointer to them.
        let rc = unsafe {
            METIS_SetDefaultOptions(options.as_mut_ptr());
            METIS_NodeND(
                &mut nvtxs,
                xadj.as_mut_ptr(),
                adjncy.as_mut_ptr(),
                std::ptr::null_mut(),
                options.as_mut_ptr(),
                perm.as_mut_ptr(),
                iperm.as_mut_ptr(),
            )
        };
        crate::cpu::clear_upper_halves();
        if rc != rstatus_et_METIS_OK {
            return None;
        }
        // METIS's `perm` is the order in faer's sense (checked by the fill it gives:
        // the other way round, the coarse liver's factor had 802 M entries, not 26 M).
        let fwd: Vec<usize> = perm
            .iter()
            .map(|&p| usize::try_from(p).ok())
            .collect::<Option<_>>()?;
        let mut seen = vec![false; n];
        for &f in &fwd {
            if f >= n || std::mem::replace(&mut seen[f], true) {
                return None;
            }
        }
        Some(fwd)
    }
}

#[cfg(not(feature = "metis"))]
mod metis {
    /// Without METIS there is no nested dissection: AMD is kept.
    pub fn node_nd(_xadj: &[usize], _adjncy: &[usize]) -> Option<Vec<usize>> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::sparse::SymCsc;

    /// The 3-D grid Laplacian of `m³` nodes, each node a 3 × 3 identity-coupled block
    /// (the pattern of a vector problem), lower triangle.
    fn grid(m: usize) -> SymCsc {
        let id = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
        let nodes = m * m * m;
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], Vec::new(), Vec::new());
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    let v = id(i, j, k);
                    let mut nb = vec![v];
                    if k + 1 < m {
                        nb.push(id(i, j, k + 1));
                    }
                    if j + 1 < m {
                        nb.push(id(i, j + 1, k));
                    }
                    if i + 1 < m {
                        nb.push(id(i + 1, j, k));
                    }
                    for c in 0..3 {
                        for (q, &w) in nb.iter().enumerate() {
                            let first = if q == 0 { c } else { 0 };
                            for d in first..3 {
                                row_idx.push(3 * w + d);
                                val.push(if q == 0 && d == c {
                                    6.5
                                } else if q == 0 {
                                    0.1
                                } else {
                                    -1.0
                                });
                            }
                        }
                        col_ptr.push(row_idx.len());
                    }
                }
            }
        }
        assert_eq!(col_ptr.len(), 3 * nodes + 1);
        SymCsc {
            n: 3 * nodes,
            col_ptr,
            row_idx,
            val,
        }
    }

    #[test]
    fn a_node_blocked_pattern_is_found_and_a_scalar_one_is_not() {
        let a = grid(4);
        assert_eq!(block_size(a.pattern_ref()), 3);
        // Drop one off-block entry from a node's second column: no longer blocked.
        let mut b = a.clone();
        let c = 1;
        let last = b.col_ptr[c + 1] - 1;
        b.row_idx.remove(last);
        b.val.remove(last);
        for p in &mut b.col_ptr[c + 1..] {
            *p -= 1;
        }
        assert_eq!(block_size(b.pattern_ref()), 1);
    }

    /// The order is a permutation that keeps each node's unknowns together, on a 3-D
    /// grid it fills the factor less than AMD (what it is for), and the factorizations
    /// of `fe::sparse` use it.
    #[cfg(feature = "metis")]
    #[test]
    fn nested_dissection_fills_a_3d_grid_less_than_amd() {
        use faer::perm::PermRef;
        use faer::sparse::linalg::cholesky::{SymmetricOrdering, factorize_symbolic_cholesky};
        let a = grid(14);
        let (fwd, inv) = nested_dissection(a.pattern_ref()).expect("large enough for METIS");
        for (i, &f) in fwd.iter().enumerate() {
            assert_eq!(inv[f], i);
            assert_eq!(f % 3, i % 3, "a node's unknowns stay in order, together");
        }
        let m = a.to_faer();
        let entries = |ord| {
            factorize_symbolic_cholesky(m.symbolic(), faer::Side::Lower, ord, Default::default())
                .expect("symbolic")
                .len_val()
        };
        let amd = entries(SymmetricOrdering::Amd);
        let nd = entries(SymmetricOrdering::Custom(PermRef::new_checked(
            &fwd, &inv, a.n,
        )));
        assert!(nd < amd, "ND {nd} entries, AMD {amd}");
        // And it is the order every factorization of the pattern uses.
        let used = crate::fe::sparse::factor_entries(&a).expect("analysis");
        assert_eq!(used, nd as u64);
        // The same pattern, the same order.
        assert_eq!(nested_dissection(a.pattern_ref()).expect("again").0, fwd);
    }

    #[test]
    fn a_small_matrix_keeps_amd() {
        assert!(nested_dissection(grid(3).pattern_ref()).is_none());
    }
}
