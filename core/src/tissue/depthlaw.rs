//! The hyperelastic force law of a palpation scene, `F(s, d)`: the tool's force at
//! probe position `s` and depth `d`, for a haptic loop (depth in, force out) and its
//! inverse (force in, depth out).
//!
//! The linear vademecum already gives the exact linear compliance `c(s)` at any `s`;
//! the tissue's nonlinearity is a correction of that law,
//!
//! ```text
//! F(s, d) = d / c(s) · g(s, d),    g(s, 0) = 1,
//! ```
//!
//! and `g` varies slowly over the surface: it depends on how thick and how curved the
//! organ is under the tool on the scale of centimetres, while `c(s)` varies on the
//! scale of the tool. Off-line, `g` is computed at `N` sample positions spread over
//! the palpable surface (farthest-point sampling of its vertices) from each press's
//! depth series ([`crate::fe::series`]: one factorization for all, a linear solve per
//! order, the Padé form past the radius) on a depth grid; on-line it is the
//! Gaussian-weighted (Shepard) mean of the samples' curves at `s`, interpolated
//! linearly in `d`. Nothing is allocated per call.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::fe::law::Law;
use crate::fe::load::{probe_functional, probe_load};
use crate::fe::probe::{ProbeRequest, locate, organ_space};
use crate::fe::series::Expander;
use crate::fe::{Element, FeError, Material};
use crate::framed::Body;
use crate::organ::OrganMesh;
use crate::tissue::samplelog::SampleLog;

/// The first bytes of a depth-law file.
pub const MAGIC: &[u8; 8] = b"PALPALAW";
/// The file's format version.
pub const VERSION: u32 = 1;

/// Why a depth-law file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DepthLawFileError {
    #[error("{path}: {source}")]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a palpa lab depth-law file (expected the magic bytes \"PALPALAW\")")]
    Foreign { path: std::path::PathBuf },
    #[error("{path}: depth-law format version {found}, this palpa reads {VERSION}")]
    Version {
        path: std::path::PathBuf,
        found: u32,
    },
    #[error("{path}: corrupt depth law: {why}")]
    Corrupt {
        path: std::path::PathBuf,
        why: String,
    },
}

/// Why a force law does not fit the scene it is asked to correct.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DepthLawFitError {
    #[error(
        "the force law does not fit this scene: {matched} of its {total} samples sit on the \
         scene's surface vertices (expected all; was it built on another organ or level?)"
    )]
    Samples { matched: usize, total: usize },
    #[error(
        "the force law was built with {law} and the scene's linear model with {scene}: the \
         law scales the scene's linear force by its own ratio, so both must come from the \
         same element and material (rebuild the law with matching --element, --young-kpa, \
         --poisson)"
    )]
    LinearModel { law: String, scene: String },
}

pub use crate::tissue::press::PADE_CHANGE_MAX;

/// The fewest series orders a law may be built from: two Padé forms to compare.
pub const MIN_ORDERS: usize = 5;

/// Most depth-grid points (the inverse keeps one curve on the stack).
pub const MAX_DEPTHS: usize = 256;

/// How the law is built.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DepthLawOptions {
    pub law: Law,
    pub material: Material,
    pub element: Element,
    pub samples: usize,
    pub depth_max_mm: f64,
    pub depth_step_mm: f64,
    pub orders: usize,
    pub tool_radius_mm: f64,
}

impl Default for DepthLawOptions {
    fn default() -> Self {
        DepthLawOptions {
            law: Law::NeoHookean,
            material: Material::default(),
            element: Element::P2,
            samples: 48,
            depth_max_mm: 15.0,
            depth_step_mm: 0.25,
            orders: 15,
            tool_radius_mm: 5.0,
        }
    }
}

/// The built law.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DepthLaw {
    pub options: DepthLawOptions,
    /// Sample positions on the palpable surface (mm).
    pub samples: Vec<[f64; 3]>,
    /// Gaussian width (mm): the median distance from a sample to its nearest other.
    pub sigma_mm: f64,
    /// `g` at each sample (rows) and grid depth `j·step` (columns).
    pub ratio: Vec<f64>,
    /// Per sample, the Padé form's relative change at the largest depth (its error
    /// indicator).
    pub pade_change: Vec<f64>,
    /// Per sample, the linear stiffness `1/c` at its position (N/mm).
    pub stiffness_n_per_mm: Vec<f64>,
    pub build_s: f64,
}

/// Picks `n` vertices of the palpable surface, each the farthest from those picked
/// (never a fixed vertex: a tool there moves nothing).
fn spread_samples(organ: &OrganMesh, n: usize) -> Vec<[f64; 3]> {
    let verts = organ.pressable_vertices();
    let pts: Vec<[f64; 3]> = verts
        .iter()
        .map(|&v| organ.mesh.vertices[v as usize])
        .collect();
    if pts.is_empty() {
        return Vec::new();
    }
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let mut out = vec![pts[0]];
    let mut nearest: Vec<f64> = pts.iter().map(|&p| d2(p, pts[0])).collect();
    while out.len() < n.min(pts.len()) {
        let (far, _) = nearest
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .expect("a non-empty list: the loop runs while fewer than all are picked");
        out.push(pts[far]);
        for (m, &p) in nearest.iter_mut().zip(&pts) {
            *m = m.min(d2(p, pts[far]));
        }
    }
    out
}

/// Why a depth law could not be built.
#[derive(Debug, thiserror::Error)]
pub enum DepthLawBuildError {
    #[error(transparent)]
    Fe(#[from] FeError),
    #[error(
        "no sample's depth series settled by {depth_max_mm} mm (best change of a Padé form \
         there: {best_change}; at most {PADE_CHANGE_MAX} is kept): raise --orders or lower \
         --depth-max-mm"
    )]
    NoSampleSettled {
        depth_max_mm: f64,
        /// The smallest relative change, or "no pole-free form".
        best_change: String,
    },
    #[error("no samples asked for: expected at least one palpable point to press")]
    NoSamples,
    #[error("the build's sample log {path}: {source}")]
    Log {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}

/// What determines every sample's result: the options and the mesh (its nodes,
/// tetrahedra and regions, hashed).
fn build_key(organ: &OrganMesh, o: &DepthLawOptions) -> String {
    format!(
        "palpa lab depth-law v{VERSION} log 2 mesh {:016x} {o:?}",
        organ.fingerprint()
    )
}

/// One sample's press: empty when the tool does not move its centre, the Padé change
/// alone when the series has not settled by the largest depth, else the Padé change,
/// the linear stiffness `1/c` and `g` on the depth grid.
fn sample_record(
    space: &crate::fe::space::Space,
    organ: &OrganMesh,
    expander: &Expander,
    o: &DepthLawOptions,
    at: [f64; 3],
    steps: usize,
) -> Result<Vec<f64>, FeError> {
    let req = ProbeRequest {
        at,
        force_n: 1.0,
        dir: None,
        radius_mm: o.tool_radius_mm,
    };
    let (probe, dir) = locate(space, organ, &req)?;
    let shape = probe_load(space, &probe, dir, 1.0, o.tool_radius_mm)?;
    let functional = probe_functional(space, &probe, dir);
    // A tool right at the fixed region's edge may not move its own centre along its
    // axis: such a sample says nothing about the law; skip it.
    let series = match expander.expand(&shape, &functional, o.orders) {
        Ok(s) => s,
        Err(FeError::ProbeNotMoved) => return Ok(Vec::new()),
        Err(e) => return Err(e),
    };
    let rational = series.rational(o.depth_max_mm);
    // A rational form that still moves at the deepest point is not trusted: its
    // curve would pull its neighbours' with it.
    if rational.change.is_nan() || rational.change > PADE_CHANGE_MAX {
        return Ok(vec![rational.change]);
    }
    let f1 = series.force[0];
    let mut record = Vec::with_capacity(steps + 2);
    record.push(rational.change);
    record.push(f1);
    for j in 0..steps {
        let d = j as f64 * o.depth_step_mm;
        record.push(if j == 0 {
            1.0
        } else {
            let w = rational.weights(d);
            let f: f64 = w.iter().zip(&series.force).map(|(w, f)| w * f).sum();
            f / (f1 * d)
        });
    }
    Ok(record)
}

impl DepthLaw {
    /// Builds the law on `organ`; `progress(done, total)` after each sample.
    pub fn build(
        organ: &OrganMesh,
        options: DepthLawOptions,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<DepthLaw, DepthLawBuildError> {
        Self::build_logged(organ, options, None, progress).map(|(law, _)| law)
    }

    /// [`build`](Self::build), keeping each finished sample in the log at `log` (see
    /// [`super::samplelog`]): run again after an interruption, it goes on from the
    /// last finished sample and gives the same law. The caller removes the log once the
    /// law is saved (a kill before that loses nothing). Returns the law and how many
    /// samples were taken from the log.
    pub fn build_logged(
        organ: &OrganMesh,
        options: DepthLawOptions,
        log: Option<&Path>,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<(DepthLaw, usize), DepthLawBuildError> {
        let o = options;
        let steps = crate::fe::depth_grid_points(o.depth_max_mm, o.depth_step_mm, MAX_DEPTHS)?;
        if o.samples == 0 {
            return Err(DepthLawBuildError::NoSamples);
        }
        // A sample is kept by the change between its last two Padé forms; the second
        // form (`DepthSeries::pade(2, ..)`) needs five orders.
        crate::fe::series::check_orders(o.orders, MIN_ORDERS)?;
        let t0 = Instant::now();
        let space = organ_space(organ, o.element);
        let expander = Expander::new(&space, o.law, o.material)?;
        let samples = spread_samples(organ, o.samples);
        if samples.is_empty() {
            return Err(FeError::NoPalpableSurface.into());
        }
        let (mut log, finished) = match log {
            Some(path) => {
                let (l, r) = SampleLog::open(path, &build_key(organ, &o)).map_err(|source| {
                    DepthLawBuildError::Log {
                        path: path.to_path_buf(),
                        source,
                    }
                })?;
                (Some((l, path)), r)
            }
            None => (None, Vec::new()),
        };
        // Each sample's record (see `sample_record`).
        let mut records: Vec<Option<Vec<f64>>> = vec![None; samples.len()];
        for (k, values) in finished {
            if k < records.len() && (values.len() <= 1 || values.len() == steps + 2) {
                records[k] = Some(values);
            }
        }
        let resumed = records.iter().filter(|r| r.is_some()).count();
        for (k, &at) in samples.iter().enumerate() {
            if records[k].is_none() {
                let record = sample_record(&space, organ, &expander, &o, at, steps)?;
                if let Some((l, path)) = log.as_mut() {
                    l.push(&(k, record.clone()))
                        .map_err(|source| DepthLawBuildError::Log {
                            path: path.to_path_buf(),
                            source,
                        })?;
                }
                records[k] = Some(record);
            }
            progress(k + 1, samples.len());
        }
        let mut ratio = Vec::with_capacity(samples.len() * steps);
        let mut pade_change = Vec::with_capacity(samples.len());
        let mut skipped = Vec::new();
        let mut stiffness = Vec::with_capacity(samples.len());
        for (k, record) in records.iter().enumerate() {
            match record.as_deref() {
                Some([change, f1, row @ ..]) => {
                    pade_change.push(*change);
                    stiffness.push(*f1);
                    ratio.extend_from_slice(row);
                }
                _ => skipped.push(k),
            }
        }
        let samples: Vec<[f64; 3]> = samples
            .into_iter()
            .enumerate()
            .filter(|(k, _)| !skipped.contains(k))
            .map(|(_, p)| p)
            .collect();
        if samples.is_empty() {
            let unsettled: Vec<f64> = records
                .iter()
                .flatten()
                .filter_map(|r| match r[..] {
                    [change] => Some(change),
                    _ => None,
                })
                .collect();
            if unsettled.is_empty() {
                return Err(FeError::ProbeNotMoved.into());
            }
            let best = unsettled.iter().copied().fold(f64::INFINITY, f64::min);
            return Err(DepthLawBuildError::NoSampleSettled {
                depth_max_mm: o.depth_max_mm,
                best_change: if best.is_finite() {
                    format!("{best:.2}")
                } else {
                    "no pole-free form".into()
                },
            });
        }
        let d =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt();
        let mut spacing: Vec<f64> = samples
            .iter()
            .enumerate()
            .map(|(i, &a)| {
                samples
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, &b)| d(a, b))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        spacing.sort_by(f64::total_cmp);
        let sigma_mm = spacing
            .get(spacing.len() / 2)
            .copied()
            .filter(|s| s.is_finite())
            .unwrap_or(10.0);
        let law = DepthLaw {
            options,
            samples,
            sigma_mm,
            ratio,
            pade_change,
            stiffness_n_per_mm: stiffness,
            build_s: t0.elapsed().as_secs_f64(),
        };
        // Every row belongs to its sample (a mismatch would put curves at the wrong
        // places silently).
        debug_assert_eq!(law.check(), Ok(()));
        Ok((law, resumed))
    }

    /// Checks what a file or a caller gave: shapes, finite values, `g(0) = 1`.
    pub fn check(&self) -> Result<(), String> {
        let o = &self.options;
        let steps = (o.depth_max_mm / o.depth_step_mm).round();
        if !(o.depth_max_mm.is_finite()
            && o.depth_step_mm > 0.0
            && steps >= 1.0
            && steps < MAX_DEPTHS as f64)
        {
            return Err(format!(
                "depth range {} mm in steps of {} mm: expected a finite range of 2 to {MAX_DEPTHS} \
                 grid points",
                o.depth_max_mm, o.depth_step_mm
            ));
        }
        let steps = steps as usize + 1;
        if self.samples.is_empty()
            || self.ratio.len() != self.samples.len() * steps
            || self.pade_change.len() != self.samples.len()
            || self.stiffness_n_per_mm.len() != self.samples.len()
        {
            return Err(format!(
                "{} ratio values for {} samples of {steps} depths",
                self.ratio.len(),
                self.samples.len()
            ));
        }
        if self.samples.iter().flatten().any(|v| !v.is_finite())
            || self.ratio.iter().any(|v| !(v.is_finite() && *v > 0.0))
            || !(self.sigma_mm.is_finite() && self.sigma_mm > 0.0)
        {
            return Err("non-finite or non-positive values".into());
        }
        if self
            .ratio
            .chunks_exact(steps)
            .any(|r| (r[0] - 1.0).abs() > 1e-12)
        {
            return Err("a sample's ratio at depth 0 is not 1".into());
        }
        Ok(())
    }

    /// Writes the law atomically (a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), DepthLawFileError> {
        crate::framed::write(path, MAGIC, (VERSION, Body::Plain), self).map_err(|source| {
            DepthLawFileError::Io {
                path: path.to_path_buf(),
                source,
            }
        })
    }

    /// Checks that this law was built on the scene's mesh (every sample one of its
    /// surface vertices) with the element and material of its linear model (its
    /// provenance `mesh` line): a liver's law once scaled a kidney scene's forces.
    pub fn check_scene(
        &self,
        vertices_mm: &[[f32; 3]],
        scene_mesh_line: &str,
    ) -> Result<(), DepthLawFitError> {
        let index =
            crate::tissue::law::PointIndex::new(vertices_mm.iter().map(|p| p.map(f64::from)));
        let matched = self
            .samples
            .iter()
            .filter(|&&p| index.find(p).is_some())
            .count();
        if matched < self.samples.len() {
            return Err(DepthLawFitError::Samples {
                matched,
                total: self.samples.len(),
            });
        }
        let o = &self.options;
        match crate::tissue::law::linear_model_mismatch(o.element, &o.material, scene_mesh_line) {
            Some((law, scene)) => Err(DepthLawFitError::LinearModel { law, scene }),
            None => Ok(()),
        }
    }

    pub fn load(path: &Path) -> Result<DepthLaw, DepthLawFileError> {
        let bytes = std::fs::read(path).map_err(|source| DepthLawFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path)
    }

    /// Reads a law from the bytes of a file (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<DepthLaw, DepthLawFileError> {
        use crate::framed::FramedError;
        let p = || path.to_path_buf();
        let law: DepthLaw =
            crate::framed::read(bytes, MAGIC, &[(VERSION, Body::Plain)]).map_err(|e| match e {
                FramedError::Foreign => DepthLawFileError::Foreign { path: p() },
                FramedError::Version(found) => DepthLawFileError::Version { path: p(), found },
                FramedError::Corrupt(why) => DepthLawFileError::Corrupt { path: p(), why },
            })?;
        law.check()
            .map_err(|why| DepthLawFileError::Corrupt { path: p(), why })?;
        Ok(law)
    }

    fn steps(&self) -> usize {
        self.ratio.len() / self.samples.len().max(1)
    }

    /// The samples' Gaussian weights at `at`, normalized, handed to `each(sample, w)`.
    fn for_weights(&self, at: [f64; 3], mut each: impl FnMut(usize, f64)) {
        let inv = 1.0 / (2.0 * self.sigma_mm * self.sigma_mm);
        let mut total = 0.0;
        // The largest log-weight first, so that a point far from every sample still
        // has weights that do not all underflow.
        let mut best = f64::INFINITY;
        for s in &self.samples {
            let d2: f64 = (0..3).map(|k| (at[k] - s[k]).powi(2)).sum();
            best = best.min(d2);
        }
        for s in &self.samples {
            let d2: f64 = (0..3).map(|k| (at[k] - s[k]).powi(2)).sum();
            total += (-(d2 - best) * inv).exp();
        }
        for (i, s) in self.samples.iter().enumerate() {
            let d2: f64 = (0..3).map(|k| (at[k] - s[k]).powi(2)).sum();
            each(i, (-(d2 - best) * inv).exp() / total);
        }
    }

    /// `g(s, d)` and whether `d` lay beyond the built range (then `g` at its end).
    pub fn ratio(&self, at: [f64; 3], depth_mm: f64) -> (f64, bool) {
        let steps = self.steps();
        let beyond = depth_mm > self.options.depth_max_mm || depth_mm < 0.0;
        let x = (depth_mm.clamp(0.0, self.options.depth_max_mm) / self.options.depth_step_mm)
            .min((steps - 1) as f64);
        let j = (x.floor() as usize).min(steps.saturating_sub(2));
        let f = x - j as f64;
        let mut g = 0.0;
        self.for_weights(at, |i, w| {
            let row = &self.ratio[i * steps..(i + 1) * steps];
            g += w * (row[j] * (1.0 - f) + row[(j + 1).min(steps - 1)] * f);
        });
        (g, beyond)
    }

    /// The force (N) at depth `depth_mm` for the linear compliance `compliance_mm_per_n`
    /// at `at`, and whether the depth was clamped to the built range.
    pub fn force_n(&self, at: [f64; 3], depth_mm: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        let (g, beyond) = self.ratio(at, depth_mm);
        let d = depth_mm.clamp(0.0, self.options.depth_max_mm);
        (d / compliance_mm_per_n * g, beyond)
    }

    /// The depth (mm) at which the force is `force_n` (the inverse: a gamepad trigger's
    /// force in, depth out), and whether it lay beyond the built range (then its end).
    pub fn depth_mm(&self, at: [f64; 3], force_n: f64, compliance_mm_per_n: f64) -> (f64, bool) {
        let steps = self.steps();
        let mut curve = [0.0f64; MAX_DEPTHS];
        self.for_weights(at, |i, w| {
            for (c, r) in curve
                .iter_mut()
                .zip(&self.ratio[i * steps..(i + 1) * steps])
            {
                *c += w * r;
            }
        });
        let h = self.options.depth_step_mm;
        let force = |j: usize| j as f64 * h / compliance_mm_per_n * curve[j];
        if force_n <= 0.0 || force_n.is_nan() {
            return (0.0, force_n < 0.0);
        }
        for j in 1..steps {
            let (lo, hi) = (force(j - 1), force(j));
            if force_n <= hi && hi > lo {
                // Inside the interval the forward law is d/c · (α + β d), g linear in
                // d: solve β d² + α d = F c exactly (the stable root).
                let beta = (curve[j] - curve[j - 1]) / h;
                let alpha = curve[j - 1] - beta * (j - 1) as f64 * h;
                let fc = force_n * compliance_mm_per_n;
                let d = 2.0 * fc / (alpha + (alpha * alpha + 4.0 * beta * fc).max(0.0).sqrt());
                return (d, false);
            }
        }
        ((steps - 1) as f64 * h, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A law whose samples all carry the same curve returns it anywhere, and the
    /// inverse undoes the forward law; beyond the range it clamps and says so.
    #[test]
    fn forward_and_inverse_agree_and_clamp() {
        let steps = 61;
        let curve: Vec<f64> = (0..steps).map(|j| 1.0 - 0.004 * j as f64).collect();
        let law = DepthLaw {
            options: DepthLawOptions::default(),
            samples: vec![[0.0, 0.0, 0.0], [50.0, 0.0, 0.0], [0.0, 40.0, 10.0]],
            sigma_mm: 20.0,
            ratio: [curve.clone(), curve.clone(), curve].concat(),
            pade_change: vec![0.0; 3],
            stiffness_n_per_mm: vec![1.0; 3],
            build_s: 0.0,
        };
        let at = [12.0, 7.0, 3.0];
        let c = 0.8;
        for d in [0.0, 0.3, 4.0, 9.87, 15.0] {
            let (f, beyond) = law.force_n(at, d, c);
            assert!(!beyond);
            let want = d / c * (1.0 - 0.004 * d / 0.25);
            assert!((f - want).abs() < 1e-12, "{d}: {f} vs {want}");
            let (back, beyond) = law.depth_mm(at, f, c);
            assert!(!beyond);
            assert!((back - d).abs() < 1e-9, "{d}: back {back}");
        }
        let (_, beyond) = law.force_n(at, 16.0, c);
        assert!(beyond);
        let (d, beyond) = law.depth_mm(at, 1e3, c);
        assert!(beyond && d == 15.0);
        // Through a file, and a flipped byte is named.
        law.check().expect("consistent");
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("law.bin");
        law.save(&path).expect("saves");
        assert_eq!(DepthLaw::load(&path).expect("loads"), law);
        let mut bytes = std::fs::read(&path).expect("reads");
        let n = bytes.len();
        bytes[n - 3] ^= 1;
        std::fs::write(&path, &bytes).expect("writes");
        let e = DepthLaw::load(&path).expect_err("corrupt").to_string();
        assert!(e.contains("checksum"), "{e}");
        std::fs::write(&path, b"something else entirely").expect("writes");
        let e = DepthLaw::load(&path).expect_err("foreign").to_string();
        assert!(e.contains("not a palpa lab depth-law file"), "{e}");
        // Far from every sample the weights still sum to one (no underflow to NaN).
        let (g, _) = law.ratio([1e5, 0.0, 0.0], 4.0);
        assert!((g - (1.0 - 0.004 * 16.0)).abs() < 1e-12, "{g}");
    }
}
