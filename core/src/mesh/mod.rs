//! Tetrahedral meshes: the container, boundary extraction and quality measures.
//!
//! Quality: each tetrahedron's six dihedral angles (between the two faces meeting at an
//! edge) and its radius ratio `ρ = 3 r_in / R_circ` (1 for the regular tetrahedron, → 0
//! for slivers). Linear and quadratic elements lose accuracy and conditioning as the
//! smallest dihedral angle → 0°, which is why the mesher guarantees a lower bound.

pub mod quality;
pub mod stuffing;

pub use quality::{Quality, quality};

/// A tetrahedral mesh with positively oriented tetrahedra (in mm).
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    pub vertices: Vec<[f64; 3]>,
    pub tets: Vec<[u32; 4]>,
}

/// Signed volume of tetrahedron abcd (positive when d is on the side of abc's normal
/// given by the right-hand rule... i.e. `(b−a)×(c−a)·(d−a) / 6`).
pub fn signed_volume(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    let u = sub(b, a);
    let v = sub(c, a);
    let w = sub(d, a);
    dot(cross(u, v), w) / 6.0
}

impl TetMesh {
    pub fn tet_points(&self, t: usize) -> [[f64; 3]; 4] {
        self.tets[t].map(|i| self.vertices[i as usize])
    }

    /// Boundary triangles (faces used by exactly one tetrahedron), oriented outward,
    /// each with the tetrahedron it belongs to.
    pub fn boundary_faces(&self) -> Vec<([u32; 3], u32)> {
        use std::collections::HashMap;
        // Faces opposite each vertex, ordered so the normal points away from it.
        const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
        let mut seen: HashMap<[u32; 3], (usize, [u32; 3], u32)> = HashMap::new();
        for (t, tet) in self.tets.iter().enumerate() {
            for f in FACES {
                let face = f.map(|i| tet[i]);
                let mut key = face;
                key.sort_unstable();
                seen.entry(key)
                    .and_modify(|e| e.0 += 1)
                    .or_insert((1, face, t as u32));
            }
        }
        let mut out: Vec<_> = seen
            .into_values()
            .filter(|e| e.0 == 1)
            .map(|e| (e.1, e.2))
            .collect();
        out.sort_unstable();
        out
    }

    pub fn bounding_box(&self) -> ([f64; 3], [f64; 3]) {
        bounds_of(&self.vertices)
    }

    pub fn volume(&self) -> f64 {
        (0..self.tets.len())
            .map(|t| {
                let [a, b, c, d] = self.tet_points(t);
                signed_volume(a, b, c, d)
            })
            .sum()
    }
}

/// Unit normal of triangle abc (right-hand rule), or zeros if degenerate.
pub fn triangle_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let n = cross(sub(b, a), sub(c, a));
    let l = norm(n);
    if l > 0.0 { n.map(|v| v / l) } else { [0.0; 3] }
}

/// Area of triangle abc.
pub fn triangle_area(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

/// Axis-aligned bounds `(lo, hi)` of a point set (infinite and reversed when empty).
pub fn bounds_of<'a>(points: impl IntoIterator<Item = &'a [f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
pub(crate) fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + t * (b[0] - a[0]),
        a[1] + t * (b[1] - a[1]),
        a[2] + t * (b[2] - a[2]),
    ]
}

/// Area-weighted vertex normals (the cross product's length is twice the area).
pub fn vertex_normals(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut n = vec![[0.0f64; 3]; vertices.len()];
    vertex_normals_into(vertices, triangles, &mut n);
    n.iter().map(|v| v.map(|c| c as f32)).collect()
}

/// [`vertex_normals`] into `out` (one per vertex, overwritten), in double precision
/// and without allocating: a vertex in no triangle, or whose triangles' areas cancel,
/// gets zero.
pub fn vertex_normals_into(vertices: &[[f32; 3]], triangles: &[[u32; 3]], out: &mut [[f64; 3]]) {
    out.fill([0.0; 3]);
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize].map(f64::from));
        let cr = cross(sub(b, a), sub(c, a));
        for &v in t {
            for c in 0..3 {
                out[v as usize][c] += cr[c];
            }
        }
    }
    for v in out.iter_mut() {
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        *v = if len > 0.0 {
            v.map(|c| c / len)
        } else {
            [0.0; 3]
        };
    }
}
