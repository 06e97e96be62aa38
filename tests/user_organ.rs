//! A user's organ from a surface file: every reader on files of every kind, units and
//! axes, repairs, and the extremes (a sphere and an ellipsoid in cm and m against the
//! volume formula, a triangle soup, polygons, a hole, inside-out, two pieces, a
//! self-intersection, a huge coordinate, a thin organ).

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use palpa_core::mesh::quality;
use palpa_core::organ::user::{self, SurfaceOptions, UserOrganError};
use palpa_core::organ::{Level, Selector, default_user_regions};
use palpa_core::surface_import::frame::{Axes, Units};
use palpa_core::surface_import::read::read;
use palpa_core::surface_import::shapes::{ellipsoid, icosphere};
use palpa_core::surface_import::{Format, SurfaceError, TriSurface};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

fn options(units: Units) -> SurfaceOptions {
    SurfaceOptions {
        units,
        axes: Axes::default(),
        close_holes_max_edges: 0,
        largest_component: false,
        strict: true,
    }
}

fn bytes_of(f: impl FnOnce(&mut Vec<u8>) -> std::io::Result<()>) -> Vec<u8> {
    let mut v = Vec::new();
    f(&mut v).expect("write to memory");
    v
}

/// The same sphere as OBJ, binary STL, ASCII and binary PLY, under misleading names:
/// the format is told by content and every reader gives the same closed surface.
#[test]
fn every_reader_reads_the_same_surface_by_content() {
    let dir = tempfile::tempdir().expect("tempdir");
    let s = ellipsoid(40.0, 30.0, 20.0, 2);
    let files = [
        ("a.obj", bytes_of(|w| s.write_obj(w)), Format::Obj),
        (
            "b.dat",
            bytes_of(|w| s.write_stl_binary(w)),
            Format::StlBinary,
        ),
        (
            "c.txt",
            bytes_of(|w| s.write_ply(w, false)),
            Format::PlyAscii,
        ),
        (
            "d.stl",
            bytes_of(|w| s.write_ply(w, true)),
            Format::PlyBinary,
        ),
    ];
    for (name, bytes, format) in files {
        let r = read(&write(dir.path(), name, &bytes)).expect(name);
        assert_eq!(r.format, format, "{name}");
        let mut got = r.surface;
        assert_eq!(got.triangles.len(), s.triangles.len(), "{name}");
        assert_eq!(
            got.vertices.len(),
            s.vertices.len(),
            "{name}: welded to shared vertices"
        );
        got.validate().expect(name);
        let rel = (got.volume() - s.volume()).abs() / s.volume();
        assert!(rel < 1e-6, "{name}: volume off by {rel:e}");
    }
    // Binary STL stores every corner separately: all but one per vertex are welded.
    let r = read(&write(
        dir.path(),
        "e.stl",
        &bytes_of(|w| s.write_stl_binary(w)),
    ))
    .expect("stl");
    assert_eq!(r.welded, 3 * s.triangles.len() - s.vertices.len());
}

/// What OBJ exporters write: normals, texture coordinates, groups, objects,
/// materials, quads, and negative (relative) indices.
#[test]
fn obj_with_everything_exporters_write_reads_as_a_closed_cube() {
    let text = "# exported\nmtllib cube.mtl\no Cube\ng skin\n\
        v 0 0 0\nv 10 0 0\nv 0 10 0\nv 10 10 0\nv 0 0 10\nv 10 0 10\nv 0 10 10\nv 10 10 10\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 -1\nusemtl red\ns off\n\
        f 1/1/1 3/2/1 4/3/1 2/1/1\nf 5//1 6//1 8//1 7//1\nf -8/1 -7/2 -3/3 -4/1\n\
        f 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    let dir = tempfile::tempdir().expect("tempdir");
    let r = read(&write(dir.path(), "cube.obj", text.as_bytes())).expect("obj");
    assert_eq!(r.polygons_split, 6);
    let mut s = r.surface;
    assert_eq!(s.triangles.len(), 12);
    s.validate().expect("closed cube");
    assert!((s.volume() - 1000.0).abs() < 1e-9);
}

/// Spheres and ellipsoids in cm and in m become the right size in mm, their enclosed
/// volume within 1 % of the formula (the polyhedron is inscribed) and the tetrahedral
/// mesh's within 2 % of the enclosed one, with min dihedral ≥ 10°.
#[test]
fn spheres_and_ellipsoids_in_cm_and_m_mesh_to_the_right_volume() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (units, r_file) in [(Units::Cm, 5.0), (Units::M, 0.05)] {
        for (name, (a, b, c)) in [("sphere", (1.0, 1.0, 1.0)), ("ellipsoid", (1.0, 0.75, 0.5))] {
            let s = ellipsoid(a * r_file, b * r_file, c * r_file, 4);
            let p = dir.path().join(format!("{name}-{}.stl", units.name()));
            s.write_by_extension(&p).expect("write");
            let (solid, rep) = user::prepare(&p, &options(units)).expect("prepare");
            let r_mm = 50.0;
            let exact = 4.0 / 3.0 * PI * (a * r_mm) * (b * r_mm) * (c * r_mm);
            let enclosed = rep.enclosed_volume_mm3;
            assert!(
                (enclosed - exact).abs() / exact < 0.01,
                "{name} in {}: {enclosed} mm³ vs {exact}",
                units.name()
            );
            assert!(rep.warnings.is_empty(), "{:?}", rep.warnings);
            let (fixed, _) = default_user_regions();
            let organ =
                user::mesh(&solid, Level::Coarse, &fixed, &Selector::Everything).expect("mesh");
            let meshed = organ.mesh.volume();
            assert!(
                (meshed - enclosed).abs() / enclosed < 0.02,
                "{name} in {}: meshed {meshed} vs {enclosed}",
                units.name()
            );
            let q = quality(&organ.mesh);
            assert!(q.min_dihedral_deg >= 10.0 && q.inverted == 0, "{q:?}");
        }
    }
}

/// The same sphere read as mm (0.05 m taken for mm) is flagged as the wrong unit.
#[test]
fn a_size_that_looks_like_another_unit_is_flagged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("tiny.obj");
    ellipsoid(0.05, 0.05, 0.05, 2)
        .write_by_extension(&p)
        .expect("write");
    let (_, rep) = user::prepare(&p, &options(Units::Mm)).expect("prepare");
    assert!(
        rep.warnings.iter().any(|w| w.contains("larger units")),
        "{:?}",
        rep.warnings
    );
}

/// Axes: a surface in cm with y up and −z anterior lands with its long axis on the
/// patient's z and its front on +y.
#[test]
fn axes_map_the_file_frame_to_the_patient() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("e.ply");
    // Long along file y (up), thin along file z.
    ellipsoid(3.0, 6.0, 1.5, 2)
        .write_by_extension(&p)
        .expect("write");
    let o = SurfaceOptions {
        axes: Axes::from_up_anterior("y", "-z").expect("axes"),
        ..options(Units::Cm)
    };
    let (_, rep) = user::prepare(&p, &o).expect("prepare");
    let (lo, hi) = rep.bbox_mm;
    assert!((hi[2] - lo[2] - 120.0).abs() < 1e-6, "z span {lo:?} {hi:?}");
    assert!((hi[1] - lo[1] - 30.0).abs() < 1e-6, "y span");
    assert!((hi[0] - lo[0] - 60.0).abs() < 1e-6, "x span");
    assert!(!rep.mirrored && !rep.flipped);
}

#[test]
fn a_hole_is_an_error_until_closed_and_the_closing_is_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = icosphere(3);
    // Remove the five triangles around vertex 0: a pentagonal hole.
    s.triangles.retain(|t| !t.contains(&0));
    let p = dir.path().join("holed.obj");
    s.write_by_extension(&p).expect("write");
    let e = user::prepare(&p, &options(Units::Cm)).expect_err("open");
    assert!(
        e.to_string().contains("hole") && e.to_string().contains("--close-holes"),
        "{e}"
    );
    let (_, rep) = user::prepare(
        &p,
        &SurfaceOptions {
            close_holes_max_edges: 8,
            ..options(Units::Cm)
        },
    )
    .expect("closed");
    assert_eq!(rep.holes.closed, 1);
    assert_eq!(rep.holes.triangles_added, 5);
    // A limit below the hole's size leaves it, and says so.
    let e = user::prepare(
        &p,
        &SurfaceOptions {
            close_holes_max_edges: 4,
            ..options(Units::Cm)
        },
    )
    .expect_err("too large");
    assert!(e.to_string().contains("hole"), "{e}");
}

#[test]
fn an_inside_out_surface_is_turned_outward_and_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = icosphere(2);
    for t in &mut s.triangles {
        t.swap(1, 2);
    }
    let p = dir.path().join("inside-out.obj");
    s.write_by_extension(&p).expect("write");
    let (solid, rep) = user::prepare(&p, &options(Units::Cm)).expect("prepare");
    assert!(rep.flipped);
    assert!(rep.warnings.iter().any(|w| w.contains("inside-out")));
    assert!(solid.surface().volume() > 0.0);
}

#[test]
fn two_pieces_are_refused_then_the_largest_kept_on_request() {
    let dir = tempfile::tempdir().expect("tempdir");
    let big = icosphere(2);
    let mut small = ellipsoid(0.3, 0.3, 0.3, 1);
    for v in &mut small.vertices {
        v[0] += 3.0;
    }
    let n = big.vertices.len() as u32;
    let s = TriSurface {
        vertices: big
            .vertices
            .iter()
            .chain(&small.vertices)
            .copied()
            .collect(),
        triangles: big
            .triangles
            .iter()
            .copied()
            .chain(small.triangles.iter().map(|t| t.map(|i| i + n)))
            .collect(),
    };
    let p = dir.path().join("two.obj");
    s.write_by_extension(&p).expect("write");
    let e = user::prepare(&p, &options(Units::Cm)).expect_err("two pieces");
    assert!(
        matches!(
            e,
            UserOrganError::Surface(SurfaceError::Components { count: 2, .. })
        ),
        "{e}"
    );
    assert!(e.to_string().contains("--largest-component"), "{e}");
    let (_, rep) = user::prepare(
        &p,
        &SurfaceOptions {
            largest_component: true,
            ..options(Units::Cm)
        },
    )
    .expect("largest");
    assert_eq!(rep.pieces_dropped, vec![80]);
    assert_eq!(rep.triangles, 320);
}

/// A closed surface whose faces cross, and a coordinate of 1e308: named, not meshed.
#[test]
fn crossing_faces_and_huge_coordinates_are_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = icosphere(2);
    // Pull one vertex through the far side.
    s.vertices[0] = s.vertices[0].map(|c| -2.0 * c);
    let p = dir.path().join("crossing.obj");
    s.write_by_extension(&p).expect("write");
    let e = user::prepare(&p, &options(Units::Cm)).expect_err("crossing");
    assert!(e.to_string().contains("intersects itself"), "{e}");
    let mut s = icosphere(1);
    s.vertices[3] = [1e308, 0.0, 0.0];
    let p = dir.path().join("huge.obj");
    std::fs::write(&p, bytes_of(|w| s.write_obj(w))).expect("write");
    let e = user::prepare(&p, &options(Units::Mm)).expect_err("huge");
    assert!(e.to_string().contains("out of range"), "{e}");
}

/// A plate 1 mm thick and 100 mm wide is thinner than the coarse lattice: said so.
#[test]
fn an_organ_thinner_than_the_lattice_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("plate.obj");
    ellipsoid(50.0, 50.0, 0.5, 3)
        .write_by_extension(&p)
        .expect("write");
    let (solid, _) = user::prepare(&p, &options(Units::Mm)).expect("prepare");
    let e = user::mesh(
        &solid,
        Level::Coarse,
        &Selector::Everything,
        &Selector::Everything,
    )
    .expect_err("thin");
    assert!(matches!(e, UserOrganError::TooThin { .. }), "{e}");
    assert!(e.to_string().contains("finer level"), "{e}");
}

#[test]
fn regions_that_fix_nothing_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("s.obj");
    icosphere(3).write_by_extension(&p).expect("write");
    let (solid, _) = user::prepare(&p, &options(Units::Cm)).expect("prepare");
    let e = user::mesh(
        &solid,
        Level::Coarse,
        &Selector::Nothing,
        &Selector::Everything,
    )
    .expect_err("free");
    assert!(e.to_string().contains("free to move"), "{e}");
    let e = user::mesh(
        &solid,
        Level::Coarse,
        &Selector::Everything,
        &Selector::Everything,
    )
    .expect_err("nothing palpable");
    assert!(matches!(e, UserOrganError::NoPalpable), "{e}");
}

/// Mutated bytes, cut, repeated or dropped (seeded), of surfaces in every format,
/// and of region files and selectors: a result or an error, never a panic.
#[test]
fn mutated_surfaces_regions_and_selectors_never_panic() {
    use palpa_core::organ::region_file::RegionFile;
    use palpa_core::organ::syntax::parse;
    use palpa_core::rng::Rng;
    use palpa_core::surface_import::read::read_bytes;
    use palpa_core::surface_import::repair::close_holes;

    let s = icosphere(1);
    let mut ascii_stl = String::from("solid s\n");
    for t in &s.triangles {
        ascii_stl += "facet normal 0 0 0\nouter loop\n";
        for &v in t {
            let p = s.vertices[v as usize];
            ascii_stl += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        ascii_stl += "endloop\nendfacet\n";
    }
    ascii_stl += "endsolid s\n";
    let surfaces = [
        bytes_of(|w| s.write_obj(w)),
        bytes_of(|w| s.write_stl_binary(w)),
        bytes_of(|w| s.write_ply(w, false)),
        bytes_of(|w| s.write_ply(w, true)),
        ascii_stl.into_bytes(),
    ];
    let texts = [
        "version = 1\nmatch_radius_mm = 5.0\nfixed_selectors = [\"normal:posterior:45 & !ball:0,0,0:10\"]\nfixed_points = [[1.0, 2.0, 3.0]]\npalpable_points = [[4.0, 5.0, 6.0]]\n".as_bytes().to_vec(),
        b"(normal:-y:45 | half:0,0,-20:0,0,1) & !polyline:0,0,0;10,0,0;10,10,0:5".to_vec(),
    ];
    let mut rng = Rng::seed(18);
    let alphabet = b"-.0123456789eE /:;,&|!()[]=\n\x00\xff";
    let mutate = |rng: &mut Rng, seed: &[u8]| rng.mutate_bytes(seed, alphabet, 4, 40);
    let (mut read_ok, mut valid) = (0, 0);
    for k in 0..3000 {
        let bytes = mutate(&mut rng, &surfaces[k % surfaces.len()]);
        if let Ok(r) = read_bytes(Path::new("mutated.obj"), &bytes) {
            read_ok += 1;
            let mut s = r.surface;
            close_holes(&mut s, 6);
            if s.validate().is_ok() {
                valid += 1;
            }
        }
    }
    let mut regions_ok = 0;
    for k in 0..3000 {
        let bytes = mutate(&mut rng, &texts[k % texts.len()]);
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(sel) = parse(&text) {
            let _ = sel.contains([0.0; 3], [0.0, 1.0, 0.0]);
        }
        if RegionFile::from_text(&text, Path::new("mutated.toml")).is_ok() {
            regions_ok += 1;
        }
    }
    // The mutations reach past the parsers: some files still read, some still close.
    assert!(read_ok > 300 && valid > 30, "{read_ok} read, {valid} valid");
    assert!(regions_ok > 10, "{regions_ok} region files read");
}

fn scaled(mut s: TriSurface, r: f64, at: [f64; 3]) -> TriSurface {
    for v in &mut s.vertices {
        *v = [0, 1, 2].map(|d| r * v[d] + at[d]);
    }
    s
}

fn union(a: &TriSurface, b: &TriSurface) -> TriSurface {
    let n = a.vertices.len() as u32;
    TriSurface {
        vertices: a.vertices.iter().chain(&b.vertices).copied().collect(),
        triangles: a
            .triangles
            .iter()
            .copied()
            .chain(b.triangles.iter().map(|t| t.map(|i| i + n)))
            .collect(),
    }
}

fn default_options() -> SurfaceOptions {
    SurfaceOptions {
        strict: false,
        ..options(Units::Mm)
    }
}

/// SOFA's liver surface (tests/data/sofa-liver: 4 384 triangles in cm) crosses itself:
/// refused by a strict reading, naming the crossing; read by its winding number by
/// default, the crossing reported, and meshed to within 2 % of the winding number's
/// inside. Measured: 5 pairs of triangles cross (the first near (−21.0, 41.4, −9.7)
/// mm), 39.27 ml inside, none of it ambiguous, 0.03 mm³ wrapped twice; the coarse
/// mesh 1.57 % under it (the goal is 2 %).
#[test]
fn a_surface_that_crosses_itself_meshes_by_its_winding_number() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/sofa-liver/liver-smooth.obj");
    let strict = SurfaceOptions {
        strict: true,
        ..options(Units::Cm)
    };
    let e = user::prepare(&p, &strict).expect_err("strict refuses it");
    assert!(
        matches!(
            e,
            UserOrganError::Surface(SurfaceError::SelfIntersecting { .. })
        ),
        "{e}"
    );
    let o = SurfaceOptions {
        strict: false,
        ..options(Units::Cm)
    };
    let (solid, rep) = user::prepare(&p, &o).expect("read by its winding number");
    let w = rep.winding.as_ref().expect("a winding report");
    eprintln!(
        "{:?}, enclosed {:.1} ml",
        w,
        rep.enclosed_volume_mm3 / 1000.0
    );
    assert!(
        w.defects.iter().any(|l| l.contains("crosses itself")),
        "{:?}",
        w.defects
    );
    assert!(w.inside.ambiguous_mm3 < 0.02 * w.inside.volume_mm3);
    let (fixed, palpable) = default_user_regions();
    let organ = user::mesh(&solid, Level::Coarse, &fixed, &palpable).expect("meshes");
    let meshed = organ.mesh.volume();
    let rel = meshed / rep.enclosed_volume_mm3 - 1.0;
    eprintln!("meshed {:.1} ml ({:+.2} %)", meshed / 1000.0, 100.0 * rel);
    assert!(
        rel.abs() < 0.02,
        "meshed {meshed} against {}",
        rep.enclosed_volume_mm3
    );
    let q = quality(&organ.mesh);
    assert!(q.inverted == 0, "{q:?}");
}

/// Two spheres of 30 mm radius, centres `d` ≈ 30 mm apart, as two closed surfaces that
/// cross (what a segmentation of two touching blobs exports): the winding number's
/// inside is their union, `2 · 4/3 π r³` less the lens `π (4r + d)(2r − d)² / 12`,
/// within the inscribed polyhedra's 0.3 %; the coarse mesh within 2 % of it; the
/// crossing and the two pieces reported.
#[test]
fn two_crossing_closed_surfaces_mesh_as_their_union() {
    let dir = tempfile::tempdir().expect("tempdir");
    let r = 30.0;
    // Off the symmetric placement, where the two spheres' vertices would coincide.
    let at: [f64; 3] = [r, 1.7, 0.9];
    let d = (at[0] * at[0] + at[1] * at[1] + at[2] * at[2]).sqrt();
    let s = union(
        &scaled(icosphere(4), r, [0.0; 3]),
        &scaled(icosphere(4), r, at),
    );
    let p = dir.path().join("two-blobs.stl");
    s.write_by_extension(&p).expect("write");
    let (solid, rep) = user::prepare(&p, &default_options()).expect("read");
    let w = rep.winding.as_ref().expect("a winding report");
    assert!(w.defects.iter().any(|l| l.contains("crosses itself")));
    assert!(w.defects.iter().any(|l| l.contains("2 separate pieces")));
    assert!(w.stray_dropped.is_empty());
    let lens = PI * (4.0 * r + d) * (2.0 * r - d).powi(2) / 12.0;
    let exact = 2.0 * 4.0 / 3.0 * PI * r.powi(3) - lens;
    let inside = rep.enclosed_volume_mm3;
    assert!(
        (inside / exact - 1.0).abs() < 6e-3,
        "{inside} against {exact}"
    );
    // The lens is wrapped twice.
    assert!(
        (w.inside.multiple_mm3 / lens - 1.0).abs() < 0.02,
        "{:?}",
        w.inside
    );
    let (fixed, _) = default_user_regions();
    let organ = user::mesh(&solid, Level::Coarse, &fixed, &Selector::Everything).expect("mesh");
    let rel = organ.mesh.volume() / inside - 1.0;
    assert!(rel.abs() < 0.02, "meshed {:+.2} %", 100.0 * rel);
}

/// A stray island apart from the organ is dropped and said (a second body is refused);
/// a small hole is read through without `--close-holes`.
#[test]
fn a_stray_piece_is_dropped_and_a_small_hole_read_through() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut body = scaled(icosphere(3), 40.0, [0.0; 3]);
    body.triangles.retain(|t| !t.contains(&0));
    let s = union(&body, &scaled(icosphere(1), 3.0, [80.0, 0.0, 0.0]));
    let p = dir.path().join("island.obj");
    s.write_by_extension(&p).expect("write");
    let (_, rep) = user::prepare(&p, &default_options()).expect("read");
    let w = rep.winding.as_ref().expect("a winding report");
    assert_eq!(w.stray_dropped, vec![80]);
    // Two bodies apart (the pieces test's spheres) are not an island: refused by
    // default too, naming the pieces.
    let two = dir.path().join("two-bodies.obj");
    union(
        &scaled(icosphere(2), 40.0, [0.0; 3]),
        &scaled(icosphere(2), 30.0, [100.0, 0.0, 0.0]),
    )
    .write_by_extension(&two)
    .expect("write");
    let e = user::prepare(&two, &default_options()).expect_err("two bodies");
    assert!(
        matches!(
            e,
            UserOrganError::Surface(SurfaceError::Components { count: 2, .. })
        ),
        "{e}"
    );
    assert!(
        w.defects.iter().any(|l| l.contains("has holes")),
        "{:?}",
        w.defects
    );
    let sphere = 4.0 / 3.0 * PI * 40f64.powi(3);
    assert!((rep.enclosed_volume_mm3 / sphere - 1.0).abs() < 0.02);
}

/// An open bowl (half a sphere) is not a solid in any reading: refused by name.
#[test]
fn an_open_sheet_is_refused_as_having_no_inside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut s = scaled(icosphere(3), 40.0, [0.0; 3]);
    let v = s.vertices.clone();
    s.triangles
        .retain(|t| t.iter().all(|&i| v[i as usize][2] > 0.0));
    let p = dir.path().join("bowl.obj");
    s.write_by_extension(&p).expect("write");
    let e = user::prepare(&p, &default_options()).expect_err("no inside");
    assert!(matches!(e, UserOrganError::NoInside { .. }), "{e}");
    assert!(e.to_string().contains("no clear inside"), "{e}");
}
