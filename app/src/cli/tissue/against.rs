//! `palpa tissue check --against OTHER.tissue`: a second tissue file answered at the
//! same presses as the first, against the same Newton solves.
//!
//! A refinement stage or a cut is judged by what it changes at held-out presses. The
//! Newton reference is nearly all of a check's time (10–20 s a press on coarse P2,
//! minutes on medium), and it depends only on the press (point, depth, push, material),
//! not on the file, so two files compared in one run share it: half the time of two
//! checks, and the two answers differ only by the files. Each compared press reports
//! the other file's errors and whether its answer differs from the first file's at
//! all (a triangle a stage did not split, nor any neighbour's fade reach, answers to
//! the last bit as before).

use std::path::Path;

use anyhow::{Context, bail};
use palpa_core::organ::OrganMesh;
use palpa_core::scene::ProbePoint;
use palpa_core::tissue::bound::{BoundTissue, TissueScratch};
use palpa_core::tissue::law::PointIndex;
use serde_json::json;

use super::eval::bound_to_scene;

/// The other file, bound to the same scene, with its own scratch and running worst.
pub(super) struct Against {
    file: String,
    bound: BoundTissue,
    scratch: TissueScratch,
    rows: Vec<f64>,
    worst_force: f64,
    worst_surface: f64,
    compared: usize,
    past_limit: usize,
    changed: usize,
}

/// What the check's main file answered at one press, for the other to be compared with.
pub(super) struct Answer<'a> {
    pub point: &'a ProbePoint,
    pub depth_mm: f64,
    pub compliance_mm_per_n: f64,
    /// The scene's linear surface at this press (the rows both files add to).
    pub linear_rows: &'a [f64],
    /// The main file's surface and force there.
    pub tissue_rows: &'a [f64],
    pub force_n: f64,
}

impl Against {
    /// Loads `file` for the scene `scene`; refused where it was built for another
    /// element, material law, material or tool than `main` (its errors would then
    /// measure another model, not another sampling of the same one).
    pub fn open(file: &Path, scene: &str, main: &BoundTissue) -> anyhow::Result<Self> {
        let (bound, _) =
            bound_to_scene(file, scene).with_context(|| format!("--against {}", file.display()))?;
        let (a, b) = (&main.law.options, &bound.law.options);
        if (a.law, a.material, a.element, a.tool_radius_mm)
            != (b.law, b.material, b.element, b.tool_radius_mm)
        {
            bail!(
                "--against {}: built for {} {} (E {} kPa, ν {}, tool {} mm), the checked file for \
                 {} {} (E {} kPa, ν {}, tool {} mm): expected a file of the same model",
                file.display(),
                b.law.name(),
                b.element.name(),
                b.material.young_kpa,
                b.material.poisson,
                b.tool_radius_mm,
                a.law.name(),
                a.element.name(),
                a.material.young_kpa,
                a.material.poisson,
                a.tool_radius_mm,
            );
        }
        let scratch = bound.scratch();
        Ok(Against {
            file: file.display().to_string(),
            bound,
            scratch,
            rows: Vec::new(),
            worst_force: 0.0,
            worst_surface: 0.0,
            compared: 0,
            past_limit: 0,
            changed: 0,
        })
    }

    /// The other file at one press Newton answered (`reference` its displacement,
    /// `reference_force_n` its force): its force and surface errors, its finest
    /// surplus, and whether it answers differently from the main file. A press past
    /// the other file's own limit is reported, not compared.
    pub fn press(
        &mut self,
        organ: &OrganMesh,
        vertex_of: &PointIndex,
        reference: &[f64],
        reference_force_n: f64,
        main: &Answer,
    ) -> serde_json::Value {
        let (limit, stopped) = self.bound.limit_mm(main.point);
        let (force, beyond) =
            self.bound
                .force_n(main.point, main.depth_mm, main.compliance_mm_per_n);
        self.rows.clear();
        self.rows.extend_from_slice(main.linear_rows);
        self.bound
            .add_surface(main.point, main.depth_mm, &mut self.scratch, &mut self.rows);
        let ([surface], _) = max_node_errors(organ, vertex_of, reference, [&self.rows]);
        let force_err = (force - reference_force_n).abs() / reference_force_n;
        // Bit for bit: a press both files blend from the same stored samples.
        let changed = force != main.force_n || self.rows.as_slice() != main.tissue_rows;
        let mut row = json!({
            "force_n": force,
            "force_rel_error": force_err,
            "surface_max_error_mm": surface,
            "blend_surplus_mm": self.bound.blend_surplus_mm(main.point, main.depth_mm),
            "beyond": beyond,
            "changed": changed,
        });
        if main.depth_mm > limit {
            row["limit_mm"] = json!(limit);
            row["stopped"] = json!(stopped);
            self.past_limit += 1;
        } else {
            self.worst_force = self.worst_force.max(force_err);
            self.worst_surface = self.worst_surface.max(surface);
            self.compared += 1;
            self.changed += usize::from(changed);
        }
        row
    }

    /// The summary's `against` entry: the other file's worst errors over the presses
    /// both compared, and how many of them it answered differently.
    pub fn summary(&self) -> serde_json::Value {
        json!({
            "file": self.file,
            "presses_compared": self.compared,
            "presses_past_limit": self.past_limit,
            "presses_changed": self.changed,
            "worst_force_rel_error": self.worst_force,
            "worst_surface_max_error_mm": self.worst_surface,
            "goal_force_5_percent": (self.compared > 0).then_some(self.worst_force <= 0.05),
            "goal_surface_0_5_mm": (self.compared > 0).then_some(self.worst_surface <= 0.5),
        })
    }
}

pub(crate) use palpa_core::tissue::law::max_node_errors;

/// Where the vademecum's surface errs most at one press, and how the error falls off
/// away from the tool: the worst node's distance from the probe and the part of its
/// error along the push (a depth error) against the rest (tissue sliding sideways
/// under the tool), and the largest error in shells 0–1, 1–2, 2–4, 4–8 and past 8 tool
/// radii from the probe.
pub(super) fn worst_node(
    organ: &OrganMesh,
    vertex_of: &PointIndex,
    reference: &[f64],
    rows: &[f64],
    at: [f64; 3],
    push: [f64; 3],
    tool_radius_mm: f64,
) -> serde_json::Value {
    const RINGS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];
    let mut ring_max = [0.0f64; RINGS.len() + 1];
    let (mut worst, mut from_probe, mut along) = (0.0f64, 0.0, 0.0);
    for v in organ.surface_nodes() {
        let x = organ.mesh.vertices[v as usize];
        let Some(r) = vertex_of.find(x) else {
            continue;
        };
        let (i, r) = (3 * v as usize, 3 * r as usize);
        let e = [0, 1, 2].map(|k| rows[r + k] - reference[i + k]);
        let size = e.iter().map(|c| c * c).sum::<f64>().sqrt();
        let dist = (0..3).map(|k| (x[k] - at[k]).powi(2)).sum::<f64>().sqrt();
        let ring = RINGS
            .iter()
            .position(|&m| dist <= m * tool_radius_mm)
            .unwrap_or(RINGS.len());
        ring_max[ring] = ring_max[ring].max(size);
        if size > worst {
            worst = size;
            from_probe = dist;
            along = (0..3).map(|k| e[k] * push[k]).sum();
        }
    }
    json!({"error_mm": worst, "from_probe_mm": from_probe, "along_push_mm": along,
        "max_error_mm_by_tool_radii": {"0-1": ring_max[0], "1-2": ring_max[1],
            "2-4": ring_max[2], "4-8": ring_max[3], "8-": ring_max[4]}})
}
