//! Export of meshes and solutions: VTK XML unstructured grids (`.vtu`, ParaView) and
//! gmsh MSH 4.1 ASCII (`.msh`). Both carry the node order of their format for
//! quadratic tetrahedra (VTK `tetra10` = ours; gmsh swaps the last two edges), point
//! fields (`displacement`, `nodal_force`, `fixed`, …) and the material and element as
//! field data, so another FE code can rebuild and re-solve the same discrete problem.
//! Files are written atomically.

use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::Path;

use crate::fe::Element;
use crate::fe::space::Space;
use crate::fsutil::atomic_write;

/// A per-node field: `components` values per node.
#[derive(Debug, Clone)]
pub struct PointField {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
}

/// Scalar metadata written as field data.
#[derive(Debug, Clone)]
pub struct FieldValue {
    pub name: String,
    pub value: f64,
}

fn check(nodes: usize, fields: &[PointField]) -> io::Result<()> {
    for f in fields {
        if f.values.len() != f.components * nodes {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "field '{}' has {} values, expected {} × {} nodes",
                    f.name,
                    f.values.len(),
                    f.components,
                    nodes
                ),
            ));
        }
    }
    Ok(())
}

fn join(values: impl Iterator<Item = String>) -> String {
    let mut s = String::new();
    for (i, v) in values.enumerate() {
        if i > 0 {
            s.push(if i % 12 == 0 { '\n' } else { ' ' });
        }
        s.push_str(&v);
    }
    s
}

/// What a written grid holds of the organ. The file says it twice: in an XML comment a
/// reader sees, and as the field value `palpa_holds_volume` (0 or 1) a script reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holds {
    /// The organ's surface only: its nodes and triangles (what a scene stores).
    Surface,
    /// Every node of the volume; the cells are the tetrahedra, or, for a model that
    /// stores no tetrahedra, the boundary triangles (the inner nodes are points).
    Volume,
}

impl Holds {
    fn comment(self) -> &'static str {
        match self {
            Holds::Surface => {
                "palpa: the organ's surface only (its nodes and triangles), as the model stores it"
            }
            Holds::Volume => "palpa: every node of the organ's volume, as the model stores it",
        }
    }
}

/// Writes a `.vtu` (VTK XML, ASCII) of a finite-element space.
pub fn write_vtu(
    path: &Path,
    space: &Space,
    fields: &[PointField],
    meta: &[FieldValue],
) -> io::Result<()> {
    check(space.nodes.len(), fields)?;
    let vtk_type = match space.element {
        Element::P1 => 10,
        Element::P2 => 24,
    };
    // A space with a material field (a nodule) carries it as cell data.
    let cell_fields: Vec<(&str, &[f64])> = space
        .stiffness
        .as_deref()
        .map(|s| ("stiffness_factor", s))
        .into_iter()
        .collect();
    write_cells_vtu(
        path,
        &space.nodes,
        &space.cells,
        (space.element.nodes_per_cell(), vtk_type),
        Holds::Volume,
        fields,
        &cell_fields,
        meta,
    )
}

/// Writes a `.vtu` of triangles (VTK type 5) over `nodes`, e.g. a scene's surface;
/// `holds` says whether `nodes` are the surface's or the whole volume's.
pub fn write_surface_vtu(
    path: &Path,
    nodes: &[[f64; 3]],
    triangles: &[[u32; 3]],
    holds: Holds,
    fields: &[PointField],
    meta: &[FieldValue],
) -> io::Result<()> {
    check(nodes.len(), fields)?;
    let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
    write_cells_vtu(path, nodes, &flat, (3, 5), holds, fields, &[], meta)
}

/// `cell_fields`: one value per cell each (a material field: each cell's Young's
/// modulus over the tissue's, `stiffness_factor`).
#[allow(clippy::too_many_arguments)]
fn write_cells_vtu(
    path: &Path,
    nodes: &[[f64; 3]],
    cells: &[u32],
    (npc, vtk_type): (usize, u8),
    holds: Holds,
    fields: &[PointField],
    cell_fields: &[(&str, &[f64])],
    meta: &[FieldValue],
) -> io::Result<()> {
    let ncells = cells.len() / npc;
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(
        s,
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    );
    let _ = writeln!(s, "<!-- {} -->", holds.comment());
    let _ = writeln!(s, "<UnstructuredGrid>\n<FieldData>");
    let _ = writeln!(
        s,
        r#"<DataArray type="Float64" Name="palpa_holds_volume" NumberOfTuples="1" format="ascii">{}</DataArray>"#,
        u8::from(holds == Holds::Volume)
    );
    for m in meta {
        let _ = writeln!(
            s,
            r#"<DataArray type="Float64" Name="{}" NumberOfTuples="1" format="ascii">{:e}</DataArray>"#,
            m.name, m.value
        );
    }
    let _ = writeln!(s, "</FieldData>");
    let _ = writeln!(
        s,
        r#"<Piece NumberOfPoints="{}" NumberOfCells="{}">"#,
        nodes.len(),
        ncells
    );
    let _ = writeln!(
        s,
        r#"<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">"#
    );
    s.push_str(&join(
        nodes.iter().flat_map(|p| p.map(|c| format!("{c:e}"))),
    ));
    let _ = writeln!(s, "\n</DataArray></Points>\n<Cells>");
    let _ = writeln!(
        s,
        r#"<DataArray type="Int64" Name="connectivity" format="ascii">"#
    );
    s.push_str(&join(cells.iter().map(|c| c.to_string())));
    let _ = writeln!(s, "\n</DataArray>");
    let _ = writeln!(
        s,
        r#"<DataArray type="Int64" Name="offsets" format="ascii">"#
    );
    s.push_str(&join((1..=ncells).map(|c| (c * npc).to_string())));
    let _ = writeln!(s, "\n</DataArray>");
    let _ = writeln!(s, r#"<DataArray type="UInt8" Name="types" format="ascii">"#);
    s.push_str(&join((0..ncells).map(|_| vtk_type.to_string())));
    let _ = writeln!(s, "\n</DataArray>\n</Cells>\n<PointData>");
    for f in fields {
        let _ = writeln!(
            s,
            r#"<DataArray type="Float64" Name="{}" NumberOfComponents="{}" format="ascii">"#,
            f.name, f.components
        );
        s.push_str(&join(f.values.iter().map(|v| format!("{v:e}"))));
        let _ = writeln!(s, "\n</DataArray>");
    }
    let _ = writeln!(s, "</PointData>");
    if !cell_fields.is_empty() {
        let _ = writeln!(s, "<CellData>");
        for (name, values) in cell_fields {
            let _ = writeln!(
                s,
                r#"<DataArray type="Float64" Name="{name}" NumberOfComponents="1" format="ascii">"#
            );
            s.push_str(&join(values.iter().map(|v| format!("{v:e}"))));
            let _ = writeln!(s, "\n</DataArray>");
        }
        let _ = writeln!(s, "</CellData>");
    }
    let _ = writeln!(s, "</Piece>\n</UnstructuredGrid>\n</VTKFile>");
    atomic_write(path, |w| w.write_all(s.as_bytes()))
}

/// Our (VTK) tetra10 order → gmsh's: gmsh lists edge (2,3) before (1,3).
const GMSH_TET10: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];

/// Writes a gmsh MSH 4.1 ASCII file: one volume entity, the tetrahedra, and each point
/// field as `$NodeData`; the metadata goes into `$Comments`-free string tags.
pub fn write_msh(
    path: &Path,
    space: &Space,
    fields: &[PointField],
    meta: &[FieldValue],
) -> io::Result<()> {
    check(space.nodes.len(), fields)?;
    let (lo, hi) = bbox(space);
    let n = space.nodes.len();
    let cells = space.cell_count();
    let mut s = String::new();
    let _ = writeln!(s, "$MeshFormat\n4.1 0 8\n$EndMeshFormat");
    let _ = writeln!(s, "$Entities\n0 0 0 1");
    let _ = writeln!(
        s,
        "1 {:e} {:e} {:e} {:e} {:e} {:e} 0 0",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    );
    let _ = writeln!(s, "$EndEntities");
    let _ = writeln!(s, "$Nodes\n1 {n} 1 {n}\n3 1 0 {n}");
    for i in 1..=n {
        let _ = writeln!(s, "{i}");
    }
    for p in &space.nodes {
        let _ = writeln!(s, "{:e} {:e} {:e}", p[0], p[1], p[2]);
    }
    let _ = writeln!(s, "$EndNodes");
    let (gtype, order): (u32, &[usize]) = match space.element {
        Element::P1 => (4, &[0, 1, 2, 3]),
        Element::P2 => (11, &GMSH_TET10),
    };
    let _ = writeln!(s, "$Elements\n1 {cells} 1 {cells}\n3 1 {gtype} {cells}");
    for c in 0..cells {
        let cell = space.cell(c);
        let _ = write!(s, "{}", c + 1);
        for &k in order {
            let _ = write!(s, " {}", cell[k] + 1);
        }
        s.push('\n');
    }
    let _ = writeln!(s, "$EndElements");
    for f in fields {
        let tags = meta
            .iter()
            .map(|m| format!("{}={:e}", m.name, m.value))
            .collect::<Vec<_>>()
            .join(" ");
        let _ = writeln!(
            s,
            "$NodeData\n2\n\"{}\"\n\"{}\"\n1\n0.0\n3\n0\n{}\n{n}",
            f.name, tags, f.components
        );
        for i in 0..n {
            let _ = write!(s, "{}", i + 1);
            for k in 0..f.components {
                let _ = write!(s, " {:e}", f.values[i * f.components + k]);
            }
            s.push('\n');
        }
        let _ = writeln!(s, "$EndNodeData");
    }
    atomic_write(path, |w| w.write_all(s.as_bytes()))
}

fn bbox(space: &Space) -> ([f64; 3], [f64; 3]) {
    crate::mesh::bounds_of(&space.nodes)
}

/// Writes `.vtu` or `.msh` by the path's extension.
pub fn write_by_extension(
    path: &Path,
    space: &Space,
    fields: &[PointField],
    meta: &[FieldValue],
) -> io::Result<()> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("vtu") => write_vtu(path, space, fields, meta),
        Some("msh") => write_msh(path, space, fields, meta),
        other => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{}: unknown output format {:?}, expected .vtu or .msh",
                path.display(),
                other.unwrap_or("")
            ),
        )),
    }
}
