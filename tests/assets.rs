//! The default scene in `assets/` comes from the current code and mesh: its recorded
//! inputs (organ mesh hash, element, material, tool radius) are recomputed here and
//! must match, and its surface geometry must be the current mesh's.

use palpa_core::axis::Discretization;
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::organ::Level;
use palpa_core::pgd::palpation::{describe, describe_get};

#[test]
fn the_default_scene_matches_the_current_mesh_and_settings() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.palpa");
    let model = file::load::<f32>(&path).expect("assets/liver-coarse.palpa loads as an f32 scene");
    let desc = &model.provenance().mesh;
    let organ = palpa_tests::coarse_liver();
    let radius: f64 = describe_get(desc, "radius_mm")
        .expect("radius recorded")
        .parse()
        .expect("number");
    let now = describe(
        &organ,
        "coarse",
        Element::P2,
        Material::default(),
        radius,
        describe_get(desc, "update") == Some("true"),
    );
    assert_eq!(
        desc, &now,
        "the asset was computed from another mesh or settings: run scripts/make-assets.sh"
    );
    assert_eq!(
        model.provenance().input_hash,
        format!("{:016x}", xxhash_rust::xxh3::xxh3_64(now.as_bytes()))
    );
    // The load axis covers the current palpable surface, face for face.
    let Discretization::SurfaceLoad {
        palpable: faces, ..
    } = &model.axes()[0].info.discretization
    else {
        panic!("the default scene is a nodal-load vademecum");
    };
    let palpable: usize = organ.palpable.iter().filter(|&&p| p).count();
    assert_eq!(faces.iter().filter(|&&p| p).count(), palpable);
    assert!(palpable > 100);
    let near = model
        .near()
        .expect("the default scene carries its near field");
    assert!(near.band_nodes.len() > 1000 && !near.table_values.is_empty());
    // Surface-only: every row belongs to a boundary node, and the geometry is there.
    assert_eq!(model.geometry().nodes.len() * 3, model.rows());
    assert!(!model.geometry().surface.is_empty());
    assert!(
        !model.tradeoff().is_empty(),
        "the tradeoff table the accuracy knob reads"
    );
    // A phone budget of 20 MB; the near and far fields in sixteen bits (what
    // `palpa export-scene` writes by default).
    assert!(std::fs::metadata(&path).expect("size").len() < 20_000_000);
    assert!(
        matches!(
            file::read_header(&path).expect("header").layout,
            file::Layout::SeparatedNearQ16 { .. }
        ),
        "the shipped scene stores its near and far fields in sixteen bits"
    );
}

/// The kidney example in `assets/kidney/` comes from the shipped surface with the
/// arguments of `scripts/make-kidney.sh`: its recorded source hash is the surface
/// file's, and re-meshing the surface with those arguments gives the recorded mesh.
#[test]
fn the_kidney_example_matches_its_shipped_surface() {
    use palpa_core::organ::syntax::parse;
    use palpa_core::organ::user::{self, SurfaceOptions};
    use palpa_core::pgd::palpation::describe_user;
    use palpa_core::surface_import::frame::{Axes, Units};

    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/kidney");
    let scene =
        file::load::<f32>(&root.join("kidney-coarse.palpa")).expect("the kidney scene loads");
    let desc = &scene.provenance().mesh;
    let surface = root.join("kidney.obj");
    let bytes = std::fs::read(&surface).expect("the kidney surface is shipped");
    assert_eq!(
        describe_get(desc, "source_xxh3"),
        Some(format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes)).as_str()),
        "the scene was built from another surface: run scripts/make-kidney.sh"
    );
    let (solid, report) = user::prepare(
        &surface,
        &SurfaceOptions {
            units: Units::Cm,
            axes: Axes::from_up_anterior("y", "z").expect("axes"),
            close_holes_max_edges: 0,
            largest_component: false,
            strict: false,
        },
    )
    .expect("the kidney surface is a closed manifold");
    // 11 × 6 × 4 cm.
    let (lo, hi) = report.bbox_mm;
    assert!((hi[2] - lo[2] - 110.0).abs() < 1e-6, "{lo:?} {hi:?}");
    let fixed = parse("normal:posterior:50").expect("selector");
    let palpable = parse("normal:anterior:85").expect("selector");
    let organ = user::mesh(
        &solid,
        Level::Coarse,
        &palpa_core::organ::Selector::Any(vec![fixed]),
        &palpa_core::organ::Selector::Any(vec![palpable]),
    )
    .expect("meshes");
    let regions = describe_get(desc, "regions").expect("regions recorded");
    let source = format!(
        "source=kidney.obj source_xxh3={} units=cm axes={} regions={regions}",
        report.source_xxh3, report.axes
    );
    let now = describe_user(
        &organ,
        "coarse",
        Element::P2,
        Material::default(),
        5.0,
        &source,
    );
    assert_eq!(
        desc, &now,
        "the kidney scene is stale: run scripts/make-kidney.sh"
    );
    assert!(
        !scene.tradeoff().is_empty(),
        "the scene carries its tradeoff table"
    ); // What `palpa open --scene assets/kidney/kidney-coarse.palpa` builds.
    let any = file::load_any(&root.join("kidney-coarse.palpa")).expect("loads");
    let s = palpa_core::scene::PalpationScene::new(any).expect("a palpation scene");
    assert_eq!(s.vertices_mm().len() * 3, scene.rows());
}

/// The default scene's tissue (`assets/liver-coarse.tissue`) comes from the current
/// code: its options are the build's, every palpable vertex clear of the fixed region
/// was pressed (or skipped with a reason), it binds to the default scene, scene and
/// tissue fit the phone budget together, its split triangles are the worst of its own
/// unsplit form and its sub-triangles split again the worst of its first level, its band
/// next to the fixed region every band edge, and one
/// of its vertex presses, pressed again here, gives back its
/// force ratio and (within the stored bound) its surface.
#[test]
fn the_default_tissue_comes_from_the_current_code() {
    use palpa_core::scene::PalpationScene;
    use palpa_core::tissue::law::TissueLaw;
    use palpa_core::tissue::surface::{SurfaceLaw, SurfaceLawOptions};

    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    let path = root.join("liver-coarse.tissue");
    let law = TissueLaw::load(&path).expect("assets/liver-coarse.tissue loads");
    let o = law.options;
    assert_eq!(
        o,
        SurfaceLawOptions {
            depth_max_mm: 15.0,
            ..SurfaceLawOptions::default()
        },
        "the tissue was built with other options: see scripts/make-assets.sh"
    );
    let organ = palpa_tests::coarse_liver();
    let palpable = organ.pressable_vertices();
    assert_eq!(
        law.samples_mm.len() + law.skipped_mm.len(),
        palpable.len(),
        "the whole palpable surface"
    );
    assert!(law.skipped_mm.len() * 50 < palpable.len());

    // It binds to the default scene; with the nodule table (the tissue's power in it)
    // the three fit the 20 MB kept for phones (18.8 MB; docs/lab/nodule-measurements.md
    // §18), and no one file passes 8 MB.
    let scene = PalpationScene::new(
        file::load_any(&root.join("liver-coarse.palpa")).expect("the default scene loads"),
    )
    .expect("scene");
    law.check_linear_model(&scene.model().provenance().mesh)
        .expect("the default scene's element and material");
    let bytes = |f: &str| std::fs::metadata(root.join(f)).expect("size").len();
    let files = [
        "liver-coarse.palpa",
        "liver-coarse.tissue",
        "liver-coarse.nodules",
    ];
    assert!(files.iter().map(|f| bytes(f)).sum::<u64>() < 20_000_000);
    assert!(files.iter().all(|f| bytes(f) < 8_000_000));

    // Its split triangles are a refinement stage of its own vertices and edges: the
    // worst of its unsplit form by largest edge surplus, as `lab tissue refine --triangles`
    // picks them.
    let split = law.refinement.triangles.len();
    assert!(
        split > 0,
        "the default tissue is refined: see scripts/make-assets.sh"
    );
    let above = law
        .refinement
        .above_mm
        .expect("a refined file keeps its threshold");
    let base = law
        .unsplit()
        .surface_law(&organ)
        .expect("its unsplit form reads back");
    let centroid = |t: [u32; 3]| {
        let mut c = [0.0; 3];
        for s in t {
            let p = law.samples_mm[s as usize];
            (0..3).for_each(|k| c[k] += f64::from(p[k]) / 3.0);
        }
        c
    };
    let at: Vec<[f64; 3]> = law
        .refinement
        .triangles
        .iter()
        .map(|&t| centroid(t))
        .collect();
    let plan = base
        .refine_preview(&organ, above, Some(split), None, &at)
        .expect("a plan");
    assert_eq!(plan.split, split);
    for p in &plan.at {
        assert!(p.split && p.rank.is_some_and(|r| r <= split), "{p:?}");
    }

    // Its sub-triangles split again are the worst of its first level's, as `tissue
    // refine --sub-triangles` picks them.
    let sub = &law.refinement.sub;
    assert!(
        !sub.is_empty(),
        "the default tissue has a second level: see scripts/make-assets.sh"
    );
    let first = law.without_sub_split();
    let plan = first
        .sub_split_plan(
            &organ,
            &first.surface_law(&organ).expect("reads back"),
            sub.sub_triangles.len(),
            None,
        )
        .expect("a plan");
    assert_eq!(plan.names(), &sub.sub_triangles[..]);

    // Its band next to the fixed region (`palpa lab tissue band`, the last stage): every
    // palpable edge from a pressed vertex to one on the fixed region, pressed at its
    // midpoint, its other end held.
    let key = |p: [f64; 3]| p.map(|c| (c as f32).to_bits());
    let pressed: std::collections::HashSet<[u32; 3]> =
        law.samples_mm.iter().map(|p| p.map(f32::to_bits)).collect();
    let edges = organ.palpable_edges();
    let at = |v: u32| organ.mesh.vertices[v as usize];
    let band: Vec<([u32; 3], [u32; 3])> = edges
        .iter()
        .filter_map(|&[a, b]| {
            let (fa, fb) = (organ.fixed[a as usize], organ.fixed[b as usize]);
            match (fa, fb) {
                (false, true) if pressed.contains(&key(at(a))) => Some((key(at(a)), key(at(b)))),
                (true, false) if pressed.contains(&key(at(b))) => Some((key(at(b)), key(at(a)))),
                _ => None,
            }
        })
        .collect();
    assert_eq!(
        law.refinement.band.len(),
        band.len(),
        "the default tissue's band is every band edge: see scripts/make-assets.sh"
    );
    for b in &law.refinement.band {
        let end = law.samples_mm[b.end as usize].map(f32::to_bits);
        let other = b.other_mm.map(f32::to_bits);
        assert!(band.contains(&(end, other)), "{b:?}");
    }

    // The vertex press nearest the anterior lobe's centre, pressed again alone.
    let centre = [-30.3f32, 70.7, 16.9];
    let dist = |p: &[f32; 3]| (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum::<f32>();
    let k = (0..law.samples_mm.len())
        .min_by(|&a, &b| dist(&law.samples_mm[a]).total_cmp(&dist(&law.samples_mm[b])))
        .expect("samples");
    let at = law.samples_mm[k].map(f64::from);
    let again = SurfaceLaw::build(
        &organ,
        SurfaceLawOptions {
            within: Some((at, 0.01)),
            edges: false,
            ..o
        },
        None,
        &|_| {},
    )
    .expect("presses");
    assert_eq!(again.samples.len(), 1);
    let steps = law.steps as usize;
    assert_eq!(again.reach[0], law.reach[k]);
    let force = (0..steps)
        .map(|j| {
            let stored = f64::from(law.ratio[k * steps + j]);
            (stored - again.ratio[j]).abs() / again.ratio[j]
        })
        .fold(0.0f64, f64::max);
    let count = law.sample_modes(k).0.len();
    let surface = palpa_tests::stored_error(&law, k, count, |j| again.residual_at(0, j));
    eprintln!(
        "vertex {at:?} pressed again: force ratio within {force:.2e}, surface within \
         {surface:.4} mm (stored bound {:.4} mm)",
        law.truncation_bound_mm
    );
    // On another CPU the rounding may differ and a press converge elsewhere within the
    // corrector's tolerance (0.05 mm, 5e-3 of the force).
    assert!(force <= 5e-3, "{force}");
    assert!(surface <= law.truncation_bound_mm + 0.05, "{surface}");
}

/// The default scene's nodule table (`assets/liver-coarse.nodules`) is of the default
/// organ's mesh and carries its measured accuracy: held-out checks against the full FE
/// (`palpa nodule check --record`) over the band at ratios to 10 (recorded: 92 felt
/// pairs, median 2.4 %, 97 % within 10 %; elsewhere within 0.77 % of the force, the far
/// field beyond the probe reach included), past ratio 10, past radius 12 mm and past
/// the band.
#[test]
fn the_default_nodule_table_is_the_default_organs_and_records_its_accuracy() {
    use palpa_core::pgd::nodule::heldout;
    use palpa_core::pgd::nodule::table::{EffectTable, TableError};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    let table = EffectTable::load(&root.join("liver-coarse.nodules")).expect("loads");
    assert_eq!(table.mesh_xxh3, palpa_tests::coarse_liver().fingerprint());
    let scene = file::load_any(&root.join("liver-coarse.palpa")).expect("the default scene");
    let scene = palpa_core::scene::PalpationScene::new(scene).expect("scene");
    table
        .check_mesh(&scene.model().provenance().mesh)
        .expect("the default scene's mesh");
    // The band under the palpable surface: under every palpable triangle, a nodule
    // 14 mm deep (radius 8 mm) that the full FE accepts, the table answers; the probe
    // nodes the fixed region holds feel none, and no effect is other than a number.
    let organ = palpa_tests::coarse_liver();
    let v = &organ.mesh.vertices;
    let (mut accepted, mut triangles, mut at_limit) = (0, 0, 0);
    for t in organ.palpable_triangles() {
        triangles += 1;
        let [a, b, c] = t.map(|i| v[i as usize]);
        let centroid = [0, 1, 2].map(|d| (a[d] + b[d] + c[d]) / 3.0);
        let (e, f) = (
            [0, 1, 2].map(|d| b[d] - a[d]),
            [0, 1, 2].map(|d| c[d] - a[d]),
        );
        let n = [
            e[1] * f[2] - e[2] * f[1],
            e[2] * f[0] - e[0] * f[2],
            e[0] * f[1] - e[1] * f[0],
        ];
        let len = n.iter().map(|x| x * x).sum::<f64>().sqrt();
        let nodule = palpa_core::fe::nodule::Nodule {
            center_mm: [0, 1, 2].map(|d| centroid[d] - 14.0 * n[d] / len),
            radius_mm: 8.0,
            ratio: 4.0,
        };
        if nodule.check(&organ).is_err() {
            continue;
        }
        accepted += 1;
        let effect = match table.place(&nodule) {
            Ok(effect) => effect,
            // The surface's distance interpolated over the lattice: at the 2 mm limit
            // the table and the FE may judge within half a millimetre differently.
            Err(TableError::TooShallow { depth_mm }) if depth_mm > 1.5 => {
                at_limit += 1;
                continue;
            }
            Err(e) => panic!("{nodule:?}, 14 mm under {centroid:?}: {e}"),
        };
        for (e, c0) in effect.at_node.iter().zip(&table.compliance_mm_per_n) {
            assert!(
                e.is_finite() && (*c0 > 0.0 || *e == 0.0),
                "{e} at compliance {c0}"
            );
        }
    }
    eprintln!(
        "{accepted} of {triangles} palpable triangles have a nodule 14 mm under them that the FE accepts; the table refuses {at_limit} at the 2 mm limit"
    );
    assert!(accepted * 10 >= triangles * 8 && at_limit * 50 <= accepted);
    assert!(table.compliance_mm_per_n.contains(&0.0), "held probe nodes");
    // Straight under the probe on the anterior face, 33-45 mm deep: in the band, but
    // farther from the probe than any lattice node's reach (30 mm), so answered by the
    // far field read along the line to the probe (measured for a 12 mm nodule 10 times
    // stiffer: the FE 3.88, 3.14, 2.48, 2.02 %, the table within 0.56 % of the force;
    // the ring's far field alone was 2.1 % low at 33 mm, past the 2 % goal).
    let space = palpa_core::fe::probe::organ_space(&organ, Element::P2);
    let point = palpa_core::fe::load::project(&space, &organ.palpable, [-40.0, 60.0, 30.0])
        .expect("the anterior face");
    let dir = palpa_core::fe::probe::smooth_inward_dir(&organ, point.point).expect("a normal");
    let req = palpa_core::fe::probe::ProbeRequest::unit(point.point, dir);
    for depth_mm in [33.0, 36.0, 40.0, 45.0] {
        let nodule = palpa_core::fe::nodule::Nodule {
            center_mm: [0, 1, 2].map(|d| point.point[d] + depth_mm * dir[d]),
            radius_mm: 12.0,
            ratio: 10.0,
        };
        let answered = table
            .place(&nodule)
            .expect("answered")
            .at(&table, point.face, point.bary)
            .expect("a palpable face");
        let (free, with) = palpa_tests::fe_without_and_with(&organ, &req, nodule);
        let fe = free.probe_displacement_mm / with.probe_displacement_mm - 1.0;
        eprintln!(
            "{depth_mm} mm under the probe: FE {:+.2} %, table {:+.2} %",
            100.0 * fe,
            100.0 * answered
        );
        assert!((answered - fe).abs() < 0.015, "{answered} against {fe}");
    }
    // A centre in the lattice's box but outside the organ is refused by name.
    let above = palpa_core::fe::nodule::Nodule {
        center_mm: [0, 1, 2].map(|d| point.point[d] - 12.0 * dir[d]),
        radius_mm: 8.0,
        ratio: 4.0,
    };
    let e = table.place(&above).expect_err("outside the organ");
    assert!(matches!(e, TableError::OutsideOrgan { .. }), "{e}");
    let [within, beyond, past_radius, past_band] = heldout::recorded(&table);
    let s = within.expect("checks recorded: scripts/make-assets.sh with NODULES=1");
    let b = beyond.expect("a check at ratios 10-100 recorded");
    assert!(b.felt >= 10 && b.error_median < 0.1, "{b:?}");
    assert!(s.felt >= 60, "{s:?}");
    // Over the whole band (measured: 92 felt pairs, median 2.4 %, 98 % within 10 %, the
    // worst 16 % at a thin edge).
    assert!(
        s.within_10_percent >= 0.9 && s.error_max <= 0.2 && s.error_median < 0.05,
        "{s:?}"
    );
    // Where the effect is under 5 %, the probe up to 37 mm from the nodule: within 2 %
    // of the force (measured 0.77 % and 0.42 % past ratio 10; with no far field beyond
    // the 30 mm reach it was 2.5 % and 2.9 %).
    assert!(
        s.unfelt_max_abs < 0.02 && b.unfelt_max_abs < 0.02,
        "{s:?} {b:?}"
    );
    // Radii 12-15 mm, the quadratic over the radius carried past the largest tabulated
    // (measured: 24 felt pairs, effects to 98 %, median 1.6 %, 92 % within 10 %, the two
    // misses 16 and 18 %; elsewhere within 0.6 % of the force).
    let r = past_radius.expect("a check at radii past the tabulated recorded");
    assert!(r.felt >= 20 && r.error_median < 0.05, "{r:?}");
    assert!(
        r.within_10_percent >= 0.8 && r.unfelt_max_abs < 0.02,
        "{r:?}"
    );
    // Past the band, radii 8-15 mm, ratios to 10: 112 pairs, 3 felt (to 8.4 %, within
    // 6.3 %); elsewhere within 1.1 % of the force (ignored, the nodule is off by up to
    // 5 %).
    let d = past_band.expect("a check past the band recorded");
    assert!(d.pairs >= 100 && d.unfelt_max_abs < 0.02, "{d:?}");
    // The surface drawn at 1 N with the nodule (the nodule-free one at the depth
    // reached, swayed with the force away from the tool), at every pair against the
    // FE's with it: measured within 0.1 mm at 526 of 530 pairs, 0.121 mm at worst
    // (drawn without the sway: 0.305 mm at worst, 15 of the 131 felt pairs over).
    for c in [&s, &b, &r, &d] {
        assert!(
            c.surface_max_mm < 0.15 && c.surface_within_goal >= 0.9,
            "{c:?}"
        );
    }
    // What the checks recorded is what the table answers now (no FE: the recorded
    // figures describe this code), past the band and at every other pair.
    let space_points = |p: &heldout::CheckedPair| {
        palpa_core::fe::load::project(&space, &organ.palpable, p.at_mm).expect("on the surface")
    };
    for p in table.checks.iter().flat_map(|c| &c.pairs) {
        let at = space_points(p);
        let now = table
            .place(&p.nodule())
            .expect("answered")
            .at(&table, at.face, at.bary)
            .expect("a palpable face");
        assert!((now - p.effect_table).abs() < 1e-6, "{p:?}: now {now}");
    }
    // The shipped tissue with the table's effect amplified by the tissue's own press
    // (the table's power of this very tissue), checked against Newton with the nodule
    // (`palpa nodule check --tissue`). Measured (129 presses to 9.7 mm, seeds 7 and 8):
    // the force within 0.37 / 0.19 % at the median and 2.7 / 2.8 % at worst; the felt
    // effect 1.4 / 2.8 % off at the median, 6.3 / 16.8 % at worst, 100 / 87 % within
    // 10 %.
    let tissue = palpa_core::tissue::law::TissueLaw::load(&root.join("liver-coarse.tissue"))
        .expect("the default tissue");
    let power = table
        .tissue_power
        .as_ref()
        .expect("the shipped tissue's power");
    assert_eq!(
        power.tissue_xxh3,
        tissue.payload_xxh3(),
        "pressed with the shipped tissue"
    );
    assert!(
        power.vertices.len() >= 500,
        "{} vertices",
        power.vertices.len()
    );
    // Pressed through the goals' range: its deepest stored step's midpoint at 9 mm.
    assert!(
        power.depths_mm.last().is_some_and(|&d| d >= 9.0),
        "{:?}",
        power.depths_mm
    );
    assert!(
        !table.tissue_checks.is_empty()
            && table
                .tissue_checks
                .iter()
                .all(|c| c.tissue_xxh3 == tissue.payload_xxh3() && c.amplified),
        "a tissue check recorded against the shipped tissue, amplified (re-run `palpa nodule check --tissue`)"
    );
    // Checks drawn around the nodule (the probe within 20 mm of its projection) and
    // right above it (`--above`, told apart by their presses), each kind's presses
    // together. Measured with the pressed tissue's own screening (docs/lab §23):
    // around (seeds 7, 8, 21: 183 presses, 36 felt), the effect 3.2 % off at the
    // median, 24.8 % at worst, 86 % within 10 %, the force 0.29 % / 3.3 %; above
    // (seeds 20, 22: 39 presses, the nodule's top about 7 mm under the tool, 29
    // felt), 5.2 % / 18.6 %, 83 %, the force 0.69 % / 6.2 %. Bounds: the goals' 5 % on
    // the force around the nodule, the rest about three times the medians and half as
    // much again as the worst.
    let above = heldout::drawn_above(&table.tissue_checks, &organ);
    let kind = |want: bool| -> Vec<&heldout::TissueCheck> {
        let checks = table.tissue_checks.iter().zip(&above);
        checks
            .filter(|(_, a)| **a == want)
            .map(|(c, _)| c)
            .collect()
    };
    let (over, around) = (kind(true), kind(false));
    let together = |checks: &[&heldout::TissueCheck]| {
        heldout::TissueSummary::of(checks.iter().flat_map(|c| &c.pairs)).expect("presses")
    };
    assert!(
        around.len() >= 3 && over.len() >= 2,
        "around and above recorded"
    );
    assert!(
        together(&around).presses >= 150,
        "presses around the nodule"
    );
    assert!(
        together(&over).gap_median_mm < 12.0,
        "the probe right above each nodule"
    );
    // Each kind: the felt presses at least, the force's median and worst, the
    // effect's median and worst, the share within 10 %.
    for (checks, felt, force, effect, within) in [
        (&around, 30, [0.01, 0.05], [0.1, 0.37], 0.75),
        (&over, 20, [0.02, 0.1], [0.16, 0.28], 0.7),
    ] {
        let t = together(checks);
        assert!(t.felt >= felt, "{t:?}");
        assert!(
            t.force_error_median < force[0] && t.force_error_max < force[1],
            "{t:?}"
        );
        assert!(
            t.effect_error_median < effect[0] && t.effect_error_max < effect[1],
            "{t:?}"
        );
        assert!(t.effect_within_10_percent >= within, "{t:?}");
    }
}
