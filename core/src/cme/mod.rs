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
//!
//! And the parametric meta-models, with unknown rates as extra coordinates:
//! - [`kron`], [`cp`], [`greedy`]: the generator in Kronecker form and the greedy
//!   minimal-residual PGD in canonical (CP) form over (species…, parameters…);
//! - [`ttsolve`]: BDF2 in time on tensor trains (AMEn for each step, from
//!   [`crate::tensor`]), with [`step`]'s error-controlled step size;
//! - [`history`]: the solution train over (time, species…, parameters…) and the
//!   Lagrange weights that read it; [`tteval`] evaluates it on-line, [`model`] wraps
//!   either form as one meta-model that a scene or `palpa cme eval` queries.
//!
//! - [`fit`]: rates from data: the likelihood of single-cell snapshots through a
//!   meta-model, its maximum, intervals and posterior.
//!
//! [`Moments`] holds what every solver reports at each output time: the marginals,
//! means, variances and the covariance of the first two species.

pub mod build;
pub mod conservation;
pub mod cp;
pub mod dsmts;
pub mod fit;
pub mod fsp;
pub mod greedy;
pub mod history;
pub mod kron;
pub mod model;
pub mod moments;
pub mod network;
pub mod sbml;
pub mod sizing;
pub mod ssa;
pub mod step;
pub mod tteval;
pub mod ttsolve;
pub mod views;

pub use moments::Moments;
pub use network::{Network, NetworkError};
