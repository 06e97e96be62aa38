//! `palpa tradeoff X.tissue`: the measured speed/accuracy table of a tissue
//! vademecum over its knobs, the modes each sample keeps, the bits of each stored
//! shape entry (eight beside a sixteen-bit law's own), the depth grid's step and, for a
//! law with split triangles, the same presses without their quarter and inner points
//! (`split_triangles: 0`; `palpa_core::tissue::knobs`), with the errors at
//! held-out points *and* depths (the λ axis) against the full nonlinear FE.
//!
//! The reference is computed once: Newton under depth control at each held-out press
//! (random points inside pressed triangles, depths off every grid), along the scene's
//! push as the app presses. Each setting is then the stored law cut and bound to the
//! scene again, so one build measures the whole table; the linear model's errors at
//! the same presses are the row that keeps nothing. The table is printed, not stored:
//! a tissue file keeps every mode and depth it was built with.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use palpa_core::axis::ProbePoint;
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::{PointIndex, ShapeBits, TissueLaw};
use serde_json::json;

use super::against::max_node_errors;
use super::check::newton_at_depths;
use super::eval::bound_to_scene;
use super::points::press_points;
use crate::cli::args::OrganArgs;

/// What the table is measured at.
pub struct Settings<'a> {
    pub organ: &'a OrganArgs,
    pub scene: &'a str,
    pub heldout: usize,
    pub depths_mm: &'a [f64],
    pub seed: u64,
}

/// One held-out press and Newton's answer there.
struct Press {
    at: [f64; 3],
    point: ProbePoint,
    compliance_mm_per_n: f64,
    depth_mm: f64,
    force_n: f64,
    /// Newton's displacement (organ node order) and the scene's linear surface (row
    /// order) at this depth.
    reference: Vec<f64>,
    linear_rows: Vec<f64>,
}

/// A setting's errors over the presses it answers.
#[derive(Default)]
struct Errors {
    compared: usize,
    past_limit: usize,
    worst_force: f64,
    sum_force: f64,
    worst_surface_mm: f64,
    /// Where the worst surface error was: point and depth (mm).
    worst_surface_at: Option<([f64; 3], f64)>,
}

impl Errors {
    fn add(&mut self, p: &Press, force_rel: f64, surface_mm: f64) {
        self.compared += 1;
        self.worst_force = self.worst_force.max(force_rel);
        self.sum_force += force_rel;
        if surface_mm >= self.worst_surface_mm {
            self.worst_surface_mm = surface_mm;
            self.worst_surface_at = Some((p.at, p.depth_mm));
        }
    }

    fn json(&self) -> serde_json::Value {
        let some = self.compared > 0;
        json!({"presses_compared": self.compared, "presses_past_limit": self.past_limit,
            "worst_force_rel_error": some.then_some(self.worst_force),
            "mean_force_rel_error": some.then(|| self.sum_force / self.compared as f64),
            "worst_surface_max_error_mm": some.then_some(self.worst_surface_mm),
            "worst_surface_at": self.worst_surface_at.map(|(at, d)| json!({"at": at, "depth_mm": d})),
            "meets_goals": some.then_some(self.worst_force <= 0.05 && self.worst_surface_mm <= 0.5)})
    }
}

pub fn run(file: &Path, s: &Settings, json_out: bool) -> anyhow::Result<()> {
    if s.depths_mm.is_empty() || s.depths_mm.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        anyhow::bail!("--depths {:?}: expected positive depths (mm)", s.depths_mm);
    }
    let (bound, scene) = bound_to_scene(file, s.scene)?;
    let law = bound.law;
    let o = law.options;
    // As `tissue check`: a little past the deepest depth shows the hold and the flag,
    // but Newton far beyond would push the tool through the organ.
    let deepest_mm = 2.0 * o.depth_max_mm;
    if let Some(d) = s.depths_mm.iter().find(|d| **d > deepest_mm) {
        anyhow::bail!(
            "--depths: {d:?} mm: expected depths up to {deepest_mm} mm, twice the vademecum's \
             deepest ({} mm)",
            o.depth_max_mm
        );
    }
    let organ = s.organ.mesh()?;
    law.check_organ(&organ)?;
    let vertex_of = PointIndex::new(scene.vertices_mm().iter().map(|p| p.map(f64::from)));
    let mut contact_scratch = scene.contact_scratch();
    let mut coeffs = vec![0.0; scene.modes()];
    let rows = 3 * scene.vertices_mm().len();
    let (mut presses, mut newton_failed) = (Vec::new(), Vec::new());
    let t = Instant::now();
    for at in press_points(&organ, &law, None, s.heldout, s.seed)? {
        let (point, _) = scene
            .closest_palpable(at)
            .context("the scene has no palpable surface")?;
        let contact = scene.contact(&point, scene.modes(), &mut contact_scratch)?;
        eprint!("\rtradeoff: Newton at press {}   ", presses.len() + 1);
        let solved = newton_at_depths(&organ, &o, at, contact.push_dir, s.depths_mm);
        for (&depth_mm, solved) in s.depths_mm.iter().zip(solved) {
            let sol = match solved {
                Ok((sol, _)) => sol,
                Err(why) => {
                    newton_failed.push(json!({"at": at, "depth_mm": depth_mm, "why": why}));
                    continue;
                }
            };
            let c = contact.compliance_mm_per_n;
            let mut linear_rows = vec![0.0; rows];
            let push = contact.push_dir.map(|d| d * depth_mm / c);
            scene.displacement(&point, push, &mut coeffs, &mut linear_rows)?;
            presses.push(Press {
                at,
                point,
                compliance_mm_per_n: c,
                depth_mm,
                force_n: sol.force_n,
                reference: sol.u,
                linear_rows,
            });
        }
    }
    eprintln!();
    let reference_s = t.elapsed().as_secs_f64();
    // The linear model: what the app draws with no tissue file.
    let mut linear = Errors::default();
    for p in &presses {
        let f = p.depth_mm / p.compliance_mm_per_n;
        let ([e], _) = max_node_errors(&organ, &vertex_of, &p.reference, [&p.linear_rows]);
        linear.add(p, (f - p.force_n).abs() / p.force_n, e);
    }
    let mut table = Vec::new();
    let intervals = law.steps as usize - 1;
    let strides: Vec<usize> = (1..=intervals.min(5))
        .filter(|&k| intervals.is_multiple_of(k))
        .collect();
    let rank = law.rank as usize;
    let mut modes: Vec<usize> = std::iter::successors(Some(1), |m| Some(2 * m))
        .take_while(|&m| m < rank)
        .collect();
    modes.push(rank);
    // The law's own bits, and eight where it has sixteen.
    let mut precisions = vec![law.shape.bits()];
    if law.shape.bits() != ShapeBits::Eight {
        precisions.push(ShapeBits::Eight);
    }
    // One setting's row: the cut law bound to the scene and measured, with its knobs,
    // bytes, split triangles and bound.
    let row = |cut: TissueLaw, mut knobs: serde_json::Value| -> anyhow::Result<_> {
        knobs["payload_bytes"] = json!(cut.payload_bytes());
        knobs["split_triangles"] = json!(cut.refinement.triangles.len());
        knobs["truncation_bound_mm"] = json!(cut.truncation_bound_mm);
        let bound = BoundTissue::bind(
            cut,
            scene.vertices_mm(),
            scene.axis_vertices_mm(),
            scene.axis_triangles(),
        )?;
        Ok(measure(
            &bound,
            &presses,
            &organ,
            &vertex_of,
            s.depths_mm,
            &knobs,
        ))
    };
    for (&stride, &modes_max, &bits) in strides
        .iter()
        .flat_map(|s| modes.iter().map(move |m| (s, m)))
        .flat_map(|(s, m)| precisions.iter().map(move |b| (s, m, b)))
    {
        {
            let cut = match law.coarsened(modes_max, bits, stride) {
                Ok(cut) => cut,
                Err(why) => {
                    table.push(json!({"modes_max": modes_max, "bits": bits.count(),
                        "depth_step_mm": o.depth_step_mm * stride as f64, "refused": why}));
                    continue;
                }
            };
            table.push(row(
                cut.law,
                json!({"modes_max": modes_max, "bits": bits.count(),
                    "depth_step_mm": o.depth_step_mm * stride as f64,
                    "dropped_sigma_mm": cut.dropped_sigma_mm,
                    "requantized_mm": cut.requantized_mm}),
            )?);
        }
    }
    // The split knob: the same presses without the split triangles' points.
    if !law.refinement.triangles.is_empty() {
        table.push(row(
            law.unsplit(),
            json!({"modes_max": rank, "bits": law.shape.bits().count(),
                "depth_step_mm": o.depth_step_mm, "dropped_sigma_mm": 0.0,
                "requantized_mm": 0.0}),
        )?);
    }
    let report = json!({"law": o.law.name(), "element": o.element.name(),
        "depth_max_mm": law.depth_max_mm(), "held_out_points": s.heldout,
        "depths_mm": s.depths_mm, "seed": s.seed, "rows": table,
        "linear": linear.json(), "newton_failed": newton_failed,
        "newton_reference_s": reference_s});
    crate::cli::args::print_report(&report, json_out)
}

/// One setting's row: errors over all presses and per held-out depth, and the
/// on-line times (force and its inverse, force in and depth out as the gamepad's trigger
/// asks: means of many calls; surface: one whole-surface update). The inverse of each
/// answered force is held to its depth (`inverse_worst_mm`).
fn measure(
    bound: &BoundTissue,
    presses: &[Press],
    organ: &palpa_core::organ::OrganMesh,
    vertex_of: &PointIndex,
    depths_mm: &[f64],
    knobs: &serde_json::Value,
) -> serde_json::Value {
    let mut scratch = bound.scratch();
    let mut rows = vec![0.0; presses.first().map_or(0, |p| p.linear_rows.len())];
    let mut all = Errors::default();
    let mut by_depth: Vec<Errors> = depths_mm.iter().map(|_| Errors::default()).collect();
    let (mut force_s, mut force_calls, mut surface_s) = (0.0, 0usize, 0.0);
    let (mut inverse_s, mut inverse_worst_mm) = (0.0, 0.0f64);
    for p in presses {
        let (limit, _) = bound.limit_mm(&p.point);
        let at_depth = depths_mm.iter().position(|&d| d == p.depth_mm);
        if p.depth_mm > limit {
            all.past_limit += 1;
            if let Some(k) = at_depth {
                by_depth[k].past_limit += 1;
            }
            continue;
        }
        let t = Instant::now();
        let mut force = 0.0;
        for _ in 0..1000 {
            force = std::hint::black_box(bound.force_n(
                std::hint::black_box(&p.point),
                std::hint::black_box(p.depth_mm),
                p.compliance_mm_per_n,
            ))
            .0;
        }
        force_s += t.elapsed().as_secs_f64();
        force_calls += 1000;
        let t = Instant::now();
        let mut depth = 0.0;
        for _ in 0..1000 {
            depth = std::hint::black_box(bound.depth_mm(
                std::hint::black_box(&p.point),
                std::hint::black_box(force),
                p.compliance_mm_per_n,
            ))
            .0;
        }
        inverse_s += t.elapsed().as_secs_f64();
        inverse_worst_mm = inverse_worst_mm.max((depth - p.depth_mm).abs());
        rows.copy_from_slice(&p.linear_rows);
        let t = Instant::now();
        bound.add_surface(&p.point, p.depth_mm, &mut scratch, &mut rows);
        surface_s += t.elapsed().as_secs_f64();
        let ([e], _) = max_node_errors(organ, vertex_of, &p.reference, [&rows]);
        let f = (force - p.force_n).abs() / p.force_n;
        all.add(p, f, e);
        if let Some(k) = at_depth {
            by_depth[k].add(p, f, e);
        }
    }
    let mut row = knobs.clone();
    for (k, v) in all.json().as_object().into_iter().flatten() {
        row[k] = v.clone();
    }
    row["by_depth"] = json!(
        depths_mm
            .iter()
            .zip(&by_depth)
            .map(|(d, e)| {
                let mut v = e.json();
                v["depth_mm"] = json!(d);
                v
            })
            .collect::<Vec<_>>()
    );
    row["force_eval_us"] = json!((force_calls > 0).then(|| force_s / force_calls as f64 * 1e6));
    row["inverse_eval_us"] = json!((force_calls > 0).then(|| inverse_s / force_calls as f64 * 1e6));
    row["inverse_worst_mm"] = json!((force_calls > 0).then_some(inverse_worst_mm));
    row["surface_eval_us"] =
        json!((all.compared > 0).then(|| surface_s / all.compared as f64 * 1e6));
    row
}
