//! Organs: a solid (an implicit function), its regions as data, and its meshes.
//!
//! Units: millimetres. Axes follow the patient: +x towards the patient's left, +y
//! anterior, +z superior (cranial). The default organ is a procedural liver
//! ([`liver::Liver`]); a user's closed surface can stand in for it ([`crate::surface_import`]).

pub mod catalogue;
pub mod liver;
pub mod region;
pub mod region_file;
pub mod syntax;
pub mod user;

use serde::{Deserialize, Serialize};

use crate::mesh::stuffing::{Implicit, StuffingReport, stuff};
use crate::mesh::{TetMesh, cross, norm, sub};
pub use region::Selector;

/// Mesh resolution levels (lattice spacing of isosurface stuffing).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Level {
    Coarse,
    Medium,
    Fine,
}

impl Level {
    pub fn name(self) -> &'static str {
        match self {
            Level::Coarse => "coarse",
            Level::Medium => "medium",
            Level::Fine => "fine",
        }
    }
}

impl std::str::FromStr for Level {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "coarse" => Ok(Level::Coarse),
            "medium" => Ok(Level::Medium),
            "fine" => Ok(Level::Fine),
            o => Err(format!(
                "unknown level '{o}', expected coarse, medium or fine"
            )),
        }
    }
}

/// A meshed organ: the tetrahedra, the boundary triangles (outward), and which
/// boundary vertices are fixed and which triangles are palpable.
#[derive(Debug, Clone)]
pub struct OrganMesh {
    pub mesh: TetMesh,
    pub boundary: Vec<[u32; 3]>,
    /// Per vertex: on the fixed region (all its degrees of freedom are clamped).
    pub fixed: Vec<bool>,
    /// Per boundary triangle: in the palpable region.
    pub palpable: Vec<bool>,
    pub report: StuffingReport,
    pub h_mm: f64,
}

impl OrganMesh {
    /// The mesh's fingerprint (`mesh_xxh3` in the files built on it): the xxh3-64 of
    /// its vertices, tetrahedra, boundary and fixed and palpable flags, so the same
    /// surface meshed with other regions differs. Every file and log that depends on
    /// the mesh records this one value.
    pub fn fingerprint(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(bytemuck::cast_slice(&self.mesh.vertices));
        h.update(bytemuck::cast_slice(&self.mesh.tets));
        h.update(bytemuck::cast_slice(&self.boundary));
        let flags: Vec<u8> = self
            .fixed
            .iter()
            .chain(&self.palpable)
            .map(|&b| u8::from(b))
            .collect();
        h.update(&flags);
        h.digest()
    }

    /// The vertices a probe can press: corners of palpable boundary triangles, outside
    /// the fixed region (a tool there moves nothing), sorted, each once.
    pub fn pressable_vertices(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .boundary
            .iter()
            .zip(&self.palpable)
            .filter(|(_, p)| **p)
            .flat_map(|(t, _)| t.iter().copied())
            .filter(|&v| !self.fixed[v as usize])
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The palpable boundary triangles, in the boundary's order.
    pub fn palpable_triangles(&self) -> Vec<[u32; 3]> {
        self.boundary
            .iter()
            .zip(&self.palpable)
            .filter_map(|(t, p)| p.then_some(*t))
            .collect()
    }

    /// The palpable boundary edges, as sorted vertex pairs, sorted and each once.
    pub fn palpable_edges(&self) -> Vec<[u32; 2]> {
        let mut e: Vec<[u32; 2]> = self
            .boundary
            .iter()
            .zip(&self.palpable)
            .filter(|(_, p)| **p)
            .flat_map(|(t, _)| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        e.sort_unstable();
        e.dedup();
        e
    }

    /// The boundary's vertices, sorted, each once (the rows a palpation scene keeps).
    pub fn surface_nodes(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.boundary.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// Meshes an implicit solid and classifies its boundary with the two selectors.
/// A boundary triangle is fixed (all three vertices clamped) when `fixed` contains its
/// centroid and normal; it is palpable when `palpable` does and it is not fixed.
pub fn mesh_organ(
    shape: &impl Implicit,
    h_mm: f64,
    fixed: &Selector,
    palpable: &Selector,
) -> OrganMesh {
    let (mesh, report) = stuff(shape, h_mm);
    let boundary: Vec<[u32; 3]> = mesh.boundary_faces().into_iter().map(|f| f.0).collect();
    let mut fixed_v = vec![false; mesh.vertices.len()];
    let mut fixed_f = vec![false; boundary.len()];
    let mut palp = vec![false; boundary.len()];
    for (i, f) in boundary.iter().enumerate() {
        let (c, n) = centroid_normal(&mesh.vertices, *f);
        if fixed.contains(c, n) {
            fixed_f[i] = true;
            for &v in f {
                fixed_v[v as usize] = true;
            }
        }
    }
    for (i, f) in boundary.iter().enumerate() {
        let (c, n) = centroid_normal(&mesh.vertices, *f);
        palp[i] = !fixed_f[i] && palpable.contains(c, n);
    }
    OrganMesh {
        mesh,
        boundary,
        fixed: fixed_v,
        palpable: palp,
        report,
        h_mm,
    }
}

/// Default regions for a user surface, which carries no region data: fixed where the
/// outward normal points posterior (−y) within 45°, palpable where it points anterior
/// (+y) within 80° or inferior (−z) within 70°.
pub fn default_user_regions() -> (Selector, Selector) {
    let fixed = Selector::NormalWithin {
        dir: [0.0, -1.0, 0.0],
        max_angle_deg: 45.0,
    };
    (fixed, Selector::anterior_inferior())
}

/// Lattice spacing of a level for a solid of bounding-box diagonal `diag_mm`, scaled
/// like the liver's levels (diag/22, /38, /66).
pub fn spacing_for_diagonal(level: Level, diag_mm: f64) -> f64 {
    diag_mm
        / match level {
            Level::Coarse => 22.0,
            Level::Medium => 38.0,
            Level::Fine => 66.0,
        }
}

/// Centroid and unit outward normal of a triangle.
pub fn centroid_normal(v: &[[f64; 3]], f: [u32; 3]) -> ([f64; 3], [f64; 3]) {
    let [a, b, c] = f.map(|i| v[i as usize]);
    let cen = [0, 1, 2].map(|d| (a[d] + b[d] + c[d]) / 3.0);
    let n = cross(sub(b, a), sub(c, a));
    let l = norm(n);
    (cen, n.map(|x| x / l))
}
