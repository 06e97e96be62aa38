//! Off-line builds killed with SIGKILL and run again end with the same file as an
//! uninterrupted run, never leaving a half-written output; a full disk (simulated)
//! keeps the previous output and says so. (`palpa offline --method pgd` and
//! `palpa scene build` have their own resume tests in `cli.rs` and `scene_build.rs`.)

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn palpa(args: &[String]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

fn args(base: &[&str], out: &Path) -> Vec<String> {
    let mut a: Vec<String> = base.iter().map(|s| s.to_string()).collect();
    a.push("--out".into());
    a.push(out.to_str().expect("utf-8 path").into());
    a
}

/// Runs `a`, and SIGKILLs it as soon as `ready()` holds (or it ends by itself).
fn run_and_kill(a: &[String], ready: impl Fn() -> bool) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(a)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn");
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < Duration::from_secs(300), "no progress");
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Names in `dir` other than the ones given (temporary files left behind).
fn others(dir: &Path, keep: &[&Path]) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .expect("ls")
        .map(|e| e.expect("entry").path())
        .filter(|p| !keep.contains(&p.as_path()))
        .collect()
}

/// The tissue build (every vertex's press followed to equilibrium): killed after a
/// few presses are logged, run again it takes those from its binary log, presses the
/// rest and writes the same law as an uninterrupted build (all but the timings); the
/// log is removed.
#[test]
fn tissue_build_resumes_from_its_press_log() {
    let dir = tempfile::tempdir().expect("tempdir");
    let full = dir.path().join("full.tissue");
    let cut = dir.path().join("cut.tissue");
    let log = dir.path().join("cut.tissue.presses.log");
    // About ten vertices of coarse P1 in the anterior lobe and the edges between them,
    // to 4 mm: seconds.
    let base = [
        "tissue",
        "build",
        "--element",
        "p1",
        "--depth-max-mm",
        "4",
        "--within",
        "-30.3,70.7,16.9,15",
    ];
    let a = common::json_ok(&palpa(&args(&base, &full)));
    assert_eq!(a["resumed_presses"], 0);
    let samples = a["samples"].as_u64().expect("samples");
    let presses = samples + a["edges"].as_u64().expect("edges");
    assert!(
        samples >= 6 && presses >= 2 * samples,
        "{samples} vertices, {presses} presses"
    );
    // A press of 5 depths × 858 rows × 3 f32 is 51 kB: kill after a few.
    let size = || std::fs::metadata(&log).map(|m| m.len()).unwrap_or(0);
    run_and_kill(&args(&base, &cut), || size() > 3 * 51_000);
    assert!(
        !cut.exists(),
        "no law is written before every press is done"
    );
    let bytes = std::fs::read(&log).expect("log");
    assert!(
        bytes.starts_with(b"palpa tissue-build log 8 "),
        "the log's key line"
    );
    let b = common::json_ok(&palpa(&args(&base, &cut)));
    let resumed = b["resumed_presses"].as_u64().expect("count");
    assert!(
        (3..presses).contains(&resumed),
        "{resumed} of {presses} presses taken from the log"
    );
    assert!(!log.exists(), "the log is removed once the law is saved");
    let x = palpa_core::tissue::law::TissueLaw::load(&full).expect("full");
    let mut y = palpa_core::tissue::law::TissueLaw::load(&cut).expect("resumed");
    (y.build_s, y.compress_s) = (x.build_s, x.compress_s);
    assert!(x == y, "the resumed law differs from the uninterrupted one");
}

/// The stages that press on a built file (`lab tissue refine` splitting triangles, the
/// same splitting sub-triangles, `lab tissue band`), each killed after its first press is
/// logged: run again it takes that press from its log, presses the rest and writes the
/// same law as an uninterrupted run (all but the timings). The band's log is removed
/// then; a refinement's is kept, for a later, larger stage to reuse.
#[test]
fn tissue_stages_resume_from_their_press_logs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = |name: &str| dir.path().join(name);
    // A few vertices of coarse P1 next to the fixed region, to 8 mm: seconds.
    let within = "--within=4.06,-39.49,-34.90,15";
    let build = [
        "tissue",
        "build",
        "--element",
        "p1",
        "--depth-max-mm",
        "8",
        "--no-refine",
        "--no-band",
        within,
    ];
    common::json_ok(&palpa(&args(&build, &path("base.tissue"))));
    let (base, split) = (path("base.tissue"), path("split.tissue"));
    let (base, split) = (
        base.to_str().expect("utf-8"),
        split.to_str().expect("utf-8"),
    );
    // One press at a time, so the kill lands between presses of the same run.
    let stages: [(&str, Vec<&str>, &[&str]); 3] = [
        (
            "split",
            vec!["refine", base, "--triangles", "2"],
            &["quarter_points", "inner_points"],
        ),
        (
            "subsplit",
            vec!["refine", split, "--sub-triangles", "1"],
            &["presses"],
        ),
        ("band", vec!["band", base, within], &["band_edges"]),
    ];
    for (name, stage, counts) in stages {
        let stage: Vec<&str> = ["lab", "tissue"]
            .into_iter()
            .chain(stage)
            .chain(["--jobs", "1"])
            .collect();
        let (full, cut) = (path(&format!("{name}.tissue")), path("cut.tissue"));
        let log = path("cut.tissue.presses.log");
        let a = common::json_ok(&palpa(&args(&stage, &full)));
        let presses: u64 = counts.iter().map(|k| a[k].as_u64().expect("presses")).sum();
        assert!(presses >= 3, "{name}: {a}");
        // A press of 9 depths × 858 rows × 3 f32 is 93 kB: kill after the first.
        let size = || std::fs::metadata(&log).map(|m| m.len()).unwrap_or(0);
        run_and_kill(&args(&stage, &cut), || size() > 93_000);
        assert!(
            !cut.exists(),
            "{name}: a law written before every press is done"
        );
        let c = common::json_ok(&palpa(&args(&stage, &cut)));
        let resumed = c["resumed_presses"].as_u64().expect("count");
        assert!(
            (1..presses).contains(&resumed),
            "{name}: {resumed} of {presses} presses taken from the log"
        );
        assert_eq!(
            log.exists(),
            name != "band",
            "{name}: the log kept once the law is saved"
        );
        let x = palpa_core::tissue::law::TissueLaw::load(&full).expect("uninterrupted");
        let mut y = palpa_core::tissue::law::TissueLaw::load(&cut).expect("resumed");
        (y.build_s, y.compress_s) = (x.build_s, x.compress_s);
        assert!(
            x == y,
            "{name}: the resumed law differs from the uninterrupted one"
        );
        std::fs::remove_file(&cut).expect("rm");
        let _ = std::fs::remove_file(&log);
    }
}

/// The builders that finish in seconds to a few minutes at their defaults and start
/// again from the beginning (the nodal-load vademecum, the CME tensor train and the
/// greedy PGD): a kill mid-run leaves no output and no temporary file once the next
/// run is done, and that run's payload is bit for bit an uninterrupted run's.
#[test]
fn killed_builds_run_again_to_the_same_file() {
    let networks = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/networks");
    let toggle = format!("{networks}/toggle.toml");
    let cascade = format!("{networks}/cascade.toml");
    let cases: Vec<(&str, Vec<&str>, u64)> = vec![
        ("nodal", vec!["offline", "liver", "--element", "p1"], 300),
        (
            "tt",
            vec!["cme", "offline", &cascade, "--t-end", "20"],
            1000,
        ),
        (
            "greedy",
            vec![
                "cme", "offline", &toggle, "--solver", "greedy", "--t-end", "20",
            ],
            500,
        ),
    ];
    for (name, base, kill_ms) in cases {
        let dir = tempfile::tempdir().expect("tempdir");
        let full = dir.path().join("full.palpa");
        let cut = dir.path().join("cut.palpa");
        let out = palpa(&args(&base, &full));
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let start = Instant::now();
        run_and_kill(&args(&base, &cut), || {
            start.elapsed() > Duration::from_millis(kill_ms)
        });
        assert!(
            !cut.exists() || palpa_core::file::read_header(&cut).is_ok(),
            "{name}: a half-written output"
        );
        let out = palpa(&args(&base, &cut));
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let x = palpa_core::file::read_header(&full).expect("full");
        let y = palpa_core::file::read_header(&cut).expect("again");
        assert_eq!(
            (x.payload_len, x.payload_xxh3),
            (y.payload_len, y.payload_xxh3),
            "{name}: the run after the kill differs from the uninterrupted one"
        );
        assert_eq!(
            others(dir.path(), &[&full, &cut]),
            Vec::<PathBuf>::new(),
            "{name}: files left behind"
        );
    }
}

/// A disk that fills up while a model is written: the command
/// fails naming the file and the cause, and the file that was there is unchanged.
#[test]
fn a_full_disk_keeps_the_previous_output() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("m.palpa");
    let synth = |seed: &str| {
        args(
            &[
                "lab", "synth", "--rows", "300", "--modes", "8", "--seed", seed,
            ],
            &model,
        )
    };
    let out = palpa(&synth("1"));
    assert!(out.status.success());
    let before = std::fs::read(&model).expect("model");
    let out = Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(synth("2"))
        .env(palpa_core::fsutil::FAULT_DISK_FULL_ENV, "4096")
        .output()
        .expect("palpa runs");
    assert!(!out.status.success(), "a full disk is an error");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("m.palpa")
            && err.contains("No space left on device")
            && err.contains("kept unchanged"),
        "{err}"
    );
    assert_eq!(std::fs::read(&model).expect("model"), before);
    assert_eq!(others(dir.path(), &[&model]), Vec::<PathBuf>::new());
}
