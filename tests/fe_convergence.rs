//! Convergence on a manufactured solution: with u* smooth, body force b = −div σ(u*)
//! and u = u* on the whole boundary, the L2 error falls like h² for P1 and h³ for P2.

use palpa_core::fe::elasticity::{LinearProblem, dirichlet_lifting};
use palpa_core::fe::shape::{TET_DEGREE4, barycentric_gradients, tet_values};
use palpa_core::fe::space::Space;
use palpa_core::fe::{Element, Material};
use palpa_core::mesh::stuffing::{Implicit, stuff};

struct Cube;
impl Implicit for Cube {
    fn value(&self, p: [f64; 3]) -> f64 {
        p.iter()
            .map(|c| c.abs() - 1.0)
            .fold(f64::NEG_INFINITY, f64::max)
    }
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        ([-1.0; 3], [1.0; 3])
    }
}

const A: f64 = 0.01;

/// u* = A (φ, φ, φ), φ = sin x sin y sin z.
fn exact(p: [f64; 3]) -> [f64; 3] {
    let phi = p[0].sin() * p[1].sin() * p[2].sin();
    [A * phi; 3]
}

/// b = −(λ+μ) ∇(div u*) − μ Δu*, with Δφ = −3φ.
fn body_force(p: [f64; 3], lambda: f64, mu: f64) -> [f64; 3] {
    let (s, c) = (p.map(f64::sin), p.map(f64::cos));
    let phi = s[0] * s[1] * s[2];
    // ∂_i div u* / A = −φ + (sum of the two mixed terms with cos in i and one other).
    let grad_div = [
        -phi + c[0] * c[1] * s[2] + c[0] * s[1] * c[2],
        -phi + c[0] * c[1] * s[2] + s[0] * c[1] * c[2],
        -phi + c[0] * s[1] * c[2] + s[0] * c[1] * c[2],
    ];
    [0, 1, 2].map(|i| -(lambda + mu) * A * grad_div[i] + mu * 3.0 * A * phi)
}

fn relative_l2_error(h: f64, element: Element, material: Material) -> f64 {
    let (mesh, _) = stuff(&Cube, h);
    let boundary: Vec<[u32; 3]> = mesh.boundary_faces().into_iter().map(|f| f.0).collect();
    let mut on_boundary = vec![false; mesh.vertices.len()];
    for f in &boundary {
        for &v in f {
            on_boundary[v as usize] = true;
        }
    }
    let space = Space::new(&mesh, &boundary, &on_boundary, element);
    let (lambda, mu) = material.lame_n_per_mm2();
    let p2 = element == Element::P2;
    let npc = element.nodes_per_cell();
    // Consistent body-force load, degree-4 quadrature.
    let mut f = vec![0.0; 3 * space.nodes.len()];
    let mut n = [0.0; 10];
    for c in 0..space.cell_count() {
        let x = space.cell_corners(c);
        let (_, vol) = barycentric_gradients(x).expect("valid");
        for (l, w) in TET_DEGREE4.points.iter().zip(TET_DEGREE4.weights) {
            let p = [0, 1, 2].map(|d| (0..4).map(|i| l[i] * x[i][d]).sum::<f64>());
            let b = body_force(p, lambda, mu);
            tet_values(p2, *l, &mut n);
            for (a, &node) in space.cell(c).iter().enumerate() {
                for d in 0..3 {
                    f[3 * node as usize + d] += w * vol * n[a] * b[d];
                }
            }
        }
    }
    let problem = LinearProblem::new(&space, material).expect("SPD");
    let ud: Vec<f64> = space.nodes.iter().flat_map(|&p| exact(p)).collect();
    let mut rhs = dirichlet_lifting(&space, material, &ud);
    for (r, v) in rhs.iter_mut().zip(space.restrict(&f)) {
        *r += v;
    }
    let uf = problem.factor.solve(&rhs);
    let mut u = space.expand(&uf);
    for (nd, &fixed) in space.fixed.iter().enumerate() {
        if fixed {
            u[3 * nd..3 * nd + 3].copy_from_slice(&ud[3 * nd..3 * nd + 3]);
        }
    }
    let (mut err2, mut norm2) = (0.0, 0.0);
    for c in 0..space.cell_count() {
        let x = space.cell_corners(c);
        let (_, vol) = barycentric_gradients(x).expect("valid");
        for (l, w) in TET_DEGREE4.points.iter().zip(TET_DEGREE4.weights) {
            let p = [0, 1, 2].map(|d| (0..4).map(|i| l[i] * x[i][d]).sum::<f64>());
            tet_values(p2, *l, &mut n);
            let mut uh = [0.0; 3];
            for (a, &node) in space.cell(c).iter().enumerate().take(npc) {
                for d in 0..3 {
                    uh[d] += n[a] * u[3 * node as usize + d];
                }
            }
            let ue = exact(p);
            for d in 0..3 {
                err2 += w * vol * (uh[d] - ue[d]).powi(2);
                norm2 += w * vol * ue[d].powi(2);
            }
        }
    }
    (err2 / norm2).sqrt()
}

#[test]
fn l2_error_rates_are_two_for_p1_and_three_for_p2() {
    // ν = 0.3: the asymptotic rates without locking (locking is measured separately).
    let material = Material {
        young_kpa: 160.0,
        poisson: 0.3,
    };
    let hs = [0.5, 0.25];
    for (element, expected) in [(Element::P1, 2.0), (Element::P2, 3.0)] {
        let e: Vec<f64> = hs
            .iter()
            .map(|&h| relative_l2_error(h, element, material))
            .collect();
        let rate = (e[0] / e[1]).ln() / (hs[0] / hs[1]).ln();
        eprintln!("{element:?}: errors {e:?}, observed rate {rate:.2}");
        // Stuffed meshes are not uniform refinements: allow ±0.35 around the rate.
        assert!(
            (rate - expected).abs() < 0.35,
            "{element:?}: rate {rate}, errors {e:?}"
        );
    }
}
