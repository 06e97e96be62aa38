//! A tissue build sharded over many machines: `palpa tissue build … --shard I/N` presses
//! shard I's share of each step into its own log; `palpa tissue merge` gathers the
//! shards' logs into the build's and goes on as far as they reach: the file (its
//! payload the same as one unsharded build's), or the next step for the shards.
//!
//! A step's presses depend on the steps before (which triangles a stage splits comes
//! from the presses so far), so a recipe of S steps runs as S rounds of "every shard,
//! then the merge". Each shard reads the build's log (what merges gathered) and writes
//! only its own; each writes the build's arguments beside the output
//! (`OUT.shard-plan`, the same for every shard), which is how the merge knows the
//! build without being told again.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, Parser};
use palpa_core::tissue::presser::Shard;
use palpa_core::tissue::presslog::RecordLog;
use serde_json::json;

use super::build::{BuildArgs, Built, Sharding, build_run, press_log, stage_log};

/// The build's arguments, beside its output.
fn plan_path(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".shard-plan");
    PathBuf::from(p)
}

/// The arguments after `palpa tissue build`, less those that do not change the file
/// (`--shard`, `--jobs`).
fn build_arguments() -> Vec<String> {
    let args: Vec<String> = std::env::args().collect();
    let start = args
        .windows(2)
        .position(|w| w[0] == "tissue" && w[1] == "build")
        .map_or(args.len(), |k| k + 2);
    let mut kept = Vec::new();
    let mut skip = false;
    for a in &args[start..] {
        if std::mem::take(&mut skip) {
            continue;
        }
        if a == "--shard" || a == "--jobs" {
            skip = true;
        } else if !(a.starts_with("--shard=") || a.starts_with("--jobs=")) {
            kept.push(a.clone());
        }
    }
    kept
}

/// A shard's run: the plan written (or checked against the other shards'), then its
/// presses; the JSON of what it did.
pub fn run_shard(args: &BuildArgs, shard: Shard) -> anyhow::Result<serde_json::Value> {
    crate::cli::args::check_out(&args.out)?;
    let plan = plan_path(&args.out);
    let mine = serde_json::to_string(&build_arguments())?;
    match std::fs::read_to_string(&plan) {
        Ok(theirs) if theirs != mine => bail!(
            "{}: another build's shards wrote their arguments here ({theirs}, this shard's are \
             {mine}): expected every shard of one build to be given the same arguments but \
             --shard and --jobs (or remove the plan and their logs to start another build)",
            plan.display()
        ),
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            palpa_core::fsutil::atomic_write(&plan, |f| {
                use std::io::Write;
                f.write_all(mine.as_bytes())
            })
            .with_context(|| format!("writing {}", plan.display()))?;
        }
        Err(e) => return Err(e).with_context(|| format!("reading {}", plan.display())),
    }
    Ok(match build_run(args, Some(Sharding::Shard(shard)))? {
        Built::File(_, summary) => summary,
        Built::Waiting(v) => v,
    })
}

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The shards' logs (`OUT.shard-I-of-N.log`, `OUT.stage-K.shard-I-of-N.log`).
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// The build's output, as the shards were given it.
    #[arg(long)]
    pub out: PathBuf,
}

/// The build's arguments as the shards wrote them.
#[derive(Debug, Parser)]
struct PlanCommand {
    #[command(flatten)]
    build: BuildArgs,
}

/// Which step and shard a log's name says it holds: `(step, I, N)`.
fn log_name(out: &Path, log: &Path) -> Option<(usize, u32, u32)> {
    let out_name = out.file_name()?.to_str()?;
    let name = log.file_name()?.to_str()?;
    let rest = name.strip_prefix(out_name)?.strip_prefix('.')?;
    let (stage, rest) = match rest.strip_prefix("stage-") {
        Some(r) => {
            let (k, r) = r.split_once('.')?;
            (k.parse::<usize>().ok().filter(|&k| k > 0)?, r)
        }
        None => (0, rest),
    };
    let rest = rest.strip_prefix("shard-")?.strip_suffix(".log")?;
    let (i, n) = rest.split_once("-of-")?;
    let (i, n) = (i.parse().ok()?, n.parse().ok()?);
    (i >= 1 && i <= n).then_some((stage, i, n))
}

/// Gathers the shards' logs into the build's and goes on.
pub fn merge(args: &MergeArgs) -> anyhow::Result<serde_json::Value> {
    let plan = plan_path(&args.out);
    let text = std::fs::read_to_string(&plan).with_context(|| {
        format!(
            "reading {}: expected the plan the shards of `palpa tissue build … --shard I/N --out {}` write beside it",
            plan.display(),
            args.out.display()
        )
    })?;
    let argv: Vec<String> =
        serde_json::from_str(&text).with_context(|| format!("{} is not a plan", plan.display()))?;
    let build = PlanCommand::try_parse_from(
        std::iter::once("palpa tissue build".to_string()).chain(argv.iter().cloned()),
    )
    .with_context(|| format!("the arguments in {}", plan.display()))?
    .build;
    // The logs by step, each with its shard.
    let mut steps: BTreeMap<usize, Vec<(u32, &PathBuf)>> = BTreeMap::new();
    let mut count = None;
    for log in &args.logs {
        let Some((stage, i, n)) = log_name(&args.out, log) else {
            bail!(
                "{}: expected a shard's log of {} ({}.shard-I-of-N.log or {}.stage-K.shard-I-of-N.log)",
                log.display(),
                args.out.display(),
                args.out.display(),
                args.out.display()
            );
        };
        if *count.get_or_insert(n) != n {
            bail!(
                "{}: a log of {n} shards among logs of {}: expected the logs of one sharded build",
                log.display(),
                count.unwrap_or(n)
            );
        }
        steps.entry(stage).or_default().push((i, log));
    }
    let count = count.context("no logs given")?;
    // Every log read and checked first; the build's logs are written only once the
    // merge has found the step complete.
    let mut checked = Vec::new();
    for (&stage, logs) in &steps {
        let main = if stage == 0 {
            press_log(&args.out)
        } else {
            stage_log(&args.out, stage)
        };
        let mut key: Option<(String, PathBuf)> = RecordLog::key_of(&main)
            .with_context(|| format!("reading {}", main.display()))?
            .map(|k| (k, main.clone()));
        let mut records = Vec::new();
        let mut torn = Vec::new();
        for (i, log) in logs {
            let (k, r, t) = RecordLog::read_strict(log)
                .with_context(|| format!("reading {}", log.display()))?;
            match &key {
                Some((first, from)) if *first != k => bail!(
                    "{} is a log of another build than {} (its key `{k}`, that one's `{first}`): \
                     expected logs of one build",
                    log.display(),
                    from.display()
                ),
                Some(_) => {}
                None => key = Some((k, (*log).clone())),
            }
            if t {
                eprintln!(
                    "tissue merge: {}: a torn last record dropped (its press is the shard's to make again)",
                    log.display()
                );
                torn.push(json!({"shard": i, "log": log}));
            }
            records.extend(r);
        }
        if let Some((key, _)) = key {
            checked.push((stage, main, key, records, torn, logs.len()));
        }
    }
    let outcome = build_run(&build, Some(Sharding::Merge(count)))?;
    let commit = || -> anyhow::Result<Vec<serde_json::Value>> {
        let mut merged = Vec::new();
        for (stage, main, key, records, torn, logs) in &checked {
            let (mut log, held) = RecordLog::open_ids(main, key)
                .with_context(|| format!("opening {}", main.display()))?;
            let mut seen: HashSet<u32> = held.into_iter().collect();
            let mut added = 0;
            for (id, body) in records {
                if seen.insert(*id) {
                    log.push_raw(*id, body)
                        .with_context(|| format!("writing {}", main.display()))?;
                    added += 1;
                }
            }
            merged.push(json!({"step": stage + 1, "log": main, "shard_logs": logs,
                "presses_added": added, "torn_records_dropped": torn}));
        }
        Ok(merged)
    };
    match outcome {
        Built::File(_, mut summary) => {
            // Every step is in the file: the shards' logs and the plan go.
            for log in &args.logs {
                let _ = std::fs::remove_file(log);
            }
            let _ = std::fs::remove_file(&plan);
            summary["shards"] = json!(count);
            Ok(summary)
        }
        // Nothing of the step logged: it is the next round's, for the shards.
        Built::Waiting(v) if v["logged"].as_u64() == Some(0) => {
            let merged = commit()?;
            Ok(
                json!({"done": false, "merged": merged, "next_step": v["step"],
                "stage": v["stage"], "presses": v["presses"], "shards": count,
                "message": format!("step {} ({}) goes on: run the {count} shards again, then merge",
                    v["step"], v["stage"].as_str().unwrap_or(""))}),
            )
        }
        Built::Waiting(v) => bail!(
            "not every shard is complete: {}; expected each shard to have finished its presses \
             (run the missing ones again: each goes on from its log)",
            v["message"].as_str().unwrap_or("")
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::args::parse_shard;
    use crate::cli::tissue::build::shard_log;

    #[test]
    fn shards_and_their_logs_are_named_both_ways() {
        assert_eq!(parse_shard("3/8"), Ok(Shard { index: 3, count: 8 }));
        for bad in ["0/4", "5/4", "1/0", "2", "a/b", "-1/3"] {
            let e = parse_shard(bad).expect_err(bad);
            assert!(e.contains("expected I/N"), "{e}");
        }
        let out = Path::new("/x/liver.tissue");
        for (stage, i, n) in [(0, 1, 1), (0, 3, 7), (2, 7, 7)] {
            let log = shard_log(out, stage, Shard { index: i, count: n });
            assert_eq!(
                log_name(out, &log),
                Some((stage, i, n)),
                "{}",
                log.display()
            );
        }
        assert_eq!(
            shard_log(out, 2, Shard { index: 3, count: 4 }),
            Path::new("/x/liver.tissue.stage-2.shard-3-of-4.log")
        );
        for other in [
            "/x/liver.tissue.presses.log",
            "/x/kidney.tissue.shard-1-of-2.log",
            "/x/liver.tissue.shard-3-of-2.log",
        ] {
            assert_eq!(log_name(out, Path::new(other)), None, "{other}");
        }
    }
}
