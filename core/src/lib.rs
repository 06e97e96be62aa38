//! palpa-core: the numerical heart of palpa, with no graphics and no windowing.
//!
//! A PGD meta-model is a separated representation
//!
//! ```text
//! u(x, p_1..p_m) ≈ Σ_{k=1..N} X_k(x) · Π_j P_{j,k}(p_j)
//! ```
//!
//! computed once off-line and *evaluated* (never solved) on-line. This crate holds
//! - [`separated`]: the representation, particularization (parameters → coefficients)
//!   and reconstruction (coefficients → field rows), allocation-free on the hot path;
//! - [`axis`]: the discretization of one parameter axis (1-D grid, triangulated
//!   surface, discrete index, surface × direction) and its interpolation stencils;
//! - [`file`](mod@file): the meta-model file (magic, version, checksummed header and payload,
//!   atomic writes, a loader that never trusts a length it has not checked);
//! - [`kernels`]: the streaming dot products that bound on-line cost by memory bandwidth;
//! - [`synthetic`]: reproducible random models for benchmarks and tests;
//! - [`mesh`], [`organ`], [`surface_import`]: tetrahedral meshing (isosurface stuffing), the
//!   procedural liver with its regions, user OBJ/STL organs;
//! - [`fe`], [`export`]: the finite-element reference (P1/P2, linear and Saint
//!   Venant–Kirchhoff) and VTU / gmsh export;
//! - [`pgd`]: the off-line solvers of the liver vademecum (the PGD over tool loads, and
//!   the default nodal-load route with its hierarchical compression);
//! - [`disk`], [`nearfield`], [`farfield`]: the tool disk's nodal shares, and what a
//!   nodal-load vademecum stores beside its modes (dense near blocks, the compliance
//!   table, low-rank far blocks);
//! - [`tensor`]: general tensor algebra (dense QR/SVD, sparse 1-D factors, tensor
//!   trains, AMEn), below every model that uses it;
//! - [`cme`]: gene networks (TOML, separable propensities), the chemical master
//!   equation by exact finite state projection and by stochastic simulation, and its
//!   parametric meta-models (greedy PGD in CP form, BDF2 on tensor trains);
//! - [`scene`]: a vademecum prepared for palpation (surface rows, palpable map) and the
//!   contact law `F = d / c(s)` evaluated on nine rows.

// No `unwrap` on anything outside the tests: input errors are values ([`thiserror`]
// enums), and each remaining `expect` names the invariant that makes it unreachable
// from input (audited; the file readers are fuzzed).
#![cfg_attr(not(test), deny(clippy::unwrap_used))]

pub mod axis;
pub mod cme;
pub mod cpu;
pub mod disk;
pub mod export;
pub mod farfield;
pub mod fe;
pub mod file;
pub mod framed;
pub mod fsutil;
pub mod kernels;
pub mod mesh;
pub mod nearfield;
pub mod organ;
pub mod pgd;
pub mod quant16;
pub mod rng;
pub mod scalar;
pub mod scene;
pub mod separated;
pub mod surface_import;
pub mod synthetic;
pub mod tensor;
pub mod timing;
pub mod tissue;
pub mod visual;

pub use axis::{AxisError, Discretization, ParamValue, Stencil};
pub use file::{AnyModel, FileError};
pub use scalar::{Precision, Scalar};
pub use separated::{
    Axis, AxisInfo, ClampReport, EvalError, FieldInfo, Geometry, ModelError, ModelMeta, Provenance,
    SeparatedModel, TradeoffRow,
};
