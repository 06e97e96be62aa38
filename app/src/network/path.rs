//! A scripted coordinate path for headless network frames (`--coordinate-path FILE`),
//! like the probe path of the palpation scene: JSON keyframes in clock seconds, each
//! naming the coordinates it sets (`t` and parameter names), linearly interpolated
//! between keyframes and held before the first and after the last. A coordinate a
//! keyframe leaves out keeps its value.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, bail};
use serde::Deserialize;

use super::NetworkRoom;

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    pub t_s: f64,
    pub coordinates: BTreeMap<String, f64>,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoordinatePath {
    pub keyframes: Vec<Keyframe>,
}

impl CoordinatePath {
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Self::from_json(&text).with_context(|| path.display().to_string())
    }

    /// Parses and checks a coordinate path's JSON.
    pub fn from_json(text: &str) -> anyhow::Result<Self> {
        let p: CoordinatePath = serde_json::from_str(text).context(
            "expected {\"keyframes\": [{\"t_s\": 0, \"coordinates\": {\"t\": 10, \"delta\": 0.02}}, ...]}",
        )?;
        p.validate()?;
        Ok(p)
    }

    fn validate(&self) -> anyhow::Result<()> {
        if self.keyframes.is_empty() {
            bail!("a coordinate path needs at least one keyframe");
        }
        for (i, k) in self.keyframes.iter().enumerate() {
            if !k.t_s.is_finite() || k.coordinates.values().any(|v| !v.is_finite()) {
                bail!("keyframe {i} has a non-finite value");
            }
        }
        if let Some(i) = self.keyframes.windows(2).position(|w| w[1].t_s <= w[0].t_s) {
            bail!(
                "keyframe times must increase (keyframe {} at {} s)",
                i + 1,
                self.keyframes[i + 1].t_s
            );
        }
        Ok(())
    }

    /// Checks that every name is a coordinate of `room` (`t` or a parameter).
    pub fn check_names(&self, room: &NetworkRoom) -> anyhow::Result<()> {
        let known: Vec<&str> = std::iter::once("t")
            .chain(room.params.iter().map(|c| c.name.as_str()))
            .collect();
        for k in &self.keyframes {
            if let Some(name) = k.coordinates.keys().find(|n| !known.contains(&n.as_str())) {
                bail!(
                    "the coordinate path names {name:?}; this model's coordinates are {}",
                    known.join(", ")
                );
            }
        }
        Ok(())
    }

    /// Sets `room`'s coordinates to the path's values at clock time `s` (values outside
    /// a trained range are kept: the evaluation clamps and flags them).
    pub fn apply(&self, s: f64, room: &mut NetworkRoom) {
        let mut names: Vec<&String> = self
            .keyframes
            .iter()
            .flat_map(|k| k.coordinates.keys())
            .collect();
        names.sort();
        names.dedup();
        for name in names {
            // The keyframes that set this coordinate.
            let set: Vec<(f64, f64)> = self
                .keyframes
                .iter()
                .filter_map(|k| k.coordinates.get(name).map(|&v| (k.t_s, v)))
                .collect();
            let value = interpolate(&set, s);
            if name == "t" {
                room.time.value = value;
            } else if let Some(c) = room.params.iter_mut().find(|c| &c.name == name) {
                c.value = value;
            }
        }
    }
}

/// Piecewise-linear through `(time, value)` points (increasing times), held at the ends.
fn interpolate(points: &[(f64, f64)], s: f64) -> f64 {
    match points.iter().position(|&(t, _)| t > s) {
        None => points.last().map_or(0.0, |p| p.1),
        Some(0) => points[0].1,
        Some(i) => {
            let ((t0, v0), (t1, v1)) = (points[i - 1], points[i]);
            v0 + (v1 - v0) * (s - t0) / (t1 - t0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_and_held_at_the_ends() {
        let p = [(0.0, 1.0), (2.0, 3.0), (3.0, 3.0)];
        assert_eq!(interpolate(&p, -1.0), 1.0);
        assert_eq!(interpolate(&p, 1.0), 2.0);
        assert_eq!(interpolate(&p, 2.5), 3.0);
        assert_eq!(interpolate(&p, 9.0), 3.0);
    }

    #[test]
    fn bad_paths_are_named() {
        let parse = |s: &str| {
            serde_json::from_str::<CoordinatePath>(s)
                .map_err(|e| e.to_string())
                .and_then(|p| p.validate().map_err(|e| e.to_string()))
        };
        assert!(parse(r#"{"keyframes": []}"#).is_err());
        assert!(
            parse(
                r#"{"keyframes": [{"t_s": 1, "coordinates": {}}, {"t_s": 1, "coordinates": {}}]}"#
            )
            .is_err_and(|e| e.contains("increase"))
        );
        assert!(parse(r#"{"keyframes": [{"t_s": 0, "coords": {}}]}"#).is_err());
        assert!(parse(r#"{"keyframes": [{"t_s": 0, "coordinates": {"t": 1}}]}"#).is_ok());
    }
}
