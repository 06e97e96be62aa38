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
use palpa_core::pgd::tissue::{BoundTissue, PointIndex, TissueScratch};
use palpa_core::scene::ProbePoint;
use serde_json::json;

use super::tissue::bound_to_scene;
use super::tissue_check::max_node_errors;

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
        organ: &palpa_core::organ::OrganMesh,
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
