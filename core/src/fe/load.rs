//! The probe load: a total force `F` (N) along a unit direction `t`, spread uniformly
//! over the part of the surface within `r_tool` of the probe point `s`.
//!
//! Consistent nodal load: with the surface shape functions `N_i`,
//! `f_i = F t · w_i / Σ_j w_j`, `w_i = ∫_{Γ ∩ B(s, r)} N_i dA`. The integral is taken
//! with a one-point rule on sub-triangles (each boundary face near s is split 4^L
//! times, L chosen so sub-triangles are ≤ r/6 across), so the load patch moves
//! smoothly with s, and the normalization makes `Σ_i f_i = F t` exactly. A point load
//! would not do: its displacement grows without bound as the mesh is refined (the
//! Boussinesq solution is singular), so force feedback would depend on the mesh.

use super::FeError;
use super::shape::tri_values;
use super::space::Space;
use crate::axis::closest_point;
use crate::mesh::{cross, norm, sub};

/// A point on the boundary: face index, barycentric coordinates on its corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    pub face: usize,
    pub bary: [f64; 3],
    pub point: [f64; 3],
    /// Unit outward normal of the face.
    pub normal: [f64; 3],
    /// Distance from the requested point (0 if it was on the surface).
    pub distance_mm: f64,
}

fn face_corners(space: &Space, f: usize) -> [[f64; 3]; 3] {
    let face = space.face(f);
    [0, 1, 2].map(|i| space.nodes[face[i] as usize])
}

fn unit_normal(c: [[f64; 3]; 3]) -> [f64; 3] {
    let n = cross(sub(c[1], c[0]), sub(c[2], c[0]));
    let l = norm(n);
    n.map(|v| v / l)
}

/// Projects `p` onto the closest point of the allowed boundary faces.
pub fn project(space: &Space, allowed: &[bool], p: [f64; 3]) -> Option<SurfacePoint> {
    let idx: Vec<usize> = (0..space.face_count()).filter(|&f| allowed[f]).collect();
    let tris: Vec<[u32; 3]> = idx
        .iter()
        .map(|&f| {
            let face = space.face(f);
            [face[0], face[1], face[2]]
        })
        .collect();
    let hit = closest_point(&space.nodes, &tris, p)?;
    let face = idx[hit.triangle as usize];
    Some(SurfacePoint {
        face,
        bary: hit.bary,
        point: hit.point,
        normal: unit_normal(face_corners(space, face)),
        distance_mm: hit.distance,
    })
}

/// The all-node load vector (`3 × nodes`) of the probe.
pub fn probe_load(
    space: &Space,
    s: &SurfacePoint,
    dir: [f64; 3],
    force_n: f64,
    radius_mm: f64,
) -> Result<Vec<f64>, FeError> {
    if !force_n.is_finite() {
        return Err(FeError::ForceNotFinite { force_n });
    }
    let dl = norm(dir);
    if !(dl.is_finite() && dl > 0.0) {
        return Err(FeError::NoDirection { dir });
    }
    let t = dir.map(|v| v / dl);
    let mut f = vec![0.0; 3 * space.nodes.len()];
    for (n, w) in probe_weights(space, s, radius_mm)? {
        for d in 0..3 {
            f[3 * n as usize + d] += force_n * t[d] * w;
        }
    }
    Ok(f)
}

/// Per-node shares (summing to 1) of a unit probe force at `s`: the consistent load of
/// direction `t` and force `F` is `F t w_n` at node n.
pub fn probe_weights(
    space: &Space,
    s: &SurfacePoint,
    radius_mm: f64,
) -> Result<Vec<(u32, f64)>, FeError> {
    if !(radius_mm.is_finite() && radius_mm > 0.0) {
        return Err(FeError::ToolRadius { radius_mm });
    }
    let p2 = space.element == super::Element::P2;
    let npf = space.element.nodes_per_face();
    let mut weights: Vec<(u32, f64)> = Vec::new();
    let mut acc = [0.0; 6];
    for f in 0..space.face_count() {
        if crate::disk::face_weights(face_corners(space, f), p2, s.point, radius_mm, &mut acc) {
            let face = space.face(f);
            for a in 0..npf {
                if acc[a] != 0.0 {
                    weights.push((face[a], acc[a]));
                }
            }
        }
    }
    // A node shared by several faces appears once per face: merge.
    weights.sort_unstable_by_key(|w| w.0);
    let mut merged: Vec<(u32, f64)> = Vec::with_capacity(weights.len());
    for (n, w) in weights {
        match merged.last_mut() {
            Some(last) if last.0 == n => last.1 += w,
            _ => merged.push((n, w)),
        }
    }
    // A tool as large as the organ is a plate, not a probe: refused by the same bound
    // as the scenes' load stencils (a huge radius once loaded the fixed region too).
    if merged.len() > crate::axis::MAX_LOAD_NODES {
        let (lo, hi) = crate::mesh::bounds_of(&space.nodes);
        return Err(FeError::ToolTooLarge {
            radius_mm,
            most: crate::axis::MAX_LOAD_NODES,
            across_mm: norm(sub(hi, lo)),
        });
    }
    let total: f64 = merged.iter().map(|w| w.1).sum();
    if total > 0.0 {
        Ok(merged.into_iter().map(|(n, w)| (n, w / total)).collect())
    } else {
        // Tool smaller than the quadrature resolution: a consistent point load at s.
        let mut nvals = [0.0; 6];
        tri_values(p2, s.bary, &mut nvals);
        let face = space.face(s.face);
        Ok((0..npf).map(|a| (face[a], nvals[a])).collect())
    }
}

/// The all-node vector `n̂` with `n̂·u = value_at(u, s)·dir`: the probe point's
/// displacement along `dir` as a linear functional.
pub fn probe_functional(space: &Space, s: &SurfacePoint, dir: [f64; 3]) -> Vec<f64> {
    let mut nvals = [0.0; 6];
    tri_values(space.element == super::Element::P2, s.bary, &mut nvals);
    let mut out = vec![0.0; 3 * space.nodes.len()];
    for (a, &node) in space.face(s.face).iter().enumerate() {
        for d in 0..3 {
            out[3 * node as usize + d] += nvals[a] * dir[d];
        }
    }
    out
}

/// Interpolates a nodal field (`3 × nodes`) at a surface point.
pub fn value_at(space: &Space, u: &[f64], s: &SurfacePoint) -> [f64; 3] {
    let mut nvals = [0.0; 6];
    tri_values(space.element == super::Element::P2, s.bary, &mut nvals);
    let face = space.face(s.face);
    let mut out = [0.0; 3];
    for a in 0..space.element.nodes_per_face() {
        for d in 0..3 {
            out[d] += nvals[a] * u[3 * face[a] as usize + d];
        }
    }
    out
}

/// Sum of a nodal vector's x, y, z parts.
pub fn resultant(f: &[f64]) -> [f64; 3] {
    let mut r = [0.0; 3];
    for (i, v) in f.iter().enumerate() {
        r[i % 3] += v;
    }
    r
}
