//! A binary log of finished presses, so that an off-line build made of independent,
//! large records (the tissue build's vertex presses, 0.1–0.2 MB each) goes on after
//! `kill -9` from the last finished one and gives the same file as an uninterrupted
//! run.
//!
//! The file is a first line with the build's key (everything that determines the
//! records), then one frame per finished record:
//!
//! ```text
//! index: u32 LE, length: u32 LE, xxh3-64 of the body: u64 LE, body (bincode, standard)
//! ```
//!
//! Each frame is written whole and synced before the call returns. On opening, frames
//! are read until one is cut short or fails its checksum (the kill's torn write); the
//! file is cut back to the last good frame and appended to from there. A log with
//! another key is started afresh.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Frame header: index, length, checksum.
const HEAD_BYTES: usize = 16;

/// An open log, appended to as records finish.
#[derive(Debug)]
pub struct RecordLog {
    file: File,
}

impl RecordLog {
    /// Opens the log at `path` for a build with `key` and returns it with the records
    /// already finished (none if the file is missing or of another build).
    pub fn open<T: DeserializeOwned>(
        path: &Path,
        key: &str,
    ) -> io::Result<(RecordLog, Vec<(u32, T)>)> {
        let key_line = format!("{}\n", key.replace('\n', " "));
        let bytes = std::fs::read(path).unwrap_or_default();
        let mut records = Vec::new();
        let mut good = 0;
        if bytes.starts_with(key_line.as_bytes()) {
            let mut at = key_line.len();
            good = at;
            while let Some((index, value, next)) = frame::<T>(&bytes, at) {
                records.push((index, value));
                at = next;
                good = next;
            }
        }
        if good == 0 {
            let mut file = File::create(path)?;
            file.write_all(key_line.as_bytes())?;
            file.sync_all()?;
        } else if good < bytes.len() {
            // Drop the torn last frame.
            let file = OpenOptions::new().write(true).open(path)?;
            file.set_len(good as u64)?;
            file.sync_all()?;
        }
        let file = OpenOptions::new().append(true).open(path)?;
        Ok((RecordLog { file }, records))
    }

    /// The indices of the records a log at `path` for `key` holds, read without
    /// changing the file (a build may be appending to it): none where it is missing or
    /// of another build.
    pub fn finished_ids<T: DeserializeOwned>(path: &Path, key: &str) -> io::Result<Vec<u32>> {
        let key_line = format!("{}\n", key.replace('\n', " "));
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(e),
        };
        let mut ids = Vec::new();
        if let Some(mut at) = bytes
            .starts_with(key_line.as_bytes())
            .then_some(key_line.len())
        {
            while let Some((index, _, next)) = frame::<T>(&bytes, at) {
                ids.push(index);
                at = next;
            }
        }
        Ok(ids)
    }

    /// Appends one finished record and syncs it to disk.
    pub fn push<T: Serialize>(&mut self, index: u32, value: &T) -> io::Result<()> {
        let body = bincode::serde::encode_to_vec(value, bincode::config::standard())
            .map_err(io::Error::other)?;
        let len = u32::try_from(body.len())
            .map_err(|_| io::Error::other(format!("a record of {} bytes", body.len())))?;
        let mut out = Vec::with_capacity(HEAD_BYTES + body.len());
        out.extend(index.to_le_bytes());
        out.extend(len.to_le_bytes());
        out.extend(xxhash_rust::xxh3::xxh3_64(&body).to_le_bytes());
        out.extend(body);
        self.file.write_all(&out)?;
        self.file.sync_data()
    }
}

/// The frame at `at`: its index, value and the offset after it; `None` when it is cut
/// short, fails its checksum or does not decode.
fn frame<T: DeserializeOwned>(bytes: &[u8], at: usize) -> Option<(u32, T, usize)> {
    let head = bytes.get(at..at + HEAD_BYTES)?;
    let word = |k: usize| u32::from_le_bytes(head[k..k + 4].try_into().expect("4 bytes"));
    let (index, len) = (word(0), word(4) as usize);
    let sum = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
    let body = bytes.get(at + HEAD_BYTES..at + HEAD_BYTES + len)?;
    if xxhash_rust::xxh3::xxh3_64(body) != sum {
        return None;
    }
    let (value, used) =
        bincode::serde::decode_from_slice(body, bincode::config::standard()).ok()?;
    (used == len).then_some((index, value, at + HEAD_BYTES + len))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_come_back_exactly_and_a_torn_frame_is_dropped() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("build.presses.log");
        let (mut log, old) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("open");
        assert!(old.is_empty());
        let a = vec![1.0f32 / 3.0, -0.0, f32::MIN_POSITIVE];
        log.push(7, &a).expect("push");
        log.push(2, &Vec::<f32>::new()).expect("push");
        log.push(9, &vec![5.0f32; 1000]).expect("push");
        drop(log);
        // A kill in the middle of the third frame.
        let full = std::fs::metadata(&path).expect("meta").len();
        let f = OpenOptions::new().write(true).open(&path).expect("f");
        f.set_len(full - 100).expect("torn");
        drop(f);
        let (mut log, old) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("reopen");
        assert_eq!(old, vec![(7, a.clone()), (2, vec![])]);
        assert_eq!(old[0].1[1].to_bits(), (-0.0f32).to_bits());
        // Appending goes on after the last good frame.
        log.push(9, &vec![6.0f32; 3]).expect("push");
        drop(log);
        let (log, old) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("reopen");
        assert_eq!(old.len(), 3);
        assert_eq!(old[2], (9, vec![6.0; 3]));
        drop(log);
        // A flipped byte in a body ends the log there.
        let mut bytes = std::fs::read(&path).expect("read");
        let k = "key a\n".len() + HEAD_BYTES + 2;
        bytes[k] ^= 1;
        std::fs::write(&path, &bytes).expect("write");
        let (log, old) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("reopen");
        assert!(old.is_empty(), "{old:?}");
        drop(log);
        let (log, old) = RecordLog::open::<Vec<f32>>(&path, "key b").expect("other build");
        assert!(old.is_empty(), "another build's records are not taken");
        drop(log);
        assert_eq!(std::fs::read(&path).expect("read"), b"key b\n");
    }

    /// Listing a log's ids reads it as opening does (a torn last frame left out,
    /// another build's log empty) and leaves the file byte for byte as it was.
    #[test]
    fn finished_ids_read_without_touching_the_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("build.presses.log");
        let ids = |key: &str| RecordLog::finished_ids::<Vec<f32>>(&path, key).expect("ids");
        assert!(ids("key a").is_empty(), "a missing log holds nothing");
        assert!(!path.exists(), "and is not created");
        let (mut log, _) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("open");
        log.push(4, &vec![1.0f32; 10]).expect("push");
        log.push(1, &vec![2.0f32; 10]).expect("push");
        drop(log);
        let full = std::fs::read(&path).expect("read");
        // A build killed in the middle of its third frame.
        let mut torn = full.clone();
        let first = "key a\n".len();
        torn.extend(&full[first..first + HEAD_BYTES + 5]);
        std::fs::write(&path, &torn).expect("write");
        assert_eq!(ids("key a"), vec![4, 1]);
        assert!(ids("key b").is_empty());
        assert_eq!(std::fs::read(&path).expect("read"), torn, "left as it was");
    }
}
