//! Small argument helpers shared by the commands.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;

use palpa_core::organ::Selector;
use palpa_core::organ::region_file::RegionFile;
use palpa_core::organ::syntax;
use palpa_core::surface_import::frame::Axes;

use super::organ::{LevelArg, OrganName};

/// Which organ mesh a command works on.
#[derive(Debug, Args)]
pub struct OrganArgs {
    #[arg(long, value_enum, default_value = "liver")]
    pub organ: OrganName,
    #[arg(long, value_enum, default_value = "coarse")]
    pub level: LevelArg,
    /// A closed surface (OBJ, STL or PLY) to mesh instead of the organ, placed and
    /// split into regions by the flags `palpa scene build` takes (give the same ones
    /// the scene was built with: a tissue remembers its mesh and regions).
    #[arg(long, requires = "units")]
    pub surface: Option<PathBuf>,
    /// The surface file's length unit: mm, cm or m.
    #[arg(long, requires = "surface")]
    pub units: Option<palpa_core::surface_import::frame::Units>,
    #[command(flatten)]
    pub place: PlaceArgs,
    #[command(flatten)]
    pub regions: RegionArgs,
}

impl OrganArgs {
    /// The flags given that only a `--surface` uses (for refusals elsewhere).
    pub fn surface_flags(&self) -> Vec<&'static str> {
        [
            ("--surface", self.surface.is_some()),
            ("--units", self.units.is_some()),
        ]
        .into_iter()
        .chain(self.place.given())
        .chain(self.regions.given())
        .filter(|f| f.1)
        .map(|f| f.0)
        .collect()
    }

    pub fn mesh(&self) -> anyhow::Result<palpa_core::organ::OrganMesh> {
        use palpa_core::organ::user::{self, SurfaceOptions};
        use palpa_core::surface_import::frame::Units;
        let Some(path) = &self.surface else {
            return super::organ::mesh(self.organ, self.level);
        };
        let options = SurfaceOptions {
            units: self.units.unwrap_or(Units::Mm),
            axes: self.place.axes()?,
            close_holes_max_edges: self.regions.close_holes,
            largest_component: self.regions.largest_component,
            strict: self.regions.strict,
        };
        let (solid, report) = user::prepare(path, &options)
            .with_context(|| format!("preparing {}", path.display()))?;
        for w in &report.warnings {
            eprintln!("palpa: warning: {w}");
        }
        if let Some(w) = &report.winding {
            eprintln!(
                "palpa: the surface is not a closed 2-manifold; its inside is read by its \
                 winding number ({:.1} ml; --strict refuses it instead):",
                w.inside.volume_mm3 / 1000.0
            );
            for line in winding_lines(w) {
                eprintln!("palpa:   {line}");
            }
        }
        let (fixed, palpable, _) = self.regions.selectors()?;
        user::mesh(&solid, self.level.into(), &fixed, &palpable)
            .with_context(|| format!("meshing {}", path.display()))
    }
}

/// How a surface file's axes become the patient's (`scene build` and every command
/// that meshes a `--surface`).
#[derive(Debug, Args, Default)]
pub struct PlaceArgs {
    /// The file axes that become the patient's x (left), y (anterior), z (superior),
    /// e.g. `x,-z,y`; default `x,y,z`.
    #[arg(long, requires = "surface", conflicts_with_all = ["up", "anterior"], allow_hyphen_values = true)]
    pub axes: Option<String>,
    /// The file's superior (up) axis, e.g. `y` (with --anterior).
    #[arg(long, requires = "anterior", allow_hyphen_values = true)]
    pub up: Option<String>,
    /// The file's anterior axis, e.g. `-z` (with --up).
    #[arg(long, requires = "up", allow_hyphen_values = true)]
    pub anterior: Option<String>,
}

impl PlaceArgs {
    pub fn axes(&self) -> anyhow::Result<Axes> {
        Ok(match (&self.axes, &self.up, &self.anterior) {
            (Some(a), _, _) => Axes::parse(a).map_err(anyhow::Error::msg)?,
            (None, Some(up), Some(ant)) => {
                Axes::from_up_anterior(up, ant).map_err(anyhow::Error::msg)?
            }
            _ => Axes::default(),
        })
    }

    fn given(&self) -> [(&'static str, bool); 3] {
        [
            ("--axes", self.axes.is_some()),
            ("--up", self.up.is_some()),
            ("--anterior", self.anterior.is_some()),
        ]
    }
}

/// Which parts of a surface are fixed and palpable, and its repairs (`scene build`
/// and every command that meshes a `--surface`).
#[derive(Debug, Args, Default)]
pub struct RegionArgs {
    /// Fixed (attached) boundary, a selector in the organ frame (mm, after units and
    /// axes), e.g. `normal:posterior:45`; repeat to add. Default: facing posterior
    /// within 45° (when no --regions file names a fixed region).
    #[arg(long, requires = "surface", allow_hyphen_values = true)]
    pub fixed: Vec<String>,
    /// Palpable boundary, a selector; repeat to add. Default: everything not fixed.
    #[arg(long, requires = "surface", allow_hyphen_values = true)]
    pub palpable: Vec<String>,
    /// A region file (painted in the app, or written by hand).
    #[arg(long, requires = "surface")]
    pub regions: Option<PathBuf>,
    /// Close holes of at most this many edges (a fan from each hole's centroid).
    #[arg(long, requires = "surface", default_value_t = 0)]
    pub close_holes: usize,
    /// Keep the largest piece of a surface in several pieces.
    #[arg(long, requires = "surface")]
    pub largest_component: bool,
    /// Refuse a surface that is not a closed, non-self-intersecting 2-manifold instead
    /// of reading its inside by the winding number.
    #[arg(long, requires = "surface")]
    pub strict: bool,
}

impl RegionArgs {
    fn given(&self) -> [(&'static str, bool); 6] {
        [
            ("--fixed", !self.fixed.is_empty()),
            ("--palpable", !self.palpable.is_empty()),
            ("--regions", self.regions.is_some()),
            ("--close-holes", self.close_holes != 0),
            ("--largest-component", self.largest_component),
            ("--strict", self.strict),
        ]
    }

    /// The fixed and palpable selectors from the flags and the region file, and their
    /// description for a scene's provenance.
    pub fn selectors(&self) -> anyhow::Result<(Selector, Selector, String)> {
        let parse = |v: &[String]| {
            v.iter()
                .map(|e| syntax::parse(e))
                .collect::<Result<Vec<_>, _>>()
        };
        let mut fixed = parse(&self.fixed)?;
        let mut palpable = parse(&self.palpable)?;
        // `fixed[EXPR]`, `palpable[EXPR]`, `file[NAME]`: what `palpa info` shows (the
        // provenance is whitespace-separated, so whitespace is dropped).
        let bare = |e: &str| e.split_whitespace().collect::<String>();
        let mut described: Vec<String> = self
            .fixed
            .iter()
            .map(|e| format!("fixed[{}]", bare(e)))
            .chain(
                self.palpable
                    .iter()
                    .map(|e| format!("palpable[{}]", bare(e))),
            )
            .collect();
        if let Some(path) = &self.regions {
            let r = RegionFile::load(path)?;
            let (f, p) = r.selectors(path)?;
            fixed.push(f);
            palpable.push(p);
            described.push(format!(
                "file:{}",
                path.file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
            ));
        }
        if fixed.is_empty() {
            fixed.push(palpa_core::organ::default_user_regions().0);
            described.push("fixed[default:normal:posterior:45]".into());
        }
        if palpable.is_empty() {
            palpable.push(Selector::Everything);
            described.push("palpable[default:all]".into());
        }
        // Region hash: the selectors as data (so a changed selector rebuilds).
        let data = format!("{fixed:?}{palpable:?}");
        described.push(format!(
            "xxh3[{:016x}]",
            xxhash_rust::xxh3::xxh3_64(data.as_bytes())
        ));
        Ok((
            Selector::Any(fixed),
            Selector::Any(palpable),
            described.join(","),
        ))
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

/// A nodule in the organ: `--nodule-at X,Y,Z [--nodule-radius-mm R] [--nodule-ratio B]`.
#[derive(Debug, Args)]
pub struct NoduleArgs {
    /// A nodule's centre X,Y,Z (mm): a sphere stiffer than the tissue around it, at
    /// least 2 mm below the organ's surface.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub nodule_at: Option<Vec<f64>>,
    /// The nodule's radius (mm) [default: 10, resolved on every level].
    #[arg(long)]
    pub nodule_radius_mm: Option<f64>,
    /// The nodule's Young's modulus over the tissue's [default: 4.4, malignant liver
    /// tumours by MR elastography].
    #[arg(long)]
    pub nodule_ratio: Option<f64>,
}

impl NoduleArgs {
    /// The nodule asked for, if any (checked against the organ by the solve).
    pub fn nodule(&self) -> anyhow::Result<Option<palpa_core::fe::nodule::Nodule>> {
        let Some(at) = &self.nodule_at else {
            if self.nodule_radius_mm.is_some() || self.nodule_ratio.is_some() {
                bail!(
                    "--nodule-radius-mm and --nodule-ratio describe a nodule: give its centre with --nodule-at X,Y,Z"
                );
            }
            return Ok(None);
        };
        Ok(Some(palpa_core::fe::nodule::Nodule {
            center_mm: to3(at, "--nodule-at")?,
            radius_mm: self.nodule_radius_mm.unwrap_or(10.0),
            ratio: self.nodule_ratio.unwrap_or(4.4),
        }))
    }
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

/// A hyperelastic law as the command line names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NonlinearModel {
    NeoHookean,
    Svk,
}

impl NonlinearModel {
    pub fn law(self) -> palpa_core::fe::law::Law {
        match self {
            NonlinearModel::NeoHookean => palpa_core::fe::law::Law::NeoHookean,
            NonlinearModel::Svk => palpa_core::fe::law::Law::Svk,
        }
    }
}

/// What a surface read by its winding number had and what was done about it, one
/// line each.
pub fn winding_lines(w: &palpa_core::organ::user::WindingReport) -> Vec<String> {
    let mut lines = w.defects.clone();
    if w.degenerate_dropped > 0 {
        lines.push(format!(
            "dropped {} degenerate triangles",
            w.degenerate_dropped
        ));
    }
    for t in &w.stray_dropped {
        lines.push(format!(
            "dropped a stray piece of {t} triangles apart from the organ"
        ));
    }
    if w.inside.multiple_mm3 >= 10.0 {
        lines.push(format!(
            "{:.2} ml is wrapped twice or more (a fold or a duplicate sheet), counted once",
            w.inside.multiple_mm3 / 1000.0
        ));
    }
    lines
}

/// `I/N`, I from 1 to N.
pub fn parse_shard(s: &str) -> Result<palpa_core::tissue::presser::Shard, String> {
    let bad = || format!("{s}: expected I/N, a shard I from 1 to N (e.g. 3/8)");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (index, count): (u32, u32) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if count == 0 || index == 0 || index > count {
        return Err(bad());
    }
    Ok(palpa_core::tissue::presser::Shard { index, count })
}
