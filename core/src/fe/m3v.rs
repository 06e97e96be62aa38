//! 3 × 3 matrices at four quadrature points at once, one value a lane: the operations of
//! [`super::m3`] on plain arrays the compiler turns into vector instructions, each lane
//! doing exactly the scalar operations in the scalar order (see [`super::lanes`]).

use super::m3::M3;

/// Quadrature points a group holds.
pub(crate) const L: usize = 4;
pub(crate) type V = [f64; L];
pub(crate) type M3V = [[V; 3]; 3];

pub(crate) const ZV: V = [0.0; L];
pub(crate) const ZERO: M3V = [[ZV; 3]; 3];
pub(crate) const ONE: V = [1.0; L];
pub(crate) const ID: M3V = [[ONE, ZV, ZV], [ZV, ONE, ZV], [ZV, ZV, ONE]];
/// The start of a scalar `Iterator::sum` of `f64`: `-0.0`, the additive identity that
/// keeps the sign of a sum of negative zeros (so the lanes agree to the last bit).
pub(crate) const SUM0: V = [-0.0; L];

#[inline(always)]
pub(crate) fn mul(a: &M3V, b: &M3V) -> M3V {
    let mut c = ZERO;
    for i in 0..3 {
        for j in 0..3 {
            for l in 0..L {
                c[i][j][l] =
                    a[i][0][l] * b[0][j][l] + a[i][1][l] * b[1][j][l] + a[i][2][l] * b[2][j][l];
            }
        }
    }
    c
}

#[inline(always)]
pub(crate) fn mul_tn(a: &M3V, b: &M3V) -> M3V {
    let mut c = ZERO;
    for i in 0..3 {
        for j in 0..3 {
            for l in 0..L {
                c[i][j][l] =
                    a[0][i][l] * b[0][j][l] + a[1][i][l] * b[1][j][l] + a[2][i][l] * b[2][j][l];
            }
        }
    }
    c
}

/// `acc += s a`, `s` one value a lane.
#[inline(always)]
pub(crate) fn add_scaled(acc: &mut M3V, s: &V, a: &M3V) {
    for i in 0..3 {
        for j in 0..3 {
            for l in 0..L {
                acc[i][j][l] += s[l] * a[i][j][l];
            }
        }
    }
}

/// `acc += a b` on the upper triangle only.
#[inline(always)]
pub(crate) fn add_upper(acc: &mut M3V, a: &M3V, b: &M3V) {
    for i in 0..3 {
        for j in i..3 {
            for l in 0..L {
                acc[i][j][l] +=
                    a[i][0][l] * b[0][j][l] + a[i][1][l] * b[1][j][l] + a[i][2][l] * b[2][j][l];
            }
        }
    }
}

pub(crate) fn lane(m: &M3V, l: usize) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = m[i][j][l];
        }
    }
    out
}

/// `det a` a lane, as [`super::m3::det`] computes it.
#[inline(always)]
pub(crate) fn det_v(a: &M3V) -> V {
    std::array::from_fn(|l| {
        a[0][0][l] * (a[1][1][l] * a[2][2][l] - a[1][2][l] * a[2][1][l])
            - a[0][1][l] * (a[1][0][l] * a[2][2][l] - a[1][2][l] * a[2][0][l])
            + a[0][2][l] * (a[1][0][l] * a[2][1][l] - a[1][1][l] * a[2][0][l])
    })
}
