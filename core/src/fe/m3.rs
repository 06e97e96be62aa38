//! 3 × 3 matrices at one quadrature point: the few operations the element kernels and
//! the material laws share (products, determinant, inverse), each written once.

/// A 3 × 3 matrix, row-major.
pub(crate) type M3 = [[f64; 3]; 3];

pub(crate) const ID: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
pub(crate) const ZERO: M3 = [[0.0; 3]; 3];

pub(crate) fn det(a: &M3) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// `a⁻¹` given `d = det a`.
pub(crate) fn inverse(a: &M3, d: f64) -> M3 {
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (i1, i2) = ((j + 1) % 3, (j + 2) % 3);
            let (j1, j2) = ((i + 1) % 3, (i + 2) % 3);
            inv[i][j] = (a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]) / d;
        }
    }
    inv
}

pub(crate) fn mul(a: &M3, b: &M3) -> M3 {
    let mut c = ZERO;
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

pub(crate) fn mul_tn(a: &M3, b: &M3) -> M3 {
    let mut c = ZERO;
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j];
        }
    }
    c
}

pub(crate) fn add_scaled(acc: &mut M3, s: f64, a: &M3) {
    for i in 0..3 {
        for j in 0..3 {
            acc[i][j] += s * a[i][j];
        }
    }
}

/// `acc += a b` on the upper triangle only (for sums known to be symmetric).
pub(crate) fn add_upper(acc: &mut M3, a: &M3, b: &M3) {
    for i in 0..3 {
        for j in i..3 {
            acc[i][j] += a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
}

/// Permutations of (0, 1, 2) with their signs (the determinant's six terms).
pub(crate) const PERMS: [([usize; 3], f64); 6] = [
    ([0, 1, 2], 1.0),
    ([1, 2, 0], 1.0),
    ([2, 0, 1], 1.0),
    ([0, 2, 1], -1.0),
    ([2, 1, 0], -1.0),
    ([1, 0, 2], -1.0),
];
