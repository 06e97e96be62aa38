//! The hyperelastic laws, one file each behind one trait ([`HyperLaw`]).
//!
//! A law is what the element kernels need of it at a quadrature point, written once in
//! each of the two forms the kernels run: one point at a time ([`super::hyper`]'s force
//! and tangent, [`super::series`]'s depth series, the plain statement of the
//! arithmetic) and four points in vector lanes ([`super::lanes`], what the builds run).
//! The two forms of a law perform the same operations in the same order, so the lanes
//! give the scalar numbers bit for bit (a unit test in `lanes` checks every law).
//!
//! At a point with deformation gradient `F`, `C = FᵀF`, a law gives:
//!
//! - its second Piola–Kirchhoff stress `S` and what its tangent needs
//!   ([`HyperLaw::state`]): for the material tangent `δE_r : ℂ : δE_c =
//!   λ lin_r lin_c + 2 shear (δE_r ⋆ δE_c)`, a scalar `lin` per direction
//!   ([`HyperLaw::linearize`]) and the contraction `⋆` ([`HyperLaw::contract`]);
//! - the series of `S` along a depth series of `F` ([`HyperLaw::stress_series`]).
//!
//! A law takes the Lamé parameters `λ, μ` per call, so they may change from cell to
//! cell (a stiffer inclusion). A third law is one new file here, a variant of [`Law`]
//! and one arm of `with_law!`.

mod neo_hookean;
mod svk;

use serde::{Deserialize, Serialize};

use super::m3::M3;
use super::m3v::{M3V, V};

pub(crate) use neo_hookean::NeoHookean;
pub(crate) use svk::Svk;

/// The hyperelastic laws a build may name (each takes the Lamé parameters of
/// [`super::Material`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Law {
    /// Saint Venant–Kirchhoff (the paper's liver).
    Svk,
    /// Compressible neo-Hookean.
    NeoHookean,
}

impl Law {
    pub fn name(self) -> &'static str {
        match self {
            Law::Svk => "svk",
            Law::NeoHookean => "neo-hookean",
        }
    }
}

impl std::str::FromStr for Law {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "svk" => Ok(Law::Svk),
            "neo-hookean" | "neohookean" => Ok(Law::NeoHookean),
            o => Err(format!(
                "unknown hyperelastic law '{o}', expected svk or neo-hookean"
            )),
        }
    }
}

/// Runs `$body` with `$L` the type of the law `$law` names: the one place a [`Law`]
/// becomes its code.
macro_rules! with_law {
    ($law:expr, $L:ident => $body:expr) => {
        match $law {
            $crate::fe::law::Law::Svk => {
                type $L = $crate::fe::law::Svk;
                $body
            }
            $crate::fe::law::Law::NeoHookean => {
                type $L = $crate::fe::law::NeoHookean;
                $body
            }
        }
    };
}
pub(crate) use with_law;

/// The stress at one quadrature point and what its tangent needs.
pub(crate) struct PointState {
    pub(crate) s: M3,
    /// `C⁻¹` where the law's tangent uses it (zero otherwise).
    pub(crate) c_inv: M3,
    /// The factor of the contraction term (`μ − λ ln J` neo-Hookean, `μ` SVK).
    pub(crate) shear: f64,
}

/// What the element kernels need of a hyperelastic law, at one point and in lanes
/// (four points, one a lane: `S`, `C⁻¹` and `shear` as in [`PointState`]).
pub(crate) trait HyperLaw {
    /// `S` and the tangent's needs at `F` (`c` = `FᵀF`).
    fn state(f: &M3, c: &M3, lambda: f64, mu: f64) -> PointState;
    /// For a direction with strain variation `d` (`δE`): `lin`, the scalar of the
    /// `λ` term, and `cde`, what [`Self::contract`] pairs (left as is where unused).
    fn linearize(st: &PointState, d: &M3, lin: &mut f64, cde: &mut M3);
    /// `dd += δE_r ⋆ δE_c` from the two directions' `δE` (`dr`, `dc`) and `cde`s.
    fn contract(dr: &M3, cr: &M3, dc: &M3, cc: &M3, dd: &mut f64);
    /// The coefficients `0..=p` of `S` from those of `F` (`f`) and `C` (`c`), into `s`.
    fn stress_series<const N: usize>(
        f: &[M3],
        c: &[M3; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3],
    );
    /// [`Self::state`] in lanes, into `s`, `ci` and `shear` (which come in as zero,
    /// zero and `μ`).
    #[allow(clippy::too_many_arguments)]
    fn state_v(f: &M3V, c: &M3V, lambda: f64, mu: f64, s: &mut M3V, ci: &mut M3V, shear: &mut V);
    /// [`Self::linearize`] in lanes.
    fn linearize_v(ci: &M3V, d: &M3V, lin: &mut V, cde: &mut M3V);
    /// [`Self::contract`] in lanes.
    fn contract_v(dr: &M3V, cr: &M3V, dc: &M3V, cc: &M3V, dd: &mut V);
    /// [`Self::stress_series`] in lanes.
    fn stress_series_v<const N: usize>(
        f: &[M3V; N],
        c: &[M3V; N],
        p: usize,
        lambda: f64,
        mu: f64,
        s: &mut [M3V; N],
    );
}
