//! A log of finished samples, so that an off-line build made of independent samples
//! (the depth law's presses) goes on after `kill -9` from the last finished one and
//! gives the same file as an uninterrupted run.
//!
//! The log is a text file: a first line with the build's key (everything that
//! determines the samples' results), then one line per finished sample, its values as
//! the hexadecimal bits of each `f64` (exact: a resumed build reads back exactly what
//! it computed). Each line is flushed and synced before the next sample starts. A
//! line cut short by the kill has no final newline and is ignored; a log with another
//! key is started afresh.

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;

/// One finished sample: its index and values (empty for a sample that was skipped).
pub type Record = (usize, Vec<f64>);

/// An open log, appended to as samples finish.
#[derive(Debug)]
pub struct SampleLog {
    file: File,
}

impl SampleLog {
    /// Opens the log at `path` for a build with `key` and returns it with the
    /// records already finished (none if the file is missing, unreadable or of
    /// another build).
    pub fn open(path: &Path, key: &str) -> io::Result<(SampleLog, Vec<Record>)> {
        let key_line = key.replace('\n', " ");
        let previous = std::fs::read_to_string(path).unwrap_or_default();
        let mut lines = previous.split_inclusive('\n');
        let same = lines.next() == Some(&format!("{key_line}\n"));
        let records: Vec<Record> = if same {
            lines
                .filter(|l| l.ends_with('\n'))
                .map_while(|l| parse(l.trim_end()))
                .collect()
        } else {
            Vec::new()
        };
        // Rewrite the key and the good records: drops a torn last line.
        let mut file = File::create(path)?;
        writeln!(file, "{key_line}")?;
        for r in &records {
            file.write_all(format(r).as_bytes())?;
        }
        file.sync_all()?;
        let file = OpenOptions::new().append(true).open(path)?;
        Ok((SampleLog { file }, records))
    }

    /// Appends one finished sample and syncs it to disk.
    pub fn push(&mut self, record: &Record) -> io::Result<()> {
        self.file.write_all(format(record).as_bytes())?;
        self.file.sync_data()
    }
}

fn format((k, values): &Record) -> String {
    let mut s = k.to_string();
    for v in values {
        s.push(' ');
        s.push_str(&format!("{:016x}", v.to_bits()));
    }
    s.push('\n');
    s
}

fn parse(line: &str) -> Option<Record> {
    let mut it = line.split(' ');
    let k = it.next()?.parse().ok()?;
    let values = it
        .map(|w| u64::from_str_radix(w, 16).ok().map(f64::from_bits))
        .collect::<Option<Vec<_>>>()?;
    Some((k, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_come_back_bit_for_bit_and_a_torn_line_is_dropped() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("law.journal");
        let (mut log, old) = SampleLog::open(&path, "key a").expect("open");
        assert!(old.is_empty());
        let a = (0, vec![1.0 / 3.0, -0.0, f64::MIN_POSITIVE]);
        log.push(&a).expect("push");
        log.push(&(1, vec![])).expect("push");
        drop(log);
        // A kill in the middle of the third line.
        let mut f = OpenOptions::new().append(true).open(&path).expect("f");
        f.write_all(b"2 3ff00000").expect("torn");
        drop(f);
        let (log, old) = SampleLog::open(&path, "key a").expect("reopen");
        assert_eq!(old, vec![a.clone(), (1, vec![])]);
        assert_eq!(old[0].1[1].to_bits(), (-0.0f64).to_bits());
        drop(log);
        let (log, old) = SampleLog::open(&path, "key b").expect("other build");
        assert!(old.is_empty(), "another build's records are not taken");
        drop(log);
    }
}
