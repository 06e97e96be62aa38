//! The depth series' right-hand sides ([`super::series`]) four quadrature points at a
//! time, the same arithmetic in vector lanes.
//!
//! Order `p`'s right-hand side `N_p` is the costliest part of a press: at every
//! quadrature point it forms the series of `F`, `C = FᵀF`, `J = det F`, `ln J`, `C⁻¹`
//! and `S` to index `p` (`O(p²)` products of 3 × 3 matrices), and the scalar code did
//! that one point after another, one multiply at a time: about 30 % of a whole-surface
//! tissue build's time. A P2 cell's eleven degree-4 points are independent, so here
//! they are laid out as three groups of four lanes (the twelfth lane repeats the
//! centroid with weight zero and is never added) and every scalar operation of
//! [`super::series::element_coefficient`] becomes the same operation on four lanes.
//!
//! **The same numbers.** Each lane performs exactly the scalar code's operations in
//! the scalar code's order (no fused multiply-add: Rust does not contract `a * b + c`),
//! and the cell's force sums the points' contributions in the rule's order, so the
//! result is the scalar one bit for bit; a unit test checks that on random states, both
//! laws, about the rest state and about a deformed one. The lanes are plain arrays
//! that the compiler turns into vector instructions: [`pulp::Arch::dispatch`] runs the
//! kernel compiled for the widest instruction set the CPU has (AVX2 with 256-bit
//! registers here), with no `unsafe` code of ours.

use super::Element;
use super::law::{HyperLaw, Law, with_law};
use super::m3v::{ID, L, M3V, ONE, V, ZERO, ZV, add_scaled, mul, mul_tn};
use super::shape::{TET_DEGREE1, TET_DEGREE4, barycentric_gradients};
use super::space::Space;

/// The most orders a depth series may ask for (the kernels' series arrays hold this
/// many and the constant term). The builds use 12–15; order `p`'s
/// right-hand side costs `O(p²)` products a quadrature point, so 30 orders already cost
/// several times the default series (200 ran past 100 s on coarse P2, unfinished).
pub const MAX_ORDERS: usize = 30;
const SERIES_LEN: usize = MAX_ORDERS + 1;
/// Room for the builds' series (12 orders and the constant term).
const SHORT: usize = 13;

/// [`super::series`]'s `stress_series`, four points a call.
#[inline(always)]
fn stress_series<const N: usize>(
    law: Law,
    f: &[M3V; N],
    p: usize,
    lambda: f64,
    mu: f64,
    s: &mut [M3V; N],
) {
    // Lets the compiler drop the bounds checks of every `k ≤ p` index below.
    assert!(p < N);
    let mut c = [ZERO; N];
    for (k, ck) in c.iter_mut().enumerate().take(p + 1) {
        let mut acc = ZERO;
        for i in 0..k.div_ceil(2) {
            add_scaled(&mut acc, &ONE, &mul_tn(&f[i], &f[k - i]));
        }
        for a in 0..3 {
            for b in 0..3 {
                for l in 0..L {
                    ck[a][b][l] = acc[a][b][l] + acc[b][a][l];
                }
            }
        }
        if k % 2 == 0 {
            add_scaled(ck, &ONE, &mul_tn(&f[k / 2], &f[k / 2]));
        }
    }
    with_law!(law, L => L::stress_series_v(f, &c, p, lambda, mu, s));
}

/// The lanes' barycentric coordinates and weights for a rule of `n` points, in groups
/// of four (the last group padded with the first point at weight zero).
struct Groups {
    points: Vec<[V; 4]>,
    weights: Vec<V>,
    /// Real points in each group.
    counts: Vec<usize>,
}

static GROUPS_P2: std::sync::LazyLock<Groups> =
    std::sync::LazyLock::new(|| groups(TET_DEGREE4.points, TET_DEGREE4.weights));
static GROUPS_P1: std::sync::LazyLock<Groups> =
    std::sync::LazyLock::new(|| groups(TET_DEGREE1.points, TET_DEGREE1.weights));

fn groups(points: &[[f64; 4]], weights: &[f64]) -> Groups {
    let n = points.len();
    let g = n.div_ceil(L);
    let mut out = Groups {
        points: Vec::with_capacity(g),
        weights: Vec::with_capacity(g),
        counts: Vec::with_capacity(g),
    };
    for q in 0..g {
        let idx = |l: usize| (q * L + l).min(n - 1);
        let real = |l: usize| q * L + l < n;
        out.points.push(std::array::from_fn(|b| {
            std::array::from_fn(|l| points[if real(l) { idx(l) } else { 0 }][b])
        }));
        out.weights.push(std::array::from_fn(|l| {
            if real(l) { weights[idx(l)] } else { 0.0 }
        }));
        out.counts.push((n - q * L).min(L));
    }
    out
}

/// [`super::series::element_coefficient`], the same numbers bit for bit, its
/// quadrature points in vector lanes.
#[allow(clippy::too_many_arguments)]
pub fn element_coefficient(
    space: &Space,
    law: Law,
    c: usize,
    base: Option<&[f64]>,
    lower: &[Vec<f64>],
    p: usize,
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
) {
    assert!(
        p <= MAX_ORDERS,
        "a series of {p} orders (at most {MAX_ORDERS})"
    );
    let (lambda, mu) = space.lame_in(c, lambda, mu);
    pulp::Arch::new().dispatch(Kernel {
        space,
        law,
        c,
        base,
        lower,
        p,
        lambda,
        mu,
        fe,
    });
}

/// The kernel's arguments, so that [`pulp::Arch::dispatch`] inlines the whole body
/// into its function compiled for the CPU's instruction set (a closure there was
/// compiled apart, for baseline x86-64: no vector registers, measured).
struct Kernel<'a> {
    space: &'a Space,
    law: Law,
    c: usize,
    base: Option<&'a [f64]>,
    lower: &'a [Vec<f64>],
    p: usize,
    lambda: f64,
    mu: f64,
    fe: &'a mut [f64],
}

impl pulp::WithSimd for Kernel<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Kernel {
            space,
            law,
            c,
            base,
            lower,
            p,
            lambda,
            mu,
            fe,
        } = self;
        // Series arrays sized to the order (zeroing 31 orders' room at every call
        // cost more than the arithmetic at the builds' 6–12 orders).
        if p < SHORT {
            element_coefficient_lanes::<SHORT>(space, law, c, base, lower, p, lambda, mu, fe);
        } else {
            element_coefficient_lanes::<SERIES_LEN>(space, law, c, base, lower, p, lambda, mu, fe);
        }
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn element_coefficient_lanes<const N: usize>(
    space: &Space,
    law: Law,
    c: usize,
    base: Option<&[f64]>,
    lower: &[Vec<f64>],
    p: usize,
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
) {
    let geo = Geometry::new(space, c);
    let (p2, npc, gl, vol) = (geo.p2, geo.npc, geo.gl, geo.vol);
    fe[..3 * npc].fill(0.0);
    let groups = geo.groups();
    // The cell's nodal values of u_0 and of each lower order (gathered once a cell).
    let mut nodal = [[[0.0; 3]; 10]; N];
    if let Some(u) = base {
        nodal[0] = geo.gather(space, c, u);
    }
    for k in 1..p {
        nodal[k] = geo.gather(space, c, &lower[k - 1]);
    }
    let mut g = [[ZV; 3]; 10];
    let mut f = [ZERO; N];
    let mut s = [ZERO; N];
    for ((l, w), &count) in groups
        .points
        .iter()
        .zip(&groups.weights)
        .zip(&groups.counts)
    {
        gradients(p2, l, &gl, &mut g);
        f[0] = ID;
        if base.is_some() {
            add_gradient(&mut f[0], &nodal[0], &g, npc);
        }
        for k in 1..=p {
            let mut h = ZERO;
            if k < p {
                add_gradient(&mut h, &nodal[k], &g, npc);
            }
            f[k] = h;
        }
        stress_series::<N>(law, &f, p, lambda, mu, &mut s);
        let mut pp = ZERO;
        for i in 0..=p {
            add_scaled(&mut pp, &ONE, &mul(&f[i], &s[p - i]));
        }
        add_points(fe, &pp, &g, (w, vol), npc, count);
    }
}

/// [`super::hyper::element`]'s internal force (no tangent), the same numbers bit for
/// bit, its quadrature points in vector lanes: the residual of every chord step.
pub fn element_force(
    space: &Space,
    law: Law,
    c: usize,
    u: &[f64],
    lambda: f64,
    mu: f64,
    fe: &mut [f64],
) {
    pulp::Arch::new().dispatch(StateKernel {
        cell: CellState::new(space, law, c, u, lambda, mu),
        out: Out::Force(fe),
    });
}

/// [`super::hyper::element`]'s tangent `ke` (row-major, `3·npc` square), the same
/// numbers bit for bit, its quadrature points in vector lanes: every segment's and
/// Newton iteration's tangent.
pub fn element_tangent(
    space: &Space,
    law: Law,
    c: usize,
    u: &[f64],
    lambda: f64,
    mu: f64,
    ke: &mut [f64],
) {
    pulp::Arch::new().dispatch(StateKernel {
        cell: CellState::new(space, law, c, u, lambda, mu),
        out: Out::Tangent(ke),
    });
}

/// A cell's element kind, corner gradients and volume: what every kernel starts from.
struct Geometry {
    p2: bool,
    npc: usize,
    gl: [[f64; 3]; 4],
    vol: f64,
}

impl Geometry {
    fn new(space: &Space, c: usize) -> Self {
        let (gl, vol) = barycentric_gradients(space.cell_corners(c))
            .expect("mesh has no degenerate tetrahedra");
        Geometry {
            p2: space.element == Element::P2,
            npc: space.element.nodes_per_cell(),
            gl,
            vol,
        }
    }

    fn groups(&self) -> &'static Groups {
        if self.p2 { &GROUPS_P2 } else { &GROUPS_P1 }
    }

    /// Cell `c`'s nodal values of the all-node vector `u`.
    fn gather(&self, space: &Space, c: usize, u: &[f64]) -> [[f64; 3]; 10] {
        let mut nodal = [[0.0; 3]; 10];
        for (a, &n) in space.cell(c).iter().enumerate().take(self.npc) {
            let n = n as usize;
            nodal[a] = [u[3 * n], u[3 * n + 1], u[3 * n + 2]];
        }
        nodal
    }
}

/// A cell at a displacement: what the force and the tangent both start from.
struct CellState {
    law: Law,
    geo: Geometry,
    /// The cell's nodal displacements.
    nodal: [[f64; 3]; 10],
    lambda: f64,
    mu: f64,
}

impl CellState {
    fn new(space: &Space, law: Law, c: usize, u: &[f64], lambda: f64, mu: f64) -> Self {
        let (lambda, mu) = space.lame_in(c, lambda, mu);
        let geo = Geometry::new(space, c);
        let nodal = geo.gather(space, c, u);
        CellState {
            law,
            geo,
            nodal,
            lambda,
            mu,
        }
    }

    /// At a group of points: the shape gradients (into `g`), `F` and the law's state.
    #[inline(always)]
    fn at(&self, l: &[V; 4], g: &mut [[V; 3]; 10]) -> (M3V, (M3V, M3V, V)) {
        gradients(self.geo.p2, l, &self.geo.gl, g);
        let mut f = ID;
        add_gradient(&mut f, &self.nodal, g, self.geo.npc);
        let st = state(self.law, &f, self.lambda, self.mu);
        (f, st)
    }
}

enum Out<'a> {
    Force(&'a mut [f64]),
    Tangent(&'a mut [f64]),
}

/// The force or tangent kernel's arguments, so that [`pulp::Arch::dispatch`] inlines
/// the whole body (see [`Kernel`]).
struct StateKernel<'a> {
    cell: CellState,
    out: Out<'a>,
}

impl pulp::WithSimd for StateKernel<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        match self.out {
            Out::Force(fe) => element_force_lanes(&self.cell, fe),
            Out::Tangent(ke) => element_tangent_lanes(&self.cell, ke),
        }
    }
}

#[inline(always)]
fn element_force_lanes(cell: &CellState, fe: &mut [f64]) {
    let npc = cell.geo.npc;
    fe[..3 * npc].fill(0.0);
    let groups = cell.geo.groups();
    let mut g = [[ZV; 3]; 10];
    for ((l, w), &count) in groups
        .points
        .iter()
        .zip(&groups.weights)
        .zip(&groups.counts)
    {
        let (f, (s, _, _)) = cell.at(l, &mut g);
        add_points(fe, &mul(&f, &s), &g, (w, cell.geo.vol), npc, count);
    }
}

/// `Law::state` of [`super::hyper`] in lanes: `S`, `C⁻¹` (neo-Hookean; zero for SVK)
/// and the factor `μ − λ ln J` (`μ` for SVK).
#[inline(always)]
fn state(law: Law, f: &M3V, lambda: f64, mu: f64) -> (M3V, M3V, V) {
    let mut c = ZERO;
    for i in 0..3 {
        for j in 0..3 {
            for l in 0..L {
                c[i][j][l] =
                    f[0][i][l] * f[0][j][l] + f[1][i][l] * f[1][j][l] + f[2][i][l] * f[2][j][l];
            }
        }
    }
    let mut s = ZERO;
    let mut ci = ZERO;
    let mut shear = [mu; L];
    with_law!(law, L => L::state_v(f, &c, lambda, mu, &mut s, &mut ci, &mut shear));
    (s, ci, shear)
}

#[inline(always)]
fn element_tangent_lanes(cell: &CellState, k: &mut [f64]) {
    let (law, lambda, npc) = (cell.law, cell.lambda, cell.geo.npc);
    let m = 3 * npc;
    k[..m * m].fill(0.0);
    let groups = cell.geo.groups();
    let mut g = [[ZV; 3]; 10];
    let mut de = [ZERO; 30];
    let mut lin = [ZV; 30];
    let mut cde = [ZERO; 30];
    for ((l, w), &count) in groups
        .points
        .iter()
        .zip(&groups.weights)
        .zip(&groups.counts)
    {
        let wv: V = std::array::from_fn(|q| w[q] * cell.geo.vol);
        let (f, (s, ci, shear)) = cell.at(l, &mut g);
        for a in 0..npc {
            for i in 0..3 {
                let r = 3 * a + i;
                let d = &mut de[r];
                for jj in 0..3 {
                    for kk in 0..3 {
                        for q in 0..L {
                            d[jj][kk][q] =
                                0.5 * (f[i][jj][q] * g[a][kk][q] + f[i][kk][q] * g[a][jj][q]);
                        }
                    }
                }
                with_law!(law, L => L::linearize_v(&ci, d, &mut lin[r], &mut cde[r]));
            }
        }
        let mut sg = [[ZV; 3]; 10];
        for a in 0..npc {
            for j in 0..3 {
                for q in 0..L {
                    sg[a][j][q] =
                        s[j][0][q] * g[a][0][q] + s[j][1][q] * g[a][1][q] + s[j][2][q] * g[a][2][q];
                }
            }
        }
        let lw: V = [lambda; L];
        let sh2: V = std::array::from_fn(|q| 2.0 * shear[q]);
        for r in 0..m {
            let (a, i) = (r / 3, r % 3);
            let (dr, cr) = (&de[r], &cde[r]);
            let lr: V = std::array::from_fn(|q| lw[q] * lin[r][q]);
            for col in r..m {
                let (b, kc) = (col / 3, col % 3);
                let mut dd = ZV;
                with_law!(law, L => L::contract_v(dr, cr, &de[col], &cde[col], &mut dd));
                let mut v: V =
                    std::array::from_fn(|q| wv[q] * (lr[q] * lin[col][q] + sh2[q] * dd[q]));
                if i == kc {
                    for q in 0..L {
                        v[q] += wv[q]
                            * (g[b][0][q] * sg[a][0][q]
                                + g[b][1][q] * sg[a][1][q]
                                + g[b][2][q] * sg[a][2][q]);
                    }
                }
                for vq in &v[..count] {
                    k[r * m + col] += vq;
                }
            }
        }
    }
    for r in 0..m {
        for col in 0..r {
            k[r * m + col] = k[col * m + r];
        }
    }
}

/// `fe[a, i] += w vol Σ_K P[i][K] ∂_K N_a` for the group's first `count` points, added
/// point by point in the rule's order as the scalar loop adds them.
#[inline(always)]
fn add_points(
    fe: &mut [f64],
    p: &M3V,
    g: &[[V; 3]; 10],
    (w, vol): (&V, f64),
    npc: usize,
    count: usize,
) {
    let mut contrib = [[ZV; 3]; 10];
    for a in 0..npc {
        for i in 0..3 {
            for q in 0..L {
                let wv = w[q] * vol;
                contrib[a][i][q] = wv
                    * (p[i][0][q] * g[a][0][q] + p[i][1][q] * g[a][1][q] + p[i][2][q] * g[a][2][q]);
            }
        }
    }
    for q in 0..count {
        for a in 0..npc {
            for i in 0..3 {
                fe[3 * a + i] += contrib[a][i][q];
            }
        }
    }
}

/// `h += Σ_a u_a ⊗ ∇N_a`, the nodes in order (as the scalar loop sums them).
#[inline(always)]
fn add_gradient(h: &mut M3V, u: &[[f64; 3]; 10], g: &[[V; 3]; 10], npc: usize) {
    for a in 0..npc {
        for i in 0..3 {
            for j in 0..3 {
                for l in 0..L {
                    h[i][j][l] += u[a][i] * g[a][j][l];
                }
            }
        }
    }
}

/// [`super::shape::tet_gradients`] at four points.
#[inline(always)]
fn gradients(p2: bool, l: &[V; 4], gl: &[[f64; 3]; 4], out: &mut [[V; 3]; 10]) {
    if p2 {
        for i in 0..4 {
            for d in 0..3 {
                for q in 0..L {
                    out[i][d][q] = (4.0 * l[i][q] - 1.0) * gl[i][d];
                }
            }
        }
        for (e, &(i, j)) in super::shape::TET_EDGES.iter().enumerate() {
            for d in 0..3 {
                for q in 0..L {
                    out[4 + e][d][q] = 4.0 * (l[i][q] * gl[j][d] + l[j][q] * gl[i][d]);
                }
            }
        }
    } else {
        for i in 0..4 {
            for d in 0..3 {
                out[i][d] = [gl[i][d]; L];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fe::Material;
    use crate::fe::hyper::tests::one_tet_space;
    use crate::rng::Rng;

    /// Random orders and bases on the test tetrahedron: the lanes give the scalar
    /// numbers exactly, for both laws and elements, every order up to twelve, and a
    /// crushed base (inverted at some points: NaN in both).
    #[test]
    fn lanes_match_the_scalar_coefficient_bit_for_bit() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        let mut nan_rows = 0;
        for kind in [Element::P1, Element::P2] {
            let space = one_tet_space(kind);
            let m = 3 * kind.nodes_per_cell();
            let mut rng = Rng::seed(31);
            for _trial in 0..4 {
                let lower: Vec<Vec<f64>> = (0..12)
                    .map(|_| (0..m).map(|_| rng.range(-0.3, 0.3)).collect())
                    .collect();
                let deformed: Vec<f64> = (0..m).map(|_| rng.range(-0.4, 0.4)).collect();
                let crushed: Vec<f64> = (0..m).map(|_| rng.range(-12.0, 12.0)).collect();
                for law in [Law::Svk, Law::NeoHookean] {
                    for base in [None, Some(&deformed[..]), Some(&crushed[..])] {
                        for p in 1..=12 {
                            let mut want = vec![0.0; m];
                            let mut got = vec![0.0; m];
                            let lw = &lower[..p - 1];
                            crate::fe::series::element_coefficient(
                                &space, law, 0, base, lw, p, lambda, mu, &mut want,
                            );
                            element_coefficient(&space, law, 0, base, lw, p, lambda, mu, &mut got);
                            for r in 0..m {
                                nan_rows += usize::from(want[r].is_nan());
                                assert!(
                                    want[r].to_bits() == got[r].to_bits()
                                        || (want[r].is_nan() && got[r].is_nan()),
                                    "{law:?} {kind:?} base {} order {p} row {r}: {} against {}",
                                    base.is_some(),
                                    got[r],
                                    want[r]
                                );
                            }
                        }
                    }
                }
            }
        }
        assert!(
            nan_rows > 0,
            "the crushed bases invert the tetrahedron somewhere"
        );
    }

    /// The internal force and the tangent in lanes are the scalar ones bit for bit
    /// (every entry), both laws and elements, moderate and crushed states (NaN in
    /// both).
    #[test]
    fn lanes_match_the_scalar_force_and_tangent_bit_for_bit() {
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        let mut nan_entries = 0;
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for kind in [Element::P1, Element::P2] {
            let space = one_tet_space(kind);
            let m = 3 * kind.nodes_per_cell();
            let mut rng = Rng::seed(32);
            for trial in 0..40 {
                let size = if trial % 4 == 3 { 12.0 } else { 0.8 };
                let u: Vec<f64> = (0..m).map(|_| rng.range(-size, size)).collect();
                for law in [Law::Svk, Law::NeoHookean] {
                    let (mut fe, mut ke) = (vec![0.0; m], vec![0.0; m * m]);
                    let hyper = crate::fe::hyper::element;
                    hyper(&space, law, 0, &u, lambda, mu, &mut fe, Some(&mut ke));
                    let (mut got_fe, mut got_ke) = (vec![7.0; m], vec![7.0; m * m]);
                    element_force(&space, law, 0, &u, lambda, mu, &mut got_fe);
                    element_tangent(&space, law, 0, &u, lambda, mu, &mut got_ke);
                    for (what, want, got) in [("force", &fe, &got_fe), ("tangent", &ke, &got_ke)] {
                        for (r, (&w, &g)) in want.iter().zip(got).enumerate() {
                            nan_entries += usize::from(w.is_nan());
                            assert!(
                                same(w, g),
                                "{law:?} {kind:?} trial {trial} {what} entry {r}: {g} against {w}"
                            );
                        }
                    }
                }
            }
        }
        assert!(
            nan_entries > 0,
            "the crushed states invert the tetrahedron somewhere"
        );
    }
}
