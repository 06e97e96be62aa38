//! `palpa scene build` end to end: a surface made here → scene, interrupted with
//! `kill -9` and resumed, described by `palpa info`, opened by the app offscreen;
//! regions from selectors and from a region file.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

fn palpa(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

fn ok(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    // One JSON line last, or one (pretty) JSON document.
    serde_json::from_str(text.lines().last().expect("a line"))
        .or_else(|_| serde_json::from_str(&text))
        .expect("json")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn a_scene_builds_from_a_surface_resumes_after_kill_and_opens() {
    let dir = tempfile::tempdir().expect("tempdir");
    let surface = dir.path().join("e.ply");
    let scene = dir.path().join("e.palpa");
    ok(&palpa(&[
        "scene",
        "shape",
        "ellipsoid",
        "--size",
        "4",
        "--out",
        s(&surface),
    ]));
    let args = [
        "scene",
        "build",
        "--surface",
        s(&surface),
        "--units",
        "cm",
        "--element",
        "p1",
        "--held-out",
        "4",
        "--out",
        s(&scene),
        "--json",
    ];
    // Kill the first run as soon as the vademecum stage is over.
    let mut child = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut seen = Vec::new();
    for line in stderr.lines() {
        let line = line.expect("line");
        let at_tradeoff = line.contains("[4/5] tradeoff");
        seen.push(line);
        if at_tradeoff {
            child.kill().expect("kill -9");
            break;
        }
    }
    let _ = child.wait();
    let build_dir = dir.path().join("e.palpa.build");
    assert!(
        build_dir.join("vademecum.palpa").exists(),
        "the finished stage is kept: {seen:?}"
    );
    assert!(!scene.exists(), "no scene before the last stage");

    let v = ok(&palpa(&args));
    assert_eq!(v["resumed"]["vademecum"], true, "{v}");
    assert!(scene.exists() && !build_dir.exists());
    // The resumed scene is an uninterrupted build's (the header's tradeoff table
    // holds timings, so the payload is compared).
    let whole = dir.path().join("whole.palpa");
    let mut whole_args = args;
    whole_args[whole_args.len() - 2] = s(&whole);
    // A tissue left beside it from another mesh is named: the app would refuse it.
    let resumed = palpa_app::scenes::load(s(&scene)).expect("the scene").scene;
    let mut stale = crate::tissue::hand_made(&resumed);
    stale.mesh_xxh3 = Some(1);
    stale.options.element = palpa_core::fe::Element::P1;
    stale
        .save(&dir.path().join("whole.tissue"))
        .expect("a stale tissue");
    let built = palpa(&whole_args);
    ok(&built);
    let stderr = String::from_utf8_lossy(&built.stderr);
    assert!(
        stderr.contains("whole.tissue beside the scene does not fit it")
            && stderr.contains("another organ mesh"),
        "{stderr}"
    );
    let (x, y) = (
        palpa_core::file::read_header(&scene).expect("resumed"),
        palpa_core::file::read_header(&whole).expect("whole"),
    );
    assert_eq!(
        (x.payload_len, x.payload_xxh3),
        (y.payload_len, y.payload_xxh3)
    );
    let vol = v["mesh"]["volume_rel_diff"].as_f64().expect("volume");
    assert!(vol.abs() < 0.02, "{v}");
    assert_eq!(v["source"]["format"], "ply (binary)");
    assert!(
        v["tradeoff"]["rows"]
            .as_array()
            .is_some_and(|r| !r.is_empty()),
        "{v}"
    );
    for stage in ["surface", "mesh", "vademecum", "tradeoff", "scene"] {
        assert!(v["seconds"][stage].is_number(), "{stage}: {v}");
    }
    // A linear scene has no tissue stage.
    assert!(
        v["seconds"]["tissue"].is_null() && v["tissue"].is_null(),
        "{v}"
    );

    let info = ok(&palpa(&["info", s(&scene), "--json"]));
    assert_eq!(info["source"]["file"], "e.ply");
    assert_eq!(info["source"]["units"], "cm");
    assert!(info["tradeoff_rows"].as_u64().is_some_and(|n| n > 0));

    // The app opens it (offscreen, on the software adapter) and presses it.
    let h = ok(&palpa(&[
        "headless",
        "--scene",
        s(&scene),
        "--frames",
        "4",
        "--size",
        "320x240",
        "--no-ui",
        "--json",
    ]));
    assert!(h.is_object(), "{h}");

    // `palpa tradeoff` does not pretend to re-measure a surface scene.
    let out = palpa(&["tradeoff", s(&scene)]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("scene build"));
}

#[test]
fn regions_come_from_selectors_and_region_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let surface = dir.path().join("s.obj");
    ok(&palpa(&[
        "scene",
        "shape",
        "sphere",
        "--size",
        "40",
        "--subdivisions",
        "3",
        "--out",
        s(&surface),
    ]));
    let build = |extra: &[&str], out: &str| {
        let scene = dir.path().join(out);
        let mut a = vec![
            "scene",
            "build",
            "--surface",
            s(&surface),
            "--units",
            "mm",
            "--element",
            "p1",
            "--held-out",
            "2",
            "--out",
        ];
        let scene_s = s(&scene).to_string();
        a.push(&scene_s);
        a.push("--json");
        a.extend_from_slice(extra);
        palpa(&a)
    };
    // The lower half fixed, the front half palpable.
    let v = ok(&build(
        &[
            "--fixed",
            "half:0,0,0:inferior",
            "--palpable",
            "normal:anterior:60",
        ],
        "a.palpa",
    ));
    let fixed_a = v["regions"]["fixed_vertices"].as_u64().expect("count");
    let palp_a = v["regions"]["palpable_triangles"].as_u64().expect("count");
    assert!(fixed_a > 0 && palp_a > 0, "{v}");
    // The same regions painted: the file's points are the old scene's classification.
    let regions = dir.path().join("r.toml");
    let mut fixed_pts = String::new();
    for k in 0..200 {
        // Points on the lower hemisphere, spread by the golden angle.
        let z = -40.0 * (k as f64 + 0.5) / 200.0;
        let r = (40.0f64 * 40.0 - z * z).sqrt();
        let a = k as f64 * 2.399_963;
        fixed_pts += &format!("[{}, {}, {}],", r * a.cos(), r * a.sin(), z);
    }
    std::fs::write(
        &regions,
        format!(
            "version = 1\nmatch_radius_mm = 8.0\nfixed_points = [{fixed_pts}]\n\
             palpable_selectors = [\"normal:anterior:60\"]\n"
        ),
    )
    .expect("write");
    let v = ok(&build(&["--regions", s(&regions)], "b.palpa"));
    let fixed_b = v["regions"]["fixed_vertices"].as_u64().expect("count");
    assert!(
        fixed_b.abs_diff(fixed_a) < fixed_a / 5,
        "painted {fixed_b} vs selected {fixed_a}"
    );
    // Bad selectors and region files fail naming the problem.
    let out = build(&["--fixed", "normal:up:45"], "c.palpa");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a direction"));
    std::fs::write(&regions, "version = 1\nmatch_radius_mm = 8.0\n").expect("write");
    let out = build(&["--regions", s(&regions)], "d.palpa");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("free to move"));
    // The other commands that take a surface need its unit too.
    let out = palpa(&["mesh", "--surface", s(&surface), "--json"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--units"));
    // And a unit without a surface is not silently ignored on the built-in organ.
    let out = palpa(&["mesh", "--units", "cm", "--json"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--surface"));
    let m = ok(&palpa(&[
        "mesh",
        "--surface",
        s(&surface),
        "--units",
        "mm",
        "--json",
    ]));
    let ml = m["volume_ml"].as_f64().expect("volume");
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 40f64.powi(3) / 1000.0;
    assert!((ml - exact).abs() / exact < 0.03, "{ml} ml vs {exact}");
    // The tissue's depth and recipe: said where they shape nothing, checked before
    // meshing.
    for flag in [["--depth-max-mm", "3"], ["--recipe", "quick"]] {
        let out = build(&flag, "g.palpa");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("shape the tissue"),
            "{err}"
        );
    }
    let out = build(&["--model", "svk", "--recipe", "fast"], "g.palpa");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("expected one of default, shipped, quick"),
        "{err}"
    );
    let out = build(
        &["--model", "neo-hookean", "--depth-max-mm", "nan"],
        "h.palpa",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("invalid depth grid"),
        "{err}"
    );
    assert!(!err.contains("[2/"), "refused before meshing: {err}");
    // Selecting nothing to fix is refused before any solving.
    let out = build(&["--fixed", "none"], "e.palpa");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("free to move"));
    // So is a held-out count no table needs (each point is a full FE solve).
    let out = dir.path().join("f.palpa");
    let mut args: Vec<&str> = "scene build --units mm --held-out 100000000 --out"
        .split(' ')
        .collect();
    args.extend([s(&out), "--surface", s(&surface)]);
    let out = palpa(&args);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("expected at most 10000"), "{err}");
    assert!(!err.contains("[2/"), "refused before meshing: {err}");
}

/// Every file made for `assets/` is listed in `assets/manifest.json` with the hash of
/// its bytes and the commands that made it, and the kidney example (the cheapest to
/// make: 16 s here) made again by its recorded commands is the recorded file: its
/// surface byte for byte, its scene's content (all but the build date and timings)
/// to the bit.
#[test]
fn the_shipped_files_are_what_their_recorded_commands_make() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    let text = std::fs::read_to_string(assets.join("manifest.json")).expect("manifest");
    let manifest: serde_json::Value = serde_json::from_str(&text).expect("json");
    let entries = manifest["assets"].as_array().expect("assets");
    let entry = |path: &str| {
        entries
            .iter()
            .find(|e| e["path"] == path)
            .unwrap_or_else(|| panic!("{path} is not in assets/manifest.json"))
    };
    let xxh3 = |p: &Path| {
        format!(
            "{:016x}",
            xxhash_rust::xxh3::xxh3_64(&std::fs::read(p).expect("read"))
        )
    };
    // Every made file (not the hand-written networks and READMEs) is listed, and is
    // the file recorded.
    let mut made = Vec::new();
    for dir in [assets.clone(), assets.join("kidney")] {
        for f in std::fs::read_dir(&dir).expect("assets") {
            let p = f.expect("entry").path();
            if matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("palpa" | "tissue" | "obj")
            ) {
                made.push(p);
            }
        }
    }
    assert!(made.len() >= 4, "{made:?}");
    for p in &made {
        let rel = p.strip_prefix(&assets).expect("under assets");
        let rel = rel.to_str().expect("utf-8").replace('\\', "/");
        let e = entry(&rel);
        assert_eq!(
            e["file_xxh3"].as_str(),
            Some(xxh3(p).as_str()),
            "{rel} changed since it was recorded: run the script that makes it"
        );
        assert!(
            !e["commands"].as_array().expect("commands").is_empty(),
            "{rel}"
        );
    }
    // The kidney scene, made again where its commands put it.
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("assets/kidney")).expect("mkdir");
    let scene = entry("kidney/kidney-coarse.palpa");
    for cmd in scene["commands"].as_array().expect("commands") {
        let words: Vec<&str> = cmd.as_str().expect("text").split_whitespace().collect();
        assert_eq!(words[0], "palpa", "{cmd}");
        let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
            .args(&words[1..])
            .current_dir(dir.path())
            .output()
            .expect("palpa runs");
        assert!(
            out.status.success(),
            "{cmd}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let remade = dir.path().join("assets/kidney");
    assert_eq!(
        entry("kidney/kidney.obj")["file_xxh3"].as_str(),
        Some(xxh3(&remade.join("kidney.obj")).as_str())
    );
    let header = palpa_core::file::read_header(&remade.join("kidney-coarse.palpa")).expect("scene");
    assert_eq!(
        scene["content_xxh3"].as_str(),
        Some(format!("{:016x}", header.content_xxh3()).as_str()),
        "the kidney scene made again differs from the one recorded"
    );
}
