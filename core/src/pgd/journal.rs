//! An append-only journal of PGD terms, so an interrupted off-line solve (even by
//! `kill -9`) resumes losing at most the term in progress.
//!
//! Layout: magic `PALPAJR1`, u64 length + bytes of a setup description (resuming with
//! a different setup is refused), then one record per term:
//! `u64 payload length | payload | u64 xxh3(payload)`, payload =
//! `f64 residual, u64 n, n × f64 X_k (free dofs), u64 m, m × f64 y_k`.
//! Each record is flushed and fsynced before the next term starts. On reading, a
//! trailing partial or corrupt record (the one being written when the process died)
//! is dropped and the file truncated to the last good record.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::Path;

use xxhash_rust::xxh3::xxh3_64;

use super::linear::Terms;

/// The first bytes of a journal.
pub const MAGIC: &[u8; 8] = b"PALPAJR1";

/// An open journal, positioned for appending.
#[derive(Debug)]
pub struct Journal {
    file: File,
}

fn bad(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg)
}

impl Journal {
    /// Creates a new journal (replacing any old one) for `setup`.
    pub fn create(path: &Path, setup: &str) -> io::Result<Journal> {
        let mut file = File::create(path)?;
        file.write_all(MAGIC)?;
        file.write_all(&(setup.len() as u64).to_le_bytes())?;
        file.write_all(setup.as_bytes())?;
        file.sync_all()?;
        Ok(Journal { file })
    }

    /// Opens an existing journal written for the same `setup`, returning the terms it
    /// holds (`kx`, `ftx` left empty: the caller recomputes them) and truncating a
    /// partial last record. Terms computed together in blocks of `whole` are kept only
    /// as whole blocks (a block interrupted while being appended is dropped), so a
    /// resumed run partitions the remaining terms as the uninterrupted one did.
    pub fn resume(path: &Path, setup: &str, whole: usize) -> io::Result<(Journal, Terms)> {
        let mut file = OpenOptions::new().read(true).write(true).open(path)?;
        let len = file.metadata()?.len();
        let mut magic = [0u8; 8];
        file.read_exact(&mut magic)?;
        if &magic != MAGIC {
            return Err(bad(format!("{}: not a palpa PGD journal", path.display())));
        }
        let mut u = [0u8; 8];
        file.read_exact(&mut u)?;
        let slen = u64::from_le_bytes(u);
        if slen > len {
            return Err(bad(format!("{}: corrupt journal header", path.display())));
        }
        let mut s = vec![0u8; slen as usize];
        file.read_exact(&mut s)?;
        if s != setup.as_bytes() {
            return Err(bad(format!(
                "{}: journal was written for another setup:\n  journal: {}\n  now:     {setup}",
                path.display(),
                String::from_utf8_lossy(&s)
            )));
        }
        let mut terms = Terms::default();
        let mut good_end = file.stream_position()?;
        let mut ends = vec![good_end];
        loop {
            let mut u = [0u8; 8];
            if file.read_exact(&mut u).is_err() {
                break;
            }
            let plen = u64::from_le_bytes(u);
            if plen > len - good_end {
                break; // Partial record.
            }
            let mut payload = vec![0u8; plen as usize];
            if file.read_exact(&mut payload).is_err() || file.read_exact(&mut u).is_err() {
                break;
            }
            if xxh3_64(&payload) != u64::from_le_bytes(u) {
                break; // Torn write.
            }
            let Some((res, x, y)) = decode(&payload) else {
                break;
            };
            terms.residual_per_mode.push(res);
            terms.x.push(x);
            terms.y.push(y);
            terms.fixed_point_iterations.push(0);
            terms.seconds_per_mode.push(0.0);
            good_end = file.stream_position()?;
            ends.push(good_end);
        }
        let keep = terms.x.len() / whole.max(1) * whole.max(1);
        terms.residual_per_mode.truncate(keep);
        terms.x.truncate(keep);
        terms.y.truncate(keep);
        terms.fixed_point_iterations.truncate(keep);
        terms.seconds_per_mode.truncate(keep);
        good_end = ends[keep];
        file.set_len(good_end)?;
        file.seek(SeekFrom::Start(good_end))?;
        Ok((Journal { file }, terms))
    }

    /// Appends term `k` of `t` and makes it durable.
    pub fn append(&mut self, t: &Terms, k: usize) -> io::Result<()> {
        let mut p = Vec::with_capacity(8 * (t.x[k].len() + t.y[k].len() + 3));
        p.extend_from_slice(&t.residual_per_mode[k].to_le_bytes());
        p.extend_from_slice(&(t.x[k].len() as u64).to_le_bytes());
        p.extend_from_slice(bytemuck::cast_slice(&t.x[k]));
        p.extend_from_slice(&(t.y[k].len() as u64).to_le_bytes());
        p.extend_from_slice(bytemuck::cast_slice(&t.y[k]));
        self.file.write_all(&(p.len() as u64).to_le_bytes())?;
        self.file.write_all(&p)?;
        self.file.write_all(&xxh3_64(&p).to_le_bytes())?;
        self.file.sync_data()
    }
}

fn decode(p: &[u8]) -> Option<(f64, Vec<f64>, Vec<f64>)> {
    let f = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("callers slice exactly 8 bytes"));
    let u = |b: &[u8]| {
        u64::from_le_bytes(b.try_into().expect("callers slice exactly 8 bytes")) as usize
    };
    if p.len() < 16 {
        return None;
    }
    let res = f(&p[0..8]);
    let n = u(&p[8..16]);
    let xend = 16usize.checked_add(n.checked_mul(8)?)?;
    if p.len() < xend + 8 {
        return None;
    }
    let m = u(&p[xend..xend + 8]);
    let yend = (xend + 8).checked_add(m.checked_mul(8)?)?;
    if p.len() != yend {
        return None;
    }
    let x = p[16..xend].chunks_exact(8).map(f).collect();
    let y = p[xend + 8..yend].chunks_exact(8).map(f).collect();
    Some((res, x, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_torn_last_record_is_dropped_and_the_rest_kept() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("j");
        let mut t = Terms::default();
        let mut j = Journal::create(&p, "setup A").expect("create");
        for k in 0..3 {
            t.x.push(vec![k as f64; 5]);
            t.y.push(vec![-(k as f64); 4]);
            t.residual_per_mode.push(0.1 * k as f64);
            j.append(&t, k).expect("append");
        }
        drop(j);
        // Simulate a crash in the middle of the third record.
        let len = std::fs::metadata(&p).expect("meta").len();
        OpenOptions::new()
            .write(true)
            .open(&p)
            .expect("open")
            .set_len(len - 20)
            .expect("cut");
        let (mut j, back) = Journal::resume(&p, "setup A", 1).expect("resume");
        assert_eq!(back.x.len(), 2);
        assert_eq!(back.x[1], vec![1.0; 5]);
        assert_eq!(back.y[1], vec![-1.0; 4]);
        // Appending continues cleanly after the truncation.
        j.append(&t, 2).expect("append");
        drop(j);
        let (_, again) = Journal::resume(&p, "setup A", 1).expect("resume");
        assert_eq!(again.x.len(), 3);
        assert!(
            Journal::resume(&p, "setup B", 1).is_err(),
            "another setup is refused"
        );
        // In blocks of 2, the third term is an unfinished block: dropped, and the file
        // is cut back so appending continues after the second.
        let (mut j, whole) = Journal::resume(&p, "setup A", 2).expect("resume");
        assert_eq!(whole.x.len(), 2);
        j.append(&t, 2).expect("append");
        drop(j);
        let (_, again) = Journal::resume(&p, "setup A", 1).expect("resume");
        assert_eq!(again.x.len(), 3);
        assert_eq!(again.x[2], vec![2.0; 5]);
    }
}
