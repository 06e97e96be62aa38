//! A tissue file bound to the scene it was built for, and `palpa eval X.tissue`: the
//! force and surface at a probe point and depth, read from the vademecum (no solving).

use std::time::Instant;

use anyhow::{Context, bail};
use palpa_app::session::training::table_face;
use palpa_core::fe::nodule::Nodule;
use palpa_core::pgd::nodule::amplification::EffectCurve;
use palpa_core::pgd::nodule::table::{
    EffectTable, NoduleEffect, apply_surface_gain, depth_under_force,
};
use palpa_core::scene::{PalpationScene, ProbePoint};
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::surplus::BLEND_SURPLUS_WARN_MM;
use serde_json::json;

use super::build::goals_json;

/// A tissue file loaded and bound to the scene it serves (`liver` or a `.palpa` file).
pub(super) fn bound_to_scene(
    file: &std::path::Path,
    scene: &str,
) -> anyhow::Result<(BoundTissue, PalpationScene)> {
    let (bound, scene, _) = bound_to_scene_with_nodules(file, scene)?;
    Ok((bound, scene))
}

/// The effect of `nodule` at `point` over the depth: the linear effect `e` amplified by
/// the table's power of the tissue `tissue_xxh3` at the point's triangle's corners; flat
/// where the table holds none. With it, the seconds the amplification took to place
/// (`None`: not amplified).
pub(crate) fn effect_curve(
    table: &EffectTable,
    nodule: &Nodule,
    tissue_xxh3: u64,
    scene: &PalpationScene,
    point: &ProbePoint,
    e: f64,
) -> (EffectCurve, Option<f64>) {
    match (
        table.amplification(nodule, tissue_xxh3),
        &table.tissue_power,
    ) {
        (Some(a), Some(power)) => {
            let corners = scene
                .probe_vertices(point)
                .map(|v| power.vertex_at(scene.vertices_mm()[v as usize].map(f64::from)));
            (a.curve(corners, point.bary, e), Some(a.place_s))
        }
        _ => (EffectCurve::flat(e), None),
    }
}

/// As [`bound_to_scene`], with the scene's nodule table (the built-in liver's, or the
/// `.nodules` file beside a scene file) where it has one.
pub(crate) fn bound_to_scene_with_nodules(
    file: &std::path::Path,
    scene: &str,
) -> anyhow::Result<(BoundTissue, PalpationScene, Option<EffectTable>)> {
    let law = TissueLaw::load(file)?;
    let loaded = palpa_app::scenes::load(scene)?;
    let scene = loaded.scene;
    law.check_linear_model(&scene.model().provenance().mesh)?;
    let bound = BoundTissue::bind(
        law,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )?;
    Ok((bound, scene, loaded.nodules))
}

/// The nodule table that answers for `scene` (`--nodules` where given, else the
/// scene's own), checked to be of its mesh, and `nodule` placed in it.
pub(crate) fn placed_nodule(
    nodule: &Nodule,
    given: Option<&std::path::Path>,
    own: Option<EffectTable>,
    scene: &PalpationScene,
    scene_name: &str,
) -> anyhow::Result<(EffectTable, NoduleEffect)> {
    let (table, name) = match given {
        Some(path) => (
            EffectTable::load(path).with_context(|| {
                format!(
                    "reading the nodule table {} (`palpa nodule build` writes one for a scene)",
                    path.display()
                )
            })?,
            path.display().to_string(),
        ),
        None => (
            own.with_context(|| {
                format!(
                    "--nodule-at: the scene {scene_name} has no nodule table (expected \
                     `palpa nodule build` to have written one beside it, or --nodules FILE)"
                )
            })?,
            format!("the nodule table of {scene_name}"),
        ),
    };
    table
        .check_mesh(&scene.model().provenance().mesh)
        .with_context(|| format!("{name} for the scene {scene_name}"))?;
    let effect = table
        .place(nodule)
        .with_context(|| format!("the nodule in {name}"))?;
    Ok((table, effect))
}

/// `F_with/F_without − 1` of `effect` at the scene's probe point `point`: an error
/// naming the face where the table has none there.
pub(crate) fn effect_at_point(
    table: &EffectTable,
    effect: &NoduleEffect,
    scene: &PalpationScene,
    point: &ProbePoint,
) -> anyhow::Result<f64> {
    table_face(table, scene, point.triangle)
        .and_then(|f| effect.at(table, f, point.bary))
        .with_context(|| {
            format!(
                "the probe point's triangle {} lies beyond the nodule table's probe nodes \
                 (it covers the palpable surface within reach of its lattice)",
                point.triangle
            )
        })
}

/// `palpa eval` on a tissue file: the press at the palpable point closest to `--at`,
/// through the scene the file serves, depth in (force out) or force in (depth out),
/// with the same keys as `palpa fe solve`. The vademecum presses along the surface's
/// vertex normal (each vertex was pressed along its own), so `--dir` is refused.
pub fn eval(
    file: &std::path::Path,
    probe: &crate::cli::args::ProbeArgs,
    scene_name: &str,
    nodule: Option<(Nodule, Option<&std::path::Path>)>,
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
    let (bound, scene, own_table) = bound_to_scene_with_nodules(file, scene_name)?;
    let (point, distance_mm) = scene
        .closest_palpable(at)
        .context("the scene has no palpable surface")?;
    crate::cli::args::warn_far_from_surface(distance_mm, scene.frame(&point).0);
    let mut contact_scratch = scene.contact_scratch();
    let contact = scene.contact(&point, scene.modes(), &mut contact_scratch)?;
    let c = contact.compliance_mm_per_n;
    // A nodule multiplies the force at depth `d` by `1 + e A(d)`: `e` the linear
    // tissue's effect from the scene's table, `A` the amplification by the tissue's own
    // press where the table holds its power, as the app's force loop does
    // (docs/methods.md §2i).
    let nodule = match nodule {
        Some((n, given)) => {
            let (table, placed) = placed_nodule(&n, given, own_table, &scene, scene_name)?;
            let e = effect_at_point(&table, &placed, &scene, &point)?;
            let (curve, amplify_s) =
                effect_curve(&table, &n, bound.law.payload_xxh3(), &scene, &point, e);
            Some((placed, e, curve, amplify_s))
        }
        None => None,
    };
    let curve = nodule.as_ref().map_or(EffectCurve::flat(0.0), |n| n.2);
    let gain = |depth_mm: f64| 1.0 + curve.at(depth_mm);
    let t = Instant::now();
    let (depth, force, beyond) = match (probe.depth_mm, probe.force_n) {
        (Some(d), _) => {
            // Past the limit both the force and the surface are held at it.
            let (f, beyond) = bound.force_n(&point, d, c);
            let d = d.min(bound.limit_mm(&point).0);
            (d, gain(d) * f, beyond)
        }
        (None, Some(f)) => {
            let (d, beyond) = depth_under_force(f, &curve, |f| bound.depth_mm(&point, f, c));
            // Held at the limit, the press is the one there: its force, not the one
            // asked for (that is `requested_force_n`).
            let f = if beyond {
                gain(d) * bound.force_n(&point, d, c).0
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
    // With a nodule, the organ sways away from the tool with the larger force.
    apply_surface_gain(
        curve.at(depth),
        scene.frame(&point).0,
        scene.vertices_mm().iter().map(|p| p.map(f64::from)),
        &mut rows,
    );
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
    let mut report = json!({
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
        "nodule": null,
    });
    if let Some((placed, e_linear, curve, amplify_s)) = &nodule {
        let n = placed.nodule;
        let amplified = curve.len > 0;
        report["nodule"] = json!({"center_mm": n.center_mm, "radius_mm": n.radius_mm,
            "ratio": n.ratio, "effect": gain(depth) - 1.0, "effect_linear": e_linear,
            "amplified": amplified, "place_ms": placed.place_s * 1e3,
            "amplify_ms": amplify_s.map(|s| s * 1e3),
            "force_without_nodule_n": force / gain(depth),
            "effect_source": if amplified {
                "the linear tissue's from the scene's nodule table, amplified as the tissue's own press loads the nodule (the table's power of this tissue)"
            } else {
                "the linear tissue's from the scene's nodule table, not amplified: the table holds no power of this tissue (palpa nodule tissue)"
            },
            "surface": "the tissue's without the nodule, at the press's depth"});
    }
    crate::cli::args::print_report(&report, json_out)
}
