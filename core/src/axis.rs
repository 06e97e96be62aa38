//! Discretization of one parameter axis and its interpolation stencils.
//!
//! Each parameter axis `p_j` of a separated representation carries nodal values
//! `P_{j,k}(node)`; between nodes a value is interpolated by a *stencil*: at most three
//! `(node, weight)` pairs with `P_{j,k}(p) = Σ_s w_s P_{j,k}(node_s)`.
//!
//! - **Grid**: a 1-D strictly increasing grid `g_0 < … < g_{M-1}`, piecewise-linear hat
//!   functions: for `g_i ≤ p ≤ g_{i+1}`, `w = ((g_{i+1} − p)/h, (p − g_i)/h)`. Exact on
//!   linear data.
//! - **Surface**: a triangulated surface (e.g. the palpable region of an organ) with
//!   nodal values at its vertices; a point is given as a triangle and barycentric
//!   coordinates `(λ_0, λ_1, λ_2)`, `Σ λ = 1`, and the stencil is the triangle's corners.
//! - **Discrete**: a finite set of labelled values (a load direction, a species count);
//!   a value is an index, or a mix of up to three entries (a force direction `t` mixes
//!   the x, y and z vademecums by linearity).
//!
//! Outside the trained range a value is **clamped** to the nearest trained value and the
//! caller is told ([`Stencil::clamped`]); nothing is extrapolated, and non-finite input
//! is an error rather than a NaN in the output.

use crate::mesh::{dot, sub};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A point of the palpable region, in the parametric axis's numbering (a palpation
/// scene's probe point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbePoint {
    /// Triangle of the parametric (palpable) surface.
    pub triangle: u32,
    /// Barycentric coordinates in that triangle's vertex order.
    pub bary: [f64; 3],
}

/// How an axis is discretized. Stored in the meta-model header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Discretization {
    /// Piecewise-linear on a strictly increasing grid.
    Grid { nodes: Vec<f64> },
    /// Barycentric on a triangulated surface; `vertices` in the field's length unit.
    Surface {
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
    },
    /// A finite set of labelled entries.
    Discrete { labels: Vec<String> },
    /// A triangulated surface carrying three values per vertex (node `3·v + c`): the
    /// probe position and the load direction folded into one parametric index, so a
    /// force along any direction `t` is one particularization with weights
    /// `λ_i t_c` (barycentric × direction).
    SurfaceVector {
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        /// The model's field node at each vertex (empty if none), so the contact
        /// rows of a probe point are known.
        field_nodes: Vec<u32>,
    },
    /// Unit nodal forces at the surface FE nodes under any tool position (node
    /// `3·j + c`: load node `j`, direction `c`). A probe of radius `radius_mm` at a point
    /// `s` of face `f` is the exact combination `Σ_j w_j(s) t_c` of these loads, with the
    /// consistent disk shares `w_j(s)` of [`crate::disk`]: the particularization is the
    /// FE load itself, not an interpolation between responses to other loads.
    SurfaceLoad {
        /// Position of every load node (corners, then for P2 the midsides), mm.
        positions: Vec<[f64; 3]>,
        /// Faces over the load nodes: 3 corners, then 3 midsides on the edges 01, 12,
        /// 02 (all `u32::MAX` for P1).
        faces: Vec<[u32; 6]>,
        /// Whether the probe may be centred on each face (the palpable region; the
        /// other faces are the rim a tool near the border still presses).
        palpable: Vec<bool>,
        /// The model's field node at each load node (`u32::MAX` if none).
        field_nodes: Vec<u32>,
        /// Tool radius the shares integrate, mm.
        radius_mm: f64,
    },
}

/// Most load nodes a tool may cover in one particularization (the stack buffer of the
/// allocation-free path): a 10 mm tool on the medium P2 liver covers about 150.
pub const MAX_LOAD_NODES: usize = 1024;

/// A parameter value to particularize at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ParamValue {
    /// A real value on a [`Discretization::Grid`] axis (or an integral value on a discrete one).
    Scalar(f64),
    /// An entry of a [`Discretization::Discrete`] axis.
    Index(usize),
    /// A linear combination of the first three entries of a discrete axis, e.g. a unit
    /// force direction `(t_x, t_y, t_z)` over an axis of directions x, y, z.
    Mix([f64; 3]),
    /// A point on a [`Discretization::Surface`] axis.
    Surface { triangle: u32, bary: [f64; 3] },
    /// A point and a direction mix on a [`Discretization::SurfaceVector`] axis.
    SurfaceMix {
        triangle: u32,
        bary: [f64; 3],
        mix: [f64; 3],
    },
}

/// Why a parameter value could not be turned into a stencil.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AxisError {
    #[error("value {value} is not finite")]
    NotFinite { value: f64 },
    #[error("a {given} value was given to a {axis} axis")]
    WrongKind {
        given: &'static str,
        axis: &'static str,
    },
    #[error("value {value} is not an integer index")]
    NotAnIndex { value: f64 },
    #[error("triangle {triangle} does not exist (the surface has {count} triangles)")]
    NoSuchTriangle { triangle: u32, count: usize },
    #[error("barycentric coordinates {bary:?} have no positive part")]
    DegenerateBary { bary: [f64; 3] },
    #[error("a mix needs a discrete axis of at most 3 entries; this one has {len}")]
    MixTooWide { len: usize },
    #[error("invalid discretization: {0}")]
    Invalid(String),
    #[error("the tool covers more than {capacity} load nodes (a stencil holds at most that many)")]
    StencilFull { capacity: usize },
}

/// Most entries a stencil has: a surface point mixing three load directions
/// (3 corners × 3 components).
pub const MAX_STENCIL: usize = 9;

/// Interpolation weights for one parameter value: `Σ_{s<len} weight[s] · P(node[s])`.
/// Entries past `len` have weight 0 and a valid node index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stencil {
    pub nodes: [u32; MAX_STENCIL],
    pub weights: [f64; MAX_STENCIL],
    pub len: usize,
    /// The value lay outside the trained range and was clamped to it.
    pub clamped: bool,
}

impl Stencil {
    fn single(node: u32, clamped: bool) -> Self {
        Stencil::from3([node; 3], [1.0, 0.0, 0.0], 1, clamped)
    }

    fn from3(nodes: [u32; 3], weights: [f64; 3], len: usize, clamped: bool) -> Self {
        let mut s = Stencil {
            nodes: [nodes[0]; MAX_STENCIL],
            weights: [0.0; MAX_STENCIL],
            len,
            clamped,
        };
        s.nodes[..3].copy_from_slice(&nodes);
        s.weights[..3].copy_from_slice(&weights);
        s
    }
}

impl Discretization {
    /// Number of nodal values this axis stores per mode.
    pub fn node_count(&self) -> usize {
        match self {
            Discretization::Grid { nodes } => nodes.len(),
            Discretization::Surface { vertices, .. } => vertices.len(),
            Discretization::Discrete { labels } => labels.len(),
            Discretization::SurfaceVector { vertices, .. } => 3 * vertices.len(),
            Discretization::SurfaceLoad { positions, .. } => 3 * positions.len(),
        }
    }

    pub fn kind_name(&self) -> &'static str {
        match self {
            Discretization::Grid { .. } => "grid",
            Discretization::Surface { .. } => "surface",
            Discretization::Discrete { .. } => "discrete",
            Discretization::SurfaceVector { .. } => "surface-vector",
            Discretization::SurfaceLoad { .. } => "surface-load",
        }
    }

    /// Checks the invariants the stencils rely on (called on construction and on load).
    pub fn validate(&self) -> Result<(), AxisError> {
        let bad = |s: String| Err(AxisError::Invalid(s));
        match self {
            Discretization::Grid { nodes } => {
                if nodes.is_empty() {
                    return bad("a grid needs at least one node".into());
                }
                if let Some(v) = nodes.iter().find(|v| !v.is_finite()) {
                    return bad(format!("grid node {v} is not finite"));
                }
                if let Some(i) = nodes.windows(2).position(|w| w[0] >= w[1]) {
                    return bad(format!(
                        "grid nodes must increase strictly; node {} ({}) ≥ node {} ({})",
                        i,
                        nodes[i],
                        i + 1,
                        nodes[i + 1]
                    ));
                }
            }
            Discretization::Surface {
                vertices,
                triangles,
            }
            | Discretization::SurfaceVector {
                vertices,
                triangles,
                ..
            } => {
                if triangles.is_empty() {
                    return bad("a surface axis needs at least one triangle".into());
                }
                if let Some(v) = vertices.iter().find(|v| v.iter().any(|c| !c.is_finite())) {
                    return bad(format!("surface vertex {v:?} is not finite"));
                }
                for (t, tri) in triangles.iter().enumerate() {
                    if let Some(&i) = tri.iter().find(|&&i| i as usize >= vertices.len()) {
                        return bad(format!(
                            "triangle {t} names vertex {i}, but there are {} vertices",
                            vertices.len()
                        ));
                    }
                }
            }
            Discretization::Discrete { labels } => {
                if labels.is_empty() {
                    return bad("a discrete axis needs at least one entry".into());
                }
            }
            Discretization::SurfaceLoad {
                positions,
                faces,
                palpable,
                field_nodes,
                radius_mm,
            } => {
                if !(radius_mm.is_finite() && *radius_mm > 0.0) {
                    return bad(format!("tool radius {radius_mm} mm must be positive"));
                }
                if faces.is_empty() || palpable.len() != faces.len() {
                    return bad(format!(
                        "a load axis needs faces and one palpable flag each ({} faces, {} flags)",
                        faces.len(),
                        palpable.len()
                    ));
                }
                if field_nodes.len() != positions.len() {
                    return bad(format!(
                        "{} field nodes for {} load nodes",
                        field_nodes.len(),
                        positions.len()
                    ));
                }
                if let Some(v) = positions.iter().find(|v| v.iter().any(|c| !c.is_finite())) {
                    return bad(format!("load node {v:?} is not finite"));
                }
                for (f, face) in faces.iter().enumerate() {
                    let p2 = face[3] != u32::MAX;
                    let used = if p2 { &face[..] } else { &face[..3] };
                    if let Some(&i) = used.iter().find(|&&i| i as usize >= positions.len()) {
                        return bad(format!(
                            "face {f} names load node {i}, but there are {}",
                            positions.len()
                        ));
                    }
                    if !p2 && face[4..].iter().any(|&i| i != u32::MAX)
                        || p2 && face[4..].contains(&u32::MAX)
                    {
                        return bad(format!("face {f} mixes P1 and P2 midsides: {face:?}"));
                    }
                }
            }
        }
        Ok(())
    }

    /// The interpolation stencil of `value`. Allocation-free; O(log M) on a grid.
    pub fn stencil(&self, value: ParamValue) -> Result<Stencil, AxisError> {
        match (self, value) {
            (Discretization::Grid { nodes }, ParamValue::Scalar(p)) => grid_stencil(nodes, p),
            (Discretization::Discrete { labels }, ParamValue::Index(i)) => {
                Ok(index_stencil(labels.len(), i))
            }
            (Discretization::Discrete { labels }, ParamValue::Scalar(p)) => {
                if !p.is_finite() {
                    return Err(AxisError::NotFinite { value: p });
                }
                if p.fract() != 0.0 {
                    return Err(AxisError::NotAnIndex { value: p });
                }
                if p < 0.0 {
                    return Ok(Stencil::single(0, true));
                }
                Ok(index_stencil(labels.len(), p as usize))
            }
            (Discretization::Discrete { labels }, ParamValue::Mix(w)) => {
                if labels.len() > 3 {
                    return Err(AxisError::MixTooWide { len: labels.len() });
                }
                if let Some(&v) = w.iter().find(|v| !v.is_finite()) {
                    return Err(AxisError::NotFinite { value: v });
                }
                let mut s = Stencil::from3([0, 1, 2], w, 3, false);
                // Entries beyond the axis get weight 0 and a valid node.
                for k in labels.len()..3 {
                    s.clamped |= s.weights[k] != 0.0;
                    s.nodes[k] = 0;
                    s.weights[k] = 0.0;
                }
                Ok(s)
            }
            (
                Discretization::Surface {
                    vertices: _,
                    triangles,
                },
                ParamValue::Surface { triangle, bary },
            ) => surface_stencil(triangles, triangle, bary),
            (
                Discretization::SurfaceVector { triangles, .. },
                ParamValue::SurfaceMix {
                    triangle,
                    bary,
                    mix,
                },
            ) => {
                if let Some(&v) = mix.iter().find(|v| !v.is_finite()) {
                    return Err(AxisError::NotFinite { value: v });
                }
                let corner = surface_stencil(triangles, triangle, bary)?;
                let mut s = corner;
                s.len = 9;
                for i in 0..3 {
                    for c in 0..3 {
                        s.nodes[3 * i + c] = 3 * corner.nodes[i] + c as u32;
                        s.weights[3 * i + c] = corner.weights[i] * mix[c];
                    }
                }
                Ok(s)
            }
            (axis, given) => Err(AxisError::WrongKind {
                given: match given {
                    ParamValue::Scalar(_) => "scalar",
                    ParamValue::Index(_) => "index",
                    ParamValue::Mix(_) => "mix",
                    ParamValue::Surface { .. } => "surface-point",
                    ParamValue::SurfaceMix { .. } => "surface-mix",
                },
                // A load axis has no ≤ 9-node stencil: SeparatedModel::particularize
                // takes its shares from `load_shares`.
                axis: axis.kind_name(),
            }),
        }
    }
}

impl Discretization {
    /// [`Self::load_shares`] for a probe value `SurfaceMix { triangle: face, bary, mix }`;
    /// returns (shares written, clamped, the direction mix).
    pub fn probe_shares(
        &self,
        value: ParamValue,
        out: &mut [(u32, f64)],
    ) -> Result<(usize, bool, [f64; 3]), AxisError> {
        let ParamValue::SurfaceMix {
            triangle,
            bary,
            mix,
        } = value
        else {
            return Err(AxisError::WrongKind {
                given: "non-surface-mix",
                axis: self.kind_name(),
            });
        };
        if let Some(&v) = mix.iter().find(|v| !v.is_finite()) {
            return Err(AxisError::NotFinite { value: v });
        }
        let (len, clamped) = self.load_shares(triangle, bary, out)?;
        Ok((len, clamped, mix))
    }

    /// The consistent shares `(load node, w_j)` of a tool centred at barycentric `bary`
    /// of face `face` of a [`Discretization::SurfaceLoad`] axis, written to `out`;
    /// returns how many. Allocation-free; O(faces) (a tool is a few faces wide, but the
    /// face list is scanned by bounding sphere). `clamped` reports a centre outside the
    /// palpable region. Shares sum to 1.
    pub fn load_shares(
        &self,
        face: u32,
        bary: [f64; 3],
        out: &mut [(u32, f64)],
    ) -> Result<(usize, bool), AxisError> {
        let Discretization::SurfaceLoad {
            positions,
            faces,
            palpable,
            radius_mm,
            ..
        } = self
        else {
            return Err(AxisError::WrongKind {
                given: "surface-load point",
                axis: self.kind_name(),
            });
        };
        let f0 = *faces.get(face as usize).ok_or(AxisError::NoSuchTriangle {
            triangle: face,
            count: faces.len(),
        })?;
        if let Some(&v) = bary.iter().find(|v| !v.is_finite()) {
            return Err(AxisError::NotFinite { value: v });
        }
        let sum: f64 = bary.iter().map(|b| b.max(0.0)).sum();
        if sum <= 0.0 {
            return Err(AxisError::DegenerateBary { bary });
        }
        let b = bary.map(|v| v.max(0.0) / sum);
        let corners = |f: &[u32; 6]| [0, 1, 2].map(|i| positions[f[i] as usize]);
        let c0 = corners(&f0);
        let center = [0, 1, 2].map(|d| b[0] * c0[0][d] + b[1] * c0[1][d] + b[2] * c0[2][d]);
        let p2 = f0[3] != u32::MAX;
        let npf = if p2 { 6 } else { 3 };
        let mut len = 0usize;
        let mut acc = [0.0; 6];
        for f in faces {
            // Most faces are far: reject them by bounding boxes before the disk rule
            // (a few comparisons instead of three square roots each).
            let c = corners(f);
            let r = *radius_mm;
            if (0..3).any(|d| {
                let lo = c[0][d].min(c[1][d]).min(c[2][d]);
                let hi = c[0][d].max(c[1][d]).max(c[2][d]);
                lo > center[d] + r || hi < center[d] - r
            }) {
                continue;
            }
            if !crate::disk::face_weights(c, p2, center, r, &mut acc) {
                continue;
            }
            for a in 0..npf {
                if acc[a] == 0.0 {
                    continue;
                }
                // Merge a node shared by several faces (a short linear scan: the
                // stencil has tens of entries).
                match out[..len].iter_mut().find(|e| e.0 == f[a]) {
                    Some(e) => e.1 += acc[a],
                    None => {
                        if len == out.len() {
                            return Err(AxisError::StencilFull {
                                capacity: out.len(),
                            });
                        }
                        out[len] = (f[a], acc[a]);
                        len += 1;
                    }
                }
            }
        }
        let total: f64 = out[..len].iter().map(|e| e.1).sum();
        if total > 0.0 {
            for e in &mut out[..len] {
                e.1 /= total;
            }
        } else {
            // Tool smaller than the quadrature resolution: a consistent point load.
            let mut nvals = [0.0; 6];
            crate::disk::tri_shape(p2, b, &mut nvals);
            len = npf.min(out.len());
            for a in 0..len {
                out[a] = (f0[a], nvals[a]);
            }
        }
        Ok((len, !palpable[face as usize]))
    }
}

fn index_stencil(len: usize, i: usize) -> Stencil {
    if i < len {
        Stencil::single(i as u32, false)
    } else {
        Stencil::single((len - 1) as u32, true)
    }
}

fn grid_stencil(nodes: &[f64], p: f64) -> Result<Stencil, AxisError> {
    if !p.is_finite() {
        return Err(AxisError::NotFinite { value: p });
    }
    let last = nodes.len() - 1;
    if p <= nodes[0] {
        return Ok(Stencil::single(0, p < nodes[0]));
    }
    if p >= nodes[last] {
        return Ok(Stencil::single(last as u32, p > nodes[last]));
    }
    // First node strictly greater than p; 1 ≤ hi ≤ last because of the checks above.
    let hi = nodes.partition_point(|&g| g <= p);
    let lo = hi - 1;
    let h = nodes[hi] - nodes[lo];
    let t = (p - nodes[lo]) / h;
    Ok(Stencil::from3(
        [lo as u32, hi as u32, lo as u32],
        [1.0 - t, t, 0.0],
        2,
        false,
    ))
}

fn surface_stencil(
    triangles: &[[u32; 3]],
    triangle: u32,
    bary: [f64; 3],
) -> Result<Stencil, AxisError> {
    let Some(tri) = triangles.get(triangle as usize) else {
        return Err(AxisError::NoSuchTriangle {
            triangle,
            count: triangles.len(),
        });
    };
    if let Some(&v) = bary.iter().find(|v| !v.is_finite()) {
        return Err(AxisError::NotFinite { value: v });
    }
    // Tolerance for "on the triangle": a few ulps of the coordinates' scale.
    const EPS: f64 = 1e-12;
    let sum: f64 = bary.iter().sum();
    let inside = bary.iter().all(|&b| b >= -EPS) && (sum - 1.0).abs() <= 1e-9;
    let mut w = bary.map(|b| b.max(0.0));
    let s: f64 = w.iter().sum();
    if s <= 0.0 {
        return Err(AxisError::DegenerateBary { bary });
    }
    w = w.map(|b| b / s);
    Ok(Stencil::from3(*tri, w, 3, !inside))
}

/// The closest point of a triangulated surface to `p`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    pub triangle: u32,
    pub bary: [f64; 3],
    pub point: [f64; 3],
    pub distance: f64,
}

impl SurfaceHit {
    pub fn value(&self) -> ParamValue {
        ParamValue::Surface {
            triangle: self.triangle,
            bary: self.bary,
        }
    }
}

/// Projects `p` to the closest point of the surface (brute force over the triangles:
/// O(T), meant for picking and set-up, not for the 1 kHz loop). `None` if the surface
/// has no triangles or `p` is not finite.
pub fn closest_point(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    p: [f64; 3],
) -> Option<SurfaceHit> {
    if p.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let mut best: Option<SurfaceHit> = None;
    for (t, tri) in triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| vertices[i as usize]);
        let bary = closest_on_triangle(p, a, b, c);
        let q = [0, 1, 2].map(|i| bary[0] * a[i] + bary[1] * b[i] + bary[2] * c[i]);
        let d = dist(p, q);
        if best.is_none_or(|h| d < h.distance) {
            best = Some(SurfaceHit {
                triangle: t as u32,
                bary,
                point: q,
                distance: d,
            });
        }
    }
    best
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d).sqrt()
}

/// Barycentric coordinates of the point of triangle abc closest to p
/// (Ericson, Real-Time Collision Detection, §5.1.5).
pub fn closest_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Discretization {
        Discretization::Grid {
            nodes: vec![0.0, 0.5, 2.0, 3.0],
        }
    }

    #[test]
    fn grid_interpolation_is_exact_on_linear_data() {
        let g = grid();
        let Discretization::Grid { nodes } = &g else {
            unreachable!()
        };
        let f = |x: f64| 3.0 * x - 1.25;
        for i in 0..=300 {
            let p = 3.0 * f64::from(i) / 300.0;
            let s = g.stencil(ParamValue::Scalar(p)).expect("in range");
            assert!(!s.clamped);
            let v: f64 = (0..3)
                .map(|k| s.weights[k] * f(nodes[s.nodes[k] as usize]))
                .sum();
            // Two products and a sum of O(10) values: a few ulps of 10.
            assert!((v - f(p)).abs() < 1e-13, "p={p} v={v}");
        }
    }

    #[test]
    fn grid_clamps_and_flags_outside() {
        let g = grid();
        let lo = g.stencil(ParamValue::Scalar(-1.0)).expect("clamped");
        assert_eq!((lo.nodes[0], lo.weights[0], lo.clamped), (0, 1.0, true));
        let hi = g.stencil(ParamValue::Scalar(7.0)).expect("clamped");
        assert_eq!((hi.nodes[0], hi.weights[0], hi.clamped), (3, 1.0, true));
        let edge = g.stencil(ParamValue::Scalar(3.0)).expect("edge");
        assert!(!edge.clamped);
        assert!(matches!(
            g.stencil(ParamValue::Scalar(f64::NAN)),
            Err(AxisError::NotFinite { .. })
        ));
        assert!(matches!(
            g.stencil(ParamValue::Scalar(f64::INFINITY)),
            Err(AxisError::NotFinite { .. })
        ));
    }

    #[test]
    fn discrete_index_and_mix() {
        let d = Discretization::Discrete {
            labels: vec!["x".into(), "y".into(), "z".into()],
        };
        let s = d.stencil(ParamValue::Index(1)).expect("ok");
        assert_eq!((s.nodes[0], s.clamped), (1, false));
        let s = d.stencil(ParamValue::Index(9)).expect("clamped");
        assert_eq!((s.nodes[0], s.clamped), (2, true));
        assert!(matches!(
            d.stencil(ParamValue::Scalar(1.5)),
            Err(AxisError::NotAnIndex { .. })
        ));
        let m = d.stencil(ParamValue::Mix([0.6, 0.0, -0.8])).expect("mix");
        assert_eq!(m.weights[..3], [0.6, 0.0, -0.8]);
        let two = Discretization::Discrete {
            labels: vec!["a".into(), "b".into()],
        };
        let m = two.stencil(ParamValue::Mix([1.0, 2.0, 3.0])).expect("mix");
        assert!(m.clamped);
        assert_eq!(m.weights[2], 0.0);
    }

    #[test]
    fn surface_bary_and_clamp() {
        let s = Discretization::Surface {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
        };
        let st = s
            .stencil(ParamValue::Surface {
                triangle: 0,
                bary: [0.2, 0.3, 0.5],
            })
            .expect("ok");
        assert!(!st.clamped);
        let st = s
            .stencil(ParamValue::Surface {
                triangle: 0,
                bary: [-0.5, 1.0, 0.5],
            })
            .expect("clamped");
        assert!(st.clamped);
        assert!((st.weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(matches!(
            s.stencil(ParamValue::Surface {
                triangle: 3,
                bary: [1.0, 0.0, 0.0]
            }),
            Err(AxisError::NoSuchTriangle { .. })
        ));
        assert!(matches!(
            s.stencil(ParamValue::Scalar(0.0)),
            Err(AxisError::WrongKind { .. })
        ));
    }

    #[test]
    fn closest_point_projects_onto_triangle() {
        let v = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let t = [[0u32, 1, 2]];
        let h = closest_point(&v, &t, [0.25, 0.25, 2.0]).expect("hit");
        assert!((h.distance - 2.0).abs() < 1e-15);
        assert!((h.bary[1] - 0.25).abs() < 1e-15 && (h.bary[2] - 0.25).abs() < 1e-15);
        let h = closest_point(&v, &t, [5.0, -1.0, 0.0]).expect("hit");
        assert_eq!(h.bary, [0.0, 1.0, 0.0]);
        assert!(closest_point(&v, &t, [f64::NAN, 0.0, 0.0]).is_none());
    }

    #[test]
    fn validate_rejects_bad_axes() {
        assert!(Discretization::Grid { nodes: vec![] }.validate().is_err());
        assert!(
            Discretization::Grid {
                nodes: vec![0.0, 0.0]
            }
            .validate()
            .is_err()
        );
        assert!(
            Discretization::Surface {
                vertices: vec![[0.0; 3]],
                triangles: vec![[0, 0, 1]]
            }
            .validate()
            .is_err()
        );
    }
}

#[cfg(test)]
mod surface_vector_tests {
    use super::*;

    #[test]
    fn surface_mix_weights_are_bary_times_direction() {
        let d = Discretization::SurfaceVector {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            field_nodes: vec![],
        };
        assert_eq!(d.node_count(), 9);
        let s = d
            .stencil(ParamValue::SurfaceMix {
                triangle: 0,
                bary: [0.2, 0.3, 0.5],
                mix: [0.0, 0.6, 0.8],
            })
            .expect("valid");
        assert_eq!(s.len, 9);
        // Vertex 2, component z: node 3·2 + 2 = 8, weight 0.5 · 0.8.
        let k = (0..9).find(|&k| s.nodes[k] == 8).expect("node 8");
        assert!((s.weights[k] - 0.4).abs() < 1e-15);
        assert!((s.weights.iter().sum::<f64>() - 1.4).abs() < 1e-14);
        assert!(matches!(
            d.stencil(ParamValue::Surface {
                triangle: 0,
                bary: [1.0, 0.0, 0.0]
            }),
            Err(AxisError::WrongKind { .. })
        ));
    }
}
