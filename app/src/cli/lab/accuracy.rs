//! `palpa lab accuracy`: today's accuracy of the shipped scenes, as Markdown, read
//! from what the files themselves record (their tradeoff tables, measured by `palpa
//! tradeoff` against the full FE at held-out presses, and the tissue's checks, recorded
//! by `palpa tissue check --record`). `docs/accuracy.md` holds its output between two
//! markers, and a test keeps the two the same.

use std::fmt::Write;
use std::io::Write as _;

use anyhow::Context;

use clap::Args;
use palpa_core::separated::ModelMeta;
use palpa_core::tissue::accuracy::{GOAL_FORCE_REL, GOAL_SURFACE_MM};
use palpa_core::tissue::law::TissueLaw;

#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Write it between the markers of this Markdown file (atomically) instead of
    /// printing it: `palpa lab accuracy --write docs/accuracy.md`.
    #[arg(long)]
    write: Option<std::path::PathBuf>,
}

/// The lines around the generated part of a Markdown file.
pub const BEGIN: &str = "<!-- palpa lab accuracy: begin -->\n";
pub const END: &str = "<!-- palpa lab accuracy: end -->";

/// The kidney example's scene, as shipped.
const KIDNEY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../assets/kidney/kidney-coarse.palpa"
);

pub fn run(args: &AccuracyArgs) -> anyhow::Result<()> {
    let text = markdown()?;
    let Some(path) = &args.write else {
        print!("{text}");
        return Ok(());
    };
    let doc = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let (Some(begin), Some(end)) = (doc.find(BEGIN), doc.find(END)) else {
        anyhow::bail!(
            "{}: expected the markers `{}` and `{END}` around the generated part",
            path.display(),
            BEGIN.trim_end()
        );
    };
    let rewritten = format!("{}{text}{}", &doc[..begin + BEGIN.len()], &doc[end..]);
    palpa_core::fsutil::atomic_write(path, |w| w.write_all(rewritten.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

/// The generated part of `docs/accuracy.md`.
pub fn markdown() -> anyhow::Result<String> {
    let mut out = String::new();
    let liver = palpa_core::file::load_any_from_bytes(palpa_app::scenes::BUILT_IN_LIVER)?;
    let tissue = TissueLaw::from_bytes(
        palpa_app::scenes::BUILT_IN_TISSUE,
        std::path::Path::new("assets/liver-coarse.tissue"),
    )?;
    let kidney = palpa_core::file::read_header(std::path::Path::new(KIDNEY))?;
    writeln!(
        out,
        "### The default liver (`assets/liver-coarse.palpa`, linear, coarse P2)\n"
    )?;
    tradeoff_table(&mut out, &liver.meta())?;
    writeln!(
        out,
        "\n### Its neo-Hookean tissue (`assets/liver-coarse.tissue`)\n"
    )?;
    tissue_table(&mut out, &tissue)?;
    let nodules = palpa_core::pgd::nodule::table::EffectTable::from_bytes(
        palpa_app::scenes::BUILT_IN_NODULES,
        std::path::Path::new("assets/liver-coarse.nodules"),
    )?;
    writeln!(
        out,
        "\n### Its nodule table (`assets/liver-coarse.nodules`, linear)\n"
    )?;
    nodule_table(&mut out, &nodules)?;
    writeln!(
        out,
        "\n### The kidney example (`assets/kidney/kidney-coarse.palpa`, linear, coarse P2)\n"
    )?;
    tradeoff_table(&mut out, &kidney.meta)?;
    Ok(out)
}

/// A scene's tradeoff rows: each count of modes against the full FE at the held-out
/// presses `palpa tradeoff` measured.
fn tradeoff_table(out: &mut String, meta: &ModelMeta) -> anyhow::Result<()> {
    writeln!(
        out,
        "| modes | surface, relative L2 | largest node error at 1 N | compliance | surface evaluation |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or("—".to_string(), f);
    for r in &meta.tradeoff {
        writeln!(
            out,
            "| {} | {:.2} % | {} | {} | {:.0} µs |",
            r.modes,
            100.0 * r.surface_rel_error,
            opt(r.surface_max_nodal_error_mm, &|v| format!("{v:.3} mm")),
            opt(r.compliance_rel_error, &|v| format!("{:.2} %", 100.0 * v)),
            r.surface_eval_us,
        )?;
    }
    Ok(())
}

/// A nodule table's recorded checks: the nodule's effect on the force against the full
/// FE's at held-out (probe point, nodule) pairs.
fn nodule_table(
    out: &mut String,
    table: &palpa_core::pgd::nodule::table::EffectTable,
) -> anyhow::Result<()> {
    let seeds: Vec<String> = table.checks.iter().map(|c| c.seed.to_string()).collect();
    let [within, beyond, past_radius, past_band] =
        palpa_core::pgd::nodule::heldout::recorded(table);
    let Some(s) = within else {
        writeln!(out, "No check recorded (`palpa nodule check --record`).")?;
        return Ok(());
    };
    let (lo, hi) = table.box_mm();
    writeln!(
        out,
        "Centres {:.1} mm apart from ({:.1}, {:.1}, {:.1}) to ({:.1}, {:.1}, {:.1}) mm, radii {:?} mm tabulated (answered to 1.25 times the largest, the quadratic over the radius carried on), ratios 1–100 (the one-pole form fitted at 2 and 10, carried beyond). Against the full linear FE with the nodule at {} held-out pairs (seeds {}; the nodule off every grid, ratios log-uniform, the probe within 20 mm of it). Goals: the effect (force with the nodule over the force without, less one) within 10 % where it exceeds 5 %; the surface drawn at 1 N (the nodule-free one at the depth reached, swayed with the force away from the tool) within 0.1 mm of the FE's with the nodule.\n",
        table.spacing_mm,
        lo[0],
        lo[1],
        lo[2],
        hi[0],
        hi[1],
        hi[2],
        table.radii_mm,
        table.checks.iter().map(|c| c.pairs.len()).sum::<usize>(),
        seeds.join(", ")
    )?;
    // The off-line the table took, as its build and `palpa nodule tissue` timed it.
    let power = table.tissue_power.as_ref().map_or(String::new(), |p| {
        format!(
            " and the tissue's power in {:.1} min: {:.1} min off-line in all",
            p.build_s / 60.0,
            (table.build_s + p.build_s) / 60.0
        )
    });
    writeln!(
        out,
        "The table built in {:.1} min ({} placements of a nodule){power}, on the machine that built them.\n",
        table.build_s / 60.0,
        table.placements,
    )?;
    writeln!(
        out,
        "| ratios | pairs with an effect above 5 % | effects seen | median error | 90th percentile | worst | within 10 % | elsewhere, worst | surface at 1 N, median / worst | within 0.1 mm |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|")?;
    let largest = table.radii_mm.last().copied().unwrap_or(0.0);
    let past = format!(
        "1.5–100, radii {largest:.0}–{:.0} mm",
        largest * palpa_core::pgd::nodule::table::RADIUS_REACH
    );
    for (ratios, s) in [
        ("1.5–10", Some(s)),
        ("10–100", beyond),
        (past.as_str(), past_radius),
        ("1.5–100, past the band", past_band),
    ] {
        let Some(s) = s else { continue };
        // No felt pair: no effect error to give.
        let pct = |x: f64, digits: usize| {
            if x.is_nan() {
                "—".to_string()
            } else {
                format!("{:.digits$} %", 100.0 * x)
            }
        };
        writeln!(
            out,
            "| {ratios} | {} of {} | {:.1}–{:.1} % | {} | {} | {} | {} | {:.2} % of the force | {:.3} / {:.3} mm | {:.0} % |",
            s.felt,
            s.pairs,
            100.0 * s.effect_min,
            100.0 * s.effect_max,
            pct(s.error_median, 1),
            pct(s.error_p90, 1),
            pct(s.error_max, 1),
            pct(s.within_10_percent, 0),
            100.0 * s.unfelt_max_abs,
            s.surface_median_mm,
            s.surface_max_mm,
            100.0 * s.surface_within_goal
        )?;
    }
    use palpa_core::pgd::nodule::heldout::{TissueSummary, drawn_above};
    // The default table is the built-in liver's: its checks are told apart by where
    // they drew the probe.
    let organ = palpa_core::organ::catalogue::mesh(
        palpa_core::organ::catalogue::OrganName::Liver,
        palpa_core::organ::Level::Coarse,
    );
    let above = drawn_above(&table.tissue_checks, &organ);
    let checks: Vec<_> = table
        .tissue_checks
        .iter()
        .zip(above)
        .filter_map(|(c, a)| TissueSummary::of(&c.pairs).map(|t| (c.seed, c.amplified, a, t)))
        .collect();
    if checks.is_empty() {
        writeln!(
            out,
            "\nThe tissue with a nodule: no check recorded (`palpa nodule check --tissue X.tissue --record`)."
        )?;
        return Ok(());
    }
    writeln!(
        out,
        "\nThe neo-Hookean tissue with a nodule (the tissue's force times `1 + e A`, `e` the linear effect from this table, `A` its amplification by the tissue's own nodule-free press, from the table's power of the tissue (`palpa nodule tissue`; \"linear\": none, the effect as it is); the surface the tissue's without the nodule at the depth, swayed with the force away from the tool), against Newton with the nodule (ratios 1.5–10; the probe within 20 mm of the nodule's projection on the surface, or right above it with `--above`, the nodule's depth under the tool then the probe's distance from it). Goals: the force within 5 % and the surface within 0.5 mm to 10 mm; the effect within 10 % where it exceeds 5 %.\n",
    )?;
    writeln!(
        out,
        "| seed | effect | the probe (from the nodule, median) | presses, to | force, median | force, worst | presses with an effect above 5 % | effects seen | effect, median error | worst | within 10 % | surface, worst |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for (seed, amplified, above, t) in checks {
        let how = if amplified { "amplified" } else { "linear" };
        let probe = if above {
            "right above it"
        } else {
            "within 20 mm"
        };
        writeln!(
            out,
            "| {seed} | {how} | {probe} ({:.1} mm) | {}, {:.1} mm | {:.2} % | {:.2} % | {} | {:.1}–{:.1} % | {:.1} % | {:.1} % | {:.0} % | {:.2} mm |",
            t.gap_median_mm,
            t.presses,
            t.depth_max_mm,
            100.0 * t.force_error_median,
            100.0 * t.force_error_max,
            t.felt,
            100.0 * t.effect_min,
            100.0 * t.effect_max,
            100.0 * t.effect_error_median,
            100.0 * t.effect_error_max,
            100.0 * t.effect_within_10_percent,
            t.surface_max_mm
        )?;
    }
    Ok(())
}

/// A tissue's recorded checks, merged depth by depth.
fn tissue_table(out: &mut String, law: &TissueLaw) -> anyhow::Result<()> {
    let a = &law.accuracy;
    if a.runs.is_empty() {
        writeln!(out, "No check recorded (`palpa tissue check --record`).")?;
        return Ok(());
    }
    let seeds: Vec<String> = a
        .runs
        .iter()
        .map(|r| r.seed.map_or("given points".into(), |s| s.to_string()))
        .collect();
    writeln!(
        out,
        "Against the full nonlinear FE (Newton) at {} held-out random points (seeds {}; \
         left out: {}). Goals: the surface within {GOAL_SURFACE_MM} mm and the force within \
         {:.0} %.\n",
        a.points(),
        seeds.join(", "),
        a.runs[0].left_out,
        100.0 * GOAL_FORCE_REL,
    )?;
    writeln!(
        out,
        "| depth | presses compared | past the tissue's reach | worst force error | worst surface error |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    for d in a.merged() {
        writeln!(
            out,
            "| {} mm | {} | {} | {:.1} % | {:.2} mm |",
            d.depth_mm,
            d.presses,
            d.past_limit,
            100.0 * d.worst_force_rel,
            d.worst_surface_mm
        )?;
    }
    match a.goals_to_mm() {
        Some(g) => writeln!(
            out,
            "\nBoth goals hold at every press measured to {} mm, the force goal to {} mm.",
            g.both_mm, g.force_mm
        )?,
        None => writeln!(out, "\nThe goals hold at no depth measured.")?,
    }
    Ok(())
}
