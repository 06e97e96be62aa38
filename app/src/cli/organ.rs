//! Organ and level arguments shared by the mesh, FE and vademecum commands (parsing
//! only: the catalogue is `palpa_core::organ::catalogue`).

use clap::ValueEnum;
use palpa_core::organ::catalogue;
use palpa_core::organ::{Level, OrganMesh};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OrganName {
    /// The procedural liver (≈ 200 × 150 × 100 mm).
    Liver,
}

impl From<OrganName> for catalogue::OrganName {
    fn from(o: OrganName) -> catalogue::OrganName {
        match o {
            OrganName::Liver => catalogue::OrganName::Liver,
        }
    }
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

/// Meshes the named organ at a level (a user's surface: `OrganArgs::mesh`).
pub fn mesh(organ: OrganName, level: LevelArg) -> anyhow::Result<OrganMesh> {
    Ok(catalogue::mesh(organ.into(), level.into()))
}
