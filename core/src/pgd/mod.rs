//! Proper Generalized Decomposition: off-line solvers that compute a separated
//! representation of a parametric solution without sampling the parameters.
//!
//! [`linear`] solves the linear parametric problem of docs/methods.md §1,
//! `K U Ms = F Ms` for `U ≈ Σ_k X_k y_kᵀ` (space × one parametric index with mass
//! matrix `Ms`), by greedy enrichment with an alternating-directions fixed point and an
//! optional Galerkin update of all parametric functions. [`palpation`] builds the
//! liver vademecum on it: the parametric index is (probe surface node, load direction).
//!
//! Further parametric axes (force magnitude for nonlinear tissue, material
//! parameters) enter as further alternating steps of the same fixed point; the solver
//! here handles one combined parametric index and is written so that step is local.

pub mod block;
pub mod cluster;
pub mod heldout;
pub mod journal;
pub mod linear;
pub mod nodal;
pub mod nodule;
pub mod palpation;
pub mod tradeoff;
