//! A user's organ: a surface file turned into a meshed organ with regions, every step
//! reported (what was read, repaired, scaled, turned, meshed) so a summary can show
//! it and a wrong unit or axis is seen before an hour of off-line solving.
//!
//! A surface that is not a closed 2-manifold (it crosses itself, has holes,
//! non-manifold edges, bow-tie vertices or stray pieces, as segmentation leaves them)
//! is read by its generalized winding number ([`crate::surface_import::winding`]):
//! small stray pieces apart from the largest are dropped (a large one is a second
//! body, refused as validation refuses it), every defect is reported, and the
//! volume inside (`w > ½`) is what the mesh is checked against. A surface with no clear
//! inside (an open sheet, a soup: the winding number far from an integer over more
//! than [`MAX_AMBIGUOUS_SHARE`] of it) is refused by name. `strict` refuses any defect,
//! as validation names it.
//!
//! Checks after meshing, each an error naming the cause: the lattice must fill the
//! solid (a solid thinner than about two lattice cells leaves almost no tetrahedra:
//! the meshed volume is compared with the enclosed one), some boundary must be fixed
//! (else the organ is free to move and the stiffness is singular), and some must be
//! palpable.

use std::path::{Path, PathBuf};

use thiserror::Error;

use super::{Level, OrganMesh, Selector, mesh_organ, spacing_for_diagonal};
use crate::mesh::{norm, sub};
use crate::surface_import::frame::{Axes, Units, size_warning, to_patient};
use crate::surface_import::repair::{HoleReport, close_holes, drop_stray, keep_largest};
use crate::surface_import::winding::{InsideVolume, Winding};
use crate::surface_import::{SurfaceError, SurfaceSolid, TriSurface, read};

/// Lines per side of the grid along which the winding number's inside is integrated.
const VOLUME_LINES: usize = 160;

/// A surface whose winding number is more than [`crate::surface_import::winding::AMBIGUOUS`]
/// from an integer over more than this share of its inside has no clear inside.
pub const MAX_AMBIGUOUS_SHARE: f64 = 0.02;

/// How to read and place a surface.
#[derive(Debug, Clone)]
pub struct SurfaceOptions {
    pub units: Units,
    pub axes: Axes,
    /// Close holes of at most this many edges (0: none).
    pub close_holes_max_edges: usize,
    /// Keep the largest piece when there are several.
    pub largest_component: bool,
    /// Refuse any defect instead of reading the surface by its winding number.
    pub strict: bool,
}

/// How a surface that is not a closed manifold was read.
#[derive(Debug, Clone)]
pub struct WindingReport {
    /// What the surface had, one line each (see [`crate::surface_import::Defects`]).
    pub defects: Vec<String>,
    pub degenerate_dropped: usize,
    /// Triangle counts of stray pieces dropped.
    pub stray_dropped: Vec<usize>,
    pub inside: InsideVolume,
}

/// What preparing the surface found and did.
#[derive(Debug, Clone)]
pub struct SurfaceReport {
    pub file_name: String,
    pub source_xxh3: String,
    pub format: &'static str,
    pub vertices: usize,
    pub triangles: usize,
    pub welded: usize,
    pub polygons_split: usize,
    pub holes: HoleReport,
    pub pieces_dropped: Vec<usize>,
    pub flipped: bool,
    pub units: Units,
    pub axes: Axes,
    pub mirrored: bool,
    pub bbox_mm: ([f64; 3], [f64; 3]),
    /// The volume the surface encloses: by the divergence theorem for a closed
    /// manifold, else the winding number's inside.
    pub enclosed_volume_mm3: f64,
    /// Set where the surface was read by its winding number.
    pub winding: Option<WindingReport>,
    pub warnings: Vec<String>,
}

/// Why a user organ could not be made.
#[derive(Debug, Error)]
pub enum UserOrganError {
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    #[error(
        "the organ is thinner than the {level} lattice ({h_mm:.2} mm cells): the mesh holds \
         {meshed_ml:.3} ml of the surface's {enclosed_ml:.3} ml; use a finer level"
    )]
    TooThin {
        level: &'static str,
        h_mm: f64,
        meshed_ml: f64,
        enclosed_ml: f64,
    },
    #[error(
        "the surface has no clear inside: its winding number is far from a whole number over \
         {ambiguous_ml:.2} ml of the {inside_ml:.2} ml it seems to enclose (an open sheet or a \
         loose soup of triangles, not a solid); it {}",
        defects.join("; ")
    )]
    NoInside {
        inside_ml: f64,
        ambiguous_ml: f64,
        defects: Vec<String>,
    },
    #[error(
        "no boundary triangle is fixed: the organ would be free to move (give --fixed \
         selectors, or paint a fixed region)"
    )]
    NoFixed,
    #[error(
        "no boundary triangle is palpable (give --palpable selectors, or paint a palpable region)"
    )]
    NoPalpable,
}

/// Reads, repairs, scales, turns and validates a surface file.
pub fn prepare(
    path: &Path,
    o: &SurfaceOptions,
) -> Result<(SurfaceSolid, SurfaceReport), UserOrganError> {
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io {
        path: PathBuf::from(path),
        source,
    })?;
    let r = read::read_bytes(path, &bytes)?;
    let mut s = r.surface;
    let holes = if o.close_holes_max_edges > 0 {
        close_holes(&mut s, o.close_holes_max_edges)
    } else {
        HoleReport::default()
    };
    let pieces_dropped = if o.largest_component {
        keep_largest(&mut s)
    } else {
        Vec::new()
    };
    to_patient(&mut s, o.units, &o.axes);
    let (flipped, winding) = match s.validate() {
        Ok(v) => (v.flipped, None),
        Err(e) if o.strict || !by_winding_reads(&e) => return Err(e.into()),
        Err(_) => {
            let (flipped, report, w) = read_by_winding(&mut s)?;
            (flipped, Some((report, w)))
        }
    };
    let (lo, hi) = crate::mesh::bounds_of(&s.vertices);
    let mut warnings = Vec::new();
    if let Some(w) = size_warning(norm(sub(hi, lo)), o.units) {
        warnings.push(w);
    }
    if flipped {
        warnings.push("the surface was inside-out; it was turned outward".into());
    }
    let report = SurfaceReport {
        file_name: path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        source_xxh3: format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes)),
        format: r.format.name(),
        vertices: s.vertices.len(),
        triangles: s.triangles.len(),
        welded: r.welded,
        polygons_split: r.polygons_split,
        holes,
        pieces_dropped,
        flipped,
        units: o.units,
        axes: o.axes,
        mirrored: o.axes.is_mirror(),
        bbox_mm: (lo, hi),
        enclosed_volume_mm3: winding
            .as_ref()
            .map_or_else(|| s.volume(), |(r, _)| r.inside.volume_mm3),
        winding: winding.as_ref().map(|(r, _)| r.clone()),
        warnings,
    };
    let solid = match winding {
        Some((r, w)) => SurfaceSolid::by_winding(s, w, r.inside.volume_mm3),
        None => SurfaceSolid::new(s),
    };
    Ok((solid, report))
}

/// Defects the winding number reads through; a coordinate out of range or an empty
/// surface is refused whatever the mode.
fn by_winding_reads(e: &SurfaceError) -> bool {
    matches!(
        e,
        SurfaceError::Degenerate { .. }
            | SurfaceError::Open { .. }
            | SurfaceError::NonManifoldEdge { .. }
            | SurfaceError::NonManifoldVertex { .. }
            | SurfaceError::Components { .. }
            | SurfaceError::Orientation { .. }
            | SurfaceError::SelfIntersecting { .. }
    )
}

/// Reads a surface that failed validation by its winding number: degenerate
/// triangles and stray pieces dropped, turned outward if it encloses a negative
/// volume, its inside measured; refused if it has none that is clear.
fn read_by_winding(s: &mut TriSurface) -> Result<(bool, WindingReport, Winding), UserOrganError> {
    let degenerate_dropped = s.drop_degenerate();
    let apart = drop_stray(s);
    if !apart.large.is_empty() {
        // A second body, not an island: as validation would say it.
        let pieces = crate::surface_import::repair::components(s);
        return Err(SurfaceError::Components {
            count: pieces.len(),
            sizes: pieces.iter().map(Vec::len).collect(),
        }
        .into());
    }
    let stray_dropped = apart.dropped;
    let defects = s.defects().lines();
    let flipped = s.volume() < 0.0;
    if flipped {
        for t in &mut s.triangles {
            t.swap(1, 2);
        }
    }
    let w = Winding::new(s);
    let inside = w.inside_volume(VOLUME_LINES);
    if inside.volume_mm3 <= 0.0 || inside.ambiguous_mm3 > MAX_AMBIGUOUS_SHARE * inside.volume_mm3 {
        return Err(UserOrganError::NoInside {
            inside_ml: inside.volume_mm3 / 1000.0,
            ambiguous_ml: inside.ambiguous_mm3 / 1000.0,
            defects,
        });
    }
    let report = WindingReport {
        defects,
        degenerate_dropped,
        stray_dropped,
        inside,
    };
    Ok((flipped, report, w))
}

/// Meshes a prepared surface at a level with the given regions, and checks the result.
pub fn mesh(
    solid: &SurfaceSolid,
    level: Level,
    fixed: &Selector,
    palpable: &Selector,
) -> Result<OrganMesh, UserOrganError> {
    use crate::mesh::stuffing::Implicit;
    let (lo, hi) = solid.bounds();
    let h = spacing_for_diagonal(level, norm(sub(hi, lo)));
    let organ = mesh_organ(solid, h, fixed, palpable);
    let enclosed = solid.enclosed_volume_mm3();
    let meshed = organ.mesh.volume();
    // Isosurface stuffing's volume is within a few per cent of the solid's when the
    // lattice resolves it; half is lost only when the solid is about one cell thick.
    if organ.mesh.tets.is_empty() || meshed < 0.5 * enclosed {
        return Err(UserOrganError::TooThin {
            level: level.name(),
            h_mm: h,
            meshed_ml: meshed / 1000.0,
            enclosed_ml: enclosed / 1000.0,
        });
    }
    if !organ.fixed.iter().any(|&f| f) {
        return Err(UserOrganError::NoFixed);
    }
    if !organ.palpable.iter().any(|&p| p) {
        return Err(UserOrganError::NoPalpable);
    }
    Ok(organ)
}
