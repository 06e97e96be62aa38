//! Finite elements for 3-D elasticity: the reference every PGD accuracy claim is
//! measured against.
//!
//! **Problem.** Find the displacement `u` (mm) of a body Ω with `u = 0` on the fixed
//! region Γ_D and a surface traction `q` (N/mm²) on Γ_N:
//!
//! ```text
//! linear:  ∫_Ω σ(u) : ε(v) dV = ∫_Γ q·v dA,   σ = λ tr(ε) I + 2μ ε,  ε = ½(∇u + ∇uᵀ)
//! hyperelastic: ∫_Ω S(u) : δE(u; v) dV = ∫_Γ q·v dA,  E = ½(FᵀF − I),
//!          S from Saint Venant–Kirchhoff or compressible neo-Hookean (`hyper`)
//! ```
//!
//! with `λ = Eν/((1+ν)(1−2ν))`, `μ = E/(2(1+ν))`; E in kPa is converted to N/mm²
//! (1 kPa = 10⁻³ N/mm²) so that lengths are mm and forces N throughout.
//!
//! **Discretization.** Lagrange tetrahedra: P1 (4 nodes, linear) or P2 (10 nodes,
//! quadratic; straight-sided, mid-edge nodes at edge midpoints). Near incompressibility
//! (ν → 0.5) P1 *locks*: λ/μ = 2ν/(1−2ν) → ∞ (24 at ν = 0.48) and piecewise-linear
//! fields cannot be nearly divergence-free, so P1 is much too stiff; P2 locks far less,
//! and is the default. Neither is a mixed (u, p) formulation: at ν = 0.499 and beyond,
//! even P2 degrades (measured in the issue notes).
//!
//! **Solve.** Sparse symmetric positive-definite stiffness on the free degrees of
//! freedom (fixed nodes removed), factored once by faer's sparse Cholesky (LLᵀ under a
//! nested-dissection ordering of the mesh's nodes, [`ordering`]).

pub mod elasticity;
pub mod hyper;
pub mod lanes;
pub mod law;
pub mod load;
mod m3;
mod m3v;
pub mod newton;
pub mod nodule;
pub mod ordering;
pub mod path;
pub mod probe;
pub mod series;
pub mod shape;
pub mod space;
pub mod sparse;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Element family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Element {
    P1,
    P2,
}

impl Element {
    pub fn name(self) -> &'static str {
        match self {
            Element::P1 => "p1",
            Element::P2 => "p2",
        }
    }
    pub fn nodes_per_cell(self) -> usize {
        match self {
            Element::P1 => 4,
            Element::P2 => 10,
        }
    }
    pub fn nodes_per_face(self) -> usize {
        match self {
            Element::P1 => 3,
            Element::P2 => 6,
        }
    }
}

impl std::str::FromStr for Element {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "p1" | "P1" => Ok(Element::P1),
            "p2" | "P2" => Ok(Element::P2),
            o => Err(format!("unknown element '{o}', expected p1 or p2")),
        }
    }
}

/// Isotropic material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub young_kpa: f64,
    pub poisson: f64,
}

impl Default for Material {
    /// Liver tissue: E = 160 kPa, ν = 0.48.
    fn default() -> Self {
        Material {
            young_kpa: 160.0,
            poisson: 0.48,
        }
    }
}

impl Material {
    /// Checks E within [`YOUNG_KPA_RANGE`] and −1 < ν < 0.5.
    pub fn validate(&self) -> Result<(), FeError> {
        if !YOUNG_KPA_RANGE.contains(&self.young_kpa) {
            return Err(FeError::YoungModulus {
                young_kpa: self.young_kpa,
            });
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(FeError::PoissonRatio {
                poisson: self.poisson,
            });
        }
        Ok(())
    }
    /// Lamé parameters (λ, μ) in N/mm².
    pub fn lame_n_per_mm2(&self) -> (f64, f64) {
        let e = self.young_kpa * 1e-3;
        let nu = self.poisson;
        (
            e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            e / (2.0 * (1.0 + nu)),
        )
    }
}

/// The number of points (depth 0 included) of a depth grid `0, step, 2 step, …, max`,
/// checked: both finite and positive, and at least one and at most `max_points − 1`
/// steps.
pub fn depth_grid_points(
    depth_max_mm: f64,
    step_mm: f64,
    max_points: usize,
) -> Result<usize, FeError> {
    let steps = (depth_max_mm / step_mm).round();
    if depth_max_mm.is_finite()
        && depth_max_mm > 0.0
        && step_mm.is_finite()
        && step_mm > 0.0
        && steps >= 1.0
        && steps < max_points as f64
    {
        Ok(steps as usize + 1)
    } else {
        Err(FeError::DepthGrid {
            depth_max_mm,
            step_mm,
            max_steps: max_points.saturating_sub(1),
        })
    }
}

/// Why one Newton step (from the last converged state to the next target) failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StepFailure {
    #[error("tangent not positive definite: {0}")]
    Tangent(String),
    #[error("line search failed at residual {residual_n:.3e} N")]
    LineSearch { residual_n: f64 },
    #[error("no convergence in {iterations} iterations (residual {residual_n:.3e} N)")]
    Iterations { iterations: usize, residual_n: f64 },
    #[error("its budget of {factorizations} tangent factorizations is spent")]
    Budget { factorizations: usize },
}

/// How a ramp ended: its step cut below the smallest, or its factorization budget spent.
fn gave_up(why: &StepFailure, min_step: f64) -> String {
    match why {
        StepFailure::Budget { .. } => "it stopped there".into(),
        _ => format!("the step fell below {min_step} of it"),
    }
}

/// Why a finite-element computation failed.
/// The Young's moduli a solve takes (kPa): 1 Pa to 1 TPa, every material from a gel
/// to diamond. Far outside, the stiffness's entries leave the range where a
/// factorization is exact and quick (at 1e-300 kPa they are subnormal: 71 s to factor
/// coarse P2 instead of 1.6 s, and the displacements overflow).
pub const YOUNG_KPA_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e9;

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FeError {
    #[error(
        "invalid material: Young's modulus {young_kpa:e} kPa: expected 1e-3 to 1e9 kPa \
         (1 Pa to 1 TPa: gels to diamond)"
    )]
    YoungModulus { young_kpa: f64 },
    #[error("invalid material: Poisson's ratio {poisson} must lie in (−1, 0.5)")]
    PoissonRatio { poisson: f64 },
    #[error(
        "the stiffness is not positive definite (is the body fixed anywhere? {fixed_nodes} fixed nodes): {detail}"
    )]
    NotPositiveDefinite { fixed_nodes: usize, detail: String },
    #[error(
        "nodule ratio {ratio}: expected the nodule's Young's modulus over the tissue's, \
         between 0.01 and 1000"
    )]
    NoduleRatio { ratio: f64 },
    #[error("nodule at {center_mm:?} mm, radius {radius_mm} mm: expected finite values")]
    NoduleNotFinite { center_mm: [f64; 3], radius_mm: f64 },
    #[error(
        "nodule radius {radius_mm} mm: this mesh (spacing {h_mm:.1} mm) resolves radii from \
         {min_mm:.1} mm; use a finer level for a smaller nodule"
    )]
    NoduleTooSmall {
        radius_mm: f64,
        min_mm: f64,
        h_mm: f64,
    },
    #[error("nodule centre {center_mm:?} mm: outside the organ (expected a point inside it)")]
    NoduleOutside { center_mm: [f64; 3] },
    #[error(
        "the nodule comes {depth_mm:.2} mm from {region} (near {at_mm:.1?} mm): expected \
         it at least 2 mm below the organ's surface everywhere (a smaller radius or a \
         deeper centre)"
    )]
    NoduleTooShallow {
        depth_mm: f64,
        region: &'static str,
        at_mm: [f64; 3],
    },
    #[error("the organ has no palpable surface (no boundary face is marked palpable)")]
    NoPalpableSurface,
    #[error("invalid load: force {force_n} N is not finite")]
    ForceNotFinite { force_n: f64 },
    #[error("invalid load: direction {dir:?} has no length (expected a finite non-zero vector)")]
    NoDirection { dir: [f64; 3] },
    #[error("invalid load: probe point {point:?} is not finite")]
    PointNotFinite { point: [f64; 3] },
    #[error("invalid load: tool radius {radius_mm:?} mm must be finite and positive")]
    ToolRadius { radius_mm: f64 },
    #[error(
        "the tool (radius {radius_mm:?} mm) covers more than {most} load nodes of an organ \
         {across_mm:.1} mm across: expected a tool a few times smaller than the organ (check \
         the tool radius, or the surface file's units)"
    )]
    ToolTooLarge {
        radius_mm: f64,
        most: usize,
        across_mm: f64,
    },
    #[error("invalid press: depth {depth_mm} mm is not finite")]
    DepthNotFinite { depth_mm: f64 },
    #[error(
        "invalid press: depth {depth_mm} mm pushes the tool through the organ, which is \
         {thickness_mm:.1} mm thick along the push there (expected a depth under that)"
    )]
    DepthThroughOrgan { depth_mm: f64, thickness_mm: f64 },
    #[error(
        "invalid depth grid: deepest press {depth_max_mm} mm in steps of {step_mm} mm; \
         expected both finite and positive, with 1 to {max_steps} steps"
    )]
    DepthGrid {
        depth_max_mm: f64,
        step_mm: f64,
        max_steps: usize,
    },
    #[error(
        "a depth series of {orders} orders: expected {min} to {max} (each order is a \
         linear solve, and its right-hand side grows with the square of the order)"
    )]
    SeriesOrders {
        orders: usize,
        min: usize,
        max: usize,
    },
    #[error(
        "active-cell cutoff {cutoff:?}: expected a fraction from 0 (every cell) to below 1 \
         of the first order's largest variation (above, no cell is active and the series \
         stays linear)"
    )]
    ActiveCutoff { cutoff: f64 },
    #[error("invalid press: the load does not move the probe point along the tool axis")]
    ProbeNotMoved,
    #[error(
        "Newton did not converge: {law} reached {:.1}% of the load ({why}); {}. {advice}",
        100.0 * reached_share,
        gave_up(why, *min_step)
    )]
    NoConvergence {
        law: &'static str,
        reached_share: f64,
        why: StepFailure,
        min_step: f64,
        advice: &'static str,
    },
    #[error(
        "Newton did not converge: {law} reached a depth of {reached_mm:.2} of {target_mm:.2} mm at {force_n:.3} N ({why}); {}. {advice}",
        gave_up(why, *min_step)
    )]
    NoConvergenceDepth {
        law: &'static str,
        reached_mm: f64,
        target_mm: f64,
        force_n: f64,
        why: StepFailure,
        min_step: f64,
        advice: &'static str,
    },
    #[error(
        "the factorization of {dofs} unknowns needs about {need_gb:.1} GB, {budget_gb:.1} GB are available: use a coarser level or P1 elements"
    )]
    TooLarge {
        dofs: usize,
        need_gb: f64,
        budget_gb: f64,
    },
}
