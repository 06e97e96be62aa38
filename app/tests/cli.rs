//! The `palpa` binary end to end: synth → info, bench output shape, clear errors.

use crate::common;

use std::process::Command;

fn palpa(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

#[test]
fn synth_then_info_describes_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = dir.path().join("s.palpa");
    let f = f.to_str().expect("utf-8 path");
    let out = palpa(&[
        "lab",
        "synth",
        "--rows",
        "30",
        "--modes",
        "4",
        "--precision",
        "f32",
        "--out",
        f,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = palpa(&["info", f, "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["rows"], 30);
    assert_eq!(v["modes"], 4);
    assert_eq!(v["precision"], "f32");
    assert_eq!(v["axes"][0]["discretization"], "surface");
}

#[test]
fn info_on_a_foreign_file_fails_with_a_clear_message() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = dir.path().join("notes.txt");
    std::fs::write(&f, "hello").expect("write");
    let out = palpa(&["info", f.to_str().expect("utf-8")]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a palpa meta-model file"), "{err}");
    assert!(err.contains("notes.txt"), "the file is named: {err}");
    assert!(
        !err.contains("note:"),
        "no kind is guessed for plain text: {err}"
    );

    // A file of another palpa kind, or a surface mesh, is named as what it is.
    let assets = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets");
    let (scene, tissue) = (
        format!("{assets}/liver-coarse.palpa"),
        format!("{assets}/liver-coarse.tissue"),
    );
    let ply = dir.path().join("organ.ply");
    std::fs::write(&ply, "ply\nformat ascii 1.0\n").expect("write");
    let ply = ply.to_str().expect("utf-8");
    let at = ["--at", "0,0,0", "--depth-mm", "1"];
    for (args, says) in [
        (vec!["tissue", "check", &scene], "is a palpa meta-model"),
        (
            vec!["cme", "eval", &tissue, "--t", "1"],
            "is a tissue vademecum",
        ),
        ([&["eval", ply][..], &at[..]].concat(), "is a surface mesh"),
        // A network in TOML has no magic bytes: named by its extension.
        (
            vec![
                "info",
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/../assets/networks/toggle.toml"
                ),
            ],
            "is a TOML file: `palpa cme solve|offline|convert` and `palpa open --scene` read",
        ),
    ] {
        let out = palpa(&args);
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// Without a display, `palpa open` on a scene that does not open says both: the app
/// would have shown the built-in liver and the reason, which nothing shows here.
#[test]
fn open_without_a_display_names_the_scene_that_did_not_open() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = dir.path().join("broken.palpa");
    std::fs::write(&f, "not a scene").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(["open", "--scene", f.to_str().expect("utf-8")])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .expect("palpa runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no display found"), "{err}");
    assert!(
        err.contains("The scene did not open either") && err.contains("broken.palpa"),
        "{err}"
    );
    assert!(!err.contains("showing the built-in"), "{err}");
}

#[test]
fn bench_eval_prints_one_json_object_per_configuration() {
    let out = palpa(&[
        "lab",
        "bench",
        "eval",
        "--rows",
        "300,600",
        "--modes",
        "7",
        "--precision",
        "f64",
        "--min-time-ms",
        "1",
        "--json",
    ]);
    let lines = common::json_lines_ok(&out);
    assert_eq!(lines.len(), 2);
    for v in &lines {
        for key in [
            "rows",
            "modes",
            "precision",
            "eval_ns",
            "bandwidth_ns",
            "ratio",
            "particularize_ns",
            "contact_ns",
        ] {
            assert!(v.get(key).is_some(), "missing {key} in {v}");
        }
        let ratio = v["ratio"].as_f64().expect("number");
        let eval = v["eval_ns"].as_f64().expect("number");
        let bw = v["bandwidth_ns"].as_f64().expect("number");
        // The ratio is what its name says (no timing is asserted).
        assert!((ratio - eval / bw).abs() <= 1e-9 * ratio.abs().max(1.0));
    }
    assert_eq!(lines[0]["rows"], 300);
    assert_eq!(lines[1]["rows"], 600);
}

/// `bench dsmts` on one case: the case's row, the suite's verdict, and the SSA timed
/// again on cleared registers and after a dense faer product on the pool's threads
/// (what `palpa_core::cpu` guards against), the ratio what its name says.
#[test]
fn bench_dsmts_times_the_ssa_after_a_dense_product() {
    let suite = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/dsmts");
    let out = palpa(&[
        "lab",
        "bench",
        "dsmts",
        "--suite",
        suite,
        "--cases",
        "00001",
        "--no-pgd",
        "--trajectories",
        "200",
        "--json",
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["cases"].as_array().map(Vec::len), Some(1), "{v}");
    assert_eq!(v["cases"][0]["case"], "00001", "{v}");
    let r = &v["ssa_after_dense_product"];
    assert_eq!(r["case"], "00001", "{v}");
    let num = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{k}: {r}"));
    let (clean, after, ratio) = (num("clean_seconds"), num("seconds"), num("ratio"));
    assert!(clean > 0.0 && after > 0.0, "{r}");
    assert!((ratio - after / clean).abs() <= 1e-9 * ratio, "{r}");
}

/// `bench fe --only ordering` factors coarse P2's rest stiffness under both orders:
/// the same matrix solved to rounding either way, nested dissection with fewer factor
/// entries (what the factorizations use), the ratios what their names say.
#[test]
fn bench_fe_ordering_compares_amd_and_nested_dissection() {
    let out = palpa(&[
        "lab",
        "bench",
        "fe",
        "--only",
        "ordering",
        "--ordering-levels",
        "coarse",
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["table"], "ordering", "{v}");
    assert_eq!(v["level"], "coarse", "{v}");
    let num =
        |k: &str, at: &serde_json::Value| at[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let (amd, nd) = (&v["amd"], &v["nested_dissection"]);
    for c in [amd, nd] {
        // Measured 2e-14 for both orders: 1e-10 leaves four orders of magnitude for
        // another machine's rounding, and far less than a wrong order would leave.
        assert!(num("double_residual", c) < 1e-10, "{v}");
    }
    let (ea, en) = (num("factor_entries", amd), num("factor_entries", nd));
    assert!(en < ea, "{v}");
    assert!(
        (num("entries_ratio", &v) - ea / en).abs() <= 1e-12 * ea / en,
        "{v}"
    );
    let (fa, fnd) = (num("double_factor_s", amd), num("double_factor_s", nd));
    assert!(
        (num("double_factor_ratio", &v) - fa / fnd).abs() <= 1e-9 * fa / fnd,
        "{v}"
    );
}

/// `bench fe --only lanes` times a real press's three element kernels both ways and
/// finds the lanes identical to the scalar arithmetic, bit for bit (it asserts no
/// time).
#[test]
fn bench_fe_lanes_agree_bit_for_bit() {
    let out = palpa(&["lab", "bench", "fe", "--only", "lanes"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect();
    let kernels: Vec<&str> = rows
        .iter()
        .map(|r| r["kernel"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(kernels, ["series_rhs", "residual", "tangent"], "{rows:?}");
    let num = |k: &str, r: &serde_json::Value| r[k].as_f64().unwrap_or_else(|| panic!("{k}: {r}"));
    for r in &rows {
        assert_eq!(r["table"], "lanes", "{r}");
        assert_eq!(r["identical"], true, "{r}");
        assert_eq!(r["largest_difference"].as_f64(), Some(0.0), "{r}");
        assert!(r["entries"].as_u64().is_some_and(|n| n > 1000), "{r}");
        let (s, l) = (num("scalar_s", r), num("lanes_s", r));
        let speedup = num("speedup", r);
        assert!((speedup - s / l).abs() <= 1e-9 * speedup, "{r}");
    }
}

/// Every benchmark refuses, before it measures anything, what would abort it or make
/// its table meaningless (some tables take an hour), naming the flag.
#[test]
fn benchmarks_refuse_bad_options_up_front() {
    let cases: [(&[&str], &str); 12] = [
        (
            &["lab", "bench", "eval", "--rows", "0", "--min-time-ms", "1"],
            "must be positive",
        ),
        // 1.6 TB of values: refused rather than an allocation failure.
        (
            &[
                "lab",
                "bench",
                "eval",
                "--rows",
                "1000000000",
                "--modes",
                "400",
            ],
            "memory available",
        ),
        (
            &["lab", "bench", "fe", "--only", "dept"],
            "--only dept: no such table",
        ),
        (
            &["lab", "bench", "fe", "--depth-mm", "nan"],
            "--depth-mm NaN",
        ),
        (
            &["lab", "bench", "fe", "--series-positions", "11"],
            "at most 10",
        ),
        (
            &["lab", "bench", "fe", "--build-positions", "11"],
            "at most 10",
        ),
        (
            &["lab", "bench", "fe", "--build-positions", "0"],
            "at least 1",
        ),
        (
            &["lab", "bench", "deform", "--modes", "0"],
            "--modes 0: expected from 1",
        ),
        (
            &["lab", "bench", "deform", "--modes", "99"],
            "--modes 99: expected from 1",
        ),
        (
            &["lab", "bench", "deform", "--depth-mm", "20"],
            "--depth-mm 20",
        ),
        (&["lab", "bench", "offline", "--modes", "0"], "--modes 0"),
        (
            &["lab", "bench", "offline", "--block", "4,0"],
            "--block [4, 0]",
        ),
    ];
    for (args, expected) in cases {
        let out = palpa(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    // A zero minimum time still measures each quantity once (no `inf`).
    let args = "lab bench eval --rows 30 --modes 4 --precision f32 --min-time-ms 0 --json";
    let out = palpa(&args.split(' ').collect::<Vec<_>>());
    assert!(out.status.success());
    let row: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON row");
    for key in ["particularize_ns", "contact_ns"] {
        assert!(
            row[key].as_f64().is_some_and(f64::is_finite),
            "{key}: {row}"
        );
    }
}

/// `palpa offline` killed with SIGKILL mid-run resumes from its journal, loses at most
/// the term in progress, never leaves a half-written output, and ends with the same
/// vademecum as an uninterrupted run.
#[test]
fn offline_resumes_after_kill_9() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().expect("tempdir");
    let full = dir.path().join("full.palpa");
    let cut = dir.path().join("cut.palpa");
    let base = [
        "offline",
        "liver",
        "--method",
        "pgd",
        "--level",
        "coarse",
        "--element",
        "p1",
        "--modes",
        "30",
        "--tol",
        "1e-9",
        // Small blocks, so the kill lands after at least one whole block.
        "--block",
        "2",
    ];
    let run = |out: &std::path::Path, extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = base.iter().map(|s| s.to_string()).collect();
        a.push("--out".into());
        a.push(out.to_str().expect("utf-8").into());
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let full_args = run(&full, &[]);
    let out = palpa(&full_args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let mut child = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(run(&cut, &[]))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    let journal = dir.path().join("cut.palpa.journal");
    let start = Instant::now();
    // Wait for a few terms in the journal (each P1 term is a few kB), then SIGKILL.
    while std::fs::metadata(&journal).map(|m| m.len()).unwrap_or(0) < 200_000 {
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("kill -9");
    let _ = child.wait();
    assert!(
        !cut.exists() || palpa_core::file::load_any(&cut).is_ok(),
        "no half-written output"
    );

    let resume_args = run(&cut, &["--resume"]);
    let out = palpa(&resume_args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(
        summary["resumed_modes"].as_u64().expect("n") > 0,
        "{summary}"
    );
    let a = palpa_core::file::load::<f64>(&full).expect("full");
    let b = palpa_core::file::load::<f64>(&cut).expect("resumed");
    assert_eq!(a.modes(), b.modes());
    let scale = a.spatial().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = a
        .spatial()
        .iter()
        .zip(b.spatial())
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    // Same terms up to round-off in the recomputed K·X and Fᵀ·X.
    assert!(
        diff <= 1e-6 * scale,
        "resumed vademecum differs: {diff:e} (scale {scale:e})"
    );
}

/// `palpa offline` in blocks, then `palpa tradeoff --plot`: the table carries the
/// optimal errors on coarse (PGD never below them), and the PNG is written.
#[test]
fn offline_in_blocks_then_tradeoff_with_plot() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("m.palpa");
    let png = dir.path().join("t.png");
    let m = model.to_str().expect("utf-8");
    let out = palpa(&[
        "offline",
        "liver",
        "--method",
        "pgd",
        "--level",
        "coarse",
        "--element",
        "p1",
        "--modes",
        "6",
        "--block",
        "3",
        "--tol",
        "1e-9",
        "--out",
        m,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = palpa(&[
        "tradeoff",
        m,
        "--held-out",
        "2",
        "--json",
        "--plot",
        png.to_str().expect("utf-8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.last().expect("row")["modes"], 6);
    for r in rows {
        let (pgd, opt) = (r["map_rel_error"].as_f64(), r["svd_rel_error"].as_f64());
        let (pgd, opt) = (pgd.expect("map error"), opt.expect("optimum"));
        assert!(pgd >= opt * (1.0 - 1e-9) && pgd < 1.25 * opt, "{r}");
        let surf = r["svd_surface_map_rel_error"]
            .as_f64()
            .expect("surface optimum");
        assert!(surf > 0.0 && surf < 1.0, "{r}");
    }
    let bytes = std::fs::read(&png).expect("png written");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

/// `palpa lab bench offline`: PGD and the brute-force route timed in one run; the brute
/// force is the optimum, and the PGD stays within 1.25× of it.
#[test]
fn bench_offline_compares_pgd_with_brute_force() {
    let out = palpa(&[
        "lab",
        "bench",
        "offline",
        "--level",
        "coarse",
        "--element",
        "p1",
        "--modes",
        "12",
        "--block",
        "1,4",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(v["brute_force"]["total_s"].as_f64().expect("time") > 0.0);
    let runs = v["pgd"].as_array().expect("pgd runs");
    assert_eq!(runs.len(), 2);
    for run in runs {
        assert!(run["brute_force_over_pgd_time"].as_f64().expect("ratio") > 0.0);
        for a in run["accuracy"].as_array().expect("rows") {
            let r = a["pgd_over_optimal"].as_f64().expect("ratio");
            assert!((1.0 - 1e-9..1.25).contains(&r), "{a}");
        }
    }
}

/// `palpa eval` on the shipped scene: JSON keys, a clamped mode request with notice,
/// and a VTU of the scene's surface.
#[test]
fn eval_on_the_default_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let vtu = dir.path().join("u.vtu");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    let out = palpa(&[
        "eval",
        scene,
        "--at=-30,90,25",
        "--force-n",
        "2",
        "--modes",
        "100000",
        "--out",
        vtu.to_str().expect("utf-8"),
        "--json",
    ]);
    let v = common::json_ok(&out);
    for key in [
        "probe_point",
        "probe_displacement_mm",
        "max_displacement_mm",
        "modes_used",
        "eval_us",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["modes_clamped"], true);
    assert_eq!(v["modes_used"], v["modes_available"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("the file holds"));
    // Pressing inward moves the tissue inward.
    assert!(v["probe_displacement_mm"].as_f64().expect("number") > 0.0);
    let text = std::fs::read_to_string(&vtu).expect("vtu written");
    assert!(text.starts_with("<?xml") && text.contains("Name=\"displacement\""));
    // The scene stores its surface, and the file holds it and says so: as many points
    // as the scene has rows' nodes, each on a triangle.
    assert!(
        text.contains("the organ's surface only"),
        "{}",
        &text[..400]
    );
    assert!(text.contains(r#"Name="palpa_holds_volume" NumberOfTuples="1" format="ascii">0<"#));
    let header = palpa_core::file::read_header(std::path::Path::new(scene)).expect("header");
    let points = format!("NumberOfPoints=\"{}\"", header.rows / 3);
    assert!(text.contains(&points), "expected {points}");
}

/// What cannot be pressed or measured is refused before any work, naming the flag: an
/// infinite force (it once printed nulls and succeeded), a tissue depth grid of no
/// step under `offline --model` (once refused only after the scene's build), a
/// tradeoff at no held-out point (once ran on), an exported scene of no modes (once
/// written), a synthetic model of no rows or one larger than memory (once an abort);
/// a missing file is named once, its cause not repeated.
#[test]
fn what_cannot_be_pressed_is_refused_by_flag() {
    let words = |line: &'static str| line.split(' ').collect::<Vec<_>>();
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("o.palpa");
    let out_s = out.to_str().expect("utf-8");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    let tissue = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let missing = dir.path().join("missing.palpa");
    let missing = missing.to_str().expect("utf-8");
    let nowhere = dir.path().join("no-such-folder/o.palpa");
    let nowhere = nowhere.to_str().expect("utf-8");
    for (args, want) in [
        // Once 45 s of building, then a failed write.
        (
            vec!["offline", "liver", "--out", nowhere],
            "no-such-folder does not exist (expected an existing folder to write into)",
        ),
        (
            vec!["cme", "offline", "toggle", "--out", nowhere],
            "no-such-folder does not exist",
        ),
        (
            vec![
                "headless",
                "--frames",
                "1",
                "--out",
                dir.path().to_str().expect("utf-8"),
            ],
            "a folder (expected a file to write)",
        ),
        (
            vec!["eval", scene, "--at=-30,90,25", "--force-n", "inf"],
            "--force-n inf: expected a finite force",
        ),
        // Flags of the other kind of file were once ignored.
        (
            vec!["tradeoff", scene, "--seed", "3"],
            "--seed applies to a tissue file's table",
        ),
        (
            vec!["tradeoff", tissue, "--svd"],
            "--svd applies to a scene's table",
        ),
        (
            vec![
                "eval",
                scene,
                "--at=-30,90,25",
                "--force-n",
                "1",
                "--scene",
                "liver",
            ],
            "--scene liver: names the scene a tissue file serves",
        ),
        (
            vec![
                "eval",
                tissue,
                "--at=-30,90,25",
                "--force-n",
                "1",
                "--modes",
                "2",
            ],
            "--modes 2: a tissue vademecum answers with the modes each press kept",
        ),
        // Once a glued probe pulling the surface out (the tissue file refused it).
        (
            vec!["eval", scene, "--at", "-30,90,25", "--depth-mm", "-1"],
            "--depth-mm -1: expected a finite depth ≥ 0 mm (the tool presses; it cannot pull)",
        ),
        (
            vec!["eval", scene, "--at=-30,90,25", "--force-n", "-1"],
            "--force-n -1: expected a finite force ≥ 0 N",
        ),
        (
            vec![
                "offline",
                "liver",
                "--model",
                "neo-hookean",
                "--depth-max-mm",
                "0",
                "--out",
                out_s,
            ],
            "--depth-max-mm: invalid depth grid",
        ),
        // Once ignored: the linear scene has no depth axis.
        (
            vec!["offline", "liver", "--depth-max-mm", "3", "--out", out_s],
            "--depth-max-mm shapes the hyperelastic vademecum",
        ),
        (
            vec!["tradeoff", tissue, "--held-out", "0"],
            "expected at least one point",
        ),
        // Once 22 s of building, then a stencil's capacity.
        (
            vec!["offline", "liver", "--radius-mm", "300", "--out", out_s],
            "the tool (radius 300.0 mm) covers more than 1024 load nodes",
        ),
        // The full FE solve once took it as a plate over the whole surface, fixed
        // region included.
        (
            words("fe solve --at=-30,90,25 --force-n 1 --radius-mm 1e300"),
            "the tool (radius 1e300 mm) covers more than 1024 load nodes",
        ),
        (vec!["cme", "eval", missing, "--t", "1"], "missing.palpa"),
        // Once a null distance (its square overflowed).
        (
            vec!["eval", scene, "--at=1e300,0,0", "--force-n", "1"],
            "--at needs three finite comma-separated numbers of magnitude at most 1e6",
        ),
        // Once ignored by the nodal build (the default), a NaN tolerance too.
        (
            vec!["offline", "liver", "--tol", "nan", "--out", out_s],
            "--tol NaN: expected a finite relative norm",
        ),
        (
            vec!["offline", "liver", "--block", "4", "--out", out_s],
            "--block tunes the PGD solver",
        ),
        // And the other way round: the nodal build's options were ignored by the PGD.
        (
            vec![
                "offline",
                "liver",
                "--method",
                "pgd",
                "--table-degree",
                "4",
                "--out",
                out_s,
            ],
            "--table-degree shapes the nodal build",
        ),
        // An exported scene (f32) once failed with an internal API's words.
        (
            vec!["tradeoff", scene],
            "the tradeoff is measured on the full vademecum",
        ),
        (
            vec!["tradeoff", tissue, "--depths", "31"],
            "expected depths up to 30 mm",
        ),
        // Once 71 s of factoring subnormal numbers, then an overflowed displacement.
        (
            vec![
                "fe",
                "solve",
                "--at=-30,90,25",
                "--force-n",
                "1",
                "--young-kpa",
                "1e-300",
            ],
            "Young's modulus 1e-300 kPa: expected 1e-3 to 1e9 kPa",
        ),
        // Once silently one order (0), or minutes of orders (200).
        (
            vec![
                "fe",
                "solve",
                "--at=-30,90,25",
                "--model",
                "neo-hookean",
                "--method",
                "series",
                "--orders",
                "0",
                "--depth-mm",
                "5",
            ],
            "a depth series of 0 orders: expected 1 to 30",
        ),
        // Once silently ignored by Newton.
        (
            words("fe solve --at=-30,90,25 --model neo-hookean --orders 3 --depth-mm 5"),
            "--orders 3: only --method series keeps orders",
        ),
        // A negative Poisson's ratio is a value, not a flag (it reaches the material's check).
        (
            words("fe solve --at -30,90,25 --force-n 1 --poisson -1"),
            "Poisson's ratio -1 must lie in (−1, 0.5)",
        ),
        (
            vec!["export-scene", scene, "--modes", "0", "--out", out_s],
            "at least one mode",
        ),
        (
            vec!["lab", "synth", "--rows", "0", "--out", out_s],
            "at least one row and one mode",
        ),
        // Once an aborted allocation (80 PB).
        (
            vec![
                "lab",
                "synth",
                "--rows",
                "100000000000",
                "--modes",
                "100000",
                "--out",
                out_s,
            ],
            "memory available",
        ),
    ] {
        let run = palpa(&args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            !run.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
        assert!(err.matches("os error").count() <= 1, "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {out_s}");
    }
}

/// One press by default: `palpa eval` on the default scene, `palpa eval` on its tissue
/// and `palpa fe solve` push along the same direction (the scene's smoothed normal, the
/// app's push) and report it as `direction`. The point lies next to the fixed region,
/// where a face's own normal is far from it: the scene's answer along the face normal
/// was 24.3 N where the app pressed, and the FE reference answered, 26.8 N. If any of
/// the three went back to the face normal, the directions would part here.
#[test]
fn eval_and_fe_solve_press_along_the_same_direction_by_default() {
    let assets = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/");
    let (scene, tissue) = (
        format!("{assets}liver-coarse.palpa"),
        format!("{assets}liver-coarse.tissue"),
    );
    let at = "--at=-21.7741,-50.4586,-36.2721";
    let press = ["--depth-mm", "2.6", "--json"];
    let linear = common::json_ok(&palpa(&[&["eval", &scene, at][..], &press].concat()));
    let run = palpa(&[&["eval", &tissue, at][..], &press].concat());
    let nonlinear = common::json_ok(&run);
    let fe = common::json_ok(&palpa(&[&["fe", "solve", at][..], &press].concat()));
    let dir = |v: &serde_json::Value| -> [f64; 3] {
        std::array::from_fn(|k| v["direction"][k].as_f64().expect("direction"))
    };
    let (d_fe, d_scene, d_tissue) = (dir(&fe), dir(&linear), dir(&nonlinear));
    // Both are the same f32 normals interpolated in f64: round-off apart.
    for d in [d_scene, d_tissue] {
        let gap = (0..3).map(|k| (d[k] - d_fe[k]).abs()).fold(0.0, f64::max);
        assert!(gap < 1e-9, "{d:?} against fe solve's {d_fe:?}");
    }
    // The same press: the scene's linear force within its compliance accuracy of the
    // FE's (2 %, as `depth_control_in_eval_and_fe_solve` holds elsewhere), and the
    // tissue's linear force is the scene's.
    let (f_scene, f_fe) = (
        linear["force_n"].as_f64().expect("force"),
        fe["force_n"].as_f64().expect("force"),
    );
    assert!(
        (f_scene - f_fe).abs() < 0.02 * f_fe,
        "scene {f_scene} N, FE {f_fe} N"
    );
    let f_tissue_linear = nonlinear["linear_force_n"].as_f64().expect("force");
    assert!((f_tissue_linear - f_scene).abs() < 1e-9 * f_scene);
    assert_eq!(nonlinear["probe_point"], nonlinear["at"]);
    // The press's keys are `palpa fe solve`'s in all three reports.
    for key in [
        "probe_point",
        "probe_projection_distance_mm",
        "direction",
        "control",
        "force_n",
        "probe_displacement_mm",
        "max_displacement_mm",
    ] {
        for (name, report) in [("eval scene", &linear), ("eval tissue", &nonlinear)] {
            assert!(report.get(key).is_some(), "{name} lacks {key}: {report}");
        }
        assert!(fe.get(key).is_some(), "fe solve lacks {key}");
    }
    let distance = |v: &serde_json::Value| v["probe_projection_distance_mm"].as_f64();
    assert_eq!(distance(&linear), distance(&nonlinear));
    // `--dir` still chooses the direction.
    let turned = common::json_ok(&palpa(
        &[&["fe", "solve", at, "--dir", "0,0,-1"][..], &press].concat(),
    ));
    assert_eq!(turned["direction"][2], -1.0);
}

/// Depth control: `eval --depth-mm` on the default scene and `fe solve --depth-mm`
/// (linear, and the neo-Hookean law on coarse P1) move the probe point by the depth and
/// report the force it takes under the same keys; the linear force matches the full FE
/// one within the scene's compliance accuracy; both flags at once are refused.
#[test]
fn depth_control_in_eval_and_fe_solve() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    let at = "--at=-30,90,25";
    let run = palpa(&["eval", scene, at, "--depth-mm", "5", "--json"]);
    let eval = common::json_ok(&run);
    assert_eq!(eval["control"], "depth");
    assert!((eval["probe_displacement_mm"].as_f64().expect("number") - 5.0).abs() < 1e-9);
    // 5 mm is past where the linear tissue agrees with the nonlinear one: flagged, and
    // said; 2 mm is not.
    assert_eq!(eval["beyond_linear_range"], true);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(said.contains("a linear press of 5.000 mm"), "{said}");
    // The shipped tissue lies beside the scene: the warning names the command that
    // answers as the app does.
    assert!(
        said.contains("`palpa eval") && said.contains("liver-coarse.tissue`"),
        "{said}"
    );
    let run = palpa(&["eval", scene, at, "--depth-mm", "2", "--json"]);
    assert_eq!(common::json_ok(&run)["beyond_linear_range"], false);
    // (`-30,90,25` lies 21 mm off the surface, which is warned too.)
    assert!(!String::from_utf8_lossy(&run.stderr).contains("a linear press"));
    let lin = common::json_ok(&palpa(&[
        "fe",
        "solve",
        "--level",
        "coarse",
        at,
        "--depth-mm",
        "5",
        "--json",
    ]));
    assert_eq!(lin["control"], "depth");
    assert!((lin["probe_displacement_mm"].as_f64().expect("number") - 5.0).abs() < 1e-9);
    let (fe, fs) = (
        eval["force_n"].as_f64().expect("force"),
        lin["force_n"].as_f64().expect("force"),
    );
    assert!((fe - fs).abs() < 0.02 * fs, "scene {fe} N, full FE {fs} N");
    let nh = common::json_ok(&palpa(&[
        "fe",
        "solve",
        "--level",
        "coarse",
        "--element",
        "p1",
        "--model",
        "neo-hookean",
        at,
        "--depth-mm",
        "5",
        "--json",
    ]));
    assert_eq!(nh["model"], "neo-hookean");
    assert!((nh["probe_displacement_mm"].as_f64().expect("number") - 5.0).abs() < 1e-6);
    assert!(nh["force_n"].as_f64().expect("force") > 0.0);
    assert!(nh["newton_iterations"].as_u64().expect("iterations") > 0);
    let both = palpa(&["eval", scene, at, "--depth-mm", "5", "--force-n", "1"]);
    assert!(!both.status.success());
    assert!(String::from_utf8_lossy(&both.stderr).contains("cannot be used with"));
    let neither = palpa(&["fe", "solve", "--level", "coarse", at]);
    assert!(!neither.status.success());
}

#[test]
fn cme_solve_prints_the_documented_json_for_fsp_and_ssa() {
    for method in ["fsp", "ssa"] {
        let out = palpa(&[
            "cme",
            "solve",
            "cascade",
            "--method",
            method,
            "--param",
            "delta=0.03",
            "--t",
            "10,30",
            "--trajectories",
            "500",
            "--json",
        ]);
        let v = common::json_ok(&out);
        assert_eq!(v["model"], "cascade");
        assert_eq!(v["method"], method);
        assert_eq!(v["t"].as_array().map(Vec::len), Some(2));
        assert_eq!(v["species"][0], "z1");
        for key in ["mean", "var", "marginals", "cov"] {
            assert_eq!(v[key].as_array().map(Vec::len), Some(2), "{key}");
        }
        assert!(v["seconds"].is_number());
        // The marginals are probability vectors from 0.
        let total: f64 = v["marginals"][1][0]
            .as_array()
            .expect("vector")
            .iter()
            .filter_map(|x| x.as_f64())
            .sum();
        assert!((total - 1.0).abs() < 1e-6, "{total}");
        assert_eq!(v["leaked"].is_array(), method == "fsp");
    }
}

#[test]
fn cme_errors_are_clear() {
    let out = palpa(&[
        "cme",
        "solve",
        "cascade",
        "--method",
        "fsp",
        "--param",
        "delta=0.2",
        "--t",
        "5",
    ]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("outside its trained range"));
    for (args, want) in [
        (
            vec!["cme", "solve", "nosuch", "--method", "fsp", "--t", "1"],
            "unknown built-in network",
        ),
        (
            vec!["cme", "solve", "toggle", "--method", "fsp", "--t", "5,1"],
            "increasing order",
        ),
        (
            vec!["cme", "solve", "toggle", "--method", "fsp", "--t", "-1"],
            "expected finite times ≥ 0",
        ),
        (
            vec![
                "cme",
                "solve",
                "toggle",
                "--method",
                "ssa",
                "--t",
                "1",
                "--trajectories",
                "100000000000",
            ],
            "expected a run that fits in half of it",
        ),
        (
            vec![
                "cme", "solve", "toggle", "--method", "fsp", "--param", "delta", "--t", "1",
            ],
            "NAME=VALUE",
        ),
        (vec!["cme", "eval", "Cargo.toml", "--t", "1"], "not a palpa"),
        (
            vec!["cme", "offline", "toggle", "--t-end=-1", "--out", "x.palpa"],
            "invalid time grid",
        ),
        (
            vec![
                "cme", "offline", "toggle", "--t-end", "1e9", "--out", "x.palpa",
            ],
            "needs at least 2.000e8 steps",
        ),
    ]
    .into_iter()
    .chain(["nan", "-1"].map(|leak| {
        (
            vec![
                "cme",
                "solve",
                "toggle",
                "--method",
                "fsp",
                "--t",
                "1",
                "--max-leak",
                leak,
            ],
            "expected a probability between 0 and 1",
        )
    })) {
        let out = palpa(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
    }
    // A file named as SBML that is not XML, and XML that is not SBML: said so, not a
    // TOML parser's complaint about the first line.
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, text, want) in [
        ("notes.xml", "rate = 1\n", "not an SBML document"),
        ("page.toml", "<html><body/></html>", "root is not <sbml>"),
    ] {
        let file = dir.path().join(name);
        std::fs::write(&file, text).expect("write");
        let file = file.to_str().expect("utf-8");
        for cmd in [
            vec!["cme", "convert", file],
            vec!["cme", "solve", file, "--method", "fsp", "--t", "1"],
        ] {
            let out = palpa(&cmd);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(
                !out.status.success() && err.contains(want),
                "{cmd:?}: {err}"
            );
        }
    }
}

/// The exact solve to t = 10¹² (days of stepping) stops where the toggle's law settles
/// and says so; the answer is the one at t = 10⁴ (2 500 relaxation times), and at
/// 10²⁰ too once `--auto-box` has grown the box that leaks by then.
#[test]
fn fsp_at_a_very_long_time_says_where_it_settled() {
    let out = palpa(&[
        "cme", "solve", "toggle", "--method", "fsp", "--t", "1e4,1e12", "--json",
    ]);
    let v = common::json_ok(&out);
    let settled = v["settled_at"].as_f64().expect("settled_at");
    assert!(settled > 0.0 && settled < 1e4, "settled at {settled}");
    let mean = |j: usize| v["mean"][j][0].as_f64().expect("mean");
    assert!(
        (mean(0) - mean(1)).abs() < 1e-9,
        "{} vs {}",
        mean(0),
        mean(1)
    );
    let leak = v["leaked"][1].as_f64().expect("leak");
    assert!(leak < 1e-6, "leak {leak}");

    // Settled, the box still leaks at its law's exit rate: by 10²⁰ the toggle's
    // declared 80 × 80 box has lost more than the target and says what to do, and
    // `--auto-box` (once a no-op on declared maxima, and still suggesting itself)
    // grows it until the same answer keeps its mass.
    let solve = |extra: &[&str]| {
        let base = ["cme", "solve", "toggle", "--method", "fsp", "--t", "1e20"];
        common::json_ok(&palpa(&[&base[..], extra, &["--json"]].concat()))
    };
    let fixed = solve(&[]);
    let warned = fixed["warnings"].to_string();
    assert!(warned.contains("use --auto-box"), "{fixed}");
    let grown = solve(&["--auto-box"]);
    assert_eq!(grown["warnings"], serde_json::json!([]), "{grown}");
    let sizes = grown["box_sizes"].as_array().expect("sizes");
    assert!(sizes.iter().all(|m| m.as_u64() > Some(80)), "{grown}");
    let leak = grown["leaked"][0].as_f64().expect("leak");
    assert!(leak < 1e-6, "{grown}");
    let mean = grown["mean"][0][0].as_f64().expect("mean");
    assert!(
        (mean - v["mean"][0][0].as_f64().expect("mean")).abs() < 1e-6,
        "{grown}"
    );
}

/// PGD flags that would change nothing, or the wrong thing: an end before the last
/// output time (the greedy solver once answered t = 1 with its law at 0.5), a species
/// name that does not exist, and the stored model's flags given to a solve or to a
/// model that keeps its history.
#[test]
fn cme_pgd_flags_that_do_not_apply_are_said() {
    let run = |args: &str| {
        let out = palpa(&args.split(' ').collect::<Vec<_>>());
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        (out.status.success(), err)
    };
    let solve = "cme solve toggle --method pgd --t 1";
    for solver in ["tt", "greedy"] {
        let (ok, err) = run(&format!("{solve} --solver {solver} --t-end 0.5"));
        assert!(
            !ok && err.contains("must reach the last output time 1"),
            "{err}"
        );
    }
    // NaN compared false with the last output time, and the solve went on.
    let (ok, err) = run(&format!("{solve} --t-end nan"));
    assert!(
        !ok && err.contains("--t-end NaN: expected a finite end time"),
        "{err}"
    );
    let (ok, err) = run(&format!("{solve} --pairs z1:X"));
    assert!(!ok && err.contains("no species \"X\""), "{err}");
    let (ok, err) = run(&format!("{solve} --pairs z1:z2"));
    assert!(
        ok && err.contains("a solve keeps the states at its output times only"),
        "{err}"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("t.palpa");
    let offline = format!("cme offline toggle --t-end 1 --out {}", out.display());
    let (ok, err) = run(&format!("{offline} --views-eps 1e-4"));
    assert!(
        ok && err.contains("this one keeps the whole history"),
        "{err}"
    );
    // Once filed under "invalid time grid".
    let cascade = format!(
        "cme offline cascade --t-end 2 --keep views --out {}",
        out.display()
    );
    let (ok, err) = run(&cascade);
    assert!(
        !ok && err.contains("invalid solver setting: a views model is a function of time only"),
        "{err}"
    );
    let (ok, err) = run(&format!("{offline} --keep views --views-eps nan"));
    assert!(!ok && err.contains("--views-eps NaN"), "{err}");
    // One solver's flags given to the other, or any of them to FSP or SSA: said.
    let (ok, err) = run(&format!("{solve} --tol 1e-3"));
    assert!(
        ok && err.contains("--tol shapes the greedy solver only"),
        "{err}"
    );
    let (ok, err) = run(&format!("{solve} --solver greedy --eps 1e-3 --max-rank 3"));
    assert!(
        ok && err.contains("--eps, --max-rank shape the tt solver only"),
        "{err}"
    );
    let (ok, err) = run("cme solve toggle --method fsp --t 1 --max-step 2 --solver tt");
    assert!(
        ok && err.contains("--solver, --max-step shape the PGD solver only"),
        "{err}"
    );
    // Tolerances a solver would misread (a negative one was taken as given).
    for (solver, flag) in [
        ("tt", "--step-error"),
        ("greedy", "--tol"),
        ("greedy", "--step-tol"),
    ] {
        let (ok, err) = run(&format!("{solve} --solver {solver} {flag} -1"));
        assert!(
            !ok && err.contains("invalid solver setting") && err.contains("-1.0"),
            "{solver} {flag}: {err}"
        );
    }
}

/// The extremes of time as a user types them: t = 0 alone by PGD (once refused: its
/// time grid needs an end), and tiny or huge times printed as numbers a person reads
/// (1e-300 was once three hundred zeros).
#[test]
fn cme_times_at_the_extremes_are_answered_and_printed_readably() {
    let v = common::json_ok(&palpa(&[
        "cme", "solve", "toggle", "--method", "pgd", "--t", "0", "--json",
    ]));
    for i in 0..2 {
        let mean = v["mean"][0][i].as_f64().expect("mean");
        assert!(
            (mean - 15.0).abs() < 1e-6,
            "species {i}: mean {mean} at t = 0"
        );
    }
    let args = "cme solve toggle --method fsp --t 1e-300,0.5,1e12";
    let out = palpa(&args.split(' ').collect::<Vec<_>>());
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for line in ["t = 1e-300: ", "t = 0.5: ", "t = 1e12: "] {
        assert!(text.contains(line), "{line:?} missing from {text}");
    }
    // And in the time grid's refusals, for both PGD solvers.
    for solver in ["tt", "greedy"] {
        let args =
            format!("cme solve toggle --method pgd --solver {solver} --t 1 --max-step 1e-300");
        let out = palpa(&args.split(' ').collect::<Vec<_>>());
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("largest step 1e-300") && err.len() < 400,
            "{solver}: {err}"
        );
    }
}

#[test]
fn cme_offline_then_eval_reproduces_fsp_and_solve_by_pgd_prints_the_same_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = dir.path().join("toggle.palpa");
    let f = f.to_str().expect("utf-8 path");
    let out = palpa(&[
        "cme",
        "offline",
        "toggle",
        "--t-end",
        "2",
        "--max-step",
        "0.1",
        "--out",
        f,
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["solver"], "tt");
    assert!(v["history_ranks"].as_array().expect("ranks")[0].as_u64() > Some(1));
    assert!(v["worst_mass_correction"].as_f64().expect("mass") < 1e-3);
    let out = palpa(&[
        "cme",
        "eval",
        f,
        "--t",
        "1,2",
        "--check-fsp",
        "toggle",
        "--json",
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["method"], "pgd");
    assert_eq!(v["species"][1], "z2");
    for key in [
        "mean",
        "var",
        "marginals",
        "cov",
        "most_negative",
        "l1_joint_vs_fsp",
    ] {
        assert_eq!(v[key].as_array().map(Vec::len), Some(2), "{key}");
    }
    for l1 in v["l1_joint_vs_fsp"].as_array().expect("list") {
        let l1 = l1.as_f64().expect("number");
        assert!(l1 < 1e-2, "joint L1 {l1}");
    }
    // A rate the model was not built over, and no terms: said so (the first once ended
    // "the model's parameters are " and nothing; the second answered as if unasked).
    for (extra, want) in [
        (
            ["--param", "alpha=2"],
            "every rate was fixed when it was built",
        ),
        (["--modes", "0"], "--modes 0: expected at least one term"),
    ] {
        let out = palpa(&[&["cme", "eval", f, "--t", "1"][..], &extra[..]].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{extra:?}: {err}"
        );
    }
    // Past the trained range: a warning, not an extrapolation.
    let out = palpa(&["cme", "eval", f, "--t", "5"]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("past the model's time range"));
    let out = palpa(&[
        "cme",
        "solve",
        "toggle",
        "--method",
        "pgd",
        "--t",
        "0.5,1",
        "--max-step",
        "0.1",
        "--json",
    ]);
    let v = common::json_ok(&out);
    assert_eq!(v["method"], "pgd");
    assert_eq!(v["marginals"].as_array().map(Vec::len), Some(2));
}

/// `palpa lab bench cme`: PGD, FSP and SSA in one run; the PGD model is closer to FSP than
/// a small SSA run, so SSA needs more trajectories than it ran to match it.
#[test]
fn bench_cme_sets_pgd_against_ssa_at_equal_accuracy() {
    let out = palpa(&[
        "lab",
        "bench",
        "cme",
        "toggle",
        "--t",
        "1,2",
        "--max-step",
        "0.1",
        "--trajectories",
        "400",
        "--json",
    ]);
    let v = common::json_ok(&out);
    let pgd = v["pgd"]["marginal_l1_vs_fsp"].as_f64().expect("pgd error");
    let ssa = v["ssa"][1]["marginal_l1_vs_fsp"]
        .as_f64()
        .expect("ssa error");
    assert!(pgd < ssa, "{v}");
    assert!(v["pgd"]["eval_us"].as_f64().expect("eval") > 0.0);
    let needed = v["ssa_trajectories_for_pgd_accuracy"]
        .as_f64()
        .expect("count");
    assert!(needed > 400.0, "{v}");
    assert!(
        v["ssa_error_exponent"]
            .as_f64()
            .expect("exponent")
            .is_finite()
    );
    assert_eq!(v["fsp"]["leak"].as_array().map(Vec::len), Some(2));
}

/// The default (nodal) route end to end on coarse P2 for tool radii 2 and 10 mm (the
/// representation does not assume 5; a 2 mm tool gets a degree-8 compliance table): `palpa offline` then `palpa tradeoff`. The
/// held-out surface and force goals hold with the defaults, the far-field rows grow in
/// error as their tolerance coarsens, and dropping the far field costs accuracy.
#[test]
fn nodal_offline_then_tradeoff_meets_the_held_out_goals_for_small_and_large_tools() {
    let dir = tempfile::tempdir().expect("tempdir");
    for radius in ["2", "10"] {
        let model = dir.path().join(format!("nodal-{radius}.palpa"));
        let m = model.to_str().expect("utf-8");
        let out = palpa(&[
            "offline",
            "liver",
            "--level",
            "coarse",
            "--radius-mm",
            radius,
            "--out",
            m,
        ]);
        let built = common::json_ok(&out);
        assert_eq!(built["method"], "nodal");
        assert!(built["far_blocks"].as_u64() > Some(0), "{built}");
        let degree = if radius == "2" { 8 } else { 5 };
        assert_eq!(built["table_degree"], degree, "{built}");
        let v = common::json_ok(&palpa(&["tradeoff", m, "--json"]));
        let rows = v["rows"].as_array().expect("rows");
        let last = rows.last().expect("a row");
        for key in [
            "modes",
            "surface_rel_error",
            "probe_rel_error",
            "compliance_rel_error",
            "surface_max_nodal_error_mm",
            "surface_eval_us",
            "bytes",
        ] {
            assert!(
                !last[key].is_null(),
                "radius {radius}: {key} missing in {last}"
            );
        }
        let f = |r: &serde_json::Value, k: &str| r[k].as_f64().expect(k);
        assert!(
            f(last, "surface_rel_error") <= 0.02,
            "radius {radius}: {last}"
        );
        assert!(
            f(last, "surface_max_nodal_rel_error") <= 0.03,
            "radius {radius}: {last}"
        );
        assert!(
            f(last, "compliance_rel_error") <= 0.02,
            "radius {radius}: {last}"
        );
        let far = v["far_rows"].as_array().expect("far rows");
        let (first, none) = (&far[0], far.last().expect("row"));
        assert!(none["far_tolerance"].is_null());
        assert_eq!(f(first, "surface_rel_error"), f(last, "surface_rel_error"));
        assert!(
            f(none, "surface_rel_error") > 2.0 * f(first, "surface_rel_error"),
            "radius {radius}: {far:?}"
        );
        assert!(f(none, "bytes") < f(first, "bytes"));
    }
}

/// The network scene, headless: time swept to the model's end over the frames, the
/// frame's means equal to `palpa cme eval`'s at that time (the same model, the same
/// coordinates), the joint shown for two species, a PNG written; `--frames 0` refused.
#[test]
fn headless_network_scene_matches_cme_eval() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("toggle.palpa");
    let f = model.to_str().expect("utf-8");
    common::json_ok(&palpa(&[
        "cme",
        "offline",
        "toggle",
        "--t-end",
        "2",
        "--max-step",
        "0.1",
        "--out",
        f,
    ]));
    let png = dir.path().join("net.png");
    let v = common::json_ok(&palpa(&[
        "headless",
        "--scene",
        f,
        "--frames",
        "4",
        "--size",
        "640x400",
        "--out",
        png.to_str().expect("utf-8"),
        "--exact-check",
        "--json",
    ]));
    assert_eq!(v["kind"], "network");
    // The exact check at the last frame: the meta-model within 1e-2 in L1.
    let exact_l1 = v["exact_l1"].as_f64().expect("exact check ran");
    assert!(exact_l1 < 1e-2, "L1 to exact {exact_l1}");
    assert_eq!(v["species"].as_array().map(Vec::len), Some(2));
    let last = &v["last_coordinates"][0];
    assert_eq!(last["name"], "t");
    assert_eq!(last["value"].as_f64(), Some(2.0));
    assert!(v["eval_us_p50"].as_f64().expect("eval time") > 0.0);
    assert!(v["joint_us_p50"].as_f64().expect("joint time") > 0.0);
    assert!((v["last_mass"].as_f64().expect("mass") - 1.0).abs() < 1e-3);
    let e = common::json_ok(&palpa(&["cme", "eval", f, "--t", "2", "--json"]));
    let (scene_means, eval_means) = (&v["last_mean"], &e["mean"][0]);
    for i in 0..2 {
        assert_eq!(
            scene_means[i].as_f64(),
            eval_means[i].as_f64(),
            "species {i}"
        );
    }
    let bytes = std::fs::read(&png).expect("png written");
    assert!(bytes.starts_with(b"\x89PNG"));
    let none = palpa(&["headless", "--scene", f, "--frames", "0"]);
    assert!(!none.status.success());
    assert!(String::from_utf8_lossy(&none.stderr).contains("--frames 0"));
}

/// A network given by name or TOML file opens through its meta-model: built on first
/// open (progress on stderr) into a cache keyed by the network and the solver options
/// (the user's cache folder for a built-in, next to a TOML file), then reused.
#[test]
fn a_network_by_name_or_toml_is_built_once_then_cached() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |scene: &str| {
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args([
                "headless", "--scene", scene, "--frames", "2", "--size", "320x240", "--json",
            ])
            .env("XDG_CACHE_HOME", dir.path())
            .output()
            .expect("palpa runs")
    };
    let first = run("toggle");
    let v = common::json_ok(&first);
    assert_eq!(v["kind"], "network");
    assert!(String::from_utf8_lossy(&first.stderr).contains("building the meta-model"));
    let cached: Vec<_> = std::fs::read_dir(dir.path().join("palpa"))
        .expect("cache folder")
        .collect();
    assert_eq!(cached.len(), 1, "one cached model");
    let again = run("toggle");
    common::json_ok(&again);
    assert!(!String::from_utf8_lossy(&again.stderr).contains("building"));
    // A TOML network: cached next to it.
    let toml = dir.path().join("my-toggle.toml");
    std::fs::copy(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../assets/networks/toggle.toml"
        ),
        &toml,
    )
    .expect("copy");
    common::json_ok(&run(toml.to_str().expect("utf-8")));
    let beside = std::fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(Result::ok)
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.starts_with("my-toggle.") && n.ends_with(".palpa")
        })
        .count();
    assert_eq!(beside, 1, "the TOML network's model is cached beside it");
    // A broken TOML file is named, not built.
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "name = 3").expect("write");
    let out = run(bad.to_str().expect("utf-8"));
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.toml"));
}

/// A coordinate path drives the network scene headless: interpolated keyframes, a rate
/// beyond its trained range kept and flagged as clamped, an unknown name refused.
#[test]
fn a_coordinate_path_drives_the_network_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("cascade.palpa");
    let f = model.to_str().expect("utf-8");
    common::json_ok(&palpa(&[
        "cme",
        "offline",
        "cascade",
        "--t-end",
        "2",
        "--max-step",
        "0.1",
        "--out",
        f,
    ]));
    let path = dir.path().join("path.json");
    std::fs::write(
        &path,
        r#"{"keyframes": [{"t_s": 0, "coordinates": {"t": 0, "delta": 0.01}},
                          {"t_s": 2, "coordinates": {"t": 2, "delta": 0.2}}]}"#,
    )
    .expect("write");
    let p = path.to_str().expect("utf-8");
    // Frame 25 is at 1 s: halfway.
    let v = common::json_ok(&palpa(&[
        "headless",
        "--scene",
        f,
        "--frames",
        "26",
        "--size",
        "320x240",
        "--coordinate-path",
        p,
        "--json",
    ]));
    let coord = |name: &str| {
        v["last_coordinates"]
            .as_array()
            .expect("coordinates")
            .iter()
            .find(|c| c["name"] == name)
            .and_then(|c| c["value"].as_f64())
            .expect("named")
    };
    assert!((coord("t") - 1.0).abs() < 1e-12);
    assert!((coord("delta") - 0.105).abs() < 1e-12);
    assert_eq!(v["last_clamped"], serde_json::json!(["delta"]));
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"keyframes": [{"t_s": 0, "coordinates": {"gamma": 1}}]}"#,
    )
    .expect("write");
    let out = palpa(&[
        "headless",
        "--scene",
        f,
        "--frames",
        "2",
        "--coordinate-path",
        bad.to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"gamma\""));
    // A network's model is no scene to export (a tensor train once failed with the
    // loader's words, a greedy model would have been written as a scene).
    let shipped = dir.path().join("shipped.palpa");
    let out = palpa(&["export-scene", f, "--out", shipped.to_str().expect("utf-8")]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("a gene-network meta-model"),
        "{err}"
    );
    assert!(!shipped.exists());
    // A scene exported with more modes than it holds keeps them all, and says so.
    let assets = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets");
    let export = format!("export-scene {assets}/liver-coarse.palpa --modes 1000 --out");
    let mut args: Vec<&str> = export.split(' ').collect();
    args.push(shipped.to_str().expect("utf-8"));
    let out = palpa(&args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    let v = common::json_ok(&out);
    assert_eq!(v["modes_asked"], 1000);
    assert!(
        err.contains("--modes 1000: the file holds")
            && err.contains(&format!("kept {}", v["modes"])),
        "{err}"
    );
}

/// An SBML model (the DSMTS dimerisation, vendored) through every network command:
/// `cme convert` shows the binomial factor, FSP sizes the automatic boxes itself, the
/// PGD sizes them by its pre-pass, and both match the published mean at t = 50.
#[test]
fn an_sbml_model_converts_and_solves_with_automatic_boxes() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/dsmts");
    let xml = root.join("00030/00030-sbml-l3v1.xml");
    let xml = xml.to_str().expect("utf-8 path");
    let dir = tempfile::tempdir().expect("tempdir");
    let toml = dir.path().join("dimer.toml");
    let out = palpa(&[
        "cme",
        "convert",
        xml,
        "--out",
        toml.to_str().expect("utf-8"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&toml).expect("written");
    assert!(
        text.contains("kind = \"binomial\", k = 2") && text.contains("max = \"auto\""),
        "{text}"
    );
    // The published mean of P at t = 50 (00030-results.csv).
    let expected_p = 28.542298;
    for method in ["fsp", "pgd"] {
        let out = palpa(&[
            "cme", "solve", xml, "--method", method, "--t", "10,50", "--json",
        ]);
        assert!(
            out.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        let p = v["mean"][1][0].as_f64().expect("mean of P");
        assert!(
            (p - expected_p).abs() < 1e-3 * expected_p,
            "{method}: P {p}"
        );
    }
    // A law palpa cannot read is refused naming the reaction and why.
    let bad = dir.path().join("bad.xml");
    let text = std::fs::read_to_string(xml)
        .expect("vendored")
        .replacen("<times/>", "<plus/>", 1)
        .replacen("<ci> k1 </ci>", "<ci> P2 </ci>", 1);
    std::fs::write(&bad, text).expect("written");
    let out = palpa(&[
        "cme",
        "solve",
        bad.to_str().expect("utf-8"),
        "--method",
        "fsp",
        "--t",
        "1",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("Dimerisation") && err.contains("separable"),
        "{err}"
    );
}

/// `PALPA_MEMORY_GB` caps what a solve may plan with: a factorization beyond it is
/// refused by name, for the linear and the nonlinear solve alike (the nonlinear one once
/// called the refusal "the stiffness is not positive definite"), and a cap that is not a
/// positive number is refused before any work.
#[test]
fn a_memory_cap_refuses_the_factorization_by_name() {
    let with_cap = |cap: &str, args: &str| {
        Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(args.split_whitespace())
            .env("PALPA_MEMORY_GB", cap)
            .output()
            .expect("palpa runs")
    };
    for model in ["linear", "neo-hookean"] {
        let out = with_cap(
            "0.1",
            &format!("fe solve --at=-30,90,25 --model {model} --depth-mm 3"),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{model}: {err}");
        assert!(
            err.contains("GB are available: use a coarser level") && err.contains("needs about"),
            "{model}: {err}"
        );
        assert!(!err.contains("not positive definite"), "{model}: {err}");
    }
    for cap in ["nan", "-1", "0", "lots"] {
        let out = with_cap(cap, "fe solve --at=-30,90,25 --depth-mm 3");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{cap}: {err}");
        assert!(
            err.contains("PALPA_MEMORY_GB") && err.contains("expected a positive number"),
            "{cap}: {err}"
        );
    }
}

/// A `--at` point far off the palpable surface still presses its closest palpable point,
/// but says so; a point on the surface is pressed without the warning.
#[test]
fn eval_warns_when_the_point_lies_far_from_the_surface() {
    let assets = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/");
    for file in ["liver-coarse.palpa", "liver-coarse.tissue"] {
        let file = format!("{assets}{file}");
        let press = |at: &str| palpa(&["eval", &file, at, "--depth-mm", "2", "--json"]);
        let far = press("--at=0,0,0");
        let report = common::json_ok(&far);
        let distance = report["probe_projection_distance_mm"]
            .as_f64()
            .expect("distance");
        assert!(distance > 10.0, "{file}: {distance} mm");
        let stderr = String::from_utf8_lossy(&far.stderr);
        assert!(
            stderr.contains("from the palpable surface")
                && stderr.contains(&format!("{distance:.1} mm")),
            "{file}: {stderr}"
        );
        // The point it pressed lies on the surface: pressing it again warns of nothing.
        let p = &report["probe_point"];
        let at = format!("--at={},{},{}", p[0], p[1], p[2]);
        let near = press(&at);
        let again = common::json_ok(&near);
        assert!(
            again["probe_projection_distance_mm"]
                .as_f64()
                .expect("distance")
                < 1e-6
        );
        let stderr = String::from_utf8_lossy(&near.stderr);
        assert!(!stderr.contains("palpable surface"), "{file}: {stderr}");
    }
}

/// docs/accuracy.md shows what the shipped files record: its generated part is what
/// `palpa lab accuracy` prints from them now.
#[test]
fn docs_accuracy_is_what_the_shipped_files_record() {
    let out = palpa(&["lab", "accuracy"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let generated = String::from_utf8(out.stdout).expect("utf-8");
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/accuracy.md"))
        .expect("docs/accuracy.md");
    let (begin, end) = (
        "<!-- palpa lab accuracy: begin -->\n",
        "<!-- palpa lab accuracy: end -->",
    );
    let start = doc.find(begin).expect("the begin marker") + begin.len();
    let stop = doc.find(end).expect("the end marker");
    assert_eq!(
        &doc[start..stop],
        generated,
        "run `palpa lab accuracy --write docs/accuracy.md`"
    );
    assert!(
        generated.contains("### Its neo-Hookean tissue"),
        "{generated}"
    );
}

/// `fe solve` with a nodule: echoed in the JSON, its stiffness field in the `.vtu` as
/// cell data, the force of a press raised; a nodule too near the surface refused
/// before any solve, naming the expectation.
#[test]
fn fe_solve_takes_a_nodule_and_writes_its_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let vtu = dir.path().join("u.vtu").display().to_string();
    let base = [
        "fe",
        "solve",
        "--at",
        "-7,69.34,7",
        "--depth-mm",
        "5",
        "--json",
    ];
    let without = common::json_ok(&palpa(&base));
    let with = common::json_ok(&palpa(
        &[
            &base[..],
            &[
                "--nodule-at=-7,50,7",
                "--nodule-radius-mm",
                "8",
                "--nodule-ratio",
                "4.4",
                "--out",
                &vtu,
            ],
        ]
        .concat(),
    ));
    assert_eq!(with["nodule"]["radius_mm"], 8.0, "{with}");
    assert!(
        with["nodule"]["cells_stiffened"].as_u64() > Some(0),
        "{with}"
    );
    let f = |v: &serde_json::Value| v["force_n"].as_f64().expect("force");
    assert!(f(&with) > f(&without), "{with} vs {without}");
    let text = std::fs::read_to_string(&vtu).expect("written");
    assert!(text.contains(r#"<CellData>"#) && text.contains(r#"Name="stiffness_factor""#));
    let out = palpa(&[&base[..], &["--nodule-at=-7,66,7"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("at least 2 mm"),
        "{err}"
    );
    let out = palpa(&[&base[..], &["--nodule-ratio", "3"]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--nodule-at"), "{err}");
}

/// The nodule store's bench on the smallest store (one centre, one radius): the placed
/// nodule's compliance equals the FE's with it (measured 1.2e-7: the stored responses
/// and the nodule's small system in single precision) and the table names the
/// unknowns it touched.
#[test]
fn bench_nodule_store_matches_the_fe() {
    let out = palpa(&[
        "lab",
        "bench",
        "nodule-store",
        "--radii",
        "8",
        "--reach-mm",
        "0",
        "--repeats",
        "1",
        "--json",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect();
    assert_eq!(rows.len(), 2, "{text}");
    assert!(rows[0]["columns"].as_u64().unwrap_or(0) > 0, "{text}");
    let gap = rows[1]["compliance_gap"].as_f64().expect("a gap");
    assert!(gap < 4e-7, "{text}");
    assert!(rows[1]["unknowns"].as_u64().unwrap_or(0) > 100, "{text}");
    assert!(rows[1]["effect"].as_f64().unwrap_or(0.0) > 0.01, "{text}");
}

/// `palpa nodule build` tabulates a nodule's effect about a point under the anterior
/// face; `palpa eval --nodule-*` reads the table beside the scene and answers as the
/// full FE with that nodule does (measured: effect +19.5 % against the FE's +19.3 %,
/// the force with the nodule within 0.9 % of the FE's); without a table, or off it, it
/// says so by name.
#[test]
fn a_nodule_table_beside_the_scene_answers_eval_as_the_fe_does() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("liver.palpa");
    let asset = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.palpa");
    std::fs::copy(asset, &scene).expect("copy the scene");
    let press = ["--at=-40,60,30", "--depth-mm", "2"];
    let nodule = [
        "--nodule-at=-38,49,19.5",
        "--nodule-radius-mm",
        "10",
        "--nodule-ratio",
        "4.4",
    ];
    let scene_s = scene.display().to_string();
    let mut eval: Vec<&str> = vec!["eval", &scene_s];
    eval.extend(press);
    eval.extend(nodule);
    eval.push("--json");
    let no_table = palpa(&eval);
    assert!(!no_table.status.success());
    let err = String::from_utf8_lossy(&no_table.stderr);
    assert!(
        err.contains("liver.nodules") && err.contains("palpa nodule build"),
        "{err}"
    );

    let table = dir.path().join("liver.nodules");
    let table_s = table.display().to_string();
    let build = |shard: &[&str]| {
        let mut a = vec![
            "nodule",
            "build",
            "--level",
            "coarse",
            "--around=-38.66,48.92,18.54",
            "--half-width-mm",
            "3",
            "--out",
            &table_s,
            "--json",
        ];
        a.extend(shard);
        common::json_ok(&palpa(&a))
    };
    let b = build(&[]);
    assert_eq!(b["centres"], 27);
    // The same in two shards (the lattice is one block: the second shard builds
    // nothing), merged: the same payload.
    for i in ["1/2", "2/2"] {
        build(&["--shard", i]);
    }
    let merged_s = dir.path().join("merged.nodules").display().to_string();
    let shard = |i: u32| format!("{table_s}.shard-{i}-of-2");
    let out = palpa(&["nodule", "merge", &shard(1), "--out", &merged_s]);
    assert!(!out.status.success(), "a shard missing");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("missing [2]"), "{err}");
    let m = common::json_ok(&palpa(&[
        "nodule",
        "merge",
        &shard(2),
        &shard(1),
        "--out",
        &merged_s,
        "--json",
    ]));
    assert_eq!(m["payload_xxh3"], b["payload_xxh3"], "{m} against {b}");
    let info = common::json_ok(&palpa(&["info", &shard(1), "--json"]));
    assert_eq!(info["shard"], serde_json::json!([1, 2]), "{info}");
    let e = common::json_ok(&palpa(&eval));
    let table_effect = e["nodule"]["effect"].as_f64().expect("an effect");
    let fe = |with: bool| {
        let mut a = vec!["fe", "solve", "--level", "coarse"];
        a.extend(press);
        if with {
            a.extend(nodule);
        }
        a.push("--json");
        common::json_ok(&palpa(&a))["force_n"]
            .as_f64()
            .expect("a force")
    };
    let (free, with) = (fe(false), fe(true));
    let fe_effect = with / free - 1.0;
    assert!(fe_effect > 0.1, "a nodule the hand feels: {fe_effect}");
    assert!(
        (table_effect - fe_effect).abs() < 0.03 * fe_effect,
        "effect {table_effect} against the FE's {fe_effect}"
    );
    let force = e["force_n"].as_f64().expect("a force");
    assert!((force - with).abs() < 0.03 * with, "{force} against {with}");

    // `palpa nodule check` measures the table at held-out pairs against the FE, and
    // the surface the scene draws at 1 N with each nodule (the built-in liver is of
    // this table's mesh): measured 0.049 mm at worst.
    let c = common::json_ok(&palpa(&[
        "nodule", "check", &table_s, "--level", "coarse", "--felt", "1", "--seed", "5", "--json",
    ]));
    let worst = c["summary"]["surface_max_mm"]
        .as_f64()
        .expect("a surface measured");
    assert!(worst > 0.0 && worst < 0.15, "{c}");

    // The neo-Hookean tissue with the same nodule: its force times `1 + effect`, the
    // effect the table's at the tissue's probe point (not amplified: this table holds
    // no power of the tissue); against Newton with the nodule.
    let tissue = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/liver-coarse.tissue");
    let mut t_eval = vec!["eval", tissue];
    t_eval.extend(press);
    t_eval.extend(nodule);
    t_eval.extend(["--nodules", &table_s, "--json"]);
    let t = common::json_ok(&palpa(&t_eval));
    let t_force = t["force_n"].as_f64().expect("a force");
    let t_effect = t["nodule"]["effect"].as_f64().expect("an effect");
    let t_free = t["nodule"]["force_without_nodule_n"]
        .as_f64()
        .expect("the force without");
    assert!(
        (t_force - t_free * (1.0 + t_effect)).abs() < 1e-9 * t_force,
        "{t}"
    );
    assert!((t_effect - table_effect).abs() < 0.02 * table_effect, "{t}");
    // A table that holds no power of this tissue answers the linear effect as it is,
    // and says so.
    assert_eq!(t["nodule"]["amplified"], false, "{t}");
    let newton = {
        let mut a = vec!["fe", "solve", "--level", "coarse", "--model", "neo-hookean"];
        a.extend(press);
        a.extend(nodule);
        a.push("--json");
        common::json_ok(&palpa(&a))["force_n"]
            .as_f64()
            .expect("a force")
    };
    // Measured: 0.5 % from Newton's with the nodule at 2 mm.
    assert!(
        (t_force - newton).abs() < 0.03 * newton,
        "{t_force} against {newton}"
    );

    // `palpa nodule check --tissue` refuses presses it cannot compare, by name.
    for (depths, said) in [
        ("0,5", "above 0 mm"),
        ("6,3", "ascending"),
        ("30", "deepest"),
    ] {
        let out = palpa(&[
            "nodule", "check", &table_s, "--tissue", tissue, "--depths", depths,
        ]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--depths") && err.contains(said),
            "{depths}: {err}"
        );
    }

    // `--above` (the probe right above each nodule) measures a tissue, and says so.
    let out = palpa(&["nodule", "check", &table_s, "--above"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--above") && err.contains("--tissue"), "{err}");

    // `palpa nodule tissue` refuses knobs it cannot press with, by name, before it
    // presses anything.
    for (knob, value, said) in [
        ("--reach-mm", "-1", "positive distance"),
        ("--share-floor", "1.5", "share from 0"),
        ("--depth-max-mm", "40", "at most the tissue's"),
    ] {
        let out = palpa(&[
            "nodule", "tissue", &table_s, "--tissue", tissue, knob, value,
        ]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(knob) && err.contains(said), "{knob}: {err}");
    }

    // A table without a nodule is refused, for a tissue file too.
    let out = palpa(&[
        "eval",
        tissue,
        "--at=-40,60,30",
        "--depth-mm",
        "2",
        "--nodules",
        &table_s,
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--nodule-at"), "{err}");

    // A nodule off the table's lattice is refused, naming the lattice.
    let mut off = eval.clone();
    let far = "--nodule-at=-30,49,19.5";
    off[5] = far;
    let out = palpa(&off);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("lattice of centres"), "{err}");
}

/// The default scene's nodule table as the commands show it: `palpa info` gives its
/// recorded accuracy, `palpa tradeoff` its knobs at the recorded pairs (a coarser
/// lattice errs more, and ignoring the nodule errs wholly), and flags of other kinds'
/// tables are refused by name.
#[test]
fn info_and_tradeoff_show_the_nodule_tables_recorded_accuracy_and_knobs() {
    let table = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../assets/liver-coarse.nodules"
    );
    let info = common::json_ok(&palpa(&["info", table, "--json"]));
    assert_eq!(info["kind"], "nodule-table");
    assert!(info["accuracy"]["felt"].as_u64().expect("felt pairs") >= 20);
    assert!(info["payload_xxh3"].is_string());
    let t = common::json_ok(&palpa(&["tradeoff", table, "--json"]));
    let rows = t["rows"].as_array().expect("rows");
    let median = |r: &serde_json::Value| r["heldout"]["error_median"].as_f64().expect("median");
    let (finest, coarsest) = (&rows[0], &rows[rows.len() - 1]);
    assert_eq!(finest["spacing_mm"], 3.0);
    assert_eq!(finest["answered"], finest["pairs"]);
    assert!(median(finest) < median(coarsest), "{rows:?}");
    assert_eq!(t["nodule_ignored"]["error_median"], 1.0);
    let out = palpa(&["tradeoff", table, "--svd"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--svd") && err.contains("nodule table"),
        "{err}"
    );
}
