//! Small argument helpers shared by the commands.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;

use super::organ::{LevelArg, OrganName};

/// Which organ mesh a command works on.
#[derive(Debug, Args)]
pub struct OrganArgs {
    #[arg(long, value_enum, default_value = "liver")]
    pub organ: OrganName,
    #[arg(long, value_enum, default_value = "coarse")]
    pub level: LevelArg,
    /// A closed surface (OBJ, or ASCII/binary STL, in mm) to mesh instead of the organ;
    /// fixed = posterior-facing (−y) surface, palpable = anterior/inferior.
    #[arg(long)]
    pub surface: Option<PathBuf>,
}

impl OrganArgs {
    pub fn mesh(&self) -> anyhow::Result<palpa_core::organ::OrganMesh> {
        super::organ::mesh(self.organ, self.level, self.surface.as_deref())
    }
}

/// Where and how hard to press.
#[derive(Debug, Args)]
pub struct ProbeArgs {
    /// Probe point X,Y,Z (mm); projected to the closest palpable surface point.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub at: Vec<f64>,
    /// Total probe force (N): force control.
    #[arg(
        long,
        required_unless_present = "depth_mm",
        conflicts_with = "depth_mm"
    )]
    pub force_n: Option<f64>,
    /// Tool depth (mm): depth control, the force is the result.
    #[arg(long)]
    pub depth_mm: Option<f64>,
    /// Load direction NX,NY,NZ (default: the inward surface normal at the probe).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub dir: Option<Vec<f64>>,
}

impl ProbeArgs {
    pub fn at(&self) -> anyhow::Result<[f64; 3]> {
        to3(&self.at, "--at")
    }
    pub fn dir(&self) -> anyhow::Result<Option<[f64; 3]>> {
        self.dir.as_deref().map(|d| to3(d, "--dir")).transpose()
    }
}

/// Three finite numbers from a comma-separated argument (`--at`, `--dir`).
pub fn to3(v: &[f64], what: &str) -> anyhow::Result<[f64; 3]> {
    match v {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => bail!("{what} needs three finite comma-separated numbers, got {v:?}"),
    }
}

/// Mean time of `f` over `reps` calls, in nanoseconds (stops at the first error).
pub fn mean_ns(reps: u32, f: impl FnMut() -> anyhow::Result<()>) -> anyhow::Result<f64> {
    palpa_core::timing::mean_ns(reps, f)
}

/// Prints a command's JSON report: one line with `--json`, indented otherwise.
pub fn print_report(report: &serde_json::Value, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{report}");
    } else {
        println!("{}", serde_json::to_string_pretty(report)?);
    }
    Ok(())
}
