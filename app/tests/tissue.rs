//! A session on a scene with a hyperelastic vademecum (`X.tissue`): the force loop
//! answers a depth with the vademecum's force, and the frame draws the linear surface
//! at that depth plus the vademecum's residual, at the same probe point and depth.

use crate::common;

use std::time::Duration;

use palpa_app::force::{NoHaptics, PressMode};
use palpa_app::offscreen::settle;
use palpa_app::scenes;
use palpa_app::session::Session;
use palpa_core::scene::PalpationScene;
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::online::Tissue;
use palpa_core::tissue::surface::{Refinement, SurfaceLawOptions};

/// A hand-made vademecum on the shipped scene: at every palpable vertex the force is
/// 0.9 of the linear one at 5 mm and 0.8 at 10 mm, and the residual moves render
/// vertex 0 along x by `d / 5` mm and nothing else.
pub(crate) fn hand_made(scene: &PalpationScene) -> TissueLaw {
    let samples = scene.axis_vertices_mm().len();
    let rows = scene.vertices_mm().len();
    let mut shape = vec![0i16; samples * 3 * rows];
    for s in 0..samples {
        shape[s * 3 * rows] = i16::MAX;
    }
    let law = TissueLaw {
        options: SurfaceLawOptions {
            depth_max_mm: 10.0,
            depth_step_mm: 5.0,
            ..SurfaceLawOptions::default()
        },
        rows_mm: scene.vertices_mm().to_vec(),
        samples_mm: scene
            .axis_vertices_mm()
            .iter()
            .map(|p| p.map(|x| x as f32))
            .collect(),
        skipped_mm: vec![],
        edge_ends: vec![],
        refinement: Refinement::default(),
        steps: 3,
        ratio: [1.0, 0.9, 0.8].repeat(samples),
        stiffness_n_per_mm: vec![1.0; samples],
        correction_mm: vec![0.0; samples],
        segments: vec![1; samples],
        reach: vec![3; samples],
        stopped: vec![String::new(); samples],
        rank: 1,
        mode_start: (0..=samples as u32).collect(),
        group: (0..samples as u32).collect(),
        coeff_start: (0..=samples as u32).map(|s| 3 * s).collect(),
        shape: palpa_core::tissue::law::Shapes::Sixteen(shape),
        shape_scale: vec![1.0 / f32::from(i16::MAX); samples],
        coeffs: [0.0, 1.0, 2.0].repeat(samples),
        truncation_bound_mm: 0.0,
        tolerance_mm: 0.05,
        build_s: 0.0,
        compress_s: 0.0,
        // The scene's own organ mesh, as a build on it would record.
        mesh_xxh3: palpa_core::pgd::palpation::describe_get(
            &scene.model().provenance().mesh,
            "mesh_xxh3",
        )
        .and_then(|h| u64::from_str_radix(h, 16).ok())
        .or(Some(0)),
        accuracy: Default::default(),
    };
    law.check().expect("a consistent hand-made law");
    law
}

fn palpa(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

fn path(p: &std::path::Path) -> String {
    p.to_str().expect("utf-8 path").to_string()
}

/// `palpa lab tissue cut INPUT FLAGS --out OUT`, which must succeed: its JSON summary.
fn tissue_cut(input: &str, flags: &[&str], out: &std::path::Path) -> serde_json::Value {
    let out = path(out);
    let args = [
        &["lab", "tissue", "cut", input][..],
        flags,
        &["--out", &out],
    ]
    .concat();
    common::json_ok(&palpa(&args))
}

/// Writes the shipped tissue's unsplit form (`lab tissue cut --unsplit`) to `out`.
fn unsplit_shipped(out: &std::path::Path) {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    tissue_cut(shipped, &["--unsplit"], out);
}

/// `palpa eval TISSUE --scene SCENE` answers at the anterior lobe, 4 mm deep.
fn eval_answers(tissue: &std::path::Path, scene: &std::path::Path) {
    let out = palpa(&[
        "eval",
        &path(tissue),
        "--scene",
        &path(scene),
        "--at",
        "-30.3,70.7,16.9",
        "--depth-mm",
        "4",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `palpa tissue check TISSUE --scene SCENE` at two held-out points (the default
/// seed), each pressed at `depths` (D1,D2,..), with `extra` arguments.
fn tissue_check(
    tissue: &std::path::Path,
    scene: &str,
    depths: &str,
    extra: &[&str],
) -> std::process::Output {
    let tissue = path(tissue);
    let mut args = vec![
        "tissue",
        "check",
        &tissue,
        "--scene",
        scene,
        "--heldout",
        "2",
        "--depths",
        depths,
    ];
    args.extend_from_slice(extra);
    palpa(&args)
}

/// `palpa offline liver` on coarse P1 with the tissue vademecum of `model` to 6 mm,
/// pressed within `within` (X,Y,Z,R), into `scene` (the tissue beside it): its JSON.
fn p1_scene_with_tissue(scene: &std::path::Path, model: &str, within: &str) -> serde_json::Value {
    common::json_ok(&palpa(&[
        "offline",
        "liver",
        "--element",
        "p1",
        "--model",
        model,
        "--depth-max-mm",
        "6",
        "--within",
        within,
        "--out",
        &path(scene),
    ]))
}

/// `palpa tissue build` on coarse P1 to `depth_mm`, pressing within the ball `within`
/// (`X,Y,Z,R`), with `extra` flags, into `out`.
fn p1_build(
    out: &std::path::Path,
    depth_mm: &str,
    within: &str,
    extra: &[&str],
) -> std::process::Output {
    let (out, within) = (path(out), format!("--within={within}"));
    let args = [
        "tissue",
        "build",
        "--element",
        "p1",
        "--depth-max-mm",
        depth_mm,
        &within,
        "--out",
        &out,
    ];
    palpa(&[&args[..], extra].concat())
}

/// [`p1_build`] of a small anterior region to 3 mm: its JSON.
fn p1_tissue(out: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    common::json_ok(&p1_build(out, "3", "-30.3,70.7,16.9,8", extra))
}

/// A session pressing 5 mm at its starting probe point, once the loop has answered.
fn pressed(tissue: Option<Tissue>) -> Session {
    let loaded = scenes::built_in().expect("built-in scene");
    let mut s = Session::with_law(loaded.scene, tissue, Box::new(NoHaptics)).expect("session");
    s.controls.pressing = true;
    s.controls.depth_mm = 5.0;
    s.force.command(s.controls.command());
    settle(&s, Duration::from_secs(2));
    assert_eq!(s.force.latest().command, s.controls.command());
    s.frame();
    s
}

#[test]
fn the_frame_draws_the_vademecum_surface_at_the_press_depth() {
    let scene = scenes::built_in().expect("built-in scene").scene;
    let law = hand_made(&scene);
    let bound = BoundTissue::bind(
        law,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )
    .expect("binds to its own scene");
    let mut nonlinear = pressed(Some(Tissue::new(bound)));
    let mut linear = pressed(None);
    let (sn, sl) = (nonlinear.sample, linear.sample);
    assert_eq!(sn.depth_mm, 5.0);
    assert!(
        (sn.magnitude_n / sl.magnitude_n - 0.9).abs() < 1e-5,
        "force {} against linear {}",
        sn.magnitude_n,
        sl.magnitude_n
    );
    assert!((sn.linear_n - sl.magnitude_n).abs() < 1e-5 * sl.magnitude_n);
    let a = nonlinear.deformed_mm().to_vec();
    let b = linear.deformed_mm().to_vec();
    for (v, (p, q)) in a.iter().zip(&b).enumerate() {
        let expected = if v == 0 { [1.0, 0.0, 0.0] } else { [0.0; 3] };
        for k in 0..3 {
            assert!(
                (p[k] - q[k] - expected[k]).abs() < 1e-4,
                "vertex {v}, axis {k}: {} against {}",
                p[k] - q[k],
                expected[k]
            );
        }
    }
}

/// `palpa eval` on a tissue file: depth in gives the vademecum's force (0.9 of the
/// linear at 5 mm), that force in gives the depth back, the surface carries the
/// residual, a press past the grid is flagged, and bad requests are named.
#[test]
fn eval_reads_a_tissue_file_both_ways() {
    let scene = scenes::built_in().expect("built-in scene").scene;
    let law = hand_made(&scene);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("hand.tissue");
    law.save(&path).expect("saves");
    let f = path.to_str().expect("utf-8 path");
    // A palpable vertex: the blend is exact there.
    let at = scene.axis_vertices_mm()[0]
        .map(|x| format!("{x}"))
        .join(",");
    let eval = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(["eval", f, "--at", &at, "--json"])
            .args(extra)
            .output()
            .expect("palpa runs");
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        let json = out
            .status
            .success()
            .then(|| serde_json::from_slice::<serde_json::Value>(&out.stdout).expect("json"));
        (json, stderr)
    };
    let (v, e) = eval(&["--depth-mm", "5"]);
    let v = v.unwrap_or_else(|| panic!("{e}"));
    assert_eq!(v["model"], "tissue");
    // A file nobody measured against the full FE claims no depth.
    assert!(v["goals_to_mm"].is_null(), "{v}");
    assert_eq!(v["probe_displacement_mm"], 5.0);
    let force = v["force_n"].as_f64().expect("force");
    let linear = v["linear_force_n"].as_f64().expect("linear force");
    assert!(
        (force / linear - 0.9).abs() < 1e-6,
        "{force} against {linear}"
    );
    // Render vertex 0 moves 1 mm along x beyond the linear surface: at least that far.
    assert!(v["max_displacement_mm"].as_f64().expect("max") > 0.0);
    assert_eq!(v["beyond_depth_max"], false);

    let (v, e) = eval(&["--force-n", &format!("{force}")]);
    let v = v.unwrap_or_else(|| panic!("{e}"));
    let back = v["probe_displacement_mm"].as_f64().expect("depth");
    assert!((back - 5.0).abs() < 1e-6, "inverse gave {back} mm");

    assert!(!e.contains("held"), "{e}");
    let (v, e) = eval(&["--depth-mm", "12"]);
    let v = v.unwrap_or_else(|| panic!("{e}"));
    assert_eq!(v["beyond_depth_max"], true);
    assert_eq!(v["requested_depth_mm"], 12.0);
    // Flagged in the report and said on stderr, with what was asked.
    assert!(
        e.contains("held at its last depth") && e.contains("(asked 12.00 mm)"),
        "{e}"
    );
    // A force no press reaches is held at the limit and answers the force there,
    // the one asked for beside it.
    let held = v["force_n"].as_f64().expect("force");
    let (v, e) = eval(&["--force-n", "1e6"]);
    let v = v.unwrap_or_else(|| panic!("{e}"));
    assert_eq!(v["beyond_depth_max"], true);
    assert_eq!(v["requested_force_n"], 1e6);
    assert!(
        e.contains("held at") && e.contains("(asked 1000000.00 N)"),
        "{e}"
    );
    let at_limit = v["force_n"].as_f64().expect("force");
    assert!(
        (at_limit - held).abs() < 1e-9 * held,
        "{at_limit} N, {held} N at 12 mm"
    );

    let (v, e) = eval(&["--depth-mm", "0"]);
    let v = v.unwrap_or_else(|| panic!("{e}"));
    assert_eq!(v["force_n"], 0.0);
    assert_eq!(v["max_displacement_mm"], 0.0);

    let (v, e) = eval(&["--depth-mm=-1"]);
    assert!(v.is_none() && e.contains("--depth-mm -1"), "{e}");
    let (v, e) = eval(&["--force-n", "NaN"]);
    assert!(v.is_none() && e.contains("--force-n NaN"), "{e}");
    let (v, e) = eval(&["--depth-mm", "5", "--dir", "0,0,1"]);
    assert!(v.is_none() && e.contains("surface normal"), "{e}");
}

/// The default scene pressed as the app presses it: the mouse's depth (depth in, force
/// out) and the gamepad trigger's force (force in, depth out) go through the shipped
/// tissue, answer as `palpa eval` does on that file at the same point, and are each
/// other's inverse; the panel's finest surplus is eval's.
#[test]
fn the_default_scene_presses_with_its_tissue_both_ways() {
    let loaded = scenes::built_in().expect("built-in scene");
    let mut s = Session::with_law(loaded.scene, loaded.law, Box::new(NoHaptics)).expect("session");
    let probe = s.controls.probe.expect("a starting probe point");
    let at = s.scene.frame(&probe).0.map(|x| format!("{x}")).join(",");
    let tissue =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.tissue");
    let eval = |flag: &str, value: f64| {
        common::json_ok(&palpa(&[
            "eval",
            &path(&tissue),
            "--at",
            &at,
            flag,
            &value.to_string(),
            "--json",
        ]))
    };
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));

    // The mouse: 6 mm deep.
    s.controls.pressing = true;
    s.controls.depth_mm = 6.0;
    s.force.command(s.controls.command());
    settle(&s, Duration::from_secs(2));
    let pressed = s.force.latest();
    assert_eq!(pressed.beyond_law, 0);
    let cli = eval("--depth-mm", 6.0);
    let force_n = num(&cli, "force_n");
    assert!(
        (f64::from(pressed.magnitude_n) - force_n).abs() <= 1e-4 * force_n,
        "the loop's {} N against eval's {force_n} N",
        pressed.magnitude_n
    );
    // Nonlinear: not the linear force at that depth.
    let linear_n = num(&cli, "linear_force_n");
    assert!((force_n - linear_n).abs() > 1e-3 * linear_n, "{cli}");

    // The trigger: that force back in gives 6 mm.
    s.controls.mode = PressMode::Force;
    s.controls.force_n = pressed.magnitude_n;
    s.force.command(s.controls.command());
    settle(&s, Duration::from_secs(2));
    let back = s.force.latest();
    assert!((back.depth_mm - 6.0).abs() < 1e-3, "{back:?}");
    let cli = eval("--force-n", force_n);
    assert!(
        (num(&cli, "probe_displacement_mm") - 6.0).abs() < 1e-3,
        "{cli}"
    );

    // The trigger past what the tissue gives here: depth and force are both held at
    // the limit, the force being the tissue's there (eval's), not the 1 kN asked.
    s.controls.force_n = 1000.0;
    s.force.command(s.controls.command());
    settle(&s, Duration::from_secs(2));
    let held = s.force.latest();
    assert_eq!(held.beyond_law, 1, "{held:?}");
    assert_eq!(held.command.target, 1000.0);
    let cli = eval("--force-n", 1000.0);
    assert_eq!(cli["beyond_depth_max"], true, "{cli}");
    let held_n = num(&cli, "force_n");
    assert!(held_n < 1000.0, "{cli}");
    assert!(
        (f64::from(held.magnitude_n) - held_n).abs() <= 1e-4 * held_n
            && (f64::from(held.depth_mm) - num(&cli, "probe_displacement_mm")).abs() < 1e-3,
        "the loop's {held:?} against eval's {cli}"
    );

    // The panel's finest surplus is eval's at the same press. It is the triangle's
    // (the probe starts on a vertex, which eval may place in a neighbour), so inside one.
    let inside = palpa_core::axis::ProbePoint {
        triangle: probe.triangle,
        bary: [0.2, 0.5, 0.3],
    };
    s.controls.probe = Some(inside);
    s.controls.mode = PressMode::Depth;
    s.force.command(s.controls.command());
    settle(&s, Duration::from_secs(2));
    s.frame();
    let surplus = s.blend_surplus_mm().expect("pressed on the vademecum");
    let at = s.scene.frame(&inside).0.map(|x| format!("{x}")).join(",");
    let cli = common::json_ok(&palpa(&[
        "eval",
        &path(&tissue),
        "--at",
        &at,
        "--depth-mm",
        "6",
        "--json",
    ]));
    assert!(
        (num(&cli, "blend_surplus_mm") - surplus).abs() <= 1e-6,
        "{cli}: the panel's {surplus} mm"
    );
}

/// The default scene opens with its hyperelastic tissue, and that tissue meets the
/// goals (surface within 0.5 mm, force within 5 % of Newton) at two held-out points
/// as deep as the scene says it does (11.5 mm, off its depth grid), and the force goal
/// as deep as it says that one holds (14.6 mm) wherever the press reaches there; a
/// session pressed deeper flags it, one pressed shallower does not, and both report
/// the finest surplus under the probe, larger for the deeper press.
#[test]
fn the_default_tissue_meets_the_goals_at_held_out_points() {
    let loaded = scenes::built_in().expect("built-in scene");
    let law = &loaded
        .law
        .as_ref()
        .expect("the default scene has its tissue")
        .bound;
    assert_eq!(law.law.options.law.name(), "neo-hookean");
    assert!(
        law.law.accuracy.points() >= 16,
        "the shipped tissue records the checks it is measured by"
    );
    // The panel counts every press (vertices, edge midpoints, split points), not the
    // vertices alone: a closed surface has three edges a vertex.
    let presses = loaded.law.as_ref().map_or(0, |t| t.samples());
    assert!(presses > 3 * law.law.samples_mm.len(), "{presses} presses");
    let goals = loaded
        .goals_to_mm
        .expect("the built-in tissue's measured depths");
    let (both_mm, force_mm) = (goals.both_mm, goals.force_mm);
    assert!(
        both_mm < force_mm && force_mm <= law.law.depth_max_mm() as f32,
        "{goals:?}"
    );
    let mut s = Session::with_law(loaded.scene, loaded.law, Box::new(NoHaptics)).expect("session");
    s.goals_to_mm = Some(goals);
    assert_eq!(s.blend_surplus_mm(), None, "lifted");
    s.controls.pressing = true;
    let mut surplus = Vec::new();
    for (depth_mm, flagged) in [(both_mm - 2.0, None), (both_mm + 1.0, Some(goals))] {
        s.controls.depth_mm = depth_mm;
        s.force.command(s.controls.command());
        settle(&s, Duration::from_secs(2));
        s.frame();
        assert_eq!(s.past_goals_mm(), flagged, "pressed {depth_mm} mm");
        surplus.push(s.blend_surplus_mm().expect("pressed on the vademecum"));
    }
    // The residual grows with the depth, and so does the finest surplus at one point.
    assert!(0.0 < surplus[0] && surplus[0] < surplus[1], "{surplus:?}");
    // The panel names the surface's depth between the two, and both past the force's.
    assert!(
        goals
            .past_text(both_mm + 1.0)
            .contains("the force within 5 % to 14.6 mm")
    );
    assert!(
        goals
            .past_text(force_mm + 0.1)
            .starts_with("deeper than 14.6 mm")
    );
    // The accuracy panel names the tissue's own measured depths apart from the linear
    // model's table; without them, that it was not measured.
    let accuracy = palpa_app::session::tissue_accuracy_text(Some(goals));
    assert!(
        accuracy.contains("to 11.5 mm deep") && accuracy.contains("force to 14.6 mm)"),
        "{accuracy}"
    );
    assert!(accuracy.starts_with("nonlinear tissue"), "{accuracy}");
    assert!(palpa_app::session::tissue_accuracy_text(None).contains("not measured"));

    let tissue =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/liver-coarse.tissue");
    let depths = format!("{both_mm},{force_mm}");
    let rows = common::json_lines_ok(&tissue_check(&tissue, "liver", &depths, &[]));
    let (summary, presses) = rows.split_last().expect("rows");
    assert_eq!(presses.len(), 4, "{summary}");
    assert_eq!(summary["surface_misses_unwarned"], 0, "{summary}");
    let mut deep_compared = 0;
    for p in presses {
        let e = |k: &str| p[k].as_f64().unwrap_or_else(|| panic!("{k}: {p}"));
        let deep = (e("depth_mm") - f64::from(force_mm)).abs() < 1e-4;
        if !deep {
            // Both goals, and better than the linear model.
            assert_eq!(p["beyond"], false, "{p}");
            assert!(e("surface_max_error_mm") <= 0.5, "{p}");
            assert!(e("force_rel_error") <= 0.05, "{p}");
            assert!(
                e("surface_max_error_mm") < e("linear_surface_max_error_mm"),
                "{p}"
            );
        } else if p["beyond"] == false {
            // The force goal wherever the press reaches (a held press is flagged).
            assert!(e("force_rel_error") <= 0.05, "{p}");
            assert!(e("force_rel_error") < e("linear_force_rel_error"), "{p}");
            deep_compared += 1;
        }
        assert!(e("blend_surplus_mm") > 0.0, "{p}");
    }
    assert!(
        deep_compared >= 1,
        "no press reached {force_mm} mm: {presses:?}"
    );
}

/// `palpa tissue check` on a built P1 vademecum (a small anterior region) against a P1
/// scene: each held-out press is compared with Newton, and `--own` follows the press at
/// the point itself, which matches Newton to the corrector's tolerance, so what is left
/// is the blend between vertices; the vademecum beats the linear model there. Bound to
/// the P2 scene instead, the P1 law is refused by name. `palpa export-scene` takes the
/// tissue along (and opens the export with it); a tissue that does not fit the
/// exported scene is named and not left beside it.
#[test]
fn tissue_check_separates_the_blend_from_the_press() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("p1.palpa");
    let tissue = dir.path().join("p1.tissue");
    // The scene and its tissue in one command (the vademecum beside the scene).
    let built = p1_scene_with_tissue(&scene, "neo-hookean", "-30.3,70.7,16.9,15");
    assert_eq!(built["tissue"]["out"], path(&tissue).as_str());
    // The vertices and the edges between them (the quadratic blend's midpoints).
    let count = |k: &str| built["tissue"][k].as_u64().unwrap_or_else(|| panic!("{k}"));
    assert!(count("samples") >= 8 && count("edges") >= count("samples"));

    let check = |scene: &str| tissue_check(&tissue, scene, "3.3,5.6", &["--own"]);
    let out = check(&path(&scene));
    let rows = common::json_lines_ok(&out);
    let (summary, presses) = rows.split_last().expect("rows");
    assert_eq!(summary["presses_compared"], 4);
    assert_eq!(presses.len(), 4);
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    for p in presses {
        let own = &p["own"];
        assert!(num(own, "force_rel_error") < 1e-3, "{p}");
        assert!(num(own, "surface_max_error_mm") < 0.01, "{p}");
        // The triangle inequality: the total error is the blend's within the press's own.
        let total = num(p, "surface_max_error_mm");
        let blend = num(own, "blend_surface_max_mm");
        assert!(
            (total - blend).abs() <= num(own, "surface_max_error_mm") + 1e-9,
            "{p}"
        );
        assert!(total < num(p, "linear_surface_max_error_mm"), "{p}");
        // The worst node is the one the total names, its push part within it, and the
        // shells around the probe hold it.
        let worst = &p["worst_node"];
        assert!((num(worst, "error_mm") - total).abs() <= 1e-12, "{p}");
        assert!(num(worst, "along_push_mm").abs() <= total + 1e-12, "{p}");
        assert!(num(worst, "from_probe_mm") >= 0.0, "{p}");
        let shells = worst["max_error_mm_by_tool_radii"]
            .as_object()
            .expect("shells");
        assert_eq!(shells.len(), 5);
        let top = shells
            .values()
            .filter_map(|v| v.as_f64())
            .fold(0.0, f64::max);
        assert!((top - total).abs() <= 1e-12, "{p}");
        assert!(
            num(p, "force_rel_error") < num(p, "linear_force_rel_error"),
            "{p}"
        );
    }

    // The tradeoff at the same held-out presses (same seed, points, depths): its row
    // that keeps every mode and depth is the check's answer, fewer modes or a longer
    // step weigh less, and the linear model errs more.
    let table = common::json_ok(&palpa(&[
        "tradeoff",
        &path(&tissue),
        "--scene",
        &path(&scene),
        "--held-out",
        "2",
        "--depths",
        "3.3,5.6",
        "--json",
    ]));
    let table_rows = table["rows"].as_array().expect("rows");
    let rank = table_rows
        .iter()
        .filter_map(|r| r["modes_max"].as_u64())
        .max()
        .expect("a mode count");
    // Built with the default eight bits, the table offers no sixteen (nothing to
    // gain from requantizing up); eight against sixteen is tested on a law built
    // with sixteen (`tests/tissue.rs`, `tissue::knobs`).
    assert!(table_rows.iter().all(|r| r["bits"] == 8), "{table}");
    let row = |modes: u64, step: f64| {
        table_rows
            .iter()
            .find(|r| r["modes_max"] == modes && r["depth_step_mm"] == step)
            .unwrap_or_else(|| panic!("no row {modes} modes, {step} mm: {table}"))
    };
    let full = row(rank, 1.0);
    for (k, check_key) in [
        ("worst_force_rel_error", "worst_force_rel_error"),
        ("worst_surface_max_error_mm", "worst_surface_max_error_mm"),
    ] {
        assert!(
            (num(full, k) - num(summary, check_key)).abs() < 1e-12,
            "{full} {summary}"
        );
    }
    assert_eq!(full["presses_compared"], 4, "{full}");
    for by_depth in full["by_depth"].as_array().expect("by depth") {
        assert_eq!(by_depth["presses_compared"], 2, "{by_depth}");
    }
    assert!(num(full, "force_eval_us") > 0.0 && num(full, "surface_eval_us") > 0.0);
    // The inverse (force in, depth out) gives each answered force's depth back.
    assert!(num(full, "inverse_eval_us") > 0.0, "{full}");
    assert!(num(full, "inverse_worst_mm") < 1e-6, "{full}");
    let linear = &table["linear"];
    assert!(num(linear, "worst_surface_max_error_mm") > num(full, "worst_surface_max_error_mm"));
    assert!(num(linear, "worst_force_rel_error") > num(full, "worst_force_rel_error"));
    if rank > 1 {
        assert!(num(row(1, 1.0), "payload_bytes") < num(full, "payload_bytes"));
        assert!(num(row(1, 1.0), "dropped_sigma_mm") > 0.0);
    }
    // Six 1 mm intervals: steps of 2 and 3 mm too, lighter.
    assert!(num(row(rank, 3.0), "payload_bytes") < num(row(rank, 2.0), "payload_bytes"));
    assert!(num(row(rank, 2.0), "payload_bytes") < num(full, "payload_bytes"));

    // The 2 mm step's cut answered beside the file at the same Newton solves
    // (`--against`): its worst errors are the tradeoff's 2 mm row, a press it answers as
    // the file does has the file's errors, and every other one is counted as changed
    // (off the grid, 3.3 mm is blended from 2 and 4 mm instead of 3 and 4: all of them).
    let cut = dir.path().join("two-mm.tissue");
    tissue_cut(&path(&tissue), &["--depth-stride", "2"], &cut);
    let rows = common::json_lines_ok(&tissue_check(
        &tissue,
        &path(&scene),
        "3.3,5.6",
        &["--against", &path(&cut)],
    ));
    let (both, presses) = rows.split_last().expect("rows");
    let other = &both["against"];
    assert_eq!(other["presses_compared"], 4, "{both}");
    for k in ["worst_force_rel_error", "worst_surface_max_error_mm"] {
        assert!(
            (num(other, k) - num(row(rank, 2.0), k)).abs() < 1e-12,
            "{other} {}",
            row(rank, 2.0)
        );
        assert!((num(both, k) - num(summary, k)).abs() < 1e-12, "{both}");
    }
    let mut changed = 0;
    for p in presses {
        let a = &p["against"];
        if a["changed"] == true {
            changed += 1;
        } else {
            for k in ["force_rel_error", "surface_max_error_mm"] {
                assert_eq!(num(a, k), num(p, k), "{p}");
            }
        }
    }
    assert_eq!(other["presses_changed"], changed, "{both}");
    assert!(changed >= 2, "{both}");
    // A file for another scene is refused by the flag's name.
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let out = tissue_check(&tissue, &path(&scene), "3.3", &["--against", shipped]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--against"), "{err}");
    // A file of the same mesh but another material law is refused too, naming both
    // models: its errors would measure another tissue, not another sampling.
    let svk = dir.path().join("svk.tissue");
    p1_tissue(&svk, &["--model", "svk"]);
    let out = tissue_check(&tissue, &path(&scene), "3.3", &["--against", &path(&svk)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--against")
            && err.contains("svk")
            && err.contains("neo-hookean")
            && err.contains("expected a file of the same model"),
        "{err}"
    );

    let out = check("liver");
    assert!(!out.status.success(), "a P1 law on the P2 scene is refused");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("p1") && err.contains("p2") && err.contains("--element"),
        "{err}"
    );

    // The export keeps the tissue: surface rows only, three modes.
    let exported = dir.path().join("small.palpa");
    let out = palpa(&[
        "export-scene",
        &path(&scene),
        "--surface-only",
        "--modes",
        "3",
        "--out",
        &path(&exported),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.path().join("small.tissue").exists());
    eval_answers(&dir.path().join("small.tissue"), &exported);
    // `palpa info` reads a tissue file; `palpa lab tissue cut` keeps one mode a sample and
    // every second depth, and says what that adds to the bound.
    let info = common::json_ok(&palpa(&["info", &path(&tissue), "--json"]));
    assert_eq!(info["kind"], "tissue");
    assert_eq!(info["vertices"].as_u64(), Some(count("samples")), "{info}");
    assert_eq!(info["edges"].as_u64(), Some(count("edges")), "{info}");
    let split: f64 = ["vertices", "edges", "quarter_points", "inner_points"]
        .iter()
        .map(|k| num(&info, k))
        .sum();
    assert_eq!(num(&info, "presses"), split, "{info}");
    let cut_path = dir.path().join("cut.tissue");
    let cut = tissue_cut(
        &path(&tissue),
        &["--modes", "1", "--depth-stride", "2"],
        &cut_path,
    );
    let (from, to) = (&cut["from"], &cut["out"]);
    assert_eq!(to["rank"], 1, "{cut}");
    assert!(
        num(to, "payload_bytes") < num(from, "payload_bytes"),
        "{cut}"
    );
    assert!((num(to, "depth_step_mm") - 2.0 * num(from, "depth_step_mm")).abs() < 1e-12);
    let grown = num(from, "truncation_bound_mm")
        + num(&cut, "dropped_sigma_mm")
        + num(&cut, "requantized_mm");
    assert!(
        (num(to, "truncation_bound_mm") - grown).abs() < 1e-9,
        "{cut}"
    );
    eval_answers(&cut_path, &scene);
    // A build stores its weights in halves already: rounding them moves nothing.
    let halved = tissue_cut(
        &path(&tissue),
        &["--half-weights"],
        &dir.path().join("half.tissue"),
    );
    assert_eq!(num(&halved, "weights_halved_mm"), 0.0, "{halved}");
    assert_eq!(
        num(&halved["out"], "file_bytes"),
        num(&halved["from"], "file_bytes"),
        "{halved}"
    );
    // A stride that does not divide the grid is refused by name, and writes nothing.
    let refused = dir.path().join("refused.tissue");
    let out = palpa(&[
        "lab",
        "tissue",
        "cut",
        &path(&tissue),
        "--depth-stride",
        "4",
        "--out",
        &path(&refused),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("stride dividing"), "{err}");
    assert!(!refused.exists());

    // The P1 tissue beside the shipped P2 scene: the export is refused by name.
    let p2 = dir.path().join("p2.palpa");
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa"),
        &p2,
    )
    .expect("copy the shipped scene");
    std::fs::copy(&tissue, dir.path().join("p2.tissue")).expect("copy");
    let out = palpa(&[
        "export-scene",
        &path(&p2),
        "--out",
        &path(&dir.path().join("e.palpa")),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("does not open with the tissue") && err.contains("p1"),
        "{err}"
    );
    assert!(
        !dir.path().join("e.tissue").exists(),
        "no unfit tissue is left beside it"
    );
}

/// Saint Venant–Kirchhoff loses stability in compression: its presses stop where the
/// force peaks (or no equilibrium is found), the vademecum answers each probe only to
/// the least reach of the presses it blends, and beyond that the force and the
/// surface are held there, flagged, with the press's reason, and the check counts
/// those presses apart from the compared ones.
#[test]
fn svk_presses_stop_where_the_tissue_loses_stability() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("svk.palpa");
    let tissue = dir.path().join("svk.tissue");
    let built = p1_scene_with_tissue(&scene, "svk", "-30.3,70.7,16.9,12");
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    assert!(num(&built["tissue"], "stopped_short") >= 1.0, "{built}");
    assert!(
        num(&built["tissue"], "shallowest_reach_mm") < 6.0,
        "{built}"
    );
    // `palpa info` counts the stopped presses by why they stopped, each once.
    let info = common::json_ok(&palpa(&["info", &path(&tissue), "--json"]));
    let by = &info["stopped_by"];
    let counted: f64 = ["force_peak", "no_equilibrium"]
        .iter()
        .map(|k| num(by, k))
        .sum();
    assert_eq!(counted, num(&info, "stopped_short"), "{info}");
    assert!(counted >= 1.0, "{info}");
    assert!(num(by, "no_equilibrium_budget_spent") <= num(by, "no_equilibrium"));
    // Where the follower finds no equilibrium, Newton tries once, from the last state
    // (a second try from rest was dropped: it never found one, and it cost time).
    let law = TissueLaw::load(&tissue).expect("loads");
    let tries = |why: &String| why.matches("; nor Newton from ").count();
    assert!(
        law.stopped.iter().all(|why| tries(why) <= 1),
        "{:?}",
        law.stopped
    );
    assert!(
        law.stopped
            .iter()
            .any(|why| tries(why) == 1 && !why.contains("budget")),
        "no press reached the fallback with budget left: {:?}",
        law.stopped
    );

    let at = "-30.3,70.7,16.9";
    let eval = |depth: &str| {
        common::json_ok(&palpa(&[
            "eval",
            &path(&tissue),
            "--scene",
            &path(&scene),
            "--at",
            at,
            "--depth-mm",
            depth,
            "--json",
        ]))
    };
    let deep = eval("6");
    let limit = num(&deep, "depth_limit_mm");
    assert!((1.0..6.0).contains(&limit), "{deep}");
    assert_eq!(deep["beyond_depth_max"], true, "{deep}");
    assert_eq!(
        num(&deep, "probe_displacement_mm"),
        limit,
        "held at the limit"
    );
    let why = deep["stopped"].as_str().expect("a reason");
    assert!(
        why.contains("force peaks") || why.contains("no equilibrium"),
        "{why}"
    );
    // The reason the probe is held is among those `palpa info` counted.
    let kind = match why.contains("force peaks") {
        true => "force_peak",
        false => "no_equilibrium",
    };
    assert!(num(by, kind) >= 1.0, "{why}: {info}");
    // At the limit itself: the same force, not flagged.
    let at_limit = eval(&limit.to_string());
    assert_eq!(at_limit["beyond_depth_max"], false, "{at_limit}");
    assert!((num(&at_limit, "force_n") - num(&deep, "force_n")).abs() < 1e-9);

    let out = palpa(&[
        "tissue",
        "check",
        &path(&tissue),
        "--scene",
        &path(&scene),
        "--at",
        at,
        "--depths",
        &format!("{},5.9", 0.5 * limit),
    ]);
    let rows = common::json_lines_ok(&out);
    let (summary, presses) = rows.split_last().expect("rows");
    assert_eq!(summary["presses_compared"], 1, "{summary}");
    assert_eq!(summary["presses_past_limit"], 1, "{summary}");
    // Within the reach the vademecum is the tissue (force goal, surface goal).
    assert!(num(&presses[0], "force_rel_error") < 0.05, "{}", presses[0]);
    assert!(
        num(&presses[0], "surface_max_error_mm") < 0.5,
        "{}",
        presses[0]
    );
    assert_eq!(
        num(&presses[1], "vademecum_limit_mm"),
        limit,
        "{}",
        presses[1]
    );
}

/// Near incompressibility (ν = 0.499) the scene and its tissue are built for that
/// material: the tissue binds to its own scene and meets both goals against Newton
/// at held-out presses (coarse P1, 4 mm), the built-in ν = 0.48 scene refuses it by
/// the material, the linear scene's tradeoff reads its material from the file, and
/// ν = 0.5 is refused.
#[test]
fn a_nearly_incompressible_tissue_meets_the_goals_on_its_own_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("nu.palpa");
    let tissue = dir.path().join("nu.tissue");
    let built = common::json_ok(&palpa(&[
        "offline",
        "liver",
        "--element",
        "p1",
        "--poisson",
        "0.499",
        "--model",
        "neo-hookean",
        "--depth-max-mm",
        "4",
        "--within",
        "-30.3,70.7,16.9,14",
        "--out",
        &path(&scene),
    ]));
    assert_eq!(built["tissue"]["stopped_short"], 0, "{built}");
    let check = |scene: &str| tissue_check(&tissue, scene, "1.3,3.3", &[]);
    let rows = common::json_lines_ok(&check(&path(&scene)));
    let summary = rows.last().expect("summary");
    assert_eq!(summary["presses_compared"], 4, "{summary}");
    assert_eq!(summary["goal_force_5_percent"], true, "{summary}");
    assert_eq!(summary["goal_surface_0_5_mm"], true, "{summary}");
    let out = check("liver");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("ν = 0.499"), "{err}");
    let table = common::json_ok(&palpa(&[
        "tradeoff",
        &path(&scene),
        "--held-out",
        "1",
        "--json",
    ]));
    assert!(
        !table["rows"].as_array().expect("rows").is_empty(),
        "{table}"
    );
    // ν = 0.5 itself is refused by name.
    let out = palpa(&[
        "offline",
        "liver",
        "--poisson",
        "0.5",
        "--out",
        &path(&scene),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("ν = 0.5 is incompressible"),
        "{err}"
    );
}

/// Bad build options are named before any press: a region that is not X,Y,Z,R, a
/// bound that is not a length, bits other than 8 or 16, no press threads, a depth grid
/// of no step (it once said "depth 0 mm is not finite").
/// `tissue check` and `lab tissue points` likewise refuse depths that do not press (one
/// of −1 mm once ran Newton for minutes) and no points at all.
#[test]
fn a_tissue_build_with_bad_options_says_which_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("bad.tissue");
    let out_s = path(&out);
    // Runs `args` then `bad`: refused, naming `says`, with nothing written.
    let refused = |args: &[&str], bad: &[&str], says: &str| {
        let run = palpa(&[args, bad].concat());
        assert!(!run.status.success(), "{bad:?} accepted");
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(err.contains(says), "{bad:?}: {err}");
        assert!(!out.exists(), "{bad:?} wrote a file");
        let log = dir.path().join("bad.tissue.presses.log");
        assert!(!log.exists(), "{bad:?} left a press log");
    };
    for (bad, says) in [
        (&["--within", "1,2,3"][..], "X,Y,Z,R"),
        // A ball without a vertex once ended in "the surface law is empty".
        (
            &["--within=-30,70,16,3"][..],
            "no palpable vertex lies within 3 mm of that point (the nearest is 3.2 mm away)",
        ),
        // Options that shape nothing together were once ignored.
        (
            &["--within=-30,70,16,9", "--cover=-30,70,16"][..],
            "cannot be used with",
        ),
        (
            &["--no-refine", "--refine-above-mm", "0.3"][..],
            "cannot be used with",
        ),
        (
            &["--no-edges", "--separate-modes"][..],
            "cannot be used with",
        ),
        (&["--tolerance-mm=-1"][..], "positive length"),
        (&["--bits", "12"][..], "8 or 16"),
        (&["--jobs", "0"][..], "at least one press"),
        (&["--orders", "0"][..], "0 orders: expected 1 to 30"),
        (&["--orders", "31"][..], "31 orders: expected 1 to 30"),
        // Above 1 no cell was active: the series silently linear.
        (
            &["--active-cutoff", "2"][..],
            "active-cell cutoff 2.0: expected a fraction",
        ),
        (&["--depth-max-mm", "0"][..], "invalid depth grid"),
        (&["--depth-max-mm", "inf"][..], "--depth-max-mm"),
        (
            &["--depth-step-mm", "nan"][..],
            "expected both finite and positive",
        ),
    ] {
        refused(
            &["tissue", "build", "--element", "p1", "--out", &out_s],
            bad,
            says,
        );
    }
    for (args, says) in [
        (
            &["check", "--depths=-1"][..],
            "expected finite depths above 0 mm",
        ),
        (&["check", "--depths", "2,nan"][..], "NaN mm"),
        (
            &["check", "--depths", "1e9"][..],
            "expected depths up to 30 mm, twice the vademecum's deepest (15 mm)",
        ),
        (&["check", "--heldout", "0"][..], "at least one point"),
        (&["check", "--depths", "3,3"][..], "3.0 mm given twice"),
        (
            &["check", "--depths", "1e300"][..],
            "--depths: 1e300 mm: expected depths up to 30 mm",
        ),
        (
            &["check", "--at", "0,0,0", "--heldout", "3"][..],
            "cannot be used",
        ),
        // Another level's mesh is named as such, not as "no triangle pressed".
        (
            &["check", "--level", "medium"][..],
            "does not fit this organ mesh: 14 of its 858 surface rows",
        ),
        (
            &[
                "points",
                "--level",
                "medium",
                "--split-of",
                concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue"),
            ][..],
            "does not fit this organ mesh",
        ),
        (&["points", "--heldout", "0"][..], "at least one point"),
        // Once still drawing after 30 s (24 GB of points).
        (
            &["points", "--heldout", "1000000000"][..],
            "expected at most 10000",
        ),
    ] {
        let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
        let file: &[&str] = if args[0] == "check" { &[shipped] } else { &[] };
        let command: &[&str] = if args[0] == "check" {
            &["tissue"]
        } else {
            &["lab", "tissue"]
        };
        refused(command, &[args, file].concat(), says);
    }
    // `lab tissue refine` likewise, and a file that is no tissue law is named.
    let shipped = dir.path().join("shipped.tissue");
    unsplit_shipped(&shipped);
    let shipped = path(&shipped);
    let shipped = shipped.as_str();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    for (input, bad, says) in [
        (shipped, &["--refine-above-mm=-1"][..], "at least 0"),
        (shipped, &["--jobs", "0"][..], "at least one press"),
        (
            shipped,
            &["--sub-triangles", "5", "--refine-above-mm", "0.3"][..],
            "cannot be used with",
        ),
        (scene, &[][..], "not a palpa tissue file"),
        (shipped, &["--at", "1,2,3"][..], "--plan"),
        (shipped, &["--plan", "--at", "1,2"][..], "X,Y,Z triples"),
        (
            shipped,
            &["--plan", "--at", "1e4,0,0"][..],
            "palpable triangle",
        ),
    ] {
        refused(
            &["lab", "tissue", "refine", input, "--out", &out_s],
            bad,
            says,
        );
    }
}

/// `lab tissue refine --plan` on the shipped file: what a five-triangle stage would split
/// and press, without pressing or writing anything, and where the triangle under a
/// pressed vertex ranks, with its edge surplus at every grid depth (none at rest).
#[test]
fn a_refinement_plan_presses_nothing_and_ranks_a_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("refined.tissue");
    // The shipped file's unsplit form (it may have split triangles: a refinement starts
    // from the vertices and edges alone).
    let input = tempfile::tempdir().expect("tempdir");
    let shipped = input.path().join("shipped.tissue");
    unsplit_shipped(&shipped);
    let shipped = path(&shipped);
    let plan = |extra: &[&str]| {
        let args = [&["lab", "tissue", "refine", &shipped, "--plan"][..], extra].concat();
        common::json_ok(&palpa(&args))
    };
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let all = plan(&[]);
    let stage = plan(&[
        "--triangles",
        "5",
        "--at",
        "-73.9546,59.5655,1.903",
        "--out",
        &path(&out),
    ]);
    assert_eq!(num(&stage, "split_triangles"), 5.0, "{stage}");
    assert_eq!(num(&stage, "triangles_above"), num(&all, "triangles_above"));
    assert!(
        num(&all, "split_triangles") > 100.0
            && num(&all, "candidates") >= num(&all, "triangles_above")
    );
    // Six quarter points and three inner ones a triangle, less those shared.
    let presses = num(&stage, "presses");
    assert!((15.0..=45.0).contains(&presses), "{stage}");
    assert_eq!(num(&stage, "presses_logged"), 0.0);
    assert_eq!(num(&stage, "presses_to_do"), presses);
    assert_eq!(num(&stage, "triangles_ready"), 0.0, "an empty log: {stage}");
    assert!(all["presses_logged"].is_null(), "no --out, no log: {all}");
    assert!(all["triangles_ready"].is_null(), "no --out, no log: {all}");
    assert!(num(&stage, "least_split_edge_surplus_mm") <= num(&stage, "worst_edge_surplus_mm"));
    let point = &stage["at"][0];
    let by_depth: Vec<f64> = point["edge_surplus_by_depth_mm"]
        .as_array()
        .expect("by depth")
        .iter()
        .map(|x| x.as_f64().expect("mm"))
        .collect();
    assert_eq!(by_depth[0], 0.0, "at rest: {point}");
    assert_eq!(
        by_depth.iter().copied().fold(0.0, f64::max),
        num(point, "edge_surplus_mm")
    );
    let rank = num(point, "rank");
    assert!(rank >= 1.0 && rank <= num(&all, "candidates"), "{point}");
    assert_eq!(point["split"].as_bool(), Some(rank <= 5.0), "{point}");
    assert!(!out.exists(), "a plan writes nothing");
    assert!(std::fs::read_dir(dir.path()).expect("dir").next().is_none());
}

/// `lab tissue refine --sub-triangles N --plan` on the shipped file's first level: four
/// candidates a split triangle, nine points a sub-triangle less those shared, the
/// sub-triangle under a point ranked (from 1, the worst), the chosen ones' corners
/// listed, nothing pressed or written;
/// on the file's unsplit form, refused by name.
#[test]
fn a_sub_triangle_plan_presses_nothing_and_ranks_a_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("sub.tissue");
    // The shipped file's first level (it may have sub-triangles split already).
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let law = TissueLaw::load(std::path::Path::new(shipped))
        .expect("the shipped tissue loads")
        .without_sub_split();
    let input = tempfile::tempdir().expect("tempdir");
    let first_level = input.path().join("first-level.tissue");
    law.save(&first_level).expect("saves");
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let plan = common::json_ok(&palpa(&[
        "lab",
        "tissue",
        "refine",
        &path(&first_level),
        "--plan",
        "--sub-triangles",
        "5",
        "--at",
        "-73.9546,59.5655,1.903",
        "--out",
        &path(&out),
    ]));
    assert_eq!(
        num(&plan, "candidates"),
        4.0 * law.refinement.triangles.len() as f64
    );
    assert_eq!(num(&plan, "sub_triangles"), 5.0);
    let presses = num(&plan, "presses");
    assert!((20.0..=45.0).contains(&presses), "{plan}");
    assert_eq!(num(&plan, "presses_logged"), 0.0);
    assert!(num(&plan, "least_split_edge_surplus_mm") <= num(&plan, "worst_edge_surplus_mm"));
    assert!(num(&plan, "first_left_edge_surplus_mm") <= num(&plan, "least_split_edge_surplus_mm"));
    let point = &plan["at"][0];
    let rank = num(point, "rank");
    assert!(rank >= 1.0 && rank <= num(&plan, "candidates"), "{point}");
    assert_eq!(point["split"].as_bool(), Some(rank <= 5.0), "{point}");
    let corners = plan["sub_triangles_mm"].as_array().expect("corners");
    assert_eq!(corners.len(), 5, "{plan}");
    assert!(std::fs::read_dir(dir.path()).expect("dir").next().is_none());
    let unsplit = input.path().join("unsplit.tissue");
    unsplit_shipped(&unsplit);
    let refused = palpa(&[
        "lab",
        "tissue",
        "refine",
        &path(&unsplit),
        "--plan",
        "--sub-triangles",
        "5",
    ]);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("no split triangles"), "{err}");

    // The shipped file itself, its sub-triangles split already: a larger stage is
    // planned from its first level, so five more give the first level's plan of that
    // many; fewer than it has are refused by name.
    let had = TissueLaw::load(std::path::Path::new(shipped))
        .expect("loads")
        .refinement
        .sub
        .sub_triangles
        .len();
    let more = (had + 5).to_string();
    let plan_of = |file: &std::path::Path, n: &str| {
        palpa(&[
            "lab",
            "tissue",
            "refine",
            &path(file),
            "--plan",
            "--sub-triangles",
            n,
        ])
    };
    let from_first = common::json_ok(&plan_of(&first_level, &more));
    let mut from_shipped = common::json_ok(&plan_of(std::path::Path::new(shipped), &more));
    from_shipped["from"] = from_first["from"].clone();
    assert_eq!(from_shipped, from_first);
    assert!(from_first["rank_to_mm"].is_null(), "every depth by default");
    let shallow = common::json_ok(&palpa(&[
        "lab",
        "tissue",
        "refine",
        &path(&first_level),
        "--plan",
        "--sub-triangles",
        &more,
        "--rank-to-mm",
        "9.3",
    ]));
    assert_eq!(shallow["rank_to_mm"].as_f64(), Some(9.3));
    assert!(num(&shallow, "worst_edge_surplus_mm") <= num(&from_first, "worst_edge_surplus_mm"));
    if had > 0 {
        let fewer = plan_of(std::path::Path::new(shipped), &(had - 1).to_string());
        assert!(!fewer.status.success());
        let err = String::from_utf8_lossy(&fewer.stderr);
        assert!(
            err.contains(&format!("1 of its {had} sub-triangles")),
            "{err}"
        );
    }
}

/// One press at a time (`--jobs 1`, for a machine short of memory) gives the law that
/// pressing on every core gives, bit for bit: each press is computed alone.
#[test]
fn pressing_one_at_a_time_gives_the_same_law() {
    let dir = tempfile::tempdir().expect("tempdir");
    let build = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        p1_tissue(&out, extra);
        let mut law = TissueLaw::load(&out).expect("loads");
        (law.build_s, law.compress_s) = (0.0, 0.0);
        law
    };
    let one = build("one.tissue", &["--jobs", "1"]);
    assert!(
        one.samples_mm.len() >= 2,
        "{} samples",
        one.samples_mm.len()
    );
    assert_eq!(one, build("all.tissue", &[]));
}

/// The same on P2 to 15 mm, where faer factors the rest stiffness in parallel: its
/// rounding followed the pool's thread count, so one press at a time and two at a time
/// gave laws apart by 7e-7 mm of their bound before the factorization's parallelism was
/// fixed to the machine's cores (`fe::sparse`). On a one-core machine both runs are
/// sequential and this passes trivially.
#[test]
fn a_p2_build_gives_one_law_however_many_presses_run_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let build = |name: &str, jobs: &str| {
        let out = dir.path().join(name);
        common::json_ok(&palpa(&[
            "tissue",
            "build",
            "--within=-30.3,70.7,16.9,7",
            "--no-refine",
            "--jobs",
            jobs,
            "--out",
            &path(&out),
        ]));
        let mut law = TissueLaw::load(&out).expect("loads");
        (law.build_s, law.compress_s) = (0.0, 0.0);
        law
    };
    let one = build("one.tissue", "1");
    assert!(
        one.samples_mm.len() >= 2,
        "{} samples",
        one.samples_mm.len()
    );
    assert_eq!(one, build("two.tissue", "2"));
}

/// A law built with sixteen bits and every triangle split: `tradeoff` measures it
/// requantized to eight too, with half the shapes' bytes, the same force, and a surface
/// within what the requantization reports (times the blend's total weight, at most
/// 1 + 4/3 + 4/3: corners, edges, a quarter's surpluses); and without its split
/// points, a row of fewer bytes.
#[test]
fn a_sixteen_bit_law_is_measured_at_eight_bits_too() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tissue = dir.path().join("p2.tissue");
    let built = common::json_ok(&palpa(&[
        "tissue",
        "build",
        "--depth-max-mm",
        "3",
        "--within=-30.3,70.7,16.9,9",
        "--refine-above-mm",
        "0",
        "--bits",
        "16",
        "--out",
        &path(&tissue),
    ]));
    let table = common::json_ok(&palpa(&[
        "tradeoff",
        &path(&tissue),
        "--held-out",
        "1",
        "--depths",
        "2.4",
        "--json",
    ]));
    let rows = table["rows"].as_array().expect("rows");
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let rank = rows.iter().filter_map(|r| r["modes_max"].as_u64()).max();
    let full = |bits: u64| {
        rows.iter()
            .find(|r| {
                r["modes_max"].as_u64() == rank && r["depth_step_mm"] == 1.0 && r["bits"] == bits
            })
            .unwrap_or_else(|| panic!("no full row at {bits} bits: {table}"))
    };
    let (sixteen, eight) = (full(16), full(8));
    assert!(2.0 * num(eight, "payload_bytes") < 1.2 * num(sixteen, "payload_bytes"));
    assert_eq!(
        eight["worst_force_rel_error"],
        sixteen["worst_force_rel_error"]
    );
    assert_eq!(num(sixteen, "requantized_mm"), 0.0);
    let surface = "worst_surface_max_error_mm";
    assert!(
        (num(eight, surface) - num(sixteen, surface)).abs()
            <= num(eight, "requantized_mm") * (1.0 + 8.0 / 3.0) + 1e-9,
        "{eight} {sixteen}"
    );
    let split = num(&built, "split_triangles");
    assert!(split >= 1.0, "{built}");
    assert_eq!(num(sixteen, "split_triangles"), split);
    let plain = rows
        .iter()
        .find(|r| r["split_triangles"] == 0)
        .unwrap_or_else(|| panic!("no row without the split: {table}"));
    assert!(num(plain, "payload_bytes") < num(sixteen, "payload_bytes"));
    assert!(num(plain, "presses_compared") >= 1.0, "{plain}");

    // A split file asked for no more triangles than it has (here every candidate is
    // split) is refused by `lab tissue refine`, which names the ways on, among them the way
    // back: `lab tissue cut --unsplit` drops the split points and keeps the vertex and edge
    // samples, and the plan on that file splits the same triangles again.
    let refine_plan =
        |file: &std::path::Path| palpa(&["lab", "tissue", "refine", &path(file), "--plan"]);
    let out = refine_plan(&tissue);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("split triangles") && err.contains("--unsplit"),
        "{err}"
    );
    let unsplit = dir.path().join("unsplit.tissue");
    let cut = tissue_cut(&path(&tissue), &["--unsplit"], &unsplit);
    let (from, to) = (&cut["from"], &cut["out"]);
    assert_eq!(num(from, "split_triangles"), split, "{cut}");
    for k in ["split_triangles", "quarter_points", "inner_points"] {
        assert_eq!(num(to, k), 0.0, "{k}: {cut}");
    }
    for k in ["vertices", "edges", "bits"] {
        assert_eq!(to[k], from[k], "{k}: {cut}");
    }
    assert!(num(to, "presses") < num(from, "presses"), "{cut}");
    let again = common::json_ok(&palpa(&[
        "lab",
        "tissue",
        "refine",
        &path(&unsplit),
        "--plan",
        "--refine-above-mm",
        "0",
    ]));
    assert_eq!(num(&again, "split_triangles"), split, "{again}");
}

/// The band next to the fixed region: `lab tissue points --next-to-fixed` draws inside
/// triangles with a corner on the attachment, and there `palpa eval` counts the
/// corners never pressed and warns (the measured tables leave the band out, and
/// measured alone it misses the goals); clear of it, no corner and no warning.
#[test]
fn a_press_next_to_the_fixed_region_is_flagged() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let out = palpa(&[
        "lab",
        "tissue",
        "points",
        "--next-to-fixed",
        "--heldout",
        "4",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let band = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let clear = palpa(&["lab", "tissue", "points", "--heldout", "2"]);
    let clear = String::from_utf8_lossy(&clear.stdout).trim().to_string();
    for (points, next_to_fixed) in [(band, true), (clear, false)] {
        let xyz: Vec<&str> = points.split(',').collect();
        assert_eq!(xyz.len(), if next_to_fixed { 12 } else { 6 }, "{points}");
        for p in xyz.chunks(3) {
            let at = format!("--at={}", p.join(","));
            let out = palpa(&["eval", shipped, &at, "--depth-mm", "2.6", "--json"]);
            let report = common::json_ok(&out);
            let unpressed = report["unpressed_corners"].as_u64().expect("a count");
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(unpressed > 0, next_to_fixed, "{at}: {report}");
            assert_eq!(
                err.contains("next to the fixed region"),
                next_to_fixed,
                "{at}: {err}"
            );
        }
    }
}

/// `palpa lab tissue band`, one band edge (`--within` its midpoint), on the shipped file
/// without its band (`lab tissue cut --no-band`): the edge from a pressed vertex to one on
/// the fixed region is pressed, and at its midpoint the file then answers Newton's force
/// there (it was 6.8 % off), as the shipped file, whose band holds every such edge, does;
/// away from the band nothing changes, bit for bit; a second band is refused.
#[test]
fn the_band_next_to_the_fixed_region_is_pressed_and_answers_there() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = |name: &str| dir.path().join(name).to_str().expect("utf-8").to_string();
    let (base, banded) = (path("base.tissue"), path("band.tissue"));
    let run = palpa(&["lab", "tissue", "cut", shipped, "--no-band", "--out", &base]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // The midpoint of the edge from vertex (−74.6, −47.6, −24.6) to the held
    // (−77.9, −50.9, −15.9) (docs/lab/tissue-measurements.md §11).
    let mid = "-76.2411,-49.2411,-20.2411";
    let within = format!("--within={mid},1");
    let out = palpa(&["lab", "tissue", "band", &base, &within, "--out", &banded]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("{e}: {}", String::from_utf8_lossy(&out.stderr));
    });
    assert_eq!(report["band_edges"], 1, "{report}");
    assert_eq!(report["band_kept"], 1, "{report}");
    let force = |file: &str, at: &str| {
        let at = format!("--at={at}");
        let v = common::json_ok(&palpa(&["eval", file, &at, "--depth-mm", "2.6", "--json"]));
        v["force_n"].as_f64().expect("force")
    };
    let at = format!("--at={mid}");
    let newton = common::json_ok(&palpa(&[
        "fe",
        "solve",
        "--model",
        "neo-hookean",
        &at,
        "--depth-mm",
        "2.6",
        "--json",
    ]));
    let reference = newton["force_n"].as_f64().expect("force");
    // The band press's own: within its 5e-3 force tolerance and the compression.
    let (before, after) = (force(&base, mid), force(&banded, mid));
    assert!(
        (after - reference).abs() < 0.015 * reference,
        "{after} N against Newton's {reference} N"
    );
    assert!(
        (before - reference).abs() > 0.05 * reference,
        "{before} N against {reference} N"
    );
    // The shipped band pressed the same edge the same way.
    let with_all = force(shipped, mid);
    assert!(
        (with_all - after).abs() < 1e-6 * after,
        "{with_all} N, {after} N"
    );
    // Far from the band, the same file.
    let clear = "-30,90,25";
    assert_eq!(force(&base, clear), force(&banded, clear));
    assert_eq!(force(&base, clear), force(shipped, clear));
    // A band is pressed once.
    let again = palpa(&["lab", "tissue", "band", &banded, "--out", &banded]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("already holds a band"));
}

/// A point of a palpable triangle whose corners are all held (on the fixed region, as
/// `lab tissue points --next-to-fixed` may draw) does not move: `palpa eval` says so by
/// name (it once said "too few modes", of a table that has none), and `tissue check`
/// reports the point as held and goes on (it once stopped the whole check there).
/// `lab tissue points` says how many of its draw lie in such triangles (the seed-8 band
/// draw of docs/lab/tissue-measurements.md §11: two of eight, this point one of them).
#[test]
fn a_point_on_the_fixed_region_is_named_held() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let draw = palpa(&[
        "lab",
        "tissue",
        "points",
        "--next-to-fixed",
        "--heldout",
        "8",
        "--seed",
        "8",
    ]);
    let (points, said) = (
        String::from_utf8_lossy(&draw.stdout),
        String::from_utf8_lossy(&draw.stderr),
    );
    assert!(points.contains("11.6337,-51.8696,-15.3203"), "{points}");
    assert!(
        said.contains("2 of the 8 points lie in a triangle whose three corners are held"),
        "{said}"
    );
    let held = "--at=11.6337,-51.8696,-15.3203";
    let out = palpa(&["eval", shipped, held, "--depth-mm", "2.6", "--json"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("lies on the fixed region"), "{err}");
    assert!(!err.contains("too few modes"), "{err}");
    // The linear scene names it too: no force presses it, a force shows the tissue
    // around it.
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    let out = palpa(&["eval", scene, held, "--depth-mm", "2.6", "--json"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("lies on the fixed region"),
        "{err}"
    );
    let out = palpa(&["eval", scene, held, "--force-n", "3", "--json"]);
    let v = common::json_ok(&out);
    assert_eq!(v["probe_displacement_mm"], 0.0, "{v}");
    let out = palpa(&["tissue", "check", shipped, held, "--depths", "2.6"]);
    let lines = common::json_lines_ok(&out);
    assert!(
        lines[0]["held"]
            .as_str()
            .is_some_and(|s| s.contains("fixed region")),
        "{lines:?}"
    );
    let summary = lines.last().expect("a summary");
    assert_eq!(summary["points_held"], 1, "{summary}");
    assert_eq!(summary["presses_compared"], 0, "{summary}");
}

/// The shipped tissue carries what `palpa tissue check --record` measured of it,
/// wherever its bytes lie (its own path, a copy, the scene beside it opened by path):
/// `palpa eval` and `palpa info` report the depths to which the goals hold, and eval
/// warns past them as the panel does.
#[test]
fn the_shipped_tissue_says_how_deep_it_is_measured() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let law = TissueLaw::load(std::path::Path::new(shipped)).expect("the shipped tissue");
    let goals = palpa_app::session::GoalDepths::of(&law).expect("recorded checks");
    let tenths = |mm: f32| (f64::from(mm) * 10.0).round() / 10.0;
    let dir = tempfile::tempdir().expect("tempdir");
    let copy = dir.path().join("copy.tissue");
    std::fs::copy(shipped, &copy).expect("copies");
    let past = format!("deeper than {:.1} mm", goals.both_mm);
    for file in [shipped, copy.to_str().expect("utf-8")] {
        for (depth, warned) in [(goals.both_mm - 1.0, false), (goals.both_mm + 0.5, true)] {
            let depth = format!("{depth}");
            let out = palpa(&["eval", file, "--at=60,10,0", "--depth-mm", &depth, "--json"]);
            let v = common::json_ok(&out);
            assert_eq!(v["goals_to_mm"]["both"], tenths(goals.both_mm), "{v}");
            assert_eq!(v["goals_to_mm"]["force"], tenths(goals.force_mm), "{v}");
            let said = String::from_utf8_lossy(&out.stderr);
            assert_eq!(said.contains(&past), warned, "{depth} mm: {said}");
        }
    }
    let info = common::json_ok(&palpa(&["info", shipped, "--json"]));
    assert_eq!(info["goals_to_mm"]["both"], tenths(goals.both_mm), "{info}");
    assert_eq!(info["accuracy"]["points"], law.accuracy.points(), "{info}");
    assert_eq!(info["mesh_xxh3"], "af6314ada9186eda", "{info}");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    let opened = scenes::load(scene).expect("the shipped scene by path");
    assert_eq!(opened.goals_to_mm, Some(goals));
}

/// Your own organ's tissue: built from the surface with the flags its scene was built
/// with, it binds to the scene and answers; built with other regions (here the
/// defaults: fixed where the surface faces posterior within 45°, palpable everywhere
/// else, where the kidney's scene fixes 50° and palpates the anterior 85°) it is
/// another organ, and the scene refuses it by name instead of answering for another
/// support. The app opening the scene with it beside says the same.
#[test]
fn a_tissue_of_your_own_organ_is_built_with_its_scenes_regions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let assets = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/kidney");
    let scene = dir.path().join("kidney-coarse.palpa");
    std::fs::copy(assets.join("kidney-coarse.palpa"), &scene).expect("copy the scene");
    let surface = path(&assets.join("kidney.obj"));
    let build = |out: &std::path::Path, regions: &[&str]| {
        let mut args = vec![
            "tissue",
            "build",
            "--surface",
            &surface,
            "--units",
            "cm",
            "--up",
            "y",
            "--anterior",
            "z",
        ];
        args.extend_from_slice(regions);
        let out = path(out);
        args.extend_from_slice(&[
            "--within",
            "0,20,0,3",
            "--depth-max-mm",
            "1",
            "--no-refine",
            "--no-edges",
            "--out",
            &out,
        ]);
        common::json_ok(&palpa(&args))
    };
    let scenes_own = dir.path().join("own.tissue");
    let summary = build(
        &scenes_own,
        &[
            "--fixed",
            "normal:posterior:50",
            "--palpable",
            "normal:anterior:85",
        ],
    );
    assert!(
        summary["samples"].as_u64().expect("samples") >= 1,
        "{summary}"
    );
    // It names its mesh as the scene's provenance does.
    let info = common::json_ok(&palpa(&["info", &path(&scenes_own)]));
    let scene_info = common::json_ok(&palpa(&["info", &path(&scene)]));
    let mesh = scene_info["provenance"]["mesh"]
        .as_str()
        .expect("mesh line");
    let hash = info["mesh_xxh3"].as_str().expect("mesh_xxh3");
    assert!(
        mesh.contains(&format!("mesh_xxh3={hash}")),
        "{hash} not in {mesh}"
    );
    let defaults = dir.path().join("defaults.tissue");
    build(&defaults, &[]);
    let eval = |tissue: &std::path::Path| {
        palpa(&[
            "eval",
            &path(tissue),
            "--scene",
            &path(&scene),
            "--at",
            "0,25,0",
            "--depth-mm",
            "0.8",
            "--json",
        ])
    };
    let v = common::json_ok(&eval(&scenes_own));
    assert!(v["force_n"].as_f64().expect("force") > 0.0, "{v}");
    let refused = eval(&defaults);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        stderr.contains("another organ mesh than the scene's"),
        "{stderr}"
    );
    assert!(stderr.contains("--fixed"), "{stderr}");
    // The app opening the scene finds the tissue beside it and binds it, or says why.
    let beside = dir.path().join("kidney-coarse.tissue");
    let headless = || {
        palpa(&[
            "headless",
            "--scene",
            &path(&scene),
            "--frames",
            "2",
            "--size",
            "64x64",
            "--no-ui",
            "--json",
        ])
    };
    std::fs::copy(&scenes_own, &beside).expect("copy");
    let v = common::json_ok(&headless());
    assert_eq!(v["tissue"], "neo-hookean vademecum", "{v}");
    std::fs::copy(&defaults, &beside).expect("copy");
    let out = headless();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("another organ mesh"), "{stderr}");
}

/// The recipes: the default one presses the vertices, the edge midpoints and, last, the
/// band next to the fixed region (where the ball reaches it); `--no-band` leaves the
/// band out and `quick` presses the vertices only; a recipe out of place is refused
/// before any press.
#[test]
fn a_tissue_build_runs_its_recipe_stage_by_stage() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A few vertices of coarse P1 next to the fixed region, to 4 mm.
    let build = |name: &str, extra: &[&str]| {
        p1_build(&dir.path().join(name), "4", "4.06,-39.49,-34.90,15", extra)
    };
    let full = common::json_ok(&build("default.tissue", &[]));
    assert_eq!(full["recipe"], "default");
    let stages = full["stages"].as_array().expect("stages");
    assert_eq!(stages.len(), 1, "{full}");
    assert_eq!(stages[0]["stage"], "band");
    let band = full["band_edges"].as_u64().expect("band edges");
    assert!(band > 0, "{full}");
    assert_eq!(stages[0]["band_kept"].as_u64(), Some(band), "{full}");
    assert!(full["edges"].as_u64().is_some_and(|e| e > 0), "{full}");
    // The file holds what the summary says, and no stage's log is left.
    let file = TissueLaw::load(&dir.path().join("default.tissue")).expect("loads");
    assert_eq!(file.refinement.band.len() as u64, band);
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("dir")
        .map(|e| e.expect("entry").file_name())
        .filter(|n| n.to_string_lossy().contains(".log"))
        .collect();
    assert!(left.is_empty(), "{left:?}");

    let no_band = common::json_ok(&build("no-band.tissue", &["--no-band"]));
    assert_eq!(no_band["stages"].as_array().map(Vec::len), Some(0));
    assert_eq!(no_band["band_edges"], 0);
    assert_eq!(no_band["samples"], full["samples"]);

    let quick = common::json_ok(&build("quick.tissue", &["--recipe", "quick"]));
    assert_eq!(
        (quick["edges"].as_u64(), quick["split_triangles"].as_u64()),
        (Some(0), Some(0))
    );
    assert_eq!(quick["stages"].as_array().map(Vec::len), Some(0));

    // The splits of another recipe are its own; a recipe that does not exist is named.
    for (extra, says) in [
        (
            &["--recipe", "quick", "--no-refine"][..],
            "names its own splits",
        ),
        (
            &["--recipe", "shipped", "--no-edges"][..],
            "edge midpoints pressed",
        ),
        (
            &["--recipe", "fast"][..],
            "expected one of default, shipped, quick",
        ),
    ] {
        let out = build("bad.tissue", extra);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{extra:?}: {err}"
        );
        assert!(!dir.path().join("bad.tissue").exists());
    }
}
