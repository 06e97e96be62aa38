//! `palpa lab bench nodule`: the mesh convergence of a nodule's effect on the probe
//! force, in one run: for each radius and level, the force with the nodule over the
//! force without it at the same press, and how far each level's effect is from the
//! finest level's. What a level "resolves" is read from this table.

use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use palpa_core::fe::law::Law;
use palpa_core::fe::newton::NewtonSettings;
use palpa_core::fe::nodule::Nodule;
use palpa_core::fe::probe::{
    ProbeRequest, smooth_inward_dir, solve_hyperelastic, solve_linear_depth,
};
use palpa_core::fe::{Element, Material};
use palpa_core::organ::catalogue::{self, OrganName};
use palpa_core::organ::{Level, OrganMesh};
use serde_json::json;

#[derive(Debug, Args)]
pub struct NoduleBenchArgs {
    /// Radii (mm), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [4.0, 6.0, 8.0, 10.0, 12.0, 15.0])]
    radii: Vec<f64>,
    /// Levels, coarsest first (the last is the reference).
    #[arg(long, value_delimiter = ',', default_values = ["coarse", "medium"])]
    levels: Vec<String>,
    /// The nodule's Young's modulus over the tissue's.
    #[arg(long, default_value_t = 4.4)]
    ratio: f64,
    /// The probe point X,Y,Z (mm), on the palpable surface.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, default_values_t = [-7.0, 69.34, 7.0])]
    at: Vec<f64>,
    /// How deep the nodule's centre lies below the probe point, along the press (mm).
    #[arg(long, default_value_t = 22.0)]
    centre_depth_mm: f64,
    /// The press's depth (mm).
    #[arg(long, default_value_t = 5.0)]
    depth_mm: f64,
    /// `linear`, or a hyperelastic law (`neo-hookean`, `svk`) pressed by Newton.
    #[arg(long, default_value = "linear")]
    model: String,
    #[arg(long)]
    json: bool,
}

/// The force of a depth-controlled press on `organ`, with or without `nodule`.
fn force(
    organ: &OrganMesh,
    law: Option<Law>,
    at: [f64; 3],
    dir: [f64; 3],
    depth_mm: f64,
    nodule: Option<Nodule>,
) -> anyhow::Result<f64> {
    let req = ProbeRequest {
        at,
        force_n: f64::NAN,
        dir: Some(dir),
        radius_mm: 5.0,
        nodule,
    };
    let material = Material::default();
    let sol = match law {
        None => solve_linear_depth(organ, Element::P2, material, &req, depth_mm)?,
        Some(law) => {
            solve_hyperelastic(
                organ,
                Element::P2,
                material,
                law,
                &req,
                Some(depth_mm),
                NewtonSettings::default(),
            )?
            .0
        }
    };
    Ok(sol.force_n)
}

pub fn run(args: &NoduleBenchArgs) -> anyhow::Result<()> {
    let law = match args.model.as_str() {
        "linear" => None,
        "neo-hookean" => Some(Law::NeoHookean),
        "svk" => Some(Law::Svk),
        other => bail!("--model {other}: expected linear, neo-hookean or svk"),
    };
    let at: [f64; 3] = args
        .at
        .as_slice()
        .try_into()
        .ok()
        .context("--at: expected X,Y,Z")?;
    let levels: Vec<Level> = args
        .levels
        .iter()
        .map(|l| {
            l.parse()
                .map_err(|e: String| anyhow::anyhow!("--levels {l}: {e}"))
        })
        .collect::<anyhow::Result<_>>()?;
    if levels.is_empty() || args.radii.is_empty() {
        bail!("--levels and --radii: expected at least one each");
    }
    // Effects[level][radius]: F_with / F_without − 1.
    let mut effects = vec![vec![f64::NAN; args.radii.len()]; levels.len()];
    let mut rows = Vec::new();
    for (li, &level) in levels.iter().enumerate() {
        let mut organ = catalogue::mesh(OrganName::Liver, level);
        // Measured below the level's smallest resolved radius too: that floor is what
        // this table sets (`fe::nodule::MIN_RADIUS_PER_H`), so it is lifted here.
        let h_mm = organ.h_mm;
        organ.h_mm = 0.0;
        let dir = smooth_inward_dir(&organ, at).context("placing the probe")?;
        let centre = [0, 1, 2].map(|d| at[d] + args.centre_depth_mm * dir[d]);
        let t0 = Instant::now();
        let without = force(&organ, law, at, dir, args.depth_mm, None)?;
        let base_s = t0.elapsed().as_secs_f64();
        for (ri, &r) in args.radii.iter().enumerate() {
            let nodule = Nodule {
                center_mm: centre,
                radius_mm: r,
                ratio: args.ratio,
            };
            let t = Instant::now();
            let (effect, note) = match force(&organ, law, at, dir, args.depth_mm, Some(nodule)) {
                Ok(with) => (with / without - 1.0, String::new()),
                Err(e) => (f64::NAN, e.to_string()),
            };
            effects[li][ri] = effect;
            rows.push(json!({
                "level": level.name(), "h_mm": h_mm, "radius_mm": r, "ratio": args.ratio,
                "force_without_n": without, "effect": effect,
                "seconds": t.elapsed().as_secs_f64(), "base_seconds": base_s, "refused": note,
            }));
        }
    }
    let reference = levels.len() - 1;
    for row in &mut rows {
        let r = row["radius_mm"].as_f64().unwrap_or(f64::NAN);
        let ri = args.radii.iter().position(|&x| x == r).unwrap_or(0);
        let e = row["effect"].as_f64().unwrap_or(f64::NAN);
        let e_ref = effects[reference][ri];
        row["relative_to_finest"] = json!((e - e_ref) / e_ref);
    }
    if args.json {
        for r in &rows {
            println!("{r}");
        }
        return Ok(());
    }
    println!(
        "the nodule's effect on the force (F with / F without − 1), {} press to {} mm at {at:?}, ratio {}, centre {} mm below the probe",
        args.model, args.depth_mm, args.ratio, args.centre_depth_mm
    );
    print!("{:>10}", "radius mm");
    for l in &levels {
        print!(" {:>16}", l.name());
    }
    println!("   (relative to {})", levels[reference].name());
    for (ri, r) in args.radii.iter().enumerate() {
        print!("{r:>10.1}");
        for (li, _) in levels.iter().enumerate() {
            let e = effects[li][ri];
            let rel = (e - effects[reference][ri]) / effects[reference][ri];
            if e.is_nan() {
                print!(" {:>16}", "refused");
            } else if li == reference {
                print!(" {:>16}", format!("{:+.4}", e));
            } else {
                print!(" {:>16}", format!("{:+.4} ({:+.0} %)", e, 100.0 * rel));
            }
        }
        println!();
    }
    Ok(())
}
