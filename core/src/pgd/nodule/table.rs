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
//! `(A, λ)` are kept at the nodes of a lattice of centres (spacing `h`), at a few radii,
//! and at the P2 nodes of the palpable surface within [`TableSettings::probe_reach_mm`] of
//! each centre; between lattice nodes the table is trilinear in the centre and quadratic
//! in the radius (through the three tabulated radii about it), and over a boundary triangle the effect is interpolated quadratically from
//! its six nodes. The force of a depth-controlled press changes by the factor
//! `c₀/(c₀+δc)`, `c₀` the nodule-free compliance at the node.
//!
//! **Off-line** ([`EffectTable::build`]): the lattice is cut into blocks; one store of
//! interior responses per block ([`super::InteriorResponses`]) places every node's
//! nodules exactly. A lattice node only has to lie inside the organ: a nodule there may
//! reach past the surface (its cells are clipped as the FE clips them), which is what
//! lets a nodule at the 2 mm limit be interpolated from nodes on both sides.
//! **On-line** ([`EffectTable::place`]): the effect at every probe node for one nodule
//! (a few thousand products), then [`NoduleEffect::at`] per probe point.

use std::collections::HashMap;
use std::time::Instant;

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

/// A lattice node's entries: each probe node within reach with `(A, λ)` per radius.
type Entries = Vec<(u32, Vec<[f32; 2]>)>;

/// The two ratios each lattice node's nodules are placed at, which fix the one-pole
/// form's `A` and `λ`.
pub const FIT_RATIOS: [f64; 2] = [2.0, 10.0];

/// The largest ratio a table answers: the one-pole form carried past the fit's ratios
/// towards its limit `−A/λ` (a rigid inclusion), measured against the full FE at ratios
/// 10–100 (docs/lab/nodule-measurements.md §9).
pub const MAX_RATIO: f64 = 100.0;

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
        "{path}: nodule table format version {found}, this palpa reads version {VERSION}: build it again with `palpa nodule build` (and `palpa nodule check --record`)"
    )]
    Version { path: String, found: u32 },
    #[error("{path}: {why}")]
    Corrupt { path: String, why: String },
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
    pub half_width_mm: f64,
    /// Lattice spacing `h` (mm).
    pub spacing_mm: f64,
    /// The radii tabulated, ascending: the table answers radii between the first and the
    /// last.
    pub radii_mm: Vec<f64>,
    /// Probe nodes farther than this from a lattice node get no entry there (the effect
    /// is taken as none).
    pub probe_reach_mm: f64,
    /// Lattice nodes a side of one store's block.
    pub block: usize,
}

/// The file's magic bytes and its one format version.
pub const MAGIC: &[u8; 8] = b"PALPANOD";
pub const VERSION: u32 = 3;

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
    /// Per lattice node: its distance to the organ's surface (mm), interpolated to a
    /// nodule's centre to refuse one within [`MIN_DEPTH_MM`] of the surface.
    pub surface_mm: Vec<f32>,
    /// Entries of lattice node `k`: `starts[k]..starts[k + 1]`.
    pub starts: Vec<u32>,
    /// Each entry's probe node (index into `probe_nodes`).
    pub entry_node: Vec<u32>,
    /// Each entry's `(A, λ)` per radius: `entry * radii + r`, at half precision (kept
    /// as `f32` here, stored as `f16`: relative 5e-4, far below the interpolation's
    /// percent).
    #[serde(with = "half_pairs")]
    pub fit: Vec<[f32; 2]>,
    /// The probe nodes: space nodes of the palpable surface's P2 faces, their rest
    /// positions and nodule-free compliance (mm/N).
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
}

/// One held-out pair of a recorded check (`super::heldout`), as measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckedPair {
    pub nodule: [f64; 5],
    /// The probe point (mm, on the palpable surface).
    pub at_mm: [f64; 3],
    pub effect_fe: f64,
    pub effect_table: f64,
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

/// One nodule's effect at every probe node: what a probe reads.
#[derive(Debug, Clone)]
pub struct NoduleEffect {
    pub nodule: Nodule,
    /// `F_with/F_without − 1` at each probe node.
    pub at_node: Vec<f64>,
    pub place_s: f64,
}

/// `(A, λ)` pairs stored as half-precision bits.
mod half_pairs {
    use half::f16;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &[[f32; 2]], s: S) -> Result<S::Ok, S::Error> {
        let bits: Vec<[u16; 2]> = v
            .iter()
            .map(|p| p.map(|x| f16::from_f32(x).to_bits()))
            .collect();
        bits.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f32; 2]>, D::Error> {
        let bits = Vec::<[u16; 2]>::deserialize(d)?;
        Ok(bits
            .into_iter()
            .map(|p| p.map(|b| f16::from_bits(b).to_f32()))
            .collect())
    }
}

/// A value as half precision keeps it.
fn to_half(x: f32) -> f32 {
    half::f16::from_f32(x).to_f32()
}

/// The largest `|λ|` kept: `A` and `λ` stay within half precision's range.
const LAMBDA_MAX: f64 = 1e3;

/// `(A, λ)` through `y₁ = −δc(β = 2)` and `y₂ = −δc(β = 10)`: `1/y` is linear in
/// `1/(β−1)` with slope `1/A` and intercept `λ/A`. Negligible changes (below 1e-12 mm/N)
/// give `(0, 0)`.
fn one_pole(y1: f64, y2: f64) -> [f32; 2] {
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
        return [(y2 * (1.0 + b * l) / b) as f32, l as f32];
    }
    [a as f32, lambda as f32]
}

/// `−δc` of the one-pole form at ratio `beta`.
#[inline]
fn pole(fit: [f32; 2], beta: f64) -> f64 {
    let b = beta - 1.0;
    f64::from(fit[0]) * b / (1.0 + b * f64::from(fit[1]))
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
            fit: Vec::new(),
            checks: Vec::new(),
            ..self.clone()
        };
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let n = self.index([i * step, j * step, k * step]);
                    out.valid.push(self.valid[n]);
                    out.surface_mm.push(self.surface_mm[n]);
                    for e in self.starts[n] as usize..self.starts[n + 1] as usize {
                        out.entry_node.push(self.entry_node[e]);
                        out.fit.extend(radii.iter().map(|&q| self.fit[e * r + q]));
                    }
                    out.starts.push(out.entry_node.len() as u32);
                }
            }
        }
        Some(out)
    }

    /// The radii answered: the first and last tabulated (mm).
    pub fn radius_range_mm(&self) -> [f64; 2] {
        [
            self.radii_mm.first().copied().unwrap_or(0.0),
            self.radii_mm.last().copied().unwrap_or(0.0),
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
            && s.half_width_mm.is_finite()
            && s.half_width_mm >= 0.0
            && s.radii_mm.len() >= 2
            && s.radii_mm.windows(2).all(|w| w[0] < w[1])
            && s.radii_mm[0] > 0.0
            && s.probe_reach_mm > 0.0
            && s.block >= 1;
        if !ok {
            return Err(TableError::Settings(format!(
                "{s:?}: expected a positive spacing, a non-negative half width, two or more \
                 ascending positive radii, a positive probe reach and blocks of one node or more"
            )));
        }
        let space = &setup.space;
        let half = (s.half_width_mm / s.spacing_mm).floor() as usize;
        let n = 2 * half + 1;
        let dims = [n; 3];
        let origin_mm = [0, 1, 2].map(|d| s.centre_mm[d] - s.spacing_mm * half as f64);
        // The probe nodes: every node of a palpable face within reach of the lattice.
        let reach = s.probe_reach_mm + s.half_width_mm * 3f64.sqrt();
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
        // Each probe node's load, functional and nodule-free compliance.
        let probed: Vec<(Load, f64)> = probe_nodes
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
                let u = setup.problem.solve(space, &f);
                let c0: f64 = phi.iter().zip(&u).map(|(a, b)| a * b).sum();
                if !(c0.is_finite() && c0 > 0.0) {
                    return Err(fail(format!("its compliance is {c0} mm/N")));
                }
                Ok(((space.free_entries(&f), space.free_entries(&phi)), c0))
            })
            .collect::<Result<_, _>>()?;
        let (loads, compliance): (Vec<Load>, Vec<f64>) = probed.into_iter().unzip();
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
            valid: vec![false; n * n * n],
            surface_mm: vec![0.0; n * n * n],
            starts: vec![0; n * n * n + 1],
            entry_node: Vec::new(),
            fit: Vec::new(),
            probe_nodes,
            probe_mm,
            compliance_mm_per_n: compliance,
            face_nodes,
            stores_s: 0.0,
            placements_s: 0.0,
            build_s: 0.0,
            placements: 0,
            checks: Vec::new(),
        };
        // Per lattice node: its entries, gathered block by block.
        let mut entries: Vec<Entries> = vec![Vec::new(); n * n * n];
        let r_max = *s.radii_mm.last().unwrap_or(&0.0);
        let blocks = n.div_ceil(s.block);
        for bz in 0..blocks {
            for by in 0..blocks {
                for bx in 0..blocks {
                    let lo = [bx, by, bz].map(|b| b * s.block);
                    let hi = lo.map(|l| (l + s.block).min(n));
                    let mut members = Vec::new();
                    for k in lo[2]..hi[2] {
                        for j in lo[1]..hi[1] {
                            for i in lo[0]..hi[0] {
                                if inside(organ, table.node_mm([i, j, k])) {
                                    members.push([i, j, k]);
                                }
                            }
                        }
                    }
                    if members.is_empty() {
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
                    let ts = Instant::now();
                    let store = InteriorResponses::build(
                        setup,
                        NoduleRanges {
                            center_mm: mid,
                            reach_mm,
                            radius_mm: (s.radii_mm[0], r_max),
                            ratio: (1.0, FIT_RATIOS[1]),
                        },
                    );
                    table.stores_s += ts.elapsed().as_secs_f64();
                    let tp = Instant::now();
                    let done: Vec<Option<(usize, Entries, usize)>> = members
                        .par_iter()
                        .map(|&m| {
                            let placed = table.node_fits(&store, &loads, m, s)?;
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
            }
        }
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let c = table.node_mm([i, j, k]);
                    let hit = closest_point(&organ.mesh.vertices, &organ.boundary, c);
                    let at = table.index([i, j, k]);
                    table.surface_mm[at] = hit.map_or(0.0, |h| h.distance as f32);
                }
            }
        }
        for (k, e) in entries.into_iter().enumerate() {
            table.starts[k] = table.entry_node.len() as u32;
            for (p, f) in e {
                table.entry_node.push(p);
                table.fit.extend(f);
            }
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
        loads: &[Load],
        m: [usize; 3],
        s: &TableSettings,
    ) -> Option<(Entries, usize)> {
        let c = self.node_mm(m);
        let near: Vec<usize> = (0..self.probe_nodes.len())
            .filter(|&p| norm(sub(self.probe_mm[p].map(f64::from), c)) <= s.probe_reach_mm)
            .collect();
        let mut fits = vec![Vec::with_capacity(s.radii_mm.len()); near.len()];
        let mut count = 0;
        for &r in &s.radii_mm {
            let mut y = [vec![0.0; near.len()], vec![0.0; near.len()]];
            for (b, &beta) in FIT_RATIOS.iter().enumerate() {
                let nodule = Nodule {
                    center_mm: c,
                    radius_mm: r,
                    ratio: beta,
                };
                let placed = store.place(&nodule).ok()?;
                count += 1;
                for (k, &p) in near.iter().enumerate() {
                    let (f, phi) = &loads[p];
                    y[b][k] = -placed.correction(store, f, phi);
                }
            }
            for (k, fit) in fits.iter_mut().enumerate() {
                fit.push(one_pole(y[0][k], y[1][k]).map(to_half));
            }
        }
        Some((
            near.iter().zip(fits).map(|(&p, f)| (p as u32, f)).collect(),
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
        let bytes =
            bincode::serde::encode_to_vec(&same, bincode::config::standard()).unwrap_or_default();
        xxhash_rust::xxh3::xxh3_64(&bytes)
    }

    /// Writes the table (atomically; deflated, checksummed).
    pub fn save(&self, path: &std::path::Path) -> Result<(), TableError> {
        crate::framed::write(path, MAGIC, (VERSION, crate::framed::Body::Deflated), self).map_err(
            |e| TableError::Io {
                path: path.display().to_string(),
                why: e.to_string(),
            },
        )
    }

    /// Reads a table [`Self::save`] wrote, every way it can be wrong named.
    pub fn load(path: &std::path::Path) -> Result<EffectTable, TableError> {
        let bytes = std::fs::read(path).map_err(|e| TableError::Io {
            path: path.display().to_string(),
            why: e.to_string(),
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// As [`Self::load`], from the file's bytes (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &std::path::Path) -> Result<EffectTable, TableError> {
        use crate::framed::{Body, FramedError};
        let name = path.display().to_string();
        let table: EffectTable = crate::framed::read(
            bytes,
            MAGIC,
            &[(VERSION, Body::Deflated), (2, Body::Deflated)],
        )
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
        if self.dims.iter().any(|&d| d < 2) || lattice > 1 << 24 {
            return Err(format!(
                "lattice of {:?} nodes: expected 2 to 2²⁴ a side",
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
        if self.starts.windows(2).any(|w| w[0] > w[1]) || self.starts[lattice] as usize != entries {
            return Err(format!(
                "entry starts not ascending to the {entries} entries"
            ));
        }
        if self.fit.len() != entries * radii
            || self.entry_node.iter().any(|&p| p as usize >= probes)
        {
            return Err(format!(
                "{} fits for {entries} entries of {radii} radii, or an entry's probe node past the {probes}",
                self.fit.len()
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
            .all(|c| c.is_finite() && *c > 0.0)
        {
            return Err("a probe node's compliance is not a positive number".into());
        }
        if self.fit.iter().flatten().any(|v| !v.is_finite()) {
            return Err("a fit is not finite".into());
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

    /// Bytes the table's entries take as stored (node ids, `(A, λ)` at half
    /// precision).
    pub fn bytes(&self) -> usize {
        self.entry_node.len() * 4 + self.fit.len() * 4
    }

    /// The effect of `nodule` at every probe node: checked against the table's ranges,
    /// then trilinear over its centre's lattice cell and quadratic over the three radii
    /// about its own.
    pub fn place(&self, nodule: &Nodule) -> Result<NoduleEffect, TableError> {
        let t0 = Instant::now();
        let (lo, hi) = (self.radii_mm[0], *self.radii_mm.last().unwrap_or(&0.0));
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
        let mut minus_dc = vec![0.0; self.probe_nodes.len()];
        let mut surface_mm = 0.0;
        for corner in 0..8 {
            let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let w: f64 = (0..3)
                .map(|d| if o[d] == 1 { frac[d] } else { 1.0 - frac[d] })
                .product();
            let i = [0, 1, 2].map(|d| (base[d] + o[d]).min(self.dims[d] - 1));
            let k = self.index(i);
            if w == 0.0 {
                continue;
            }
            if !self.valid[k] {
                return Err(outside());
            }
            surface_mm += w * f64::from(self.surface_mm[k]);
            let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
            for entry in s..e {
                let fit = &self.fit[entry * radii..(entry + 1) * radii];
                let v: f64 = by_radius
                    .iter()
                    .map(|&(i, w)| w * pole(fit[i], nodule.ratio))
                    .sum();
                minus_dc[self.entry_node[entry] as usize] += w * v;
            }
        }
        let depth_mm = surface_mm - nodule.radius_mm;
        if depth_mm < MIN_DEPTH_MM {
            return Err(TableError::TooShallow { depth_mm });
        }
        let at_node = minus_dc
            .iter()
            .zip(&self.compliance_mm_per_n)
            .map(|(&y, &c0)| c0 / (c0 - y) - 1.0)
            .collect();
        Ok(NoduleEffect {
            nodule: *nodule,
            at_node,
            place_s: t0.elapsed().as_secs_f64(),
        })
    }
}

impl EffectTable {
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
        Some(
            six.iter()
                .zip(w)
                .map(|(&n, w)| w * self.at_node[n as usize])
                .sum::<f64>()
                .max(0.0),
        )
    }
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
mod tests {
    use super::*;

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
