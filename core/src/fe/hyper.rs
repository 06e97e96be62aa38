//! The element force and tangent of a hyperelastic law (Total Lagrangian), one
//! quadrature point at a time: the plain statement of the arithmetic that
//! [`super::lanes`] runs four points at a time.
//!
//! With `F = I + ∇u` (gradients in the reference configuration), `C = FᵀF` and the
//! Green strain `E = ½(C − I)`, a law ([`super::law`]: SVK, neo-Hookean) gives the
//! second Piola–Kirchhoff stress `S` and its material tangent `ℂ = ∂S/∂E`. Both laws
//! reduce to linear elasticity with the same λ, μ at small strain.
//!
//! ```text
//! internal force   f_int[a,i]      = ∫ (F S)_iK ∂_K N_a dV
//! tangent          K[(a,i),(b,k)]  = ∫ δ_ik ∇N_a·S·∇N_b dV                (geometric)
//!                                  + ∫ δE^(a,i) : ℂ : δE^(b,k) dV         (material)
//! with δE^(a,i)_JK = ½(F_iJ ∂_K N_a + F_iK ∂_J N_a).
//! ```
//!
//! Quadrature: degree 4 (Keast, 11 points) for P2; one point for P1 (constant
//! gradients). A quadrature point with `J ≤ 0` (an inverted element) makes the
//! neo-Hookean force non-finite, which the Newton line search rejects.

use super::Element;
use super::law::{HyperLaw, Law, PointState, with_law};
use super::m3::M3;
use super::shape::{TET_DEGREE1, TET_DEGREE4, barycentric_gradients, tet_gradients};
use super::space::Space;

impl Law {
    fn state(self, f: &M3, lambda: f64, mu: f64) -> PointState {
        let mut c: M3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                c[i][j] = (0..3).map(|k| f[k][i] * f[k][j]).sum();
            }
        }
        with_law!(self, L => L::state(f, &c, lambda, mu))
    }
}

/// Element internal force `fe` (3·npc) and, if asked, tangent `ke` (row-major) of cell
/// `c` at the all-node displacement `u`.
#[allow(clippy::too_many_arguments)]
pub fn element(
    space: &Space,
    law: Law,
    c: usize,
    u: &[f64],
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
    ke: Option<&mut [f64]>,
) {
    let (lambda, mu) = space.lame_in(c, lambda, mu);
    let p2 = space.element == Element::P2;
    let npc = space.element.nodes_per_cell();
    let m = 3 * npc;
    fe[..m].fill(0.0);
    let mut ke = ke;
    if let Some(k) = ke.as_deref_mut() {
        k[..m * m].fill(0.0);
    }
    let cell = space.cell(c);
    let (gl, vol) =
        barycentric_gradients(space.cell_corners(c)).expect("mesh has no degenerate tetrahedra");
    let rule = if p2 { &TET_DEGREE4 } else { &TET_DEGREE1 };
    let mut g = [[0.0; 3]; 10];
    let mut de = [[[0.0; 3]; 3]; 30];
    // Per dof: tr δE (SVK) or C⁻¹:δE (neo-Hookean), and C⁻¹ δE (neo-Hookean).
    let mut lin = [0.0; 30];
    let mut cde = [[[0.0; 3]; 3]; 30];
    for (l, w) in rule.points.iter().zip(rule.weights) {
        tet_gradients(p2, *l, &gl, &mut g);
        let wv = w * vol;
        // F = I + Σ_a u_a ⊗ g_a
        let mut f: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for a in 0..npc {
            let n = cell[a] as usize;
            for i in 0..3 {
                for j in 0..3 {
                    f[i][j] += u[3 * n + i] * g[a][j];
                }
            }
        }
        let st = law.state(&f, lambda, mu);
        let s = &st.s;
        // P = F S (first Piola–Kirchhoff)
        let mut p: M3 = [[0.0; 3]; 3];
        for i in 0..3 {
            for k in 0..3 {
                p[i][k] = (0..3).map(|j| f[i][j] * s[j][k]).sum();
            }
        }
        for a in 0..npc {
            for i in 0..3 {
                fe[3 * a + i] += wv * (0..3).map(|k| p[i][k] * g[a][k]).sum::<f64>();
            }
        }
        let Some(k) = ke.as_deref_mut() else { continue };
        for a in 0..npc {
            for i in 0..3 {
                let r = 3 * a + i;
                let d = &mut de[r];
                for jj in 0..3 {
                    for kk in 0..3 {
                        d[jj][kk] = 0.5 * (f[i][jj] * g[a][kk] + f[i][kk] * g[a][jj]);
                    }
                }
                with_law!(law, L => L::linearize(&st, d, &mut lin[r], &mut cde[r]));
            }
        }
        // The tangent is symmetric: fill the upper triangle (col ≥ r), mirror after.
        let sg: [[f64; 3]; 10] = std::array::from_fn(|a| {
            [0, 1, 2].map(|j| s[j][0] * g[a][0] + s[j][1] * g[a][1] + s[j][2] * g[a][2])
        });
        for r in 0..m {
            let (a, i) = (r / 3, r % 3);
            let (lr, dr, cr) = (lin[r], &de[r], &cde[r]);
            for col in r..m {
                let (b, kc) = (col / 3, col % 3);
                // δE_r : 𝕀 : δE_col (SVK) or δE_r : 𝕀_{C⁻¹} : δE_col
                // = tr(C⁻¹δE_r C⁻¹δE_col) (neo-Hookean).
                let mut dd = 0.0;
                with_law!(law, L => L::contract(dr, cr, &de[col], &cde[col], &mut dd));
                let mut v = wv * (lambda * lr * lin[col] + 2.0 * st.shear * dd);
                if i == kc {
                    v += wv * (g[b][0] * sg[a][0] + g[b][1] * sg[a][1] + g[b][2] * sg[a][2]);
                }
                k[r * m + col] += v;
            }
        }
    }
    if let Some(k) = ke {
        for r in 0..m {
            for col in 0..r {
                k[r * m + col] = k[col * m + r];
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::fe::Material;
    use crate::mesh::TetMesh;
    use crate::rng::Rng;

    /// One irregular tetrahedron.
    pub(crate) fn one_tet() -> TetMesh {
        TetMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [10.0, 1.0, 0.5],
                [1.0, 9.0, 0.0],
                [0.5, 1.0, 11.0],
            ],
            tets: vec![[0, 1, 2, 3]],
        }
    }

    /// [`one_tet`], nothing fixed (element-level checks).
    pub(crate) fn one_tet_space(element: Element) -> Space {
        Space::new(&one_tet(), &[], &[false; 4], element)
    }

    /// The tangent is the derivative of the internal force: central differences agree
    /// to O(ε²) at a random, moderately large deformation, for both laws.
    #[test]
    fn tangent_matches_finite_differences_of_the_internal_force() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        for law in [Law::Svk, Law::NeoHookean] {
            for kind in [Element::P1, Element::P2] {
                let space = one_tet_space(kind);
                let m = 3 * kind.nodes_per_cell();
                let mut rng = Rng::seed(5);
                // Moderate: the neo-Hookean law needs J > 0 at every quadrature point.
                let u: Vec<f64> = (0..m).map(|_| rng.range(-0.8, 0.8)).collect();
                let mut ke = vec![0.0; m * m];
                let mut fe = vec![0.0; m];
                element(&space, law, 0, &u, lambda, mu, &mut fe, Some(&mut ke));
                assert!(fe.iter().all(|v| v.is_finite()), "{law:?}: J > 0 here");
                let eps = 1e-5;
                let mut worst: f64 = 0.0;
                let scale = ke.iter().fold(0.0f64, |a, b| a.max(b.abs()));
                for j in 0..m {
                    let mut up = u.clone();
                    let mut dn = u.clone();
                    up[j] += eps;
                    dn[j] -= eps;
                    let (mut fp, mut fm) = (vec![0.0; m], vec![0.0; m]);
                    element(&space, law, 0, &up, lambda, mu, &mut fp, None);
                    element(&space, law, 0, &dn, lambda, mu, &mut fm, None);
                    for i in 0..m {
                        let fd = (fp[i] - fm[i]) / (2.0 * eps);
                        worst = worst.max((fd - ke[i * m + j]).abs());
                    }
                }
                assert!(
                    worst < 1e-7 * scale,
                    "{law:?} {kind:?}: worst {worst:e}, scale {scale:e}"
                );
                for i in 0..m {
                    for j in 0..m {
                        assert!((ke[i * m + j] - ke[j * m + i]).abs() <= 1e-12 * scale);
                    }
                }
            }
        }
    }

    /// At small strain both laws are linear elasticity: the same tangent at u = 0.
    #[test]
    fn both_laws_share_the_linear_tangent_at_rest() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        let space = one_tet_space(Element::P2);
        let m = 30;
        let u = vec![0.0; m];
        let (mut k1, mut k2, mut fe) = (vec![0.0; m * m], vec![0.0; m * m], vec![0.0; m]);
        element(&space, Law::Svk, 0, &u, lambda, mu, &mut fe, Some(&mut k1));
        assert!(fe.iter().all(|&v| v.abs() < 1e-15));
        element(
            &space,
            Law::NeoHookean,
            0,
            &u,
            lambda,
            mu,
            &mut fe,
            Some(&mut k2),
        );
        assert!(fe.iter().all(|&v| v.abs() < 1e-12));
        let scale = k1.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        for (a, b) in k1.iter().zip(&k2) {
            assert!((a - b).abs() <= 1e-10 * scale);
        }
    }

    /// An inverted element makes the neo-Hookean force non-finite (never a silent
    /// answer from a folded tetrahedron).
    #[test]
    fn an_inverted_element_is_not_finite_for_neo_hookean() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        let space = one_tet_space(Element::P1);
        // Push the apex through the base: J < 0.
        let mut u = vec![0.0; 12];
        u[11] = -20.0;
        let mut fe = vec![0.0; 12];
        element(&space, Law::NeoHookean, 0, &u, lambda, mu, &mut fe, None);
        assert!(fe.iter().any(|v| !v.is_finite()));
        element(&space, Law::Svk, 0, &u, lambda, mu, &mut fe, None);
        assert!(fe.iter().all(|v| v.is_finite()));
    }
}
