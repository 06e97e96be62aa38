//! A tissue file bound to the scene it was built for, and `palpa eval X.tissue`: the
//! force and surface at a probe point and depth, read from the vademecum (no solving).

use std::time::Instant;

use anyhow::{Context, bail};
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::surplus::BLEND_SURPLUS_WARN_MM;
use serde_json::json;

use super::build::goals_json;

/// A tissue file loaded and bound to the scene it serves (`liver` or a `.palpa` file).
pub(super) fn bound_to_scene(
    file: &std::path::Path,
    scene: &str,
) -> anyhow::Result<(BoundTissue, palpa_core::scene::PalpationScene)> {
    let law = TissueLaw::load(file)?;
    let scene = palpa_app::scenes::load(scene)?.scene;
    law.check_linear_model(&scene.model().provenance().mesh)?;
    let bound = BoundTissue::bind(
        law,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )?;
    Ok((bound, scene))
}

/// `palpa eval` on a tissue file: the press at the palpable point closest to `--at`,
/// through the scene the file serves, depth in (force out) or force in (depth out),
/// with the same keys as `palpa fe solve`. The vademecum presses along the surface's
/// vertex normal (each vertex was pressed along its own), so `--dir` is refused.
pub fn eval(
    file: &std::path::Path,
    probe: &crate::cli::args::ProbeArgs,
    scene: &str,
    out: Option<&std::path::Path>,
    json_out: bool,
) -> anyhow::Result<()> {
    if probe.dir.is_some() {
        bail!(
            "--dir: a tissue vademecum presses along the surface normal, the direction its \
             vertices were pressed in; leave --dir out"
        );
    }
    let at = probe.at()?;
    probe.check_press()?;
    let (bound, scene) = bound_to_scene(file, scene)?;
    let (point, distance_mm) = scene
        .closest_palpable(at)
        .context("the scene has no palpable surface")?;
    crate::cli::args::warn_far_from_surface(distance_mm, scene.frame(&point).0);
    let mut contact_scratch = scene.contact_scratch();
    let contact = scene.contact(&point, scene.modes(), &mut contact_scratch)?;
    let c = contact.compliance_mm_per_n;
    let t = Instant::now();
    let (depth, force, beyond) = match (probe.depth_mm, probe.force_n) {
        (Some(d), _) => {
            // Past the limit both the force and the surface are held at it.
            let (f, beyond) = bound.force_n(&point, d, c);
            (d.min(bound.limit_mm(&point).0), f, beyond)
        }
        (None, Some(f)) => {
            let (d, beyond) = bound.depth_mm(&point, f, c);
            // Held at the limit, the press is the one there: its force, not the one
            // asked for (that is `requested_force_n`).
            let f = if beyond {
                bound.force_n(&point, d, c).0
            } else {
                f
            };
            (d, f, beyond)
        }
        (None, None) => bail!("give --depth-mm or --force-n"),
    };
    let force_eval_us = t.elapsed().as_secs_f64() * 1e6;
    let mut coeffs = vec![0.0; scene.modes()];
    let mut rows = vec![0.0; 3 * scene.vertices_mm().len()];
    let mut scratch = bound.scratch();
    let t = Instant::now();
    let push = contact.push_dir.map(|d| d * depth / c);
    scene.displacement(&point, push, &mut coeffs, &mut rows)?;
    bound.add_surface(&point, depth, &mut scratch, &mut rows);
    let surface_eval_us = t.elapsed().as_secs_f64() * 1e6;
    let max = rows
        .chunks_exact(3)
        .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .fold(0.0, f64::max);
    if let Some(out) = out {
        use palpa_core::export::{FieldValue, Holds, PointField, write_surface_vtu};
        let nodes: Vec<[f64; 3]> = scene
            .vertices_mm()
            .iter()
            .map(|p| p.map(f64::from))
            .collect();
        let fields = [PointField {
            name: "displacement".into(),
            components: 3,
            values: rows.clone(),
        }];
        let meta = [
            FieldValue {
                name: "force_n".into(),
                value: force,
            },
            FieldValue {
                name: "depth_mm".into(),
                value: depth,
            },
        ];
        write_surface_vtu(
            out,
            &nodes,
            scene.triangles(),
            Holds::Surface,
            &fields,
            &meta,
        )
        .with_context(|| format!("writing {}", out.display()))?;
    }
    let (limit_mm, stopped) = bound.limit_mm(&point);
    if beyond {
        let asked = match probe.force_n {
            Some(f) => format!("{f:.2} N"),
            None => format!("{:.2} mm", probe.depth_mm.unwrap_or(depth)),
        };
        eprintln!(
            "warning: {} (asked {asked})",
            palpa_app::session::held_text(limit_mm, stopped)
        );
    }
    let surplus_mm = bound.blend_surplus_mm(&point, depth);
    if let Some(eta) = surplus_mm.filter(|&e| e > BLEND_SURPLUS_WARN_MM) {
        eprintln!("warning: {}", palpa_app::session::blend_surplus_text(eta));
    }
    // Past the depth the file is measured within the goals to, as the panel says it.
    let goals = palpa_app::session::GoalDepths::of(&bound.law);
    if let Some(g) = goals.filter(|g| depth > f64::from(g.both_mm)) {
        eprintln!("warning: {}", g.past_text(depth as f32));
    }
    let unpressed = bound.unpressed_corners(&point);
    if unpressed > 0 {
        eprintln!(
            "warning: {}",
            palpa_app::session::next_to_fixed_text(unpressed)
        );
    }
    let report = json!({
        "model": "tissue", "law": bound.law.options.law.name(),
        "element": bound.law.options.element.name(),
        "at": scene.frame(&point).0,
        // The keys of `palpa fe solve`, which presses along the same direction by default.
        "probe_point": scene.frame(&point).0, "probe_projection_distance_mm": distance_mm,
        "direction": contact.push_dir,
        "control": if probe.force_n.is_some() { "force" } else { "depth" },
        "probe_displacement_mm": depth, "force_n": force, "linear_force_n": depth / c,
        "requested_force_n": probe.force_n, "requested_depth_mm": probe.depth_mm,
        "max_displacement_mm": max, "depth_max_mm": bound.law.depth_max_mm(),
        "beyond_depth_max": beyond,
        "depth_limit_mm": limit_mm, "stopped": stopped,
        "blend_surplus_mm": surplus_mm,
        "unpressed_corners": unpressed,
        // Measured within the goals to these depths (the built-in tissue), else null.
        "goals_to_mm": goals_json(goals),
        "force_eval_us": force_eval_us, "surface_eval_us": surface_eval_us,
    });
    crate::cli::args::print_report(&report, json_out)
}
