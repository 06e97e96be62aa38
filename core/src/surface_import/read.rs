//! Reading OBJ, STL (ASCII and binary) and PLY (ASCII and binary) triangle surfaces,
//! the format told by content (the extension only breaks ties), and welding corners
//! that coincide within a tolerance relative to the surface's size.
//!
//! What is read: positions and faces. Normals, texture coordinates, colours, groups,
//! objects, materials and any other PLY element are skipped. Polygons are split into
//! triangles as fans from their first corner (exact for the convex polygons exporters
//! write).

use std::collections::HashMap;
use std::path::Path;

use super::indexed::Indexed;
use super::{SurfaceError, TriSurface};
use crate::mesh::{norm, sub};

/// The file formats a surface can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Obj,
    StlAscii,
    StlBinary,
    PlyAscii,
    PlyBinary,
}

impl Format {
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::StlAscii => "stl (ascii)",
            Format::StlBinary => "stl (binary)",
            Format::PlyAscii => "ply (ascii)",
            Format::PlyBinary => "ply (binary)",
        }
    }
}

/// A surface as read, with what reading did to it.
#[derive(Debug, Clone)]
pub struct ReadSurface {
    pub surface: TriSurface,
    pub format: Format,
    /// Corners merged into another within the weld tolerance (STL stores every
    /// facet's corners separately; some exporters split vertices at seams).
    pub welded: usize,
    /// Polygons with more than three corners, split into triangles.
    pub polygons_split: usize,
}

/// Corners closer than this fraction of the bounding-box diagonal are one vertex.
pub const WELD_RELATIVE: f64 = 1e-6;

/// Reads a surface file, telling the format from its content.
pub fn read(path: &Path) -> Result<ReadSurface, SurfaceError> {
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io {
        path: path.into(),
        source,
    })?;
    read_bytes(path, &bytes)
}

/// As [`read`], from bytes already in memory (`path` names them in messages).
pub fn read_bytes(path: &Path, bytes: &[u8]) -> Result<ReadSurface, SurfaceError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let format =
        sniff(bytes, ext.as_deref()).ok_or_else(|| SurfaceError::Format { path: path.into() })?;
    let err = |line: usize, reason: String| SurfaceError::Parse {
        path: path.into(),
        line,
        reason,
    };
    let indexed = match format {
        Format::Obj => parse_obj(bytes, &err)?,
        Format::StlAscii => Indexed::soup(parse_stl_ascii(bytes, &err)?),
        Format::StlBinary => Indexed::soup(parse_stl_binary(bytes, &err)?),
        Format::PlyAscii | Format::PlyBinary => super::ply::parse(bytes, &err)?,
    };
    let (surface, welded) = weld(&indexed.vertices, &indexed.triangles);
    Ok(ReadSurface {
        surface,
        format,
        welded,
        polygons_split: indexed.polygons_split,
    })
}

/// The format of `bytes`: PLY by its magic line, binary STL by its exact size, ASCII
/// STL by `solid` … `facet`, OBJ by its `v`/`f` records; the extension decides only
/// between formats the content leaves open.
fn sniff(bytes: &[u8], ext: Option<&str>) -> Option<Format> {
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        let head = String::from_utf8_lossy(&bytes[..bytes.len().min(512)]);
        return Some(if head.contains("format ascii") {
            Format::PlyAscii
        } else {
            Format::PlyBinary
        });
    }
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if n.checked_mul(50).and_then(|x| x.checked_add(84)) == Some(bytes.len()) {
            return Some(Format::StlBinary);
        }
    }
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    let trimmed = head.trim_start();
    if trimmed.starts_with("solid") && (head.contains("facet") || ext == Some("stl")) {
        return Some(Format::StlAscii);
    }
    let obj_like = head.lines().any(|l| {
        let l = l.trim_start();
        l.starts_with("v ") || l.starts_with("f ") || l.starts_with("v\t")
    });
    if obj_like || ext == Some("obj") {
        return Some(Format::Obj);
    }
    None
}

type ErrFn<'a> = dyn Fn(usize, String) -> SurfaceError + 'a;

fn parse_obj(bytes: &[u8], err: &ErrFn) -> Result<Indexed, SurfaceError> {
    let text = String::from_utf8_lossy(bytes);
    let mut out = Indexed::default();
    let mut idx: Vec<u32> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let ln = i + 1;
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                // `v x y z [w]` or `v x y z r g b`: the first three are the position.
                let c: Vec<f64> = it
                    .take(3)
                    .map(|s| s.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| err(ln, format!("bad vertex coordinate: {e}")))?;
                if c.len() != 3 || c.iter().any(|x| !x.is_finite()) {
                    return Err(err(
                        ln,
                        format!("a vertex needs three finite coordinates, got {line:?}"),
                    ));
                }
                out.vertices.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                // Negative indices count back from the last vertex defined so far.
                let n = out.vertices.len() as i64;
                idx.clear();
                for tok in it {
                    let k: i64 = tok
                        .split('/')
                        .next()
                        .unwrap_or("")
                        .parse()
                        .map_err(|e| err(ln, format!("bad face index {tok:?}: {e}")))?;
                    let r = if k > 0 { k - 1 } else { n + k };
                    if k == 0 || !(0..n).contains(&r) {
                        return Err(err(
                            ln,
                            format!("vertex index {k} out of range (1..={n}, or −1..=−{n})"),
                        ));
                    }
                    idx.push(r as u32);
                }
                if idx.len() < 3 {
                    return Err(err(
                        ln,
                        format!("a face needs at least 3 vertices, got {}", idx.len()),
                    ));
                }
                out.push_polygon(&idx);
            }
            _ => {}
        }
    }
    Ok(out)
}

fn parse_stl_binary(bytes: &[u8], err: &ErrFn) -> Result<Vec<[f64; 3]>, SurfaceError> {
    let n = (bytes.len() - 84) / 50;
    let mut corners = Vec::with_capacity(3 * n);
    for t in 0..n {
        let rec = &bytes[84 + 50 * t..84 + 50 * t + 50];
        for v in 0..3 {
            let off = 12 + 12 * v;
            let c = [0, 1, 2].map(|d| {
                let b = &rec[off + 4 * d..off + 4 * d + 4];
                f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            });
            if c.iter().any(|x| !x.is_finite()) {
                return Err(err(0, format!("binary facet {t} has a non-finite vertex")));
            }
            corners.push(c);
        }
    }
    Ok(corners)
}

fn parse_stl_ascii(bytes: &[u8], err: &ErrFn) -> Result<Vec<[f64; 3]>, SurfaceError> {
    let text = String::from_utf8_lossy(bytes);
    let mut corners = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        if it.next() == Some("vertex") {
            let c: Vec<f64> = it
                .map(|s| s.parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| err(i + 1, format!("bad vertex: {e}")))?;
            if c.len() != 3 || c.iter().any(|x| !x.is_finite()) {
                return Err(err(
                    i + 1,
                    format!("a vertex needs three finite coordinates, got {line:?}"),
                ));
            }
            corners.push([c[0], c[1], c[2]]);
        }
    }
    if !corners.len().is_multiple_of(3) {
        return Err(err(
            0,
            format!("{} vertices do not make whole triangles", corners.len()),
        ));
    }
    Ok(corners)
}

/// Merges vertices closer than [`WELD_RELATIVE`] × the bounding-box diagonal (a hash
/// grid of that cell size, each vertex compared with the 27 cells around it), drops
/// vertices no triangle uses, and renumbers. Returns the surface and how many
/// vertices were merged into another.
pub fn weld(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> (TriSurface, usize) {
    let finite: Vec<[f64; 3]> = vertices
        .iter()
        .copied()
        .filter(|v| v.iter().all(|c| c.is_finite()))
        .collect();
    let (lo, hi) = if finite.is_empty() {
        ([0.0; 3], [0.0; 3])
    } else {
        crate::mesh::bounds_of(&finite)
    };
    let diag = norm(sub(hi, lo));
    // A surface far beyond any organ's size is refused by validation, naming the
    // vertex; until then only bit-identical corners are merged.
    let tol = if diag.is_finite() && diag <= 1e3 * super::MAX_COORD_MM {
        WELD_RELATIVE * diag
    } else {
        0.0
    };
    let used = {
        let mut u = vec![false; vertices.len()];
        for t in triangles {
            for &v in t {
                u[v as usize] = true;
            }
        }
        u
    };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut out: Vec<[f64; 3]> = Vec::new();
    let mut map = vec![u32::MAX; vertices.len()];
    let mut merged = 0;
    let cell_of = |p: [f64; 3]| {
        if tol > 0.0 && p.iter().all(|c| c.is_finite()) {
            // Clamped so a coordinate far outside the others (refused later, by
            // validation, naming the vertex) cannot overflow the cell index.
            p.map(|c| (c / tol).floor().clamp(-1e15, 1e15) as i64)
        } else {
            [0; 3]
        }
    };
    for (i, &p) in vertices.iter().enumerate() {
        if !used[i] {
            continue;
        }
        let c = cell_of(p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &j in list {
                            let q = out[j as usize];
                            let close = if tol > 0.0 {
                                norm(sub(p, q)) <= tol
                            } else {
                                p.map(f64::to_bits) == q.map(f64::to_bits)
                            };
                            if close {
                                found = Some(j);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        map[i] = match found {
            Some(j) => {
                merged += 1;
                j
            }
            None => {
                out.push(p);
                let j = (out.len() - 1) as u32;
                grid.entry(c).or_default().push(j);
                j
            }
        };
    }
    let triangles = triangles
        .iter()
        .map(|t| t.map(|v| map[v as usize]))
        .collect();
    (
        TriSurface {
            vertices: out,
            triangles,
        },
        merged,
    )
}
