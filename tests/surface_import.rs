//! A user surface goes through the same pipeline as the procedural liver: the liver's
//! own boundary, written as OBJ and read back, meshes to nearly the same solid.

use std::fmt::Write as _;

use palpa_core::mesh::quality;
use palpa_core::organ::liver::{Liver, spacing_mm};
use palpa_core::organ::{Level, default_user_regions, mesh_organ};
use palpa_core::surface_import::{SurfaceSolid, TriSurface};

#[test]
fn the_liver_surface_round_trips_through_obj_into_a_volume_mesh() {
    let liver = Liver::default();
    let organ = mesh_organ(
        &liver,
        spacing_mm(Level::Medium),
        &liver.fixed_region(),
        &liver.palpable_region(),
    );
    // Keep only the vertices the boundary uses, renumbered.
    let mut map = vec![u32::MAX; organ.mesh.vertices.len()];
    let mut obj = String::new();
    let mut next = 0u32;
    for f in &organ.boundary {
        for &v in f {
            if map[v as usize] == u32::MAX {
                map[v as usize] = next;
                next += 1;
                let p = organ.mesh.vertices[v as usize];
                let _ = writeln!(obj, "v {:.17e} {:.17e} {:.17e}", p[0], p[1], p[2]);
            }
        }
    }
    for f in &organ.boundary {
        let _ = writeln!(
            obj,
            "f {} {} {}",
            map[f[0] as usize] + 1,
            map[f[1] as usize] + 1,
            map[f[2] as usize] + 1
        );
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("liver.obj");
    std::fs::write(&path, obj).expect("write");

    let mut s = TriSurface::read(&path).expect("read");
    s.validate()
        .expect("the liver boundary is a closed manifold");
    let enclosed = s.volume();
    let (fixed, palpable) = default_user_regions();
    let user = mesh_organ(
        &SurfaceSolid::new(s),
        spacing_mm(Level::Coarse),
        &fixed,
        &palpable,
    );
    let q = quality(&user.mesh);
    assert_eq!(q.inverted, 0);
    assert!(q.min_dihedral_deg >= 10.0, "{q:?}");
    let rel = (user.mesh.volume() - enclosed).abs() / enclosed;
    eprintln!(
        "user mesh: {} vertices, volume error {rel:.4}, {q:?}",
        user.mesh.vertices.len()
    );
    // Stuffing at h = 12 mm resolves the surface to O(h²/R): a few percent.
    assert!(rel < 0.03, "volume {} vs {enclosed}", user.mesh.volume());
    assert!(user.fixed.iter().any(|&f| f) && user.palpable.iter().any(|&p| p));
}
