//! The hyperelastic vademecum (`palpa_core::tissue::law`), built on coarse P2 in a
//! small region and bound to the shipped scene: against Newton at a held-out point
//! (force and surface), and the extremes: depth 0, past the grid, the inverse, a
//! corrupt file, a law of another mesh. The region's plain build is made once and
//! shared by both tests.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use palpa_core::fe::law::Law;
use palpa_core::fe::newton::NewtonSettings;
use palpa_core::fe::probe::organ_space;
use palpa_core::fe::probe::{ProbeRequest, solve_hyperelastic};
use palpa_core::fe::series::Expander;
use palpa_core::file;
use palpa_core::organ::OrganMesh;
use palpa_core::scene::PalpationScene;
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::{
    Grouping, PointIndex, QUANT_SHARES, ShapeBits, TissueError, TissueLaw,
};
use palpa_core::tissue::presser::PressLog;
use palpa_core::tissue::surface::{
    PressCount, Pressing, SurfaceLaw, SurfaceLawBuildError, SurfaceLawOptions, organ_vertex_normals,
};
use palpa_tests::{coarse_liver, stored_error};

mod subsplit;

fn shipped_scene() -> PalpationScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.palpa");
    PalpationScene::new(file::load_any(&path).expect("the shipped scene loads")).expect("scene")
}

/// A surface point of the anterior right lobe, not a mesh vertex.
const CENTRE: [f64; 3] = [-30.3, 70.7, 16.9];

/// The region's build options: the vertices within 12 mm of [`CENTRE`], to 6 mm.
fn region_options() -> SurfaceLawOptions {
    SurfaceLawOptions {
        depth_max_mm: 6.0,
        orders: 10,
        within: Some((CENTRE, 12.0)),
        ..SurfaceLawOptions::default()
    }
}

/// The plain vademecum of the region and the log of its presses, built once for both
/// tests (they run at once; the second waits for the first's build).
struct Region {
    law: SurfaceLaw,
    log: PathBuf,
}

fn region() -> &'static Region {
    static REGION: OnceLock<Region> = OnceLock::new();
    REGION.get_or_init(|| {
        let log = Path::new(env!("CARGO_TARGET_TMPDIR")).join("tissue-region.presses.log");
        // A log left by an earlier run would be taken as this build's presses.
        let _ = std::fs::remove_file(&log);
        let none = &|_: PressCount| {};
        let (law, resumed) = SurfaceLaw::build_logged(
            &coarse_liver(),
            region_options(),
            None,
            Some(&PressLog::at(&log)),
            none,
        )
        .expect("builds");
        assert_eq!(resumed, 0);
        Region { law, log }
    })
}

#[test]
fn the_tissue_vademecum_matches_newton_at_a_held_out_point() {
    let organ = coarse_liver();
    let options = region_options();
    let law = &region().law;
    assert!(law.samples.len() >= 3, "{} samples", law.samples.len());
    // Each vertex's stored force never falls with depth, as far as its press reached
    // (the inverse bisects it): a dip within tolerance is held at the largest force.
    let steps = law.ratio.len() / law.reach.len();
    for (s, &reach) in law.reach.iter().enumerate().take(law.samples.len()) {
        let force = |j: usize| law.ratio[s * steps + j] * j as f64;
        for j in 1..reach as usize {
            assert!(
                force(j) >= force(j - 1),
                "vertex {s}: depth {j} below {}",
                j - 1
            );
        }
    }
    let tissue = TissueLaw::compress(&organ, law, 0.02, ShapeBits::Sixteen).expect("compresses");
    assert!(tissue.truncation_bound_mm <= 0.02);
    // Eight bits: fewer bytes, and a bound that still says what a node may err.
    let eight = TissueLaw::compress(&organ, law, 0.02, ShapeBits::Eight).expect("compresses");
    assert!(eight.payload_bytes() < tissue.payload_bytes());
    // A tolerance below eight bits' quantization floor: past the SVD's own modes, each
    // further mode takes what the stored ones leave, until every node is within it.
    let tight = TissueLaw::compress(&organ, law, 0.002, ShapeBits::Eight).expect("compresses");
    eprintln!(
        "8 bits to 0.002 mm: rank {}, bound {}",
        tight.rank, tight.truncation_bound_mm
    );
    assert!(
        tight.truncation_bound_mm <= 0.002,
        "{}",
        tight.truncation_bound_mm
    );
    assert!(tight.rank as usize > steps - 1, "rank {}", tight.rank);
    // The stored bound is the stored error, node by node at every grid depth, and each
    // sample keeps the fewest modes within the tolerance.
    for (t, tolerance_mm) in [(&tissue, 0.02), (&eight, 0.02), (&tight, 0.002)] {
        let mut worst = 0.0f64;
        for s in 0..t.reach.len() {
            let count = t.sample_modes(s).0.len();
            let with = |q: usize| stored_error(t, s, q, |j| law.residual_at(s, j));
            worst = worst.max(with(count));
            if count > 0 {
                assert!(
                    with(count - 1) > tolerance_mm,
                    "sample {s} keeps a mode too many"
                );
            }
        }
        assert!(
            (worst - t.truncation_bound_mm).abs() <= 1e-9 * worst.max(1e-3),
            "{worst} vs {}",
            t.truncation_bound_mm
        );
    }

    // The file comes back as saved; a flipped byte is named, not loaded.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("region.tissue");
    tissue.save(&path).expect("saves");
    let back = TissueLaw::load(&path).expect("loads");
    assert_eq!(back, tissue);
    let mut bytes = std::fs::read(&path).expect("read");
    let k = bytes.len() / 2;
    bytes[k] ^= 0x40;
    let e = TissueLaw::from_bytes(&bytes, &path).expect_err("corrupt");
    assert!(e.to_string().contains("checksum"), "{e}");

    let scene = shipped_scene();
    // A law of another mesh (its samples moved by 5 mm) does not bind.
    let mut moved = tissue.clone();
    moved.samples_mm[0][0] += 5.0;
    let e = BoundTissue::bind(
        moved,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )
    .expect_err("another mesh");
    assert!(matches!(e, TissueError::Mismatch { .. }), "{e}");
    assert!(e.to_string().contains("another mesh"), "{e}");

    let bound = BoundTissue::bind(
        back,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )
    .expect("binds to the scene of its mesh");
    let (point, _) = scene.closest_palpable(CENTRE).expect("palpable");
    let contact = scene
        .contact(&point, scene.modes(), &mut scene.contact_scratch())
        .expect("contact");
    let c = contact.compliance_mm_per_n;
    let mut scratch = bound.scratch();
    let rows = 3 * scene.vertices_mm().len();

    // Depth 0: exactly no force and no residual.
    assert_eq!(bound.force_n(&point, 0.0, c), (0.0, false));
    let mut zero = vec![0.0; rows];
    assert!(bound.add_surface(&point, 0.0, &mut scratch, &mut zero));
    assert!(zero.iter().all(|&v| v == 0.0));
    // Past the grid: held at its end and flagged.
    let end_mm = options.depth_max_mm;
    let (f_end, _) = bound.force_n(&point, end_mm, c);
    assert_eq!(bound.force_n(&point, end_mm + 3.0, c), (f_end, true));
    assert_eq!(bound.depth_mm(&point, 2.0 * f_end, c), (end_mm, true));

    // Held-out press, 5.3 mm (off the 1 mm grid), along the scene's push.
    let depth = 5.3;
    let (newton, _) = solve_hyperelastic(
        &organ,
        options.element,
        options.material,
        Law::NeoHookean,
        &ProbeRequest {
            at: CENTRE,
            force_n: f64::NAN,
            dir: Some(contact.push_dir),
            radius_mm: options.tool_radius_mm,
            nodule: None,
        },
        Some(depth),
        NewtonSettings::default(),
    )
    .expect("newton");
    let (force, beyond) = bound.force_n(&point, depth, c);
    assert!(!beyond);
    let rel = (force - newton.force_n) / newton.force_n;
    let linear_rel = (depth / c - newton.force_n) / newton.force_n;
    let (back, _) = bound.depth_mm(&point, force, c);
    assert!((back - depth).abs() < 1e-9, "inverse: {back}");

    let mut coeffs = vec![0.0; scene.modes()];
    let mut linear = vec![0.0; rows];
    scene
        .displacement(
            &point,
            contact.push_dir.map(|d| d * depth / c),
            &mut coeffs,
            &mut linear,
        )
        .expect("linear surface");
    let mut nonlinear = linear.clone();
    bound.add_surface(&point, depth, &mut scratch, &mut nonlinear);
    // The eight-bit law's surface differs from the sixteen-bit one's by at most both
    // bounds times the blend's total weight (corners 1, edges at most 4/3).
    let bound8 = BoundTissue::bind(
        eight,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )
    .expect("binds");
    let mut nonlinear8 = linear.clone();
    bound8.add_surface(&point, depth, &mut bound8.scratch(), &mut nonlinear8);
    let apart = nonlinear
        .chunks(3)
        .zip(nonlinear8.chunks(3))
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0f64, f64::max);
    let allowed =
        (bound.law.truncation_bound_mm + bound8.law.truncation_bound_mm) * (1.0 + 4.0 / 3.0);
    eprintln!("eight bits: {apart:.4} mm from sixteen (allowed {allowed:.4} mm)");
    // They may agree exactly: where a mode's step is set by its share of the tolerance
    // (`QUANT_SHARES`) rather than by the bits, both round it alike. The smaller
    // payload above shows the two laws differ.
    assert!(apart <= allowed, "{apart} vs {allowed}");
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let (mut e_tissue, mut e_linear) = (0.0f64, 0.0f64);
    for v in organ.surface_nodes() {
        let r = vertex_of
            .find(organ.mesh.vertices[v as usize])
            .expect("every organ surface vertex is a scene vertex") as usize;
        let err = |rows: &[f64]| {
            (0..3)
                .map(|k| (rows[3 * r + k] - newton.u[3 * v as usize + k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        e_tissue = e_tissue.max(err(&nonlinear));
        e_linear = e_linear.max(err(&linear));
    }
    eprintln!(
        "{depth} mm: force {force:.4} N vs Newton {:.4} N ({rel:.1e}, linear {linear_rel:.1e}); \
         surface max error {e_tissue:.3} mm (linear {e_linear:.3} mm)",
        newton.force_n
    );
    assert!(rel.abs() < 0.03, "force {rel}");
    assert!(rel.abs() < linear_rel.abs(), "no better than linear");
    assert!(
        e_tissue < 0.3 && e_tissue < 0.5 * e_linear,
        "{e_tissue} {e_linear}"
    );
}

/// The split triangles (docs/methods.md §2e) through the whole chain: plan, surplus,
/// compression, binding and blend. Split everywhere in a small region, the vademecum
/// gives back at an inner point and at a quarter point the press computed there alone,
/// where the plain quadratic blend of the same presses does not. The split presses are
/// appended to the log of a plain build, and a third run takes them all from it.
#[test]
fn a_split_triangle_gives_back_its_inner_and_quarter_presses() {
    let organ = coarse_liver();
    let options = region_options();
    // The split presses are appended to a copy of the plain build's log.
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("split.presses.log");
    let none = &|_: PressCount| {};
    let plain = &region().law;
    std::fs::copy(&region().log, &log).expect("the plain build's log copies");
    // The progress tells the presses taken from the log from those computed (what an
    // estimate of the time left divides by), while the split phase grows the total.
    let counts = std::sync::Mutex::new(Vec::new());
    let record = |c: PressCount| counts.lock().expect("one test thread").push(c);
    let (split, resumed) = SurfaceLaw::build_logged(
        &organ,
        options,
        Some(0.0),
        Some(&PressLog::at(&log)),
        &record,
    )
    .expect("splits");
    let first = plain.samples.len() + plain.edges.len();
    assert!(
        resumed >= first,
        "the plain presses come from the log: {resumed}"
    );
    let counts = counts.into_inner().expect("recorded");
    let last = counts
        .iter()
        .max_by_key(|c| c.done)
        .expect("progress reported");
    assert_eq!(last.from_log, resumed, "{last:?}");
    assert_eq!(last.done, last.total, "{last:?}");
    assert!(
        last.done > last.from_log,
        "the split presses are computed: {last:?}"
    );
    assert!(
        counts
            .iter()
            .all(|c| c.from_log <= c.done && c.done <= c.total),
        "{counts:?}"
    );
    let r = &split.refinement;
    assert!(!r.triangles.is_empty(), "no triangle split");
    assert_eq!(r.inner_corners.len(), 3 * r.triangles.len());
    assert!(
        split.refine_skip_reasons.is_empty(),
        "{:?}",
        split.refine_skip_reasons
    );
    let total = first + r.quarter_ends.len() + r.inner_corners.len();
    let (again, resumed) =
        SurfaceLaw::build_logged(&organ, options, Some(0.0), Some(&PressLog::at(&log)), none)
            .expect("again");
    assert!(resumed >= total, "{resumed} of {total} from the log");
    for s in 0..total {
        for j in 0..split.steps() {
            assert_eq!(again.residual_at(s, j), split.residual_at(s, j));
            if s < first {
                assert_eq!(plain.residual_at(s, j), split.residual_at(s, j));
            }
        }
    }

    refined_in_place(&organ, plain, &split, &log);

    let compress = |law: &SurfaceLaw| {
        let t = TissueLaw::compress(&organ, law, 0.002, ShapeBits::Sixteen).expect("compresses");
        let scene = shipped_scene();
        BoundTissue::bind(
            t,
            scene.vertices_mm(),
            scene.axis_vertices_mm(),
            scene.axis_triangles(),
        )
        .expect("binds")
    };
    let (bound_split, bound_plain) = (compress(&split), compress(plain));
    blend_surplus_checked(&organ, plain, &split, &bound_plain, &bound_split);
    // Each split triangle's points share one set of modes: fewer modes than each point
    // alone, and every sample's stored error, measured, within the law's bound.
    let shared = &bound_split.law;
    let alone =
        TissueLaw::compress_grouped(&organ, &split, 0.002, ShapeBits::Sixteen, Grouping::Sample)
            .expect("compresses");
    let modes = |t: &TissueLaw| t.mode_start.last().copied().unwrap_or(0);
    let groups = |t: &TissueLaw| t.mode_start.len() - 1;
    eprintln!(
        "split law: {} modes in {} groups, {} with each sample alone",
        modes(shared),
        groups(shared),
        modes(&alone)
    );
    assert_eq!(groups(shared), first + r.triangles.len());
    assert!(modes(shared) < modes(&alone));
    assert!(shared.truncation_bound_mm <= 0.002);
    for s in 0..total {
        let count = shared.sample_modes(s).0.len();
        let e = stored_error(shared, s, count, |j| split.residual_at(s, j));
        assert!(e <= shared.truncation_bound_mm + 1e-12, "sample {s}: {e}");
    }
    // At 8 bits each mode's step follows its weights (coarser where they are small):
    // a smaller file than every mode at the full 8 bits, the same bound kept.
    let file_bytes = |t: &TissueLaw, name: &str| {
        let path = dir.path().join(name);
        t.save(&path).expect("saves");
        std::fs::metadata(&path).expect("saved").len()
    };
    let (mut sizes, tolerance_mm) = (Vec::new(), 0.05);
    for shares in [&QUANT_SHARES[..], &[0.0]] {
        let t = TissueLaw::compress_with(
            &organ,
            &split,
            tolerance_mm,
            ShapeBits::Eight,
            Grouping::default(),
            shares,
        )
        .expect("compresses");
        assert!(t.truncation_bound_mm <= tolerance_mm, "{shares:?}");
        for s in 0..total {
            let count = t.sample_modes(s).0.len();
            let e = stored_error(&t, s, count, |j| split.residual_at(s, j));
            assert!(
                e <= t.truncation_bound_mm + 1e-9,
                "{shares:?}, sample {s}: {e}"
            );
        }
        sizes.push(file_bytes(&t, &format!("{}.tissue", sizes.len())));
    }
    eprintln!(
        "8-bit split law: {} bytes, {} at the full 8 bits",
        sizes[0], sizes[1]
    );
    assert!(sizes[0] < sizes[1], "{sizes:?}");

    let scene = shipped_scene();
    let space = organ_space(&organ, options.element);
    let expander = Expander::new(&space, options.law, options.material).expect("rest factor");
    let normals = organ_vertex_normals(&organ);
    let c = r.inner_corners[0];
    let depth = options.depth_max_mm;
    let point = |weights: [f64; 3]| {
        let (mut at, mut push) = ([0.0; 3], [0.0; 3]);
        for (k, w) in weights.iter().enumerate() {
            let v = split.samples[c[k] as usize] as usize;
            for d in 0..3 {
                at[d] += w * organ.mesh.vertices[v][d];
                push[d] -= w * f64::from(normals[v][d]);
            }
        }
        (at, push)
    };
    // The inner point's triangle alone (`build_covering`): every press it makes is the
    // split build's press of the same point, bit for bit, so there it answers as the
    // larger build does.
    let (inner_at, _) = point([0.5, 0.25, 0.25]);
    let (cover, _) =
        SurfaceLaw::build_covering(&organ, options, Some(0.0), &[inner_at], None, none)
            .expect("covers");
    assert_eq!(cover.samples.len(), 3, "one triangle's corners");
    assert_eq!(cover.refinement.triangles.len(), 1, "one triangle split");
    let (in_split, in_cover) = (sample_keys(&split), sample_keys(&cover));
    assert_eq!(in_cover.len(), 3 + 3 + 9);
    for (key, &s) in &in_cover {
        let t = *in_split
            .get(key)
            .unwrap_or_else(|| panic!("{key:?} not in the split build"));
        for j in 0..split.steps() {
            assert_eq!(cover.residual_at(s, j), split.residual_at(t, j), "{key:?}");
        }
    }
    let off = SurfaceLaw::build_covering(&organ, options, None, &[[0.0, 0.0, 0.0]], None, none);
    assert!(
        off.as_ref()
            .is_err_and(|e| e.to_string().contains("palpable surface")),
        "a point inside the organ is refused"
    );
    let bound_cover = compress(&cover);
    // The inner point near corner c[0], and the quarter point of edge c[0]–c[1] near c[0].
    for weights in [[0.5, 0.25, 0.25], [0.75, 0.25, 0.0]] {
        let (at, push) = point(weights);
        let pressing = Pressing {
            space: &space,
            organ: &organ,
            expander: &expander,
            o: &options,
        };
        let (press, depths) = pressing
            .follow_at(at, push, &[])
            .expect("fe")
            .expect("the press reaches the grid's end");
        assert_eq!(press.u.len(), depths.len());
        let (u, unit) = (press.u.last().expect("states"), &press.first.u[0]);
        let (point, _) = scene.closest_palpable(at).expect("palpable");
        let error =
            |bound: &BoundTissue| blend_error(&organ, &scene, bound, &point, depth, u, unit);
        let (e_split, e_plain) = (error(&bound_split), error(&bound_plain));
        // Each sample's compression errs by at most its bound; the blend's weights sum
        // to at most 3.25 here (corners 1, edges 1.25, the point's own surplus 1).
        let allowed = 3.25 * bound_split.law.truncation_bound_mm + 1e-4;
        eprintln!(
            "{weights:?} at {depth} mm: split {e_split:.4} mm (allowed {allowed:.4}), \
             plain quadratic {e_plain:.4} mm"
        );
        assert!(e_split <= allowed, "{e_split} > {allowed}");
        if weights[2] > 0.0 {
            let e_cover = error(&bound_cover);
            assert!(e_cover <= allowed, "covering build: {e_cover} > {allowed}");
        }
        assert!(
            e_plain > 2.0 * allowed,
            "the split changed nothing: {e_plain}"
        );
    }
}

/// The plain law compressed, read back and split in place (`lab tissue refine`): every
/// split press taken from the split build's log (the two share a key), the same
/// triangles and points split, each surplus within the blend's share of the file's
/// bound of the split build's, the file's own samples kept unchanged; the worst
/// triangle alone where one is asked for; a split file refused.
fn refined_in_place(organ: &OrganMesh, plain: &SurfaceLaw, split: &SurfaceLaw, log: &Path) {
    let none = &|_: PressCount| {};
    let r = &split.refinement;
    let first = plain.samples.len() + plain.edges.len();
    let total = first + r.quarter_ends.len() + r.inner_corners.len();
    let base = TissueLaw::compress(organ, plain, 0.002, ShapeBits::Sixteen).expect("compresses");
    let bound = base.truncation_bound_mm;
    let back = base.surface_law(organ).expect("reads back");
    assert_eq!(back.samples, plain.samples);
    assert_eq!(back.edges, plain.edges);
    for s in 0..first {
        for j in 0..plain.steps() {
            let gap = node_gap(back.residual_at(s, j), plain.residual_at(s, j));
            assert!(
                gap <= bound + 1e-6,
                "sample {s}, depth {j}: {gap} > {bound}"
            );
        }
    }
    let (refined, resumed, above) = back
        .refine(organ, 0.0, None, Some(&PressLog::at(log)), none)
        .expect("refines");
    assert_eq!(resumed, total - first, "every split press from the log");
    assert_eq!(above, r.triangles.len());
    assert_eq!(&refined.refinement, r);
    // A quarter point's parent blend weighs 1.75 in all, an inner point's 2.25.
    for s in first..total {
        for j in 0..split.steps() {
            let gap = node_gap(refined.residual_at(s, j), split.residual_at(s, j));
            assert!(gap <= 2.25 * bound + 1e-5, "sample {s}, depth {j}: {gap}");
        }
    }
    let file = base
        .refined(organ, &refined)
        .expect("compresses the split points");
    assert_eq!(file.refinement, *r);
    assert!(file.truncation_bound_mm >= bound && file.truncation_bound_mm <= 0.002);
    for s in 0..first {
        let (modes, start) = file.sample_modes(s);
        let (base_modes, base_start) = base.sample_modes(s);
        let weights = modes.len() * split.steps();
        assert_eq!(
            file.coeffs[start..start + weights],
            base.coeffs[base_start..base_start + weights]
        );
        assert_eq!(
            file.shape_scale[modes.clone()],
            base.shape_scale[base_modes.clone()]
        );
        let m = 3 * file.rows_mm.len();
        for (k, b) in modes.zip(base_modes) {
            for i in 0..m {
                assert_eq!(file.shape.get(k * m + i), base.shape.get(b * m + i));
            }
        }
    }
    for s in first..total {
        let count = file.sample_modes(s).0.len();
        let e = stored_error(&file, s, count, |j| refined.residual_at(s, j));
        assert!(e <= file.truncation_bound_mm + 1e-12, "sample {s}: {e}");
    }
    subsplit::sub_split_in_place(organ, plain.options, &file, log);
    // The worst triangle alone (by its largest edge surplus as stored: within the
    // bound of the computed one, and two triangles share their worst edge); none at
    // all gives the file back.
    let edge_surplus = |tri: [u32; 3]| {
        let t = r.triangles.iter().position(|&c| c == tri).expect("split");
        split.split_figures[t].0
    };
    let worst = r
        .triangles
        .iter()
        .map(|&t| edge_surplus(t))
        .fold(0.0, f64::max);
    let partial = |most| {
        let law = base.surface_law(organ).expect("reads back");
        law.refine(organ, 0.0, Some(most), Some(&PressLog::at(log)), none)
            .expect("refines")
    };
    let (one, _, above) = partial(1);
    assert_eq!(above, r.triangles.len());
    assert_eq!(one.refinement.triangles.len(), 1);
    let chosen = edge_surplus(one.refinement.triangles[0]);
    assert!(chosen >= worst - 2.0 * bound, "{chosen} of {worst}");
    refine_previewed(organ, &base, &one, r, log);
    let (zero, _, _) = partial(0);
    let same = base.refined(organ, &zero).expect("compresses");
    assert!(same.refinement.triangles.is_empty());
    assert_eq!(
        (&same.shape, &same.coeffs, &same.shape_scale, &same.ratio),
        (&base.shape, &base.coeffs, &base.shape_scale, &base.ratio)
    );
    assert_eq!(same.truncation_bound_mm, bound);
    refined_onward(organ, &base, &one, &refined, log);
}

/// A file split in two stages (the worst triangle, then all) splits what one stage
/// of all does, pressing only the second stage's points: the first stage's samples
/// kept as that file stores them (bit for bit), the new ones' surpluses the same as
/// the one-stage refinement's, the first stage's within its file's bound.
fn refined_onward(
    organ: &OrganMesh,
    base: &TissueLaw,
    one: &SurfaceLaw,
    all: &SurfaceLaw,
    log: &Path,
) {
    let none = &|_: PressCount| {};
    let first_stage = base
        .refined(organ, one)
        .expect("compresses the first stage");
    let back = first_stage
        .surface_law(organ)
        .expect("a split file reads back");
    assert_eq!(back.refinement.triangles, one.refinement.triangles);
    let r = &all.refinement;
    let (onward, resumed, _) = back
        .clone()
        .refine(organ, 0.0, None, Some(&PressLog::at(log)), none)
        .expect("goes on");
    let points =
        |r: &palpa_core::tissue::surface::Refinement| r.quarter_ends.len() + r.inner_corners.len();
    assert_eq!(
        resumed,
        points(r) - points(&one.refinement),
        "only the new points pressed (here from the log)"
    );
    let o = &onward.refinement;
    assert_eq!(o.triangles[0], one.refinement.triangles[0], "kept first");
    let sorted = |t: &[[u32; 3]]| {
        let mut t = t.to_vec();
        t.sort_unstable();
        t
    };
    assert_eq!(sorted(&o.triangles), sorted(&r.triangles));
    let file = first_stage
        .refined(organ, &onward)
        .expect("compresses onward");
    let read = file.surface_law(organ).expect("reads back");
    let (keys_all, keys_on, keys_one) = (sample_keys(all), sample_keys(&onward), sample_keys(one));
    assert_eq!(keys_all.len(), keys_on.len());
    let bound = first_stage.truncation_bound_mm;
    for (key, &s) in &keys_on {
        let direct = keys_all[key];
        for j in 0..onward.steps() {
            match keys_one.get(key) {
                // Held: as the first stage's file answers, in the new file too.
                Some(&held) => {
                    assert_eq!(read.residual_at(s, j), back.residual_at(held, j));
                    let gap = node_gap(onward.residual_at(s, j), all.residual_at(direct, j));
                    assert!(gap <= 2.25 * bound + 1e-5, "{key:?}, depth {j}: {gap}");
                }
                None => assert_eq!(
                    onward.residual_at(s, j),
                    all.residual_at(direct, j),
                    "{key:?}, depth {j}"
                ),
            }
        }
    }
    assert!(file.truncation_bound_mm <= first_stage.tolerance_mm);
    let again = back.refine(organ, 0.0, Some(1), None, none);
    assert!(
        matches!(again, Err(SurfaceLawBuildError::AlreadyRefined { .. })),
        "a stage of no more triangles is refused"
    );
}

/// The largest surface-node distance (mm) between `bound`'s blend at `probe` pressed
/// `depth` deep and a press's state there, `u − depth · unit` (`unit` its first order).
fn blend_error(
    organ: &OrganMesh,
    scene: &PalpationScene,
    bound: &BoundTissue,
    probe: &palpa_core::axis::ProbePoint,
    depth: f64,
    u: &[f64],
    unit: &[f64],
) -> f64 {
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let mut rows = vec![0.0; 3 * scene.vertices_mm().len()];
    assert!(bound.add_surface(probe, depth, &mut bound.scratch(), &mut rows));
    organ
        .surface_nodes()
        .into_iter()
        .map(|v| {
            let row = vertex_of
                .find(organ.mesh.vertices[v as usize])
                .expect("row");
            (0..3)
                .map(|d| {
                    let i = 3 * v as usize + d;
                    (rows[3 * row as usize + d] - (u[i] - depth * unit[i])).powi(2)
                })
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The largest node distance between two residual rows (3 values a node, mm).
fn node_gap(a: &[f32], b: &[f32]) -> f64 {
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(a, b)| {
            (0..3)
                .map(|k| f64::from(a[k] - b[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The finest surplus at the probe (`BoundTissue::blend_surplus_mm`), at each split
/// triangle's centroid and near each corner: with the plain law, the triangle's edge
/// surplus at each grid depth as the refinement plan reads it (within the compression
/// bound); with the split law, within that triangle's largest quarter or inner surplus;
/// none at rest.
fn blend_surplus_checked(
    organ: &OrganMesh,
    plain: &SurfaceLaw,
    split: &SurfaceLaw,
    bound_plain: &BoundTissue,
    bound_split: &BoundTissue,
) {
    let scene = shipped_scene();
    let step = plain.options.depth_step_mm;
    let r = &split.refinement;
    let bound = bound_plain.law.truncation_bound_mm + bound_split.law.truncation_bound_mm;
    for (i, tri) in r.triangles.iter().enumerate() {
        let corner = |s: u32| organ.mesh.vertices[split.samples[s as usize] as usize];
        let c = tri.map(corner);
        for w in [
            [1.0 / 3.0; 3],
            [0.7, 0.15, 0.15],
            [0.15, 0.7, 0.15],
            [0.15, 0.15, 0.7],
        ] {
            let at: [f64; 3] = std::array::from_fn(|k| (0..3).map(|v| w[v] * c[v][k]).sum());
            let (point, off) = scene.closest_palpable(at).expect("on the surface");
            assert!(off < 1e-6, "{at:?}");
            let preview = plain
                .refine_preview(organ, 0.0, None, None, &[at])
                .expect("previews");
            let by_depth = &preview.at[0].edge_surplus_by_depth_mm;
            let eta = |b: &BoundTissue, j: usize| {
                b.blend_surplus_mm(&point, j as f64 * step)
                    .expect("pressed corners and edges")
            };
            assert_eq!(eta(bound_plain, 0), 0.0);
            assert_eq!(eta(bound_split, 0), 0.0);
            for (j, &edges) in by_depth.iter().enumerate() {
                let (p, q) = (eta(bound_plain, j), eta(bound_split, j));
                assert!(
                    (p - edges).abs() <= bound + 1e-5,
                    "{at:?} at {j}: {p} vs {edges}"
                );
                assert!(
                    q <= split.split_figures[i].1 + bound + 1e-5,
                    "{at:?} at {j}: {q}"
                );
            }
        }
    }
}

/// `lab tissue refine --plan` says what the refinement did, before it: the same counts,
/// every press found in the shared log (none without it), the one-triangle stage's
/// triangle ranked first and the others not split by it; a point off the surface and
/// a split law refused.
fn refine_previewed(
    organ: &OrganMesh,
    base: &TissueLaw,
    one: &SurfaceLaw,
    r: &palpa_core::tissue::surface::Refinement,
    log: &Path,
) {
    let law = base.surface_law(organ).expect("reads back");
    let centroid = |tri: [u32; 3]| {
        let mut c = [0.0; 3];
        for s in tri {
            let p = organ.mesh.vertices[law.samples[s as usize] as usize];
            (0..3).for_each(|k| c[k] += p[k] / 3.0);
        }
        c
    };
    let at: Vec<[f64; 3]> = r.triangles.iter().map(|&t| centroid(t)).collect();
    let all = law
        .refine_preview(organ, 0.0, None, Some(log), &at)
        .expect("previews");
    let presses = r.quarter_ends.len() + r.inner_corners.len();
    assert_eq!(
        (all.above, all.split),
        (r.triangles.len(), r.triangles.len())
    );
    assert_eq!((all.presses, all.logged), (presses, presses));
    assert_eq!(
        all.ready, all.split,
        "every press logged: every triangle ready"
    );
    assert!(all.candidates >= all.above);
    for p in &all.at {
        let surplus = p.edge_surplus_mm.expect("a split triangle is a candidate");
        let by_depth = p.edge_surplus_by_depth_mm.iter().copied();
        assert_eq!(by_depth.fold(0.0, f64::max), surplus);
        assert_eq!(p.edge_surplus_by_depth_mm.len(), law.steps());
        assert!(p.split && p.rank.is_some_and(|k| k <= all.above), "{p:?}");
    }
    let first = law
        .refine_preview(organ, 0.0, Some(1), None, &at)
        .expect("previews");
    assert_eq!((first.split, first.logged, first.ready), (1, 0, 0));
    assert_eq!(
        first.presses,
        6 + 3,
        "six quarter points and three inner ones"
    );
    assert_eq!(first.least_split_mm, Some(first.worst_mm));
    for (p, &t) in first.at.iter().zip(&r.triangles) {
        let top = t == one.refinement.triangles[0];
        assert_eq!((p.split, p.rank == Some(1)), (top, top), "{p:?}");
    }
    let off = law.refine_preview(organ, 0.0, None, None, &[[1e4, 0.0, 0.0]]);
    assert!(
        matches!(off, Err(SurfaceLawBuildError::OffSurface { .. })),
        "{off:?}"
    );
    // On the one-triangle stage: a stage of all goes on from it, its nine points
    // held; a stage of one again is refused.
    let onward = one
        .refine_preview(organ, 0.0, None, None, &[])
        .expect("previews onward");
    assert_eq!((onward.kept, onward.split), (1, all.split));
    assert_eq!(onward.presses + 9, all.presses, "the stage's points held");
    assert_eq!(onward.ready, 1, "the held triangle is ready, the worst");
    let again = one.refine_preview(organ, 0.0, Some(1), None, &[]);
    assert!(
        matches!(
            again,
            Err(SurfaceLawBuildError::AlreadyRefined {
                triangles: 1,
                asked: 1
            })
        ),
        "{again:?}"
    );
}

/// What each stored sample of a law is, by the mesh vertices that name it (a vertex,
/// an edge's ends, a quarter point's near and far ends, an inner point's corners),
/// and its index: two builds of different extent compared press by press.
fn sample_keys(law: &SurfaceLaw) -> std::collections::HashMap<Vec<u32>, usize> {
    let v = |s: u32| law.samples[s as usize];
    let r = &law.refinement;
    law.samples
        .iter()
        .map(|&s| vec![s])
        .chain(law.edges.iter().map(|e| {
            let mut k = vec![v(e[0]), v(e[1])];
            k.sort_unstable();
            k
        }))
        .chain(
            r.quarter_ends
                .iter()
                .map(|q| vec![u32::MAX, v(q[0]), v(q[1])]),
        )
        .chain(r.inner_corners.iter().map(|c| c.map(v).to_vec()))
        .enumerate()
        .map(|(i, k)| (k, i))
        .collect()
}
