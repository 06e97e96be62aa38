//! The tool disk's consistent load on a triangulated surface, without the FE space.
//!
//! A probe of radius `r` centred at the surface point `s` spreads a unit force over
//! `Γ ∩ B(s, r)`. Its consistent nodal shares are `w_a = ∫_{Γ∩B} N_a dA / Σ_b ∫ N_b dA`
//! with the face shape functions `N_a` (P1: the barycentric coordinates; P2: corners
//! `λ_i(2λ_i − 1)` and midsides `4λ_iλ_j` on the edges 01, 12, 02). Each integral is a
//! one-point rule on `4^L` sub-triangles, `L` chosen so a sub-triangle is ≤ r/6 across,
//! so the shares move smoothly (up to that resolution) as `s` slides.
//!
//! Both the FE reference (`fe::load`) and the nodal-load parametric axis
//! ([`Discretization::SurfaceLoad`](crate::axis::Discretization::SurfaceLoad)) call
//! [`face_weights`], so the on-line particularization integrates exactly the disk the
//! full FE solve integrates.

use crate::mesh::{cross, norm, sub};

/// Edges of a triangle in the midside order of P2 faces.
pub const TRI_EDGES: [(usize, usize); 3] = [(0, 1), (1, 2), (0, 2)];

/// Values of the triangle's shape functions at barycentric `l` (3 or 6 entries).
pub fn tri_shape(p2: bool, l: [f64; 3], out: &mut [f64]) {
    simplex_shape(p2, l, &TRI_EDGES, out);
}

/// Lagrange shape functions of a simplex with `V` vertices at barycentric `l`: P1 the
/// coordinates themselves; P2 the vertices `λ_i(2λ_i − 1)`, then `4λ_iλ_j` on `edges`.
pub fn simplex_shape<const V: usize>(
    p2: bool,
    l: [f64; V],
    edges: &[(usize, usize)],
    out: &mut [f64],
) {
    if p2 {
        for i in 0..V {
            out[i] = l[i] * (2.0 * l[i] - 1.0);
        }
        for (e, &(i, j)) in edges.iter().enumerate() {
            out[V + e] = 4.0 * l[i] * l[j];
        }
    } else {
        out[..V].copy_from_slice(&l);
    }
}

/// `∫_{face ∩ B(center, r)} N_a dA` for the face's shape functions (3 corners, then 3
/// midsides for P2), unnormalized, into `acc`. Returns `false` (and leaves `acc`
/// untouched) when the face lies entirely outside the ball.
pub fn face_weights(
    c: [[f64; 3]; 3],
    p2: bool,
    center: [f64; 3],
    radius_mm: f64,
    acc: &mut [f64; 6],
) -> bool {
    // Skip faces entirely outside the ball (by their circumscribing distance).
    let cen = [0, 1, 2].map(|d| (c[0][d] + c[1][d] + c[2][d]) / 3.0);
    let rad = c.iter().map(|v| norm(sub(*v, cen))).fold(0.0, f64::max);
    if norm(sub(cen, center)) > radius_mm + rad {
        return false;
    }
    let npf = if p2 { 6 } else { 3 };
    let mut nvals = [0.0; 6];
    let area = 0.5 * norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
    let level = ((2.0 * rad * 6.0 / radius_mm).log2().ceil().max(0.0) as u32).min(7);
    let k = 1usize << level; // sub-triangles per edge; k² of them
    let sub_area = area / (k * k) as f64;
    *acc = [0.0; 6];
    for i in 0..k {
        for j in 0..k - i {
            // Upward sub-triangle centroid, then the downward one (if any).
            for (di, dj, up) in [(1.0 / 3.0, 1.0 / 3.0, true), (2.0 / 3.0, 2.0 / 3.0, false)] {
                if !up && i + j + 1 >= k {
                    continue;
                }
                let b1 = (i as f64 + di) / k as f64;
                let b2 = (j as f64 + dj) / k as f64;
                let l = [1.0 - b1 - b2, b1, b2];
                let x = [0, 1, 2].map(|d| l[0] * c[0][d] + l[1] * c[1][d] + l[2] * c[2][d]);
                if norm(sub(x, center)) <= radius_mm {
                    tri_shape(p2, l, &mut nvals);
                    for a in 0..npf {
                        acc[a] += nvals[a] * sub_area;
                    }
                }
            }
        }
    }
    true
}

/// Degree-`q` Lagrange basis on a triangle at barycentric `b`, over the lattice points
/// `(i, j, k)/q`, `i + j + k = q`, in the order of [`lattice`]. `out.len()` must be
/// `(q+1)(q+2)/2`. Silvester's form: `L_ijk = R_i(q b0) R_j(q b1) R_k(q b2)` with
/// `R_i(z) = Π_{a<i} (z − a)/(a + 1)`.
pub fn lagrange_tri(q: usize, b: [f64; 3], out: &mut [f64]) {
    let r = |i: usize, z: f64| -> f64 {
        let mut v = 1.0;
        for a in 0..i {
            v *= (z - a as f64) / (a + 1) as f64;
        }
        v
    };
    let qf = q as f64;
    let mut n = 0;
    for i in 0..=q {
        for j in 0..=q - i {
            let k = q - i - j;
            out[n] = r(i, qf * b[0]) * r(j, qf * b[1]) * r(k, qf * b[2]);
            n += 1;
        }
    }
}

/// The barycentric coordinates of the degree-`q` lattice, in [`lagrange_tri`]'s order.
pub fn lattice(q: usize) -> Vec<[f64; 3]> {
    let qf = q as f64;
    let mut out = Vec::with_capacity((q + 1) * (q + 2) / 2);
    for i in 0..=q {
        for j in 0..=q - i {
            let k = q - i - j;
            out.push([i as f64 / qf, j as f64 / qf, k as f64 / qf]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lagrange_is_nodal_and_reproduces_cubics() {
        for q in 1..=5 {
            let pts = lattice(q);
            let mut v = vec![0.0; pts.len()];
            for (a, p) in pts.iter().enumerate() {
                lagrange_tri(q, *p, &mut v);
                for (b, &x) in v.iter().enumerate() {
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!((x - want).abs() < 1e-12, "q {q} node {a} basis {b}: {x}");
                }
            }
            // A polynomial of degree ≤ q is reproduced at an off-lattice point.
            let f = |b: [f64; 3]| b[0].powi(q.min(3) as i32) + 0.5 * b[1] * b[2] - b[2];
            let at = [0.21, 0.33, 0.46];
            lagrange_tri(q, at, &mut v);
            let interp: f64 = pts.iter().zip(&v).map(|(p, w)| w * f(*p)).sum();
            if q >= 3 {
                assert!(
                    (interp - f(at)).abs() < 1e-12,
                    "q {q}: {interp} vs {}",
                    f(at)
                );
            }
        }
    }

    #[test]
    fn disk_shares_cover_a_face_inside_the_ball() {
        let c = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mut acc = [0.0; 6];
        assert!(face_weights(c, true, [0.3, 0.3, 0.0], 10.0, &mut acc));
        // Whole face inside: the shape functions sum to one at every quadrature
        // point, so the weights sum to the area exactly; midsides carry the load.
        let total: f64 = acc.iter().sum();
        assert!((total - 0.5).abs() < 1e-12, "total {total}");
        assert!(acc[3..].iter().all(|&w| w > 0.0), "{acc:?}");
        assert!(!face_weights(c, true, [30.0, 0.0, 0.0], 2.0, &mut acc));
    }
}
