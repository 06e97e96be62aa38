//! A scene's nonlinear tissue as the on-line loops use it: the force law alone
//! ([`DepthLaw`]: force from depth, the surface drawn linear), or the tissue vademecum
//! bound to the scene ([`BoundTissue`]: force and surface). The force thread and the
//! renderer ask it the same questions whichever it is.

use crate::axis::ProbePoint;
use crate::fe::Material;
use crate::tissue::bound::BoundTissue;
use crate::tissue::depthlaw::DepthLaw;

/// A scene's nonlinear tissue, as the on-line loops use it: the force law alone
/// ([`DepthLaw`], samples spread over the surface; the surface drawn is linear), or
/// the vademecum bound to the scene (force and surface from every palpable vertex).
#[derive(Debug, Clone)]
pub enum Tissue {
    ForceLaw(DepthLaw),
    Vademecum(Box<BoundTissue>),
}

impl Tissue {
    pub fn law(&self) -> crate::fe::law::Law {
        match self {
            Tissue::ForceLaw(l) => l.options.law,
            Tissue::Vademecum(t) => t.law.options.law,
        }
    }

    pub fn material(&self) -> Material {
        match self {
            Tissue::ForceLaw(l) => l.options.material,
            Tissue::Vademecum(t) => t.law.options.material,
        }
    }

    pub fn depth_max_mm(&self) -> f64 {
        match self {
            Tissue::ForceLaw(l) => l.options.depth_max_mm,
            Tissue::Vademecum(t) => t.law.depth_max_mm(),
        }
    }

    /// The deepest press answered at `p` (mm) and, where a press of the blend stopped
    /// short of the grid, why (see [`BoundTissue::limit_mm`]). Allocation-free.
    pub fn limit_mm(&self, p: &ProbePoint) -> (f64, Option<&str>) {
        match self {
            Tissue::ForceLaw(l) => (l.options.depth_max_mm, None),
            Tissue::Vademecum(t) => t.limit_mm(p),
        }
    }

    /// The corners of `p`'s triangle a vademecum never pressed
    /// ([`BoundTissue::unpressed_corners`]); `None` for a force law.
    pub fn unpressed_corners(&self, p: &ProbePoint) -> Option<usize> {
        match self {
            Tissue::ForceLaw(_) => None,
            Tissue::Vademecum(t) => Some(t.unpressed_corners(p)),
        }
    }

    /// The vademecum's finest surplus at `p` and `depth_mm`
    /// ([`BoundTissue::blend_surplus_mm`]); `None` for a force law (no surface).
    pub fn blend_surplus_mm(&self, p: &ProbePoint, depth_mm: f64) -> Option<f64> {
        match self {
            Tissue::ForceLaw(_) => None,
            Tissue::Vademecum(t) => t.blend_surplus_mm(p, depth_mm),
        }
    }

    /// How many positions were pressed off-line: a vademecum's vertices, edge
    /// midpoints and split triangles' points all count (one reach each).
    pub fn samples(&self) -> usize {
        match self {
            Tissue::ForceLaw(l) => l.samples.len(),
            Tissue::Vademecum(t) => t.law.reach.len(),
        }
    }

    /// Whether the drawn surface is the nonlinear one (else the linear one at the
    /// press's depth).
    pub fn has_surface(&self) -> bool {
        matches!(self, Tissue::Vademecum(_))
    }

    /// Depth in, force out, at the probe point `p` (rest position `point_mm`) with the
    /// linear compliance there; flagged past the law's range. Allocation-free.
    pub fn force_n(
        &self,
        p: &ProbePoint,
        point_mm: [f64; 3],
        depth_mm: f64,
        compliance_mm_per_n: f64,
    ) -> (f64, bool) {
        match self {
            Tissue::ForceLaw(l) => l.force_n(point_mm, depth_mm, compliance_mm_per_n),
            Tissue::Vademecum(t) => t.force_n(p, depth_mm, compliance_mm_per_n),
        }
    }

    /// Force in, depth out (the inverse of [`Self::force_n`]). Allocation-free.
    pub fn depth_mm(
        &self,
        p: &ProbePoint,
        point_mm: [f64; 3],
        force_n: f64,
        compliance_mm_per_n: f64,
    ) -> (f64, bool) {
        match self {
            Tissue::ForceLaw(l) => l.depth_mm(point_mm, force_n, compliance_mm_per_n),
            Tissue::Vademecum(t) => t.depth_mm(p, force_n, compliance_mm_per_n),
        }
    }
}
