//! Atomic file writes: nothing already saved is lost and no half-written file ever
//! appears under the final name.
//!
//! The data goes to a temporary file in the destination's folder (same file system, so
//! the rename is atomic), is flushed and `fsync`ed, then renamed over the destination;
//! on Unix the folder is `fsync`ed too so the rename itself survives a power cut. If
//! anything fails, the temporary file is removed, the destination is untouched and the
//! error says so. A temporary file left by a process that was killed (`kill -9` gives
//! it no chance to clean up) is removed by the next write to the same destination.
//!
//! A full disk can be simulated for tests: with `PALPA_FAULT_DISK_FULL_AFTER_BYTES=N`
//! in the environment, a write of more than `N` bytes fails as `ENOSPC` would, after
//! the bytes went to the temporary file and before the rename.

use std::fs::{self, File};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The environment variable that simulates a full disk (see the module doc).
pub const FAULT_DISK_FULL_ENV: &str = "PALPA_FAULT_DISK_FULL_AFTER_BYTES";

fn temp_prefix(dest: &Path) -> String {
    let name = dest
        .file_name()
        .map_or_else(|| "palpa".into(), |n| n.to_string_lossy().into_owned());
    format!(".{name}.tmp-")
}

fn temp_path(dest: &Path) -> PathBuf {
    let unique = format!(
        "{}{}-{}",
        temp_prefix(dest),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    dest.with_file_name(unique)
}

/// Removes temporary files of `dest` whose writer process no longer runs.
fn sweep_stale_temps(dest: &Path) {
    let prefix = temp_prefix(dest);
    let dir = match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !process_alive(pid) {
            let _ = fs::remove_file(entry.path());
        }
    }
}

#[cfg(target_os = "linux")]
fn process_alive(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

/// Without `/proc`, a process is assumed alive: a stale file is left rather than a
/// running writer's file removed.
#[cfg(not(target_os = "linux"))]
fn process_alive(_pid: u32) -> bool {
    true
}

fn injected_disk_full(written: u64) -> io::Result<()> {
    let limit = std::env::var(FAULT_DISK_FULL_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok());
    match limit {
        Some(n) if written > n => Err(io::Error::from_raw_os_error(28)),
        _ => Ok(()),
    }
}

/// Writes `dest` atomically with the bytes `write` produces.
pub fn atomic_write<F>(dest: &Path, write: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    sweep_stale_temps(dest);
    let tmp = temp_path(dest);
    let result = (|| -> io::Result<()> {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w)?;
        let file = w.into_inner().map_err(io::IntoInnerError::into_error)?;
        injected_disk_full(file.metadata()?.len())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, dest)?;
        sync_parent(dest);
        Ok(())
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        let kept = if dest.exists() {
            "the file already there is kept unchanged"
        } else {
            "nothing was written"
        };
        return Err(io::Error::new(e.kind(), format!("{e} ({kept})")));
    }
    Ok(())
}

#[cfg(unix)]
fn sync_parent(dest: &Path) {
    let parent = match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    // Best effort: the data is already durable; this makes the rename durable too.
    if let Ok(dir) = File::open(parent) {
        let _ = dir.sync_all();
    }
}

#[cfg(not(unix))]
fn sync_parent(_dest: &Path) {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn failed_write_keeps_the_old_file_and_leaves_no_temp() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dest = dir.path().join("model.palpa");
        atomic_write(&dest, |w| w.write_all(b"old")).expect("first write");
        let err = atomic_write(&dest, |w| {
            w.write_all(b"half of the new")?;
            Err(io::Error::other("interrupted"))
        });
        assert!(err.is_err());
        assert_eq!(fs::read(&dest).expect("read"), b"old");
        let names: Vec<_> = fs::read_dir(dir.path())
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("model.palpa")]);
    }

    #[test]
    fn a_killed_writers_temp_file_is_swept_by_the_next_write() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dest = dir.path().join("model.palpa");
        // No process has pid u32::MAX − 1 on Linux (pid_max ≤ 2²²).
        let stale = dir.path().join(".model.palpa.tmp-4294967294-0");
        fs::write(&stale, b"half").expect("stale");
        let other = dir.path().join(".other.palpa.tmp-4294967294-0");
        fs::write(&other, b"not ours").expect("other");
        atomic_write(&dest, |w| w.write_all(b"new")).expect("write");
        assert_eq!(fs::read(&dest).expect("read"), b"new");
        assert_eq!(stale.exists(), !cfg!(target_os = "linux"));
        assert!(
            other.exists(),
            "another destination's temp file is left alone"
        );
    }

    #[test]
    fn the_error_says_the_old_file_is_kept() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dest = dir.path().join("model.palpa");
        atomic_write(&dest, |w| w.write_all(b"old")).expect("first write");
        let err =
            atomic_write(&dest, |_| Err(io::Error::from_raw_os_error(28))).expect_err("fails");
        assert_eq!(err.raw_os_error(), None);
        assert_eq!(err.kind(), io::ErrorKind::StorageFull);
        assert!(err.to_string().contains("kept unchanged"), "{err}");
    }
}
