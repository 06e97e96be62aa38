//! A scene's nonlinear tissue as the on-line loops use it: the tissue vademecum bound to
//! the scene ([`BoundTissue`]), force and surface at any palpable point and depth. The
//! force thread and the renderer ask it the same questions.

use crate::axis::ProbePoint;
use crate::fe::Material;
use crate::tissue::bound::BoundTissue;

/// A scene's nonlinear tissue, as the on-line loops use it.
#[derive(Debug, Clone)]
pub struct Tissue {
    pub bound: Box<BoundTissue>,
}

impl Tissue {
    pub fn new(bound: BoundTissue) -> Tissue {
        Tissue {
            bound: Box::new(bound),
        }
    }

    pub fn law(&self) -> crate::fe::law::Law {
        self.bound.law.options.law
    }

    pub fn material(&self) -> Material {
        self.bound.law.options.material
    }

    pub fn depth_max_mm(&self) -> f64 {
        self.bound.law.depth_max_mm()
    }

    /// The deepest press answered at `p` (mm) and, where a press of the blend stopped
    /// short of the grid, why (see [`BoundTissue::limit_mm`]). Allocation-free.
    pub fn limit_mm(&self, p: &ProbePoint) -> (f64, Option<&str>) {
        self.bound.limit_mm(p)
    }

    /// The corners of `p`'s triangle the vademecum never pressed
    /// ([`BoundTissue::unpressed_corners`]).
    pub fn unpressed_corners(&self, p: &ProbePoint) -> usize {
        self.bound.unpressed_corners(p)
    }

    /// The vademecum's finest surplus at `p` and `depth_mm`
    /// ([`BoundTissue::blend_surplus_mm`]).
    pub fn blend_surplus_mm(&self, p: &ProbePoint, depth_mm: f64) -> Option<f64> {
        self.bound.blend_surplus_mm(p, depth_mm)
    }

    /// How many positions were pressed off-line: vertices, edge midpoints and split
    /// triangles' points all count (one reach each).
    pub fn samples(&self) -> usize {
        self.bound.law.reach.len()
    }

    /// Depth in, force out, at the probe point `p` with the linear compliance there;
    /// flagged past the law's range. Allocation-free.
    pub fn force_n(&self, p: &ProbePoint, depth_mm: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        self.bound.force_n(p, depth_mm, compliance_mm_per_n)
    }

    /// Force in, depth out (the inverse of [`Self::force_n`]). Allocation-free.
    pub fn depth_mm(&self, p: &ProbePoint, force_n: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        self.bound.depth_mm(p, force_n, compliance_mm_per_n)
    }
}
