//! Small argument helpers shared by the commands.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;

use super::organ::{LevelArg, OrganName};

/// Which organ mesh a command works on.
#[derive(Debug, Args)]
pub struct OrganArgs {
    #[arg(long, value_enum, default_value = "liver")]
    pub organ: OrganName,
    #[arg(long, value_enum, default_value = "coarse")]
    pub level: LevelArg,
    /// A closed surface (OBJ, STL or PLY) to mesh instead of the organ; fixed =
    /// posterior-facing (−y) surface, palpable = anterior/inferior (`palpa scene build`
    /// chooses regions).
    #[arg(long, requires = "units")]
    pub surface: Option<PathBuf>,
    /// The surface file's length unit: mm, cm or m.
    #[arg(long, requires = "surface")]
    pub units: Option<palpa_core::surface_import::frame::Units>,
    /// The surface file's axes that become the patient's x, y, z (e.g. `x,-z,y`).
    #[arg(long, requires = "surface")]
    pub axes: Option<String>,
}

impl OrganArgs {
    pub fn mesh(&self) -> anyhow::Result<palpa_core::organ::OrganMesh> {
        use palpa_core::organ::user::{self, SurfaceOptions};
        use palpa_core::surface_import::frame::{Axes, Units};
        let Some(path) = &self.surface else {
            return super::organ::mesh(self.organ, self.level);
        };
        let axes = match &self.axes {
            Some(a) => Axes::parse(a).map_err(anyhow::Error::msg)?,
            None => Axes::default(),
        };
        let options = SurfaceOptions {
            units: self.units.unwrap_or(Units::Mm),
            axes,
            close_holes_max_edges: 0,
            largest_component: false,
        };
        let (solid, report) = user::prepare(path, &options)
            .with_context(|| format!("preparing {}", path.display()))?;
        for w in &report.warnings {
            eprintln!("palpa: warning: {w}");
        }
        let (fixed, palpable) = palpa_core::organ::default_user_regions();
        user::mesh(&solid, self.level.into(), &fixed, &palpable)
            .with_context(|| format!("meshing {}", path.display()))
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
    /// Load direction NX,NY,NZ (default: the inward normal at the probe, smoothed across
    /// edges: the surface's area-weighted vertex normals interpolated, the direction the
    /// app presses along and `palpa eval` and `palpa fe solve` both default to).
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
    /// Refuses a pull: the tool presses into the tissue and cannot hold it, so a
    /// negative force or depth is no palpation (a linear scene would answer it as a
    /// glued probe, the tissue law not at all). `palpa fe solve`, the reference,
    /// answers pulls.
    pub fn check_press(&self) -> anyhow::Result<()> {
        if let Some(d) = self.depth_mm
            && !(d.is_finite() && d >= 0.0)
        {
            bail!(
                "--depth-mm {d}: expected a finite depth ≥ 0 mm (the tool presses; it cannot pull)"
            );
        }
        if let Some(f) = self.force_n
            && !(f.is_finite() && f >= 0.0)
        {
            bail!(
                "--force-n {f}: expected a finite force ≥ 0 N (the tool presses; it cannot pull)"
            );
        }
        Ok(())
    }
}

pub use palpa_app::pick::{COORDINATE_MAX, coordinate_ok};

/// How far from the palpable surface a `--at` point may lie before its press is warned:
/// two tool radii. Every point is projected to its closest palpable point, so any point
/// presses somewhere; past this a typo, or a point in another mesh's frame, is likelier
/// than the press the user meant.
pub const FAR_FROM_SURFACE_MM: f64 = 10.0;

/// Warns (stderr) when `--at` lay more than [`FAR_FROM_SURFACE_MM`] from the palpable
/// surface, naming the point actually pressed.
pub fn warn_far_from_surface(distance_mm: f64, pressed: [f64; 3]) {
    if distance_mm > FAR_FROM_SURFACE_MM {
        eprintln!(
            "warning: --at lies {distance_mm:.1} mm from the palpable surface (more than \
             {FAR_FROM_SURFACE_MM} mm); pressing its closest palpable point \
             ({:.2}, {:.2}, {:.2})",
            // `+ 0.0` prints a negative zero as 0.00.
            pressed[0] + 0.0,
            pressed[1] + 0.0,
            pressed[2] + 0.0
        );
    }
}

/// Three finite numbers from a comma-separated argument (`--at`, `--dir`).
pub fn to3(v: &[f64], what: &str) -> anyhow::Result<[f64; 3]> {
    match v {
        [x, y, z] if v.iter().all(|&c| coordinate_ok(c)) => Ok([*x, *y, *z]),
        _ => bail!(
            "{what} needs three finite comma-separated numbers of magnitude at most \
             {COORDINATE_MAX:e}, got {v:?}"
        ),
    }
}

/// Checks before any work that `--out` can be written: its folder exists and it is no
/// folder itself. (`offline liver --out /missing/x.palpa` once built for 45 s, then
/// failed to write.)
pub fn check_out(out: &std::path::Path) -> anyhow::Result<()> {
    let folder = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => std::path::Path::new("."),
    };
    if !folder.is_dir() {
        bail!(
            "--out {}: the folder {} does not exist (expected an existing folder to write into)",
            out.display(),
            folder.display()
        );
    }
    if out.is_dir() {
        bail!(
            "--out {}: a folder (expected a file to write)",
            out.display()
        );
    }
    Ok(())
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
