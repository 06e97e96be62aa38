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

/// A log read strictly: its key line, its records (index, body as written), and
/// whether a torn last frame was dropped.
pub type StrictRead = (String, Vec<(u32, Vec<u8>)>, bool);

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
        Self::open_with(path, key, frame::<T>)
    }

    /// [`open`](Self::open) for a caller that copies records without reading them: the
    /// log and the indices it holds (frames checked by their checksums only).
    pub fn open_ids(path: &Path, key: &str) -> io::Result<(RecordLog, Vec<u32>)> {
        let (log, records) = Self::open_with(path, key, |b, at| {
            raw_frame(b, at).map(|(index, _, next)| (index, (), next))
        })?;
        Ok((log, records.into_iter().map(|(index, ())| index).collect()))
    }

    /// [`open`](Self::open) with the frames read by `frame`: the good frames kept, a
    /// torn last one cut off, a log of another key started afresh.
    fn open_with<R>(
        path: &Path,
        key: &str,
        frame: impl Fn(&[u8], usize) -> Option<(u32, R, usize)>,
    ) -> io::Result<(RecordLog, Vec<(u32, R)>)> {
        let key_line = format!("{}\n", key.replace('\n', " "));
        let bytes = std::fs::read(path).unwrap_or_default();
        let mut records = Vec::new();
        let mut good = 0;
        if bytes.starts_with(key_line.as_bytes()) {
            let mut at = key_line.len();
            good = at;
            while let Some((index, value, next)) = frame(&bytes, at) {
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

    /// The records a log at `path` for `key` holds, read without changing the file (as
    /// [`open`](Self::open) reads them: a torn last frame left out; none where the file
    /// is missing or of another build).
    pub fn read<T: DeserializeOwned>(path: &Path, key: &str) -> io::Result<Vec<(u32, T)>> {
        let key_line = format!("{}\n", key.replace('\n', " "));
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(e),
        };
        let mut records = Vec::new();
        if bytes.starts_with(key_line.as_bytes()) {
            let mut at = key_line.len();
            while let Some((index, value, next)) = frame::<T>(&bytes, at) {
                records.push((index, value));
                at = next;
            }
        }
        Ok(records)
    }

    /// A whole log read strictly, for merging logs written elsewhere: its key line, its
    /// records' indices and bodies as written (each body checked against its checksum,
    /// not decoded), and whether a torn last frame (one cut short by the end of the
    /// file, a kill's interrupted write) was dropped. A frame that fails its checksum
    /// with more of the file after it is corruption, an error naming its offset; so is
    /// a file without a key line.
    pub fn read_strict(path: &Path) -> io::Result<StrictRead> {
        let bytes = std::fs::read(path)?;
        let bad = |why: String| io::Error::new(io::ErrorKind::InvalidData, why);
        let Some(end) = bytes.iter().position(|&b| b == b'\n') else {
            return Err(bad("no key line: expected a press log".into()));
        };
        let key = std::str::from_utf8(&bytes[..end])
            .map_err(|_| bad("its key line is not text: expected a press log".into()))?
            .to_string();
        let mut at = end + 1;
        let mut records = Vec::new();
        while at < bytes.len() {
            match raw_frame(&bytes, at) {
                Some((index, body, next)) => {
                    records.push((index, body.to_vec()));
                    at = next;
                }
                None => {
                    // Cut short by the end of the file: the last write, torn.
                    let reaches_end = bytes.get(at + 4..at + 8).is_none_or(|w| {
                        let len = u32::from_le_bytes(w.try_into().expect("4 bytes")) as usize;
                        at + HEAD_BYTES + len >= bytes.len()
                    });
                    if reaches_end {
                        return Ok((key, records, true));
                    }
                    return Err(bad(format!(
                        "the record at byte {at} (after {} good ones) fails its checksum, and \
                         more follows: expected a log as a build writes it",
                        records.len()
                    )));
                }
            }
        }
        Ok((key, records, false))
    }

    /// Appends a record's body as another log held it (see
    /// [`read_strict`](Self::read_strict)) and syncs it to disk.
    pub fn push_raw(&mut self, index: u32, body: &[u8]) -> io::Result<()> {
        let len = u32::try_from(body.len())
            .map_err(|_| io::Error::other(format!("a record of {} bytes", body.len())))?;
        let mut out = Vec::with_capacity(HEAD_BYTES + body.len());
        out.extend(index.to_le_bytes());
        out.extend(len.to_le_bytes());
        out.extend(xxhash_rust::xxh3::xxh3_64(body).to_le_bytes());
        out.extend(body);
        self.file.write_all(&out)?;
        self.file.sync_data()
    }

    /// The key line of the log at `path` (without its newline), or `None` where there
    /// is no log there.
    pub fn key_of(path: &Path) -> io::Result<Option<String>> {
        match std::fs::read(path) {
            Ok(bytes) => {
                let end = bytes
                    .iter()
                    .position(|&b| b == b'\n')
                    .unwrap_or(bytes.len());
                Ok(Some(String::from_utf8_lossy(&bytes[..end]).into_owned()))
            }
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e),
        }
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

/// The frame at `at`: its index, body and the offset after it; `None` when it is cut
/// short or fails its checksum.
fn raw_frame(bytes: &[u8], at: usize) -> Option<(u32, &[u8], usize)> {
    let head = bytes.get(at..at + HEAD_BYTES)?;
    let word = |k: usize| u32::from_le_bytes(head[k..k + 4].try_into().expect("4 bytes"));
    let (index, len) = (word(0), word(4) as usize);
    let sum = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
    let body = bytes.get(at + HEAD_BYTES..at + HEAD_BYTES + len)?;
    (xxhash_rust::xxh3::xxh3_64(body) == sum).then_some((index, body, at + HEAD_BYTES + len))
}

/// The frame at `at`: its index, value and the offset after it; `None` when it is cut
/// short, fails its checksum or does not decode.
fn frame<T: DeserializeOwned>(bytes: &[u8], at: usize) -> Option<(u32, T, usize)> {
    let (index, body, next) = raw_frame(bytes, at)?;
    let len = body.len();
    let (value, used) =
        bincode::serde::decode_from_slice(body, bincode::config::standard()).ok()?;
    (used == len).then_some((index, value, next))
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

    /// A strict read keeps every record, drops a torn last frame and says so, and
    /// refuses a damaged frame with more after it, naming its offset.
    #[test]
    fn a_strict_read_tells_a_torn_end_from_corruption() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("x.log");
        let (mut log, _) = RecordLog::open::<Vec<f32>>(&path, "key a").expect("open");
        for i in 0..3 {
            log.push(i, &vec![i as f32; 50]).expect("push");
        }
        drop(log);
        let full = std::fs::read(&path).expect("read");
        let (key, records, torn) = RecordLog::read_strict(&path).expect("reads");
        assert_eq!((key.as_str(), records.len(), torn), ("key a", 3, false));
        // Copied record by record into another log, the same bytes.
        let copy = dir.path().join("y.log");
        let (mut log, _) = RecordLog::open::<Vec<f32>>(&copy, "key a").expect("open");
        for (i, body) in &records {
            log.push_raw(*i, body).expect("push");
        }
        drop(log);
        assert_eq!(std::fs::read(&copy).expect("read"), full);
        std::fs::write(&path, &full[..full.len() - 30]).expect("write");
        let (_, records, torn) = RecordLog::read_strict(&path).expect("reads");
        assert_eq!((records.len(), torn), (2, true));
        let mut bad = full.clone();
        bad["key a\n".len() + HEAD_BYTES + 3] ^= 1;
        std::fs::write(&path, &bad).expect("write");
        let e = RecordLog::read_strict(&path).expect_err("corrupt");
        assert!(
            e.to_string()
                .contains("the record at byte 6 (after 0 good ones)"),
            "{e}"
        );
        assert_eq!(
            RecordLog::read::<Vec<f32>>(&path, "key a")
                .expect("tolerant")
                .len(),
            0
        );
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
