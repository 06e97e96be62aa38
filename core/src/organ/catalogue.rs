//! The organs a command can name: one place that turns "which organ, which level"
//! into a tetrahedral mesh with its regions. (A user's surface goes through
//! [`super::user`] instead, with its units, axes and regions.)

use super::liver::{Liver, spacing_mm};
use super::{Level, OrganMesh, mesh_organ};

/// The built-in organs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrganName {
    /// The procedural liver (≈ 200 × 150 × 100 mm).
    Liver,
}

/// Meshes the named organ at a level.
pub fn mesh(organ: OrganName, level: Level) -> OrganMesh {
    match organ {
        OrganName::Liver => {
            let liver = Liver::default();
            mesh_organ(
                &liver,
                spacing_mm(level),
                &liver.fixed_region(),
                &liver.palpable_region(),
            )
        }
    }
}
