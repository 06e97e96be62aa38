//! The organs a command can name, and user surfaces standing in for them: one place
//! that turns "which organ, which level" into a tetrahedral mesh with its regions.

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::mesh::stuffing::Implicit;

use super::liver::{Liver, spacing_mm};
use super::{Level, OrganMesh, default_user_regions, mesh_organ, spacing_for_diagonal};
use crate::surface_import::{SurfaceError, SurfaceSolid, TriSurface};

/// The built-in organs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrganName {
    /// The procedural liver (≈ 200 × 150 × 100 mm).
    Liver,
}

/// Why an organ could not be meshed.
#[derive(Debug, Error)]
pub enum CatalogueError {
    #[error(transparent)]
    Read(SurfaceError),
    #[error("{path} cannot be meshed")]
    NotMeshable {
        path: PathBuf,
        #[source]
        source: SurfaceError,
    },
}

/// Meshes the named organ, or the closed surface in `surface` (OBJ/STL, with the
/// default user regions), at a level.
pub fn mesh(
    organ: OrganName,
    level: Level,
    surface: Option<&Path>,
) -> Result<OrganMesh, CatalogueError> {
    if let Some(path) = surface {
        let mut s = TriSurface::read(path).map_err(CatalogueError::Read)?;
        s.validate().map_err(|source| CatalogueError::NotMeshable {
            path: path.to_path_buf(),
            source,
        })?;
        let solid = SurfaceSolid::new(s);
        let (lo, hi) = solid.bounds();
        let diag = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
        let (fixed, palpable) = default_user_regions();
        return Ok(mesh_organ(
            &solid,
            spacing_for_diagonal(level, diag),
            &fixed,
            &palpable,
        ));
    }
    Ok(match organ {
        OrganName::Liver => {
            let liver = Liver::default();
            mesh_organ(
                &liver,
                spacing_mm(level),
                &liver.fixed_region(),
                &liver.palpable_region(),
            )
        }
    })
}
