//! Isosurface stuffing (Labelle & Shewchuk, SIGGRAPH 2007): a tetrahedral mesh of the
//! region `f(x) < 0` of an implicit function, with bounded dihedral angles.
//!
//! 1. A body-centred cubic (BCC) lattice of spacing `h` covers the domain: cube corners
//!    plus cube centres. Its tetrahedra (four per pair of face-adjacent cube centres,
//!    one per edge of the shared square face) tile space; *black* edges (corner–corner,
//!    centre–centre, length h) are the long ones, *red* edges (centre–corner, length
//!    h·√3/2) the short ones.
//! 2. `f` is evaluated at every lattice vertex; where it changes sign along an edge, the
//!    *cut point* is found by bisection on `f` along the edge.
//! 3. **Warping**: a vertex closer to a cut point on one of its edges than α·|edge|
//!    (α = 0.24999 on black, 0.41189 on red edges, the paper's values) is moved onto
//!    the nearest such cut point and becomes a surface vertex (f = 0).
//! 4. **Filling**: each lattice tetrahedron is clipped to `f ≤ 0` by its signs (−, 0,
//!    +). Six sign patterns need cutting; they give a tetrahedron, a pyramid (split in
//!    2) or a prism (split in 3). A quadrilateral face is always split by the diagonal
//!    through its vertex of smallest global index, so both tetrahedra sharing it split
//!    it the same way and the mesh is conforming (Dompierre et al. 1999).
//!
//! The paper's angle bound (10.7°–164.8°) assumes its parity rule for the diagonals;
//! this implementation uses the index rule instead, and measures the angles it gets
//! ([`super::quality`](mod@super::quality)). The surface is resolved to O(h): features thinner than about
//! h (a sharp edge, a thin lobe) are rounded off at coarse levels.

use std::collections::HashMap;

use rayon::prelude::*;

use super::{TetMesh, lerp, norm, signed_volume, sub};

/// An implicit solid: `value < 0` inside, `> 0` outside, 0 on the surface.
pub trait Implicit: Sync {
    fn value(&self, p: [f64; 3]) -> f64;
    /// A box containing the solid.
    fn bounds(&self) -> ([f64; 3], [f64; 3]);
}

const ALPHA_LONG: f64 = 0.24999;
const ALPHA_SHORT: f64 = 0.41189;

struct Lattice {
    lo: [f64; 3],
    h: f64,
    /// Corners per axis (n + 1); centres per axis are n.
    n: [usize; 3],
}

impl Lattice {
    fn corners(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }
    fn centres(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }
    fn corner(&self, i: usize, j: usize, k: usize) -> u32 {
        (i + (self.n[0] + 1) * (j + (self.n[1] + 1) * k)) as u32
    }
    fn centre(&self, i: usize, j: usize, k: usize) -> u32 {
        (self.corners() + i + self.n[0] * (j + self.n[1] * k)) as u32
    }
    /// Integer coordinates in half-cells: corners at even, centres at odd values.
    fn half_coords(&self, v: u32) -> [i64; 3] {
        let v = v as usize;
        if v < self.corners() {
            let (a, b) = (self.n[0] + 1, self.n[1] + 1);
            [
                (v % a) as i64 * 2,
                ((v / a) % b) as i64 * 2,
                (v / (a * b)) as i64 * 2,
            ]
        } else {
            let c = v - self.corners();
            let (a, b) = (self.n[0], self.n[1]);
            [
                (c % a) as i64 * 2 + 1,
                ((c / a) % b) as i64 * 2 + 1,
                (c / (a * b)) as i64 * 2 + 1,
            ]
        }
    }
    fn vertex_at_half(&self, h: [i64; 3]) -> Option<u32> {
        let odd = h[0] & 1;
        if h.iter().any(|&c| c & 1 != odd || c < 0) {
            return None;
        }
        if odd == 0 {
            let [i, j, k] = h.map(|c| (c / 2) as usize);
            (i <= self.n[0] && j <= self.n[1] && k <= self.n[2]).then(|| self.corner(i, j, k))
        } else {
            let [i, j, k] = h.map(|c| (c / 2) as usize);
            (i < self.n[0] && j < self.n[1] && k < self.n[2]).then(|| self.centre(i, j, k))
        }
    }
    fn position(&self, v: u32) -> [f64; 3] {
        let h = self.half_coords(v);
        [0, 1, 2].map(|d| self.lo[d] + 0.5 * self.h * h[d] as f64)
    }
    /// The 14 lattice neighbours of v: 6 black (±2 half-cells on an axis), 8 red.
    fn neighbours(&self, v: u32) -> impl Iterator<Item = (u32, bool)> + '_ {
        let c = self.half_coords(v);
        const BLACK: [[i64; 3]; 6] = [
            [2, 0, 0],
            [-2, 0, 0],
            [0, 2, 0],
            [0, -2, 0],
            [0, 0, 2],
            [0, 0, -2],
        ];
        let red = (0..8).map(|m| {
            [
                if m & 1 == 0 { 1 } else { -1 },
                if m & 2 == 0 { 1 } else { -1 },
                if m & 4 == 0 { 1 } else { -1 },
            ]
        });
        BLACK
            .into_iter()
            .map(|d| (d, true))
            .chain(red.map(|d| (d, false)))
            .filter_map(move |(d, black)| {
                self.vertex_at_half([c[0] + d[0], c[1] + d[1], c[2] + d[2]])
                    .map(|w| (w, black))
            })
    }
}

/// Where `f` vanishes on the segment a→b (f(a), f(b) of opposite signs): bisection,
/// 40 halvings (2⁻⁴⁰·h: far below any tolerance that matters).
fn root(shape: &impl Implicit, a: [f64; 3], fa: f64, b: [f64; 3]) -> [f64; 3] {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        let fm = shape.value(lerp(a, b, mid));
        if (fm < 0.0) == (fa < 0.0) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lerp(a, b, 0.5 * (lo + hi))
}

/// A vertex of the output mesh before numbering: a lattice vertex (maybe warped) or a
/// cut point on a lattice edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Key {
    Lattice(u32),
    Cut(u32, u32),
}

fn edge_key(a: u32, b: u32) -> (u32, u32) {
    if a < b { (a, b) } else { (b, a) }
}

/// What stuffing produced besides the mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct StuffingReport {
    pub lattice_vertices: usize,
    pub warped: usize,
    /// Sub-tetrahedra dropped because their volume was below 1e-12·h³.
    pub degenerate_dropped: usize,
}

/// Meshes `{f < 0}` with lattice spacing `h_mm`.
pub fn stuff(shape: &impl Implicit, h_mm: f64) -> (TetMesh, StuffingReport) {
    let (blo, bhi) = shape.bounds();
    // One cell of margin beyond the box, so every boundary lattice tetrahedron is
    // outside the solid.
    let lo = blo.map(|c| c - 1.5 * h_mm);
    let n = [0, 1, 2].map(|d| (((bhi[d] + 1.5 * h_mm) - lo[d]) / h_mm).ceil() as usize + 1);
    let lat = Lattice { lo, h: h_mm, n };
    let total = lat.corners() + lat.centres();

    let pos0: Vec<[f64; 3]> = (0..total as u32).map(|v| lat.position(v)).collect();
    let val0: Vec<f64> = pos0.par_iter().map(|&p| shape.value(p)).collect();

    // Cut points on edges whose endpoints have strictly opposite signs.
    let cut_edges: Vec<(u32, u32)> = (0..total as u32)
        .flat_map(|v| {
            lat.neighbours(v)
                .filter(move |&(w, _)| v < w)
                .map(move |(w, _)| (v, w))
                .collect::<Vec<_>>()
        })
        .filter(|&(v, w)| val0[v as usize] * val0[w as usize] < 0.0)
        .collect();
    let cuts: HashMap<(u32, u32), [f64; 3]> = cut_edges
        .par_iter()
        .map(|&(v, w)| {
            (
                (v, w),
                root(shape, pos0[v as usize], val0[v as usize], pos0[w as usize]),
            )
        })
        .collect();

    // Warping: each vertex moves to its nearest violating cut point, if any.
    let warps: Vec<Option<[f64; 3]>> = (0..total as u32)
        .into_par_iter()
        .map(|v| {
            if val0[v as usize] == 0.0 {
                return None;
            }
            let p = pos0[v as usize];
            let mut best: Option<(f64, [f64; 3])> = None;
            for (w, black) in lat.neighbours(v) {
                if let Some(&c) = cuts.get(&edge_key(v, w)) {
                    let len = norm(sub(pos0[w as usize], p));
                    let d = norm(sub(c, p));
                    let alpha = if black { ALPHA_LONG } else { ALPHA_SHORT };
                    if d < alpha * len && best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, c));
                    }
                }
            }
            best.map(|b| b.1)
        })
        .collect();
    let warped = warps.iter().filter(|w| w.is_some()).count();
    let mut pos = pos0.clone();
    let mut val = val0.clone();
    for (v, w) in warps.iter().enumerate() {
        if let Some(p) = w {
            pos[v] = *p;
            val[v] = 0.0;
        }
    }

    // Fill, numbering output vertices on first use.
    let mut b = Builder {
        ids: HashMap::new(),
        vertices: Vec::new(),
        tets: Vec::new(),
        degenerate: 0,
        min_vol: 1e-12 * h_mm.powi(3),
        pos: &pos,
        cuts: &cuts,
    };
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let c1 = lat.centre(i, j, k);
                for axis in 0..3 {
                    let mut nb = [i, j, k];
                    nb[axis] += 1;
                    if nb[axis] >= n[axis] {
                        continue;
                    }
                    let c2 = lat.centre(nb[0], nb[1], nb[2]);
                    // The square face between the two cubes, in cyclic order.
                    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                    let sq: [u32; 4] = [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(du, dw)| {
                        let mut c = [i, j, k];
                        c[axis] += 1;
                        c[u] += du;
                        c[w] += dw;
                        lat.corner(c[0], c[1], c[2])
                    });
                    for e in 0..4 {
                        let tet = [c1, c2, sq[e], sq[(e + 1) % 4]];
                        if let Some(poly) = clip(tet, &val, shape, &pos) {
                            b.add(poly);
                        }
                    }
                }
            }
        }
    }
    let degenerate_dropped = b.degenerate;
    (
        TetMesh {
            vertices: b.vertices,
            tets: b.tets,
        },
        StuffingReport {
            lattice_vertices: total,
            warped,
            degenerate_dropped,
        },
    )
}

/// The part of a lattice tetrahedron inside the solid.
#[derive(Debug, Clone, Copy)]
enum Poly {
    Tet([Key; 4]),
    /// Apex and a base quadrilateral in cyclic order.
    Pyramid(Key, [Key; 4]),
    /// Bottom triangle 0,1,2 and top 3,4,5, with lateral edges i — i+3.
    Prism([Key; 6]),
}

/// Clips lattice tetrahedron `t` (vertex values `val` after warping) to `f ≤ 0`.
fn clip(t: [u32; 4], val: &[f64], shape: &impl Implicit, pos: &[[f64; 3]]) -> Option<Poly> {
    let mut minus = Vec::with_capacity(4);
    let mut zero = Vec::with_capacity(4);
    let mut plus = Vec::with_capacity(4);
    for &v in &t {
        let f = val[v as usize];
        if f < 0.0 {
            minus.push(v);
        } else if f > 0.0 {
            plus.push(v);
        } else {
            zero.push(v);
        }
    }
    let l = Key::Lattice;
    let cut = |a: u32, b: u32| {
        let (x, y) = edge_key(a, b);
        Key::Cut(x, y)
    };
    match (minus.len(), zero.len(), plus.len()) {
        (0, 4, 0) => {
            // All four vertices on the surface: keep it if its centroid is inside.
            let c = [0, 1, 2].map(|d| t.iter().map(|&v| pos[v as usize][d]).sum::<f64>() / 4.0);
            (shape.value(c) < 0.0).then_some(Poly::Tet(t.map(l)))
        }
        (0, _, _) => None,
        (_, _, 0) => Some(Poly::Tet(t.map(l))),
        (1, 0, 3) => {
            let m = minus[0];
            Some(Poly::Tet([
                l(m),
                cut(m, plus[0]),
                cut(m, plus[1]),
                cut(m, plus[2]),
            ]))
        }
        (1, 1, 2) => {
            let m = minus[0];
            Some(Poly::Tet([
                l(m),
                l(zero[0]),
                cut(m, plus[0]),
                cut(m, plus[1]),
            ]))
        }
        (1, 2, 1) => {
            let m = minus[0];
            Some(Poly::Tet([l(m), l(zero[0]), l(zero[1]), cut(m, plus[0])]))
        }
        (2, 0, 2) => {
            let (a, b) = (minus[0], minus[1]);
            let (p, q) = (plus[0], plus[1]);
            Some(Poly::Prism([
                l(a),
                cut(a, p),
                cut(a, q),
                l(b),
                cut(b, p),
                cut(b, q),
            ]))
        }
        (2, 1, 1) => {
            let (a, b, p) = (minus[0], minus[1], plus[0]);
            Some(Poly::Pyramid(
                l(zero[0]),
                [l(a), l(b), cut(b, p), cut(a, p)],
            ))
        }
        (3, 0, 1) => {
            let p = plus[0];
            let [a, b, c] = [minus[0], minus[1], minus[2]];
            Some(Poly::Prism([
                l(a),
                l(b),
                l(c),
                cut(a, p),
                cut(b, p),
                cut(c, p),
            ]))
        }
        _ => None,
    }
}

struct Builder<'a> {
    ids: HashMap<Key, u32>,
    vertices: Vec<[f64; 3]>,
    tets: Vec<[u32; 4]>,
    degenerate: usize,
    min_vol: f64,
    pos: &'a [[f64; 3]],
    cuts: &'a HashMap<(u32, u32), [f64; 3]>,
}

impl Builder<'_> {
    fn id(&mut self, k: Key) -> u32 {
        if let Some(&i) = self.ids.get(&k) {
            return i;
        }
        self.vertices.push(match k {
            Key::Lattice(v) => self.pos[v as usize],
            Key::Cut(a, b) => self.cuts[&(a, b)],
        });
        let i = (self.vertices.len() - 1) as u32;
        self.ids.insert(k, i);
        i
    }

    fn add(&mut self, poly: Poly) {
        match poly {
            Poly::Tet(k) => {
                let t = k.map(|k| self.id(k));
                self.push(t);
            }
            Poly::Pyramid(apex, base) => {
                let z = self.id(apex);
                let q = base.map(|k| self.id(k));
                for t in split_pyramid(z, q) {
                    self.push(t);
                }
            }
            Poly::Prism(k) => {
                let p = k.map(|k| self.id(k));
                for t in split_prism(p) {
                    self.push(t);
                }
            }
        }
    }

    fn push(&mut self, t: [u32; 4]) {
        let p = t.map(|i| self.vertices[i as usize]);
        let vol = signed_volume(p[0], p[1], p[2], p[3]);
        if vol.abs() <= self.min_vol {
            self.degenerate += 1;
        } else if vol > 0.0 {
            self.tets.push(t);
        } else {
            self.tets.push([t[0], t[2], t[1], t[3]]);
        }
    }
}

/// Two tetrahedra, the base split by the diagonal through its smallest index.
fn split_pyramid(z: u32, q: [u32; 4]) -> [[u32; 4]; 2] {
    let min = (0..4).min_by_key(|&i| q[i]).expect("4 vertices");
    if min % 2 == 0 {
        [[z, q[0], q[1], q[2]], [z, q[0], q[2], q[3]]]
    } else {
        [[z, q[1], q[2], q[3]], [z, q[1], q[3], q[0]]]
    }
}

/// Three tetrahedra (Dompierre et al. 1999): rotate so the smallest index is vertex 0,
/// then pick the diagonal of the opposite quadrilateral through its smallest index.
fn split_prism(p: [u32; 6]) -> [[u32; 4]; 3] {
    let min = (0..6).min_by_key(|&i| p[i]).expect("6 vertices");
    // Swap bottom and top if the minimum is on top (orientation is fixed afterwards).
    let p = if min >= 3 {
        [p[3], p[4], p[5], p[0], p[1], p[2]]
    } else {
        p
    };
    let r = min % 3;
    let v = [
        p[r],
        p[(r + 1) % 3],
        p[(r + 2) % 3],
        p[r + 3],
        p[(r + 1) % 3 + 3],
        p[(r + 2) % 3 + 3],
    ];
    if v[1].min(v[5]) < v[2].min(v[4]) {
        [
            [v[0], v[1], v[2], v[5]],
            [v[0], v[1], v[5], v[4]],
            [v[0], v[4], v[5], v[3]],
        ]
    } else {
        [
            [v[0], v[1], v[2], v[4]],
            [v[0], v[4], v[2], v[5]],
            [v[0], v[4], v[5], v[3]],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality;

    struct Sphere(f64);
    impl Implicit for Sphere {
        fn value(&self, p: [f64; 3]) -> f64 {
            norm(p) - self.0
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            ([-self.0; 3], [self.0; 3])
        }
    }

    #[test]
    fn sphere_mesh_is_valid_closed_and_of_the_right_volume() {
        let (m, rep) = stuff(&Sphere(10.0), 1.5);
        let q = quality(&m);
        assert_eq!(q.inverted, 0);
        assert!(q.min_dihedral_deg > 0.0);
        // Volume within O(h²) of 4/3 π r³ (surface approximated to O(h²) by chords).
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 1000.0;
        assert!(
            (m.volume() - exact).abs() / exact < 0.02,
            "{} vs {exact}",
            m.volume()
        );
        // Closed: every boundary edge is shared by exactly two boundary faces.
        let faces = m.boundary_faces();
        let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
        for (f, _) in &faces {
            for e in 0..3 {
                *edges.entry(edge_key(f[e], f[(e + 1) % 3])).or_default() += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2), "boundary not closed");
        // Boundary vertices lie on the sphere.
        for (f, _) in &faces {
            for &v in f {
                assert!((norm(m.vertices[v as usize]) - 10.0).abs() < 1e-6);
            }
        }
        assert!(rep.warped > 0);
        eprintln!(
            "sphere: {} vertices, {} tets, {q:?}, {rep:?}",
            m.vertices.len(),
            m.tets.len()
        );
    }
}
