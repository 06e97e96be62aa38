//! `palpa lab bench offline`: the off-line cost of a palpation vademecum, PGD against the
//! brute-force route (one FE solve per palpable vertex and direction, then the optimal
//! separated form of that map), measured in one run on the same factored stiffness,
//! with both results' errors over the whole map in the natural norm.

use std::time::Instant;

use clap::Args;
use palpa_core::fe::{Element, Material};
use palpa_core::pgd::linear::{Settings, Terms, map_error};
use palpa_core::pgd::palpation::{brute_force, compute, setup};
use serde_json::json;

use crate::cli::organ::{LevelArg, OrganName, mesh as mesh_organ};

#[derive(Debug, Args)]
pub struct OfflineBenchArgs {
    #[arg(long, value_enum, default_value = "coarse")]
    level: LevelArg,
    #[arg(long, default_value = "p2")]
    element: Element,
    #[arg(long, default_value_t = 100)]
    modes: usize,
    /// PGD block sizes to time, comma-separated (1 is the one-term enrichment).
    #[arg(long, value_delimiter = ',', default_values_t = [16])]
    block: Vec<usize>,
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    #[arg(long)]
    json: bool,
}

pub fn run(args: &OfflineBenchArgs) -> anyhow::Result<()> {
    if args.modes == 0 {
        anyhow::bail!("--modes 0: expected at least one mode");
    }
    if args.block.is_empty() || args.block.contains(&0) {
        anyhow::bail!("--block {:?}: expected block sizes ≥ 1", args.block);
    }
    let organ = mesh_organ(OrganName::Liver, args.level)?;
    let s = setup(&organ, args.element, Material::default(), args.radius_mm)?;
    // The parametric space has one load case a column: no more modes than that.
    if args.modes > s.f.cols.len() {
        anyhow::bail!(
            "--modes {}: the {} level has {} load cases, so at most that many modes",
            args.modes,
            format!("{:?}", args.level).to_lowercase(),
            s.f.cols.len()
        );
    }
    let ops = s.ops();
    // The brute-force terms are the optimum: their map error is the reference each
    // PGD is compared with.
    let (brute, g2, [solve_s, eigen_s, brute_s]) = brute_force(&s, args.modes);
    let check = |t: &Terms, n: usize| map_error(&ops, t, n.min(t.x.len()), g2);
    let mut pgd_rows = Vec::new();
    for &b in &args.block {
        let settings = Settings {
            max_modes: args.modes,
            tol: 0.0,
            block: b,
            ..Settings::default()
        };
        let t0 = Instant::now();
        let terms = compute(&s, &settings, Terms::default(), |_| {});
        let pgd_s = t0.elapsed().as_secs_f64();
        let ns: Vec<usize> = [1, 10, 50, args.modes]
            .into_iter()
            .filter(|&n| n <= args.modes)
            .collect();
        let ratios: Vec<_> = ns
            .iter()
            .map(|&n| json!({"modes": n, "pgd_map_error": check(&terms, n), "optimal_map_error": check(&brute, n),
                             "pgd_over_optimal": check(&terms, n) / check(&brute, n)}))
            .collect();
        pgd_rows.push(
            json!({"block": b, "pgd_s": pgd_s, "brute_force_over_pgd_time": brute_s / pgd_s,
                             "accuracy": ratios}),
        );
    }
    let out = json!({
        "level": format!("{:?}", args.level).to_lowercase(),
        "element": args.element.name(),
        "free_dofs": s.f.rows,
        "parameters": s.f.cols.len(),
        "modes": args.modes,
        "setup_s": s.setup_s,
        "brute_force": {"solves_s": solve_s, "eigen_s": eigen_s, "total_s": brute_s},
        "pgd": pgd_rows,
    });
    crate::cli::args::print_report(&out, args.json)
}
