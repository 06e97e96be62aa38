//! Organ selection shared by the mesh and FE commands.

use clap::ValueEnum;
use palpa_core::organ::liver::{Liver, spacing_mm};
use palpa_core::organ::{Level, OrganMesh, mesh_organ};

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

/// Meshes the named organ at a level.
pub fn mesh(organ: OrganName, level: LevelArg) -> OrganMesh {
    match organ {
        OrganName::Liver => {
            let liver = Liver::default();
            mesh_organ(
                &liver,
                spacing_mm(level.into()),
                &liver.fixed_region(),
                &liver.palpable_region(),
            )
        }
    }
}
