//! The nodal vademecum with a nodule as coordinates: any nodule inside declared ranges
//! answered exactly, without a solve, from stored interior responses.
//!
//! **The identity.** A nodule changes the stiffness only on the cells it touches
//! ([`crate::fe::nodule`]: cell `e` gets the factor `s_e`, a function of the nodule's
//! centre, radius and ratio). Element stiffness is linear in the modulus, so
//!
//! ```text
//! K(n) = K₀ + U C Uᵀ,   C = Σ_e (s_e − 1) K_e   (m × m, on the m free unknowns of those cells)
//! ```
//!
//! with `U` selecting those unknowns. For any load `f`, with `G = K₀⁻¹` and `u₀ = G f`,
//! Woodbury's identity gives the displacement with the nodule exactly:
//!
//! ```text
//! u = u₀ − G_{:,p} z,   (I + C G_pp) z = C u₀|_p .
//! ```
//!
//! Every block of `G` on the right has its columns on the nodule's unknowns `p`:
//! `G_pp`, the rows a probe reads and a scene draws (`G_{L,p}`, `G_{S,p}`), and by
//! symmetry `u₀|_p = G_{p,L} f = (G_{L,p})ᵀ f`. So a store of `G`'s columns on every
//! unknown a nodule in the ranges can touch, at the rows of the load nodes, the surface
//! nodes and those unknowns, answers every such nodule: placing one is an `m × m`
//! factorization, a probe's compliance correction `δc = −φᵀ G_{:,p} z` a few `m`-long
//! products (`φ` the probe point's functional, itself a combination of load rows).
//!
//! **Off-line**: one solve per stored column, over the nodal build's factor of `K₀`.
//! **On-line**: [`InteriorResponses::place`] (the cells' factors, `C`, `G_pp`, the LU of
//! `I + C G_pp`) and [`PlacedNodule::correction`]. What a nodule's ratios share (its
//! cells, their stiffness, its unknowns, `G_pp`) is cut once ([`InteriorResponses::cut`])
//! and each ratio placed from it ([`NoduleCut::place`]): a table's build places every
//! centre and radius at two ratios. Nothing is approximated but the storage of `G` in
//! single precision, and the `m × m` system formed and factored in it (its condition is
//! about the ratio's: a few correct digits more than the table needs).

pub mod amplification;
pub mod heldout;
pub mod table;
pub mod training;

use std::time::Instant;

use faer::Mat;
use faer::linalg::solvers::Solve;
use rayon::prelude::*;
use thiserror::Error;

use super::nodal::NodalSetup;
use crate::fe::elasticity::{cell_dofs, element_stiffness};
use crate::fe::nodule::Nodule;
use crate::fe::space::Space;
use crate::mesh::{norm, sub};

/// Why a nodule could not be answered by a store.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NoduleStoreError {
    #[error(
        "the nodule's centre {center_mm:?} mm is {distance_mm:.1} mm from the stored region's centre {region_mm:?}; the store answers centres within {reach_mm:.1} mm"
    )]
    CentreOutside {
        center_mm: [f64; 3],
        region_mm: [f64; 3],
        distance_mm: f64,
        reach_mm: f64,
    },
    #[error("nodule radius {radius_mm} mm is outside the store's range {lo} to {hi} mm")]
    Radius { radius_mm: f64, lo: f64, hi: f64 },
    #[error("nodule ratio {ratio} is outside the store's range {lo} to {hi}")]
    Ratio { ratio: f64, lo: f64, hi: f64 },
    #[error(
        "the nodule touches cell {cell}, whose unknowns the store does not hold (its responses were stored for centres within {reach_mm:.1} mm and radii to {radius_mm:.1} mm)"
    )]
    CellNotStored {
        cell: usize,
        reach_mm: f64,
        radius_mm: f64,
    },
    #[error("the nodule's correction is singular (I + C G_pp has no inverse): ratio {ratio}")]
    Singular { ratio: f64 },
}

/// The nodules a store answers: centres within `reach_mm` of `center_mm` (each also
/// checked against the organ by [`Nodule::check`] before a solve would be), radii and
/// ratios in their closed ranges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoduleRanges {
    pub center_mm: [f64; 3],
    /// `f64::INFINITY`: anywhere in the organ.
    pub reach_mm: f64,
    pub radius_mm: (f64, f64),
    pub ratio: (f64, f64),
}

/// `G`'s columns on every free unknown a nodule in the ranges can touch, at the rows of
/// the load nodes, the surface nodes and those unknowns, in single precision.
#[derive(Debug, Clone)]
pub struct InteriorResponses {
    pub ranges: NoduleRanges,
    /// Free unknowns whose unit-load responses are stored, ascending.
    pub cols: Vec<u32>,
    /// Free unknowns at which they are stored, ascending.
    pub rows: Vec<u32>,
    /// For each free unknown: its row, or `u32::MAX`.
    row_of: Vec<u32>,
    /// For each free unknown: its column, or `u32::MAX`.
    col_of: Vec<u32>,
    /// `G[rows, cols]`, one column after another.
    g: Vec<f32>,
    /// The space of `K₀` (no nodule), for the cells' element stiffness.
    space: Space,
    lambda: f64,
    mu: f64,
    poisson: f64,
    pub build_s: f64,
}

/// Longest edge of cell `c`'s corners from its first corner, as
/// [`Nodule::cell_fractions`] bounds a cell (mm).
fn cell_size(space: &Space, c: usize) -> f64 {
    let t = space.cell_corners(c);
    (1..4).map(|i| norm(sub(t[i], t[0]))).fold(0.0, f64::max)
}

/// Marks every free unknown of the cells a nodule in `ranges` can touch (those
/// [`Nodule::cell_fractions`] can give a share: first corner within the radius plus the
/// cell's size of a centre).
fn mark_touched(space: &Space, ranges: &NoduleRanges, mark: &mut [bool]) {
    let mut dofs = Vec::new();
    for c in 0..space.cell_count() {
        let first = space.cell_corners(c)[0];
        let d = norm(sub(first, ranges.center_mm));
        if d <= ranges.reach_mm + ranges.radius_mm.1 + cell_size(space, c) {
            cell_dofs(space, c, &mut dofs);
            for &d in dofs.iter().filter(|&&d| d != usize::MAX) {
                mark[d] = true;
            }
        }
    }
}

/// The free unknowns marked, ascending, and each one's place among them.
fn indexed(mark: &[bool]) -> (Vec<u32>, Vec<u32>) {
    let list: Vec<u32> = (0..mark.len() as u32)
        .filter(|&d| mark[d as usize])
        .collect();
    let mut of = vec![u32::MAX; mark.len()];
    for (k, &d) in list.iter().enumerate() {
        of[d as usize] = k as u32;
    }
    (list, of)
}

/// Columns solved together: one multi-right-hand-side pass over the factor.
const BATCH: usize = 96;

impl InteriorResponses {
    /// Solves `K₀ g = e_j` for every free unknown `j` of the cells a nodule in `ranges`
    /// can touch, keeping the rows of `setup`'s load and surface nodes and of those
    /// unknowns.
    pub fn build(setup: &NodalSetup, ranges: NoduleRanges) -> InteriorResponses {
        Self::build_over(setup, &[ranges], true)
    }

    /// The store of every unknown a nodule in any of `regions` can touch (its `ranges`
    /// a sphere about them all), at the rows of those unknowns, and of `setup`'s load
    /// and surface nodes where `surface_rows`. Columns are solved in batches of
    /// [`BATCH`]; the factor's solve treats each right-hand side on its own, so a
    /// column's value does not depend on which others share its batch (shards of a
    /// build, whose stores hold other columns, agree bit for bit: `tests/nodule_table.rs`).
    pub fn build_over(
        setup: &NodalSetup,
        regions: &[NoduleRanges],
        surface_rows: bool,
    ) -> InteriorResponses {
        let t0 = Instant::now();
        let space = &setup.space;
        let n = space.free_dofs;
        let mut mark = vec![false; n];
        for r in regions {
            mark_touched(space, r, &mut mark);
        }
        let (cols, col_of) = indexed(&mark);
        if surface_rows {
            for &node in setup.load_nodes.iter().chain(&setup.surface_nodes) {
                let d = space.dof[node as usize];
                if d != u32::MAX {
                    for k in 0..3 {
                        mark[d as usize + k] = true;
                    }
                }
            }
        }
        let (rows, row_of) = indexed(&mark);
        let nr = rows.len();
        let mut g = vec![0.0f32; nr * cols.len()];
        let threads = rayon::current_num_threads().max(1);
        for (group_index, group) in cols.chunks(BATCH * threads).enumerate() {
            let solved: Vec<Mat<f64>> = group
                .par_chunks(BATCH)
                .map(|chunk| {
                    let mut rhs = Mat::<f64>::zeros(n, chunk.len());
                    for (k, &d) in chunk.iter().enumerate() {
                        rhs[(d as usize, k)] = 1.0;
                    }
                    setup.problem.factor.solve_many(&mut rhs);
                    rhs
                })
                .collect();
            let first = group_index * BATCH * threads;
            for (k, rhs) in solved.iter().enumerate() {
                for b in 0..rhs.ncols() {
                    let col = first + k * BATCH + b;
                    let out = &mut g[col * nr..(col + 1) * nr];
                    for (r, &d) in rows.iter().enumerate() {
                        out[r] = rhs[(d as usize, b)] as f32;
                    }
                }
            }
        }
        let ranges = match regions {
            [one] => *one,
            _ => {
                let count = regions.len().max(1) as f64;
                let center_mm =
                    [0, 1, 2].map(|d| regions.iter().map(|r| r.center_mm[d]).sum::<f64>() / count);
                let fold = |f: fn(f64, f64) -> f64, init: f64, pick: fn(&NoduleRanges) -> f64| {
                    regions.iter().map(pick).fold(init, f)
                };
                NoduleRanges {
                    center_mm,
                    reach_mm: fold(f64::max, 0.0, |r| r.reach_mm)
                        + regions
                            .iter()
                            .map(|r| norm(sub(r.center_mm, center_mm)))
                            .fold(0.0, f64::max),
                    radius_mm: (
                        fold(f64::min, f64::INFINITY, |r| r.radius_mm.0),
                        fold(f64::max, 0.0, |r| r.radius_mm.1),
                    ),
                    ratio: (
                        fold(f64::min, f64::INFINITY, |r| r.ratio.0),
                        fold(f64::max, 0.0, |r| r.ratio.1),
                    ),
                }
            }
        };
        let (lambda, mu) = setup.problem.material.lame_n_per_mm2();
        let mut base = setup.space.clone();
        base.stiffness = None;
        InteriorResponses {
            ranges,
            cols,
            rows,
            row_of,
            col_of,
            g,
            space: base,
            lambda,
            mu,
            poisson: setup.problem.material.poisson,
            build_s: t0.elapsed().as_secs_f64(),
        }
    }

    /// The store of `ranges` cut from this one: its columns, at their rows only (what
    /// placing a nodule reads); a load's responses then come from elsewhere
    /// ([`PlacedNodule::corrections`]). `None` where this store lacks one of them.
    pub fn restrict(&self, ranges: NoduleRanges) -> Option<InteriorResponses> {
        let t0 = Instant::now();
        let mut mark = vec![false; self.col_of.len()];
        mark_touched(&self.space, &ranges, &mut mark);
        let (cols, col_of) = indexed(&mark);
        let from: Vec<usize> = cols
            .iter()
            .map(|&d| {
                let c = self.col_of[d as usize];
                (c != u32::MAX).then_some(c as usize)
            })
            .collect::<Option<_>>()?;
        let at: Vec<usize> = cols
            .iter()
            .map(|&d| self.row_of[d as usize] as usize)
            .collect();
        let (nr, m) = (self.rows.len(), cols.len());
        let mut g = vec![0.0f32; m * m];
        g.par_chunks_mut(m.max(1)).zip(&from).for_each(|(out, &c)| {
            let src = &self.g[c * nr..(c + 1) * nr];
            for (x, &r) in out.iter_mut().zip(&at) {
                *x = src[r];
            }
        });
        Some(InteriorResponses {
            ranges,
            rows: cols.clone(),
            row_of: col_of.clone(),
            cols,
            col_of,
            g,
            space: self.space.clone(),
            lambda: self.lambda,
            mu: self.mu,
            poisson: self.poisson,
            build_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// The store's column of the free unknown `dof`, if stored.
    pub fn col_of(&self, dof: u32) -> Option<usize> {
        let c = self.col_of[dof as usize];
        (c != u32::MAX).then_some(c as usize)
    }

    /// Bytes of the stored responses.
    pub fn bytes(&self) -> usize {
        self.g.len() * size_of::<f32>()
    }

    /// `G[dof, col]`, or `None` where `dof` is not a stored row.
    #[inline]
    fn at(&self, dof: u32, col: usize) -> Option<f32> {
        let r = self.row_of[dof as usize];
        (r != u32::MAX).then(|| self.g[col * self.rows.len() + r as usize])
    }

    /// Whether every free unknown of a sparse vector is a stored row.
    pub fn holds_rows(&self, v: &[(u32, f64)]) -> bool {
        v.iter().all(|&(d, _)| self.row_of[d as usize] != u32::MAX)
    }

    /// Places `nodule`: its cells' stiffness factors, `C`, `G_pp` and the LU of
    /// `I + C G_pp`. The nodule is assumed checked against the organ
    /// ([`Nodule::check`]); here it is checked against the store's ranges.
    pub fn place(&self, nodule: &Nodule) -> Result<PlacedNodule, NoduleStoreError> {
        let t0 = Instant::now();
        let r = &self.ranges;
        if !(r.ratio.0..=r.ratio.1).contains(&nodule.ratio) {
            return Err(NoduleStoreError::Ratio {
                ratio: nodule.ratio,
                lo: r.ratio.0,
                hi: r.ratio.1,
            });
        }
        let cut = self.cut(nodule.center_mm, nodule.radius_mm)?;
        let mut placed = cut.place(nodule.ratio)?;
        placed.place_s = t0.elapsed().as_secs_f64();
        Ok(placed)
    }

    /// What every ratio of a nodule at `center_mm` of radius `radius_mm` shares: the
    /// cells it touches with their volume fractions and element stiffness, its
    /// unknowns, the pattern of `C` on them and `G_pp` ([`NoduleCut::place`] then
    /// places one ratio).
    pub fn cut(&self, center_mm: [f64; 3], radius_mm: f64) -> Result<NoduleCut, NoduleStoreError> {
        let r = &self.ranges;
        let distance_mm = norm(sub(center_mm, r.center_mm));
        if distance_mm > r.reach_mm {
            return Err(NoduleStoreError::CentreOutside {
                center_mm,
                region_mm: r.center_mm,
                distance_mm,
                reach_mm: r.reach_mm,
            });
        }
        if !(r.radius_mm.0..=r.radius_mm.1).contains(&radius_mm) {
            return Err(NoduleStoreError::Radius {
                radius_mm,
                lo: r.radius_mm.0,
                hi: r.radius_mm.1,
            });
        }
        let shape = Nodule {
            center_mm,
            radius_mm,
            ratio: 2.0,
        };
        let fractions = shape.cell_fractions(&self.space);
        let cells: Vec<usize> = (0..fractions.len())
            .filter(|&c| fractions[c] > 0.0)
            .collect();
        // The nodule's unknowns, ascending, and each one's place among them.
        let mut dofs: Vec<u32> = Vec::new();
        let mut local = Vec::new();
        for &c in &cells {
            cell_dofs(&self.space, c, &mut local);
            for &d in local.iter().filter(|&&d| d != usize::MAX) {
                if self.col_of[d] == u32::MAX {
                    return Err(NoduleStoreError::CellNotStored {
                        cell: c,
                        reach_mm: r.reach_mm,
                        radius_mm: r.radius_mm.1,
                    });
                }
                dofs.push(d as u32);
            }
        }
        dofs.sort_unstable();
        dofs.dedup();
        let m = dofs.len();
        let index = |d: usize| dofs.binary_search(&(d as u32)).ok().map(|i| i as u32);
        // Each cell's element stiffness and its entries' (row, column) among the
        // nodule's unknowns; then C's pattern by rows (C is symmetric, a row couples an
        // unknown to those of its own cells only) and each entry's place in it.
        let npc = self.space.element.nodes_per_cell();
        let mut ke = vec![0.0; cells.len() * 9 * npc * npc];
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(ke.len());
        for (e, &c) in cells.iter().enumerate() {
            let k_e = &mut ke[e * 9 * npc * npc..(e + 1) * 9 * npc * npc];
            element_stiffness(&self.space, c, self.lambda, self.mu, k_e);
            cell_dofs(&self.space, c, &mut local);
            let at: Vec<u32> = local
                .iter()
                .map(|&d| {
                    if d == usize::MAX {
                        u32::MAX
                    } else {
                        index(d).unwrap_or(u32::MAX)
                    }
                })
                .collect();
            // Entry (i, j) of K_e is stored as C's (j, i): C's rows are its columns.
            for &ai in &at {
                for &aj in &at {
                    pairs.push((aj, ai));
                }
            }
        }
        let mut pattern: Vec<(u32, u32)> = pairs
            .iter()
            .copied()
            .filter(|&(i, j)| i != u32::MAX && j != u32::MAX)
            .collect();
        pattern.sort_unstable();
        pattern.dedup();
        let mut row_starts = vec![0u32; m + 1];
        for &(i, _) in &pattern {
            row_starts[i as usize + 1] += 1;
        }
        for i in 0..m {
            row_starts[i + 1] += row_starts[i];
        }
        let c_cols: Vec<u32> = pattern.iter().map(|&(_, j)| j).collect();
        let slot: Vec<u32> = pairs
            .iter()
            .map(|&(i, j)| {
                if i == u32::MAX || j == u32::MAX {
                    return u32::MAX;
                }
                let (lo, hi) = (
                    row_starts[i as usize] as usize,
                    row_starts[i as usize + 1] as usize,
                );
                let k = c_cols[lo..hi].binary_search(&j).expect("in the pattern");
                (lo + k) as u32
            })
            .collect();
        let cols: Vec<usize> = dofs
            .iter()
            .map(|&d| self.col_of[d as usize] as usize)
            .collect();
        // G_pp from the stored columns (rows of p are stored: p ⊂ cols ⊂ rows), one
        // contiguous column at a time, in single precision as stored: the small dense
        // system is formed and factored in it too.
        let nr = self.rows.len();
        let rows_p: Vec<usize> = dofs
            .iter()
            .map(|&d| self.row_of[d as usize] as usize)
            .collect();
        let mut g_pp = vec![0.0f32; m * m];
        for (j, out) in g_pp.chunks_exact_mut(m).enumerate() {
            let g = &self.g[cols[j] * nr..(cols[j] + 1) * nr];
            for (x, &r) in out.iter_mut().zip(&rows_p) {
                *x = g[r];
            }
        }
        Ok(NoduleCut {
            center_mm,
            radius_mm,
            poisson: self.poisson,
            fractions: cells.iter().map(|&c| fractions[c]).collect(),
            ke,
            slot,
            row_starts,
            c_cols,
            dofs,
            cols,
            g_pp,
        })
    }

    /// `G_{c,:} v` for a sparse vector `v` on stored rows, at every stored column `c`:
    /// the response (by symmetry) to the load `v` wherever a nodule can lie, what
    /// [`PlacedNodule::corrections`] reads for many nodules under the same load.
    pub fn response_at_cols(&self, v: &[(u32, f64)]) -> Vec<f64> {
        let nr = self.rows.len();
        let at: Vec<(usize, f64)> = v
            .iter()
            .filter_map(|&(d, x)| {
                let r = self.row_of[d as usize];
                (r != u32::MAX).then_some((r as usize, x))
            })
            .collect();
        self.g
            .chunks_exact(nr)
            .map(|col| at.iter().map(|&(r, x)| x * f64::from(col[r])).sum())
            .collect()
    }

    /// `G_{p,:} v` for a sparse vector `v` on stored rows: the response at the placed
    /// nodule's unknowns (by symmetry) to the load `v`.
    fn at_nodule(&self, placed: &PlacedNodule, v: &[(u32, f64)]) -> Vec<f64> {
        placed
            .cols
            .iter()
            .map(|&col| {
                v.iter()
                    .map(|&(d, x)| x * f64::from(self.at(d, col).unwrap_or(0.0)))
                    .sum()
            })
            .collect()
    }
}

/// A nodule's centre and radius cut from a store: everything its ratios share
/// ([`InteriorResponses::cut`]).
#[derive(Debug)]
pub struct NoduleCut {
    center_mm: [f64; 3],
    radius_mm: f64,
    poisson: f64,
    /// The volume fraction inside the sphere of each cell it touches.
    fractions: Vec<f64>,
    /// Those cells' element stiffness (tissue), one after another.
    ke: Vec<f64>,
    /// Each element entry's place among `C`'s stored entries, or `u32::MAX` (fixed).
    slot: Vec<u32>,
    /// `C`'s pattern by rows: row `i`'s columns are `c_cols[row_starts[i]..row_starts[i + 1]]`.
    row_starts: Vec<u32>,
    c_cols: Vec<u32>,
    dofs: Vec<u32>,
    cols: Vec<usize>,
    g_pp: Vec<f32>,
}

impl NoduleCut {
    /// The nodule of this centre and radius at `ratio`: `C` and the LU of `I + C G_pp`.
    pub fn place(&self, ratio: f64) -> Result<PlacedNodule, NoduleStoreError> {
        let t0 = Instant::now();
        let nodule = Nodule {
            center_mm: self.center_mm,
            radius_mm: self.radius_mm,
            ratio,
        };
        let m = self.dofs.len();
        let per = self.ke.len() / self.fractions.len().max(1);
        // C = Σ_e (s_e − 1) K_e on the nodule's unknowns, by rows.
        let mut values = vec![0.0f64; self.c_cols.len()];
        for (e, &phi) in self.fractions.iter().enumerate() {
            let w = nodule.factor(phi, self.poisson) - 1.0;
            let k_e = &self.ke[e * per..(e + 1) * per];
            for (&at, &k) in self.slot[e * per..(e + 1) * per].iter().zip(k_e) {
                if at != u32::MAX {
                    values[at as usize] += w * k;
                }
            }
        }
        let c_rows: Vec<Vec<(u32, f64)>> = (0..m)
            .map(|i| {
                let (lo, hi) = (self.row_starts[i] as usize, self.row_starts[i + 1] as usize);
                (lo..hi)
                    .filter(|&k| values[k] != 0.0)
                    .map(|k| (self.c_cols[k], values[k]))
                    .collect()
            })
            .collect();
        // G_pp and C are symmetric, so (C G_pp)ᵀ = G_pp C, whose column j is the sum of
        // G_pp's columns weighted by C's row j: contiguous sums.
        let g_pp = &self.g_pp;
        let mut gc = vec![0.0f32; m * m];
        for (j, dst) in gc.chunks_exact_mut(m).enumerate() {
            for &(k, v) in &c_rows[j] {
                crate::kernels::axpy(dst, v as f32, &g_pp[k as usize * m..(k as usize + 1) * m]);
            }
        }
        // I + C G_pp = (I + G_pp C)ᵀ: entry (i, j) is column i's entry j.
        let system = Mat::<f32>::from_fn(m, m, |i, j| gc[i * m + j] + f32::from(u8::from(i == j)));
        let t_factor = Instant::now();
        let lu = system.partial_piv_lu();
        let factor_s = t_factor.elapsed().as_secs_f64();
        // A singular system shows as a non-finite solve of a probe vector.
        let mut probe = Mat::<f32>::from_fn(m, 1, |i, _| 1.0 + i as f32 / m as f32);
        lu.solve_in_place(probe.as_mut());
        // faer's kernels leave the vector registers' upper halves set: cleared before
        // the scalar work that follows on this thread (crate::cpu).
        crate::cpu::clear_upper_halves();
        if (0..m).any(|i| !probe[(i, 0)].is_finite()) {
            return Err(NoduleStoreError::Singular { ratio });
        }
        Ok(PlacedNodule {
            nodule,
            dofs: self.dofs.clone(),
            cols: self.cols.clone(),
            c_rows,
            lu,
            cells: self.fractions.len(),
            factor_s,
            place_s: t0.elapsed().as_secs_f64(),
        })
    }
}

/// A nodule placed in a store: what every probe with it reuses.
#[derive(Debug)]
pub struct PlacedNodule {
    pub nodule: Nodule,
    /// The free unknowns of the cells it touches, ascending.
    pub dofs: Vec<u32>,
    /// Their columns in the store.
    cols: Vec<usize>,
    /// `C` by rows: (column among `dofs`, value).
    c_rows: Vec<Vec<(u32, f64)>>,
    lu: faer::linalg::solvers::PartialPivLu<f32>,
    /// Cells it touches.
    pub cells: usize,
    /// Seconds of placing it, and of those the LU factorization's.
    pub place_s: f64,
    pub factor_s: f64,
}

impl PlacedNodule {
    /// `z` of the module doc for the load `f` (free unknown, value; every unknown a
    /// stored row): `(I + C G_pp) z = C G_{p,:} f`.
    pub fn solve(&self, store: &InteriorResponses, f: &[(u32, f64)]) -> Vec<f64> {
        let u0 = store.at_nodule(self, f);
        let m = self.dofs.len();
        let mut z = Mat::<f32>::from_fn(m, 1, |i, _| {
            self.c_rows[i]
                .iter()
                .map(|&(k, v)| v * u0[k as usize])
                .sum::<f64>() as f32
        });
        self.lu.solve_in_place(z.as_mut());
        (0..m).map(|i| f64::from(z[(i, 0)])).collect()
    }

    /// The change the nodule makes to `φᵀ u` under the load `f`: `−φᵀ G_{:,p} z`
    /// (both sparse on stored rows). With `φ` the probe point's functional and `f` the
    /// unit probe load, the change of the probe's compliance (mm/N).
    pub fn correction(
        &self,
        store: &InteriorResponses,
        f: &[(u32, f64)],
        phi: &[(u32, f64)],
    ) -> f64 {
        let z = self.solve(store, f);
        let g = store.at_nodule(self, phi);
        -g.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>()
    }

    /// [`Self::correction`] for many pairs `(f, φ)` at once, each given by its responses
    /// over the store's columns ([`InteriorResponses::response_at_cols`]): one blocked
    /// solve `(I + C G_pp) Z = C U` for all of them, `δc_k = −V_kᵀ Z_k`.
    pub fn corrections(&self, responses: &[(&[f64], &[f64])]) -> Vec<f64> {
        let m = self.dofs.len();
        let n = responses.len();
        // U by rows (the n loads' responses at one unknown contiguous), so that `C U`
        // is a sum of contiguous rows weighted by C's sparse rows.
        let mut u = vec![0.0f64; m * n];
        for (k, (f, _)) in responses.iter().enumerate() {
            for (i, &c) in self.cols.iter().enumerate() {
                u[i * n + k] = f[c];
            }
        }
        let mut z = Mat::<f32>::zeros(m, n);
        let mut row = vec![0.0f64; n];
        for (i, c_row) in self.c_rows.iter().enumerate() {
            row.fill(0.0);
            for &(j, v) in c_row {
                crate::kernels::axpy(&mut row, v, &u[j as usize * n..(j as usize + 1) * n]);
            }
            for (k, &x) in row.iter().enumerate() {
                z[(i, k)] = x as f32;
            }
        }
        self.lu.solve_in_place(z.as_mut());
        crate::cpu::clear_upper_halves();
        responses
            .iter()
            .enumerate()
            .map(|(k, (_, phi))| {
                -self
                    .cols
                    .iter()
                    .enumerate()
                    .map(|(i, &c)| phi[c] * f64::from(z[(i, k)]))
                    .sum::<f64>()
            })
            .collect()
    }

    /// The change the nodule makes to the displacement at the free unknowns `at` (every
    /// one a stored row) under the load whose `z` is given.
    pub fn displacement_change(
        &self,
        store: &InteriorResponses,
        z: &[f64],
        at: &[u32],
    ) -> Vec<f64> {
        at.iter()
            .map(|&d| {
                -self
                    .cols
                    .iter()
                    .zip(z)
                    .map(|(&col, zi)| zi * f64::from(store.at(d, col).unwrap_or(0.0)))
                    .sum::<f64>()
            })
            .collect()
    }
}
