//! General tensor algebra, below every model that uses it: no chemistry, no mechanics.
//!
//! - [`dense`]: thin QR and SVD of small dense blocks (faer), the building blocks of
//!   every truncation here and of the randomized SVD of the nodal vademecum;
//! - [`sparse1d`]: sparse 1-D factors (CSR) of Kronecker-structured operators;
//! - [`tt`]: tensor trains: cores, rounding, products, contractions;
//! - [`amen`]: the alternating minimal-energy solver for linear systems in tensor-train
//!   form with Kronecker-structured operators.

pub mod amen;
pub mod dense;
pub mod sparse1d;
pub mod tt;

pub use sparse1d::Sparse1d;
