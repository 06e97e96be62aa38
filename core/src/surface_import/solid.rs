//! A surface as an implicit solid: the signed distance, its sign from the closest
//! feature's pseudo-normal (a validated closed manifold) or from the generalized
//! winding number (a surface as segmentation gives it: [`super::winding`]).

use std::collections::HashMap;

use super::TriSurface;
use super::winding::Winding;
use crate::mesh::stuffing::Implicit;
use crate::mesh::{cross, dot, norm, sub};

/// A validated closed surface as an implicit solid (signed distance).
#[derive(Debug)]
pub struct SurfaceSolid {
    s: TriSurface,
    lo: [f64; 3],
    hi: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    buckets: Vec<Vec<u32>>,
    face_n: Vec<[f64; 3]>,
    edge_n: HashMap<(u32, u32), [f64; 3]>,
    vert_n: Vec<[f64; 3]>,
    /// Where set, the sign is the winding number's (inside where `w > ½`), with the
    /// volume inside.
    winding: Option<(Winding, f64)>,
}

impl SurfaceSolid {
    /// A surface that passed [`TriSurface::validate`]: the sign from pseudo-normals.
    pub fn new(s: TriSurface) -> SurfaceSolid {
        Self::build(s, None)
    }

    /// Any triangle soup with a clear inside (see [`Winding::inside_volume`]): the sign
    /// from its winding number.
    /// `inside_mm3`: the volume where `w > ½` ([`Winding::inside_volume`]).
    pub fn by_winding(s: TriSurface, winding: Winding, inside_mm3: f64) -> SurfaceSolid {
        Self::build(s, Some((winding, inside_mm3)))
    }

    /// The volume the solid encloses (mm³): by the divergence theorem for a validated
    /// surface, the winding number's inside otherwise.
    pub fn enclosed_volume_mm3(&self) -> f64 {
        self.winding
            .as_ref()
            .map_or_else(|| self.s.volume(), |w| w.1)
    }

    /// Whether the sign comes from the winding number.
    pub fn signed_by_winding(&self) -> bool {
        self.winding.is_some()
    }

    /// Builds the distance acceleration and pseudo-normals.
    fn build(s: TriSurface, winding: Option<(Winding, f64)>) -> SurfaceSolid {
        let (lo, hi) = crate::mesh::bounds_of(&s.vertices);
        let diag = norm(sub(hi, lo));
        let cell = (diag / 48.0).max(1e-9);
        let dims = [0, 1, 2].map(|d| (((hi[d] - lo[d]) / cell).floor() as usize + 1).max(1));
        let mut buckets = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let face_n: Vec<[f64; 3]> = s
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| s.vertices[i as usize]);
                let n = cross(sub(b, a), sub(c, a));
                let l = norm(n);
                n.map(|x| x / l)
            })
            .collect();
        let mut edge_n: HashMap<(u32, u32), [f64; 3]> = HashMap::new();
        let mut vert_n = vec![[0.0; 3]; s.vertices.len()];
        for (t, tri) in s.triangles.iter().enumerate() {
            let pts = tri.map(|i| s.vertices[i as usize]);
            let (tlo, thi) = crate::mesh::bounds_of(&pts);
            let c0 = [0, 1, 2].map(|d| (((tlo[d] - lo[d]) / cell) as usize).min(dims[d] - 1));
            let c1 = [0, 1, 2].map(|d| (((thi[d] - lo[d]) / cell) as usize).min(dims[d] - 1));
            for k in c0[2]..=c1[2] {
                for j in c0[1]..=c1[1] {
                    for i in c0[0]..=c1[0] {
                        buckets[i + dims[0] * (j + dims[1] * k)].push(t as u32);
                    }
                }
            }
            for e in 0..3 {
                let (a, b) = (tri[e], tri[(e + 1) % 3]);
                let n = edge_n.entry((a.min(b), a.max(b))).or_insert([0.0; 3]);
                for d in 0..3 {
                    n[d] += face_n[t][d];
                }
                // Angle at vertex e.
                let u = sub(pts[(e + 1) % 3], pts[e]);
                let w = sub(pts[(e + 2) % 3], pts[e]);
                let ang = (dot(u, w) / (norm(u) * norm(w))).clamp(-1.0, 1.0).acos();
                for d in 0..3 {
                    vert_n[tri[e] as usize][d] += ang * face_n[t][d];
                }
            }
        }
        SurfaceSolid {
            s,
            lo,
            hi,
            cell,
            dims,
            buckets,
            face_n,
            edge_n,
            vert_n,
            winding,
        }
    }

    pub fn surface(&self) -> &TriSurface {
        &self.s
    }

    /// Closest triangle, barycentric coordinates and distance.
    fn closest(&self, p: [f64; 3]) -> (usize, [f64; 3], f64) {
        let c = [0, 1, 2].map(|d| {
            (((p[d] - self.lo[d]) / self.cell).floor() as i64).clamp(0, self.dims[d] as i64 - 1)
        });
        // Distance from p to the grid box (rings start counting from there).
        let outside: f64 = (0..3)
            .map(|d| (self.lo[d] - p[d]).max(p[d] - self.hi[d]).max(0.0).powi(2))
            .sum::<f64>()
            .sqrt();
        let mut best = (0usize, [1.0, 0.0, 0.0], f64::INFINITY);
        let max_ring = *self.dims.iter().max().expect("an array of 3") as i64;
        for ring in 0..=max_ring {
            if best.2 < outside + (ring as f64 - 1.0) * self.cell {
                break;
            }
            for k in c[2] - ring..=c[2] + ring {
                for j in c[1] - ring..=c[1] + ring {
                    for i in c[0] - ring..=c[0] + ring {
                        let on_shell = (i - c[0]).abs() == ring
                            || (j - c[1]).abs() == ring
                            || (k - c[2]).abs() == ring;
                        if !on_shell || i < 0 || j < 0 || k < 0 {
                            continue;
                        }
                        let (i, j, k) = (i as usize, j as usize, k as usize);
                        if i >= self.dims[0] || j >= self.dims[1] || k >= self.dims[2] {
                            continue;
                        }
                        for &t in &self.buckets[i + self.dims[0] * (j + self.dims[1] * k)] {
                            let tri =
                                self.s.triangles[t as usize].map(|v| self.s.vertices[v as usize]);
                            let bary = crate::axis::closest_point(&tri, &[[0, 1, 2]], p)
                                .expect("the surface was checked finite when it was read")
                                .bary;
                            let q = [0, 1, 2].map(|d| {
                                bary[0] * tri[0][d] + bary[1] * tri[1][d] + bary[2] * tri[2][d]
                            });
                            let dist = norm(sub(p, q));
                            if dist < best.2 {
                                best = (t as usize, bary, dist);
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

impl Implicit for SurfaceSolid {
    fn value(&self, p: [f64; 3]) -> f64 {
        let (t, bary, dist) = self.closest(p);
        if let Some((w, _)) = &self.winding {
            return if w.at(p) > 0.5 { -dist } else { dist };
        }
        let tri = self.s.triangles[t];
        let zeros = bary.iter().filter(|&&b| b <= 1e-12).count();
        let n = match zeros {
            2 => {
                let k = (0..3).find(|&k| bary[k] > 1e-12).expect("one vertex");
                self.vert_n[tri[k] as usize]
            }
            1 => {
                let k = (0..3).find(|&k| bary[k] <= 1e-12).expect("one zero");
                let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                self.edge_n[&(a.min(b), a.max(b))]
            }
            _ => self.face_n[t],
        };
        let q = [0, 1, 2].map(|d| {
            (0..3)
                .map(|k| bary[k] * self.s.vertices[tri[k] as usize][d])
                .sum::<f64>()
        });
        if dot(sub(p, q), n) < 0.0 { -dist } else { dist }
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.lo, self.hi)
    }
}
