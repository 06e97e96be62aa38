//! The build's presses: logged as each finishes, so a killed build goes on.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::organ::OrganMesh;
use crate::tissue::options::{PressCount, SurfaceLawBuildError, SurfaceLawOptions, VertexPress};
use crate::tissue::press::{Pressing, path_options};
use crate::tissue::presslog::RecordLog;

/// A surface point to press: where, along what, and its id in the press log.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PressPoint {
    pub(crate) at: [f64; 3],
    pub(crate) push: [f64; 3],
    pub(crate) id: u32,
}

/// A logged press: what [`Pressing::point_press_prepared`] gave at one log id.
pub(super) type Logged = Result<VertexPress, String>;

/// One of `count` shards of a build (`index` from 1): each call's presses are dealt to
/// the shards in turn, in the call's own order (a stage's presses cost alike, so turns
/// balance them), so every shard that sees the same earlier presses deals alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// The shard (from 1) that presses the `k`-th press of a call.
    pub fn owner(count: u32, k: usize) -> u32 {
        (k % count as usize) as u32 + 1
    }
}

/// How a sharded build runs: a shard presses its own presses into its own log; the
/// merge presses none and reads the build's log and the shards' (`logs`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShardRun {
    Press { shard: Shard, own_log: PathBuf },
    Merge { count: u32, logs: Vec<PathBuf> },
}

/// Where a build's presses are logged: its log at `path`, and where it is sharded, how
/// (a shard and the merge read the log at `path` and do not write it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PressLog {
    pub path: PathBuf,
    pub shard: Option<ShardRun>,
}

impl PressLog {
    /// One log, written as the presses finish.
    pub fn at(path: &Path) -> PressLog {
        PressLog {
            path: path.to_path_buf(),
            shard: None,
        }
    }

    /// The shards and which one this run is (index 0: the merge, pressing none).
    fn shard(&self) -> Option<Shard> {
        match &self.shard {
            None => None,
            Some(ShardRun::Press { shard, .. }) => Some(*shard),
            Some(ShardRun::Merge { count, .. }) => Some(Shard {
                index: 0,
                count: *count,
            }),
        }
    }
}

/// What [`open_press_log`] opens: the log to append to and its path, the shards, and
/// the presses already logged.
pub(super) type Opened = (
    Option<(RecordLog, PathBuf)>,
    Option<Shard>,
    Vec<(u32, Logged)>,
);

/// Opens a build's press log (see [`crate::tissue::presslog`]) and returns the log to
/// append to (a shard's own; none for the merge, which presses nothing), the shards,
/// and the presses already logged (a shard's: the build's log's and its own). The key
/// names everything that determines a press, so a build and a refinement of the same
/// options share their presses (a covering build's key also names its vertices: its
/// edge ids count its own edges).
pub(super) fn open_press_log(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    cover: Option<&[u32]>,
    log: &PressLog,
) -> Result<Opened, SurfaceLawBuildError> {
    let log_error = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SurfaceLawBuildError::Log { path, source }
    };
    let key = press_log_key(organ, o, rows, cover);
    match &log.shard {
        None => {
            let (l, r) =
                RecordLog::open::<Logged>(&log.path, &key).map_err(log_error(&log.path))?;
            Ok((Some((l, log.path.clone())), None, r))
        }
        Some(run) => {
            let mut records =
                RecordLog::read::<Logged>(&log.path, &key).map_err(log_error(&log.path))?;
            let own = match run {
                ShardRun::Press { own_log, .. } => {
                    let (l, r) =
                        RecordLog::open::<Logged>(own_log, &key).map_err(log_error(own_log))?;
                    records.extend(r);
                    Some((l, own_log.clone()))
                }
                ShardRun::Merge { logs, .. } => {
                    for l in logs {
                        records.extend(RecordLog::read::<Logged>(l, &key).map_err(log_error(l))?);
                    }
                    None
                }
            };
            Ok((own, log.shard(), records))
        }
    }
}

/// The ids a build's press log at `path` already holds, read without changing it
/// (none where it is missing or of another build).
pub(crate) fn logged_press_ids(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    path: &Path,
) -> Result<Vec<u32>, SurfaceLawBuildError> {
    let key = press_log_key(organ, o, rows, None);
    RecordLog::finished_ids::<Logged>(path, &key).map_err(|source| SurfaceLawBuildError::Log {
        path: path.to_path_buf(),
        source,
    })
}

/// A build's press-log key: everything that determines its presses (the code's
/// version, the organ mesh's fingerprint, the rows, the options and the way a press is
/// followed, serialized and hashed, and a covering build's vertices).
fn press_log_key(
    organ: &OrganMesh,
    o: &SurfaceLawOptions,
    rows: usize,
    cover: Option<&[u32]>,
) -> String {
    let po = path_options(o);
    let covered = cover.map_or(String::new(), |c| {
        let bytes: Vec<u8> = c.iter().flat_map(|v| v.to_le_bytes()).collect();
        format!(
            " cover {} {:016x}",
            c.len(),
            xxhash_rust::xxh3::xxh3_64(&bytes)
        )
    });
    let options = bincode::serde::encode_to_vec((o, &po), bincode::config::standard())
        .expect("plain numbers and flags always encode");
    format!(
        "palpa tissue-build log {LOG_VERSION} palpa {} mesh {:016x} rows {rows} options {:016x}{covered}",
        env!("CARGO_PKG_VERSION"),
        organ.fingerprint(),
        xxhash_rust::xxh3::xxh3_64(&options),
    )
}

/// The press log's own version: a record's layout ([`Logged`]) and what a press's
/// answer means. A log of another version is started afresh.
const LOG_VERSION: u32 = 8;

/// Presses a task expands together (see [`Presser::press`]).
const PRESS_BATCH: usize = crate::fe::series::SOLVE_WIDTH;

/// Presses surface points in parallel, logging each as it finishes and reporting
/// progress (see [`PressCount`]).
pub(super) struct Presser<'a> {
    pub(super) pressing: Pressing<'a>,
    pub(super) rows: &'a [u32],
    pub(super) steps: usize,
    pub(super) log: Option<(&'a Mutex<RecordLog>, &'a Path)>,
    /// Where the build is sharded: which presses are this run's.
    pub(super) shard: Option<Shard>,
    pub(super) done: std::sync::atomic::AtomicUsize,
    pub(super) from_log: std::sync::atomic::AtomicUsize,
    pub(super) progress: &'a (dyn Fn(PressCount) + Sync),
}

impl Presser<'_> {
    /// Presses `points` (those in `finished` taken from it) and returns their presses
    /// in order and how many came from the log; `total` is what the progress counts
    /// to.
    pub(super) fn press(
        &self,
        points: &[PressPoint],
        finished: &mut HashMap<u32, Logged>,
        total: usize,
    ) -> Result<(Vec<Logged>, usize), SurfaceLawBuildError> {
        use rayon::prelude::*;
        use std::sync::atomic::Ordering;
        let mut out: Vec<Option<Logged>> = points.iter().map(|p| finished.remove(&p.id)).collect();
        let resumed = out.iter().filter(|p| p.is_some()).count();
        let logged = self.from_log.fetch_add(resumed, Ordering::Relaxed) + resumed;
        (self.progress)(PressCount {
            done: self.done.fetch_add(resumed, Ordering::Relaxed) + resumed,
            total,
            from_log: logged,
        });
        let mut todo: Vec<usize> = (0..points.len()).filter(|&k| out[k].is_none()).collect();
        // A shard presses its own; what the others press is waited for.
        let mut waiting: Vec<(u32, Vec<u32>)> = Vec::new();
        if let Some(shard) = self.shard {
            for &k in todo
                .iter()
                .filter(|&&k| Shard::owner(shard.count, k) != shard.index)
            {
                let owner = Shard::owner(shard.count, k);
                match waiting.iter_mut().find(|w| w.0 == owner) {
                    Some(w) => w.1.push(points[k].id),
                    None => waiting.push((owner, vec![points[k].id])),
                }
            }
            waiting.sort_unstable_by_key(|w| w.0);
            todo.retain(|&k| Shard::owner(shard.count, k) == shard.index);
        }
        // A few presses a task, taken in `points`' order: their rest series are
        // expanded together (one pass over the rest factor solves all of them), then
        // each is followed and logged in turn. Few, because a task's presses run on
        // one core: a split range would have each thread press a long run in turn (a
        // build's last run, presses of minutes on medium P2, went on on one core while
        // the other sat idle), and an interrupted build would leave the log holding
        // two fronts rather than the first presses. A press's numbers do not depend on
        // its batch (`fe::series::rest_orders_batch`).
        let computed: Vec<Vec<(usize, Logged)>> = todo
            .chunks(PRESS_BATCH)
            .par_bridge()
            .map(|batch| -> Result<_, SurfaceLawBuildError> {
                crate::cpu::clear_upper_halves();
                let at: Vec<_> = batch
                    .iter()
                    .map(|&k| (points[k].at, points[k].push))
                    .collect();
                let prepared = self.pressing.prepare(&at)?;
                let mut done = Vec::with_capacity(batch.len());
                for (&k, prepared) in batch.iter().zip(prepared) {
                    let p = &points[k];
                    let press = self
                        .pressing
                        .point_press_prepared(self.rows, self.steps, prepared)?;
                    if let Some((l, path)) = self.log {
                        // Off-line and once a press (seconds): a lock is fine here.
                        let mut l = l.lock().unwrap_or_else(|p| p.into_inner());
                        l.push(p.id, &press)
                            .map_err(|source| SurfaceLawBuildError::Log {
                                path: path.to_path_buf(),
                                source,
                            })?;
                    }
                    (self.progress)(PressCount {
                        done: self.done.fetch_add(1, Ordering::Relaxed) + 1,
                        total,
                        from_log: logged,
                    });
                    done.push((k, press));
                }
                Ok(done)
            })
            .collect::<Result<_, _>>()?;
        let pressed = computed.iter().map(Vec::len).sum::<usize>();
        if let (Some(shard), false) = (self.shard, waiting.is_empty()) {
            return Err(SurfaceLawBuildError::ShardWaiting {
                index: shard.index,
                count: shard.count,
                pressed,
                present: resumed,
                total: points.len(),
                waiting,
            });
        }
        for (k, press) in computed.into_iter().flatten() {
            out[k] = Some(press);
        }
        let out = out
            .into_iter()
            .map(|p| p.expect("every point is pressed"))
            .collect();
        Ok((out, resumed))
    }
}

/// The per-sample arrays as the build fills them (vertices, edges, quarter points,
/// inner points).
#[derive(Default)]
pub(super) struct Stored {
    pub(super) residual: Vec<f32>,
    pub(super) ratio: Vec<f64>,
    pub(super) stiffness: Vec<f64>,
    pub(super) correction: Vec<f64>,
    pub(super) segments: Vec<u32>,
    pub(super) reach: Vec<u32>,
    pub(super) stopped: Vec<String>,
}

impl Stored {
    /// The samples from `first` on, taken off (`n_row` residual values a sample).
    pub(super) fn split_off(&mut self, first: usize, steps: usize, n_row: usize) -> Stored {
        Stored {
            residual: self.residual.split_off(first * n_row),
            ratio: self.ratio.split_off(first * steps),
            stiffness: self.stiffness.split_off(first),
            correction: self.correction.split_off(first),
            segments: self.segments.split_off(first),
            reach: self.reach.split_off(first),
            stopped: self.stopped.split_off(first),
        }
    }

    /// Appends `from`'s sample `s` as it is.
    pub(super) fn copy(&mut self, from: &Stored, s: usize, steps: usize, row: usize) {
        let n = steps * row;
        self.residual
            .extend_from_slice(&from.residual[s * n..][..n]);
        self.ratio
            .extend_from_slice(&from.ratio[s * steps..][..steps]);
        self.stiffness.push(from.stiffness[s]);
        self.correction.push(from.correction[s]);
        self.segments.push(from.segments[s]);
        self.reach.push(from.reach[s]);
        self.stopped.push(from.stopped[s].clone());
    }

    pub(super) fn push(
        &mut self,
        p: &VertexPress,
        residual: &[f32],
        ratio: &[f64],
        reach: u32,
        why: String,
    ) {
        self.residual.extend_from_slice(residual);
        self.ratio.extend_from_slice(ratio);
        self.stiffness.push(p.stiffness_n_per_mm);
        self.correction.push(p.correction_mm);
        self.segments.push(p.segments);
        self.reach.push(reach);
        self.stopped.push(why);
    }

    /// The reason of whichever of `p` and the stored samples `others` stopped first
    /// (empty where none stopped short).
    fn first_stop(&self, p: &VertexPress, others: &[usize]) -> String {
        std::iter::once((p.reach, &p.stopped))
            .chain(others.iter().map(|&s| (self.reach[s], &self.stopped[s])))
            .min_by_key(|(r, _)| *r)
            .map_or(String::new(), |(_, w)| w.clone())
    }

    /// `p`'s surplus over the blend `base` of stored samples, up to the depth all of
    /// them reached and held there: residual, ratio, reach and why it stopped.
    pub(super) fn surplus(
        &self,
        p: &VertexPress,
        base: &[(usize, f64)],
        steps: usize,
        row: usize,
    ) -> (Vec<f32>, Vec<f64>, u32, String) {
        let r = base.iter().fold(p.reach, |r, &(s, _)| r.min(self.reach[s])) as usize;
        let n = steps * row;
        let residual = (0..n)
            .map(|i| {
                let i = (i / row).min(r - 1) * row + i % row;
                let b: f64 = base
                    .iter()
                    .map(|&(s, w)| w * f64::from(self.residual[s * n + i]))
                    .sum();
                (f64::from(p.residual[i]) - b) as f32
            })
            .collect();
        let ratio = (0..steps)
            .map(|j| {
                let j = j.min(r - 1);
                let b: f64 = base
                    .iter()
                    .map(|&(s, w)| w * self.ratio[s * steps + j])
                    .sum();
                p.ratio[j] - b
            })
            .collect();
        let others: Vec<usize> = base.iter().map(|b| b.0).collect();
        (residual, ratio, r as u32, self.first_stop(p, &others))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::organ::Level;
    use crate::organ::catalogue::{OrganName, mesh};

    /// The key names what determines a press and nothing else: another option, rows
    /// or cover is another key; the same ones the same key.
    #[test]
    fn the_key_changes_with_what_determines_a_press() {
        let organ = mesh(OrganName::Liver, Level::Coarse);
        let o = SurfaceLawOptions::default();
        let key = press_log_key(&organ, &o, 10, None);
        assert!(key.starts_with("palpa tissue-build log 8 palpa "), "{key}");
        assert_eq!(press_log_key(&organ, &o, 10, None), key);
        assert_ne!(press_log_key(&organ, &o, 11, None), key);
        assert_ne!(press_log_key(&organ, &o, 10, Some(&[1, 2])), key);
        let deeper = SurfaceLawOptions {
            depth_max_mm: o.depth_max_mm + 1.0,
            ..o
        };
        assert_ne!(press_log_key(&organ, &deeper, 10, None), key);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("x.tissue.presses.log");
        let (mut log, _) = RecordLog::open::<Logged>(&path, &key).expect("open");
        log.push(5, &Logged::Err("held".into())).expect("push");
        drop(log);
        assert_eq!(logged_press_ids(&organ, &o, 10, &path).expect("ids"), [5]);
        assert!(
            logged_press_ids(&organ, &o, 11, &path)
                .expect("ids")
                .is_empty()
        );
    }
}
