//! The `palpa` binary end to end: synth → info, bench output shape, clear errors.

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
}

#[test]
fn bench_eval_prints_one_json_object_per_configuration() {
    let out = palpa(&[
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
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON object per line"))
        .collect();
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

#[test]
fn bench_eval_rejects_zero_sizes() {
    let out = palpa(&["bench", "eval", "--rows", "0", "--min-time-ms", "1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("must be positive"));
}
