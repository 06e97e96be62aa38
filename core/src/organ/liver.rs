//! The default organ: a procedural liver, about 200 × 150 × 100 mm.
//!
//! The solid is a smooth signed-distance-like function built from blended primitives:
//! - the **right lobe**, a large ellipsoid whose upper surface is the smooth convex
//!   diaphragmatic dome;
//! - the **left lobe**, a flattened ellipsoid whose thickness tapers towards the
//!   patient's left, ending in a thin edge;
//! - a smooth union of the two (blend radius 25 mm), so the lobes merge as they do
//!   across the falciform ligament, with a shallow notch at the anterior border;
//! - a plane cut of the antero-inferior side with a small blend radius: the **sharp
//!   inferior border**;
//! - a flattened **posterior face** (where the bare area lies) with the groove of the
//!   **vena-cava bed** cut into it.
//!
//! Distances are approximate (ellipsoids use Quilez's bound `k0(k0−1)/k1`), which is
//! all isosurface stuffing needs: the zero level set is exact, values elsewhere only
//! steer the root finding.
//!
//! Regions: the **fixed** region is the posterior bare area (posterior-facing surface
//! above the mid-height) and the vena-cava bed; the **palpable** region is the
//! anterior and inferior surface a surgeon can reach.

use serde::{Deserialize, Serialize};

use super::Selector;
use crate::mesh::stuffing::Implicit;

/// Parameters of the procedural liver (mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Liver {
    pub right_center: [f64; 3],
    pub right_radii: [f64; 3],
    pub left_center: [f64; 3],
    pub left_radii: [f64; 3],
    /// Left-lobe thickness at its tip, as a fraction of its thickness at its centre.
    pub left_taper: f64,
    pub blend_mm: f64,
    /// Inferior border plane: points with n·p > offset are removed.
    pub border_normal: [f64; 3],
    pub border_offset_mm: f64,
    pub border_blend_mm: f64,
    /// Posterior face: y ≥ posterior_y.
    pub posterior_y_mm: f64,
    /// Vena cava: a vertical cylinder (x, y) of this radius, cut into the back.
    pub cava_xy_mm: [f64; 2],
    pub cava_radius_mm: f64,
}

impl Default for Liver {
    fn default() -> Self {
        Liver {
            right_center: [-32.0, 0.0, 0.0],
            right_radii: [70.0, 75.0, 52.0],
            left_center: [45.0, 12.0, 14.0],
            left_radii: [58.0, 50.0, 24.0],
            left_taper: 0.35,
            blend_mm: 25.0,
            border_normal: [0.0, 0.55, -1.0],
            border_offset_mm: 30.0,
            border_blend_mm: 2.0,
            posterior_y_mm: -58.0,
            cava_xy_mm: [-8.0, -62.0],
            cava_radius_mm: 13.0,
        }
    }
}

fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}
fn smax(a: f64, b: f64, k: f64) -> f64 {
    -smin(-a, -b, k)
}

fn ellipsoid(p: [f64; 3], c: [f64; 3], r: [f64; 3]) -> f64 {
    let q = [0, 1, 2].map(|d| p[d] - c[d]);
    let k0 = (0..3).map(|d| (q[d] / r[d]).powi(2)).sum::<f64>().sqrt();
    let k1 = (0..3)
        .map(|d| (q[d] / (r[d] * r[d])).powi(2))
        .sum::<f64>()
        .sqrt();
    if k1 == 0.0 {
        -r.iter().copied().fold(f64::INFINITY, f64::min)
    } else {
        k0 * (k0 - 1.0) / k1
    }
}

impl Liver {
    /// The fixed region: posterior bare area and vena-cava bed.
    pub fn fixed_region(&self) -> Selector {
        let bare_area = Selector::All(vec![
            Selector::NormalWithin {
                dir: [0.0, -1.0, 0.0],
                max_angle_deg: 50.0,
            },
            Selector::HalfSpace {
                point: [0.0, 0.0, -12.0],
                normal: [0.0, 0.0, 1.0],
            },
            Selector::HalfSpace {
                point: [20.0, 0.0, 0.0],
                normal: [-1.0, 0.0, 0.0],
            },
        ]);
        let cava_bed = Selector::NearLine {
            point: [self.cava_xy_mm[0], self.cava_xy_mm[1], 0.0],
            dir: [0.0, 0.0, 1.0],
            radius_mm: self.cava_radius_mm + 4.0,
        };
        Selector::Any(vec![bare_area, cava_bed])
    }

    /// The palpable region: anterior and inferior surface.
    pub fn palpable_region(&self) -> Selector {
        Selector::anterior_inferior()
    }
}

impl Implicit for Liver {
    fn value(&self, p: [f64; 3]) -> f64 {
        let right = ellipsoid(p, self.right_center, self.right_radii);
        // Left lobe: thickness shrinks linearly towards its tip (+x).
        let lr = self.left_radii;
        let s = ((p[0] - self.left_center[0]) / lr[0]).clamp(-1.0, 1.0);
        let thick = if s > 0.0 {
            1.0 - (1.0 - self.left_taper) * s
        } else {
            1.0
        };
        let left = ellipsoid(p, self.left_center, [lr[0], lr[1], lr[2] * thick]);
        let mut f = smin(right, left, self.blend_mm);
        // Antero-inferior border: a plane cut with a small blend → a sharp edge.
        let n = self.border_normal;
        let nl = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let plane = (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]) / nl - self.border_offset_mm;
        f = smax(f, plane, self.border_blend_mm);
        // Flattened posterior face.
        f = smax(f, self.posterior_y_mm - p[1], 12.0);
        // Vena-cava bed: remove a vertical cylinder.
        let dx = p[0] - self.cava_xy_mm[0];
        let dy = p[1] - self.cava_xy_mm[1];
        let cyl = self.cava_radius_mm - (dx * dx + dy * dy).sqrt();
        f = smax(f, cyl, 4.0);
        f
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for (c, r) in [
            (self.right_center, self.right_radii),
            (self.left_center, self.left_radii),
        ] {
            for d in 0..3 {
                lo[d] = lo[d].min(c[d] - r[d] - self.blend_mm);
                hi[d] = hi[d].max(c[d] + r[d] + self.blend_mm);
            }
        }
        (lo, hi)
    }
}

/// Lattice spacing per level, chosen for ≈1.5k / 7k / 40k vertices.
pub fn spacing_mm(level: super::Level) -> f64 {
    match level {
        super::Level::Coarse => 12.0,
        super::Level::Medium => 7.0,
        super::Level::Fine => 4.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality;
    use crate::organ::{Level, mesh_organ};

    #[test]
    fn liver_levels_have_the_intended_sizes_and_quality() {
        let liver = Liver::default();
        for level in [Level::Coarse, Level::Medium] {
            let m = mesh_organ(
                &liver,
                spacing_mm(level),
                &liver.fixed_region(),
                &liver.palpable_region(),
            );
            let q = quality(&m.mesh);
            let (lo, hi) = m.mesh.bounding_box();
            eprintln!(
                "{}: {} vertices, {} tets, bbox {:?}..{:?}, fixed {} palpable tris {} of {}, {q:?}",
                level.name(),
                m.mesh.vertices.len(),
                m.mesh.tets.len(),
                lo.map(|x| x.round()),
                hi.map(|x| x.round()),
                m.fixed.iter().filter(|&&f| f).count(),
                m.palpable.iter().filter(|&&p| p).count(),
                m.boundary.len()
            );
            assert_eq!(q.inverted, 0);
            assert!(
                q.min_dihedral_deg >= 10.0,
                "{level:?}: {}",
                q.min_dihedral_deg
            );
        }
    }
}
