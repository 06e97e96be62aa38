//! The nodule in the pressed tissue: the table's linear effect times how much more of
//! the press's load the nodule's cells carry in the pressed state than in the linear
//! one.
//!
//! A nodule multiplies the stiffness of cell `c` by `s_c` ([`crate::fe::nodule`]).
//! To first order in `s_c − 1` (the Born approximation), the tool's force at depth `d`
//! changes by the stress power the nodule's cells would add along the nodule-free
//! press,
//!
//! ```text
//! δF(d) ≈ Σ_c (s_c − 1) f_c(u(d)) · u'(d),    F(d) = Σ_c f_c(u(d)) · u'(d),
//! ```
//!
//! `f_c` the cell's internal force, `u'` the press's rate `du/dd` (the second sum is the
//! tool's force: the work done on the organ per millimetre of depth). In linear
//! elasticity `f_c(u) · u' = d û·K_c û`, so the first-order relative effect is the
//! same at every depth. First order overstates a stiff nodule's effect (it lets the
//! stiff cells strain as the soft ones did); the linear table's effect `e` is exact,
//! the nodule screening itself included. The pressed tissue's effect is taken as
//!
//! ```text
//! e_tissue(s, d) = e(s) · A(s, d),   A = [Σ_c (s_c − 1) P_c(s, d)] / [Σ_c (s_c − 1) P_c^lin(s)],
//! ```
//!
//! `P_c = f_c · u' / F` the share of the press's power cell `c` carries, pressed and
//! linear: the screening assumed the same in both, the redistribution of the load
//! the press causes (the tissue above a nodule compressed onto it, or the tool rolling
//! off it) carried exactly. At the recorded neo-Hookean presses (docs/lab §17) it
//! moved the felt effects' errors from −21…+53 % (a mean growth with depth) to
//! −5…+13 %, the table's own error included.
//!
//! The screening is not the same in both where the nodule carries much of the press:
//! a stiff nodule whose top lies a few millimetres under the tool is screened more by
//! the compressed layer above it than by the linear tissue (Newton's effect 0.83–1.15
//! times the linear one where `A` says 1.06–1.34; docs/lab §22). To second order in
//! the contrast, that extra screening grows with the nodule's first-order share of the
//! press, `f = Σ_c (s_c − 1) P_c^lin`, and with the depth, so `A` is taken as
//!
//! ```text
//! A(s, d) = [Σ_c (s_c − 1) P_c(s, d)] / f · exp(−κ f d),   κ = PRESSED_SCREENING_PER_MM,
//! ```
//!
//! which keeps first order exact (`A` → its first-order value as `s_c → 1`), and was
//! measured against Newton right above the nodule and at the recorded presses.
//!
//! Off-line ([`VertexPower::from_press`]): every palpable vertex pressed without a
//! nodule along the tissue build's push. Over each step of the depth grid a cell's
//! share is the power of the step's mean state along its secant over the step's mean
//! force; two steps' shares are averaged into one stored depth ([`STEPS_PER_DEPTH`]).
//! A vertex keeps the cells within its reach that carry at least
//! [`CellPower::share_floor`] of its linear press's power, each with its linear share
//! (half precision) and, at each stored depth, the logarithm of its pressed share over
//! the linear one in one byte ([`RATIO_LOG2_MIN`], [`RATIO_STEPS_PER_OCTAVE`]).
//! Against the full store (every cell with a corner within 30 mm, every 1 mm step, half
//! precision) this is a seventh of the bytes and answers the recorded presses as well
//! (docs/lab §18).
//! On-line ([`CellPower::place`]): a nodule's factors on the stored cells, two sums
//! per vertex and depth; a probe blends its triangle's corners ([`Placed::curve`]).

use half::f16;

use crate::fe::Material;
use crate::fe::law::Law;
use crate::fe::nodule::Nodule;
use crate::fe::space::Space;
use serde::{Deserialize, Serialize};

/// The pressed tissue's extra screening of a nodule, per millimetre of depth and per
/// unit of the nodule's first-order share of the press (`exp(−κ f d)`, see the module
/// doc): chosen over 0.02–0.06 at 70 presses right above nodules, then measured at the
/// recorded checks and at fresh seeds (docs/lab/nodule-measurements.md §23).
pub const PRESSED_SCREENING_PER_MM: f64 = 0.04;

/// How many depths an [`EffectCurve`] holds: the tissue's grid steps, at most.
pub const CURVE_DEPTHS: usize = 24;

/// The linear shares are stored times this (only their ratios are read), so that small
/// ones stay normal numbers in half precision.
pub const SHARE_SCALE: f64 = 1024.0;

/// How deep a vertex is pressed by default (mm): the goals' range; past it a curve
/// holds its end ([`EffectCurve::at`]).
pub const PRESS_DEPTH_MM: f64 = 10.0;

/// Grid steps averaged into one stored depth.
pub const STEPS_PER_DEPTH: usize = 2;

/// A pressed share over the linear one is stored as the byte
/// `q = round((log₂ R − RATIO_LOG2_MIN) · RATIO_STEPS_PER_OCTAVE)`, clamped to 0–255:
/// ratios from 1/64 to 2^6.75 within 1.7 % (a cell that gives power back, a negative
/// share, is read as 1/64 of its linear share).
pub const RATIO_LOG2_MIN: f64 = -6.0;
pub const RATIO_STEPS_PER_OCTAVE: f64 = 20.0;

/// The stored ratio `R` for each byte.
fn ratio_of_byte() -> [f64; 256] {
    std::array::from_fn(|q| (q as f64 / RATIO_STEPS_PER_OCTAVE + RATIO_LOG2_MIN).exp2())
}

/// The byte that stores the ratio `r` (see [`RATIO_LOG2_MIN`]).
fn byte_of_ratio(r: f64) -> u8 {
    if r.is_nan() || r <= 0.0 {
        return 0;
    }
    ((r.log2() - RATIO_LOG2_MIN) * RATIO_STEPS_PER_OCTAVE)
        .round()
        .clamp(0.0, 255.0) as u8
}

/// The depths (mm) the shares are stored at, from a grid of `steps` steps of `step_mm`:
/// the midpoints of each [`STEPS_PER_DEPTH`] steps (a last partial one dropped).
pub fn stored_depths_mm(step_mm: f64, steps: usize) -> Vec<f64> {
    let k = STEPS_PER_DEPTH as f64;
    (0..steps / STEPS_PER_DEPTH)
        .map(|j| (j as f64 + 0.5) * k * step_mm)
        .collect()
}

/// Which cells a vertex keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keep {
    /// Those with a corner within this distance of the vertex (mm),
    pub reach_mm: f64,
    /// and at least this share of its linear press's power.
    pub share_floor: f64,
}

impl Default for Keep {
    /// 30 mm (the table's probe reach and its largest radius); a floor of 3·10⁻⁴,
    /// which keeps about 200 cells a vertex on coarse P2 and answers the recorded
    /// presses as all the cells within the reach do (docs/lab §18).
    fn default() -> Keep {
        Keep {
            reach_mm: 30.0,
            share_floor: 3e-4,
        }
    }
}

/// What every vertex's press shares: the cells (corners, mm), the depths its shares are
/// taken at, and the tissue they are of.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellPower {
    /// The tissue file's payload checksum (`palpa info X.tissue`): the presses are its.
    pub tissue_xxh3: u64,
    /// Poisson's ratio of the tissue (the nodule's factors depend on it).
    pub poisson: f64,
    /// A vertex keeps the cells with a corner within this distance (mm)
    pub reach_mm: f64,
    /// and at least this share of its linear press's power.
    pub share_floor: f64,
    /// The depths (mm) the pressed shares are taken at ([`stored_depths_mm`]),
    /// ascending.
    pub depths_mm: Vec<f64>,
    /// Every cell's corners (mm), in the mesh's order.
    pub cells: Vec<[[f32; 3]; 4]>,
    pub vertices: Vec<VertexPower>,
    /// Seconds the presses took.
    pub build_s: f64,
}

/// One palpable vertex's press, as the cells near it share its power.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VertexPower {
    /// The vertex (mm, rest).
    pub at_mm: [f32; 3],
    /// Its cells (the mesh's, indices into [`CellPower::cells`]).
    pub cells: Vec<u32>,
    /// Each cell's share of the linear press's power times [`SHARE_SCALE`] (IEEE half
    /// precision, its bits: full relative precision to shares of 6·10⁻⁸).
    pub linear: Vec<u16>,
    /// Each cell's share at each depth the press reached over its linear share, a byte
    /// ([`RATIO_LOG2_MIN`]): `pressed[j · cells + k]`.
    pub pressed: Vec<u8>,
    /// How many of [`CellPower::depths_mm`] the press reached (past them the last
    /// is held).
    pub depths: u32,
}

/// A placed nodule's amplification at every vertex: `A` at each depth, the pressed
/// tissue's extra screening included.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// `A[v · depths + j]`, 1 where the nodule touches none of the vertex's cells.
    pub at_vertex: Vec<f32>,
    pub depths_mm: Vec<f64>,
    /// Seconds the placing took.
    pub place_s: f64,
}

/// The effect a probe point feels as a function of the depth: the linear effect times
/// the amplification at depths `first_mm + j · step_mm`, interpolated linearly between
/// them (from the linear effect at 0 mm; past the last, see [`Self::at`]). Plain data,
/// small enough for the force loop's command.
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct EffectCurve {
    /// The linear effect (at 0 mm).
    pub effect: f32,
    /// How many depths follow (0: the same effect at every depth).
    pub len: u32,
    pub first_mm: f32,
    pub step_mm: f32,
    /// The effect at the depths.
    pub at_depth: [f32; CURVE_DEPTHS],
}

impl EffectCurve {
    /// The same effect at every depth (the linear model, or no amplification known).
    pub fn flat(effect: f64) -> EffectCurve {
        EffectCurve {
            effect: effect as f32,
            ..EffectCurve::default()
        }
    }

    /// The effect at `depth_mm`: no allocation, no search. The depths are the midpoints
    /// of the pressed steps, so the press reached half a step past the last: the last
    /// two are carried on over that half step, and the end held past it.
    pub fn at(&self, depth_mm: f64) -> f64 {
        let n = (self.len as usize).min(CURVE_DEPTHS);
        let d = depth_mm as f32;
        if n == 0 || d.is_nan() || d <= 0.0 {
            return f64::from(self.effect);
        }
        if d <= self.first_mm {
            let t = d / self.first_mm;
            return f64::from(self.effect + t * (self.at_depth[0] - self.effect));
        }
        if n == 1 {
            return f64::from(self.at_depth[0]);
        }
        let x = ((d - self.first_mm) / self.step_mm).min((n - 1) as f32 + 0.5);
        let j = (x as usize).min(n - 2);
        let t = x - j as f32;
        f64::from(self.at_depth[j] + t * (self.at_depth[j + 1] - self.at_depth[j]))
    }

    /// The largest effect over the curve.
    pub fn max(&self) -> f64 {
        let n = (self.len as usize).min(CURVE_DEPTHS);
        let end = self.at(f64::MAX);
        f64::from(
            self.at_depth[..n]
                .iter()
                .fold(self.effect, |m, &e| m.max(e)),
        )
        .max(end)
    }
}

impl CellPower {
    /// The presses `vertices` of the tissue `tissue_xxh3` (Poisson's ratio `poisson`)
    /// on `space`, taken with `keep` through a grid of `steps` steps of `step_mm`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        space: &Space,
        tissue_xxh3: u64,
        poisson: f64,
        keep: Keep,
        step_mm: f64,
        steps: usize,
        vertices: Vec<VertexPower>,
        build_s: f64,
    ) -> CellPower {
        CellPower {
            tissue_xxh3,
            poisson,
            reach_mm: keep.reach_mm,
            share_floor: keep.share_floor,
            depths_mm: stored_depths_mm(step_mm, steps),
            cells: (0..space.cell_count())
                .map(|c| space.cell_corners(c).map(|p| p.map(|x| x as f32)))
                .collect(),
            vertices,
            build_s,
        }
    }

    /// The nodule's amplification at every vertex (see the module doc).
    pub fn place(&self, nodule: &Nodule) -> Placed {
        let t0 = std::time::Instant::now();
        // The factors' excess on the cells the nodule reaches (a cell far from it: 0).
        let corners = |t: &[[f32; 3]; 4]| t.map(|p| p.map(f64::from));
        let fractions = nodule.fractions(self.cells.iter().map(corners));
        let excess: Vec<f64> = fractions
            .iter()
            .map(|&phi| {
                if phi > 0.0 {
                    nodule.factor(phi, self.poisson) - 1.0
                } else {
                    0.0
                }
            })
            .collect();
        let ratio = ratio_of_byte();
        let n = self.depths_mm.len();
        let mut at_vertex = vec![1.0f32; self.vertices.len() * n];
        let mut weight = Vec::new();
        for (v, out) in self.vertices.iter().zip(at_vertex.chunks_exact_mut(n)) {
            let m = v.cells.len();
            // Each cell's first-order change, linear: `(s_c − 1) P_c^lin`.
            weight.clear();
            weight.extend(
                v.cells
                    .iter()
                    .zip(&v.linear)
                    .map(|(&c, &p)| excess[c as usize] * f16::from_bits(p).to_f64()),
            );
            let lin: f64 = weight.iter().sum();
            if lin <= 0.0 {
                continue;
            }
            let reached = (v.depths as usize).min(n);
            let first = lin / SHARE_SCALE;
            let mut last = 1.0;
            for (j, a) in out.iter_mut().enumerate() {
                if j < reached {
                    let pressed: f64 = weight
                        .iter()
                        .zip(&v.pressed[j * m..(j + 1) * m])
                        .map(|(w, &q)| w * ratio[q as usize])
                        .sum();
                    last = pressed / lin;
                }
                let screened = (-PRESSED_SCREENING_PER_MM * first * self.depths_mm[j]).exp();
                *a = (last * screened) as f32;
            }
        }
        Placed {
            at_vertex,
            depths_mm: self.depths_mm.clone(),
            place_s: t0.elapsed().as_secs_f64(),
        }
    }

    /// The arrays agree with each other (what a file must hold before it is read from):
    /// the reason where they do not.
    pub fn check(&self) -> Result<(), String> {
        let d = &self.depths_mm;
        let step = if d.len() > 1 { d[1] - d[0] } else { 1.0 };
        let uniform = d.iter().enumerate().all(|(j, x)| {
            x.is_finite() && (x - d[0] - j as f64 * step).abs() <= 1e-9 * (1.0 + x.abs())
        });
        if d.is_empty() || d.len() > CURVE_DEPTHS || !(d[0] > 0.0 && step > 0.0) || !uniform {
            return Err(format!(
                "tissue power at depths {d:?} mm: expected 1 to {CURVE_DEPTHS} equally spaced depths above 0 mm"
            ));
        }
        if !(self.share_floor >= 0.0 && self.share_floor < 1.0) {
            return Err(format!(
                "tissue power's share floor {}: expected from 0 to below 1",
                self.share_floor
            ));
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(format!(
                "tissue power of Poisson's ratio {}: expected between −1 and 0.5",
                self.poisson
            ));
        }
        for (i, v) in self.vertices.iter().enumerate() {
            let m = v.cells.len();
            let reached = v.depths as usize;
            if v.cells.iter().any(|&c| c as usize >= self.cells.len())
                || v.linear.len() != m
                || reached > d.len()
                || v.pressed.len() != reached * m
            {
                return Err(format!(
                    "tissue power's vertex {i}: {m} cells (of {}), {} linear and {} pressed shares over {reached} depths: expected a share a cell, a cell of the {} stored, at most {} depths",
                    self.cells.len(),
                    v.linear.len(),
                    v.pressed.len(),
                    self.cells.len(),
                    d.len()
                ));
            }
        }
        Ok(())
    }

    /// The stored vertex at `p_mm` (within 1 µm), if any.
    pub fn vertex_at(&self, p_mm: [f64; 3]) -> Option<usize> {
        self.vertices.iter().position(|v| {
            (0..3)
                .map(|i| (f64::from(v.at_mm[i]) - p_mm[i]).powi(2))
                .sum::<f64>()
                < 1e-6
        })
    }

    /// Stored bytes of the shares, before compression.
    pub fn bytes(&self) -> usize {
        self.cells.len() * 48
            + self
                .vertices
                .iter()
                .map(|v| 6 * v.cells.len() + v.pressed.len())
                .sum::<usize>()
    }
}

impl Placed {
    /// The effect curve at a probe point whose triangle has the stored vertices
    /// `corners` (`None`: not stored, dropped) at barycentric `bary`, its linear effect
    /// `effect`: the corners' amplifications blended, the dropped ones' weight given
    /// to the others; all dropped, the flat curve.
    pub fn curve(&self, corners: [Option<usize>; 3], bary: [f64; 3], effect: f64) -> EffectCurve {
        let n = self.depths_mm.len().min(CURVE_DEPTHS);
        let mut c = EffectCurve::flat(effect);
        let w: f64 = (0..3)
            .filter(|&k| corners[k].is_some())
            .map(|k| bary[k])
            .sum();
        if w <= 0.0 {
            return c;
        }
        let stride = self.depths_mm.len();
        c.first_mm = self.depths_mm[0] as f32;
        c.step_mm = if n > 1 {
            (self.depths_mm[1] - self.depths_mm[0]) as f32
        } else {
            1.0
        };
        for j in 0..n {
            let mut a = 0.0;
            for k in 0..3 {
                if let Some(v) = corners[k] {
                    a += bary[k] * f64::from(self.at_vertex[v * stride + j]);
                }
            }
            c.at_depth[j] = (effect * a / w) as f32;
        }
        c.len = n as u32;
        c
    }
}

impl VertexPower {
    /// A vertex's shares from its nodule-free press: `linear` the unit-depth linear
    /// field (all-node, mm) and `force_1_n` its force (N at 1 mm: `û·K û`, the whole
    /// organ's), `states` the equilibria at the grid depths `0, h, 2h, …` (all-node;
    /// the first the rest) with their forces (N), `cells` the mesh cells within its
    /// reach, of which it keeps those with at least `share_floor` of the linear power.
    #[allow(clippy::too_many_arguments)]
    pub fn from_press(
        space: &Space,
        law: Law,
        material: Material,
        at_mm: [f64; 3],
        cells: &[usize],
        share_floor: f64,
        linear: &[f64],
        force_1_n: f64,
        states: &[Vec<f64>],
        forces_n: &[f64],
        step_mm: f64,
    ) -> VertexPower {
        let (lambda, mu) = material.lame_n_per_mm2();
        let npc = space.element.nodes_per_cell();
        let m = 3 * npc;
        let gather = |c: usize, u: &[f64], out: &mut [f64]| {
            for (a, &node) in space.cell(c).iter().enumerate() {
                for i in 0..3 {
                    out[3 * a + i] = u[3 * node as usize + i];
                }
            }
        };
        let (mut ke, mut fe, mut uc, mut vc) =
            (vec![0.0; m * m], vec![0.0; m], vec![0.0; m], vec![0.0; m]);
        // Linear: û·K_c û over û·K û (over the kept cells the shares need not sum to 1).
        let mut lin = Vec::with_capacity(cells.len());
        for &c in cells {
            crate::fe::elasticity::element_stiffness(space, c, lambda, mu, &mut ke);
            gather(c, linear, &mut uc);
            let mut p = 0.0;
            for r in 0..m {
                let kr: f64 = (0..m).map(|q| ke[r * m + q] * uc[q]).sum();
                p += uc[r] * kr;
            }
            lin.push(p / force_1_n.max(f64::MIN_POSITIVE));
        }
        // Each grid step's shares, summed over the steps of a stored depth.
        let depths = states.len().saturating_sub(1) / STEPS_PER_DEPTH;
        let mut pressed = vec![0.0; depths * cells.len()];
        let mut mean = vec![0.0; linear.len()];
        for j in 0..depths * STEPS_PER_DEPTH {
            let (a, b) = (&states[j], &states[j + 1]);
            for ((x, p), q) in mean.iter_mut().zip(a).zip(b) {
                *x = 0.5 * (p + q);
            }
            let force = 0.5 * (forces_n[j] + forces_n[j + 1]);
            let row = &mut pressed[(j / STEPS_PER_DEPTH) * cells.len()..][..cells.len()];
            for (&c, share) in cells.iter().zip(row) {
                crate::fe::lanes::element_force(space, law, c, &mean, lambda, mu, &mut fe);
                for (a_, &node) in space.cell(c).iter().enumerate() {
                    for i in 0..3 {
                        let k = 3 * node as usize + i;
                        vc[3 * a_ + i] = (b[k] - a[k]) / step_mm;
                    }
                }
                let p: f64 = fe.iter().zip(&vc).map(|(f, v)| f * v).sum();
                *share += p / force.max(f64::MIN_POSITIVE);
            }
        }
        let kept: Vec<usize> = (0..cells.len())
            .filter(|&k| lin[k] >= share_floor)
            .collect();
        VertexPower {
            at_mm: at_mm.map(|x| x as f32),
            cells: kept.iter().map(|&k| cells[k] as u32).collect(),
            linear: kept
                .iter()
                .map(|&k| f16::from_f64(SHARE_SCALE * lin[k]).to_bits())
                .collect(),
            pressed: (0..depths)
                .flat_map(|j| {
                    let row = &pressed[j * cells.len()..][..cells.len()];
                    let lin = &lin;
                    kept.iter()
                        .map(move |&k| byte_of_ratio(row[k] / (STEPS_PER_DEPTH as f64 * lin[k])))
                })
                .collect(),
            depths: depths as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular tetrahedron-ish cell about `c` (mm), 2 mm across.
    fn cell(c: [f32; 3]) -> [[f32; 3]; 4] {
        [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 2.0],
        ]
        .map(|d| [c[0] + d[0], c[1] + d[1], c[2] + d[2]])
    }

    /// Shares of the linear press's power, stored as a build stores them.
    fn bits(v: &[f64]) -> Vec<u16> {
        v.iter()
            .map(|&x| f16::from_f64(SHARE_SCALE * x).to_bits())
            .collect()
    }

    /// The pressed tissue's extra screening at depth `d_mm` of a nodule whose
    /// first-order share of the press is `first`.
    fn screened(first: f64, d_mm: f64) -> f32 {
        (-PRESSED_SCREENING_PER_MM * first * d_mm).exp() as f32
    }

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3 * y.abs())
    }

    fn ratios(v: &[f64]) -> Vec<u8> {
        v.iter().map(|&r| byte_of_ratio(r)).collect()
    }

    /// Two vertices over two cells: the first's press doubles the second cell's share
    /// and keeps the first's, its second depth not reached; the second vertex keeps
    /// only the first cell.
    fn power() -> CellPower {
        CellPower {
            tissue_xxh3: 7,
            poisson: 0.48,
            reach_mm: 30.0,
            share_floor: 0.0,
            depths_mm: vec![1.0, 3.0],
            cells: vec![cell([0.0, 0.0, 10.0]), cell([0.0, 0.0, 30.0])],
            vertices: vec![
                VertexPower {
                    at_mm: [0.0, 0.0, 0.0],
                    cells: vec![0, 1],
                    linear: bits(&[0.2, 0.1]),
                    pressed: ratios(&[1.0, 2.0]),
                    depths: 1,
                },
                VertexPower {
                    at_mm: [10.0, 0.0, 0.0],
                    cells: vec![0],
                    linear: bits(&[0.3]),
                    pressed: ratios(&[2.0, 1.0]),
                    depths: 2,
                },
            ],
            build_s: 0.0,
        }
    }

    #[test]
    fn the_amplification_is_the_pressed_share_over_the_linear_on_the_nodules_cells() {
        let p = power();
        let around = |z: f64, ratio: f64| Nodule {
            center_mm: [0.7, 0.7, z],
            radius_mm: 4.0,
            ratio,
        };
        // On the second cell (a share 0.1, three times stiffer: first order 0.3):
        // doubled at the first vertex, held past its reach, screened with the depth;
        // the second vertex keeps no cell of it (1).
        let a = p.place(&around(30.7, 4.0));
        let s = |first: f64| [screened(first, 1.0), screened(first, 3.0)];
        let [s1, s3] = s(0.3);
        assert!(
            close(&a.at_vertex, &[2.0 * s1, 2.0 * s3, 1.0, 1.0]),
            "{a:?}"
        );
        assert!(s1 < 1.0 && s3 < s1);
        // On the first cell (shares 0.2 and 0.3: first order 0.6 and 0.9): kept at the
        // first vertex; doubled, then kept at the second.
        let a = p.place(&around(10.7, 4.0));
        let ([a1, a3], [b1, b3]) = (s(0.6), s(0.9));
        assert!(close(&a.at_vertex, &[a1, a3, 2.0 * b1, b3]), "{a:?}");
        // Ratio 1 changes no cell: no amplification anywhere.
        assert!(
            p.place(&around(10.7, 1.0))
                .at_vertex
                .iter()
                .all(|&x| x == 1.0)
        );
        // A nodule far from every cell: none.
        assert!(
            p.place(&around(80.0, 4.0))
                .at_vertex
                .iter()
                .all(|&x| x == 1.0)
        );
    }

    #[test]
    fn a_probe_blends_its_corners_and_the_curve_interpolates_in_depth() {
        let p = power();
        let a = p.place(&Nodule {
            center_mm: [0.7, 0.7, 10.7],
            radius_mm: 4.0,
            ratio: 4.0,
        });
        let v0 = p.vertex_at([0.0, 0.0, 0.0]);
        let v1 = p.vertex_at([10.0, 0.0, 0.0]);
        assert_eq!(
            (v0, v1, p.vertex_at([5.0, 0.0, 0.0])),
            (Some(0), Some(1), None)
        );
        let c = a.curve([v0, v1, None], [0.25, 0.25, 0.5], 0.1);
        // Halfway between the corners' A (1 and 2 at 1 mm, 1 and 1 at 3 mm, each
        // screened: first order 0.6 and 0.9).
        let at1 = 0.1 * f64::from(screened(0.6, 1.0) + 2.0 * screened(0.9, 1.0)) / 2.0;
        let at3 = 0.1 * f64::from(screened(0.6, 3.0) + screened(0.9, 3.0)) / 2.0;
        let near = |x: f64, y: f64| (x - y).abs() < 1e-6;
        assert!(near(c.at(1.0), at1), "{c:?}");
        assert!(near(c.at(3.0), at3) && near(c.at(2.0), 0.5 * (at1 + at3)));
        // From the linear effect at the rest; carried on over the half step the press
        // reached past the last depth (to 4 mm), held past it.
        let end = at3 + 0.5 * (at3 - at1);
        assert!(near(c.at(0.0), 0.1) && near(c.at(0.5), 0.5 * (0.1 + at1)));
        assert!(near(c.at(3.5), at3 + 0.25 * (at3 - at1)) && near(c.at(4.0), end));
        assert!(near(c.at(40.0), end) && near(c.at(f64::INFINITY), end));
        assert!(near(c.at(f64::NAN), 0.1) && near(c.at(-3.0), 0.1));
        assert!(near(c.max(), at1));
        // No stored corner: the flat curve.
        let flat = a.curve([None; 3], [0.2, 0.3, 0.5], 0.1);
        assert_eq!(flat, EffectCurve::flat(0.1));
        assert!((flat.at(7.0) - 0.1).abs() < 1e-7);
    }

    #[test]
    fn a_ratio_is_kept_in_a_byte_within_its_step() {
        let ratio = ratio_of_byte();
        let half_step = (0.5 / RATIO_STEPS_PER_OCTAVE).exp2();
        for r in [0.02, 0.3, 0.97, 1.0, 1.3, 7.0, 100.0] {
            let back = ratio[byte_of_ratio(r) as usize];
            assert!(
                back / r <= half_step * (1.0 + 1e-12) && r / back <= half_step * (1.0 + 1e-12),
                "{r} → {back}"
            );
        }
        // Past the range, clamped; power given back (or none, or NaN) read as the least.
        assert_eq!(ratio[byte_of_ratio(1e3) as usize], (6.75f64).exp2());
        for r in [0.0, -0.4, f64::NAN, 1e-9] {
            assert_eq!(byte_of_ratio(r), 0, "{r}");
        }
        assert_eq!(ratio[0], 1.0 / 64.0);
        assert_eq!(
            stored_depths_mm(1.0, 15),
            vec![1.0, 3.0, 5.0, 7.0, 9.0, 11.0, 13.0]
        );
    }

    #[test]
    fn arrays_that_disagree_are_refused_by_name() {
        assert_eq!(power().check(), Ok(()));
        let mut p = power();
        p.vertices[1].cells[0] = 2;
        assert!(
            p.check()
                .expect_err("a cell past the stored")
                .contains("vertex 1")
        );
        let mut p = power();
        p.vertices[0].pressed.pop();
        assert!(p.check().expect_err("a share short").contains("pressed"));
        let mut p = power();
        p.depths_mm = vec![0.5, 2.0, 2.5];
        assert!(
            p.check()
                .expect_err("uneven depths")
                .contains("equally spaced")
        );
        let mut p = power();
        p.share_floor = f64::NAN;
        assert!(p.check().expect_err("no floor").contains("share floor"));
        let mut p = power();
        p.poisson = 0.5;
        assert!(p.check().expect_err("ν = 0.5").contains("Poisson"));
    }

    #[test]
    fn a_table_amplifies_only_for_the_tissue_it_was_pressed_with() {
        let mut table = crate::pgd::nodule::table::tests::tiny();
        let n = Nodule {
            center_mm: [0.7, 0.7, 10.7],
            radius_mm: 4.0,
            ratio: 4.0,
        };
        assert!(table.amplification(&n, 7).is_none());
        table.tissue_power = Some(power());
        assert!(table.amplification(&n, 8).is_none());
        let placed = table.amplification(&n, 7).expect("amplified");
        assert_eq!(placed.at_vertex, power().place(&n).at_vertex);
    }
}
