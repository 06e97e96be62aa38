//! The tissue's nonlinear vademecum `u(x; s, d)` and force law `F(s, d)`, compressed
//! for a scene: what the app evaluates when the organ is hyperelastic.
//!
//! Off-line, [`SurfaceLaw`] follows the press at every palpable vertex `v` to
//! equilibrium on the depth grid and keeps, at grid depths `d_j`, the surface residual
//! `r_v(x; d_j) = u(x; v, d_j) − d_j · û(x; v)` and the force ratio
//! `g_v(d_j) = F(v, d_j) / (d_j F₁(v))` (the linear force `d / c` is exact in the
//! linear vademecum, so only the ratio is stored). Each vertex's residuals over the
//! depths, a matrix `R_v` (3 · surface vertices × depths), are compressed by its thin
//! SVD,
//!
//! ```text
//! R_v ≈ A_v C_v,   A_v = U_q (3n × q),   C_v = Σ_q V_qᵀ (q × depths),
//! ```
//!
//! keeping the fewest modes `q` whose stored reconstruction (shapes in 16 or 8 bits
//! with their scales, weights in f32: [`super::shapes`]) leaves no node of any
//! grid depth more than `tol` from the computed residual. That error is measured
//! exactly, node by node, as evaluation will see it; between grid depths both are
//! blended linearly, so it bounds every depth: the stored bound is a guarantee on the
//! compression, not an estimate. Where the SVD's own modes, as stored, still leave
//! more (8-bit quantization's floor at a large press), each further mode is the
//! leading singular pair of what the stored ones leave, while that lowers the error.
//! (`σ_{q+1}` plus each kept mode's quantization is
//! also a bound, but a loose one: at 0.1 mm and 8 bits it kept 553 modes for 147
//! vertex presses of coarse P2, where 339 are within the tolerance.) One SVD over
//! all vertices does poorly here: each press's residual is a bump at its own place, and bumps at 500
//! places are not a low-rank family; at 512 modes it still errs by 1.4 mm on coarse
//! P2. Along its depths, one press's residual is nearly one shape growing: two to
//! four modes.
//!
//! Where the edges were pressed too (the default), each palpable edge `ab` also keeps
//! the surplus of its midpoint's press over its ends' mean,
//! `e_ab = r_mid − (r_a + r_b)/2` (and the same for `g`), compressed like a vertex.
//!
//! On-line, a probe at barycentric `λ` of a palpable triangle blends the quadratic
//! (hierarchical) interpolant of its corners and edges on the rows the scene draws,
//!
//! ```text
//! r(x; s, d) ≈ Σ_k λ_k r_{v_k}(x; d) + Σ_{edges ab} 4 λ_a λ_b e_ab(x; d),
//! ```
//!
//! coefficients linear in `d` between grid depths; the force is
//! `F(s, d) = d / c(s) · g(s, d)`, `g` blended the same way, with `c(s)` the linear
//! vademecum's exact compliance, and its inverse (force in, depth out) solves that
//! curve, a quadratic in `d` on each grid interval, on the interval that holds the
//! force. The quadratic term matters where the deep press's response turns quickly
//! along the surface: near a sharp border the tissue under the tool slides sideways by
//! up to 6 mm beyond the linear answer at 13 mm, and the linear blend of three corners
//! erred by 3.1 mm at a held-out point where the quadratic one erred by 0.2 mm (coarse
//! P2). Corners that were not sampled (next to the fixed region) drop out and the others
//! are renormalized; an edge is pressed only where both its ends were. Depths past the
//! grid are held at its end and flagged. Nothing is allocated per call.
//!
//! Where the quadratic blend is too coarse (a triangle whose largest edge surplus
//! exceeds the build's threshold), the triangle is split once into four and its quarter
//! and inner points are pressed too (see [`Refinement`]): their surpluses over the
//! quadratic blend come after the edges', and a probe in a split triangle adds the three
//! of the quarter it lies in with weights `4 μ_i μ_j`, so the blend there is the
//! quadratic interpolant of that quarter's six presses. A split triangle's points lie
//! a few millimetres apart and their surpluses share their shape far from the tool, so
//! they are compressed together ([`Grouping`]): `[R_1 … R_n] ≈ A [C_1 … C_n]` over the
//! group's columns (every member at every depth), each mode the leading singular pair
//! of what the stored ones leave, the same exact node-error rule over all members, one
//! set of shapes `A` and a weight block `C_i` per member. A neighbour that was not split
//! adds the quarter points of the edge they share, weighted as on the edge and fading
//! out halfway to its far corner, so the surface does not jump as the probe crosses the
//! edge.
//! At most nine samples enter one probe's blend.
//!
//! A press with no equilibrium past some depth (Saint Venant–Kirchhoff losing
//! stability, a deep press rolling off the frictionless tool) keeps the depths it
//! reached: each sample stores its *reach* and why it stopped, and a probe's own limit
//! is the least reach among the samples its blend uses. Past that limit the force and
//! surface are held at it and flagged, the way they are past the grid, and the reason
//! is the press's own message (the depth that failed).
//!
//! The file is bound to a scene by the rest positions of its rows and samples, so a
//! law built on the organ mesh serves any scene exported from the same mesh.

use crate::tissue::accuracy::Accuracy;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use faer::Mat;
use serde::{Deserialize, Serialize};

use crate::fe::{Element, Material};
use crate::framed::Body;
use crate::organ::OrganMesh;
use crate::tensor::dense::thin_svd;
use crate::tissue::predict::RowPrediction;
pub use crate::tissue::shapes::{ShapeBits, Shapes};
use crate::tissue::subsplit::{SubSplit, sub_triangle_keys};
use crate::tissue::surface::{BandEdge, Refinement, SurfaceLaw, SurfaceLawOptions};
use crate::tissue::weights::{Weights, to_half};

/// The first bytes of a tissue file.
pub const MAGIC: &[u8; 8] = b"PALPATIS";
/// The file's format version. There has been no release, so there is one: a file of
/// another version is refused by name, with the command that builds it anew. The body
/// (LZMA) holds the law's fields, its weights apart ([`super::weights`]: in
/// halves where every one is a half), the sub-triangles split again ([`SubSplit`]),
/// the band next to the fixed region ([`BandEdge`]), the organ mesh's fingerprint
/// ([`TissueLaw::mesh_xxh3`]) and what `palpa tissue check --record` measured of it
/// ([`Accuracy`]); the shapes are stored as what their neighbours do not predict
/// ([`super::predict`]).
pub const VERSION: u32 = 15;

/// Why a tissue file could not be made, read, written or bound to a scene.
#[derive(Debug, thiserror::Error)]
pub enum TissueError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "the tissue's band next to the fixed region ends at {at_mm:?} mm, which is no palpable \
         vertex of the scene: expected the scene of the mesh the tissue was built on"
    )]
    BandOffScene { at_mm: [f32; 3] },
    #[error("{path}: not a palpa tissue file (expected the magic bytes \"PALPATIS\")")]
    Foreign { path: PathBuf },
    #[error(
        "{path}: tissue format version {found}, this palpa reads version {VERSION} only: build \
         it anew with `palpa tissue build` (the shipped liver's: scripts/make-assets.sh)"
    )]
    Version { path: PathBuf, found: u32 },
    #[error(
        "{path}: the tissue law records no organ mesh fingerprint: expected one (every \
         `palpa tissue build` records it)"
    )]
    NoFingerprint { path: PathBuf },
    #[error("{path}: corrupt tissue law: {why}")]
    Corrupt { path: PathBuf, why: String },
    #[error("cannot refine this tissue law: {why}")]
    Refine { why: String },
    #[error("no palpable vertex could be pressed: the surface law is empty")]
    Empty,
    #[error("the SVD of the residual matrix ({rows} × {cols}) did not converge")]
    Svd { rows: usize, cols: usize },
    #[error(
        "the tissue law does not fit this scene: {matched} of its {total} palpable vertices \
         sit on the scene's palpable surface (expected all; was it built on another mesh?)"
    )]
    Mismatch { matched: usize, total: usize },
    #[error(
        "the tissue law does not fit this organ mesh: {matched} of its {total} surface rows \
         sit on the mesh's {vertices} vertices (expected all; give the --level, or the \
         --surface, --units, --axes or --up/--anterior and region flags, it was built with)"
    )]
    Organ {
        matched: usize,
        total: usize,
        vertices: usize,
    },
    #[error(
        "the tissue law was built with {law} and the scene's linear model with {scene}: the \
         vademecum adds its residual to the scene's linear answer, so both must come from \
         the same element and material (rebuild the tissue with matching --element, \
         --young-kpa, --poisson)"
    )]
    LinearModel { law: String, scene: String },
    #[error(
        "the tissue law was built on another organ mesh than {what} (mesh fingerprint \
         {law:016x} against {other}): the same surface meshed at another level or with other \
         fixed and palpable regions is another organ. {hint} (--level, --surface, --units, \
         --axes or --up/--anterior, --fixed, --palpable, --regions, --close-holes, \
         --largest-component)"
    )]
    MeshDiffers {
        law: u64,
        other: String,
        what: &'static str,
        hint: &'static str,
    },
}

/// The compressed nonlinear vademecum (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TissueLaw {
    pub options: SurfaceLawOptions,
    /// Rest positions of the rows (surface vertices), mm.
    pub rows_mm: Vec<[f32; 3]>,
    /// Rest positions of the sampled palpable vertices, mm.
    pub samples_mm: Vec<[f32; 3]>,
    /// Palpable vertices that were not pressed (next to the fixed region), mm.
    pub skipped_mm: Vec<[f32; 3]>,
    /// Pressed palpable edges, as their ends' sample indices: sample
    /// `samples_mm.len() + e` of every per-sample array is edge `e`'s surplus over its
    /// ends' mean (residual and force ratio; see the module docs).
    pub edge_ends: Vec<[u32; 2]>,
    /// Triangles split into four: their quarter and inner points' samples follow the
    /// edges' (see [`Refinement`]).
    pub refinement: Refinement,
    /// Grid depths `j · depth_step_mm`, `j = 0..steps`.
    pub steps: u32,
    /// `ratio[sample · steps + j]`: `g` at grid depth `j`.
    pub ratio: Vec<f32>,
    pub stiffness_n_per_mm: Vec<f32>,
    /// Per sample: the largest last Newton correction of its grid states (mm), and the
    /// series segments its press took.
    pub correction_mm: Vec<f32>,
    pub segments: Vec<u32>,
    /// Per sample: the grid depths its press reached, depth 0 included (`steps` where
    /// it reached them all), and why it stopped short (empty where it did not). Past
    /// its reach a sample's arrays hold the last depth reached.
    pub reach: Vec<u32>,
    pub stopped: Vec<String>,
    /// The most modes a group keeps.
    pub rank: u32,
    /// Group `g`'s modes are `mode_start[g]..mode_start[g + 1]` (see [`Grouping`]).
    pub mode_start: Vec<u32>,
    /// Per sample: the group whose modes its residual weighs.
    pub group: Vec<u32>,
    /// Per sample: where its weights start in `coeffs` (its group's modes × `steps`,
    /// mode by mode); `coeff_start[samples]` is `coeffs.len()`.
    pub coeff_start: Vec<u32>,
    /// Each mode's surface shape (unit norm), quantized to 16 or 8 bits (see
    /// [`super::shapes`]): entry `mode · 3·rows + row3` times
    /// `shape_scale[mode]`. What quantizing costs a node is in the stored bound.
    pub shape: Shapes,
    pub shape_scale: Vec<f32>,
    /// `coeffs[coeff_start[s] + k · steps + j]`: sample `s`'s weight of its group's
    /// `k`-th mode at grid depth `j`, mm.
    pub coeffs: Vec<f32>,
    /// The largest node error of any sample's stored reconstruction at any grid depth,
    /// measured exactly when compressed (grown by what a cut drops, see
    /// [`super::knobs`]): no node's compressed residual is farther than this
    /// from the computed one, mm.
    pub truncation_bound_mm: f64,
    /// The tolerance asked for, mm.
    pub tolerance_mm: f64,
    pub build_s: f64,
    pub compress_s: f64,
    /// The fingerprint of the organ mesh the presses were made on
    /// ([`crate::organ::OrganMesh::fingerprint`]: vertices, tetrahedra and the fixed and
    /// palpable flags), compared with a scene's or an organ's before they are used
    /// together. Every file holds one (a law made in memory by a test may not, and is
    /// then not saved).
    #[serde(skip)]
    pub mesh_xxh3: Option<u64>,
    /// What `palpa tissue check --record` measured of this law against the full
    /// nonlinear FE (see [`Accuracy`]); empty until a check is recorded.
    #[serde(skip)]
    pub accuracy: Accuracy,
}

/// The shares of the tolerance one mode's rounding may take (node error in mm at the
/// mode's largest weight), tried in turn while a group is left above the tolerance.
/// A mode's step is then coarser than `bits` allow wherever its weights are small, and
/// fewer levels deflate to fewer bytes (the entries stay `bits` wide); the stop rule
/// measures the error exactly, so the bound keeps its meaning. Measured on the whole
/// coarse surface's 2 147 presses (8 bits, 0.1 mm; docs/lab/tissue-measurements.md §6), one share for
/// every press: 0 (the plain 8-bit step) 4 134 modes, 6.15 MB; 0.1: 4 152, 3.77 MB;
/// 0.2: 4 177, 2.82 MB; 0.3: 4 232, 2.31 MB; 0.4: 4 352, 2.01 MB; 0.5 left a press at
/// 0.11 mm. A split triangle's shared modes, refitted to their own rounding, often
/// stay above the tolerance at 0.3, hence the finer shares after it.
pub const QUANT_SHARES: [f64; 3] = [0.3, 0.1, 0.0];

/// One group's modes as stored: shapes, scales, each mode's weights (member after
/// member, depths 1.. each), and the largest node error they leave.
pub(super) struct GroupModes {
    pub(super) shape: Shapes,
    pub(super) scale: Vec<f32>,
    pub(super) weights: Vec<Vec<f32>>,
    pub(super) error: f64,
}

/// Compresses one group's residual columns `a` (`members` samples, depths 1.. each).
///
/// The modes as stored (shape in `bits` with an f32 scale, weights in halves: see
/// [`super::weights`]) are added one by one until no node of any grid depth of
/// any member errs by more than the tolerance: the error measured exactly, as
/// evaluation will see it, not bounded by `σ_{q+1}` plus each mode's quantization
/// (that bound is loose by the spread of the error over nodes and modes: on coarse P2
/// it kept about half as many modes again).
/// Past the SVD's own modes (where the stored ones still leave more than the
/// tolerance: 8-bit quantization's floor at a large press), each further mode is the
/// leading singular pair of what the stored modes leave, while that lowers the error.
/// A group of several samples takes each mode from what the stored ones leave,
/// quantization included, with the weights fitted to the quantized shape: its weights
/// are larger than one sample's, and the SVD's own modes, each quantized, left a floor
/// that further modes chased (measured on four split triangles of coarse P2 at 8 bits:
/// up to 136 modes a group, more than its nine points took alone). Each mode's step is
/// at least what lets it err by `share` of the tolerance at its largest weight (see
/// [`QUANT_SHARES`]). `None` where an SVD fails.
fn group_modes(
    a: faer::MatRef<'_, f64>,
    members: usize,
    tolerance_mm: f64,
    bits: ShapeBits,
    share: f64,
) -> Option<GroupModes> {
    let (m, cols) = (a.nrows(), a.ncols());
    let refit = members > 1;
    let svd = match refit {
        true => None,
        false => Some(thin_svd(a)?),
    };
    let n = svd.as_ref().map_or(0, |svd| svd.s.len().min(MAX_RANK));
    let mut left = a.to_owned();
    let mut out = GroupModes {
        shape: Shapes::new(bits),
        scale: Vec::new(),
        weights: Vec::new(),
        error: node_max(left.as_ref()),
    };
    while out.scale.len() < MAX_RANK && out.error > tolerance_mm {
        let kept = out.scale.len();
        let (column, mut c): (Vec<f64>, Vec<f32>) =
            if let Some(svd) = svd.as_ref().filter(|_| kept < n) {
                (
                    (0..m).map(|i| svd.u[(i, kept)]).collect(),
                    (0..cols)
                        .map(|c| (svd.s[kept] * svd.v[(c, kept)]) as f32)
                        .collect(),
                )
            } else {
                let rest = thin_svd(left.as_ref())?;
                (
                    (0..m).map(|i| rest.u[(i, 0)]).collect(),
                    (0..cols)
                        .map(|c| (rest.s[0] * rest.v[(c, 0)]) as f32)
                        .collect(),
                )
            };
        let top_weight = c.iter().fold(0.0f64, |t, &w| t.max(f64::from(w).abs()));
        // Node error of a step `h`: at most `√3 h / 2` per unit weight.
        let min_step = match top_weight > 0.0 {
            true => 2.0 * share * tolerance_mm / (3f64.sqrt() * top_weight),
            false => 0.0,
        };
        let mut one = Shapes::new(bits);
        let (scale, _) = one.push_mode_coarse(&column, min_step);
        if refit {
            let q: Vec<f64> = (0..m).map(|i| one.get(i) * f64::from(scale)).collect();
            let qq: f64 = q.iter().map(|x| x * x).sum();
            for (j, w) in c.iter_mut().enumerate() {
                let along: f64 = (0..m).map(|i| q[i] * left[(i, j)]).sum();
                *w = if qq > 0.0 { (along / qq) as f32 } else { 0.0 };
            }
        }
        // The weights as stored: the error below is the one evaluation will see.
        for w in &mut c {
            *w = to_half(*w);
        }
        let mut next = left.clone();
        for (j, &w) in c.iter().enumerate() {
            let w = f64::from(w) * f64::from(scale);
            for i in 0..m {
                next[(i, j)] -= w * one.get(i);
            }
        }
        let next_error = node_max(next.as_ref());
        // A refitted mode lowers the residual's norm, not always its worst node: it
        // stops only where it lowers nothing.
        let stalled = match refit {
            true => next.norm_l2() >= left.norm_l2(),
            false => kept >= n && next_error >= out.error,
        };
        if stalled {
            break;
        }
        (left, out.error) = (next, next_error);
        out.shape.push_copy(&one, 0, m);
        out.scale.push(scale);
        out.weights.push(c);
    }
    Some(out)
}

/// One group's residual columns (`members` of `law`, depths 1.. each) compressed:
/// coarse steps first (`first_share` of the tolerance); where they leave the group
/// above the tolerance (a group's refitted modes chase their own rounding), finer
/// ones (`finer`), down to the full 8 or 16 bits.
fn compress_group(
    law: &SurfaceLaw,
    members: &[usize],
    m: usize,
    tolerance_mm: f64,
    bits: ShapeBits,
    first_share: &f64,
    finer: &[f64],
) -> Result<GroupModes, TissueError> {
    let steps = law.steps();
    // Columns j ≥ 1 only (depth 0 is exactly zero), sample after sample.
    let cols = members.len() * (steps - 1);
    let a = Mat::from_fn(m, cols, |i, c| {
        let (s, j) = (members[c / (steps - 1)], c % (steps - 1) + 1);
        f64::from(law.residual_at(s, j)[i])
    });
    let svd_error = || TissueError::Svd { rows: m, cols };
    let mut modes = group_modes(a.as_ref(), members.len(), tolerance_mm, bits, *first_share)
        .ok_or_else(svd_error)?;
    for &share in finer {
        if modes.error <= tolerance_mm {
            break;
        }
        let again = group_modes(a.as_ref(), members.len(), tolerance_mm, bits, share)
            .ok_or_else(svd_error)?;
        if again.error < modes.error {
            modes = again;
        }
    }
    Ok(modes)
}

/// The largest node displacement (three rows a node) over the columns of `a`, mm.
fn node_max(a: faer::MatRef<'_, f64>) -> f64 {
    let mut worst = 0.0f64;
    for j in 0..a.ncols() {
        for n in 0..a.nrows() / 3 {
            let d = (0..3).map(|c| a[(3 * n + c, j)].powi(2)).sum::<f64>();
            worst = worst.max(d);
        }
    }
    worst.sqrt()
}

/// Which samples share their modes.
///
/// A split triangle's quarter and inner points lie within a few millimetres of each
/// other, and their surpluses over the quadratic blend are not local (on coarse P2 a
/// split point's surplus exceeds 0.05 mm at 522 of 858 surface nodes on average) but
/// share their far shape: on four split triangles of a covering build (coarse P2, to
/// 15 mm, 8 bits, 0.1 mm), their 36 points took 45 modes shared by triangle, where
/// they took 100 alone (the file 151 KB against 200 KB, the same bound); on eight
/// neighbouring ones (the anterior lobe), 72 against 103 (201 KB against 217 KB).
/// One group for all 56 points there took 40 modes, but its weights outweighed the
/// shapes saved (258 KB). Vertex and edge presses, 8–12 mm apart, share little
/// (grouped with the split points of their triangle: 89 modes in all against 94), and
/// are kept alone. See docs/methods.md §2e and docs/lab/tissue-measurements.md §6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Grouping {
    /// Every sample its own modes (`palpa tissue build --separate-modes`).
    Sample,
    /// The quarter and inner points of each split triangle share one set of modes (a
    /// quarter point on an edge between two split triangles goes with the first);
    /// vertices and edges keep their own.
    #[default]
    SplitTriangle,
}

impl Grouping {
    /// The groups of `law`'s samples (indices in sample order within each group;
    /// every sample in exactly one group).
    fn groups(self, law: &SurfaceLaw) -> Vec<Vec<usize>> {
        let r = &law.refinement;
        let first_quarter = law.samples.len() + law.edges.len();
        let first_inner = first_quarter + r.quarter_ends.len();
        let first_sub = first_inner + r.inner_corners.len();
        let n = first_sub + r.sub.points.len();
        // The band's samples come last, each alone: its presses lie 8–12 mm apart.
        let band = (n..n + r.band.len()).map(|s| vec![s]);
        if self == Grouping::Sample || r.triangles.is_empty() {
            return (0..n).map(|s| vec![s]).chain(band).collect();
        }
        let mut groups: Vec<Vec<usize>> = (0..first_quarter).map(|s| vec![s]).collect();
        let mut taken = vec![false; n];
        let sorted = |mut c: [u32; 3]| {
            c.sort_unstable();
            c
        };
        for &tri in &r.triangles {
            let quarters = r
                .quarter_ends
                .iter()
                .enumerate()
                .filter(|(_, e)| tri.contains(&e[0]) && tri.contains(&e[1]))
                .map(|(q, _)| first_quarter + q);
            let inner = r
                .inner_corners
                .iter()
                .enumerate()
                .filter(|(_, c)| sorted(**c) == sorted(tri))
                .map(|(i, _)| first_inner + i);
            let members: Vec<usize> = quarters.chain(inner).filter(|&s| !taken[s]).collect();
            for &s in &members {
                taken[s] = true;
            }
            if !members.is_empty() {
                groups.push(members);
            }
        }
        groups.extend(
            (first_quarter..first_sub)
                .filter(|&s| !taken[s])
                .map(|s| vec![s]),
        );
        // The second level's points, a sub-triangle's together (one on an edge between
        // two goes with the first).
        let by_key = r.sub.samples_by_key(first_sub);
        for &name in &r.sub.sub_triangles {
            let mut members: Vec<usize> = sub_triangle_keys(name)
                .iter()
                .filter_map(|k| by_key.get(k).map(|&s| s as usize))
                .filter(|&s| !std::mem::replace(&mut taken[s], true))
                .collect();
            members.sort_unstable();
            if !members.is_empty() {
                groups.push(members);
            }
        }
        groups.extend((first_sub..n).filter(|&s| !taken[s]).map(|s| vec![s]));
        groups.extend(band);
        groups
    }
}

/// Most modes one group may keep.
pub const MAX_RANK: usize = 256;

/// The compression's default bound on any node's residual (mm) and bits per stored
/// shape entry. Eight bits halve the file; at held-out presses on coarse P2 they
/// changed the worst surface error by at most 0.02 mm against sixteen, while the blend
/// between presses errs by 0.2–0.7 mm (docs/lab/tissue-measurements.md §8). Their quantization costs a node
/// about 0.06 mm, so the bound is 0.1 mm (a fifth of the surface goal), not 0.05.
pub const DEFAULT_TOLERANCE_MM: f64 = 0.1;
pub const DEFAULT_BITS: ShapeBits = ShapeBits::Eight;

impl TissueLaw {
    /// Checks that the organ mesh a command rebuilt (`--level`, `--surface`) is the one
    /// this law was built on: every row (surface vertex) must be one of its vertices.
    /// Another level's mesh would otherwise show only as "no triangle pressed", or
    /// as Newton references on a different surface. A law that records its mesh's
    /// fingerprint must match the organ's too: the same surface with
    /// other fixed or palpable regions is another organ.
    pub fn check_organ(&self, organ: &OrganMesh) -> Result<(), TissueError> {
        let vertices_mm = &organ.mesh.vertices;
        let index = PointIndex::new(vertices_mm.iter().copied());
        let matched = self
            .rows_mm
            .iter()
            .filter(|p| index.find(p.map(f64::from)).is_some())
            .count();
        if matched == self.rows_mm.len() {
            let organ_hash = organ.fingerprint();
            match self.mesh_xxh3 {
                Some(law) if law != organ_hash => Err(TissueError::MeshDiffers {
                    law,
                    other: format!("{organ_hash:016x}"),
                    what: "the organ mesh given",
                    hint: "Give the flags the tissue was built with",
                }),
                _ => Ok(()),
            }
        } else {
            Err(TissueError::Organ {
                matched,
                total: self.rows_mm.len(),
                vertices: vertices_mm.len(),
            })
        }
    }

    /// Checks that the scene's linear model (its provenance's `mesh` line, e.g.
    /// `... element=p2 young_kpa=160 poisson=0.48 ...`) used this law's element and
    /// material: a residual of P1 added to a linear answer of P2 is neither model
    /// (measured: forces 30–40 % off). Keys the line does not name are not compared.
    /// Where both record it, the organ mesh's fingerprint (`mesh_xxh3`) must agree too:
    /// a tissue pressed on the same surface with another fixed region binds to every
    /// vertex, yet answers for another support.
    pub fn check_linear_model(&self, scene_mesh_line: &str) -> Result<(), TissueError> {
        let o = &self.options;
        if let Some((law, scene)) = linear_model_mismatch(o.element, &o.material, scene_mesh_line) {
            return Err(TissueError::LinearModel { law, scene });
        }
        let scene = crate::pgd::palpation::describe_get(scene_mesh_line, "mesh_xxh3");
        match (self.mesh_xxh3, scene) {
            (Some(law), Some(scene)) if format!("{law:016x}") != scene => {
                Err(TissueError::MeshDiffers {
                    law,
                    other: scene.to_string(),
                    what: "the scene's",
                    hint: "Build the tissue with the flags the scene was built with",
                })
            }
            _ => Ok(()),
        }
    }

    /// Compresses a built surface law to `tolerance_mm`, its shapes stored in `bits`
    /// (see the module docs).
    pub fn compress(
        organ: &OrganMesh,
        law: &SurfaceLaw,
        tolerance_mm: f64,
        bits: ShapeBits,
    ) -> Result<TissueLaw, TissueError> {
        Self::compress_grouped(organ, law, tolerance_mm, bits, Grouping::default())
    }

    /// [`Self::compress`] with the samples sharing modes as `grouping` says.
    pub fn compress_grouped(
        organ: &OrganMesh,
        law: &SurfaceLaw,
        tolerance_mm: f64,
        bits: ShapeBits,
        grouping: Grouping,
    ) -> Result<TissueLaw, TissueError> {
        Self::compress_with(organ, law, tolerance_mm, bits, grouping, &QUANT_SHARES)
    }

    /// [`Self::compress_grouped`] with each mode's rounding allowed `shares[0]` of the
    /// tolerance, then each next share where a group is left above the tolerance
    /// ([`QUANT_SHARES`] by default; `&[0.0]`: every mode at the full `bits`).
    pub fn compress_with(
        organ: &OrganMesh,
        law: &SurfaceLaw,
        tolerance_mm: f64,
        bits: ShapeBits,
        grouping: Grouping,
        shares: &[f64],
    ) -> Result<TissueLaw, TissueError> {
        Self::compress_onto(organ, law, tolerance_mm, bits, grouping, shares, None)
    }

    /// [`Self::compress_with`], the groups of `base`'s samples (the first of `law`'s,
    /// each its own group there and here) copied from it unchanged, not compressed
    /// again: how a refinement keeps the file it refines ([`Self::refined`]).
    pub(super) fn compress_onto(
        organ: &OrganMesh,
        law: &SurfaceLaw,
        tolerance_mm: f64,
        bits: ShapeBits,
        grouping: Grouping,
        shares: &[f64],
        base: Option<(&TissueLaw, &[Option<usize>])>,
    ) -> Result<TissueLaw, TissueError> {
        let (first_share, finer) = shares.split_first().unwrap_or((&0.0, &[]));
        let t0 = Instant::now();
        let steps = law.steps();
        if law.samples.is_empty() {
            return Err(TissueError::Empty);
        }
        let groups = grouping.groups(law);
        let n_samples = groups.iter().map(Vec::len).sum::<usize>();
        let m = 3 * law.rows.len();
        let (mut mode_start, mut group) = (vec![0u32], vec![0u32; n_samples]);
        let mut sample_coeffs: Vec<Vec<f32>> = vec![Vec::new(); n_samples];
        let (mut shape, mut shape_scale) = (Shapes::new(bits), Vec::new());
        let (mut rank, mut bound) = (0usize, 0.0f64);
        for (g, members) in groups.iter().enumerate() {
            // A group the base file holds whole is copied; any other is compressed
            // from the law's residuals. Where some of those came from the base file
            // (decompressed: a group it held in part, which an onward refinement does
            // not make), their error adds to the base's bound.
            let in_base: Vec<Option<usize>> = members
                .iter()
                .map(|&s| base.and_then(|(_, at)| at.get(s).copied().flatten()))
                .collect();
            let whole: Option<Vec<usize>> = in_base.iter().copied().collect();
            let modes = match (base, whole) {
                (Some((b, _)), Some(whole)) if b.holds_group(&whole) => {
                    b.group_modes_of(&whole, steps)?
                }
                _ => {
                    let mut modes =
                        compress_group(law, members, m, tolerance_mm, bits, first_share, finer)?;
                    if let Some((b, _)) = base.filter(|_| in_base.iter().any(Option::is_some)) {
                        modes.error += b.truncation_bound_mm;
                    }
                    modes
                }
            };
            let (kept, error) = (modes.scale.len(), modes.error);
            for k in 0..kept {
                shape.push_copy(&modes.shape, k, m);
            }
            shape_scale.extend(&modes.scale);
            for (k, &s) in members.iter().enumerate() {
                for mode in 0..kept {
                    sample_coeffs[s].push(0.0f32);
                    sample_coeffs[s].extend(&modes.weights[mode][k * (steps - 1)..][..steps - 1]);
                }
            }
            // Where even that leaves more, the bound says what remains.
            rank = rank.max(kept);
            bound = bound.max(error);
            mode_start.push(mode_start[g] + kept as u32);
            for &s in members {
                group[s] = g as u32;
            }
        }
        let mut coeff_start = vec![0u32];
        for c in &sample_coeffs {
            coeff_start.push(coeff_start.last().copied().unwrap_or(0) + c.len() as u32);
        }
        let coeffs = sample_coeffs.concat();
        let at = |v: u32| organ.mesh.vertices[v as usize].map(|x| x as f32);
        let tissue = TissueLaw {
            options: law.options,
            rows_mm: law.rows.iter().map(|&v| at(v)).collect(),
            samples_mm: law.samples.iter().map(|&v| at(v)).collect(),
            skipped_mm: law.skipped.iter().map(|&v| at(v)).collect(),
            edge_ends: law.edges.clone(),
            refinement: law.refinement.clone(),
            steps: steps as u32,
            ratio: law.ratio.iter().map(|&g| g as f32).collect(),
            stiffness_n_per_mm: law.stiffness_n_per_mm.iter().map(|&k| k as f32).collect(),
            correction_mm: law.correction_mm.iter().map(|&c| c as f32).collect(),
            segments: law.segments.clone(),
            reach: law.reach.clone(),
            stopped: law.stopped.clone(),
            rank: rank as u32,
            mode_start,
            group,
            coeff_start,
            shape,
            shape_scale,
            coeffs,
            truncation_bound_mm: bound,
            tolerance_mm,
            build_s: law.build_s,
            compress_s: t0.elapsed().as_secs_f64(),
            mesh_xxh3: Some(organ.fingerprint()),
            accuracy: Default::default(),
        };
        debug_assert_eq!(tissue.check(), Ok(()));
        Ok(tissue)
    }

    pub fn depth_max_mm(&self) -> f64 {
        self.options.depth_step_mm * f64::from(self.steps.saturating_sub(1))
    }

    /// Sample `s`'s modes (its group's), and where its weights of them start in
    /// `coeffs` (`steps` a mode).
    pub fn sample_modes(&self, s: usize) -> (std::ops::Range<usize>, usize) {
        let g = self.group[s] as usize;
        let modes = self.mode_start[g] as usize..self.mode_start[g + 1] as usize;
        (modes, self.coeff_start[s] as usize)
    }

    /// Checks what a file gave: shapes, finite values, `g(0) = 1`, zero residual at
    /// depth 0.
    pub fn check(&self) -> Result<(), String> {
        let steps = self.steps as usize;
        let vertices = self.samples_mm.len();
        let refined = &self.refinement;
        let (ns, rank, m) = (
            vertices
                + self.edge_ends.len()
                + refined.quarter_ends.len()
                + refined.inner_corners.len()
                + refined.sub.points.len()
                + refined.band.len(),
            self.rank as usize,
            3 * self.rows_mm.len(),
        );
        let step = self.options.depth_step_mm;
        if !((2..=256).contains(&steps) && step.is_finite() && step > 0.0) {
            return Err(format!(
                "{steps} depths in steps of {} mm: expected 2 to 256 depths, a positive step",
                self.options.depth_step_mm
            ));
        }
        let modes = self.mode_start.last().copied().unwrap_or(0) as usize;
        let groups = self.mode_start.len().saturating_sub(1);
        if vertices == 0 || rank > MAX_RANK || m == 0 {
            return Err(format!(
                "{ns} samples, rank {rank}, {m} rows: expected samples, rows, rank ≤ {MAX_RANK}"
            ));
        }
        if self.ratio.len() != ns * steps
            || self.stiffness_n_per_mm.len() != ns
            || self.correction_mm.len() != ns
            || self.segments.len() != ns
            || self.reach.len() != ns
            || self.stopped.len() != ns
            || self.mode_start.first() != Some(&0)
            || self
                .mode_start
                .windows(2)
                .any(|w| w[1] < w[0] || (w[1] - w[0]) as usize > rank)
            || self.group.len() != ns
            || self.group.iter().any(|&g| g as usize >= groups)
            || self.coeff_start.len() != ns + 1
            || self.coeff_start[0] != 0
            || self.coeff_start[ns] as usize != self.coeffs.len()
            || (0..ns).any(|s| {
                let g = self.group[s] as usize;
                let count = (self.mode_start[g + 1] - self.mode_start[g]) as usize;
                self.coeff_start[s + 1].checked_sub(self.coeff_start[s])
                    != Some((count * steps) as u32)
            })
            || self.shape.len() != modes * m
            || self.shape_scale.len() != modes
        {
            return Err(format!(
                "array lengths do not match {ns} samples × {steps} depths, {modes} modes of \
                 {m} rows in {groups} groups"
            ));
        }
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        if !(finite(&self.shape_scale)
            && finite(&self.coeffs)
            && finite(&self.stiffness_n_per_mm)
            && self.ratio[..vertices * steps]
                .iter()
                .all(|g| g.is_finite() && *g > 0.0)
            && finite(&self.ratio[vertices * steps..])
            && self
                .rows_mm
                .iter()
                .chain(&self.samples_mm)
                .all(|p| finite(p)))
        {
            return Err("non-finite values, or a non-positive force ratio".into());
        }
        if self
            .edge_ends
            .iter()
            .any(|&[a, b]| a == b || a as usize >= vertices || b as usize >= vertices)
        {
            return Err(format!(
                "an edge's ends are not two of the {vertices} samples"
            ));
        }
        let distinct = |c: &[u32]| {
            c.iter().all(|&v| (v as usize) < vertices)
                && (0..c.len()).all(|i| (i + 1..c.len()).all(|j| c[i] != c[j]))
        };
        if !(refined.quarter_ends.iter().all(|c| distinct(c))
            && refined.inner_corners.iter().all(|c| distinct(c))
            && refined.triangles.iter().all(|c| distinct(c))
            && refined.above_mm.is_none_or(|t| t.is_finite() && t >= 0.0))
        {
            return Err(format!(
                "a split triangle's corners or a quarter or inner point's are not distinct \
                 samples of the {vertices}, or the split threshold is not a length"
            ));
        }
        if refined.band.iter().any(|b| {
            b.end as usize >= vertices
                || !finite(&b.other_mm)
                || self.samples_mm.iter().any(|p| p == &b.other_mm)
        }) {
            return Err(format!(
                "a band edge's pressed end is not one of the {vertices} samples, or its other \
                 end is not a finite point apart from them"
            ));
        }
        if self.reach.iter().zip(&self.stopped).any(|(&r, why)| {
            !(2..=steps as u32).contains(&r) || (r < steps as u32) == why.is_empty()
        }) {
            return Err(format!(
                "a sample's reach is not 2 to {steps} depths, or says no reason for stopping short"
            ));
        }
        let (at_vertices, at_edges) = self.ratio.split_at(vertices * steps);
        if at_vertices.chunks_exact(steps).any(|r| r[0] != 1.0)
            || at_edges.chunks_exact(steps).any(|r| r[0] != 0.0)
            || self.coeffs.chunks_exact(steps).any(|c| c[0] != 0.0)
        {
            return Err("a sample's press at depth 0 is not the rest state".into());
        }
        let sub = &refined.sub;
        let n_corners = vertices as u32;
        if sub.points.iter().any(|p| {
            p.eighths.iter().map(|&e| u32::from(e)).sum::<u32>() != 8
                || p.corners.iter().any(|&c| c >= n_corners)
        }) || sub.sub_triangles.iter().any(|(c, at)| {
            !c.is_sorted()
                || c.iter().any(|&c| c >= n_corners)
                || !(*at == u32::MAX || c.contains(at))
        }) {
            return Err(
                "a second-level point's weights are not eighths of its triangle's corner \
                 samples, or a sub-triangle is named by no triangle's corners"
                    .into(),
            );
        }
        Ok(())
    }

    /// Bytes of the stored arrays (what a scene keeps in memory).
    pub fn payload_bytes(&self) -> usize {
        self.shape.bytes() + 4 * (self.shape_scale.len() + self.coeffs.len() + self.ratio.len())
    }

    /// The xxh3 of everything the file holds but the build's wall-clock times: equal for
    /// two builds of the same presses however they ran (sharded and merged, resumed
    /// after a kill, on another machine).
    pub fn payload_xxh3(&self) -> u64 {
        let mut law = self.clone();
        (law.build_s, law.compress_s) = (0.0, 0.0);
        let bytes = bincode::serde::encode_to_vec(
            (
                &law,
                &self.refinement.sub,
                &self.refinement.band,
                self.mesh_xxh3,
                &self.accuracy,
            ),
            bincode::config::standard(),
        )
        .expect("a loaded or built law always encodes");
        xxhash_rust::xxh3::xxh3_64(&bytes)
    }

    /// Writes the law atomically (a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), TissueError> {
        let Some(mesh_xxh3) = self.mesh_xxh3 else {
            return Err(TissueError::NoFingerprint {
                path: path.to_path_buf(),
            });
        };
        let mut stored = self.clone();
        stored.shape = RowPrediction::new(&self.rows_mm)
            .encode(&self.shape)
            .ok_or_else(|| TissueError::Corrupt {
                path: path.to_path_buf(),
                why: shape_length_why(&self.shape, self.rows_mm.len()),
            })?;
        let weights = Weights::pack(&std::mem::take(&mut stored.coeffs));
        let sub = &self.refinement.sub;
        crate::framed::write(
            path,
            MAGIC,
            (VERSION, Body::Lzma),
            &(
                &stored,
                &weights,
                sub,
                &self.refinement.band,
                mesh_xxh3,
                &self.accuracy,
            ),
        )
        .map_err(|source| TissueError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    pub fn load(path: &Path) -> Result<TissueLaw, TissueError> {
        let bytes = std::fs::read(path).map_err(|source| TissueError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Reads a law from a file's bytes (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<TissueLaw, TissueError> {
        use crate::framed::FramedError;
        let p = || path.to_path_buf();
        let named = |e| match e {
            FramedError::Foreign => TissueError::Foreign { path: p() },
            FramedError::Version(found) => TissueError::Version { path: p(), found },
            FramedError::Corrupt(why) => TissueError::Corrupt { path: p(), why },
        };
        type Body5 = (TissueLaw, Weights, SubSplit, Vec<BandEdge>, u64, Accuracy);
        let (mut law, weights, sub, band, mesh_xxh3, accuracy) =
            match crate::framed::read::<Body5>(bytes, MAGIC, &[(VERSION, Body::Lzma)]) {
                Ok(body) => body,
                Err(e) => return Err(named(e)),
            };
        law.coeffs = weights
            .unpack()
            .map_err(|why| TissueError::Corrupt { path: p(), why })?;
        law.shape = RowPrediction::new(&law.rows_mm)
            .decode(&law.shape)
            .ok_or_else(|| TissueError::Corrupt {
                path: p(),
                why: shape_length_why(&law.shape, law.rows_mm.len()),
            })?;
        law.refinement.sub = sub;
        law.refinement.band = band;
        law.mesh_xxh3 = Some(mesh_xxh3);
        law.accuracy = accuracy;
        law.check()
            .map_err(|why| TissueError::Corrupt { path: p(), why })?;
        Ok(law)
    }
}

/// Where a scene's linear model (its provenance's `mesh` line, e.g. `... element=p2
/// young_kpa=160 poisson=0.48 ...`) used another element or material than a nonlinear
/// law built with `element` and `material`: the two descriptions, the law's first.
/// Keys the line does not name are not compared.
pub fn linear_model_mismatch(
    element: Element,
    material: &Material,
    scene_mesh_line: &str,
) -> Option<(String, String)> {
    let value = |key: &str| {
        scene_mesh_line
            .split_whitespace()
            .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
    };
    let number_differs = |key: &str, ours: f64| {
        value(key)
            .and_then(|v| v.parse::<f64>().ok())
            .is_some_and(|v| (v - ours).abs() > 1e-9 * ours.abs().max(1.0))
    };
    let element_differs = value("element").is_some_and(|e| e != element.name());
    if !(element_differs
        || number_differs("young_kpa", material.young_kpa)
        || number_differs("poisson", material.poisson))
    {
        return None;
    }
    let describe = |e: &str, y: String, p: String| format!("{e}, E = {y} kPa, ν = {p}");
    Some((
        describe(
            element.name(),
            material.young_kpa.to_string(),
            material.poisson.to_string(),
        ),
        describe(
            value("element").unwrap_or("?"),
            value("young_kpa").unwrap_or("?").to_string(),
            value("poisson").unwrap_or("?").to_string(),
        ),
    ))
}

/// Why `shape` is no whole number of modes over `rows` surface rows.
fn shape_length_why(shape: &Shapes, rows: usize) -> String {
    format!(
        "{} shape entries over {rows} surface rows: expected a whole number of modes of {} \
         entries each",
        shape.len(),
        3 * rows
    )
}

/// Whether `path` starts with a tissue file's magic (an unreadable path is not one;
/// loading it then says why).
pub fn is_tissue_file(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == MAGIC)
}

/// How far apart (mm) a law's rest position and a scene's may be and still be the
/// same mesh vertex (they pass through f32 and f64).
pub const SAME_POINT_MM: f64 = 0.01;

/// Points by position: which of a set lies within [`SAME_POINT_MM`] of a query (a
/// hash grid of 1 mm cells, the query's cell and its neighbours searched, so a point
/// next to a cell's border is found as well).
#[derive(Debug, Clone)]
pub struct PointIndex {
    cells: HashMap<[i64; 3], Vec<(u32, [f64; 3])>>,
}

impl PointIndex {
    pub fn new(points: impl IntoIterator<Item = [f64; 3]>) -> PointIndex {
        let mut cells: HashMap<[i64; 3], Vec<(u32, [f64; 3])>> = HashMap::new();
        for (i, p) in points.into_iter().enumerate() {
            cells.entry(cell(p)).or_default().push((i as u32, p));
        }
        PointIndex { cells }
    }

    /// The index of a point within [`SAME_POINT_MM`] of `p`, if any.
    pub fn find(&self, p: [f64; 3]) -> Option<u32> {
        let c = cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &(i, q) in list {
                        let d2: f64 = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum();
                        if d2 <= SAME_POINT_MM * SAME_POINT_MM {
                            return Some(i);
                        }
                    }
                }
            }
        }
        None
    }
}

/// Over the organ's surface nodes drawn by the scene (`vertex_of`: a node's render
/// vertex by rest position): each candidate's largest nodal distance from the
/// reference field `reference` (organ node order; candidates in the scene's row
/// order), and the reference's largest displacement (mm).
pub fn max_node_errors<const N: usize>(
    organ: &OrganMesh,
    vertex_of: &PointIndex,
    reference: &[f64],
    candidates: [&[f64]; N],
) -> ([f64; N], f64) {
    let (mut worst, mut top) = ([0.0f64; N], 0.0f64);
    for v in organ.surface_nodes() {
        let Some(r) = vertex_of.find(organ.mesh.vertices[v as usize]) else {
            continue;
        };
        let (i, r) = (3 * v as usize, 3 * r as usize);
        let dist = |rows: &[f64]| {
            (0..3)
                .map(|k| (rows[r + k] - reference[i + k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        for (w, rows) in worst.iter_mut().zip(candidates) {
            *w = w.max(dist(rows));
        }
        top = top.max((0..3).map(|k| reference[i + k].powi(2)).sum::<f64>().sqrt());
    }
    (worst, top)
}

fn cell(p: [f64; 3]) -> [i64; 3] {
    p.map(|x| x.floor() as i64)
}

#[cfg(test)]
pub(crate) mod tests;
