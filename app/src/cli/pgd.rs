//! Off-line vademecum computation and on-line evaluation of a palpation meta-model:
//! `palpa offline liver`, `palpa eval`, `palpa export-scene`.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use palpa_core::axis::{Discretization, closest_point};
use palpa_core::export::{FieldValue, PointField, write_surface_vtu};
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::mesh::triangle_normal;
use palpa_core::pgd::journal::Journal;
use palpa_core::pgd::linear::{Settings, update};
use palpa_core::pgd::palpation::{compute, describe, setup, to_model};
use palpa_core::{ParamValue, Precision, Scalar, SeparatedModel};
use serde_json::json;

use super::args::ProbeArgs;
use super::organ::{LevelArg, OrganName, mesh as mesh_organ};

#[derive(Debug, Args)]
pub struct OfflineArgs {
    #[arg(value_enum, default_value = "liver")]
    organ: OrganName,
    #[arg(long, value_enum, default_value = "coarse")]
    level: LevelArg,
    #[arg(long, default_value = "p2")]
    element: Element,
    /// Maximum number of terms.
    #[arg(long, default_value_t = 100)]
    modes: usize,
    /// Stop when a new term's relative norm falls below this.
    #[arg(long, default_value_t = 1e-4)]
    tol: f64,
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    /// Skip the Galerkin update of the parametric functions after each term.
    #[arg(long)]
    no_update: bool,
    /// Fixed-point tolerance of each enrichment (relative change of the new term).
    #[arg(long, default_value_t = Settings::default().fixed_point_tol)]
    fp_tol: f64,
    /// Most fixed-point iterations per term (or per block).
    #[arg(long, default_value_t = Settings::default().fixed_point_max_iter)]
    fp_max_iter: usize,
    /// Terms found together per fixed point (their spatial solves share one pass
    /// over the factored stiffness); 1 is the paper's one-term enrichment.
    #[arg(long, default_value_t = 16)]
    block: usize,
    #[arg(long)]
    out: PathBuf,
    /// Continue from the journal of an interrupted run (`OUT.journal`).
    #[arg(long)]
    resume: bool,
}

fn journal_path(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".journal");
    PathBuf::from(p)
}

pub fn offline(args: &OfflineArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let material = Material::default();
    let organ = mesh_organ(args.organ, args.level, None)?;
    let s = setup(&organ, args.element, material, args.radius_mm)
        .context("building the FE operators")?;
    let desc = describe(
        &organ,
        &format!("{:?}", args.level).to_lowercase(),
        args.element,
        material,
        args.radius_mm,
        !args.no_update,
    );
    let settings = Settings {
        max_modes: args.modes,
        tol: args.tol,
        update: !args.no_update,
        fixed_point_tol: args.fp_tol,
        fixed_point_max_iter: args.fp_max_iter.max(1),
        block: args.block.max(1),
        ..Settings::default()
    };
    let jpath = journal_path(&args.out);
    // The journal key also names the block size: a resumed run must partition the
    // terms into the same blocks to reproduce an uninterrupted one.
    let journal_key = format!("{desc} block={}", settings.block);
    let (mut journal, mut start) = if args.resume {
        Journal::resume(&jpath, &journal_key, settings.block)
            .with_context(|| format!("resuming from {}", jpath.display()))?
    } else {
        (
            Journal::create(&jpath, &journal_key)
                .with_context(|| format!("creating {}", jpath.display()))?,
            Default::default(),
        )
    };
    if !start.x.is_empty() {
        // Rebuild what the journal does not store; the update recomputes every y.
        let ops = s.ops();
        start.kx = start
            .x
            .iter()
            .map(|x| {
                let mut y = vec![0.0; x.len()];
                ops.k.mul(x, &mut y);
                y
            })
            .collect();
        start.ftx = start.x.iter().map(|x| ops.f.mul_t(x)).collect();
        start.extend_gram();
        if settings.update {
            update(&ops, &mut start);
        }
        eprintln!(
            "palpa: resumed {} terms from {}",
            start.x.len(),
            jpath.display()
        );
    }
    let resumed = start.x.len();
    let mut journal_err: Option<std::io::Error> = None;
    let t_solve = Instant::now();
    let mut journaled = resumed;
    let terms = compute(&s, &settings, start, |t| {
        let k = t.x.len() - 1;
        // A block solve reports several new terms at once.
        while journal_err.is_none() && journaled < t.x.len() {
            if let Err(e) = journal.append(t, journaled) {
                journal_err = Some(e);
            }
            journaled += 1;
        }
        let done = t.x.len() - resumed;
        let per = t_solve.elapsed().as_secs_f64() / done as f64;
        let eta = per * (settings.max_modes - t.x.len()) as f64;
        eprint!(
            "\rmodes {:>4}/{}  residual {:.3e}  {:.2} s/mode  ETA ≤ {:.0} s   ",
            t.x.len(),
            settings.max_modes,
            t.residual_per_mode[k],
            per,
            eta
        );
        let _ = std::io::stderr().flush();
    });
    eprintln!();
    if let Some(e) = journal_err {
        return Err(e).with_context(|| format!("writing the journal {}", jpath.display()));
    }
    let mut model = to_model(&s, &terms, &desc, args.tol);
    let mut prov = model.provenance().clone();
    prov.input_hash = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(desc.as_bytes()));
    model.set_provenance(prov);
    file::save(&model, &args.out).with_context(|| format!("writing {}", args.out.display()))?;
    let _ = std::fs::remove_file(&jpath);
    println!(
        "{}",
        json!({
            "out": args.out,
            "modes": terms.x.len(),
            "resumed_modes": resumed,
            "final_residual": terms.residual_per_mode.last(),
            "block": settings.block,
            "fixed_point_iterations_mean": terms.fixed_point_iterations[resumed..].iter().sum::<usize>() as f64
                / (terms.x.len() - resumed).max(1) as f64,
            "free_dofs": s.f.rows,
            "parameters": s.f.cols.len(),
            "setup_s": s.setup_s,
            "pgd_s": t_solve.elapsed().as_secs_f64(),
            "total_s": t0.elapsed().as_secs_f64(),
            "bytes": std::fs::metadata(&args.out).map(|m| m.len()).ok(),
        })
    );
    Ok(())
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    file: PathBuf,
    #[command(flatten)]
    probe: ProbeArgs,
    /// Modes to use (default: all the file holds).
    #[arg(long)]
    modes: Option<usize>,
    /// Write the evaluated displacement of the rows the file holds (.vtu: its
    /// surface triangles when it has them, else its nodes as points).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

pub fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    match file::load_any(&args.file).with_context(|| format!("loading {}", args.file.display()))? {
        palpa_core::AnyModel::F32(m) => eval_model(&m, args),
        palpa_core::AnyModel::F64(m) => eval_model(&m, args),
    }
}

fn eval_model<T: Scalar>(m: &SeparatedModel<T>, args: &EvalArgs) -> anyhow::Result<()> {
    let at = args.probe.at()?;
    let Some(Discretization::SurfaceVector {
        vertices,
        triangles,
        field_nodes,
    }) = m.axes().first().map(|a| &a.info.discretization)
    else {
        bail!(
            "{} is not a palpation meta-model (its first axis is not a probe surface)",
            args.file.display()
        );
    };
    if m.axes().len() != 1 {
        bail!(
            "{} has {} axes; palpa eval expects the linear vademecum's one",
            args.file.display(),
            m.axes().len()
        );
    }
    let hit = closest_point(vertices, triangles, at).context("the probe surface is empty")?;
    let tri = triangles[hit.triangle as usize];
    let [a, b, c] = tri.map(|i| vertices[i as usize]);
    let n = triangle_normal(a, b, c);
    let dir = match args.probe.dir()? {
        Some(d) => {
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if l == 0.0 {
                bail!("--dir has no length");
            }
            d.map(|v| v / l)
        }
        None => n.map(|v| -v),
    };
    let available = m.modes();
    let (modes, clamped_modes) = match args.modes {
        Some(k) if k > available => {
            eprintln!("palpa: {k} modes asked, the file holds {available}; using {available}");
            (available, true)
        }
        Some(0) => bail!("--modes must be at least 1"),
        Some(k) => (k, false),
        None => (available, false),
    };
    let mut coeffs = vec![0.0; modes];
    let value = [ParamValue::SurfaceMix {
        triangle: hit.triangle,
        bary: hit.bary,
        mix: dir,
    }];
    let contact_rows: Vec<u32> = if field_nodes.is_empty() {
        Vec::new()
    } else {
        tri.iter()
            .flat_map(|&v| (0..3).map(move |c| 3 * field_nodes[v as usize] + c))
            .collect()
    };
    let mut contact = vec![0.0; contact_rows.len()];
    // Time the on-line path (particularize + contact rows) over repetitions.
    let reps = 2000;
    let t = Instant::now();
    for _ in 0..reps {
        m.particularize(std::hint::black_box(&value), &mut coeffs)?;
        m.reconstruct_rows(&contact_rows, &coeffs, &mut contact);
    }
    let contact_eval_ns = t.elapsed().as_nanos() as f64 / f64::from(reps);
    let mut full = vec![0.0; m.rows()];
    let t = Instant::now();
    m.reconstruct(&coeffs, &mut full);
    let full_us = t.elapsed().as_secs_f64() * 1e6;
    let f = args.probe.force_n;
    let probe_displacement_mm = if contact.is_empty() {
        None
    } else {
        let u: [f64; 3] = [0, 1, 2].map(|d| {
            (0..3)
                .map(|i| hit.bary[i] * contact[3 * i + d])
                .sum::<f64>()
                * f
        });
        Some(u[0] * dir[0] + u[1] * dir[1] + u[2] * dir[2])
    };
    let max = full
        .chunks_exact(3)
        .map(|v| f.abs() * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .fold(0.0, f64::max);
    if let Some(out) = &args.out {
        let g = m.geometry();
        if g.nodes.is_empty() {
            bail!("{} carries no geometry to write", args.file.display());
        }
        let u: Vec<f64> = full.iter().map(|v| v * f).collect();
        let fields = [PointField {
            name: "displacement".into(),
            components: 3,
            values: u,
        }];
        let meta = [
            FieldValue {
                name: "force_n".into(),
                value: f,
            },
            FieldValue {
                name: "modes_used".into(),
                value: modes as f64,
            },
        ];
        let cells: Vec<[u32; 3]> = if g.surface.is_empty() {
            // No surface: degenerate triangles would mislead; write points only.
            Vec::new()
        } else {
            g.surface.clone()
        };
        write_surface_vtu(out, &g.nodes, &cells, &fields, &meta)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    let report = json!({
        "probe_point": hit.point,
        "probe_projection_distance_mm": hit.distance,
        "direction": dir,
        "force_n": f,
        "probe_displacement_mm": probe_displacement_mm,
        "max_displacement_mm": max,
        "modes_used": modes,
        "modes_available": available,
        "modes_clamped": clamped_modes,
        "eval_us": contact_eval_ns / 1e3,
        "full_reconstruction_us": full_us,
        "precision": T::PRECISION.name(),
    });
    super::args::print_report(&report, args.json)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PrecisionArg {
    F32,
    F64,
}

#[derive(Debug, Args)]
pub struct ExportSceneArgs {
    file: PathBuf,
    /// Keep only the boundary nodes' rows (what a palpation scene renders).
    #[arg(long)]
    surface_only: bool,
    #[arg(long, value_enum, default_value = "f32")]
    precision: PrecisionArg,
    /// Keep the first n modes.
    #[arg(long)]
    modes: Option<usize>,
    #[arg(long)]
    out: PathBuf,
}

pub fn export_scene(args: &ExportSceneArgs) -> anyhow::Result<()> {
    let m = file::load_any(&args.file)
        .with_context(|| format!("loading {}", args.file.display()))?
        .into_f64();
    let mut m = match args.modes {
        Some(n) => m.truncated(n.min(m.modes())).context("truncating")?,
        None => m,
    };
    if args.surface_only {
        let g = m.geometry();
        if g.surface.is_empty() {
            bail!(
                "{} carries no surface geometry to select",
                args.file.display()
            );
        }
        let mut nodes: Vec<u32> = g.surface.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        m = m
            .select_nodes(&nodes)
            .context("selecting the surface rows")?;
    }
    match args.precision {
        PrecisionArg::F32 => file::save(&m.convert::<f32>(), &args.out),
        PrecisionArg::F64 => file::save(&m, &args.out),
    }
    .with_context(|| format!("writing {}", args.out.display()))?;
    let bytes = std::fs::metadata(&args.out).map(|x| x.len()).unwrap_or(0);
    println!(
        "{}",
        json!({"out": args.out, "rows": m.rows(), "modes": m.modes(),
               "precision": match args.precision { PrecisionArg::F32 => Precision::F32, PrecisionArg::F64 => Precision::F64 }.name(),
               "bytes": bytes})
    );
    Ok(())
}
