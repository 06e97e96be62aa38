//! A tissue build sharded (`tissue build … --shard I/N`, `tissue merge`): the merged
//! file's payload is the unsharded build's for N = 1, 2, 4 and 7; a missing shard, a
//! log of another build and a corrupt log are refused by name; a torn last record is
//! dropped, and a shard killed mid-way goes on from its log.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common;

fn palpa(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_palpa"))
        .args(args)
        .output()
        .expect("palpa runs")
}

/// A small region of the coarse liver on P1, to 3 mm: 43 presses in two steps of the
/// first pass (vertices and edges, then two split triangles' points), then the band.
const BUILD: [&str; 7] = [
    "tissue",
    "build",
    "--element",
    "p1",
    "--depth-max-mm",
    "3",
    "--within=-30.3,70.7,16.9,14",
];

fn build(out: &Path, extra: &[&str]) -> Output {
    let out = out.to_str().expect("utf-8 path");
    palpa(&[&BUILD[..], extra, &["--jobs", "1", "--out", out]].concat())
}

/// The shards' logs beside `out`, as a shell's `OUT.*shard-*.log` finds them.
fn shard_logs(out: &Path) -> Vec<PathBuf> {
    let name = out.file_name().and_then(|n| n.to_str()).expect("a name");
    let mut logs: Vec<PathBuf> = std::fs::read_dir(out.parent().expect("a folder"))
        .expect("lists")
        .map(|e| e.expect("entry").path())
        .filter(|p| {
            let n = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            n.starts_with(name) && n.contains(".shard-") && n.ends_with(".log")
        })
        .collect();
    logs.sort();
    logs
}

fn merge(out: &Path) -> Output {
    let logs = shard_logs(out);
    let mut args = vec!["tissue".to_string(), "merge".to_string()];
    args.extend(logs.iter().map(|p| p.display().to_string()));
    args.extend(["--out".to_string(), out.display().to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    palpa(&args)
}

/// Rounds of every shard then the merge until the file is written; the merged
/// summary and the rounds it took.
fn sharded(out: &Path, n: u32) -> (serde_json::Value, usize) {
    for round in 1..=4 {
        for i in 1..=n {
            let v = common::json_ok(&build(out, &["--shard", &format!("{i}/{n}")]));
            assert!(v["waiting"] == true || v["payload_xxh3"].is_string(), "{v}");
        }
        let v = common::json_ok(&merge(out));
        if out.exists() {
            return (v, round);
        }
        assert_eq!(v["done"], false, "{v}");
    }
    panic!("{n} shards did not finish in 4 rounds");
}

/// Measured: the two steps of the first pass take two rounds for N > 1, and the
/// file's payload is the unsharded build's (xxh3 `8ecf4a85a32b64a5` on this mesh).
#[test]
fn merged_shards_give_the_unsharded_payload() {
    let dir = tempfile::tempdir().expect("tempdir");
    let whole = common::json_ok(&build(&dir.path().join("one.tissue"), &[]));
    let want = whole["payload_xxh3"]
        .as_str()
        .expect("a payload hash")
        .to_string();
    for n in [1, 2, 4, 7] {
        let out = dir.path().join(format!("s{n}.tissue"));
        let (v, rounds) = sharded(&out, n);
        assert_eq!(v["payload_xxh3"], want.as_str(), "{n} shards: {v}");
        // One shard never waits; more wait once, for the first pass's second step.
        assert_eq!(rounds, if n == 1 { 1 } else { 2 }, "{n} shards");
        let info = common::json_ok(&palpa(&["info", out.to_str().expect("utf-8"), "--json"]));
        assert_eq!(info["payload_xxh3"], want.as_str());
        assert!(
            shard_logs(&out).is_empty(),
            "the merge removed the shards' logs"
        );
    }
}

#[test]
fn a_merge_refuses_what_is_not_one_complete_build() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.tissue");
    // Shard 2 of 3 never ran: the merge names it and its presses.
    for i in [1, 3] {
        common::json_ok(&build(&out, &["--shard", &format!("{i}/3")]));
    }
    let m = merge(&out);
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(!m.status.success());
    assert!(
        err.contains("not every shard is complete")
            && err.contains("shard 2 of 3: 8 presses (ids 975, "),
        "{err}"
    );
    // Killed mid-way: shard 2's log cut inside its last record goes on from there.
    common::json_ok(&build(&out, &["--shard", "2/3"]));
    let log2 = dir.path().join("x.tissue.shard-2-of-3.log");
    let bytes = std::fs::read(&log2).expect("log");
    std::fs::write(&log2, &bytes[..bytes.len() - 40]).expect("cut");
    let again = common::json_ok(&build(&out, &["--shard", "2/3"]));
    assert_eq!(again["pressed"], 1, "only the torn press again: {again}");
    // A torn last record in a log the merge reads is dropped and said.
    let bytes = std::fs::read(&log2).expect("log");
    std::fs::write(&log2, &bytes[..bytes.len() - 40]).expect("cut");
    let m = merge(&out);
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(err.contains("shard 2 of 3: 1 presses"), "{err}");
    common::json_ok(&build(&out, &["--shard", "2/3"]));
    let v = common::json_ok(&merge(&out));
    assert_eq!(v["done"], false, "{v}");
    // A corrupt record with more after it: refused, naming the log.
    let first = dir.path().join("x.tissue.shard-1-of-3.log");
    let mut bytes = std::fs::read(&first).expect("log");
    let key_end = bytes.iter().position(|&b| b == b'\n').expect("key line");
    bytes[key_end + 20] ^= 0xff;
    std::fs::write(&first, &bytes).expect("flip");
    let m = merge(&out);
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(
        err.contains("x.tissue.shard-1-of-3.log") && err.contains("fails its checksum"),
        "{err}"
    );
    // A log of another build (another depth) beside these: refused by name.
    std::fs::remove_file(&first).expect("rm");
    let other = dir.path().join("y.tissue");
    let mut args: Vec<&str> = BUILD.to_vec();
    args[5] = "4";
    let o = other.to_str().expect("utf-8");
    common::json_ok(&palpa(
        &[&args[..], &["--shard", "1/3", "--jobs", "1", "--out", o]].concat(),
    ));
    std::fs::rename(
        dir.path().join("y.tissue.shard-1-of-3.log"),
        dir.path().join("x.tissue.shard-1-of-3.log"),
    )
    .expect("mv");
    let m = merge(&out);
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(err.contains("is a log of another build"), "{err}");
    // A shard given other arguments than the plan's: refused, naming the plan.
    let wrong = palpa(
        &[
            &args[..],
            &["--shard", "1/3", "--out", out.to_str().expect("utf-8")],
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&wrong.stderr);
    assert!(
        !wrong.status.success() && err.contains("x.tissue.shard-plan"),
        "{err}"
    );
}

/// `--plan` presses nothing but a few samples: its first step's count is exactly what
/// the build presses there (25 vertices and edge midpoints in this region), its split
/// step is flagged as assumed, and more cores never predict a longer build.
#[test]
fn a_plan_counts_the_first_pass_exactly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("p.tissue");
    let out_s = out.to_str().expect("utf-8");
    let v = common::json_ok(&palpa(
        &[
            &BUILD[..],
            &[
                "--plan",
                "--plan-presses",
                "2",
                "--plan-cores",
                "1,2,7",
                "--json",
                "--out",
                out_s,
            ],
        ]
        .concat(),
    ));
    assert!(!out.exists(), "a plan writes no file");
    let steps = v["steps"].as_array().expect("steps");
    assert_eq!(steps[0]["presses"], 25, "{v}");
    assert_eq!(steps[0]["exact"], true);
    assert_eq!(steps[1]["exact"], false, "the split is assumed: {v}");
    let times: Vec<f64> = v["predicted"]
        .as_array()
        .expect("predicted")
        .iter()
        .map(|r| r["predicted_s"].as_f64().expect("seconds"))
        .collect();
    assert!(
        times.windows(2).all(|w| w[1] <= w[0]) && times[2] > 0.0,
        "{v}"
    );
    let bad = palpa(&[&BUILD[..], &["--plan", "--plan-cores", "0", "--out", out_s]].concat());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("cores ≥ 1"));
}
