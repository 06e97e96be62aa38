//! A sharded tissue build on a real Slurm: a single-node cluster (Debian's slurmctld,
//! slurmd and munge, configured in a temporary folder by
//! `scripts/cluster/local-slurm.sh`, stopped afterwards) runs the build of a small
//! region as rounds of an array of 4 shards and a merge job
//! (`scripts/cluster/slurm-tissue.sh`); the merged file's payload equals the local
//! unsharded build's. Needs root and the packages `scripts/deps.sh --cluster` installs.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;

fn scripts() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/cluster")
}

/// The cluster in `dir`, stopped when dropped (a failed assertion included).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let out = Command::new(scripts().join("local-slurm.sh"))
            .args(["start", dir.to_str().expect("utf-8 path")])
            .output()
            .expect("the script runs");
        assert!(
            out.status.success(),
            "the cluster did not start:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(scripts().join("local-slurm.sh"))
            .args(["stop", self.dir.to_str().unwrap_or("")])
            .output();
    }
}

/// Measured here: two rounds of 4 shards and a merge, about 20 s.
#[test]
fn a_sharded_build_on_slurm_merges_to_the_local_payload() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cluster = Cluster::start(&dir.path().join("slurm"));
    let palpa = env!("CARGO_BIN_EXE_palpa");
    let build = [
        "--element",
        "p1",
        "--depth-max-mm",
        "3",
        "--within=-30.3,70.7,16.9,14",
    ];
    let local = dir.path().join("local.tissue");
    let whole = common::json_ok(
        &Command::new(palpa)
            .args(["tissue", "build"])
            .args(build)
            .args(["--jobs", "1", "--out", local.to_str().expect("utf-8")])
            .output()
            .expect("palpa runs"),
    );
    let out = dir.path().join("cluster.tissue");
    let submitted = Command::new(scripts().join("slurm-tissue.sh"))
        .env("SLURM_CONF", &cluster.conf)
        .args(["--shards", "4", "--palpa", palpa, "--"])
        .args(build)
        .args(["--out", out.to_str().expect("utf-8")])
        .output()
        .expect("the script runs");
    assert!(
        submitted.status.success(),
        "{}",
        String::from_utf8_lossy(&submitted.stderr)
    );
    let status = dir.path().join("cluster.tissue.slurm/status");
    let started = Instant::now();
    while !status.exists() {
        assert!(
            started.elapsed() < Duration::from_secs(240),
            "no status after 4 minutes; the jobs said:\n{}",
            std::fs::read_dir(dir.path().join("cluster.tissue.slurm"))
                .map(|d| d
                    .filter_map(|e| e.ok())
                    .map(|e| format!(
                        "{}: {}",
                        e.path().display(),
                        std::fs::read_to_string(e.path()).unwrap_or_default()
                    ))
                    .collect::<Vec<_>>()
                    .join("\n"))
                .unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let said = std::fs::read_to_string(&status).expect("status");
    assert_eq!(said.trim(), "done", "{said}");
    eprintln!(
        "slurm: the build took {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let info = common::json_ok(
        &Command::new(palpa)
            .args(["info", out.to_str().expect("utf-8"), "--json"])
            .output()
            .expect("palpa runs"),
    );
    assert_eq!(info["payload_xxh3"], whole["payload_xxh3"]);
    drop(cluster);
}
