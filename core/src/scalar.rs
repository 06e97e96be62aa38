//! Storage precision of a meta-model's arrays.
//!
//! Modes may be stored as `f32` (half the bytes, half the memory traffic) or `f64`.
//! Evaluation always accumulates in `f64`, so an `f32` model loses only the rounding of
//! its stored entries (relative 2^-24 each), not a further error that grows with the
//! number of modes.

use serde::{Deserialize, Serialize};

/// Storage precision tag, written in the file header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F64 => 8,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Precision {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            other => Err(format!("unknown precision '{other}', expected f32 or f64")),
        }
    }
}

/// A storage scalar: `f32` or `f64`.
pub trait Scalar:
    bytemuck::Pod + Copy + Send + Sync + PartialEq + std::fmt::Debug + 'static
{
    const PRECISION: Precision;
    fn to_f64(self) -> f64;
    fn from_f64(v: f64) -> Self;
    /// Converts a little-endian stored value to native order (no-op on little-endian hosts).
    fn le_to_native(self) -> Self;
    /// `self + other` in the storage type (for reference kernels only).
    fn add(self, other: Self) -> Self;
}

impl Scalar for f32 {
    const PRECISION: Precision = Precision::F32;
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn le_to_native(self) -> Self {
        f32::from_bits(u32::from_le(self.to_bits()))
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self + other
    }
}

impl Scalar for f64 {
    const PRECISION: Precision = Precision::F64;
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn le_to_native(self) -> Self {
        f64::from_bits(u64::from_le(self.to_bits()))
    }
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self + other
    }
}
