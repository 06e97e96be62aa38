//! The nodule's effect on the probe's force, tabulated off-line over the nodule's centre,
//! radius and ratio and over the probe point, so that a nodule is answered without a
//! solve and without the stored interior responses (hundreds of megabytes a region).
//!
//! **What is tabulated.** A nodule `n = (c, R, β)` changes the probe's compliance at the
//! point `x` by `δc(x; n)`, exactly given by Woodbury's identity ([`super`]). For a fixed
//! geometry `(c, R)` the identity makes `δc` a sum over the nodule's polarization modes
//! of `(β−1)/(1+(β−1)λ_k)`; one mode carries it:
//!
//! ```text
//! δc(x; c, R, β) ≈ −A(x; c, R) (β−1) / (1 + (β−1) λ(x; c, R))
//! ```
//!
//! with `A` and `λ` fitted through the exact `δc` at two ratios ([`FIT_RATIOS`]; within
//! 1.5 % of the exact effect at ratios 1.5–10, docs/lab/nodule-measurements.md §6).
//! They are kept at the nodes of a lattice of centres (spacing `h`), at a few radii,
//! and at the P2 nodes of the palpable surface within [`TableSettings::probe_reach_mm`]
//! of each centre. The probe nodes of one centre and radius share one pole: `λ` is their
//! `|A|`-weighted mean (the dominant polarization mode's, whichever probe reads it) and
//! each `A` is matched at ratio 4, then stored in 127ths of the largest: a byte an entry
//! and radius, where an `(A, λ)` of its own took four (§11 of the lab notes: the error at
//! held-out pairs unchanged). Between lattice nodes the table is trilinear in the centre
//! and quadratic in the radius (through the three tabulated radii about it), and over a
//! boundary triangle the effect is interpolated quadratically from its six nodes. The
//! force of a depth-controlled press changes by the factor `c₀/(c₀+δc)`, `c₀` the
//! nodule-free compliance at the node.
//!
//! **Beyond the reach** a lattice node has no entries, yet a nodule is still felt there
//! (up to 4 % of the force 30–45 mm from its centre). There the change is a far field,
//! `−δc ∝ ρ^{−p}` with `ρ` the distance from the lattice node: the probe's strain at
//! the nodule falls as `ρ⁻²` in a half-space and the change goes with its square (`p` =
//! 4); the organ's finite size and the fixed region make it fall more slowly. The far
//! field is read along the line from the probe node to the lattice node: the entry for
//! that probe of the lattice node nearest the point 0.9 of the reach from the probe
//! ([`TOWARD_REACH`]), carried out as `ρ^{−3}` ([`TOWARD_POWER`]). Where that node has no
//! entry (outside the band), a ring's: `τ ρ^{−3.5}` ([`TAIL_POWER`]), `τ` from the node's
//! own entries in the outer fifth of its reach weighted by their nearness to the probe
//! node (`(d² + 3²)⁻²`, `d` in mm) (docs/lab/nodule-measurements.md §13–14).
//!
//! **Past the band** (a centre deeper, or a lattice cell reaching beside a surface no
//! probe presses) the nodule is answered from the deepest centre on the way to its
//! nearest probe node that the band answers, carried back the same way
//! ([`EffectTable::place`]); [`EffectTable::place_in_band`] refuses it instead.
//! **Radii** past the largest tabulated, to [`RADIUS_REACH`] times it, are the quadratic
//! through the three largest carried on.
//!
//! **Off-line** ([`EffectTable::build`]): one store of interior responses
//! ([`super::InteriorResponses`]) for every unknown the lattice's nodules can touch, each
//! column solved once; the lattice is cut into blocks, each block's store cut from it,
//! and every node's nodules placed exactly there, all the probe nodes' responses solved
//! once beforehand and read by every placement in one blocked solve. A lattice node
//! only has to lie inside the organ: a nodule there may reach past the surface (its
//! cells are clipped as the FE clips them), which is what lets a nodule at the 2 mm
//! limit be interpolated from nodes on both sides; nodes shallower than any answered
//! nodule's interpolation reads are left out. A probe node held by the fixed region
//! has no compliance and feels no nodule.
//! **On-line** ([`EffectTable::place`]): the effect at every probe node for one nodule
//! (a few thousand products), then [`NoduleEffect::at`] per probe point.
//!
//! **The surface** is not tabulated: the one drawn with a nodule is the nodule-free
//! surface at the depth the press reaches, swayed away from the tool with the force the
//! nodule adds ([`surface_gain`]).

use std::collections::HashMap;
use std::time::Instant;

use faer::Mat;
use rayon::prelude::*;
use thiserror::Error;

use super::{InteriorResponses, NoduleRanges};
use crate::axis::closest_point;
use crate::disk::TRI_EDGES;
use crate::fe::load::{probe_functional, probe_load};
use crate::fe::nodule::{MIN_DEPTH_MM, Nodule, inside};
use crate::fe::probe::smooth_inward_dir;
use crate::mesh::{norm, sub};
use crate::organ::OrganMesh;
use crate::pgd::nodal::NodalSetup;

/// A probe node's unit load and functional (free unknown, value).
type Load = (Vec<(u32, f64)>, Vec<(u32, f64)>);

/// A lattice node's entries: the probe nodes within reach, then per radius the shared
/// `λ`, the scale and each entry's steps (`entry * radii + r`).
type Entries = (Vec<u32>, Vec<f32>, Vec<f32>, Vec<i8>);

/// The two ratios each lattice node's nodules are placed at, which fix the one-pole
/// form's `A` and `λ`.
pub const FIT_RATIOS: [f64; 2] = [2.0, 10.0];

/// The largest ratio a table answers: the one-pole form carried past the fit's ratios
/// towards its limit `−A/λ` (a rigid inclusion), measured against the full FE at ratios
/// 10–100 (docs/lab/nodule-measurements.md §9).
pub const MAX_RATIO: f64 = 100.0;

/// How far past its largest tabulated radius a table answers, as a factor of it: the
/// quadratic over the radius extrapolated (12 mm tabulated, 15 mm answered), measured
/// against the full FE at radii past the largest (docs/lab/nodule-measurements.md §14).
pub const RADIUS_REACH: f64 = 1.25;

/// Why a table cannot answer a nodule, or could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TableError {
    #[error(
        "the nodule's centre {center_mm:?} mm lies outside the table's lattice of centres (from {lo_mm:?} to {hi_mm:?} mm, nodes inside the organ only)"
    )]
    CentreOutside {
        center_mm: [f64; 3],
        lo_mm: [f64; 3],
        hi_mm: [f64; 3],
    },
    #[error(
        "the nodule's centre {center_mm:?} mm lies outside the organ (expected a centre inside it, at least {MIN_DEPTH_MM} mm plus its radius under the surface)"
    )]
    OutsideOrgan { center_mm: [f64; 3] },
    #[error(
        "the nodule reaches {depth_mm:.1} mm from the organ's surface; expected at least {MIN_DEPTH_MM} mm (its centre deeper, or its radius smaller)"
    )]
    TooShallow { depth_mm: f64 },
    #[error("nodule radius {radius_mm} mm is outside the table's range {lo} to {hi} mm")]
    Radius { radius_mm: f64, lo: f64, hi: f64 },
    #[error("nodule ratio {ratio} is outside the table's range {lo} to {hi}")]
    Ratio { ratio: f64, lo: f64, hi: f64 },
    #[error(
        "the table was built on mesh {table}, the scene is of mesh {scene}: expected the table of the scene's mesh (`palpa nodule build` on the scene's organ and level)"
    )]
    Mesh { table: String, scene: String },
    #[error("the full FE solve of a held-out pair: {0}")]
    Fe(String),
    #[error("the table's settings: {0}")]
    Settings(String),
    #[error("{path}: not a nodule table (expected a file `EffectTable::save` wrote)")]
    Foreign { path: String },
    #[error(
        "{path}: nodule table format version {found}, this palpa reads version {VERSION}: build it again with `palpa nodule build` (then `palpa nodule tissue` for a tissue's power and `palpa nodule check --record`)"
    )]
    Version { path: String, found: u32 },
    #[error("{path}: {why}")]
    Corrupt { path: String, why: String },
    #[error(
        "{path}: shard {i} of {n} of a build, not a whole table: join the {n} shards with `palpa nodule merge`"
    )]
    Shard { path: String, i: u32, n: u32 },
    #[error("merging shards: {0}")]
    Merge(String),
    #[error("{path}: {why}")]
    Io { path: String, why: String },
    #[error("probe node {node} at {at_mm:?} mm: {why}")]
    ProbeNode {
        node: u32,
        at_mm: [f64; 3],
        why: String,
    },
}

/// What the off-line build tabulates.
#[derive(Debug, Clone, PartialEq)]
pub struct TableSettings {
    /// The lattice's middle and half its width along each axis (mm): nodes at
    /// `centre + h·(i, j, k)` within it.
    pub centre_mm: [f64; 3],
    pub half_width_mm: [f64; 3],
    /// Only lattice nodes within this distance of the palpable surface (mm), where a
    /// nodule can be felt; every node inside the organ where `None`.
    pub max_depth_mm: Option<f64>,
    /// Lattice spacing `h` (mm).
    pub spacing_mm: f64,
    /// The radii tabulated, ascending: the table answers radii between the first and the
    /// last.
    pub radii_mm: Vec<f64>,
    /// Probe nodes farther than this from a lattice node get no entry there (the far
    /// field fitted to its outermost entries answers there).
    pub probe_reach_mm: f64,
    /// Lattice nodes a side of one store's block.
    pub block: usize,
    /// `Some([i, n])`: build only shard `i` of `n` (from 1), its blocks dealt in turn;
    /// [`EffectTable::merge`] joins the `n` shards into the whole build.
    pub shard: Option<[usize; 2]>,
}

/// The file's magic bytes and its one format version.
pub const MAGIC: &[u8; 8] = b"PALPANOD";
pub const VERSION: u32 = 10;

/// Whether `path` starts as a nodule table does (unreadable: no).
pub fn is_table_file(path: &std::path::Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == MAGIC)
}

/// The tabulated effect.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EffectTable {
    /// The mesh it was built on ([`OrganMesh::fingerprint`]).
    pub mesh_xxh3: u64,
    pub origin_mm: [f64; 3],
    pub spacing_mm: f64,
    /// Lattice nodes along each axis.
    pub dims: [usize; 3],
    pub radii_mm: Vec<f64>,
    /// Per lattice node (x fastest): inside the organ, with entries.
    pub valid: Vec<bool>,
    /// Per lattice node: its distance to the organ's surface (mm; negative outside the
    /// organ), interpolated to a nodule's centre to refuse one within [`MIN_DEPTH_MM`]
    /// of the surface or outside the organ.
    pub surface_mm: Vec<f32>,
    /// Entries of lattice node `k`: `starts[k]..starts[k + 1]`.
    pub starts: Vec<u32>,
    /// Each entry's probe node (index into `probe_nodes`).
    pub entry_node: Vec<u32>,
    /// Per lattice node and radius (`node * radii + r`): the pole `λ ≥ 0` its entries
    /// share, and the scale of their `A` (mm/N).
    pub lambda: Vec<f32>,
    pub scale: Vec<f32>,
    /// Each entry's `A` per radius (`entry * radii + r`), in 127ths of its lattice
    /// node's scale.
    pub amp: Vec<i8>,
    /// The probe nodes: space nodes of the palpable surface's P2 faces, their rest
    /// positions and nodule-free compliance (mm/N; 0 where the fixed region holds it).
    pub probe_nodes: Vec<u32>,
    pub probe_mm: Vec<[f32; 3]>,
    pub compliance_mm_per_n: Vec<f64>,
    /// Each palpable boundary face's six probe nodes (corners, then the midpoints of
    /// edges 01, 12, 02), by face; `None` for faces outside the palpable region.
    pub face_nodes: Vec<Option<[u32; 6]>>,
    /// Seconds of the build: stores, placements, all.
    pub stores_s: f64,
    pub placements_s: f64,
    pub build_s: f64,
    pub placements: usize,
    /// Held-out checks against the full FE, as `palpa nodule check --record` measured
    /// them.
    pub checks: Vec<TableCheck>,
    /// Held-out presses of the scene's nonlinear tissue with the table's effect against
    /// Newton with the nodule, as `palpa nodule check --tissue --record` measured them.
    pub tissue_checks: Vec<TissueCheck>,
    /// `Some([i, n])`: only shard `i` of `n` of a build, not a table to answer from
    /// until merged.
    pub shard: Option<[u32; 2]>,
    /// How a tissue's presses share their power among the cells near each vertex: the
    /// amplification of the effect in that tissue (`palpa nodule tissue`).
    pub tissue_power: Option<super::amplification::CellPower>,
}

/// One held-out pair of a recorded check (`super::heldout`), as measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckedPair {
    pub nodule: [f64; 5],
    /// The probe point (mm, on the palpable surface).
    pub at_mm: [f64; 3],
    pub effect_fe: f64,
    pub effect_table: f64,
    /// The largest distance over the scene's surface vertices between the surface
    /// drawn at 1 N with the nodule (the nodule-free one at the probe's depth, times
    /// [`surface_gain`]) and the FE's with it (mm).
    pub surface_mm: f64,
}

/// A nodule as a recorded check keeps it: centre (mm), radius (mm), ratio.
pub fn nodule_row(n: &Nodule) -> [f64; 5] {
    [
        n.center_mm[0],
        n.center_mm[1],
        n.center_mm[2],
        n.radius_mm,
        n.ratio,
    ]
}

impl CheckedPair {
    /// The nodule: centre, radius, ratio.
    pub fn nodule(&self) -> Nodule {
        let n = self.nodule;
        Nodule {
            center_mm: [n[0], n[1], n[2]],
            radius_mm: n[3],
            ratio: n[4],
        }
    }

    /// `|table − FE| / FE`, the effect's relative error.
    pub fn error(&self) -> f64 {
        (self.effect_table - self.effect_fe).abs() / self.effect_fe.abs().max(1e-300)
    }
}

/// A recorded check: its seed and pairs.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TableCheck {
    pub seed: u64,
    pub pairs: Vec<CheckedPair>,
    /// Seconds of the FE solves (two a pair).
    pub fe_s: f64,
}

/// One held-out press of a recorded tissue check: the nonlinear tissue's force times
/// `1 + e A` (the table's effect `e` at the point amplified as the tissue's press loads
/// the nodule, as the app's force loop applies it) against Newton's with the nodule, at
/// one depth.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TissuePair {
    /// Centre (mm), radius (mm), ratio.
    pub nodule: [f64; 5],
    /// The probe point (mm, on the palpable surface) and the press's depth (mm).
    pub at_mm: [f64; 3],
    pub depth_mm: f64,
    /// Newton's force without and with the nodule (N).
    pub force_fe_without_n: f64,
    pub force_fe_n: f64,
    /// The tissue's force without the nodule (N), the table's (linear) effect at the
    /// point, and the effect the tissue answered with at this depth, `e A`
    /// ([`super::amplification::EffectCurve`]).
    pub force_tissue_without_n: f64,
    pub effect_linear: f64,
    pub effect_answered: f64,
    /// The largest distance over the surface's vertices between the surface drawn (the
    /// tissue's without the nodule at the press's depth, times [`surface_gain`] of the
    /// effect answered) and Newton's with it (mm).
    pub surface_mm: f64,
}

impl TissuePair {
    /// Newton's effect, `F_with/F_without − 1`.
    pub fn effect_fe(&self) -> f64 {
        self.force_fe_n / self.force_fe_without_n - 1.0
    }

    /// The answered force with the nodule against Newton's, relative.
    pub fn force_error(&self) -> f64 {
        let f = self.force_tissue_without_n * (1.0 + self.effect_answered);
        (f - self.force_fe_n).abs() / self.force_fe_n
    }

    /// The answered effect's relative error.
    pub fn effect_error(&self) -> f64 {
        let fe = self.effect_fe();
        (self.effect_answered - fe).abs() / fe.abs().max(1e-300)
    }
}

/// How far about the probe (mm) the drawn surface with a nodule keeps the nodule-free
/// shape at the pressed depth ([`surface_gain`]; chosen at the recorded pairs,
/// docs/lab/nodule-measurements.md §15).
pub const SURFACE_NEAR_MM: f64 = 10.0;

/// The drawn surface with a nodule at a vertex `distance2_mm2` (squared, mm²) from the
/// probe, as a multiple of the nodule-free surface at the same depth, the nodule
/// changing the force by `effect`: `1 + e (1 − exp(−r²/ℓ²))`, `ℓ` =
/// [`SURFACE_NEAR_MM`]. Under the tool the depth holds the surface (gain 1); away from
/// it the organ sways with the total force, `1 + e` times the nodule-free one's at that
/// depth. A nodule's own correction field is local to it and the probe, and small
/// next to either part (ratio 1: gain 1 everywhere).
#[inline]
pub fn surface_gain(effect: f64, distance2_mm2: f64) -> f64 {
    1.0 + effect * (1.0 - (-distance2_mm2 / (SURFACE_NEAR_MM * SURFACE_NEAR_MM)).exp())
}

/// Multiplies the drawn surface `rows` (3 per vertex, mm; the nodule-free surface at
/// the pressed depth) by [`surface_gain`] at each of `vertices_mm` (rest positions), the
/// probe at `probe_mm` (rest), the nodule changing the force by `effect`.
pub fn apply_surface_gain(
    effect: f64,
    probe_mm: [f64; 3],
    vertices_mm: impl IntoIterator<Item = [f64; 3]>,
    rows: &mut [f64],
) {
    if effect == 0.0 {
        return;
    }
    for (x, u) in vertices_mm.into_iter().zip(rows.chunks_exact_mut(3)) {
        let r2: f64 = (0..3).map(|k| (x[k] - probe_mm[k]).powi(2)).sum();
        let g = surface_gain(effect, r2);
        u.iter_mut().for_each(|v| *v *= g);
    }
}

/// Under a force `force_n`, the depth at which the tissue's force times
/// `1 + effect(depth)` gives it, and whether the tissue's depth is held at its limit:
/// `depth_of(F)` is the tissue's depth under `F`. A few fixed-point steps (the gain
/// changes by a few per cent of the force over the whole press).
pub fn depth_under_force(
    force_n: f64,
    effect: &super::amplification::EffectCurve,
    depth_of: impl Fn(f64) -> (f64, bool),
) -> (f64, bool) {
    let mut out = depth_of(force_n / (1.0 + effect.at(0.0)));
    if effect.len > 0 {
        for _ in 0..4 {
            out = depth_of(force_n / (1.0 + effect.at(out.0)));
        }
    }
    out
}

/// A recorded tissue check: the tissue file it answered with, its seed and presses.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TissueCheck {
    pub seed: u64,
    /// The tissue file's name, law and payload checksum (`palpa info X.tissue`).
    pub tissue: String,
    pub law: String,
    pub tissue_xxh3: u64,
    /// Whether the effect was amplified by the table's power of this tissue
    /// ([`EffectTable::tissue_power`]); else the linear effect as it is.
    pub amplified: bool,
    pub pairs: Vec<TissuePair>,
    /// Seconds of Newton's solves (two presses a pair).
    pub fe_s: f64,
}

/// One nodule's effect at every probe node: what a probe reads.
#[derive(Debug, Clone)]
pub struct NoduleEffect {
    pub nodule: Nodule,
    /// `F_with/F_without − 1` at each probe node.
    pub at_node: Vec<f64>,
    pub place_s: f64,
}

/// The largest `|λ|` a fit keeps (a change that hardly grows between the fit's ratios).
const LAMBDA_MAX: f64 = 1e3;

/// The ratio at which an entry's `A` is matched once its lattice node's shared `λ` is
/// set: the fit's ratios' geometric middle.
const MATCH_RATIO: f64 = 4.0;

/// The tail beyond a lattice node's reach is read from its entries farther than this
/// share of the reach,
const TAIL_RING: f64 = 0.8;
/// each weighted by `(d² + TAIL_NEAR_MM²)⁻²`, `d` its distance to the probe node read,
const TAIL_NEAR_MM: f64 = 3.0;
/// and carried out as `ρ^{−TAIL_POWER}`.
const TAIL_POWER: f64 = 3.5;

/// Beyond the reach, a probe node is read first from the lattice node on the way from it
/// to the centre at this share of the reach (within reach there), its entry carried to
/// the centre as `ρ^{−TOWARD_POWER}`: the change along one line, where the ring's holds
/// the change in other directions (docs/lab/nodule-measurements.md §14).
const TOWARD_REACH: f64 = 0.9;
const TOWARD_POWER: f64 = 3.0;

/// One lattice node's entries at one radius, `(A, λ)` each (fitted alone), made to
/// share one pole: `λ̄ = Σ|A|λ / Σ|A|` (at least 0: every polarization mode's is), each
/// `A` matched at [`MATCH_RATIO`], then stored in 127ths of the largest. Returns `λ̄`,
/// the scale, and the steps (docs/lab/nodule-measurements.md §11: the effect within
/// 7.4 % at held-out pairs where the entries' own poles gave 8.0 %).
fn share_pole(fits: &[[f64; 2]]) -> (f32, f32, Vec<i8>) {
    let weight: f64 = fits.iter().map(|f| f[0].abs()).sum();
    let lambda = if weight > 0.0 {
        (fits.iter().map(|f| f[0].abs() * f[1]).sum::<f64>() / weight).max(0.0)
    } else {
        0.0
    };
    let b = MATCH_RATIO - 1.0;
    let a: Vec<f64> = fits
        .iter()
        .map(|&[a, l]| a * b / (1.0 + b * l) * (1.0 + b * lambda) / b)
        .collect();
    let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let steps = a
        .iter()
        .map(|&x| {
            if scale > 0.0 {
                (x / scale * 127.0).round().clamp(-127.0, 127.0) as i8
            } else {
                0
            }
        })
        .collect();
    (lambda as f32, scale as f32, steps)
}

/// Each probe node's nodule-free compliance `φᵀ K₀⁻¹ f` (mm/N), and the responses
/// `K₀⁻¹ f` and `K₀⁻¹ φ` at `store`'s columns, in single precision. Solved in batches of
/// consecutive probe nodes, so that every shard of a build gets the same values.
#[allow(clippy::type_complexity)]
fn probe_responses(
    setup: &NodalSetup,
    loads: &[Load],
    store: &InteriorResponses,
) -> (Vec<f64>, Vec<(Vec<f32>, Vec<f32>)>) {
    const BATCH: usize = 48;
    let n = setup.space.free_dofs;
    let solved: Vec<Vec<(f64, (Vec<f32>, Vec<f32>))>> = loads
        .par_chunks(BATCH)
        .map(|chunk| {
            let mut rhs = Mat::<f64>::zeros(n, 2 * chunk.len());
            for (k, (f, phi)) in chunk.iter().enumerate() {
                for &(d, x) in f {
                    rhs[(d as usize, 2 * k)] = x;
                }
                for &(d, x) in phi {
                    rhs[(d as usize, 2 * k + 1)] = x;
                }
            }
            setup.problem.factor.solve_many(&mut rhs);
            chunk
                .iter()
                .enumerate()
                .map(|(k, (_, phi))| {
                    let c0: f64 = phi.iter().map(|&(d, x)| x * rhs[(d as usize, 2 * k)]).sum();
                    let at = |j: usize| -> Vec<f32> {
                        store
                            .cols
                            .iter()
                            .map(|&d| rhs[(d as usize, j)] as f32)
                            .collect()
                    };
                    (c0, (at(2 * k), at(2 * k + 1)))
                })
                .collect()
        })
        .collect();
    solved.into_iter().flatten().unzip()
}

/// `(A, λ)` through `y₁ = −δc(β = 2)` and `y₂ = −δc(β = 10)`: `1/y` is linear in
/// `1/(β−1)` with slope `1/A` and intercept `λ/A`. Negligible changes (below 1e-12 mm/N)
/// give `(0, 0)`.
fn one_pole(y1: f64, y2: f64) -> [f64; 2] {
    if y1.abs() < 1e-12 || y2.abs() < 1e-12 {
        return [0.0, 0.0];
    }
    let (x1, x2) = (1.0 / (FIT_RATIOS[0] - 1.0), 1.0 / (FIT_RATIOS[1] - 1.0));
    let slope = (1.0 / y1 - 1.0 / y2) / (x1 - x2);
    let a = 1.0 / slope;
    let lambda = (1.0 / y1 - slope * x1) * a;
    if !(a.is_finite() && lambda.is_finite()) {
        return [0.0, 0.0];
    }
    // Saturated (the change hardly grows between the ratios): λ held at LAMBDA_MAX and
    // A matched at β = 10, within half precision's range.
    if lambda.abs() > LAMBDA_MAX {
        let l = LAMBDA_MAX.copysign(lambda);
        let b = FIT_RATIOS[1] - 1.0;
        return [y2 * (1.0 + b * l) / b, l];
    }
    [a, lambda]
}

/// `−δc` of the one-pole form at ratio `beta`.
#[inline]
fn pole(fit: [f64; 2], beta: f64) -> f64 {
    let b = beta - 1.0;
    fit[0] * b / (1.0 + b * fit[1])
}

impl EffectTable {
    fn index(&self, i: [usize; 3]) -> usize {
        i[0] + self.dims[0] * (i[1] + self.dims[1] * i[2])
    }

    fn node_mm(&self, i: [usize; 3]) -> [f64; 3] {
        [0, 1, 2].map(|d| self.origin_mm[d] + self.spacing_mm * i[d] as f64)
    }

    /// The lattice's box: its first and last nodes (mm).
    pub fn box_mm(&self) -> ([f64; 3], [f64; 3]) {
        (self.origin_mm, self.node_mm(self.dims.map(|d| d - 1)))
    }

    /// The table belongs to the scene whose provenance's mesh line is `mesh_line`
    /// (it records `mesh_xxh3`).
    pub fn check_mesh(&self, mesh_line: &str) -> Result<(), TableError> {
        let table = format!("{:016x}", self.mesh_xxh3);
        let scene = crate::pgd::palpation::describe_get(mesh_line, "mesh_xxh3");
        if scene == Some(table.as_str()) {
            return Ok(());
        }
        Err(TableError::Mesh {
            table,
            scene: scene.unwrap_or("(not recorded)").to_string(),
        })
    }

    /// The table a build with `step` times the spacing (and only the radii `radii`,
    /// indices into `radii_mm`, the first and last among them) would have written: the
    /// same lattice nodes' entries, every `step`-th along each axis. `None` where `step`
    /// does not divide the lattice's cells or the radii are not two or more, ascending.
    /// What `palpa tradeoff` measures the knobs with, without building again.
    pub fn coarsened(&self, step: usize, radii: &[usize]) -> Option<EffectTable> {
        let r = self.radii_mm.len();
        if step == 0
            || self.dims.iter().any(|&d| (d - 1) % step != 0)
            || radii.len() < 2
            || !radii.windows(2).all(|w| w[0] < w[1])
            || radii[radii.len() - 1] >= r
        {
            return None;
        }
        let dims = self.dims.map(|d| (d - 1) / step + 1);
        let mut out = EffectTable {
            dims,
            spacing_mm: self.spacing_mm * step as f64,
            radii_mm: radii.iter().map(|&i| self.radii_mm[i]).collect(),
            valid: Vec::new(),
            surface_mm: Vec::new(),
            starts: vec![0],
            entry_node: Vec::new(),
            lambda: Vec::new(),
            scale: Vec::new(),
            amp: Vec::new(),
            checks: Vec::new(),
            tissue_checks: Vec::new(),
            tissue_power: None,
            ..self.clone()
        };
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let n = self.index([i * step, j * step, k * step]);
                    out.valid.push(self.valid[n]);
                    out.surface_mm.push(self.surface_mm[n]);
                    out.lambda
                        .extend(radii.iter().map(|&q| self.lambda[n * r + q]));
                    out.scale
                        .extend(radii.iter().map(|&q| self.scale[n * r + q]));
                    for e in self.starts[n] as usize..self.starts[n + 1] as usize {
                        out.entry_node.push(self.entry_node[e]);
                        out.amp.extend(radii.iter().map(|&q| self.amp[e * r + q]));
                    }
                    out.starts.push(out.entry_node.len() as u32);
                }
            }
        }
        Some(out)
    }

    /// The radii answered: the first and last tabulated (mm).
    /// The radii the table answers: from its smallest tabulated radius to
    /// [`RADIUS_REACH`] times its largest (past it, the quadratic through the three
    /// largest radii carries the effect on).
    pub fn radius_range_mm(&self) -> [f64; 2] {
        [
            self.radii_mm.first().copied().unwrap_or(0.0),
            self.radii_mm.last().copied().unwrap_or(0.0) * RADIUS_REACH,
        ]
    }

    /// Builds the table over `settings`' lattice for the nodal setup `setup` of `organ`.
    pub fn build(
        setup: &NodalSetup,
        organ: &OrganMesh,
        settings: &TableSettings,
    ) -> Result<EffectTable, TableError> {
        let t0 = Instant::now();
        let s = settings;
        let ok = s.spacing_mm.is_finite()
            && s.spacing_mm > 0.0
            && s.half_width_mm.iter().all(|w| w.is_finite() && *w >= 0.0)
            && s.max_depth_mm.is_none_or(|d| d.is_finite() && d > 0.0)
            && s.shard.is_none_or(|[i, n]| i >= 1 && i <= n)
            && s.radii_mm.len() >= 2
            && s.radii_mm.windows(2).all(|w| w[0] < w[1])
            && s.radii_mm[0] > 0.0
            && s.probe_reach_mm > 0.0
            && s.block >= 1;
        if !ok {
            return Err(TableError::Settings(format!(
                "{s:?}: expected a positive spacing, non-negative half widths, a positive depth, \
                 two or more ascending positive radii, a positive probe reach, blocks of one \
                 node or more and a shard I/N with I from 1 to N"
            )));
        }
        let space = &setup.space;
        let half = s.half_width_mm.map(|w| (w / s.spacing_mm).floor() as usize);
        let dims = half.map(|h| 2 * h + 1);
        let lattice: usize = dims.iter().product();
        let origin_mm = [0, 1, 2].map(|d| s.centre_mm[d] - s.spacing_mm * half[d] as f64);
        // The probe nodes: every node of a palpable face within reach of the lattice.
        let reach = s.probe_reach_mm + norm(s.half_width_mm);
        let mut node_of: HashMap<u32, u32> = HashMap::new();
        let mut probe_nodes = Vec::new();
        let mut face_nodes = vec![None; space.face_count()];
        for (f, slot) in face_nodes.iter_mut().enumerate() {
            if !organ.palpable.get(f).copied().unwrap_or(false) {
                continue;
            }
            let face = space.face(f);
            if face.len() != 6 {
                return Err(TableError::Settings(
                    "expected a P2 space (six nodes a boundary face)".into(),
                ));
            }
            let near = face
                .iter()
                .any(|&v| norm(sub(space.nodes[v as usize], s.centre_mm)) <= reach);
            if !near {
                continue;
            }
            let mut six = [0u32; 6];
            for (k, &v) in face.iter().enumerate() {
                let next = probe_nodes.len() as u32;
                six[k] = *node_of.entry(v).or_insert_with(|| {
                    probe_nodes.push(v);
                    next
                });
            }
            *slot = Some(six);
        }
        // Each probe node's load and functional (their responses are solved below, in
        // batches).
        let loads: Vec<Load> = probe_nodes
            .par_iter()
            .map(|&v| {
                let at = space.nodes[v as usize];
                let fail = |why: String| TableError::ProbeNode {
                    node: v,
                    at_mm: at,
                    why,
                };
                let point = crate::fe::load::project(space, &organ.palpable, at)
                    .ok_or_else(|| fail("no palpable surface to project onto".into()))?;
                let dir = smooth_inward_dir(organ, point.point).map_err(|e| fail(e.to_string()))?;
                let f = probe_load(space, &point, dir, 1.0, setup.radius_mm)
                    .map_err(|e| fail(e.to_string()))?;
                let phi = probe_functional(space, &point, dir);
                Ok((space.free_entries(&f), space.free_entries(&phi)))
            })
            .collect::<Result<_, _>>()?;
        let probe_mm: Vec<[f32; 3]> = probe_nodes
            .iter()
            .map(|&v| space.nodes[v as usize].map(|x| x as f32))
            .collect();
        let mut table = EffectTable {
            mesh_xxh3: organ.fingerprint(),
            origin_mm,
            spacing_mm: s.spacing_mm,
            dims,
            radii_mm: s.radii_mm.clone(),
            valid: vec![false; lattice],
            surface_mm: vec![0.0; lattice],
            starts: vec![0; lattice + 1],
            entry_node: Vec::new(),
            lambda: vec![0.0; lattice * s.radii_mm.len()],
            scale: vec![0.0; lattice * s.radii_mm.len()],
            amp: Vec::new(),
            probe_nodes,
            probe_mm,
            compliance_mm_per_n: Vec::new(),
            face_nodes,
            stores_s: 0.0,
            placements_s: 0.0,
            build_s: 0.0,
            placements: 0,
            checks: Vec::new(),
            tissue_checks: Vec::new(),
            tissue_power: None,
            shard: s.shard.map(|[i, n]| [i as u32, n as u32]),
        };
        // Each node's distance to the surface (to refuse a shallow nodule), and to the
        // palpable surface where the lattice keeps only what can be felt.
        let palpable = organ.palpable_triangles();
        let depths: Vec<(f32, bool)> = (0..lattice)
            .into_par_iter()
            .map(|at| {
                let i = [
                    at % dims[0],
                    (at / dims[0]) % dims[1],
                    at / (dims[0] * dims[1]),
                ];
                let c = table.node_mm(i);
                let hit = closest_point(&organ.mesh.vertices, &organ.boundary, c);
                let felt = s.max_depth_mm.is_none_or(|d| {
                    closest_point(&organ.mesh.vertices, &palpable, c)
                        .is_some_and(|h| h.distance <= d)
                });
                // Signed: negative outside the organ, so that a nodule's depth
                // interpolated over a cell says whether its centre lies inside.
                let distance = hit.map_or(0.0, |h| h.distance as f32);
                let signed = if inside(organ, c) {
                    distance
                } else {
                    -distance
                };
                (signed, felt)
            })
            .collect();
        for (at, &(d, _)) in depths.iter().enumerate() {
            table.surface_mm[at] = d;
        }
        // The blocks with members, dealt to the shards in turn: this shard's, with the
        // sphere each one's centres fill.
        let r_max = *s.radii_mm.last().unwrap_or(&0.0);
        // A nodule is answered only at least MIN_DEPTH_MM under the surface, so its
        // centre the smallest radius deeper still, and its trilinear interpolation reads
        // nodes within a lattice cell's diagonal of it: shallower nodes are never read
        // (a millimetre's margin for the interpolated depth).
        let shallowest = (MIN_DEPTH_MM + s.radii_mm[0] - s.spacing_mm * 3f64.sqrt() - 1.0) as f32;
        let blocks = dims.map(|n| n.div_ceil(s.block));
        let mut dealt = 0usize;
        let mut mine: Vec<(Vec<[usize; 3]>, NoduleRanges)> = Vec::new();
        for bz in 0..blocks[2] {
            for by in 0..blocks[1] {
                for bx in 0..blocks[0] {
                    let lo = [bx, by, bz].map(|b| b * s.block);
                    let hi = [0, 1, 2].map(|d| (lo[d] + s.block).min(dims[d]));
                    let mut members = Vec::new();
                    for k in lo[2]..hi[2] {
                        for j in lo[1]..hi[1] {
                            for i in lo[0]..hi[0] {
                                let (depth, felt) = depths[table.index([i, j, k])];
                                if felt
                                    && depth >= shallowest
                                    && inside(organ, table.node_mm([i, j, k]))
                                {
                                    members.push([i, j, k]);
                                }
                            }
                        }
                    }
                    if members.is_empty() {
                        continue;
                    }
                    dealt += 1;
                    if s.shard.is_some_and(|[i, n]| (dealt - 1) % n != i - 1) {
                        continue;
                    }
                    let mid = [0, 1, 2].map(|d| {
                        let a = table.node_mm(lo)[d];
                        let b = table.node_mm(hi.map(|h| h - 1))[d];
                        0.5 * (a + b)
                    });
                    let reach_mm = members
                        .iter()
                        .map(|&m| norm(sub(table.node_mm(m), mid)))
                        .fold(0.0, f64::max)
                        + 1e-9;
                    let ranges = NoduleRanges {
                        center_mm: mid,
                        reach_mm,
                        radius_mm: (s.radii_mm[0], r_max),
                        ratio: (1.0, FIT_RATIOS[1]),
                    };
                    mine.push((members, ranges));
                }
            }
        }
        // One store of every unknown this shard's nodules can touch, at those rows: the
        // blocks' stores are cut from it.
        let ts = Instant::now();
        let regions: Vec<NoduleRanges> = mine.iter().map(|m| m.1).collect();
        let whole = InteriorResponses::build_over(setup, &regions, false);
        table.stores_s += ts.elapsed().as_secs_f64();
        // Each probe node's load and functional solved (in batches of consecutive probe
        // nodes, as the store's columns are): its nodule-free compliance, and both
        // responses at the store's columns.
        let tp = Instant::now();
        let (compliance, responses) = probe_responses(setup, &loads, &whole);
        // A probe node held by the fixed region (its load or its reading all on fixed
        // unknowns) has no compliance and feels no nodule; any other needs a positive one.
        let held = |p: usize| loads[p].0.is_empty() || loads[p].1.is_empty();
        let bad = |p: usize, c0: f64| !(c0.is_finite() && (c0 > 0.0 || (c0 == 0.0 && held(p))));
        if let Some(p) = (0..compliance.len()).find(|&p| bad(p, compliance[p])) {
            return Err(TableError::ProbeNode {
                node: table.probe_nodes[p],
                at_mm: table.probe_mm[p].map(f64::from),
                why: format!("its compliance is {} mm/N", compliance[p]),
            });
        }
        table.compliance_mm_per_n = compliance;
        table.stores_s += tp.elapsed().as_secs_f64();
        // Per lattice node: its entries, gathered block by block.
        let mut entries: Vec<Entries> = vec![Default::default(); lattice];
        for (members, ranges) in &mine {
            let ts = Instant::now();
            let Some(store) = whole.restrict(*ranges) else {
                return Err(TableError::Settings(
                    "a block's store is not inside the shard's (a bug)".into(),
                ));
            };
            // Each probe node within reach of a member: its responses at the block's
            // columns, shared by every member's placements.
            let reach = ranges.reach_mm + s.probe_reach_mm;
            let at: Vec<usize> = store
                .cols
                .iter()
                .map(|&d| whole.col_of(d).expect("a block's columns are the shard's"))
                .collect();
            let local: Vec<Option<(Vec<f64>, Vec<f64>)>> = responses
                .par_iter()
                .enumerate()
                .map(|(p, (f, phi))| {
                    let near =
                        norm(sub(table.probe_mm[p].map(f64::from), ranges.center_mm)) <= reach;
                    near.then(|| {
                        let gather =
                            |v: &[f32]| at.iter().map(|&c| f64::from(v[c])).collect::<Vec<_>>();
                        (gather(f), gather(phi))
                    })
                })
                .collect();
            table.stores_s += ts.elapsed().as_secs_f64();
            let tp = Instant::now();
            let done: Vec<Option<(usize, Entries, usize)>> = members
                .par_iter()
                .map(|&m| {
                    let placed = table.node_fits(&store, &local, m, s)?;
                    Some((table.index(m), placed.0, placed.1))
                })
                .collect();
            table.placements_s += tp.elapsed().as_secs_f64();
            for (k, e, count) in done.into_iter().flatten() {
                table.valid[k] = true;
                entries[k] = e;
                table.placements += count;
            }
        }
        if dealt == 0 {
            return Err(TableError::Settings(format!(
                "no lattice node lies inside the organ{}: expected a lattice over it",
                s.max_depth_mm
                    .map(|d| format!(" within {d} mm of the palpable surface"))
                    .unwrap_or_default()
            )));
        }
        let radii = s.radii_mm.len();
        for (k, (nodes, lambda, scale, amp)) in entries.into_iter().enumerate() {
            table.starts[k] = table.entry_node.len() as u32;
            if !nodes.is_empty() {
                table.lambda[k * radii..(k + 1) * radii].copy_from_slice(&lambda);
                table.scale[k * radii..(k + 1) * radii].copy_from_slice(&scale);
            }
            table.entry_node.extend(nodes);
            table.amp.extend(amp);
        }
        *table.starts.last_mut().expect("n³ + 1 starts") = table.entry_node.len() as u32;
        table.build_s = t0.elapsed().as_secs_f64();
        Ok(table)
    }

    /// The entries of lattice node `m`: `(A, λ)` per radius at every probe node within
    /// reach, and the placements made; `None` where a nodule there cannot be placed.
    fn node_fits(
        &self,
        store: &InteriorResponses,
        responses: &[Option<(Vec<f64>, Vec<f64>)>],
        m: [usize; 3],
        s: &TableSettings,
    ) -> Option<(Entries, usize)> {
        let c = self.node_mm(m);
        let near: Vec<usize> = (0..self.probe_nodes.len())
            .filter(|&p| norm(sub(self.probe_mm[p].map(f64::from), c)) <= s.probe_reach_mm)
            .collect();
        let pairs: Vec<(&[f64], &[f64])> = near
            .iter()
            .map(|&p| {
                let (f, phi) = responses[p].as_ref()?;
                Some((f.as_slice(), phi.as_slice()))
            })
            .collect::<Option<_>>()?;
        let radii = s.radii_mm.len();
        let (mut lambda, mut scale) = (vec![0.0; radii], vec![0.0; radii]);
        let mut amp = vec![0i8; near.len() * radii];
        let mut count = 0;
        for (ri, &r) in s.radii_mm.iter().enumerate() {
            let mut y = [vec![0.0; near.len()], vec![0.0; near.len()]];
            let cut = store.cut(c, r).ok()?;
            for (b, &beta) in FIT_RATIOS.iter().enumerate() {
                let placed = cut.place(beta).ok()?;
                count += 1;
                for (y, dc) in y[b].iter_mut().zip(placed.corrections(&pairs)) {
                    *y = -dc;
                }
            }
            let fits: Vec<[f64; 2]> = (0..near.len())
                .map(|k| one_pole(y[0][k], y[1][k]))
                .collect();
            let (l, sc, steps) = share_pole(&fits);
            (lambda[ri], scale[ri]) = (l, sc);
            for (k, q) in steps.into_iter().enumerate() {
                amp[k * radii + ri] = q;
            }
        }
        Some((
            (near.iter().map(|&p| p as u32).collect(), lambda, scale, amp),
            count,
        ))
    }

    /// The xxh3 of what two builds of the same table share however they ran: all but
    /// the build's timings and the recorded checks' FE times.
    pub fn payload_xxh3(&self) -> u64 {
        let mut same = self.clone();
        (same.stores_s, same.placements_s, same.build_s) = (0.0, 0.0, 0.0);
        for c in &mut same.checks {
            c.fe_s = 0.0;
        }
        for c in &mut same.tissue_checks {
            c.fe_s = 0.0;
        }
        let bytes =
            bincode::serde::encode_to_vec(&same, bincode::config::standard()).unwrap_or_default();
        xxhash_rust::xxh3::xxh3_64(&bytes)
    }

    /// The whole table from the `n` shards of one build ([`TableSettings::shard`]), in
    /// any order: the same as the build unsharded, but for its timings (the shards'
    /// summed). Refused, naming what differs, unless every shard from 1 to `n` is here
    /// once and all were built with the same settings on the same mesh.
    pub fn merge(mut parts: Vec<EffectTable>) -> Result<EffectTable, TableError> {
        let bad = |why: String| Err(TableError::Merge(why));
        let Some(n) = parts.first().and_then(|p| p.shard).map(|[_, n]| n) else {
            return bad("expected shards of a build (`palpa nodule build --shard I/N`)".into());
        };
        parts.sort_by_key(|p| p.shard.map_or(0, |[i, _]| i));
        let have: Vec<u32> = parts
            .iter()
            .filter_map(|p| p.shard.map(|[i, _]| i))
            .collect();
        let missing: Vec<u32> = (1..=n).filter(|i| !have.contains(i)).collect();
        if parts.iter().any(|p| p.shard.is_none_or(|[_, m]| m != n)) {
            return bad(format!("shards of {n} mixed with other files"));
        }
        if !missing.is_empty() || have.len() != n as usize {
            return bad(format!(
                "expected each of the {n} shards once; have {have:?}, missing {missing:?}"
            ));
        }
        let first = &parts[0];
        let same = |p: &EffectTable| {
            p.mesh_xxh3 == first.mesh_xxh3
                && p.origin_mm == first.origin_mm
                && p.spacing_mm == first.spacing_mm
                && p.dims == first.dims
                && p.radii_mm == first.radii_mm
                && p.surface_mm == first.surface_mm
                && p.probe_nodes == first.probe_nodes
                && p.compliance_mm_per_n == first.compliance_mm_per_n
                && p.face_nodes == first.face_nodes
        };
        if let Some(p) = parts.iter().find(|p| !same(p)) {
            return bad(format!(
                "shard {:?} was built with other settings or on another mesh than shard 1 (expected one build's shards)",
                p.shard
            ));
        }
        let radii = first.radii_mm.len();
        let lattice = first.valid.len();
        let mut out = EffectTable {
            valid: vec![false; lattice],
            starts: vec![0; lattice + 1],
            entry_node: Vec::new(),
            lambda: vec![0.0; lattice * radii],
            scale: vec![0.0; lattice * radii],
            amp: Vec::new(),
            stores_s: parts.iter().map(|p| p.stores_s).sum(),
            placements_s: parts.iter().map(|p| p.placements_s).sum(),
            build_s: parts.iter().map(|p| p.build_s).sum(),
            placements: parts.iter().map(|p| p.placements).sum(),
            checks: Vec::new(),
            tissue_checks: Vec::new(),
            tissue_power: None,
            shard: None,
            ..first.clone()
        };
        for k in 0..lattice {
            out.starts[k] = out.entry_node.len() as u32;
            let owners: Vec<&EffectTable> = parts.iter().filter(|p| p.valid[k]).collect();
            match owners[..] {
                [] => {}
                [p] => {
                    out.valid[k] = true;
                    let q = k * radii..(k + 1) * radii;
                    out.lambda[q.clone()].copy_from_slice(&p.lambda[q.clone()]);
                    out.scale[q.clone()].copy_from_slice(&p.scale[q]);
                    let (a, b) = (p.starts[k] as usize, p.starts[k + 1] as usize);
                    out.entry_node.extend_from_slice(&p.entry_node[a..b]);
                    out.amp.extend_from_slice(&p.amp[a * radii..b * radii]);
                }
                _ => {
                    return bad(format!(
                        "lattice node {k} is in {} shards (expected one build's shards, each of its own blocks)",
                        owners.len()
                    ));
                }
            }
        }
        out.starts[lattice] = out.entry_node.len() as u32;
        Ok(out)
    }

    /// Writes the table (atomically; LZMA-compressed, checksummed).
    pub fn save(&self, path: &std::path::Path) -> Result<(), TableError> {
        crate::framed::write(path, MAGIC, (VERSION, crate::framed::Body::Lzma), self).map_err(|e| {
            TableError::Io {
                path: path.display().to_string(),
                why: e.to_string(),
            }
        })
    }

    /// Reads a table [`Self::save`] wrote, every way it can be wrong named; a shard of
    /// a build is refused (it answers only its own blocks' nodules).
    pub fn load(path: &std::path::Path) -> Result<EffectTable, TableError> {
        Self::whole(Self::load_shard(path)?, path)
    }

    /// As [`Self::load`], a shard of a build too: what [`Self::merge`] reads.
    pub fn load_shard(path: &std::path::Path) -> Result<EffectTable, TableError> {
        let bytes = std::fs::read(path).map_err(|e| TableError::Io {
            path: path.display().to_string(),
            why: e.to_string(),
        })?;
        Self::read_any(&bytes, path)
    }

    /// As [`Self::load`], from the file's bytes (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &std::path::Path) -> Result<EffectTable, TableError> {
        Self::whole(Self::read_any(bytes, path)?, path)
    }

    /// `table`, unless it is a shard of a build.
    fn whole(table: EffectTable, path: &std::path::Path) -> Result<EffectTable, TableError> {
        match table.shard {
            Some([i, n]) => Err(TableError::Shard {
                path: path.display().to_string(),
                i,
                n,
            }),
            None => Ok(table),
        }
    }

    fn read_any(bytes: &[u8], path: &std::path::Path) -> Result<EffectTable, TableError> {
        use crate::framed::{Body, FramedError};
        let name = path.display().to_string();
        let table: EffectTable = crate::framed::read(bytes, MAGIC, &[(VERSION, Body::Lzma)])
            .map_err(|e| match e {
                FramedError::Foreign => TableError::Foreign { path: name.clone() },
                FramedError::Version(found) => TableError::Version {
                    path: name.clone(),
                    found,
                },
                FramedError::Corrupt(why) => TableError::Corrupt {
                    path: name.clone(),
                    why,
                },
            })?;
        table
            .check()
            .map_err(|why| TableError::Corrupt { path: name, why })?;
        Ok(table)
    }

    /// The table's arrays agree with each other (what a file must hold before it is
    /// read from): the reason where they do not.
    fn check(&self) -> Result<(), String> {
        if let Some(p) = &self.tissue_power {
            p.check()?;
        }
        let lattice: usize = self.dims.iter().product();
        let entries = self.entry_node.len();
        let probes = self.probe_nodes.len();
        let radii = self.radii_mm.len();
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(self.spacing_mm.is_finite() && self.spacing_mm > 0.0 && finite(&self.origin_mm)) {
            return Err(format!(
                "lattice spacing {} mm from {:?}: expected a positive spacing and a finite origin",
                self.spacing_mm, self.origin_mm
            ));
        }
        if self.dims.contains(&0) || lattice > 1 << 24 {
            return Err(format!(
                "lattice of {:?} nodes: expected 1 to 2²⁴ in all",
                self.dims
            ));
        }
        if radii < 2 || !self.radii_mm.windows(2).all(|w| w[0] < w[1]) || self.radii_mm[0] <= 0.0 {
            return Err(format!(
                "radii {:?}: expected two or more, ascending, positive",
                self.radii_mm
            ));
        }
        if self.valid.len() != lattice
            || self.surface_mm.len() != lattice
            || self.starts.len() != lattice + 1
        {
            return Err(format!(
                "{} validity flags and {} entry starts for {lattice} lattice nodes",
                self.valid.len(),
                self.starts.len()
            ));
        }
        let ascending = (0..lattice).all(|k| {
            let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
            s > e || e > entries || self.entry_node[s..e].windows(2).all(|w| w[0] < w[1])
        });
        if !ascending {
            return Err("a lattice node's entries not in ascending probe-node order".into());
        }
        if self.starts.windows(2).any(|w| w[0] > w[1]) || self.starts[lattice] as usize != entries {
            return Err(format!(
                "entry starts not ascending to the {entries} entries"
            ));
        }
        if self.amp.len() != entries * radii
            || self.lambda.len() != lattice * radii
            || self.scale.len() != lattice * radii
            || self.entry_node.iter().any(|&p| p as usize >= probes)
        {
            return Err(format!(
                "{} steps for {entries} entries of {radii} radii, {} poles and {} scales for {lattice} lattice nodes, or an entry's probe node past the {probes}",
                self.amp.len(),
                self.lambda.len(),
                self.scale.len()
            ));
        }
        if self.probe_mm.len() != probes || self.compliance_mm_per_n.len() != probes {
            return Err(format!(
                "{probes} probe nodes but {} positions and {} compliances",
                self.probe_mm.len(),
                self.compliance_mm_per_n.len()
            ));
        }
        if !self
            .compliance_mm_per_n
            .iter()
            .all(|c| c.is_finite() && *c >= 0.0)
        {
            return Err(
                "a probe node's compliance is not a non-negative number (0: held by the fixed region)"
                    .into(),
            );
        }
        if self
            .lambda
            .iter()
            .chain(&self.scale)
            .any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err("a pole or a scale is not a non-negative number".into());
        }
        if self
            .face_nodes
            .iter()
            .flatten()
            .flatten()
            .any(|&p| p as usize >= probes)
        {
            return Err(format!("a face's node past the {probes} probe nodes"));
        }
        Ok(())
    }

    /// Bytes the table's entries take as stored (node ids, a byte an entry and radius,
    /// the lattice nodes' poles and scales), before compression.
    pub fn bytes(&self) -> usize {
        self.entry_node.len() * 4
            + self.amp.len()
            + self.valid.iter().filter(|&&v| v).count() * self.radii_mm.len() * 8
    }

    /// How the tissue whose payload checksum is `tissue_xxh3` amplifies `nodule`'s
    /// effect at every stored vertex and depth, where the table holds that tissue's
    /// power (`palpa nodule tissue`); `None` otherwise (the linear effect as it is).
    pub fn amplification(
        &self,
        nodule: &Nodule,
        tissue_xxh3: u64,
    ) -> Option<super::amplification::Placed> {
        let power = self.tissue_power.as_ref()?;
        (power.tissue_xxh3 == tissue_xxh3).then(|| power.place(nodule))
    }

    /// The effect of `nodule` at every probe node: checked against the table's ranges,
    /// then trilinear over its centre's lattice cell and quadratic over the three radii
    /// about its own; past the band, carried from the band's deepest centre on the way
    /// to the palpable surface.
    pub fn place(&self, nodule: &Nodule) -> Result<NoduleEffect, TableError> {
        self.timed(nodule, true)
    }

    /// As [`Self::place`], but only nodules whose lattice cell lies in the band (refused
    /// as [`TableError::CentreOutside`] otherwise).
    pub fn place_in_band(&self, nodule: &Nodule) -> Result<NoduleEffect, TableError> {
        self.timed(nodule, false)
    }

    fn timed(&self, nodule: &Nodule, deep: bool) -> Result<NoduleEffect, TableError> {
        let t0 = Instant::now();
        let at_node = self.answer(nodule, deep)?;
        Ok(NoduleEffect {
            nodule: *nodule,
            at_node,
            place_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// The effect at every probe node; `deep`: a cell with corners outside the band
    /// answered from the band's deepest point towards the palpable surface
    /// ([`Self::answer_deep`]), refused otherwise.
    fn answer(&self, nodule: &Nodule, deep: bool) -> Result<Vec<f64>, TableError> {
        let [lo, hi] = self.radius_range_mm();
        if !(nodule.radius_mm >= lo && nodule.radius_mm <= hi) {
            return Err(TableError::Radius {
                radius_mm: nodule.radius_mm,
                lo,
                hi,
            });
        }
        if !(nodule.ratio >= 1.0 && nodule.ratio <= MAX_RATIO) {
            return Err(TableError::Ratio {
                ratio: nodule.ratio,
                lo: 1.0,
                hi: MAX_RATIO,
            });
        }
        let outside = || TableError::CentreOutside {
            center_mm: nodule.center_mm,
            lo_mm: self.origin_mm,
            hi_mm: self.node_mm(self.dims.map(|d| d - 1)),
        };
        // The lattice cell and the fractions within it.
        let mut base = [0usize; 3];
        let mut frac = [0.0; 3];
        for d in 0..3 {
            let g = (nodule.center_mm[d] - self.origin_mm[d]) / self.spacing_mm;
            let last = (self.dims[d] - 1) as f64;
            if !(g >= 0.0 && g <= last) {
                return Err(outside());
            }
            let b = (g.floor() as usize).min(self.dims[d].saturating_sub(2));
            base[d] = b;
            frac[d] = g - b as f64;
        }
        let by_radius = radius_weights(&self.radii_mm, nodule.radius_mm);
        let radii = self.radii_mm.len();
        // The cell's corners with their weights (none of weight 0).
        let corners: Vec<(usize, f64, [f64; 3])> = (0..8)
            .filter_map(|corner| {
                let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
                let w: f64 = (0..3)
                    .map(|d| if o[d] == 1 { frac[d] } else { 1.0 - frac[d] })
                    .product();
                let i = [0, 1, 2].map(|d| (base[d] + o[d]).min(self.dims[d] - 1));
                (w != 0.0).then(|| (self.index(i), w, self.node_mm(i)))
            })
            .collect();
        // Too shallow first: a build leaves out the nodes only such nodules would read.
        let surface_mm: f64 = corners
            .iter()
            .map(|&(k, w, _)| w * f64::from(self.surface_mm[k]))
            .sum();
        if surface_mm <= 0.0 {
            return Err(TableError::OutsideOrgan {
                center_mm: nodule.center_mm,
            });
        }
        let depth_mm = surface_mm - nodule.radius_mm;
        if depth_mm < MIN_DEPTH_MM {
            return Err(TableError::TooShallow { depth_mm });
        }
        if corners.iter().any(|&(k, _, _)| !self.valid[k]) {
            return if deep {
                self.answer_deep(nodule).ok_or_else(outside)
            } else {
                Err(outside())
            };
        }
        let mut minus_dc = vec![0.0; self.probe_nodes.len()];
        let mut reached = vec![false; self.probe_nodes.len()];
        for &(k, w, at) in &corners {
            let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
            // Each radius's shared pole at this ratio, times its scale and weight.
            let per_step: Vec<(usize, f64)> = by_radius
                .iter()
                .map(|&(i, wr)| (i, w * wr * self.unit(k, i, nodule.ratio)))
                .collect();
            reached.fill(false);
            for entry in s..e {
                let steps = &self.amp[entry * radii..(entry + 1) * radii];
                let v: f64 = per_step.iter().map(|&(i, f)| f * f64::from(steps[i])).sum();
                minus_dc[self.entry_node[entry] as usize] += v;
                reached[self.entry_node[entry] as usize] = true;
            }
            let read = Reading {
                by_radius: &by_radius,
                weight: w,
                ratio: nodule.ratio,
            };
            self.add_tail(at, s..e, &per_step, &read, &reached, &mut minus_dc);
        }
        Ok(minus_dc
            .iter()
            .zip(&self.compliance_mm_per_n)
            .map(|(&y, &c0)| if c0 > 0.0 { c0 / (c0 - y) - 1.0 } else { 0.0 })
            .collect())
    }

    /// A nodule inside the organ whose lattice cell reaches past the band (deeper than
    /// the band, or beside a surface no probe presses): the same nodule moved towards
    /// its nearest probe node, half a cell at a time, to the first centre the band
    /// answers, its change of the compliance carried back to the true centre as the far
    /// field's `ρ^{−p}` ([`TOWARD_POWER`]), `ρ` from the centre to each probe node
    /// (docs/lab/nodule-measurements.md §14). `None` where no such centre is found.
    fn answer_deep(&self, nodule: &Nodule) -> Option<Vec<f64>> {
        let c = nodule.center_mm;
        let distance = |p: &[f32; 3]| norm(sub(p.map(f64::from), c));
        let nearest = self
            .probe_mm
            .iter()
            .zip(&self.compliance_mm_per_n)
            .filter(|&(_, &c0)| c0 > 0.0)
            .map(|(p, _)| p)
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))?
            .map(f64::from);
        let gap = norm(sub(c, nearest));
        let step = 0.5 * self.spacing_mm;
        let mut t = gap - step;
        while t > 0.0 {
            let moved = Nodule {
                center_mm: [0, 1, 2].map(|d| nearest[d] + (c[d] - nearest[d]) * t / gap),
                ..*nodule
            };
            match self.answer(&moved, false) {
                Ok(up) => {
                    let at = moved.center_mm;
                    return Some(
                        up.iter()
                            .zip(&self.compliance_mm_per_n)
                            .zip(&self.probe_mm)
                            .map(|((&e, &c0), p)| {
                                if c0 <= 0.0 {
                                    return 0.0;
                                }
                                let p = p.map(f64::from);
                                let fall = (norm(sub(p, at)) / norm(sub(p, c))).powf(TOWARD_POWER);
                                let y = c0 * e / (1.0 + e) * fall;
                                c0 / (c0 - y) - 1.0
                            })
                            .collect(),
                    );
                }
                Err(TableError::CentreOutside { .. }) => t -= step,
                Err(_) => return None,
            }
        }
        None
    }
}

impl EffectTable {
    /// Adds to `minus_dc` the change beyond the reach of the lattice node at `at_mm`
    /// (entries `entries`, read at this nodule through `per_step`), at every probe node
    /// it does not reach (`reached` false) and the fixed region does not hold: the far
    /// field `τ ρ^{−p}` of the module's docs.
    fn add_tail(
        &self,
        at_mm: [f64; 3],
        entries: std::ops::Range<usize>,
        per_step: &[(usize, f64)],
        read: &Reading,
        reached: &[bool],
        minus_dc: &mut [f64],
    ) {
        let radii = self.radii_mm.len();
        let rho = |n: u32| norm(sub(self.probe_mm[n as usize].map(f64::from), at_mm));
        let reach = entries
            .clone()
            .map(|e| rho(self.entry_node[e]))
            .fold(0.0, f64::max);
        if reach <= 0.0 {
            return;
        }
        // Each outer entry's `−δc ρ^p` at this nodule, and where it is.
        let ring: Vec<([f64; 3], f64)> = entries
            .filter_map(|e| {
                let n = self.entry_node[e];
                let r = rho(n);
                (r >= TAIL_RING * reach).then(|| {
                    let v: f64 = per_step
                        .iter()
                        .map(|&(i, f)| f * f64::from(self.amp[e * radii + i]))
                        .sum();
                    (
                        self.probe_mm[n as usize].map(f64::from),
                        v * r.powf(TAIL_POWER),
                    )
                })
            })
            .collect();
        for (n, y) in minus_dc.iter_mut().enumerate() {
            if reached[n] || self.compliance_mm_per_n[n] <= 0.0 {
                continue;
            }
            if let Some(v) = self.toward(at_mm, n, TOWARD_REACH * reach, read) {
                *y += v;
                continue;
            }
            if ring.is_empty() {
                continue;
            }
            let p = self.probe_mm[n].map(f64::from);
            let (mut num, mut den) = (0.0, 0.0);
            for (q, v) in &ring {
                let d2 = norm(sub(p, *q)).powi(2) + TAIL_NEAR_MM * TAIL_NEAR_MM;
                let w = 1.0 / (d2 * d2);
                num += w * v;
                den += w;
            }
            *y += num / den * rho(n as u32).powf(-TAIL_POWER);
        }
    }

    /// Lattice node `k`'s shared pole for radius `r` at `ratio`, times its scale: what
    /// one step of an entry is worth.
    fn unit(&self, k: usize, r: usize, ratio: f64) -> f64 {
        let q = k * self.radii_mm.len() + r;
        pole(
            [f64::from(self.scale[q]) / 127.0, f64::from(self.lambda[q])],
            ratio,
        )
    }

    /// The change at probe node `n` beyond the reach of the lattice node at `at_mm`,
    /// read where the probe is within reach: at the valid lattice node nearest the point
    /// `near_mm` from the probe on the way to `at_mm`, from its own entry for `n`, carried
    /// back to `at_mm` as `ρ^{−p}`. `None` where that node is not valid or has no entry
    /// for `n`.
    fn toward(&self, at_mm: [f64; 3], n: usize, near_mm: f64, read: &Reading) -> Option<f64> {
        let p = self.probe_mm[n].map(f64::from);
        let rho = norm(sub(p, at_mm));
        if rho <= near_mm {
            return None;
        }
        let i = [0, 1, 2].map(|d| {
            let q = p[d] + (at_mm[d] - p[d]) * near_mm / rho;
            let g = ((q - self.origin_mm[d]) / self.spacing_mm).round();
            g.clamp(0.0, (self.dims[d] - 1) as f64) as usize
        });
        let k = self.index(i);
        if !self.valid[k] {
            return None;
        }
        let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
        let entry = s + self.entry_node[s..e].binary_search(&(n as u32)).ok()?;
        let radii = self.radii_mm.len();
        let v: f64 = read
            .by_radius
            .iter()
            .map(|&(r, wr)| {
                read.weight
                    * wr
                    * self.unit(k, r, read.ratio)
                    * f64::from(self.amp[entry * radii + r])
            })
            .sum();
        Some(v * (norm(sub(p, self.node_mm(i))) / rho).powf(TOWARD_POWER))
    }

    /// The boundary face whose corners lie at `corners_mm` (within a micrometre, in
    /// the same order): how a scene that numbers its faces otherwise finds the table's.
    pub fn face_at(&self, corners_mm: [[f64; 3]; 3]) -> Option<usize> {
        let close = |p: u32, q: [f64; 3]| {
            let a = self.probe_mm[p as usize];
            (0..3).all(|d| (f64::from(a[d]) - q[d]).abs() < 1e-3)
        };
        self.face_nodes
            .iter()
            .position(|six| six.is_some_and(|six| (0..3).all(|k| close(six[k], corners_mm[k]))))
    }
}

impl NoduleEffect {
    /// `F_with/F_without − 1` at the point `bary` of boundary face `face` (a palpable
    /// one), by the quadratic interpolation of its six nodes, at least 0 (a stiffer
    /// inclusion never makes the tissue more compliant; the quadratic weights can
    /// undershoot between nodes); `None` off the table's faces.
    pub fn at(&self, table: &EffectTable, face: usize, bary: [f64; 3]) -> Option<f64> {
        let six = table.face_nodes.get(face).copied().flatten()?;
        let l = bary;
        let corner = |k: usize| l[k] * (2.0 * l[k] - 1.0);
        let mut w = [corner(0), corner(1), corner(2), 0.0, 0.0, 0.0];
        for (e, (i, j)) in TRI_EDGES.iter().enumerate() {
            w[3 + e] = 4.0 * l[*i] * l[*j];
        }
        // A node the fixed region holds has no effect of its own (no press there to
        // change): the face's free nodes stand in for it, their mean, as the effect
        // near it is their limit.
        let held = |n: u32| table.compliance_mm_per_n[n as usize] <= 0.0;
        let (sum, count) = six
            .iter()
            .filter(|&&n| !held(n))
            .fold((0.0, 0usize), |(s, c), &n| {
                (s + self.at_node[n as usize], c + 1)
            });
        let stand_in = sum / count.max(1) as f64;
        Some(
            six.iter()
                .zip(w)
                .map(|(&n, w)| {
                    w * if held(n) {
                        stand_in
                    } else {
                        self.at_node[n as usize]
                    }
                })
                .sum::<f64>()
                .max(0.0),
        )
    }
}

/// How a lattice node's entries are read for one nodule: the radii's weights, the
/// corner's trilinear weight, the ratio.
struct Reading<'a> {
    by_radius: &'a [(usize, f64)],
    weight: f64,
    ratio: f64,
}

/// The weights of the tabulated radii at radius `r` (within their range): Lagrange's
/// quadratic through the three radii about `r` where three or more are tabulated
/// (docs/lab/nodule-measurements.md §10: the effect's worst error at held-out pairs
/// 10.8 → 8.0 %), linear between two otherwise.
fn radius_weights(radii: &[f64], r: f64) -> Vec<(usize, f64)> {
    let i = radii
        .windows(2)
        .position(|w| r <= w[1])
        .unwrap_or(radii.len().saturating_sub(2));
    if radii.len() < 3 {
        let f = (r - radii[i]) / (radii[i + 1] - radii[i]);
        return vec![(i, 1.0 - f), (i + 1, f)];
    }
    // The three radii about `r`: its interval and the nearer neighbour beyond.
    let i = i.min(radii.len() - 3);
    let x = [radii[i], radii[i + 1], radii[i + 2]];
    (0..3)
        .map(|a| {
            let w: f64 = (0..3)
                .filter(|&b| b != a)
                .map(|b| (r - x[b]) / (x[a] - x[b]))
                .product();
            (i + a, w)
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A table of one lattice node and no entries, for tests of what it records.
    pub(crate) fn tiny() -> EffectTable {
        EffectTable {
            mesh_xxh3: 0,
            origin_mm: [0.0; 3],
            spacing_mm: 3.0,
            dims: [1, 1, 1],
            radii_mm: vec![8.0, 12.0],
            valid: vec![true],
            surface_mm: vec![20.0],
            starts: vec![0, 0],
            entry_node: Vec::new(),
            lambda: vec![0.0; 2],
            scale: vec![0.0; 2],
            amp: Vec::new(),
            probe_nodes: Vec::new(),
            probe_mm: Vec::new(),
            compliance_mm_per_n: Vec::new(),
            face_nodes: Vec::new(),
            stores_s: 0.0,
            placements_s: 0.0,
            build_s: 0.0,
            placements: 0,
            checks: Vec::new(),
            tissue_checks: Vec::new(),
            tissue_power: None,
            shard: None,
        }
    }

    /// The one-pole fit through two ratios reproduces a one-pole function everywhere
    /// between them, and a negligible change is none.
    #[test]
    fn one_pole_fit_is_exact_on_one_pole_functions() {
        for (a, lambda) in [(0.3, 0.5), (0.01, 2.0), (1.0, 0.05)] {
            let f = |beta: f64| a * (beta - 1.0) / (1.0 + (beta - 1.0) * lambda);
            let fit = one_pole(f(2.0), f(10.0));
            for beta in [1.0, 1.5, 4.4, 7.0, 10.0] {
                let e = (pole(fit, beta) - f(beta)).abs();
                assert!(e <= 1e-6 * f(10.0), "{a} {lambda} {beta}: {e}");
            }
        }
        assert_eq!(one_pole(0.0, 1e-3), [0.0, 0.0]);
    }

    /// Entries that share one pole keep it and their own `A` to the step's precision;
    /// entries with poles of their own are matched at the middle ratio.
    #[test]
    fn a_shared_pole_keeps_one_pole_entries_and_matches_the_middle_ratio() {
        let mut rng = crate::rng::Rng::seed(11);
        let fits: Vec<[f64; 2]> = (0..50).map(|_| [rng.range(0.0, 0.4), 0.3]).collect();
        let (lambda, scale, steps) = share_pole(&fits);
        assert!((f64::from(lambda) - 0.3).abs() < 1e-6, "{lambda}");
        for (f, &q) in fits.iter().zip(&steps) {
            let a = f64::from(scale) * f64::from(q) / 127.0;
            assert!(
                (a - f[0]).abs() <= 0.5 / 127.0 * f64::from(scale) + 1e-7,
                "{f:?} {a}"
            );
        }
        let fits: Vec<[f64; 2]> = (0..50)
            .map(|_| [rng.range(0.01, 0.4), rng.range(0.1, 0.5)])
            .collect();
        let (lambda, scale, steps) = share_pole(&fits);
        assert!((0.1..=0.5).contains(&lambda), "{lambda}");
        for (f, &q) in fits.iter().zip(&steps) {
            let shared = [f64::from(scale) * f64::from(q) / 127.0, f64::from(lambda)];
            let (own, got) = (pole(*f, MATCH_RATIO), pole(shared, MATCH_RATIO));
            assert!(
                (own - got).abs()
                    <= 0.5 / 127.0 * pole([f64::from(scale), f64::from(lambda)], MATCH_RATIO)
                        + 1e-7,
                "{f:?}: {own} against {got}"
            );
        }
        assert_eq!(share_pole(&[[0.0, 0.0]; 3]), (0.0, 0.0, vec![0, 0, 0]));
    }

    /// The radius's weights: one at a tabulated radius, a partition of unity between,
    /// exact on quadratics where three radii are tabulated and on lines for two.
    #[test]
    fn radius_weights_interpolate_quadratics() {
        let radii = [8.0, 10.0, 12.0, 15.0];
        let q = |r: f64| 0.3 - 0.02 * r + 0.004 * r * r;
        let mut rng = crate::rng::Rng::seed(5);
        for _ in 0..200 {
            let r = rng.range(8.0, 15.0);
            let w = radius_weights(&radii, r);
            assert_eq!(w.len(), 3);
            let sum: f64 = w.iter().map(|x| x.1).sum();
            assert!((sum - 1.0).abs() < 1e-12, "{r}: {sum}");
            let v: f64 = w.iter().map(|&(i, x)| x * q(radii[i])).sum();
            assert!((v - q(r)).abs() < 1e-12, "{r}: {v} against {}", q(r));
            // The three radii about r: r lies between the first and the last.
            assert!(radii[w[0].0] <= r && r <= radii[w[2].0], "{r}: {w:?}");
        }
        for (k, &r) in radii.iter().enumerate() {
            let w = radius_weights(&radii, r);
            for &(i, x) in &w {
                assert!(
                    (x - f64::from(u8::from(i == k))).abs() < 1e-12,
                    "{r}: {w:?}"
                );
            }
        }
        let w = radius_weights(&[8.0, 12.0], 9.0);
        assert_eq!(w, vec![(0, 0.75), (1, 0.25)]);
    }
}
