//! User organ surfaces: OBJ and STL (ASCII and binary) triangle surfaces, checked to be
//! closed 2-manifolds, and turned into an implicit solid the mesher can fill.
//!
//! Checks, each reported with where it fails: every edge is shared by exactly two
//! triangles (an edge used once is a hole, more than twice is non-manifold), the two
//! triangles traverse it in opposite directions (consistent orientation), every
//! vertex's triangles form a single fan (no "bow-tie" vertices), and no triangle is
//! degenerate. The orientation is made outward (positive enclosed volume).
//!
//! The implicit function is the signed distance: the distance to the closest triangle
//! (found through a uniform grid of triangle buckets), negative inside, with the sign
//! taken from the angle-weighted pseudo-normal of the closest feature (face, edge or
//! vertex), which is exact for closed manifolds (Bærentzen & Aanæs 2005).

pub mod frame;
mod indexed;
mod ply;
pub mod read;
pub mod repair;
pub mod shapes;
mod solid;
pub mod winding;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::mesh::{cross, dot, norm, sub};
pub use read::{Format, ReadSurface};
pub use solid::SurfaceSolid;

/// A triangle surface (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct TriSurface {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Largest coordinate magnitude a surface may have (1 km, in mm).
pub const MAX_COORD_MM: f64 = 1e6;

/// Why a surface cannot be used.
#[derive(Debug, Error)]
pub enum SurfaceError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {reason}")]
    Parse {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    #[error(
        "{path}: not a surface file this reads (expected OBJ, STL in ASCII or binary, or PLY in ASCII or binary)"
    )]
    Format { path: PathBuf },
    #[error("the surface has no triangles")]
    Empty,
    #[error(
        "vertex {vertex} at {at:?} is out of range: coordinates must be finite and within ±{limit_mm} mm (organs are measured in mm)"
    )]
    Coordinate {
        vertex: usize,
        at: [f64; 3],
        limit_mm: f64,
    },
    #[error("triangle {triangle} is degenerate (zero area or a repeated vertex) at {at:?}")]
    Degenerate { triangle: usize, at: [f64; 3] },
    #[error(
        "not closed: edge {a}–{b} (from {pa:?} to {pb:?}) belongs to only one triangle (a hole; \
         `--close-holes N` closes holes of up to N edges)"
    )]
    Open {
        a: u32,
        b: u32,
        pa: [f64; 3],
        pb: [f64; 3],
    },
    #[error("not manifold: edge {a}–{b} (from {pa:?} to {pb:?}) is shared by {count} triangles")]
    NonManifoldEdge {
        a: u32,
        b: u32,
        pa: [f64; 3],
        pb: [f64; 3],
        count: usize,
    },
    #[error("not manifold: vertex {v} at {at:?} joins {fans} separate fans of triangles")]
    NonManifoldVertex { v: u32, at: [f64; 3], fans: usize },
    #[error(
        "the surface has {count} separate pieces of {sizes:?} triangles; an organ is one closed \
         surface (`--largest-component` keeps the largest)"
    )]
    Components { count: usize, sizes: Vec<usize> },
    #[error(
        "inconsistent orientation: the two triangles at edge {a}–{b} (at {pa:?}) traverse it the same way"
    )]
    Orientation { a: u32, b: u32, pa: [f64; 3] },
    #[error(
        "the surface intersects itself: triangles {a} and {b} cross near {at:?} (a solid needs a surface that does not pass through itself)"
    )]
    SelfIntersecting { a: usize, b: usize, at: [f64; 3] },
}

/// What validation changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Validation {
    /// The surface was inside-out (consistently oriented, enclosing negative volume)
    /// and was turned outward.
    pub flipped: bool,
}

impl TriSurface {
    /// Reads an OBJ, STL or PLY file (the format told by content), welding corners
    /// that coincide (see [`read::read`] for what reading did).
    pub fn read(path: &Path) -> Result<TriSurface, SurfaceError> {
        read::read(path).map(|r| r.surface)
    }

    /// Signed volume (positive when oriented outward).
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Checks that the surface is usable as an organ: coordinates in range, no
    /// degenerate triangle, closed, manifold, consistently oriented (then orients it
    /// outward), in one piece.
    pub fn validate(&mut self) -> Result<Validation, SurfaceError> {
        if self.triangles.is_empty() {
            return Err(SurfaceError::Empty);
        }
        // Far larger than any organ, far below where products of coordinates overflow.
        if let Some((vertex, &at)) = self
            .vertices
            .iter()
            .enumerate()
            .find(|(_, v)| v.iter().any(|c| !c.is_finite() || c.abs() > MAX_COORD_MM))
        {
            return Err(SurfaceError::Coordinate {
                vertex,
                at,
                limit_mm: MAX_COORD_MM,
            });
        }
        let p = |i: u32| self.vertices[i as usize];
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(p);
            if tri[0] == tri[1]
                || tri[1] == tri[2]
                || tri[0] == tri[2]
                || norm(cross(sub(b, a), sub(c, a))) == 0.0
            {
                return Err(SurfaceError::Degenerate { triangle: t, at: a });
            }
        }
        // Directed edge counts.
        let mut edges: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
        for tri in &self.triangles {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let key = (a.min(b), a.max(b));
                let entry = edges.entry(key).or_default();
                if a < b { entry.0 += 1 } else { entry.1 += 1 }
            }
        }
        let mut sorted: Vec<_> = edges.into_iter().collect();
        sorted.sort_unstable_by_key(|e| e.0);
        for ((a, b), (fwd, back)) in sorted {
            let count = fwd + back;
            if count == 1 {
                return Err(SurfaceError::Open {
                    a,
                    b,
                    pa: p(a),
                    pb: p(b),
                });
            }
            if count > 2 {
                return Err(SurfaceError::NonManifoldEdge {
                    a,
                    b,
                    pa: p(a),
                    pb: p(b),
                    count,
                });
            }
            if fwd != 1 {
                return Err(SurfaceError::Orientation { a, b, pa: p(a) });
            }
        }
        // Vertex fans: the triangles around each vertex must be edge-connected.
        let mut around: Vec<Vec<usize>> = vec![Vec::new(); self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t);
            }
        }
        for (v, tris) in around.iter().enumerate() {
            if tris.len() < 2 {
                continue;
            }
            let fans = count_fans(v as u32, tris, &self.triangles);
            if fans > 1 {
                return Err(SurfaceError::NonManifoldVertex {
                    v: v as u32,
                    at: p(v as u32),
                    fans,
                });
            }
        }
        if let Some((a, b, at)) = self.first_crossing() {
            return Err(SurfaceError::SelfIntersecting { a, b, at });
        }
        let pieces = repair::components(self);
        if pieces.len() > 1 {
            return Err(SurfaceError::Components {
                count: pieces.len(),
                sizes: pieces.iter().map(Vec::len).collect(),
            });
        }
        let flipped = self.volume() < 0.0;
        if flipped {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        Ok(Validation { flipped })
    }
}

impl TriSurface {
    /// Two triangles that share no vertex and cross (an edge of one passes through
    /// the other), with a crossing point.
    fn first_crossing(&self) -> Option<(usize, usize, [f64; 3])> {
        self.crossings(1).1.into_iter().next()
    }

    /// How many pairs of triangles that share no vertex cross, and the first `keep`
    /// of them (lowest triangle pair first) with a crossing point. Broad phase: a
    /// uniform grid of about four triangles per cell over the bounding boxes.
    /// Coplanar overlaps are not looked for (a closed manifold that only touches
    /// itself in a plane is rare; it meshes).
    pub fn crossings(&self, keep: usize) -> (usize, Vec<(usize, usize, [f64; 3])>) {
        let tri = |t: usize| self.triangles[t].map(|v| self.vertices[v as usize]);
        let (lo, hi) = crate::mesh::bounds_of(&self.vertices);
        let n = self.triangles.len();
        let cells_per_side = ((n as f64 / 4.0).cbrt().ceil() as usize).clamp(1, 128);
        let size = [0, 1, 2].map(|d| ((hi[d] - lo[d]) / cells_per_side as f64).max(1e-12));
        let cell = |p: [f64; 3], d: usize| {
            (((p[d] - lo[d]) / size[d]).floor().max(0.0) as usize).min(cells_per_side - 1)
        };
        let mut grid: HashMap<[usize; 3], Vec<usize>> = HashMap::new();
        for t in 0..n {
            let (a, b) = crate::mesh::bounds_of(&tri(t));
            let (c0, c1) = ([0, 1, 2].map(|d| cell(a, d)), [0, 1, 2].map(|d| cell(b, d)));
            for i in c0[0]..=c1[0] {
                for j in c0[1]..=c1[1] {
                    for k in c0[2]..=c1[2] {
                        grid.entry([i, j, k]).or_default().push(t);
                    }
                }
            }
        }
        let mut seen = std::collections::HashSet::new();
        let mut found = Vec::new();
        for members in grid.values() {
            for (x, &t) in members.iter().enumerate() {
                for &u in &members[x + 1..] {
                    let (p, q) = (self.triangles[t], self.triangles[u]);
                    if p.iter().any(|v| q.contains(v)) || !seen.insert((t.min(u), t.max(u))) {
                        continue;
                    }
                    let (tp, tq) = (tri(t), tri(u));
                    if let Some(at) = edges_cross(&tp, &tq).or_else(|| edges_cross(&tq, &tp)) {
                        found.push((t.min(u), t.max(u), at));
                    }
                }
            }
        }
        found.sort_by_key(|&(a, b, _)| (a, b));
        let count = found.len();
        found.truncate(keep);
        (count, found)
    }

    /// Every defect [`TriSurface::validate`] refuses, counted, so that a surface
    /// meshed by its winding number can say what it had.
    pub fn defects(&self) -> Defects {
        let mut edges: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
        for tri in &self.triangles {
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let entry = edges.entry((a.min(b), a.max(b))).or_default();
                if a < b { entry.0 += 1 } else { entry.1 += 1 }
            }
        }
        let mut d = Defects::default();
        for &(fwd, back) in edges.values() {
            match fwd + back {
                1 => d.open_edges += 1,
                2 if fwd != 1 => d.orientation_conflicts += 1,
                2 => {}
                _ => d.non_manifold_edges += 1,
            }
        }
        let mut around: Vec<Vec<usize>> = vec![Vec::new(); self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t);
            }
        }
        d.bow_tie_vertices = around
            .iter()
            .enumerate()
            .filter(|(v, tris)| tris.len() >= 2 && count_fans(*v as u32, tris, &self.triangles) > 1)
            .count();
        let (count, first) = self.crossings(5);
        d.crossings = count;
        d.crossing_at = first.iter().map(|c| c.2).collect();
        d.pieces = repair::components(self).iter().map(Vec::len).collect();
        d
    }

    /// Drops the triangles of zero area or with a repeated vertex; returns how many.
    pub fn drop_degenerate(&mut self) -> usize {
        let before = self.triangles.len();
        let v = &self.vertices;
        self.triangles.retain(|t| {
            let [a, b, c] = t.map(|i| v[i as usize]);
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2] && norm(cross(sub(b, a), sub(c, a))) > 0.0
        });
        before - self.triangles.len()
    }
}

/// What a surface has that a closed 2-manifold has not ([`TriSurface::defects`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Defects {
    /// Pairs of triangles that cross, and up to five crossing points.
    pub crossings: usize,
    pub crossing_at: Vec<[f64; 3]>,
    /// Edges of one triangle (holes).
    pub open_edges: usize,
    /// Edges of three or more triangles.
    pub non_manifold_edges: usize,
    /// Vertices joining separate fans of triangles.
    pub bow_tie_vertices: usize,
    /// Edges its two triangles traverse the same way.
    pub orientation_conflicts: usize,
    /// Triangles of each edge-connected piece, largest first.
    pub pieces: Vec<usize>,
}

impl Defects {
    /// One line per defect found, in words.
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.crossings > 0 {
            let at = self.crossing_at[0].map(|x| (x * 10.0).round() / 10.0);
            out.push(format!(
                "crosses itself: {} pairs of triangles cross (the first near {at:?} mm)",
                self.crossings
            ));
        }
        if self.open_edges > 0 {
            out.push(format!(
                "has holes: {} edges belong to one triangle only",
                self.open_edges
            ));
        }
        if self.non_manifold_edges > 0 {
            out.push(format!(
                "{} edges are shared by three or more triangles",
                self.non_manifold_edges
            ));
        }
        if self.bow_tie_vertices > 0 {
            out.push(format!(
                "{} vertices join separate fans of triangles",
                self.bow_tie_vertices
            ));
        }
        if self.orientation_conflicts > 0 {
            out.push(format!(
                "{} edges are traversed the same way by both their triangles (orientation flips)",
                self.orientation_conflicts
            ));
        }
        if self.pieces.len() > 1 {
            out.push(format!(
                "{} separate pieces of {:?} triangles",
                self.pieces.len(),
                self.pieces
            ));
        }
        out
    }
}

/// Where an edge of `a` passes through triangle `b` (Möller–Trumbore, parameters
/// strictly inside), if one does.
fn edges_cross(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> Option<[f64; 3]> {
    let (e1, e2) = (sub(b[1], b[0]), sub(b[2], b[0]));
    let scale = norm(e1).max(norm(e2));
    for k in 0..3 {
        let (o, end) = (a[k], a[(k + 1) % 3]);
        let dir = sub(end, o);
        let h = cross(dir, e2);
        let det = dot(e1, h);
        if det.abs() <= 1e-12 * scale * scale * norm(dir) {
            continue;
        }
        let f = 1.0 / det;
        let s0 = sub(o, b[0]);
        let u = f * dot(s0, h);
        let qv = cross(s0, e1);
        let v = f * dot(dir, qv);
        let t = f * dot(e2, qv);
        let eps = 1e-9;
        if u > eps && v > eps && u + v < 1.0 - eps && t > eps && t < 1.0 - eps {
            return Some([0, 1, 2].map(|d| o[d] + t * dir[d]));
        }
    }
    None
}

/// Number of edge-connected groups among the triangles around vertex v.
fn count_fans(v: u32, tris: &[usize], all: &[[u32; 3]]) -> usize {
    let mut group: Vec<usize> = (0..tris.len()).collect();
    fn find(g: &mut [usize], i: usize) -> usize {
        let mut r = i;
        while g[r] != r {
            r = g[r];
        }
        g[i] = r;
        r
    }
    let mut by_other: HashMap<u32, usize> = HashMap::new();
    for (k, &t) in tris.iter().enumerate() {
        for &w in &all[t] {
            if w == v {
                continue;
            }
            if let Some(&j) = by_other.get(&w) {
                let (a, b) = (find(&mut group, k), find(&mut group, j));
                group[a] = b;
            } else {
                by_other.insert(w, k);
            }
        }
    }
    (0..tris.len())
        .filter(|&k| find(&mut group, k) == k)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::stuffing::Implicit;

    fn cube_obj() -> String {
        let mut s = String::new();
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0] {
                    s += &format!("v {} {} {}\n", 10.0 * x, 10.0 * y, 10.0 * z);
                }
            }
        }
        // Quads, outward (vertex i = x + 2y + 4z, 1-based).
        for f in [
            "1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6",
        ] {
            s += &format!("f {f}\n");
        }
        s
    }

    fn read_str(name: &str, text: &str) -> Result<TriSurface, SurfaceError> {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join(name);
        std::fs::write(&p, text).expect("write");
        TriSurface::read(&p)
    }

    #[test]
    fn a_closed_cube_validates_and_its_distance_is_signed() {
        let mut s = read_str("cube.obj", &cube_obj()).expect("parse");
        s.validate().expect("closed");
        assert!((s.volume() - 1000.0).abs() < 1e-9);
        let solid = SurfaceSolid::new(s);
        assert!((solid.value([5.0, 5.0, 5.0]) + 5.0).abs() < 1e-12);
        assert!((solid.value([5.0, 5.0, 13.0]) - 3.0).abs() < 1e-12);
        assert!(
            (solid.value([13.0, 14.0, 10.0]) - 5.0).abs() < 1e-12,
            "edge region"
        );
        assert!(solid.value([0.5, 0.5, 0.5]) < 0.0);
    }

    /// Two closed cubes pushed into each other: each is a closed manifold, together
    /// they cross, which is named (it used to mesh for minutes with no message).
    #[test]
    fn a_self_intersecting_surface_is_refused() {
        let mut text = cube_obj();
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0] {
                    text += &format!(
                        "v {} {} {}\n",
                        5.0 + 10.0 * x,
                        4.0 + 10.0 * y,
                        3.0 + 10.0 * z
                    );
                }
            }
        }
        for f in [
            "1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6",
        ] {
            let shifted: Vec<String> = f
                .split(' ')
                .map(|i| (i.parse::<u32>().expect("index") + 8).to_string())
                .collect();
            text += &format!("f {}\n", shifted.join(" "));
        }
        let mut s = read_str("two.obj", &text).expect("parses");
        match s.validate() {
            Err(SurfaceError::SelfIntersecting { at, .. }) => {
                assert!(at.iter().all(|c| (0.0..=15.0).contains(c)), "{at:?}");
            }
            other => panic!("expected the crossing, got {other:?}"),
        }
        // One cube alone does not cross itself.
        read_str("cube.obj", &cube_obj())
            .expect("parses")
            .validate()
            .expect("valid");
    }

    /// A vertex at 1e308 (finite, but its products overflow) is named, not meshed
    /// (it used to panic in the closest-point query).
    #[test]
    fn a_huge_coordinate_is_rejected_naming_the_vertex() {
        let text = cube_obj().replacen("v 10 10 10", "v 1e308 10 10", 1);
        assert_ne!(text, cube_obj());
        let mut s = read_str("huge.obj", &text).expect("parses");
        match s.validate() {
            Err(SurfaceError::Coordinate { vertex: 7, .. }) => {}
            other => panic!("expected the coordinate error, got {other:?}"),
        }
    }

    #[test]
    fn an_open_surface_is_rejected_naming_the_edge() {
        let text: String = cube_obj()
            .lines()
            .filter(|l| *l != "f 2 4 8 6")
            .map(|l| format!("{l}\n"))
            .collect();
        let mut s = read_str("open.obj", &text).expect("parse");
        let e = s.validate().expect_err("open");
        assert!(matches!(e, SurfaceError::Open { .. }), "{e}");
        assert!(e.to_string().contains("hole"), "{e}");
    }

    #[test]
    fn a_non_manifold_surface_is_rejected() {
        // Two cubes sharing one edge: the edge has 4 triangles.
        let mut text = cube_obj();
        for z in [0.0, 1.0] {
            for y in [1.0, 2.0] {
                for x in [1.0, 2.0] {
                    text += &format!("v {} {} {}\n", 10.0 * x, 10.0 * y, 10.0 * z);
                }
            }
        }
        for f in [
            "1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6",
        ] {
            let shifted: Vec<String> = f
                .split(' ')
                .map(|i| (i.parse::<u32>().expect("int") + 8).to_string())
                .collect();
            text += &format!("f {}\n", shifted.join(" "));
        }
        // The cubes' coincident vertices are separate OBJ vertices: merge them by
        // position, as STL reading does, so the shared edge is one edge.
        let s = read_str("two.obj", &text).expect("parse");
        let corners: Vec<[f64; 3]> = s
            .triangles
            .iter()
            .flat_map(|t| t.map(|i| s.vertices[i as usize]))
            .collect();
        let n = corners.len() as u32 / 3;
        let tris: Vec<[u32; 3]> = (0..n).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let (mut merged, _) = read::weld(&corners, &tris);
        let e = merged.validate().expect_err("non-manifold");
        assert!(
            matches!(e, SurfaceError::NonManifoldEdge { count: 4, .. }),
            "{e}"
        );
    }

    #[test]
    fn bad_files_name_the_line() {
        let e = read_str("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 zero\n").expect_err("parse");
        assert!(e.to_string().contains(":3:"), "{e}");
        let e = read_str("bad2.obj", "v 0 0 0\nf 1 2 3\n").expect_err("range");
        assert!(e.to_string().contains("out of range"), "{e}");
        let e = read_str("bad.stl", "hello").expect_err("stl");
        assert!(e.to_string().contains("STL"), "{e}");
    }

    #[test]
    fn binary_and_ascii_stl_read_the_same_surface() {
        let obj = read_str("cube.obj", &cube_obj()).expect("parse");
        let mut ascii = String::from("solid cube\n");
        let mut bin = vec![0u8; 80];
        bin.extend_from_slice(&(obj.triangles.len() as u32).to_le_bytes());
        for t in &obj.triangles {
            ascii += "facet normal 0 0 0\nouter loop\n";
            bin.extend_from_slice(&[0u8; 12]);
            for &v in t {
                let p = obj.vertices[v as usize];
                ascii += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
                for c in p {
                    bin.extend_from_slice(&(c as f32).to_le_bytes());
                }
            }
            ascii += "endloop\nendfacet\n";
            bin.extend_from_slice(&[0u8; 2]);
        }
        let a = read_str("a.stl", &ascii).expect("ascii");
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("b.stl");
        std::fs::write(&p, &bin).expect("write");
        let b = TriSurface::read(&p).expect("binary");
        assert_eq!(a.triangles.len(), 12);
        assert_eq!(a.vertices.len(), 8);
        assert_eq!(a, b);
    }
}
