//! Snapshot data: copy numbers counted in single cells at a few times.
//!
//! A CSV file with a header `t,<species>…` and one row per cell: the time it was
//! measured and its count of each observed species. A species of the network that is
//! not a column is unobserved (summed out of the likelihood); columns may come in any
//! order. Blank lines and lines starting with `#` are skipped. Each cell is measured
//! once (a snapshot destroys it), so cells at different times are independent.

use std::collections::BTreeMap;
use std::path::Path;

use thiserror::Error;

/// Why a data file could not be read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DataError {
    #[error("{source_name}: {reason}")]
    File { source_name: String, reason: String },
    #[error("{source_name}, line {line}: {reason}")]
    Line {
        source_name: String,
        line: usize,
        reason: String,
    },
}

/// Cells measured at a few times.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshots {
    /// The observed species, in column order.
    pub species: Vec<String>,
    /// The measurement times, increasing, each with at least one cell.
    pub times: Vec<f64>,
    /// `cells[k]`: the counts of the cells measured at `times[k]`, one value per
    /// observed species.
    pub cells: Vec<Vec<Vec<u32>>>,
}

impl Snapshots {
    /// Parses a data file's text; `source_name` names it in errors.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, DataError> {
        let file_err = |reason: String| DataError::File {
            source_name: source_name.to_string(),
            reason,
        };
        let line_err = |line: usize, reason: String| DataError::Line {
            source_name: source_name.to_string(),
            line,
            reason,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((header_line, header)) = lines.next() else {
            return Err(file_err(
                "no header: expected a first line `t,<species>…` and one row per cell".into(),
            ));
        };
        let columns: Vec<&str> = header.split(',').map(str::trim).collect();
        if columns.first() != Some(&"t") {
            return Err(line_err(
                header_line,
                format!("header {header:?}: expected `t` first, then species names"),
            ));
        }
        let species: Vec<String> = columns[1..].iter().map(|s| s.to_string()).collect();
        if species.is_empty() {
            return Err(line_err(
                header_line,
                "header has no species: expected `t,<species>…`".into(),
            ));
        }
        for (i, s) in species.iter().enumerate() {
            if s.is_empty() {
                return Err(line_err(
                    header_line,
                    format!("column {} has no name", i + 2),
                ));
            }
            if species[..i].contains(s) {
                return Err(line_err(
                    header_line,
                    format!("species {s:?} appears twice"),
                ));
            }
        }
        let mut by_time: BTreeMap<u64, (f64, Vec<Vec<u32>>)> = BTreeMap::new();
        for (line, row) in lines {
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            if fields.len() != columns.len() {
                return Err(line_err(
                    line,
                    format!(
                        "{} fields, expected {} (t, {})",
                        fields.len(),
                        columns.len(),
                        species.join(", ")
                    ),
                ));
            }
            let t: f64 = fields[0]
                .parse()
                .ok()
                .filter(|t: &f64| t.is_finite() && *t >= 0.0)
                .ok_or_else(|| {
                    line_err(
                        line,
                        format!("time {:?}: expected a finite time ≥ 0", fields[0]),
                    )
                })?;
            let counts = fields[1..]
                .iter()
                .zip(&species)
                .map(|(f, s)| {
                    f.parse::<u32>().map_err(|_| {
                        line_err(
                            line,
                            format!("{s} = {f:?}: expected a whole count of molecules ≥ 0"),
                        )
                    })
                })
                .collect::<Result<Vec<u32>, _>>()?;
            // Times as written are keys: 10 and 10.0 are the same time.
            by_time
                .entry(t.to_bits())
                .or_insert_with(|| (t, Vec::new()))
                .1
                .push(counts);
        }
        if by_time.is_empty() {
            return Err(file_err(
                "no cells: expected one row per cell after the header".into(),
            ));
        }
        let mut groups: Vec<(f64, Vec<Vec<u32>>)> = by_time.into_values().collect();
        groups.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Snapshots {
            species,
            times: groups.iter().map(|g| g.0).collect(),
            cells: groups.into_iter().map(|g| g.1).collect(),
        })
    }

    /// Reads a data file.
    pub fn read(path: &Path) -> Result<Self, DataError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| DataError::File {
            source_name: name.clone(),
            reason: format!("cannot read: {e}"),
        })?;
        Self::parse(&text, &name)
    }

    /// The CSV text [`Self::parse`] reads back.
    pub fn to_csv(&self) -> String {
        use std::fmt::Write as _;
        let mut s = format!("t,{}\n", self.species.join(","));
        for (t, cells) in self.times.iter().zip(&self.cells) {
            for c in cells {
                let _ = write!(s, "{t}");
                for x in c {
                    let _ = write!(s, ",{x}");
                }
                s.push('\n');
            }
        }
        s
    }

    /// Cells in all.
    pub fn cell_count(&self) -> usize {
        self.cells.iter().map(Vec::len).sum()
    }

    /// At each time, each distinct observed state with the number of cells in it.
    pub fn histograms(&self) -> Vec<Vec<(Vec<u32>, u32)>> {
        self.cells
            .iter()
            .map(|cells| {
                let mut h: BTreeMap<&[u32], u32> = BTreeMap::new();
                for c in cells {
                    *h.entry(c.as_slice()).or_default() += 1;
                }
                h.into_iter().map(|(k, n)| (k.to_vec(), n)).collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_reads_back_what_was_written_and_bad_rows_are_named_by_line() {
        let text = "# two times\nt,z2,z1\n5,1,2\n10,3,4\n5,0,7\n\n10.0,9,9\n";
        let s = Snapshots::parse(text, "d.csv").expect("parses");
        assert_eq!(s.species, vec!["z2", "z1"]);
        assert_eq!(s.times, vec![5.0, 10.0]);
        assert_eq!(s.cells[0], vec![vec![1, 2], vec![0, 7]]);
        assert_eq!(s.cells[1].len(), 2);
        assert_eq!(Snapshots::parse(&s.to_csv(), "again").expect("parses"), s);
        let bad = Snapshots::parse("t,z1\n1,2\n1,x\n", "d.csv").expect_err("refused");
        assert!(bad.to_string().contains("line 3"), "{bad}");
        assert!(bad.to_string().contains("z1 = \"x\""), "{bad}");
        for (text, says) in [
            ("t,z1\n1,2,3\n", "line 2: 3 fields, expected 2"),
            ("t,z1\n-1,2\n", "expected a finite time"),
            ("t,z1\n1,-2\n", "whole count"),
            ("z1,t\n1,2\n", "expected `t` first"),
            ("t,z1,z1\n", "appears twice"),
            ("t,z1\n", "no cells"),
            ("", "no header"),
        ] {
            let e = Snapshots::parse(text, "d.csv").expect_err(text);
            assert!(e.to_string().contains(says), "{text:?}: {e}");
        }
    }
}
