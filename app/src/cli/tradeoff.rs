//! `palpa tradeoff FILE`: the measured speed/accuracy table of a palpation vademecum,
//! for n = 1 … N modes in log steps, written into the file's header (what the app's
//! accuracy knob reads) and printed.
//!
//! Accuracy is measured two ways: at held-out probe positions (seeded random interior
//! points of random palpable triangles, never nodes) against full FE solves with the
//! same factored stiffness (relative L2 error over the surface nodes, and relative
//! error of the probe displacement along the load), and over the whole nodal solution
//! map in the natural norm against the optimal rank-n approximation (Eckart–Young;
//! computed by default on coarse, `--svd` elsewhere: one FE solve per palpable node
//! and direction).
//!
//! A nodule table (`S.nodules`) gets the table of its knobs (`cli::nodule::tradeoff`).
//! A tissue file (`X.tissue`) gets its own table, over its modes and depth step with
//! errors at held-out points and depths against Newton (`tissue::tradeoff`); `--depths`,
//! `--scene`, `--seed` and the organ options apply to it only, `--svd` and `--plot` to a
//! scene only; either given to the other kind is refused, not ignored.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::TradeoffRow;
use palpa_core::axis::Discretization;
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::pgd::palpation::{describe, describe_get};
use palpa_core::pgd::tradeoff::pgd_table;
use serde_json::json;

use super::organ::{LevelArg, OrganName, mesh as mesh_organ};

#[derive(Debug, Args)]
pub struct TradeoffArgs {
    file: PathBuf,
    /// Random held-out probe positions (default 24; a nodal model adds two near the
    /// fixed region, two on the sharpest border and two on the left lobe; a tissue
    /// file: 4, each pressed at every `--depths`).
    #[arg(long)]
    held_out: Option<usize>,
    /// A tissue file's held-out depths (mm), off its depth grids [default: 2.6,7.3,12.7].
    #[arg(long, value_delimiter = ',')]
    depths: Option<Vec<f64>>,
    /// A tissue file's scene: `liver` (built in) or a `.palpa` file of its mesh
    /// [default: liver].
    #[arg(long)]
    scene: Option<String>,
    /// Seed of the held-out points (tissue files) [default: 7].
    #[arg(long)]
    seed: Option<u64>,
    /// The organ a tissue file was built on (a vademecum's own file names it).
    #[command(flatten)]
    organ: super::args::OrganArgs,
    /// Compute the optimal (SVD) errors even above the coarse level.
    #[arg(long)]
    svd: bool,
    #[arg(long)]
    json: bool,
    /// Also plot error and evaluation time against the number of modes (PNG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

pub fn run(args: &TradeoffArgs) -> anyhow::Result<()> {
    if args.held_out == Some(0) {
        bail!("--held-out 0: expected at least one point to measure at");
    }
    if let Some(n) = args.held_out {
        super::tissue::points::check_heldout(n)?;
    }
    let o = &args.organ;
    let (tissue_only, scene_only) = (
        [
            ("--depths", args.depths.is_some()),
            ("--scene", args.scene.is_some()),
            ("--seed", args.seed.is_some()),
        ],
        [("--svd", args.svd), ("--plot", args.plot.is_some())],
    );
    let first = |flags: &[(&'static str, bool)]| flags.iter().find(|f| f.1).map(|f| f.0);
    if palpa_core::pgd::nodule::table::is_table_file(&args.file) {
        let held_out = [("--held-out", args.held_out.is_some())];
        if let Some(flag) = first(&tissue_only)
            .or(first(&scene_only))
            .or(first(&held_out))
        {
            bail!(
                "{flag} does not apply to a nodule table, whose knobs are measured at the held-out pairs its checks recorded"
            );
        }
        return super::nodule::tradeoff(&args.file, &args.organ, args.json);
    }
    if palpa_core::tissue::law::is_tissue_file(&args.file) {
        if let Some(flag) = first(&scene_only) {
            bail!(
                "{flag} applies to a scene's table (modes against the linear FE); {} is a \
                 tissue file, whose table is measured against Newton at held-out depths",
                args.file.display()
            );
        }
        let settings = super::tissue::tradeoff::Settings {
            organ: &args.organ,
            scene: args.scene.as_deref().unwrap_or("liver"),
            heldout: args.held_out.unwrap_or(4),
            depths_mm: args.depths.as_deref().unwrap_or(&[2.6, 7.3, 12.7]),
            seed: args.seed.unwrap_or(7),
        };
        return super::tissue::tradeoff::run(&args.file, &settings, args.json);
    }
    let flag = first(&tissue_only).or_else(|| o.surface_flags().first().copied());
    if let Some(flag) = flag {
        bail!(
            "{flag} applies to a tissue file's table; {} is a scene, whose table needs \
             no more than the file (its level, material and held-out points are its own)",
            args.file.display()
        );
    }
    let held_out = args.held_out.unwrap_or(24);
    let header = file::read_header(&args.file)
        .with_context(|| format!("reading the header of {}", args.file.display()))?;
    if describe_get(&header.meta.provenance.mesh, "organ") == Some("user") {
        bail!(
            "{}: a scene built from a surface file by `palpa scene build`, which measured its \
             table then (`palpa info` shows it); rebuild it with `palpa scene build` to measure again",
            args.file.display()
        );
    }
    if header.precision != palpa_core::Precision::F64 {
        bail!(
            "{}: stored in {}, as `palpa export-scene` ships a scene; the tradeoff is measured \
             on the full vademecum `palpa offline` writes (f64), before export (`palpa info` \
             shows the table it measured then)",
            args.file.display(),
            header.precision.name()
        );
    }
    let model = file::load::<f64>(&args.file)
        .with_context(|| format!("loading {}", args.file.display()))?;
    let desc = model.provenance().mesh.clone();
    let level: LevelArg = match describe_get(&desc, "level") {
        Some("coarse") => LevelArg::Coarse,
        Some("medium") => LevelArg::Medium,
        Some("fine") => LevelArg::Fine,
        other => bail!(
            "{}: provenance names no known level ({other:?}); was it made by palpa offline?",
            args.file.display()
        ),
    };
    let element: Element = describe_get(&desc, "element")
        .unwrap_or("p2")
        .parse()
        .map_err(anyhow::Error::msg)?;
    let radius_mm: f64 = describe_get(&desc, "radius_mm").unwrap_or("5").parse()?;
    let update = describe_get(&desc, "update") == Some("true");
    let organ = mesh_organ(OrganName::Liver, level)?;
    // The material its provenance names (the defaults where an older file names none).
    let number = |key: &str, default: f64| -> anyhow::Result<f64> {
        describe_get(&desc, key).map_or(Ok(default), |v| {
            v.parse()
                .with_context(|| format!("provenance {key}={v}: expected a number"))
        })
    };
    let material = Material {
        young_kpa: number("young_kpa", Material::default().young_kpa)?,
        poisson: number("poisson", Material::default().poisson)?,
    };
    if describe(
        &organ,
        &format!("{level:?}").to_lowercase(),
        element,
        material,
        radius_mm,
        update,
    ) != desc
    {
        bail!(
            "{}: the organ mesh or settings changed since this vademecum was computed; recompute it",
            args.file.display()
        );
    }
    if let Some(Discretization::SurfaceLoad { .. }) =
        model.axes().first().map(|a| &a.info.discretization)
    {
        return run_nodal(args, held_out, model, &organ, element, material, radius_mm);
    }
    let t = pgd_table(
        &model,
        &organ,
        element,
        material,
        radius_mm,
        held_out,
        level == LevelArg::Coarse || args.svd,
    )?;
    let (rows, surface_optimum) = (t.rows, t.surface_optimum);
    let mut model = model;
    model.set_tradeoff(rows.clone());
    file::save(&model, &args.file).with_context(|| format!("writing {}", args.file.display()))?;
    let json_rows: Vec<_> = rows
        .iter()
        .zip(&surface_optimum)
        .map(|(r, surf_opt)| {
            json!({"modes": r.modes, "surface_rel_error": r.surface_rel_error, "probe_rel_error": r.probe_rel_error,
                   "svd_surface_map_rel_error": surf_opt,
                   "map_rel_error": r.map_rel_error, "svd_rel_error": r.svd_rel_error,
                   "pgd_over_svd": r.map_rel_error.zip(r.svd_rel_error).map(|(a, b)| a / b),
                   "surface_eval_us": r.surface_eval_us, "contact_eval_ns": r.contact_eval_ns, "bytes": r.bytes})
        })
        .collect();
    let (floor_surf, floor_probe) = t.floor;
    if let Some(path) = &args.plot {
        plot(&rows, &surface_optimum, path)?;
    }
    let out = json!({"rows": json_rows, "held_out": held_out,
                     "s_interpolation_floor": {"surface_rel_error": floor_surf, "probe_rel_error": floor_probe},
                     "brute_force_solve_s": t.brute_force_solve_s});
    super::args::print_report(&out, args.json)
}

/// The tradeoff of a nodal-load vademecum (measured by `palpa_core::pgd::tradeoff`),
/// stored in the file's header and printed.
fn run_nodal(
    args: &TradeoffArgs,
    held_out: usize,
    model: palpa_core::SeparatedModel<f64>,
    organ: &palpa_core::organ::OrganMesh,
    element: Element,
    material: Material,
    radius_mm: f64,
) -> anyhow::Result<()> {
    use palpa_core::pgd::tradeoff::nodal_table;
    let t = nodal_table(&model, organ, element, material, radius_mm, held_out)?;
    let worst = |e: &palpa_core::pgd::heldout::Errors| {
        let c = &t.cases[e.worst_surface_case];
        json!({"kind": c.kind, "point_mm": c.point})
    };
    let rows = t.header_rows();
    let json_rows: Vec<_> = t
        .rows
        .iter()
        .map(|r| {
            let (e, b) = (&r.errors, &r.without_near);
            json!({
                "modes": r.modes, "surface_rel_error": e.surface_rel_error,
                "probe_rel_error": e.compliance_rel_error,
                "compliance_rel_error": e.compliance_rel_error,
                "surface_max_nodal_error_mm": e.surface_max_nodal_error_mm,
                "surface_max_nodal_rel_error": e.surface_max_nodal_rel_error,
                "worst_surface_case": worst(e),
                "map_rel_error": null, "svd_rel_error": null,
                "without_near_field": {"surface_rel_error": b.surface_rel_error,
                                       "surface_max_nodal_error_mm": b.surface_max_nodal_error_mm,
                                       "compliance_rel_error": b.compliance_rel_error},
                "surface_eval_us": r.surface_eval_us, "contact_eval_ns": r.contact_eval_ns,
                "bytes": r.bytes,
            })
        })
        .collect();
    let far_rows: Vec<_> = t
        .far_rows
        .iter()
        .map(|r| {
            let e = &r.errors;
            json!({
                "far_tolerance": r.tolerance, "modes": r.modes,
                "surface_rel_error": e.surface_rel_error,
                "surface_max_nodal_error_mm": e.surface_max_nodal_error_mm,
                "surface_max_nodal_rel_error": e.surface_max_nodal_rel_error,
                "compliance_rel_error": e.compliance_rel_error,
                "surface_eval_us": r.surface_eval_us, "bytes": r.bytes,
            })
        })
        .collect();
    let mut model = model;
    model.set_tradeoff(rows.clone());
    file::save(&model, &args.file).with_context(|| format!("writing {}", args.file.display()))?;
    if let Some(path) = &args.plot {
        plot(&rows, &vec![None; rows.len()], path)?;
    }
    let kinds: Vec<&str> = t.cases.iter().map(|c| c.kind).collect();
    let out = json!({"rows": json_rows, "far_rows": far_rows, "held_out": t.cases.len(),
                     "held_out_kinds": kinds, "method": "nodal",
                     "fe_reference_s": t.fe_reference_s});
    super::args::print_report(&out, args.json)
}

/// Error and time against modes, two log–log panels.
fn plot(
    rows: &[TradeoffRow],
    surface_optimum: &[Option<f64>],
    path: &std::path::Path,
) -> anyhow::Result<()> {
    use super::plot::{Panel, Series, write_png};
    let series = |name: &str, f: &dyn Fn(usize, &TradeoffRow) -> Option<f64>| Series {
        name: name.into(),
        points: rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| f(i, r).map(|v| [f64::from(r.modes), v]))
            .collect(),
    };
    let mut errors = vec![
        series("surface, held-out (max)", &|_, r| Some(r.surface_rel_error)),
        series("probe, held-out (max)", &|_, r| Some(r.probe_rel_error)),
    ];
    if rows.iter().any(|r| r.compliance_rel_error.is_some()) {
        errors.push(series("compliance, held-out (max)", &|_, r| {
            r.compliance_rel_error
        }));
        errors.push(series("surface max nodal error at 1 N (mm)", &|_, r| {
            r.surface_max_nodal_error_mm
        }));
    }
    if rows.iter().any(|r| r.map_rel_error.is_some()) {
        errors.push(series("map, PGD", &|_, r| r.map_rel_error));
        errors.push(series("map, optimal rank n", &|_, r| r.svd_rel_error));
        errors.push(series("surface map, optimal rank n", &|i, _| {
            surface_optimum[i]
        }));
    }
    let panels = [
        Panel {
            title: "relative error".into(),
            x_label: "modes n".into(),
            y_label: "relative error".into(),
            series: errors,
        },
        Panel {
            title: "evaluation time".into(),
            x_label: "modes n".into(),
            y_label: "µs".into(),
            series: vec![
                series("whole surface (µs)", &|_, r| Some(r.surface_eval_us)),
                series("contact, 3 nodes (µs)", &|_, r| {
                    Some(r.contact_eval_ns * 1e-3)
                }),
            ],
        },
    ];
    write_png(&panels, 1400, 560, path)
}
