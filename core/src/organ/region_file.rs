//! Region files: the fixed and palpable regions of a user organ as data, written by
//! the app's region painter and read by `palpa scene build --regions`.
//!
//! Painting marks triangles of one mesh; a scene is rebuilt on another (another
//! level, or the tetrahedral mesh of the source surface), so a painted region is
//! stored by position: the centroids of its triangles in the organ frame (mm, patient
//! axes). A triangle of the new mesh is in the region when its centroid lies within
//! `match_radius_mm` of one of them (the painter sets it to the painted mesh's mean
//! edge length, so a region neither shrinks nor bleeds by more than about one
//! painted triangle). Selector expressions ([`super::syntax`]) may stand beside or
//! instead of painted points; a triangle is in a region when either says so.
//!
//! ```toml
//! version = 1
//! painted_on = "kidney.palpa"
//! match_radius_mm = 6.2
//! fixed_selectors = ["normal:posterior:40"]
//! palpable_selectors = []
//! fixed_points = [[1.0, -30.5, 2.0], ...]
//! palpable_points = [...]
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::Selector;
use super::syntax::{SyntaxError, parse};

/// The version this build writes and reads.
pub const REGION_FILE_VERSION: u32 = 1;

/// Fixed and palpable regions of an organ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionFile {
    pub version: u32,
    /// The scene or surface the points were painted on (a record for people).
    #[serde(default)]
    pub painted_on: String,
    pub match_radius_mm: f64,
    #[serde(default)]
    pub fixed_selectors: Vec<String>,
    #[serde(default)]
    pub palpable_selectors: Vec<String>,
    #[serde(default)]
    pub fixed_points: Vec<[f64; 3]>,
    #[serde(default)]
    pub palpable_points: Vec<[f64; 3]>,
}

/// Why a region file cannot be used.
#[derive(Debug, Error)]
pub enum RegionFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a region file: {reason}")]
    Parse { path: PathBuf, reason: String },
    #[error("{path}: region file version {found}; this palpa reads version {REGION_FILE_VERSION}")]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: {reason}")]
    Invalid { path: PathBuf, reason: String },
    #[error("{path}: {source}")]
    Selector { path: PathBuf, source: SyntaxError },
    #[error(
        "{path}: names no fixed region (no fixed point or selector): the organ would be free to move"
    )]
    NoFixed { path: PathBuf },
}

impl RegionFile {
    pub fn load(path: &Path) -> Result<RegionFile, RegionFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| RegionFileError::Io {
            path: path.into(),
            source,
        })?;
        Self::from_text(&text, path)
    }

    /// Parses and checks a region file's text (`path` names it in messages).
    pub fn from_text(text: &str, path: &Path) -> Result<RegionFile, RegionFileError> {
        let r: RegionFile = toml::from_str(text).map_err(|e| RegionFileError::Parse {
            path: path.into(),
            reason: e.to_string(),
        })?;
        if r.version != REGION_FILE_VERSION {
            return Err(RegionFileError::Version {
                path: path.into(),
                found: r.version,
            });
        }
        let invalid = |reason: String| RegionFileError::Invalid {
            path: path.into(),
            reason,
        };
        if !(r.match_radius_mm.is_finite() && r.match_radius_mm > 0.0) {
            return Err(invalid(format!(
                "match_radius_mm = {} (expected a positive length in mm)",
                r.match_radius_mm
            )));
        }
        for (name, pts) in [
            ("fixed_points", &r.fixed_points),
            ("palpable_points", &r.palpable_points),
        ] {
            if let Some((i, p)) = pts
                .iter()
                .enumerate()
                .find(|(_, p)| p.iter().any(|c| !c.is_finite() || c.abs() > 1e6))
            {
                return Err(invalid(format!(
                    "{name}[{i}] = {p:?} (expected finite coordinates within ±1e6 mm)"
                )));
            }
        }
        if r.fixed_points.is_empty() && r.fixed_selectors.is_empty() {
            return Err(RegionFileError::NoFixed { path: path.into() });
        }
        r.selectors(path)?;
        Ok(r)
    }

    /// The fixed and palpable selectors the file describes.
    pub fn selectors(&self, path: &Path) -> Result<(Selector, Selector), RegionFileError> {
        let one = |exprs: &[String], points: &[[f64; 3]]| {
            let mut v = exprs
                .iter()
                .map(|e| {
                    parse(e).map_err(|source| RegionFileError::Selector {
                        path: path.into(),
                        source,
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            if !points.is_empty() {
                v.push(Selector::NearPoints {
                    points: points.to_vec(),
                    radius_mm: self.match_radius_mm,
                });
            }
            Ok(Selector::Any(v))
        };
        Ok((
            one(&self.fixed_selectors, &self.fixed_points)?,
            one(&self.palpable_selectors, &self.palpable_points)?,
        ))
    }

    /// Writes the file atomically (a temporary file, then a rename).
    pub fn save(&self, path: &Path) -> Result<(), RegionFileError> {
        let text = toml::to_string(self).map_err(|e| RegionFileError::Parse {
            path: path.into(),
            reason: e.to_string(),
        })?;
        crate::fsutil::atomic_write(path, |w| std::io::Write::write_all(w, text.as_bytes()))
            .map_err(|source| RegionFileError::Io {
                path: path.into(),
                source,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> RegionFile {
        RegionFile {
            version: 1,
            painted_on: "x.palpa".into(),
            match_radius_mm: 2.0,
            fixed_selectors: vec!["normal:posterior:30".into()],
            palpable_selectors: vec![],
            fixed_points: vec![[0.0, 0.0, 0.0]],
            palpable_points: vec![[10.0, 0.0, 0.0]],
        }
    }

    #[test]
    fn a_region_file_round_trips_and_selects() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("r.toml");
        file().save(&p).expect("save");
        let r = RegionFile::load(&p).expect("load");
        assert_eq!(r, file());
        let (fixed, palpable) = r.selectors(&p).expect("selectors");
        assert!(
            fixed.contains([1.0, 1.0, 0.0], [1.0, 0.0, 0.0]),
            "near a point"
        );
        assert!(
            fixed.contains([50.0, 0.0, 0.0], [0.0, -1.0, 0.0]),
            "by selector"
        );
        assert!(!fixed.contains([50.0, 0.0, 0.0], [0.0, 1.0, 0.0]));
        assert!(palpable.contains([11.0, 0.0, 0.0], [0.0, 1.0, 0.0]));
    }

    #[test]
    fn bad_region_files_say_what_is_wrong() {
        let p = Path::new("r.toml");
        let text = |r: &RegionFile| toml::to_string(r).expect("toml");
        let mut r = file();
        r.fixed_points.clear();
        r.fixed_selectors.clear();
        let e = RegionFile::from_text(&text(&r), p).expect_err("no fixed");
        assert!(e.to_string().contains("free to move"), "{e}");
        let mut r = file();
        r.match_radius_mm = -1.0;
        assert!(RegionFile::from_text(&text(&r), p).is_err());
        let mut r = file();
        r.fixed_selectors = vec!["normal:up:3".into()];
        let e = RegionFile::from_text(&text(&r), p).expect_err("selector");
        assert!(e.to_string().contains("not a direction"), "{e}");
        let mut r = file();
        r.version = 9;
        assert!(matches!(
            RegionFile::from_text(&text(&r), p),
            Err(RegionFileError::Version { found: 9, .. })
        ));
        assert!(RegionFile::from_text("garbage = [", p).is_err());
        let e = RegionFile::from_text(
            "version = 1\nmatch_radius_mm = 1.0\nfixed_points = [[1e308, 0.0, 0.0]]\n",
            p,
        )
        .expect_err("huge");
        assert!(e.to_string().contains("fixed_points[0]"), "{e}");
    }
}
