//! Gene regulatory networks: the chemical master equation (CME)
//!
//! `dP(z, t)/dt = Σ_r [ a_r(z − ν_r) P(z − ν_r, t) − a_r(z) P(z, t) ]`
//!
//! for copy numbers `z ∈ ℕ^d`, reactions `r` with change vectors `ν_r` and separable
//! propensities `a_r` ([`network`]). Two reference solvers, one result type:
//! - [`fsp`]: finite state projection (Munsky & Khammash 2006) on a box, integrated
//!   exactly by uniformization; the probability that leaves the box (the *leak*) bounds
//!   the L1 error of the truncation;
//! - [`ssa`]: Gillespie's direct method, seeded, parallel over trajectories, with
//!   standard errors of the moments.
//!
//! [`Moments`] holds what every solver reports at each output time: the marginals,
//! means, variances and the covariance of the first two species.

pub mod amen;
pub mod cp;
pub mod dense;
pub mod fsp;
pub mod kron;
pub mod model;
pub mod moments;
pub mod network;
pub mod pgd;
pub mod ssa;
pub mod tt;
pub mod tteval;
pub mod ttsolve;

pub use moments::Moments;
pub use network::{Network, NetworkError};
