//! The drawn surface: finer and smoother than the mechanical one, carried by it.
//!
//! The mechanical surface of a coarse mesh is what the vademecum moves, and drawn as it
//! is its silhouette shows the lattice (a saw-tooth along a sharp border). Surgical
//! simulators draw a separate visual model embedded in the mechanical one; so does a
//! scene here.
//!
//! **The visual surface** is the mechanical render surface subdivided `levels` times
//! by Loop's scheme (each triangle into four, every vertex moved to a weighted mean of
//! its neighbours: a smooth limit surface, C² except at irregular vertices). It lies
//! within a fraction of an edge of the mechanical surface.
//!
//! **The embedding.** Each visual vertex `p` is attached to the mechanical triangle
//! closest to it, `(a, b, c)` with unit normal `n`, by the barycentric coordinates
//! `λ` of its projection on that triangle's plane and its height `h` above it:
//!
//! ```text
//! p = λ_a a + λ_b b + λ_c c + h n          (exact at rest)
//! p' = λ_a a' + λ_b b' + λ_c c' + h n'     (a', b', c' deformed; n' their unit normal)
//! ```
//!
//! so the drawn surface follows the mechanical nodes' displacement (interpolated
//! linearly on the render triangles, as they are drawn) and turns with them: a rigid
//! motion of the mechanical surface moves it rigidly. The mechanical surface is all a
//! scene stores, so the embedding is in its triangles rather than its tetrahedra; the
//! two agree where the visual vertex lies on the mechanical surface (`h = 0`), and
//! `h` is a fraction of a millimetre to a few.
//!
//! Normals are recomputed each frame from the deformed visual triangles (area
//! weighted), so the dimple under the tool shades as it is.

use std::collections::HashMap;

use crate::axis::closest_on_triangle;
use crate::mesh::{cross, dot, norm, sub};

/// A visual vertex's place on the mechanical surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Embed {
    /// The mechanical render triangle.
    pub triangle: u32,
    /// Its vertices.
    pub corners: [u32; 3],
    /// Barycentric coordinates of the projection on its plane (may step a little
    /// outside `[0, 1]` where the vertex is closest to an edge).
    pub bary: [f32; 3],
    /// Height above the triangle's plane along its unit normal (mm).
    pub height_mm: f32,
}

/// A finer surface carried by the mechanical render surface (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct VisualSurface {
    pub rest_mm: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub embed: Vec<Embed>,
}

/// One level of Loop subdivision of a triangle mesh (boundary edges keep their
/// midpoints and boundary vertices their place, for a surface that is not closed).
pub fn loop_subdivide(v: &[[f64; 3]], t: &[[u32; 3]]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    // Edges in the order the triangles meet them: (new vertex, opposite corners).
    let mut edges: HashMap<(u32, u32), (u32, [u32; 2], u8)> = HashMap::new();
    let mut order: Vec<(u32, u32)> = Vec::new();
    let first_new = v.len() as u32;
    for tri in t {
        for e in 0..3 {
            let (a, b) = (tri[e], tri[(e + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let next = first_new + order.len() as u32;
            let entry = edges.entry(key).or_insert_with(|| {
                order.push(key);
                (next, [u32::MAX; 2], 0)
            });
            if entry.2 < 2 {
                entry.1[entry.2 as usize] = tri[(e + 2) % 3];
            }
            entry.2 = entry.2.saturating_add(1);
        }
    }
    // Each vertex's neighbours and whether it is on the boundary.
    let mut ring: Vec<Vec<u32>> = vec![Vec::new(); v.len()];
    let mut boundary: Vec<Vec<u32>> = vec![Vec::new(); v.len()];
    for &(a, b) in &order {
        ring[a as usize].push(b);
        ring[b as usize].push(a);
        if edges[&(a, b)].2 == 1 {
            boundary[a as usize].push(b);
            boundary[b as usize].push(a);
        }
    }
    let mut out = Vec::with_capacity(v.len() + order.len());
    for (i, &p) in v.iter().enumerate() {
        let r = &ring[i];
        let q = if boundary[i].len() == 2 {
            let (b0, b1) = (v[boundary[i][0] as usize], v[boundary[i][1] as usize]);
            [0, 1, 2].map(|d| 0.75 * p[d] + 0.125 * (b0[d] + b1[d]))
        } else if !boundary[i].is_empty() || r.len() < 3 {
            p
        } else {
            let n = r.len() as f64;
            let beta = if r.len() == 3 {
                3.0 / 16.0
            } else {
                3.0 / (8.0 * n)
            };
            let mut q = p.map(|c| (1.0 - n * beta) * c);
            for &j in r {
                for d in 0..3 {
                    q[d] += beta * v[j as usize][d];
                }
            }
            q
        };
        out.push(q);
    }
    for key in &order {
        let (_, opp, count) = edges[key];
        let (a, b) = (v[key.0 as usize], v[key.1 as usize]);
        let q = if count == 2 {
            let (c, d) = (v[opp[0] as usize], v[opp[1] as usize]);
            [0, 1, 2].map(|k| 0.375 * (a[k] + b[k]) + 0.125 * (c[k] + d[k]))
        } else {
            [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]))
        };
        out.push(q);
    }
    let mid = |a: u32, b: u32| edges[&(a.min(b), a.max(b))].0;
    let mut tris = Vec::with_capacity(4 * t.len());
    for &[a, b, c] in t {
        let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
        tris.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
    }
    (out, tris)
}

/// Unit normal of a triangle, or zero for a degenerate one.
fn unit_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let n = cross(sub(b, a), sub(c, a));
    let l = norm(n);
    if l > 0.0 { n.map(|x| x / l) } else { [0.0; 3] }
}

impl VisualSurface {
    /// The mechanical render surface (`vertices`, `triangles`) subdivided `levels`
    /// times and embedded in it.
    pub fn subdivided(vertices: &[[f32; 3]], triangles: &[[u32; 3]], levels: u32) -> Self {
        let mech: Vec<[f64; 3]> = vertices.iter().map(|p| p.map(f64::from)).collect();
        let (mut v, mut t) = (mech.clone(), triangles.to_vec());
        for _ in 0..levels {
            (v, t) = loop_subdivide(&v, &t);
        }
        let embed = embed(&mech, triangles, &v);
        VisualSurface {
            rest_mm: v.iter().map(|p| p.map(|c| c as f32)).collect(),
            triangles: t,
            embed,
        }
    }

    /// The visual vertices on a deformed mechanical surface (`mech`: xyz per
    /// mechanical vertex, `w` a value carried along, such as |u|): positions with `w`
    /// interpolated, and unit normals. `sums` is scratch (one per visual vertex).
    pub fn deform(
        &self,
        mech: &[[f32; 4]],
        positions: &mut [[f32; 4]],
        normals: &mut [[f32; 4]],
        sums: &mut [[f32; 3]],
    ) {
        for (out, e) in positions.iter_mut().zip(&self.embed) {
            let [a, b, c] = e.corners.map(|i| mech[i as usize]);
            let n = cross3(sub3(b, a), sub3(c, a));
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let h = if l > 0.0 { e.height_mm / l } else { 0.0 };
            let [la, lb, lc] = e.bary;
            *out = [
                la * a[0] + lb * b[0] + lc * c[0] + h * n[0],
                la * a[1] + lb * b[1] + lc * c[1] + h * n[1],
                la * a[2] + lb * b[2] + lc * c[2] + h * n[2],
                la * a[3] + lb * b[3] + lc * c[3],
            ];
        }
        sums.fill([0.0; 3]);
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let n = cross3(sub3(b, a), sub3(c, a));
            for &i in t {
                let s = &mut sums[i as usize];
                s[0] += n[0];
                s[1] += n[1];
                s[2] += n[2];
            }
        }
        for (out, s) in normals.iter_mut().zip(sums.iter()) {
            let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            *out = if l > 0.0 {
                [s[0] / l, s[1] / l, s[2] / l, 0.0]
            } else {
                [0.0, 0.0, 1.0, 0.0]
            };
        }
    }

    /// The rest point under barycentric coordinates `bary` of drawn triangle
    /// `triangle`.
    pub fn rest_point(&self, triangle: u32, bary: [f64; 3]) -> [f64; 3] {
        let t = self.triangles[triangle as usize];
        [0, 1, 2].map(|d| {
            (0..3)
                .map(|k| bary[k] * f64::from(self.rest_mm[t[k] as usize][d]))
                .sum()
        })
    }

    /// The point of the mechanical surface (`mech`: its rest vertices) under a point of
    /// the drawn surface: the closest point of the mechanical triangles its drawn
    /// triangle's corners are embedded in, as (mechanical triangle, barycentric
    /// coordinates).
    pub fn mechanical_point(
        &self,
        mech: &[[f32; 3]],
        triangle: u32,
        bary: [f64; 3],
    ) -> (u32, [f64; 3]) {
        let p = self.rest_point(triangle, bary);
        let mut best = (u32::MAX, [1.0, 0.0, 0.0], f64::INFINITY);
        for &v in &self.triangles[triangle as usize] {
            let e = &self.embed[v as usize];
            let [a, b, c] = e.corners.map(|i| mech[i as usize].map(f64::from));
            let l = closest_on_triangle(p, a, b, c);
            let q = [0, 1, 2].map(|d| l[0] * a[d] + l[1] * b[d] + l[2] * c[d]);
            let dist = norm(sub(p, q));
            if dist < best.2 {
                best = (e.triangle, l, dist);
            }
        }
        (best.0, best.1)
    }

    /// A value per mechanical vertex interpolated at the visual vertices.
    pub fn interpolate(&self, mech: &[f32], out: &mut [f32]) {
        for (o, e) in out.iter_mut().zip(&self.embed) {
            *o = (0..3)
                .map(|k| e.bary[k] * mech[e.corners[k] as usize])
                .sum();
        }
    }
}

fn sub3(a: [f32; 4], b: [f32; 4]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Each point's closest mechanical triangle (through a grid of triangle buckets), as
/// the barycentric coordinates of its projection on that plane and its height.
fn embed(mech: &[[f64; 3]], triangles: &[[u32; 3]], points: &[[f64; 3]]) -> Vec<Embed> {
    let (lo, hi) = crate::mesh::bounds_of(mech);
    let per_side = ((triangles.len() as f64 / 2.0).cbrt().ceil() as usize).clamp(1, 96);
    let size = [0, 1, 2].map(|d| ((hi[d] - lo[d]) / per_side as f64).max(1e-9));
    let cell = |p: [f64; 3]| {
        [0, 1, 2].map(|d| (((p[d] - lo[d]) / size[d]).floor() as i64).clamp(0, per_side as i64 - 1))
    };
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); per_side.pow(3)];
    let at = |c: [i64; 3]| c[0] as usize + per_side * (c[1] as usize + per_side * c[2] as usize);
    for (t, tri) in triangles.iter().enumerate() {
        let (a, b) = crate::mesh::bounds_of(&tri.map(|i| mech[i as usize]));
        let (c0, c1) = (cell(a), cell(b));
        for k in c0[2]..=c1[2] {
            for j in c0[1]..=c1[1] {
                for i in c0[0]..=c1[0] {
                    buckets[at([i, j, k])].push(t as u32);
                }
            }
        }
    }
    let smallest = size.iter().copied().fold(f64::INFINITY, f64::min);
    points
        .iter()
        .map(|&p| {
            let c = cell(p);
            let mut best = (u32::MAX, f64::INFINITY);
            // Rings of cells until the best distance is inside the searched box.
            for ring in 0..per_side as i64 {
                for k in (c[2] - ring).max(0)..=(c[2] + ring).min(per_side as i64 - 1) {
                    for j in (c[1] - ring).max(0)..=(c[1] + ring).min(per_side as i64 - 1) {
                        for i in (c[0] - ring).max(0)..=(c[0] + ring).min(per_side as i64 - 1) {
                            let shell = (i - c[0]).abs() == ring
                                || (j - c[1]).abs() == ring
                                || (k - c[2]).abs() == ring;
                            if !shell {
                                continue;
                            }
                            for &t in &buckets[at([i, j, k])] {
                                let [a, b, cc] = triangles[t as usize].map(|v| mech[v as usize]);
                                let l = closest_on_triangle(p, a, b, cc);
                                let q = [0, 1, 2].map(|d| l[0] * a[d] + l[1] * b[d] + l[2] * cc[d]);
                                let dist = norm(sub(p, q));
                                if dist < best.1 {
                                    best = (t, dist);
                                }
                            }
                        }
                    }
                }
                if best.1 <= ring as f64 * smallest {
                    break;
                }
            }
            let corners = triangles[best.0 as usize];
            let [a, b, c] = corners.map(|v| mech[v as usize]);
            let n = unit_normal(a, b, c);
            let height = dot(sub(p, a), n);
            let q = [0, 1, 2].map(|d| p[d] - height * n[d]);
            Embed {
                triangle: best.0,
                corners,
                bary: plane_bary(q, a, b, c).map(|x| x as f32),
                height_mm: height as f32,
            }
        })
        .collect()
}

/// Barycentric coordinates of `q` (in the plane of `abc`) with respect to `abc`.
fn plane_bary(q: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (v0, v1, v2) = (sub(b, a), sub(c, a), sub(q, a));
    let (d00, d01, d11) = (dot(v0, v0), dot(v0, v1), dot(v1, v1));
    let (d20, d21) = (dot(v2, v0), dot(v2, v1));
    let den = d00 * d11 - d01 * d01;
    if den == 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let lb = (d11 * d20 - d01 * d21) / den;
    let lc = (d00 * d21 - d01 * d20) / den;
    [1.0 - lb - lc, lb, lc]
}

/// How sharply a surface folds: the angle between the normals of the two triangles at
/// each edge, its largest and 99th percentile in degrees (`None` without an edge of two
/// triangles). A saw-tooth border shows as large angles; a smooth surface of fine
/// triangles has small ones.
pub fn crease_deg(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Option<(f64, f64)> {
    let p = |i: u32| vertices[i as usize].map(f64::from);
    let normals: Vec<[f64; 3]> = triangles
        .iter()
        .map(|t| unit_normal(p(t[0]), p(t[1]), p(t[2])))
        .collect();
    let mut edge_faces: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (f, t) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            edge_faces.entry((a.min(b), a.max(b))).or_default().push(f);
        }
    }
    let mut angles: Vec<f64> = edge_faces
        .values()
        .filter(|f| f.len() == 2)
        .map(|f| {
            dot(normals[f[0]], normals[f[1]])
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        })
        .collect();
    if angles.is_empty() {
        return None;
    }
    angles.sort_by(f64::total_cmp);
    let p99 = angles[((angles.len() - 1) as f64 * 0.99).round() as usize];
    Some((*angles.last().expect("not empty"), p99))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// An octahedron: six vertices, eight triangles, outward.
    fn octahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let v = vec![
            [10.0, 0.0, 0.0],
            [-10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0, -10.0, 0.0],
            [0.0, 0.0, 10.0],
            [0.0, 0.0, -10.0],
        ];
        let t = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        (v, t)
    }

    #[test]
    fn the_rest_pose_is_exact_and_a_rigid_motion_moves_it_rigidly() {
        let (v, t) = octahedron();
        let vis = VisualSurface::subdivided(&v, &t, 2);
        assert_eq!(vis.triangles.len(), 8 * 16);
        let n = vis.rest_mm.len();
        let (mut pos, mut nrm, mut sums) =
            (vec![[0.0; 4]; n], vec![[0.0; 4]; n], vec![[0.0; 3]; n]);
        let rest: Vec<[f32; 4]> = v.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect();
        vis.deform(&rest, &mut pos, &mut nrm, &mut sums);
        for (a, b) in pos.iter().zip(&vis.rest_mm) {
            for d in 0..3 {
                assert!((a[d] - b[d]).abs() < 2e-5, "{a:?} {b:?}");
            }
        }
        // A seeded rotation about a random axis and a translation.
        let mut rng = Rng::seed(5);
        for _ in 0..4 {
            let axis = [rng.normal(), rng.normal(), rng.normal()];
            let l = norm(axis);
            let k = axis.map(|x| x / l);
            let angle = rng.range(-3.0, 3.0);
            let shift = [
                rng.range(-20.0, 20.0),
                rng.range(-20.0, 20.0),
                rng.range(-20.0, 20.0),
            ];
            let rotate = |p: [f64; 3]| {
                // Rodrigues' formula.
                let (c, s) = (angle.cos(), angle.sin());
                let kxp = cross(k, p);
                let kp = dot(k, p);
                [0, 1, 2].map(|d| p[d] * c + kxp[d] * s + k[d] * kp * (1.0 - c) + shift[d])
            };
            let moved: Vec<[f32; 4]> = v
                .iter()
                .map(|p| {
                    let q = rotate(p.map(f64::from));
                    [q[0] as f32, q[1] as f32, q[2] as f32, 0.0]
                })
                .collect();
            vis.deform(&moved, &mut pos, &mut nrm, &mut sums);
            for (a, b) in pos.iter().zip(&vis.rest_mm) {
                let q = rotate(b.map(f64::from));
                for d in 0..3 {
                    assert!((f64::from(a[d]) - q[d]).abs() < 1e-4, "{a:?} {q:?}");
                }
            }
        }
    }

    #[test]
    fn loop_subdivision_of_an_octahedron_rounds_it_towards_a_sphere() {
        let (v, t) = octahedron();
        let vis = VisualSurface::subdivided(&v, &t, 3);
        let radii: Vec<f64> = vis.rest_mm.iter().map(|p| norm(p.map(f64::from))).collect();
        let (lo, hi) = radii
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &r| (a.min(r), b.max(r)));
        // The octahedron's corners are at 10, its face centres at 5.77; Loop's limit
        // is far rounder.
        assert!(hi / lo < 1.25, "{lo} {hi}");
        // The octahedron's edges fold by 70.5°; three levels leave 31.7° (measured:
        // the largest, next to its valence-4 corners).
        let (v8, _) = crease_deg(&v, &t).expect("edges");
        let (vs, _) = crease_deg(&vis.rest_mm, &vis.triangles).expect("edges");
        assert!(
            (v8 - 70.53).abs() < 0.01 && vs < v8 / 2.0,
            "octahedron {v8}°, subdivided {vs}°"
        );
    }
}
