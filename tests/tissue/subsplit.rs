//! Sub-triangles split again (`palpa_core::tissue::subsplit`) through the whole chain:
//! plan, presses, surpluses over the file's blend, compression, file and blend.

use std::path::Path;

use palpa_core::fe::probe::organ_space;
use palpa_core::fe::series::Expander;
use palpa_core::organ::OrganMesh;
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::presser::PressLog;
use palpa_core::tissue::surface::{
    PressCount, Pressing, SurfaceLawBuildError, SurfaceLawOptions, organ_vertex_normals,
};

use super::{blend_error, shipped_scene};

/// `file` (split in a small region, its presses in `log`) with its worst sub-triangle
/// split again: the file's own samples kept as they are (weights, modes; cut off
/// again, the file itself), the new
/// points pressed once each and stored within the file's tolerance, the file written
/// and read back whole; at the sub-triangle's inner point the new file gives back the
/// press computed there alone, closer than the file did. A file with sub-triangles
/// split refuses a first-level stage and another second-level one.
pub(super) fn sub_split_in_place(
    organ: &OrganMesh,
    options: SurfaceLawOptions,
    file: &TissueLaw,
    log: &Path,
) {
    let none = &|_: PressCount| {};
    let mut law = file.surface_law(organ).expect("reads back");
    let plan = file.sub_split_plan(organ, &law, 1, None).expect("plans");
    assert_eq!(plan.chosen, 1);
    assert_eq!(plan.candidates.len(), 4 * file.refinement.triangles.len());
    assert!(
        plan.candidates
            .windows(2)
            .all(|w| w[0].edge_surplus_mm >= w[1].edge_surplus_mm)
    );
    // Ranked to a shallower depth, each candidate's surplus is at most its surplus
    // over every depth, and smaller somewhere (the residual grows with depth); ranked
    // to the deepest grid depth, the same ranking; at zero depth nothing is missed.
    let surplus_of = |p: &palpa_core::tissue::subsplit_file::SubSplitPlan| {
        let mut v: Vec<_> = p
            .candidates
            .iter()
            .map(|c| ((c.triangle, c.sub), c.edge_surplus_mm))
            .collect();
        v.sort_by_key(|x| x.0);
        v
    };
    let ranked = |d: f64| file.sub_split_plan(organ, &law, 1, Some(d));
    let every = surplus_of(&plan);
    let deepest = ranked(options.depth_max_mm).expect("plans");
    assert_eq!(surplus_of(&deepest), every);
    let shallow = surplus_of(&ranked(2.0).expect("plans"));
    assert!(shallow.iter().zip(&every).all(|(s, e)| s.1 <= e.1));
    assert!(shallow.iter().zip(&every).any(|(s, e)| s.1 < 0.5 * e.1));
    assert!(
        surplus_of(&ranked(0.0).expect("plans"))
            .iter()
            .all(|s| s.1 == 0.0)
    );
    for bad in [-1.0, f64::NAN] {
        let err = ranked(bad)
            .expect_err("a depth below zero is refused")
            .to_string();
        assert!(err.contains("ranking depth"), "{err}");
    }
    assert_eq!(
        plan.presses(),
        9,
        "one sub-triangle: six quarter and three inner points"
    );
    let (kept, resumed) = law
        .press_sub_split(organ, &plan, Some(&PressLog::at(log)), none)
        .expect("presses");
    assert_eq!(resumed, 0);
    assert!(kept.iter().all(Result::is_ok), "{kept:?}");
    let new = file
        .sub_split(organ, law, &plan, &kept)
        .expect("compresses");
    let sub = &new.refinement.sub;
    assert_eq!((sub.sub_triangles.len(), sub.points.len()), (1, 9));
    let old = file.reach.len();
    assert_eq!(new.reach.len(), old + 9);
    assert_eq!(new.coeffs[..file.coeffs.len()], file.coeffs[..]);
    assert_eq!(
        new.shape_scale[..file.shape_scale.len()],
        file.shape_scale[..]
    );
    assert!(new.truncation_bound_mm <= file.tolerance_mm.max(file.truncation_bound_mm));
    let first_level = new.without_sub_split();
    assert_eq!(
        (&first_level.coeffs, &first_level.shape, &first_level.group),
        (&file.coeffs, &file.shape, &file.group),
        "the file it was split from"
    );
    assert_eq!(first_level.refinement, file.refinement);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("sub.tissue");
    new.save(&path).expect("saves");
    assert_eq!(TissueLaw::load(&path).expect("loads"), new);

    // The inner point nearest the sub-triangle's first corner, pressed alone.
    let p = sub.points[6];
    let back = file.surface_law(organ).expect("reads back");
    let w = p.bary();
    let normals = organ_vertex_normals(organ);
    let (mut at, mut push) = ([0.0; 3], [0.0; 3]);
    for k in 0..3 {
        let v = back.samples[p.corners[k] as usize] as usize;
        for d in 0..3 {
            at[d] += w[k] * organ.mesh.vertices[v][d];
            push[d] -= w[k] * f64::from(normals[v][d]);
        }
    }
    assert!(w.iter().all(|&x| x > 0.0), "an inner point: {w:?}");
    let space = organ_space(organ, options.element);
    let expander = Expander::new(&space, options.law, options.material).expect("rest factor");
    let pressing = Pressing {
        space: &space,
        organ,
        expander: &expander,
        o: &options,
    };
    let (press, _) = pressing
        .follow_at(at, push, &[])
        .expect("fe")
        .expect("the press reaches the grid's end");
    let depth = options.depth_max_mm;
    let (u, unit) = (press.u.last().expect("states"), &press.first.u[0]);
    let scene = shipped_scene();
    let (probe, _) = scene.closest_palpable(at).expect("palpable");
    let bind = |law: &TissueLaw| {
        BoundTissue::bind(
            law.clone(),
            scene.vertices_mm(),
            scene.axis_vertices_mm(),
            scene.axis_triangles(),
        )
        .expect("binds")
    };
    let error = |law: &TissueLaw| blend_error(organ, &scene, &bind(law), &probe, depth, u, unit);
    let (e_new, e_file) = (error(&new), error(file));
    blend_surplus_decays(&bind(&new), &bind(file), &probe, options.depth_step_mm);
    // Every blended sample errs by at most the bound; here the weights sum to at most
    // 1 + 1.25 + 1.25 + 1 (corners, edges, first-level surpluses, the point's own).
    let allowed = 4.5 * new.truncation_bound_mm + 1e-4;
    eprintln!("sub-triangle inner point at {depth} mm: {e_new:.4} mm, before {e_file:.4} mm");
    assert!(e_new <= allowed, "{e_new} > {allowed}");
    assert!(e_new < e_file, "{e_new} vs {e_file}");

    let again = new.surface_law(organ).expect("reads back");
    assert!(matches!(
        again.clone().refine(organ, 0.0, None, None, none),
        Err(SurfaceLawBuildError::SubSplitFirst { sub_triangles: 1 })
    ));
    let refused = new
        .sub_split_plan(organ, &again, 2, None)
        .expect_err("refused");
    assert!(refused.to_string().contains("already has 1"), "{refused}");

    // A stage on the file split again is planned from the file it was split from: the
    // same sub-triangle, its presses all from the log, the same file; a stage that
    // would leave its sub-triangle out is refused.
    let (first, law, again) = new.second_level_plan(organ, 1, None).expect("plans");
    assert_eq!(again.names(), plan.names());
    let mut law = law;
    let (kept, resumed) = law
        .press_sub_split(organ, &again, Some(&PressLog::at(log)), none)
        .expect("from the log");
    assert_eq!(resumed, 9);
    let mut same = first
        .sub_split(organ, law, &again, &kept)
        .expect("compresses");
    // The same file but for the times it records.
    (same.build_s, same.compress_s) = (new.build_s, new.compress_s);
    assert!(
        same == new,
        "a stage of the same sub-triangle changed the file"
    );
    let (_, _, more) = new.second_level_plan(organ, 3, None).expect("plans");
    assert_eq!(more.names()[..1], plan.names()[..]);
    assert!(more.presses() > 9);
    let left_out = new
        .second_level_plan(organ, 0, None)
        .expect_err("leaves its sub-triangle out")
        .to_string();
    assert!(left_out.contains("1 of its 1 sub-triangles"), "{left_out}");
}

/// In a sub-triangle split again, `η` is made of its own quarter's surplus and the
/// first level's, which is the file's `η` before the split (its samples kept as they
/// are): zero at rest, and at each grid depth at most either of the two.
fn blend_surplus_decays(
    new: &BoundTissue,
    file: &BoundTissue,
    probe: &palpa_core::axis::ProbePoint,
    step_mm: f64,
) {
    let steps = new.law.steps as usize;
    for j in 0..steps {
        let d = j as f64 * step_mm;
        let (fine, above) = new.blend_surplus_levels_mm(probe, d).expect("pressed");
        let before = file.blend_surplus_mm(probe, d).expect("pressed");
        assert_eq!(above, Some(before), "the first level's surplus at {d} mm");
        let eta = new.blend_surplus_mm(probe, d).expect("pressed");
        if j == 0 {
            assert_eq!((eta, fine, before), (0.0, 0.0, 0.0), "at rest");
        }
        assert!(
            eta <= fine && eta <= before,
            "{eta} vs {fine}, {before} at {d} mm"
        );
    }
}
