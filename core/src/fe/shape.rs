//! Shape functions in barycentric coordinates and quadrature rules.
//!
//! Tetrahedron, barycentric `λ_0..λ_3` (Σ λ = 1). P1: `N_i = λ_i`. P2 (VTK `tetra10`
//! order): corners `N_i = λ_i(2λ_i − 1)`, then edges (0,1), (1,2), (0,2), (0,3), (1,3),
//! (2,3) with `N_ij = 4 λ_i λ_j`. Triangle faces likewise: corners, then edges (0,1),
//! (1,2), (0,2).

/// Edges of a tetrahedron in VTK `tetra10` order.
pub const TET_EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];
/// Edges of a triangle in VTK `quadratic_triangle` order.
pub use crate::disk::TRI_EDGES;

/// Values of the tetrahedron's shape functions at barycentric `l` (4 or 10 entries).
pub fn tet_values(p2: bool, l: [f64; 4], out: &mut [f64]) {
    crate::disk::simplex_shape(p2, l, &TET_EDGES, out);
}

/// Physical gradients of the shape functions at barycentric `l`, given the
/// (constant, straight-sided) barycentric gradients `gl`.
pub fn tet_gradients(p2: bool, l: [f64; 4], gl: &[[f64; 3]; 4], out: &mut [[f64; 3]]) {
    if p2 {
        for i in 0..4 {
            out[i] = gl[i].map(|g| (4.0 * l[i] - 1.0) * g);
        }
        for (e, &(i, j)) in TET_EDGES.iter().enumerate() {
            out[4 + e] = [0, 1, 2].map(|d| 4.0 * (l[i] * gl[j][d] + l[j] * gl[i][d]));
        }
    } else {
        out[..4].copy_from_slice(gl);
    }
}

/// Values of the triangle's shape functions at barycentric `l` (3 or 6 entries).
pub fn tri_values(p2: bool, l: [f64; 3], out: &mut [f64]) {
    crate::disk::tri_shape(p2, l, out);
}

/// Barycentric gradients of a straight tetrahedron and its volume.
/// `None` for a degenerate (zero-volume) tetrahedron.
pub fn barycentric_gradients(x: [[f64; 3]; 4]) -> Option<([[f64; 3]; 4], f64)> {
    use crate::mesh::{cross, dot, sub};
    let a = sub(x[1], x[0]);
    let b = sub(x[2], x[0]);
    let c = sub(x[3], x[0]);
    let det = dot(a, cross(b, c));
    if det.abs() < 1e-300 {
        return None;
    }
    // Rows of J⁻¹ for J = [a b c] (columns): (b×c, c×a, a×b) / det.
    let g1 = cross(b, c).map(|v| v / det);
    let g2 = cross(c, a).map(|v| v / det);
    let g3 = cross(a, b).map(|v| v / det);
    let g0 = [0, 1, 2].map(|d| -(g1[d] + g2[d] + g3[d]));
    Some(([g0, g1, g2, g3], det / 6.0))
}

/// A quadrature rule on the tetrahedron: barycentric points and weights summing to 1
/// (multiply by the volume).
#[derive(Debug)]
pub struct TetRule {
    pub points: &'static [[f64; 4]],
    pub weights: &'static [f64],
}

const A4: f64 = 0.585_410_196_624_968_5;
const B4: f64 = 0.138_196_601_125_010_5;
/// Degree 2, 4 points: exact for the P2 stiffness on straight tetrahedra.
pub const TET_DEGREE2: TetRule = TetRule {
    points: &[
        [A4, B4, B4, B4],
        [B4, A4, B4, B4],
        [B4, B4, A4, B4],
        [B4, B4, B4, A4],
    ],
    weights: &[0.25, 0.25, 0.25, 0.25],
};
/// Degree 1, 1 point (P1 stiffness).
pub const TET_DEGREE1: TetRule = TetRule {
    points: &[[0.25, 0.25, 0.25, 0.25]],
    weights: &[1.0],
};

/// Keast's 11-point degree-4 rule (for the SVK internal forces and errors).
const K1: f64 = 0.071_428_571_428_571_4; // 1/14
const K2: f64 = 0.785_714_285_714_285_7; // 11/14
const K3: f64 = 0.399_403_576_166_799_2;
const K4: f64 = 0.100_596_423_833_200_8;
const W0: f64 = -0.078_933_333_333_333_3;
const W1: f64 = 0.045_733_333_333_333_3;
const W2: f64 = 0.149_333_333_333_333_3;
pub const TET_DEGREE4: TetRule = TetRule {
    points: &[
        [0.25, 0.25, 0.25, 0.25],
        [K2, K1, K1, K1],
        [K1, K2, K1, K1],
        [K1, K1, K2, K1],
        [K1, K1, K1, K2],
        [K3, K3, K4, K4],
        [K3, K4, K3, K4],
        [K3, K4, K4, K3],
        [K4, K3, K3, K4],
        [K4, K3, K4, K3],
        [K4, K4, K3, K3],
    ],
    weights: &[W0, W1, W1, W1, W1, W2, W2, W2, W2, W2, W2],
};

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ over the unit tetrahedron of λ0^a λ1^b λ2^c λ3^d = a!b!c!d! 3! / (a+b+c+d+3)! · V.
    fn exact_monomial(e: [u32; 4]) -> f64 {
        let f = |n: u32| (1..=n).map(f64::from).product::<f64>();
        f(e[0]) * f(e[1]) * f(e[2]) * f(e[3]) * 6.0 / f(e.iter().sum::<u32>() + 3)
    }

    #[test]
    fn rules_integrate_their_degree_exactly() {
        for (rule, deg) in [(TET_DEGREE1, 1), (TET_DEGREE2, 2), (TET_DEGREE4, 4)] {
            assert!((rule.weights.iter().sum::<f64>() - 1.0).abs() < 1e-14);
            for a in 0..=deg {
                for b in 0..=deg - a {
                    for c in 0..=deg - a - b {
                        let e = [a, b, c, 0];
                        let q: f64 = rule
                            .points
                            .iter()
                            .zip(rule.weights)
                            .map(|(p, w)| {
                                w * (0..4).map(|i| p[i].powi(e[i] as i32)).product::<f64>()
                            })
                            .sum();
                        let ex = exact_monomial(e);
                        assert!(
                            (q - ex).abs() < 1e-12,
                            "degree {deg}, exponents {e:?}: {q} vs {ex}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn p2_values_partition_unity_and_gradients_sum_to_zero() {
        let x = [
            [0.0, 0.0, 0.0],
            [2.0, 0.1, 0.0],
            [0.3, 1.5, 0.2],
            [0.1, 0.2, 1.7],
        ];
        let (gl, vol) = barycentric_gradients(x).expect("non-degenerate");
        assert!(vol > 0.0);
        let l = [0.1, 0.2, 0.3, 0.4];
        let mut n = [0.0; 10];
        tet_values(true, l, &mut n);
        assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let mut g = [[0.0; 3]; 10];
        tet_gradients(true, l, &gl, &mut g);
        for d in 0..3 {
            assert!(g.iter().map(|v| v[d]).sum::<f64>().abs() < 1e-13);
        }
    }
}
