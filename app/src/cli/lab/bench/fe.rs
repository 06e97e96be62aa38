//! `palpa lab bench fe`: the cost of the full FE reference, and its behaviour at the
//! extremes. One JSON object per line, each with a `table` field:
//! - `cost`: per level and element, assembly / factorization / solve seconds, dofs and
//!   peak memory (Linux VmHWM, reset before each run);
//! - `poisson`: probe displacement for ν = 0.45 … 0.499, P1 and P2 (locking);
//! - `svk`: Newton iterations, load steps and seconds for F = 1, 5, 10 N, or the load
//!   fraction reached when it does not converge;
//! - `positions`: linear P2 probe displacement at named positions (anterior, left
//!   lobe, the sharp inferior border, next to the fixed region);
//! - `depth`: each hyperelastic law pushed to `--depth-mm` (15) under depth control at
//!   ten spread positions on coarse P2: the force, Newton work and seconds, or the
//!   depth and force where it stopped and why;
//! - `depth_poisson`: the neo-Hookean press at the anterior point for ν = 0.48, 0.49,
//!   0.499;
//! - `ordering`: the P2 rest stiffness factored under AMD and under nested dissection
//!   (what `fe::sparse` uses), at `--ordering-levels`: entries, seconds and ratios;
//! - `lanes`: a press's element kernels (series right-hand sides, residual, tangent)
//!   one quadrature point at a time and four in vector lanes: seconds, speedup, and
//!   that the two agree bit for bit.

use std::time::Instant;

use anyhow::bail;
use clap::Args;
use palpa_core::fe::law::Law;
use palpa_core::fe::newton::NewtonSettings;
use palpa_core::fe::probe::{
    ProbeRequest, organ_space, solve_hyperelastic, solve_linear, solve_series,
};
use palpa_core::fe::{Element, Material};
use serde_json::json;

use crate::cli::memory::{peak_bytes, reset_peak};
use palpa_core::organ::OrganMesh;

use crate::cli::organ::{LevelArg, OrganName, mesh as mesh_organ};

#[derive(Debug, Args)]
pub struct FeBenchArgs {
    /// Also run P2 on the fine level (≈ 0.9 M dofs: many minutes and several GB).
    #[arg(long)]
    fine_p2: bool,
    /// Skip the (slow) SVK tables.
    #[arg(long)]
    no_svk: bool,
    /// Run only these tables (cost, poisson, positions, svk, svk_limit, depth,
    /// depth_poisson, series, surface_law, build_cost, ordering, lanes).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Depth of the `depth` table (mm).
    #[arg(long, default_value_t = 15.0)]
    depth_mm: f64,
    /// `series` table: orders of the depth series.
    #[arg(long, default_value_t = 15)]
    series_orders: usize,
    /// `series` table: depths compared with Newton (mm), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [3.5, 8.5, 15.0])]
    series_depths: Vec<f64>,
    /// `series` table: the first N of the ten positions.
    #[arg(long, default_value_t = 10)]
    series_positions: usize,
    /// `surface_law` table: the element (p1 builds in minutes, p2 in about an hour).
    #[arg(long, default_value = "p2")]
    surface_element: Element,
    /// `surface_law` table: held-out presses compared with Newton.
    #[arg(long, default_value_t = 6)]
    surface_heldout: usize,
    /// `surface_law` table: depths of the held-out presses (mm), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [4.0, 8.5])]
    surface_depths: Vec<f64>,
    /// `build_cost` table: the first N of the ten positions (each a few minutes).
    #[arg(long, default_value_t = 3)]
    build_positions: usize,
    /// `build_cost` table: also solve every depth from rest (the literal brute force,
    /// as `palpa fe solve --depth-mm` does; several minutes more a position).
    #[arg(long)]
    build_from_rest: bool,
    /// `ordering` table: the levels measured (P2; medium's AMD factorization takes about
    /// a minute and 4 GB), comma-separated.
    #[arg(long, value_delimiter = ',', default_values = ["coarse", "medium"])]
    ordering_levels: Vec<LevelArg>,
    /// `series` table: laws (svk, neo-hookean), comma-separated.
    #[arg(long, value_delimiter = ',', default_values = ["neo-hookean", "svk"])]
    series_laws: Vec<Law>,
}

/// The tables `--only` may name.
const TABLES: [&str; 12] = [
    "cost",
    "poisson",
    "positions",
    "svk",
    "svk_limit",
    "depth",
    "depth_poisson",
    "series",
    "surface_law",
    "build_cost",
    "ordering",
    "lanes",
];

impl FeBenchArgs {
    /// Refuses what would make a table meaningless before any table runs (some take
    /// an hour): a misspelt table name would otherwise run nothing and say nothing.
    fn validate(&self) -> anyhow::Result<()> {
        if let Some(t) = self.only.iter().find(|t| !TABLES.contains(&t.as_str())) {
            bail!(
                "--only {t}: no such table; expected some of {}",
                TABLES.join(", ")
            );
        }
        if !(self.depth_mm.is_finite() && self.depth_mm > 0.0) {
            bail!("--depth-mm {}: expected a finite depth > 0", self.depth_mm);
        }
        for (flag, depths) in [
            ("--series-depths", &self.series_depths),
            ("--surface-depths", &self.surface_depths),
        ] {
            if depths.is_empty() || depths.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
                bail!("{flag} {depths:?}: expected finite depths > 0 (mm)");
            }
        }
        for (flag, n) in [
            ("--series-orders", self.series_orders),
            ("--series-positions", self.series_positions),
            ("--surface-heldout", self.surface_heldout),
            ("--build-positions", self.build_positions),
        ] {
            if n == 0 {
                bail!("{flag} 0: expected at least 1");
            }
        }
        for (flag, n) in [
            ("--series-positions", self.series_positions),
            ("--build-positions", self.build_positions),
        ] {
            if n > DEPTH_POSITIONS.len() {
                bail!(
                    "{flag} {n}: expected at most {} (the listed positions)",
                    DEPTH_POSITIONS.len()
                );
            }
        }
        Ok(())
    }

    fn wants(&self, table: &str) -> bool {
        let svk = table.starts_with("svk");
        (self.only.is_empty() || self.only.iter().any(|t| t == table)) && !(svk && self.no_svk)
    }
}

const ANTERIOR: [f64; 3] = [-30.0, 90.0, 25.0];
pub const POSITIONS: [(&str, [f64; 3]); 5] = [
    ("anterior right lobe", ANTERIOR),
    ("left lobe", [60.0, 40.0, 20.0]),
    ("sharp inferior border", [-30.0, 80.0, 0.0]),
    ("inferior surface", [-20.0, 45.0, -45.0]),
    ("next to the fixed region", [-60.0, -40.0, -20.0]),
];

/// Ten spread positions for the depth table (each projected to the palpable surface).
const DEPTH_POSITIONS: [(&str, [f64; 3]); 10] = [
    POSITIONS[0],
    POSITIONS[1],
    POSITIONS[2],
    POSITIONS[3],
    POSITIONS[4],
    ("right lobe, lateral", [-90.0, 30.0, 10.0]),
    ("dome", [-20.0, 20.0, 60.0]),
    ("left lobe tip", [90.0, 40.0, 10.0]),
    ("middle anterior", [10.0, 80.0, 20.0]),
    ("inferior right", [-70.0, 50.0, -30.0]),
];

pub fn run(args: &FeBenchArgs) -> anyhow::Result<()> {
    args.validate()?;
    let levels = [LevelArg::Coarse, LevelArg::Medium, LevelArg::Fine];
    if args.wants("cost") {
        cost(args, &levels)?;
    }
    if args.wants("poisson") {
        poisson()?;
    }
    let coarse = mesh_organ(OrganName::Liver, LevelArg::Coarse)?;
    if args.wants("positions") {
        positions(args, &levels)?;
    }
    if args.wants("svk_limit") {
        svk_limit(&coarse);
    }
    if args.wants("depth") {
        depth(args, &coarse);
    }
    if args.wants("depth_poisson") {
        depth_poisson(args, &coarse);
    }
    if args.wants("series") {
        series(args, &coarse)?;
    }
    if args.wants("surface_law") {
        surface_law(args, &coarse)?;
    }
    if args.wants("svk") {
        svk(&coarse);
    }
    if args.wants("ordering") {
        ordering(&args.ordering_levels)?;
    }
    if args.wants("lanes") {
        super::lanes::lanes_table(&coarse, ANTERIOR)?;
    }
    if args.wants("build_cost") {
        super::build::build_cost(
            &coarse,
            &DEPTH_POSITIONS[..args.build_positions],
            args.build_from_rest,
        )?;
    }
    Ok(())
}

fn req(at: [f64; 3], force_n: f64) -> ProbeRequest {
    ProbeRequest {
        at,
        force_n,
        dir: None,
        radius_mm: 5.0,
        nodule: None,
    }
}

/// Assembly, factorization and solve seconds and peak memory per level and element.
fn cost(args: &FeBenchArgs, levels: &[LevelArg]) -> anyhow::Result<()> {
    for &level in levels {
        let organ = mesh_organ(OrganName::Liver, level)?;
        for element in [Element::P1, Element::P2] {
            if element == Element::P2 && level == LevelArg::Fine && !args.fine_p2 {
                println!(
                    "{}",
                    json!({"table": "cost", "level": "fine", "element": "p2", "skipped": "≈0.9 M dofs; run with --fine-p2"})
                );
                continue;
            }
            reset_peak();
            let t = Instant::now();
            let sol = solve_linear(&organ, element, Material::default(), &req(ANTERIOR, 1.0))?;
            println!(
                "{}",
                json!({
                    "table": "cost",
                    "level": format!("{level:?}").to_lowercase(),
                    "element": element.name(),
                    "dofs": organ_space(&organ, element).free_dofs,
                    "assembly_s": sol.assembly_s,
                    "factor_s": sol.factor_s,
                    "solve_s": sol.solve_s,
                    "total_s": t.elapsed().as_secs_f64(),
                    "peak_rss_mb": peak_bytes().map(|b| b as f64 / 1e6),
                    "probe_displacement_mm": sol.probe_displacement_mm,
                })
            );
        }
    }
    Ok(())
}

/// The rest stiffness of P2 at each level factored under AMD and under nested
/// dissection (`fe::ordering`), one thread each: the factor's entries, the seconds of the
/// analysis, a factorization and a solve in both precisions, and their ratios.
fn ordering(levels: &[LevelArg]) -> anyhow::Result<()> {
    use palpa_core::fe::elasticity::{assemble, element_stiffness};
    use palpa_core::fe::sparse::{SymCsc, ordering_cost};
    for &level in levels {
        let organ = mesh_organ(OrganName::Liver, level)?;
        let space = organ_space(&organ, Element::P2);
        let (lambda, mu) = Material::default().lame_n_per_mm2();
        let mut k = SymCsc::pattern(&space);
        assemble(&space, &mut k, |c, ke| {
            element_stiffness(&space, c, lambda, mu, ke);
        });
        let nd = ordering_cost(&k, true)?;
        let amd = ordering_cost(&k, false)?;
        let ratio = |a: f64, n: f64| a / n;
        println!(
            "{}",
            json!({
                "table": "ordering",
                "level": format!("{level:?}").to_lowercase(),
                "element": "p2",
                "dofs": k.n,
                "amd": cost_json(&amd),
                "nested_dissection": cost_json(&nd),
                "entries_ratio": ratio(amd.factor_entries as f64, nd.factor_entries as f64),
                "double_factor_ratio": ratio(amd.double_factor_s, nd.double_factor_s),
                "single_factor_ratio": ratio(amd.single_factor_s, nd.single_factor_s),
                "double_solve_ratio": ratio(amd.double_solve_s, nd.double_solve_s),
                "single_solve_ratio": ratio(amd.single_solve_s, nd.single_solve_s),
            })
        );
    }
    Ok(())
}

fn cost_json(c: &palpa_core::fe::sparse::OrderingCost) -> serde_json::Value {
    json!({
        "factor_entries": c.factor_entries,
        "analysis_s": c.analysis_s,
        "double_factor_s": c.double_factor_s,
        "double_solve_s": c.double_solve_s,
        "single_factor_s": c.single_factor_s,
        "single_solve_s": c.single_solve_s,
        "double_residual": c.double_residual,
    })
}

/// The probe displacement as ν → 0.5, P1 against P2 (locking).
fn poisson() -> anyhow::Result<()> {
    for level in [LevelArg::Coarse, LevelArg::Medium] {
        let organ = mesh_organ(OrganName::Liver, level)?;
        for poisson in [0.45, 0.48, 0.49, 0.499] {
            let mut row = json!({"table": "poisson", "level": format!("{level:?}").to_lowercase(), "poisson": poisson});
            for element in [Element::P1, Element::P2] {
                let m = Material {
                    poisson,
                    ..Material::default()
                };
                let sol = solve_linear(&organ, element, m, &req(ANTERIOR, 1.0))?;
                row[format!("{}_probe_mm", element.name())] = json!(sol.probe_displacement_mm);
            }
            println!("{row}");
        }
    }
    Ok(())
}

/// The linear probe displacement at named positions.
fn positions(args: &FeBenchArgs, levels: &[LevelArg]) -> anyhow::Result<()> {
    for &level in levels {
        let organ = mesh_organ(OrganName::Liver, level)?;
        for (name, at) in POSITIONS {
            let mut row = json!({"table": "positions", "level": format!("{level:?}").to_lowercase(), "position": name});
            for element in [Element::P1, Element::P2] {
                if element == Element::P2 && level == LevelArg::Fine && !args.fine_p2 {
                    continue;
                }
                let sol = solve_linear(&organ, element, Material::default(), &req(at, 1.0))?;
                row["probe_point"] = json!(sol.probe.point);
                row[format!("{}_probe_mm", element.name())] = json!(sol.probe_displacement_mm);
            }
            println!("{row}");
        }
    }
    Ok(())
}

/// The largest force SVK Newton still reaches, by bisection.
fn svk_limit(coarse: &OrganMesh) {
    // Largest force SVK Newton still reaches, by bisection on F ∈ [1, 256] N
    // (P1 everywhere; P2 at the anterior point, where it is slower).
    for (name, at) in POSITIONS {
        for element in [Element::P1, Element::P2] {
            if element == Element::P2 && at != ANTERIOR {
                continue;
            }
            let converges = |f: f64| {
                solve_hyperelastic(
                    coarse,
                    element,
                    Material::default(),
                    Law::Svk,
                    &req(at, f),
                    None,
                    NewtonSettings::default(),
                )
                .is_ok()
            };
            let (mut ok, mut bad) = (0.0, 256.0);
            if converges(bad) {
                ok = bad;
            } else {
                let mut lo = 1.0;
                if converges(lo) {
                    ok = lo;
                    for _ in 0..6 {
                        let mid = (lo * bad).sqrt();
                        if converges(mid) {
                            ok = mid;
                            lo = mid;
                        } else {
                            bad = mid;
                        }
                    }
                }
            }
            let beyond = solve_hyperelastic(
                coarse,
                element,
                Material::default(),
                Law::Svk,
                &req(at, bad),
                None,
                NewtonSettings::default(),
            )
            .err()
            .map(|e| e.to_string());
            println!(
                "{}",
                json!({"table": "svk_limit", "level": "coarse", "element": element.name(), "position": name,
                       "max_converged_force_n": ok, "first_failing_force_n": bad, "beyond": beyond})
            );
        }
    }
}

/// Both hyperelastic laws pushed to the depth at ten positions (coarse P2).
fn depth(args: &FeBenchArgs, coarse: &OrganMesh) {
    for law in [Law::NeoHookean, Law::Svk] {
        for (name, at) in DEPTH_POSITIONS {
            depth_row(args, coarse, law, Material::default(), name, at);
        }
    }
}

/// The largest nodal distance between `scale·a` and `b` (all-node vectors), mm.
fn max_nodal_mm(a: &[f64], b: &[f64], scale: f64) -> f64 {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(a, b)| {
            (0..3)
                .map(|k| (scale * a[k] - b[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The depth series (with its Padé form) against Newton at the ten positions and a
/// few depths, coarse P2: force, largest nodal displacement error, and the time of
/// each (one series serves every depth at a position; Newton solves each depth).
fn series(args: &FeBenchArgs, coarse: &OrganMesh) -> anyhow::Result<()> {
    for &law in &args.series_laws {
        for (name, at) in DEPTH_POSITIONS.into_iter().take(args.series_positions) {
            let deepest = args.series_depths.iter().copied().fold(0.0, f64::max);
            let t = Instant::now();
            let expanded = solve_series(
                coarse,
                Element::P2,
                Material::default(),
                law,
                &req(at, f64::NAN),
                deepest,
                args.series_orders,
            );
            let series_s = t.elapsed().as_secs_f64();
            let series = match expanded {
                Ok((_, s, _)) => s,
                Err(e) => {
                    println!(
                        "{}",
                        json!({"table": "series", "law": law.name(), "position": name, "error": e.to_string()})
                    );
                    continue;
                }
            };
            // The continued expansion (about the state at 55 % of the deepest press).
            let space = organ_space(coarse, Element::P2);
            let t = Instant::now();
            let continued = (|| -> anyhow::Result<_> {
                let (probe, dir) =
                    palpa_core::fe::probe::locate(&space, coarse, &req(at, f64::NAN))?;
                let shape = palpa_core::fe::load::probe_load(&space, &probe, dir, 1.0, 5.0)?;
                let functional = palpa_core::fe::load::probe_functional(&space, &probe, dir);
                Ok(palpa_core::fe::series::continued_series(
                    &space,
                    law,
                    Material::default(),
                    &shape,
                    &functional,
                    0.55 * deepest,
                    args.series_orders,
                )?)
            })();
            let continued_s = t.elapsed().as_secs_f64();
            for &depth in &args.series_depths {
                let rational = series.rational(depth);
                let (force, u) = series.evaluate(&rational, depth);
                let mut row = json!({"table": "series", "level": "coarse", "element": "p2",
                    "law": law.name(), "position": name, "depth_mm": depth,
                    "orders": series.force.len(), "pade": format!("[{}/{}]", rational.degree, rational.q.len() - 1),
                    "pade_change": rational.change, "series_radius_mm": series.radius_mm(),
                    "series_force_n": force, "series_s": series_s});
                let t = Instant::now();
                match solve_hyperelastic(
                    coarse,
                    Element::P2,
                    Material::default(),
                    law,
                    &req(at, f64::NAN),
                    Some(depth),
                    NewtonSettings::default(),
                ) {
                    Ok((sol, _)) => {
                        let worst = max_nodal_mm(&u, &sol.u, 1.0);
                        for m in [6, 8, 10] {
                            if let Some(r) = series.pade_vector(m, depth) {
                                let (f, v) = series.evaluate(&r, depth);
                                let w = max_nodal_mm(&v, &sol.u, 1.0);
                                row[format!("vector_pade_{m}")] = json!({"force_rel_error": (f - sol.force_n) / sol.force_n, "max_nodal_error_mm": w});
                            }
                        }
                        // The linear press at the same depth is the series' first term.
                        let linear_worst = max_nodal_mm(&series.u[0], &sol.u, depth);
                        row["linear_max_nodal_error_mm"] = json!(linear_worst);
                        row["linear_force_rel_error"] =
                            json!((depth * series.force[0] - sol.force_n) / sol.force_n);
                        if let Ok(c) = &continued {
                            let (cf, cu) = c.evaluate(depth, deepest);
                            let worst = max_nodal_mm(&cu, &sol.u, 1.0);
                            row["continued"] = json!({"split_mm": c.split_mm, "seconds": continued_s,
                                "force_rel_error": (cf - sol.force_n) / sol.force_n, "max_nodal_error_mm": worst});
                        }
                        row["newton_force_n"] = json!(sol.force_n);
                        row["force_rel_error"] = json!((force - sol.force_n) / sol.force_n);
                        row["max_nodal_error_mm"] = json!(worst);
                        row["newton_max_displacement_mm"] = json!(sol.max_displacement_mm);
                    }
                    Err(e) => row["newton_error"] = json!(e.to_string()),
                }
                row["newton_s"] = json!(t.elapsed().as_secs_f64());
                println!("{row}");
            }
        }
    }
    Ok(())
}

/// The nonlinear surface (neo-Hookean, coarse): residuals from every palpable vertex's
/// continued depth series, blended barycentrically at held-out random points, against
/// Newton's surface there; beside it the linear surface at the same depth (what the
/// app draws without it), the build's time and bytes.
fn surface_law(args: &FeBenchArgs, coarse: &OrganMesh) -> anyhow::Result<()> {
    use palpa_core::rng::Rng;
    use palpa_core::tissue::surface::{SurfaceLaw, SurfaceLawOptions};
    let depth_max = args
        .surface_depths
        .iter()
        .copied()
        .fold(1.0, f64::max)
        .ceil();
    let options = SurfaceLawOptions {
        element: args.surface_element,
        depth_max_mm: depth_max,
        depth_step_mm: 0.5,
        ..SurfaceLawOptions::default()
    };
    let law = SurfaceLaw::build(coarse, options, None, &|c| {
        eprint!("\rsurface law: vertex {}/{}   ", c.done, c.total);
    })?;
    eprintln!();
    println!(
        "{}",
        json!({"table": "surface_law", "level": "coarse", "element": options.element.name(),
            "law": options.law.name(), "samples": law.samples.len(), "skipped": law.skipped.len(),
            "rows": law.rows.len(), "depth_max_mm": depth_max, "build_s": law.build_s,
            "bytes": law.bytes()})
    );
    let faces: Vec<usize> = (0..coarse.palpable.len())
        .filter(|&f| coarse.palpable[f])
        .collect();
    let mut rng = Rng::seed(91);
    let (mut worst_law, mut worst_linear) = (0.0f64, 0.0f64);
    for _ in 0..args.surface_heldout {
        let (p, tri, bary) = crate::cli::tissue::points::heldout_point(coarse, &faces, &mut rng);
        let unit = solve_linear(coarse, options.element, options.material, &req(p, 1.0))?;
        let c = unit.probe_displacement_mm;
        for &depth in &args.surface_depths {
            let t = Instant::now();
            let reference = solve_hyperelastic(
                coarse,
                options.element,
                options.material,
                options.law,
                &req(p, f64::NAN),
                Some(depth),
                NewtonSettings::default(),
            );
            let newton_s = t.elapsed().as_secs_f64();
            let mut row = json!({"table": "surface_law", "position": p, "depth_mm": depth,
                "newton_s": newton_s});
            match reference {
                Ok((sol, _)) => {
                    let n = law.rows.len();
                    let mut residual = vec![0.0; 3 * n];
                    let covered = law.add_residual(tri, bary, depth, &mut residual);
                    let (mut e_law, mut e_lin, mut top) = (0.0f64, 0.0f64, 0.0f64);
                    for (i, &r) in law.rows.iter().enumerate() {
                        let mut d_law = 0.0;
                        let mut d_lin = 0.0;
                        let mut m = 0.0;
                        for k in 0..3 {
                            let g = 3 * r as usize + k;
                            let lin = depth / c * unit.u[g];
                            d_lin += (lin - sol.u[g]).powi(2);
                            d_law += (lin + residual[3 * i + k] - sol.u[g]).powi(2);
                            m += sol.u[g].powi(2);
                        }
                        e_law = e_law.max(d_law.sqrt());
                        e_lin = e_lin.max(d_lin.sqrt());
                        top = top.max(m.sqrt());
                    }
                    worst_law = worst_law.max(e_law);
                    worst_linear = worst_linear.max(e_lin);
                    row["covered"] = json!(covered);
                    row["max_displacement_mm"] = json!(top);
                    row["surface_max_error_mm"] = json!(e_law);
                    row["linear_surface_max_error_mm"] = json!(e_lin);
                }
                Err(e) => row["newton_error"] = json!(e.to_string()),
            }
            println!("{row}");
        }
    }
    println!(
        "{}",
        json!({"table": "surface_law", "summary": true, "worst_surface_max_error_mm": worst_law,
            "worst_linear_surface_max_error_mm": worst_linear, "goal_0_5_mm": worst_law <= 0.5})
    );
    Ok(())
}

/// The neo-Hookean press at the anterior point as ν → 0.5 (P2).
fn depth_poisson(args: &FeBenchArgs, coarse: &OrganMesh) {
    for poisson in [0.48, 0.49, 0.499] {
        let m = Material {
            poisson,
            ..Material::default()
        };
        depth_row(args, coarse, Law::NeoHookean, m, POSITIONS[0].0, ANTERIOR);
    }
}

/// One depth-controlled press on coarse P2, printed as a JSON row.
fn depth_row(
    args: &FeBenchArgs,
    coarse: &OrganMesh,
    law: Law,
    material: Material,
    name: &str,
    at: [f64; 3],
) {
    let t = Instant::now();
    let out = solve_hyperelastic(
        coarse,
        Element::P2,
        material,
        law,
        &req(at, f64::NAN),
        Some(args.depth_mm),
        NewtonSettings::default(),
    );
    let mut row = json!({"table": "depth", "level": "coarse", "element": "p2",
        "law": law.name(), "poisson": material.poisson, "position": name,
        "depth_mm": args.depth_mm, "seconds": t.elapsed().as_secs_f64()});
    match out {
        Ok((sol, rep)) => {
            row["converged"] = json!(true);
            row["force_n"] = json!(sol.force_n);
            row["max_displacement_mm"] = json!(sol.max_displacement_mm);
            row["newton_iterations"] = json!(rep.iterations);
            row["steps"] = json!(rep.load_steps);
            row["step_cuts"] = json!(rep.step_cuts);
            row["probe_point"] = json!(sol.probe.point);
        }
        Err(e) => {
            row["converged"] = json!(false);
            row["error"] = json!(e.to_string());
        }
    }
    println!("{row}");
}

/// SVK Newton's work at 1, 5 and 10 N.
fn svk(coarse: &OrganMesh) {
    for element in [Element::P1, Element::P2] {
        for force_n in [1.0, 5.0, 10.0] {
            let t = Instant::now();
            let out = solve_hyperelastic(
                coarse,
                element,
                Material::default(),
                Law::Svk,
                &req(ANTERIOR, force_n),
                None,
                NewtonSettings::default(),
            );
            let row = match out {
                Ok((sol, rep)) => {
                    json!({"table": "svk", "level": "coarse", "element": element.name(), "force_n": force_n,
                    "converged": true, "newton_iterations": rep.iterations, "load_steps": rep.load_steps,
                    "step_cuts": rep.step_cuts, "seconds": t.elapsed().as_secs_f64(),
                    "probe_displacement_mm": sol.probe_displacement_mm})
                }
                Err(e) => {
                    json!({"table": "svk", "level": "coarse", "element": element.name(), "force_n": force_n,
                    "converged": false, "error": e.to_string(), "seconds": t.elapsed().as_secs_f64()})
                }
            };
            println!("{row}");
        }
    }
}
