//! Organ selection shared by the mesh and FE commands.

use std::path::Path;

use anyhow::Context;
use clap::ValueEnum;
use palpa_core::mesh::stuffing::Implicit;
use palpa_core::organ::liver::{Liver, spacing_mm};
use palpa_core::organ::{Level, OrganMesh, default_user_regions, mesh_organ, spacing_for_diagonal};
use palpa_core::surface_import::{SurfaceSolid, TriSurface};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OrganName {
    /// The procedural liver (≈ 200 × 150 × 100 mm).
    Liver,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LevelArg {
    Coarse,
    Medium,
    Fine,
}

impl From<LevelArg> for Level {
    fn from(l: LevelArg) -> Level {
        match l {
            LevelArg::Coarse => Level::Coarse,
            LevelArg::Medium => Level::Medium,
            LevelArg::Fine => Level::Fine,
        }
    }
}

/// Meshes the named organ, or the closed surface in `surface` (OBJ/STL), at a level.
pub fn mesh(
    organ: OrganName,
    level: LevelArg,
    surface: Option<&Path>,
) -> anyhow::Result<OrganMesh> {
    if let Some(path) = surface {
        let mut s = TriSurface::read(path)?;
        s.validate()
            .with_context(|| format!("{} cannot be meshed", path.display()))?;
        let solid = SurfaceSolid::new(s);
        let (lo, hi) = solid.bounds();
        let diag = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
        let (fixed, palpable) = default_user_regions();
        return Ok(mesh_organ(
            &solid,
            spacing_for_diagonal(level.into(), diag),
            &fixed,
            &palpable,
        ));
    }
    Ok(match organ {
        OrganName::Liver => {
            let liver = Liver::default();
            mesh_organ(
                &liver,
                spacing_mm(level.into()),
                &liver.fixed_region(),
                &liver.palpable_region(),
            )
        }
    })
}
