//! `palpa fe solve`: one full finite-element solve of a probe load.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand, ValueEnum};
use palpa_core::export::{FieldValue, PointField, write_by_extension};
use palpa_core::fe::law::Law;
use palpa_core::fe::newton::NewtonSettings;
use palpa_core::fe::probe::{
    ProbeRequest, request_space, smooth_inward_dir, solve_hyperelastic, solve_linear,
    solve_linear_depth, solve_series,
};
use palpa_core::fe::{Element, Material};
use serde_json::json;

use super::args::{NoduleArgs, OrganArgs, ProbeArgs};

#[derive(Debug, Subcommand)]
pub enum FeCommand {
    /// Solve the probe problem on the full FE model.
    Solve(SolveArgs),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Method {
    Newton,
    Series,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Model {
    Linear,
    /// Saint Venant–Kirchhoff (geometrically and materially nonlinear), Newton.
    Svk,
    /// Compressible neo-Hookean (stable in strong compression), Newton.
    NeoHookean,
}

impl Model {
    fn law(self) -> Option<Law> {
        match self {
            Model::Linear => None,
            Model::Svk => Some(Law::Svk),
            Model::NeoHookean => Some(Law::NeoHookean),
        }
    }
}

#[derive(Debug, Args)]
pub struct SolveArgs {
    #[command(flatten)]
    organ: OrganArgs,
    #[command(flatten)]
    probe: ProbeArgs,
    #[command(flatten)]
    nodule: NoduleArgs,
    /// Tool radius (mm): the force is spread over the surface within it.
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    #[arg(long, value_enum, default_value = "linear")]
    model: Model,
    /// Hyperelastic depth control: Newton steps to the depth, or the depth's power
    /// series (one linear solve per order with the rest stiffness).
    #[arg(long, value_enum, default_value = "newton")]
    method: Method,
    /// Series: orders kept (default 12).
    #[arg(long)]
    orders: Option<usize>,
    #[arg(long, default_value = "p2")]
    element: Element,
    #[arg(long, default_value_t = 160.0)]
    young_kpa: f64,
    #[arg(long, default_value_t = 0.48)]
    poisson: f64,
    /// Write the solution (.vtu or .msh).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: &FeCommand) -> anyhow::Result<()> {
    match cmd {
        FeCommand::Solve(args) => solve(args),
    }
}

fn solve(args: &SolveArgs) -> anyhow::Result<()> {
    let t = Instant::now();
    // No `check_press`: the reference answers a pull too (the tool glued to the
    // surface), which the scenes and tissue files do not.
    let at = args.probe.at()?;
    if let Some(out) = &args.out {
        super::args::check_out(out)?;
    }
    let dir = args.probe.dir()?;
    let material = Material {
        young_kpa: args.young_kpa,
        poisson: args.poisson,
    };
    let organ = args.organ.mesh()?;
    // Unless told otherwise, along the direction the app and the tissue press.
    let dir = match dir {
        Some(d) => Some(d),
        None => Some(smooth_inward_dir(&organ, at).context("placing the probe")?),
    };
    let req = ProbeRequest {
        at,
        force_n: args.probe.force_n.unwrap_or(f64::NAN),
        dir,
        radius_mm: args.radius_mm,
        nodule: args.nodule.nodule()?,
    };
    // The nodule checked and put on the mesh once, before any solve.
    let space =
        request_space(&organ, args.element, material, &req).context("placing the nodule")?;
    let depth = args.probe.depth_mm;
    let mut series_report = serde_json::Value::Null;
    if args.method == Method::Series && (args.model.law().is_none() || depth.is_none()) {
        anyhow::bail!(
            "--method series expands a hyperelastic press in its depth: it needs --model \
             svk|neo-hookean and --depth-mm"
        );
    }
    if args.method != Method::Series
        && let Some(n) = args.orders
    {
        anyhow::bail!(
            "--orders {n}: only --method series keeps orders (Newton solves to the depth)"
        );
    }
    let (sol, newton_iterations, load_steps) = match (args.model.law(), depth) {
        (Some(law), Some(d)) if args.method == Method::Series => {
            let (sol, series, continued_at) = solve_series(
                &organ,
                args.element,
                material,
                law,
                &req,
                d,
                args.orders.unwrap_or(12),
            )
            .with_context(|| format!("expanding the press ({})", law.name()))?;
            let r = series.rational(d);
            let pade = json!({"numerator_degree": r.degree, "denominator": r.q, "scale_mm": r.scale_mm, "relative_change": r.change});
            series_report = json!({
                "orders": series.force.len(),
                "force_coefficients": series.force,
                "radius_mm": series.radius_mm(),
                "force_by_orders": (1..=series.force.len()).map(|n| series.force_n(d, n)).collect::<Vec<_>>(),
                "pade": pade,
                "continued_at_mm": continued_at,
            });
            (sol, 0, 0)
        }
        (None, None) => (
            solve_linear(&organ, args.element, material, &req).context("solving")?,
            0,
            1,
        ),
        (None, Some(d)) => (
            solve_linear_depth(&organ, args.element, material, &req, d)
                .context("solving (depth control)")?,
            0,
            1,
        ),
        (Some(law), _) => {
            let (sol, rep) = solve_hyperelastic(
                &organ,
                args.element,
                material,
                law,
                &req,
                depth,
                NewtonSettings::default(),
            )
            .with_context(|| format!("solving ({})", law.name()))?;
            (sol, rep.iterations, rep.load_steps)
        }
    };
    let seconds = t.elapsed().as_secs_f64();
    super::args::warn_far_from_surface(sol.probe.distance_mm, sol.probe.point);
    let report = json!({
        "young_kpa": material.young_kpa,
        "poisson": material.poisson,
        "element": args.element.name(),
        "model": args.model.law().map_or("linear", Law::name),
        "control": if depth.is_some() { "depth" } else { "force" },
        "level": format!("{:?}", args.organ.level).to_lowercase(),
        "probe_point": sol.probe.point,
        "probe_projection_distance_mm": sol.probe.distance_mm,
        "direction": sol.dir,
        "force_n": sol.force_n,
        "radius_mm": args.radius_mm,
        "probe_displacement_mm": sol.probe_displacement_mm,
        "max_displacement_mm": sol.max_displacement_mm,
        "newton_iterations": newton_iterations,
        "load_steps": load_steps,
        "dofs": space.free_dofs,
        "nodule": req.nodule.map(|n| json!({
            "center_mm": n.center_mm,
            "radius_mm": n.radius_mm,
            "ratio": n.ratio,
            "cells_stiffened": space.stiffness.as_ref().map_or(0, |s| s.iter().filter(|&&f| f != 1.0).count()),
        })),
        "assembly_s": sol.assembly_s,
        "factor_s": sol.factor_s,
        "solve_s": sol.solve_s,
        "seconds": seconds,
        "series": series_report,
    });
    if let Some(out) = &args.out {
        let fields = [
            PointField {
                name: "displacement".into(),
                components: 3,
                values: sol.u.clone(),
            },
            PointField {
                name: "nodal_force".into(),
                components: 3,
                values: sol.load.clone(),
            },
            PointField {
                name: "fixed".into(),
                components: 1,
                values: space
                    .fixed
                    .iter()
                    .map(|&f| if f { 1.0 } else { 0.0 })
                    .collect(),
            },
        ];
        let meta = [
            FieldValue {
                name: "young_kpa".into(),
                value: material.young_kpa,
            },
            FieldValue {
                name: "poisson".into(),
                value: material.poisson,
            },
            FieldValue {
                name: "element_order".into(),
                value: if args.element == Element::P2 {
                    2.0
                } else {
                    1.0
                },
            },
        ];
        write_by_extension(out, &space, &fields, &meta)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    super::args::print_report(&report, args.json)
}
