//! A palpation scene: the part of a liver vademecum a palpation app shows, and the
//! contact law that turns an indentation into a force.
//!
//! The meta-model is `u(x; s, t) = Σ_k X_k(x) Y_k(s, t)` in mm per newton, with one
//! surface × direction axis (`Discretization::SurfaceVector`): a force `F t` at the
//! surface point `s` is the particularization at `(s, F t)`. The scene keeps only the
//! surface rows of `X` (one render vertex per surface node, three rows each).
//!
//! **Contact law.** The probe at `s` pushes along the inward normal `t = −n(s)` (vertex
//! normals of the rest surface, interpolated and normalized). Under a unit force the
//! contact point moves by `w(s) = Σ_i λ_i u(x_i; s, t)` (the three vertices of the
//! triangle holding `s`, barycentric weights `λ_i`), and the compliance along the push
//! is `c(s) = t · w(s)` [mm/N]. By linearity an indentation depth `d` needs the force
//! `F = d / c(s)`. Only nine rows of `X` are touched, which is what lets the force loop
//! run at 1 kHz.
//!
//! When it fails: a truncation to very few modes can give `c(s) ≤ 0` at some points
//! (the first modes are global and need not reproduce local stiffness); the scene then
//! reports [`ContactError::NonPositiveCompliance`] instead of an infinite or negative
//! force. Surface points outside the palpable region have no parametric value: the
//! scene says so ([`PalpationScene::palpable_point`] returns `None`).

use std::collections::HashMap;

use thiserror::Error;

pub use crate::axis::ProbePoint;
use crate::axis::{Discretization, ParamValue, closest_point};
use crate::file::AnyModel;
pub use crate::mesh::vertex_normals;
use crate::nearfield::NearField;
use crate::separated::{EvalError, SeparatedModel, TradeoffRow};
use crate::visual::VisualSurface;

/// Why a model cannot be shown as a palpation scene.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    #[error(
        "the model has kind {kind:?} with {axes} axes; a palpation scene needs one \
         surface-vector axis (probe position × load direction)"
    )]
    NotPalpation { kind: String, axes: usize },
    #[error("the model's field has {0} components; a palpation scene needs 3 (displacement)")]
    Components(u32),
    #[error("the model carries no surface geometry (nodes and boundary triangles)")]
    NoGeometry,
    #[error("the model's rows ({rows}) do not match its geometry ({nodes} nodes × 3 components)")]
    RowsGeometry { rows: usize, nodes: usize },
    #[error(
        "palpable vertex {vertex} has no field node in the model (was it exported without it?)"
    )]
    PalpableWithoutNode { vertex: usize },
    #[error("the model could not keep its surface rows: {0}")]
    Select(crate::separated::ModelError),
}

/// Why a contact could not be evaluated.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ContactError {
    #[error(transparent)]
    Eval(#[from] EvalError),
    #[error(
        "the probe point {point_mm:?} mm does not move under a push (its exact compliance \
         along the push is {compliance_mm_per_n:.3e} mm/N): it lies on the fixed region, \
         its triangle held; expected a palpable point off the attachment"
    )]
    Held {
        point_mm: [f64; 3],
        compliance_mm_per_n: f64,
    },
    #[error(
        "the compliance along the push is {compliance_mm_per_n:.3e} mm/N (expected > 0): \
         too few modes ({modes}) to represent the local stiffness here"
    )]
    NonPositiveCompliance {
        compliance_mm_per_n: f64,
        modes: usize,
    },
}

/// What the contact law gives at a probe point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Rest position of the contact point, mm.
    pub point_mm: [f64; 3],
    /// Unit push direction (inward normal).
    pub push_dir: [f64; 3],
    /// Displacement of the contact point under a unit push, mm/N.
    pub unit_displacement_mm_per_n: [f64; 3],
    /// `push_dir · unit_displacement`, mm/N.
    pub compliance_mm_per_n: f64,
}

/// Scratch space for [`PalpationScene::contact`]; make one per thread with
/// [`PalpationScene::contact_scratch`], then the contact evaluation allocates nothing.
#[derive(Debug, Clone)]
pub struct ContactScratch {
    coeffs: Vec<f64>,
}

/// A liver vademecum prepared for palpation (surface rows only, f32 storage).
#[derive(Debug, Clone)]
pub struct PalpationScene {
    model: SeparatedModel<f32>,
    /// Rest positions of the render vertices (the model's nodes), mm.
    vertices_mm: Vec<[f32; 3]>,
    /// Boundary triangles over the render vertices, outward-oriented as stored.
    triangles: Vec<[u32; 3]>,
    /// Area-weighted outward vertex normals of the rest surface.
    normals: Vec<[f32; 3]>,
    /// For each boundary triangle: the palpable triangle it is, and for each of its
    /// corners the corner index in the palpable triangle; `None` outside the region.
    palpable_of: Vec<Option<(u32, [u8; 3])>>,
    /// Palpable triangles over palpable vertices, and each palpable vertex's render vertex.
    axis_triangles: Vec<[u32; 3]>,
    axis_vertices_mm: Vec<[f64; 3]>,
    axis_node: Vec<u32>,
    /// For a nodal-load axis: the load face of each palpable triangle (the axis's
    /// own triangle numbering otherwise, i.e. the identity).
    axis_face: Option<Vec<u32>>,
    /// The drawn surface, carried by the render surface ([`crate::visual`]).
    visual: VisualSurface,
}

/// Most drawn vertices a scene subdivides its render surface towards: one level of
/// Loop subdivision on the shipped coarse scenes (3 426 drawn vertices on 858), none on
/// finer ones. Measured on the software adapter (`palpa headless`, 1280x720, the liver
/// pressed 6 mm, medians of three runs): frames 25.3 ms drawing the render surface,
/// 27.1 ms with one level (+7 %), 31.5 ms with two (+24 %).
pub const VISUAL_VERTICES: usize = 8_000;

/// Levels of subdivision for a render surface of `vertices` vertices (each level about
/// quadruples them), at most two.
pub fn visual_levels(vertices: usize) -> u32 {
    (0..=2u32)
        .rev()
        .find(|&l| vertices.saturating_mul(4usize.pow(l)) <= VISUAL_VERTICES)
        .unwrap_or(0)
}

impl PalpationScene {
    /// Prepares a loaded model: keeps its surface nodes, converts to f32, checks that it
    /// is a palpation vademecum and maps the palpable region onto the surface.
    pub fn new(model: AnyModel) -> Result<Self, SceneError> {
        let model: SeparatedModel<f32> = match model {
            AnyModel::F32(m) => m,
            AnyModel::F64(m) => m.convert(),
        };
        let axes = model.axes();
        let (axis_vertices_mm, axis_triangles, field_nodes, axis_face) = match axes {
            [a] => match &a.info.discretization {
                Discretization::SurfaceVector {
                    vertices,
                    triangles,
                    field_nodes,
                } => (
                    vertices.clone(),
                    triangles.clone(),
                    field_nodes.clone(),
                    None,
                ),
                Discretization::SurfaceLoad {
                    positions,
                    faces,
                    palpable,
                    field_nodes,
                    ..
                } => {
                    let pal: Vec<u32> = (0..faces.len() as u32)
                        .filter(|&f| palpable[f as usize])
                        .collect();
                    let tris = pal
                        .iter()
                        .map(|&f| {
                            let c = faces[f as usize];
                            [c[0], c[1], c[2]]
                        })
                        .collect();
                    (positions.clone(), tris, field_nodes.clone(), Some(pal))
                }
                _ => return Err(not_palpation(&model)),
            },
            _ => return Err(not_palpation(&model)),
        };
        if model.field().components != 3 {
            return Err(SceneError::Components(model.field().components));
        }
        let g = model.geometry();
        if g.nodes.is_empty() || g.surface.is_empty() {
            return Err(SceneError::NoGeometry);
        }
        // Keep only the nodes the surface uses (a full model carries the interior too).
        let mut used = vec![false; g.nodes.len()];
        for t in &g.surface {
            for &v in t {
                if let Some(u) = used.get_mut(v as usize) {
                    *u = true;
                }
            }
        }
        let model = if used.iter().all(|&u| u) {
            model
        } else {
            let keep: Vec<u32> = (0..g.nodes.len() as u32)
                .filter(|&v| used[v as usize])
                .collect();
            model.select_nodes(&keep).map_err(SceneError::Select)?
        };
        let g = model.geometry();
        if model.rows() != 3 * g.nodes.len() {
            return Err(SceneError::RowsGeometry {
                rows: model.rows(),
                nodes: g.nodes.len(),
            });
        }
        // The axis of a selected model may have lost some field nodes (a load axis's
        // midside nodes are not render vertices); the palpable corners must remain.
        let axis_node = match model.axes()[0].info.discretization {
            Discretization::SurfaceVector {
                ref field_nodes, ..
            }
            | Discretization::SurfaceLoad {
                ref field_nodes, ..
            } => field_nodes.clone(),
            _ => field_nodes,
        };
        if let Some(&vertex) = axis_triangles.iter().flatten().find(|&&v| {
            axis_node
                .get(v as usize)
                .is_none_or(|&f| f as usize >= g.nodes.len())
        }) {
            return Err(SceneError::PalpableWithoutNode {
                vertex: vertex as usize,
            });
        }
        let vertices_mm: Vec<[f32; 3]> = g.nodes.iter().map(|p| p.map(|c| c as f32)).collect();
        let triangles = g.surface.clone();
        let normals = vertex_normals(&vertices_mm, &triangles);

        let mut by_nodes: HashMap<[u32; 3], u32> = HashMap::with_capacity(axis_triangles.len());
        for (i, t) in axis_triangles.iter().enumerate() {
            let mut key = t.map(|v| axis_node[v as usize]);
            key.sort_unstable();
            by_nodes.insert(key, i as u32);
        }
        let palpable_of = triangles
            .iter()
            .map(|t| {
                let mut key = *t;
                key.sort_unstable();
                let a = *by_nodes.get(&key)?;
                let at = axis_triangles[a as usize].map(|v| axis_node[v as usize]);
                let corner = t.map(|v| at.iter().position(|&w| w == v).unwrap_or(0) as u8);
                Some((a, corner))
            })
            .collect();
        let visual =
            VisualSurface::subdivided(&vertices_mm, &triangles, visual_levels(vertices_mm.len()));
        Ok(PalpationScene {
            visual,
            model,
            vertices_mm,
            triangles,
            normals,
            palpable_of,
            axis_triangles,
            axis_vertices_mm,
            axis_node,
            axis_face,
        })
    }

    /// The near field (exact band and compliance table), if the scene's model has one.
    pub fn near(&self) -> Option<&NearField> {
        self.model.near()
    }

    pub fn model(&self) -> &SeparatedModel<f32> {
        &self.model
    }
    pub fn modes(&self) -> usize {
        self.model.modes()
    }
    pub fn vertices_mm(&self) -> &[[f32; 3]] {
        &self.vertices_mm
    }
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// The drawn surface.
    pub fn visual(&self) -> &VisualSurface {
        &self.visual
    }
    pub fn normals(&self) -> &[[f32; 3]] {
        &self.normals
    }
    pub fn tradeoff(&self) -> &[TradeoffRow] {
        self.model.tradeoff()
    }

    /// Rest positions of the palpable (axis) vertices, mm.
    pub fn axis_vertices_mm(&self) -> &[[f64; 3]] {
        &self.axis_vertices_mm
    }

    /// Palpable triangles over the axis vertices (the numbering of
    /// [`ProbePoint::triangle`]).
    pub fn axis_triangles(&self) -> &[[u32; 3]] {
        &self.axis_triangles
    }

    /// Whether render vertex `v` belongs to the palpable region.
    pub fn palpable_vertices(&self) -> Vec<bool> {
        let mut out = vec![false; self.vertices_mm.len()];
        for &n in self.axis_triangles.iter().flatten() {
            if let Some(o) = self
                .axis_node
                .get(n as usize)
                .and_then(|&f| out.get_mut(f as usize))
            {
                *o = true;
            }
        }
        out
    }

    /// The palpable point at barycentric `bary` of boundary triangle `triangle`, or
    /// `None` when that triangle is outside the palpable region (or does not exist).
    pub fn palpable_point(&self, triangle: u32, bary: [f64; 3]) -> Option<ProbePoint> {
        let (a, corner) = (*self.palpable_of.get(triangle as usize)?)?;
        let mut b = [0.0; 3];
        for (i, &c) in corner.iter().enumerate() {
            b[c as usize] = bary[i];
        }
        Some(ProbePoint {
            triangle: a,
            bary: b,
        })
    }

    /// The palpable point closest to `p_mm` (rest geometry), and its distance in mm.
    /// O(triangles): for set-up, picking fallbacks and steering, not the 1 kHz loop.
    pub fn closest_palpable(&self, p_mm: [f64; 3]) -> Option<(ProbePoint, f64)> {
        let hit = closest_point(&self.axis_vertices_mm, &self.axis_triangles, p_mm)?;
        Some((
            ProbePoint {
                triangle: hit.triangle,
                bary: hit.bary,
            },
            hit.distance,
        ))
    }

    /// The render vertices of a palpable triangle, in its corner order.
    pub fn probe_vertices(&self, p: &ProbePoint) -> [u32; 3] {
        self.axis_triangles[p.triangle as usize].map(|v| self.axis_node[v as usize])
    }

    /// Rest position and outward unit normal at a probe point.
    pub fn frame(&self, p: &ProbePoint) -> ([f64; 3], [f64; 3]) {
        let vs = self.probe_vertices(p);
        let mut x = [0.0; 3];
        let mut n = [0.0; 3];
        for (i, &v) in vs.iter().enumerate() {
            for c in 0..3 {
                x[c] += p.bary[i] * self.vertices_mm[v as usize][c] as f64;
                n[c] += p.bary[i] * self.normals[v as usize][c] as f64;
            }
        }
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if len > 0.0 {
            n = n.map(|c| c / len);
        }
        (x, n)
    }

    /// The parameter value for a force vector `force_n` (N) applied at `p`.
    pub fn param(&self, p: &ProbePoint, force_n: [f64; 3]) -> ParamValue {
        let triangle = match &self.axis_face {
            Some(faces) => faces[p.triangle as usize],
            None => p.triangle,
        };
        ParamValue::SurfaceMix {
            triangle,
            bary: p.bary,
            mix: force_n,
        }
    }

    pub fn contact_scratch(&self) -> ContactScratch {
        ContactScratch {
            coeffs: vec![0.0; self.modes()],
        }
    }

    /// The contact law at `p` with the first `modes` modes (see the module docs).
    /// Allocation-free; touches 9 rows of `X`.
    pub fn contact(
        &self,
        p: &ProbePoint,
        modes: usize,
        scratch: &mut ContactScratch,
    ) -> Result<Contact, ContactError> {
        let (point_mm, normal) = self.frame(p);
        let push_dir = normal.map(|c| -c);
        let n = modes.min(scratch.coeffs.len());
        // A nodal-load model carries the exact compliance tensor: no modes involved.
        if let (Some(near), Some(faces)) = (self.model.near(), &self.axis_face)
            && let Some(c) = near.compliance_tensor(faces[p.triangle as usize], p.bary)
        {
            let w: [f64; 3] = std::array::from_fn(|d| {
                c[d][0] * push_dir[0] + c[d][1] * push_dir[1] + c[d][2] * push_dir[2]
            });
            let compliance = w[0] * push_dir[0] + w[1] * push_dir[1] + w[2] * push_dir[2];
            // The table is exact (no modes): only a held surface has none.
            if compliance.is_nan() || compliance <= 0.0 {
                return Err(ContactError::Held {
                    point_mm,
                    compliance_mm_per_n: compliance,
                });
            }
            return Ok(Contact {
                point_mm,
                push_dir,
                unit_displacement_mm_per_n: w,
                compliance_mm_per_n: compliance,
            });
        }
        let coeffs = &mut scratch.coeffs[..n];
        self.model
            .particularize(&[self.param(p, push_dir)], coeffs)?;
        let w = self.point_displacement(p, coeffs, None);
        let compliance = w[0] * push_dir[0] + w[1] * push_dir[1] + w[2] * push_dir[2];
        // NaN counts as non-positive.
        if compliance.is_nan() || compliance <= 0.0 {
            return Err(ContactError::NonPositiveCompliance {
                compliance_mm_per_n: compliance,
                modes: n,
            });
        }
        Ok(Contact {
            point_mm,
            push_dir,
            unit_displacement_mm_per_n: w,
            compliance_mm_per_n: compliance,
        })
    }

    /// Displacement (mm) of the surface point `p` for the coefficients `coeffs`: the
    /// nine rows of its triangle's corners, interpolated, plus `near_rows` (per field
    /// row, e.g. the near field a frame computed) when given. Allocation-free.
    pub fn point_displacement(
        &self,
        p: &ProbePoint,
        coeffs: &[f64],
        near_rows: Option<&[f64]>,
    ) -> [f64; 3] {
        let vs = self.probe_vertices(p);
        let rows: [u32; 9] = std::array::from_fn(|i| 3 * vs[i / 3] + (i % 3) as u32);
        let mut out = [0.0; 9];
        self.model.reconstruct_rows(&rows, coeffs, &mut out);
        let mut w = [0.0; 3];
        for i in 0..3 {
            for c in 0..3 {
                let near = near_rows.map_or(0.0, |r| r[rows[3 * i + c] as usize]);
                w[c] += p.bary[i] * (out[3 * i + c] + near);
            }
        }
        w
    }

    /// Displacement of every render vertex (3 per vertex, mm) for a force `force_n` at
    /// `p`, with the first `out_coeffs.len()` modes: the CPU reference of the GPU path.
    pub fn displacement(
        &self,
        p: &ProbePoint,
        force_n: [f64; 3],
        coeffs: &mut [f64],
        out_mm: &mut [f64],
    ) -> Result<(), EvalError> {
        let v = [self.param(p, force_n)];
        self.model.particularize(&v, coeffs)?;
        self.model.reconstruct(coeffs, out_mm);
        self.model.add_near_field(&v, out_mm)
    }

    /// The near-field part of the displacement alone (added to `out_mm`), for a
    /// renderer that computes the modes' part elsewhere (the GPU). A no-op without a
    /// near field.
    pub fn add_near_displacement(
        &self,
        p: &ProbePoint,
        force_n: [f64; 3],
        out_mm: &mut [f64],
    ) -> Result<(), EvalError> {
        self.model.add_near_field(&[self.param(p, force_n)], out_mm)
    }
}

fn not_palpation(m: &SeparatedModel<f32>) -> SceneError {
    SceneError::NotPalpation {
        kind: m.kind().to_string(),
        axes: m.axes().len(),
    }
}
