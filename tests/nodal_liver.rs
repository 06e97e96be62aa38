//! The nodal-load vademecum on the coarse P1 liver: the load particularization is
//! exact (a full-rank model reproduces a direct FE solve at a vertex and between
//! vertices to solver precision), the compliance table is exact at its lattice points
//! and close between them, a truncated model keeps the near field exact under the tool,
//! and the file round trip keeps the near field.

use palpa_core::fe::{Element, Material};
use palpa_core::pgd::heldout::{self, nodal_errors};
use palpa_core::pgd::nodal::{NodalSettings, build, setup};
use palpa_core::{SeparatedModel, file};

use palpa_tests::coarse_liver;

fn press(
    s: &palpa_core::pgd::nodal::NodalSetup,
    face: usize,
    bary: [f64; 3],
    kind: &'static str,
) -> heldout::Case {
    heldout::press(&s.space, &s.problem, face, bary, s.radius_mm, kind).expect("FE solve")
}

#[test]
fn a_full_rank_model_is_exact_at_and_between_vertices_and_a_truncated_one_keeps_the_near_field() {
    let organ = coarse_liver();
    let s = setup(&organ, Element::P1, Material::default(), 5.0).expect("setup");
    let surface = organ.surface_nodes();
    let face = (0..organ.boundary.len())
        .find(|&f| organ.palpable[f])
        .expect("a palpable face");
    // A point on a vertex, on an edge, at the centroid and a generic interior point.
    let cases = vec![
        press(&s, face, [1.0, 0.0, 0.0], "vertex"),
        press(&s, face, [0.5, 0.5, 0.0], "edge"),
        press(&s, face, [1.0 / 3.0; 3], "centroid"),
        press(&s, face, [0.17, 0.29, 0.54], "interior"),
    ];
    // Full rank: the surface rows span at most 3·(surface nodes) directions.
    let full_rank = 3 * surface.len();
    let settings = NodalSettings {
        modes: full_rank,
        table_degree: Some(4),
        ..NodalSettings::default()
    };
    let (model, report) = build(&s, &settings, "test", |_| {}).expect("build");
    assert!(report.surface_map_rel_error < 1e-6, "{report:?}");
    for c in &cases {
        let e = nodal_errors(
            &model,
            &s.space,
            std::slice::from_ref(c),
            &surface,
            model.modes(),
        )
        .expect("evaluates");
        // Exact up to the solver and the f32 band: relative 1e-5.
        assert!(e.surface_rel_error < 1e-5, "{}: {e:?}", c.kind);
        // The compliance table is exact at its lattice points (a vertex, an edge
        // midpoint of a degree-4 lattice) and interpolated elsewhere.
        let tol = if c.kind == "vertex" || c.kind == "edge" {
            1e-5
        } else {
            5e-3
        };
        assert!(e.compliance_rel_error < tol, "{}: {e:?}", c.kind);
    }
    // Without the near field the same full-rank modes are still exact on the surface.
    let bare = model.clone().without_near();
    let e = nodal_errors(&bare, &s.space, &cases, &surface, bare.modes()).expect("evaluates");
    assert!(e.surface_rel_error < 1e-5, "{e:?}");

    // Truncated to 30 modes: the near field keeps every node within the band exact, so
    // the error falls well below the bare truncation's.
    let settings = NodalSettings {
        modes: 30,
        ..NodalSettings::default()
    };
    let (small, _) = build(&s, &settings, "test", |_| {}).expect("build");
    let with = nodal_errors(&small, &s.space, &cases, &surface, 30).expect("evaluates");
    let without = nodal_errors(
        &small.clone().without_near(),
        &s.space,
        &cases,
        &surface,
        30,
    )
    .expect("evaluates");
    assert!(
        with.surface_max_nodal_error_mm < 0.5 * without.surface_max_nodal_error_mm,
        "with {with:?}, without {without:?}"
    );
    assert!(with.compliance_rel_error < 2e-2, "{with:?}");
    // The hierarchical far field carries what the band leaves: the surface goals hold
    // at these points, and dropping the far field loses them.
    assert!(small.near().and_then(|n| n.far.as_ref()).is_some());
    assert!(with.surface_rel_error < 0.02, "{with:?}");
    assert!(with.surface_max_nodal_rel_error < 0.03, "{with:?}");
    let band_only = small.clone().with_far_tolerance(None);
    let e_band = nodal_errors(&band_only, &s.space, &cases, &surface, 30).expect("evaluates");
    assert!(
        e_band.surface_rel_error > 2.0 * with.surface_rel_error,
        "band only {e_band:?}, with far field {with:?}"
    );

    // The file keeps the near field; the surface-only f32 scene evaluates the same.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("nodal.palpa");
    file::save(&small, &path).expect("save");
    let back: SeparatedModel<f64> = file::load(&path).expect("load");
    assert_eq!(back.near(), small.near());
    let version = |p: &std::path::Path| {
        let b = std::fs::read(p).expect("read");
        u32::from_le_bytes(b[8..12].try_into().expect("4 bytes"))
    };
    assert_eq!(version(&path), file::FORMAT_VERSION);
    let Some(nested) = small.near().and_then(|n| n.far.as_deref()) else {
        panic!("the builder writes a far field");
    };
    assert!(
        nested.group_rank.iter().any(|&k| k > 0),
        "some row groups share a basis"
    );
    // Without the far field the model opens with its band only.
    let band_path = dir.path().join("band.palpa");
    file::save(&band_only, &band_path).expect("save");
    let back: SeparatedModel<f64> = file::load(&band_path).expect("load");
    assert!(back.near().is_some_and(|n| n.far.is_none()));
    assert_eq!(back.near(), band_only.near());
    let f32_scene = small
        .select_nodes(&surface)
        .expect("surface")
        .convert::<f32>();
    let near = f32_scene.near().expect("near kept");
    assert!(
        near.band_nodes
            .iter()
            .all(|&x| (x as usize) < surface.len())
    );
    let Some(far) = near.far.as_deref() else {
        panic!("far field kept");
    };
    assert!(far.group_rows.iter().all(|&x| (x as usize) < surface.len()));
    // The scene's near and far field give the full model's values on its rows.
    let probe = [palpa_core::axis::ParamValue::SurfaceMix {
        triangle: 0,
        bary: [0.2, 0.3, 0.5],
        mix: [0.0, 0.0, 1.0],
    }];
    let mut full = vec![0.0; small.rows()];
    small.add_near_field(&probe, &mut full).expect("full");
    let mut rows = vec![0.0; f32_scene.rows()];
    f32_scene.add_near_field(&probe, &mut rows).expect("scene");
    let scale = full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (i, &x) in surface.iter().enumerate() {
        for d in 0..3 {
            let (a, b) = (rows[3 * i + d], full[3 * x as usize + d]);
            assert!((a - b).abs() <= 1e-5 * scale, "node {x}: {a} vs {b}");
        }
    }
    // In sixteen bits (what `palpa export-scene` writes): the near
    // and far fields in about half the bytes, a probe's correction within 1e-3 of its
    // largest entry (a tenth of the far field's own tolerance; measured 1.8e-4), and
    // the accuracy against the reference unchanged.
    let size = |p: &std::path::Path| std::fs::metadata(p).expect("size").len();
    let (q_path, f_path) = (dir.path().join("q16.palpa"), dir.path().join("f32.palpa"));
    file::save_q16(&f32_scene, &q_path).expect("save q16");
    file::save(&f32_scene, &f_path).expect("save f32");
    let f32_near = f32_scene.near().expect("near");
    let near_bytes = f32_near.bytes() as u64;
    eprintln!(
        "scene: {} B in f32, {} B in sixteen bits (near and far fields {near_bytes} B in f32)",
        size(&f_path),
        size(&q_path)
    );
    assert!(size(&f_path) - size(&q_path) > near_bytes * 4 / 10);
    // What `palpa info` reports of them: their bits and stored bytes.
    let stored = |p: &std::path::Path| {
        file::read_header(p)
            .expect("header")
            .layout
            .near_field_bytes()
            .expect("a near field")
    };
    assert_eq!(stored(&f_path), (32, f32_near.bytes()));
    let (bits, q_bytes) = stored(&q_path);
    assert_eq!(bits, 16);
    assert!(
        q_bytes < f32_near.bytes() * 6 / 10,
        "{q_bytes} of {} B",
        f32_near.bytes()
    );
    let q16: SeparatedModel<f32> = file::load(&q_path).expect("load q16");
    let mut worst = 0.0f64;
    let mut rng = palpa_core::rng::Rng::seed(5);
    let palpable: Vec<usize> = (0..f32_near.table_block.len())
        .filter(|&f| f32_near.table_block[f] != u32::MAX)
        .collect();
    for &t in palpable.iter().step_by(palpable.len().div_ceil(20)) {
        let w = [
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
        ];
        let sum: f64 = w.iter().sum();
        let probe = [palpa_core::axis::ParamValue::SurfaceMix {
            triangle: t as u32,
            bary: w.map(|x| x / sum),
            mix: [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ],
        }];
        let (mut a, mut b) = (vec![0.0; f32_scene.rows()], vec![0.0; f32_scene.rows()]);
        f32_scene.add_near_field(&probe, &mut a).expect("f32");
        q16.add_near_field(&probe, &mut b).expect("q16");
        let scale = a.iter().fold(1e-12f64, |m, v| m.max(v.abs()));
        let diff = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        worst = worst.max(diff / scale);
    }
    eprintln!("sixteen bits: a probe's near and far correction within {worst:.1e} of its largest");
    assert!(worst < 1e-3, "{worst}");
    let q_full = dir.path().join("q16-full.palpa");
    file::save_q16(&small, &q_full).expect("save q16");
    let back: SeparatedModel<f64> = file::load(&q_full).expect("load q16");
    let e = nodal_errors(&back, &s.space, &cases, &surface, 30).expect("evaluates");
    assert!(
        (e.surface_max_nodal_error_mm - with.surface_max_nodal_error_mm).abs() < 1e-3
            && (e.compliance_rel_error - with.compliance_rel_error).abs() < 1e-4,
        "sixteen bits {e:?}, f32 {with:?}"
    );
    // Without a far field too (the band and table alone).
    let q_band = dir.path().join("q16-band.palpa");
    file::save_q16(&band_only, &q_band).expect("save q16");
    let back: SeparatedModel<f64> = file::load(&q_band).expect("load");
    assert!(back.near().is_some_and(|n| n.far.is_none()
        && n.band_values.len() == band_only.near().expect("near").band_values.len()));
    // A model without a load axis refuses a near field with its reason.
    let err = palpa_core::synthetic::palpation_like::<f64>(12, 2, 3, 1)
        .with_near(small.near().expect("near").clone())
        .expect_err("no load axis");
    assert!(err.to_string().contains("surface-load"), "{err}");
}
