//! Off-line vademecum computation and on-line evaluation of a palpation meta-model:
//! `palpa offline liver`, `palpa eval`, `palpa export-scene`.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use palpa_core::axis::{Discretization, closest_point};
use palpa_core::export::{FieldValue, Holds, PointField, write_surface_vtu};
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::mesh::triangle_normal;
use palpa_core::pgd::cluster::FarSettings;
use palpa_core::pgd::journal::Journal;
use palpa_core::pgd::linear::Settings;
use palpa_core::pgd::nodal::{self, NodalSettings};
use palpa_core::pgd::palpation::{compute, describe, journal_key, restore, setup, to_model};
use palpa_core::{ParamValue, Precision, Scalar, SeparatedModel};
use serde_json::json;

use super::args::{NoduleArgs, ProbeArgs};
use super::organ::{LevelArg, OrganName, mesh as mesh_organ};
use palpa_core::pgd::nodule::table::{EffectTable, NoduleEffect, apply_surface_gain};

/// How the vademecum is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Unit nodal loads on the parametric axis (exact at any probe position), modes by a
    /// randomized SVD of the surface map, plus the exact near field and compliance table.
    Nodal,
    /// The PGD over tool loads centred at palpable vertices (interpolated in between).
    Pgd,
}

#[derive(Debug, Args)]
pub struct OfflineArgs {
    /// `nodal` (default) or `pgd` (the earlier vertex-load vademecum).
    #[arg(long, value_enum, default_value = "nodal")]
    method: MethodArg,
    /// Nodal method: surface nodes within this distance of a loaded node get the exact
    /// near field (mm).
    #[arg(long, default_value_t = NodalSettings::default().band_radius_mm)]
    band_radius_mm: f64,
    /// Nodal method: degree of the compliance lattice on each palpable face.
    /// (Default: 5, raised up to 8 for tools small against the mesh.)
    #[arg(long)]
    table_degree: Option<usize>,
    /// Nodal method: tolerance of the hierarchical far field (singular values of the
    /// remainder's well-separated blocks, per unit load response, below it are
    /// dropped); `none` keeps only the band within `--band-radius-mm`. Default: 0.01
    /// for tools of 5 mm and more, down to 0.006 for smaller ones (a 2 mm tool's
    /// surface error needs it).
    #[arg(long, default_value = "auto")]
    far_tolerance: FarTolerance,
    #[arg(value_enum, default_value = "liver")]
    organ: OrganName,
    #[arg(long, value_enum, default_value = "coarse")]
    level: LevelArg,
    #[arg(long, default_value = "p2")]
    element: Element,
    /// Number of separated terms: for `pgd` the most it computes (default 100); for
    /// `nodal` the global modes beside the far field (default 5: the far field's
    /// blocks compress the remainder of few modes better than of many).
    #[arg(long)]
    modes: Option<usize>,
    /// Stop when a new term's relative norm falls below this.
    #[arg(long, default_value_t = PGD_TOL)]
    tol: f64,
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    /// The tissue's Young modulus (kPa).
    #[arg(long, default_value_t = Material::default().young_kpa)]
    young_kpa: f64,
    /// The tissue's Poisson ratio (below 0.5; P2 stays accurate toward it, P1 locks).
    #[arg(long, default_value_t = Material::default().poisson)]
    poisson: f64,
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
    #[arg(long, default_value_t = PGD_BLOCK)]
    block: usize,
    #[arg(long)]
    out: PathBuf,
    /// Continue from the journal of an interrupted run (`OUT.journal`).
    #[arg(long)]
    resume: bool,
    /// The tissue: `linear` writes the scene alone; `neo-hookean` or `svk` also builds
    /// the hyperelastic vademecum beside it (`OUT.tissue`, as `palpa tissue build`
    /// with its defaults would), so the scene opens with it.
    #[arg(long, value_enum, default_value = "linear")]
    model: TissueModel,
    /// With a hyperelastic `--model`: the deepest press it covers (mm) [default: 15].
    #[arg(long)]
    depth_max_mm: Option<f64>,
    /// With a hyperelastic `--model`: press only the palpable surface within X,Y,Z,R
    /// (mm), the region a scene shows.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    within: Option<Vec<f64>>,
}

impl OfflineArgs {
    /// The deepest press of the hyperelastic vademecum (mm).
    fn depth_max_mm(&self) -> f64 {
        self.depth_max_mm.unwrap_or(15.0)
    }

    /// The material asked for, checked (a finite positive modulus, `-1 < ν < 0.5`).
    fn material(&self) -> anyhow::Result<Material> {
        let (e, nu) = (self.young_kpa, self.poisson);
        if !(e.is_finite() && e > 0.0 && nu.is_finite() && nu > -1.0 && nu < 0.5) {
            bail!(
                "--young-kpa {e} --poisson {nu}: expected a positive modulus and -1 < ν < 0.5 \
                 (ν = 0.5 is incompressible, which displacement elements cannot represent)"
            );
        }
        Ok(Material {
            young_kpa: e,
            poisson: nu,
        })
    }
}

/// The tissue an `offline` scene is built for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TissueModel {
    Linear,
    NeoHookean,
    Svk,
}

/// The vademecum's description of an `offline` run (mesh, level, element, material,
/// tool, update): what its provenance records and a later `tradeoff` checks.
fn describe_run(
    organ: &palpa_core::organ::OrganMesh,
    args: &OfflineArgs,
    material: Material,
    update: bool,
) -> String {
    describe(
        organ,
        &format!("{:?}", args.level).to_lowercase(),
        args.element,
        material,
        args.radius_mm,
        update,
    )
}

/// `--method pgd`'s defaults: a new term's relative norm to stop at, and terms a block.
const PGD_TOL: f64 = 1e-4;
const PGD_BLOCK: usize = 16;

/// The PGD solver's own options: finite and positive, and refused with the nodal
/// build (the default), which has no fixed point to tune (they were once ignored there,
/// a NaN tolerance too).
fn check_pgd_options(args: &OfflineArgs) -> anyhow::Result<()> {
    if !(args.tol.is_finite() && args.tol >= 0.0) {
        bail!("--tol {}: expected a finite relative norm ≥ 0", args.tol);
    }
    if !(args.fp_tol.is_finite() && args.fp_tol > 0.0) {
        bail!(
            "--fp-tol {}: expected a finite relative change > 0",
            args.fp_tol
        );
    }
    if args.fp_max_iter == 0 || args.block == 0 {
        bail!(
            "--fp-max-iter {} --block {}: expected at least 1 each",
            args.fp_max_iter,
            args.block
        );
    }
    let d = Settings::default();
    let tuned = [
        ("--tol", args.tol != PGD_TOL),
        ("--no-update", args.no_update),
        ("--fp-tol", args.fp_tol != d.fixed_point_tol),
        ("--fp-max-iter", args.fp_max_iter != d.fixed_point_max_iter),
        ("--block", args.block != PGD_BLOCK),
    ];
    if args.method == MethodArg::Nodal
        && let Some((flag, _)) = tuned.iter().find(|(_, set)| *set)
    {
        bail!("{flag} tunes the PGD solver: it applies with --method pgd, not the nodal build");
    }
    // And the nodal build's own options, with the PGD solver.
    let nodal = [
        (
            "--band-radius-mm",
            args.band_radius_mm != NodalSettings::default().band_radius_mm,
        ),
        ("--table-degree", args.table_degree.is_some()),
        (
            "--far-tolerance",
            !matches!(args.far_tolerance, FarTolerance::Auto),
        ),
    ];
    if args.method == MethodArg::Pgd
        && let Some((flag, _)) = nodal.iter().find(|(_, set)| *set)
    {
        bail!(
            "{flag} shapes the nodal build: it applies with --method nodal (the default), not \
             the PGD solver"
        );
    }
    Ok(())
}

fn journal_path(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".journal");
    PathBuf::from(p)
}

pub fn offline(args: &OfflineArgs) -> anyhow::Result<()> {
    super::args::check_out(&args.out)?;
    check_pgd_options(args)?;
    if args.model == TissueModel::Linear
        && let Some(flag) = [
            ("--depth-max-mm", args.depth_max_mm.is_some()),
            ("--within", args.within.is_some()),
        ]
        .iter()
        .find_map(|(flag, given)| given.then_some(flag))
    {
        bail!(
            "{flag} shapes the hyperelastic vademecum: it applies with --model neo-hookean \
             or svk, not the linear scene alone"
        );
    }
    if args.model != TissueModel::Linear {
        // Refused before the scene's minutes of work, not after them.
        palpa_core::fe::depth_grid_points(
            args.depth_max_mm(),
            1.0,
            palpa_core::tissue::surface::MAX_GRID_POINTS,
        )
        .context("--depth-max-mm")?;
    }
    if args.method == MethodArg::Nodal {
        return offline_nodal(args);
    }
    if args.model != TissueModel::Linear {
        bail!(
            "--model: the hyperelastic vademecum is built beside the nodal scene; leave out --method pgd"
        );
    }
    let t0 = Instant::now();
    let material = args.material()?;
    let organ = mesh_organ(args.organ, args.level)?;
    let s = setup(&organ, args.element, material, args.radius_mm)
        .context("building the FE operators")?;
    let desc = describe_run(&organ, args, material, !args.no_update);
    let settings = Settings {
        max_modes: args.modes.unwrap_or(100),
        tol: args.tol,
        update: !args.no_update,
        fixed_point_tol: args.fp_tol,
        fixed_point_max_iter: args.fp_max_iter,
        block: args.block,
        ..Settings::default()
    };
    let jpath = journal_path(&args.out);
    let journal_key = journal_key(&desc, settings.block);
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
        restore(&s, &mut start, settings.update);
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

/// `palpa offline liver --method nodal`: see `palpa_core::pgd::nodal`.
fn offline_nodal(args: &OfflineArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    if args.resume {
        bail!("--resume applies to --method pgd; the nodal build has no journal");
    }
    if args.model != TissueModel::Linear && args.radius_mm != 5.0 {
        bail!(
            "--radius-mm {}: the hyperelastic vademecum presses with the 5 mm tool; leave \
             --radius-mm out with --model {:?}",
            args.radius_mm,
            args.model
        );
    }
    let modes = args.modes.unwrap_or(NodalSettings::default().modes);
    if modes == 0 {
        bail!("--modes must be at least 1");
    }
    if !(args.band_radius_mm.is_finite() && args.band_radius_mm >= 0.0) {
        bail!("--band-radius-mm {} must be ≥ 0", args.band_radius_mm);
    }
    if let Some(q) = args.table_degree
        && !(1..=8).contains(&q)
    {
        bail!("--table-degree {q} must be 1 to 8");
    }
    let material = args.material()?;
    let organ = mesh_organ(args.organ, args.level)?;
    let s = nodal::setup(&organ, args.element, material, args.radius_mm)
        .context("building the FE operators and the load axis")?;
    let desc = describe_run(&organ, args, material, false);
    let settings = NodalSettings {
        modes,
        band_radius_mm: args.band_radius_mm,
        table_degree: args.table_degree,
        far: match args.far_tolerance {
            FarTolerance::Auto => Some(FarSettings::for_tool(args.radius_mm)),
            FarTolerance::Fixed(tolerance) => Some(FarSettings {
                tolerance,
                ..FarSettings::default()
            }),
            FarTolerance::Off => None,
        },
        ..NodalSettings::default()
    };
    let (mut model, report) = nodal::build(&s, &settings, &desc, |stage| {
        eprintln!("palpa: {stage} ({:.1} s)", t0.elapsed().as_secs_f64());
    })
    .context("computing the nodal vademecum")?;
    if model.modes() < modes {
        // The surface map has no more independent directions than its smaller side.
        eprintln!(
            "palpa: warning: --modes {modes}: the surface map holds {} independent modes; kept {}",
            model.modes(),
            model.modes()
        );
    }
    let mut prov = model.provenance().clone();
    prov.input_hash = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(desc.as_bytes()));
    model.set_provenance(prov);
    file::save(&model, &args.out).with_context(|| format!("writing {}", args.out.display()))?;
    let tissue = tissue_beside(args)?;
    println!(
        "{}",
        json!({
            "out": args.out,
            "tissue": tissue,
            "method": "nodal",
            "modes": model.modes(),
            "modes_asked": modes,
            "load_nodes": report.load_nodes,
            "solves": report.solves,
            "free_dofs": s.space.free_dofs,
            "surface_rows": report.surface_rows,
            "surface_map_rel_error": report.surface_map_rel_error,
            "band_radius_mm": settings.band_radius_mm,
            "band_entries": report.band_entries,
            "table_degree": report.table_degree,
            "far_tolerance": settings.far.map(|f| f.tolerance),
            "far_blocks": report.far_blocks,
            "far_bytes": report.far_bytes,
            "near_bytes": report.near_bytes,
            "setup_s": report.setup_s,
            "solve_s": report.solve_s,
            "svd_s": report.svd_s,
            "modes_s": report.modes_s,
            "band_s": report.band_s,
            "table_s": report.table_s,
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
    /// Write the evaluated displacement of the nodes the file holds (.vtu): a scene's
    /// surface, or every node of a full model with its boundary triangles as cells;
    /// the file says which.
    #[arg(long)]
    out: Option<PathBuf>,
    /// For a tissue file (`palpa tissue build`): the scene it serves, `liver` (built
    /// in) or a `.palpa` file of the same mesh [default: liver].
    #[arg(long)]
    scene: Option<String>,
    #[command(flatten)]
    nodule: NoduleArgs,
    /// With `--nodule-at`: the nodule table of the scene (`palpa nodule build`)
    /// [default: the scene's path with the extension `.nodules`].
    #[arg(long)]
    nodules: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

/// The nodule asked for and the table that answers it, checked against the scene.
fn nodule_of(
    args: &EvalArgs,
    mesh_line: &str,
) -> anyhow::Result<Option<(EffectTable, NoduleEffect)>> {
    let Some(nodule) = args.nodule.nodule()? else {
        return Ok(None);
    };
    let path = args
        .nodules
        .clone()
        .unwrap_or_else(|| args.file.with_extension("nodules"));
    let table = EffectTable::load(&path).with_context(|| {
        format!(
            "reading the nodule table {} (`palpa nodule build` writes one for a scene)",
            path.display()
        )
    })?;
    table
        .check_mesh(mesh_line)
        .with_context(|| format!("{} for {}", path.display(), args.file.display()))?;
    let effect = table
        .place(&nodule)
        .with_context(|| format!("the nodule in {}", path.display()))?;
    Ok(Some((table, effect)))
}

pub fn eval(args: &EvalArgs) -> anyhow::Result<()> {
    if let (Some(t), None) = (&args.nodules, &args.nodule.nodule_at) {
        bail!(
            "--nodules {}: a table answers a nodule; give it with --nodule-at X,Y,Z",
            t.display()
        );
    }
    if palpa_core::tissue::law::is_tissue_file(&args.file) {
        if let Some(k) = args.modes {
            bail!(
                "--modes {k}: a tissue vademecum answers with the modes each press kept; \
                 `palpa lab tissue cut --modes` cuts them (and `palpa tradeoff` measures the cut)"
            );
        }
        return super::tissue::eval(
            &args.file,
            &args.probe,
            args.scene.as_deref().unwrap_or("liver"),
            args.nodule.nodule()?.map(|n| (n, args.nodules.as_deref())),
            args.out.as_deref(),
            args.json,
        );
    }
    if let Some(scene) = &args.scene {
        bail!(
            "--scene {scene}: names the scene a tissue file serves; {} is no tissue file \
             (a scene is evaluated as itself)",
            args.file.display()
        );
    }
    let model =
        file::load_any(&args.file).with_context(|| format!("loading {}", args.file.display()))?;
    let push = scene_push(&model, args.probe.at()?);
    match model {
        palpa_core::AnyModel::F32(m) => eval_model(&m, args, push),
        palpa_core::AnyModel::F64(m) => eval_model(&m, args, push),
    }
}

/// The direction the app presses along at the palpable point closest to `at`: the
/// scene's smoothed inward normal (`PalpationScene::frame`), which `palpa fe solve`
/// and a tissue file press along too. `None` where the file makes no scene; the face's
/// normal is the default there.
fn scene_push(model: &palpa_core::AnyModel, at: [f64; 3]) -> Option<[f64; 3]> {
    let scene = palpa_core::scene::PalpationScene::new(model.clone()).ok()?;
    let (point, _) = scene.closest_palpable(at)?;
    Some(scene.frame(&point).1.map(|c| -c))
}

/// `--dir` made a unit vector, or `default` where it was not given.
fn unit_dir(given: Option<[f64; 3]>, default: [f64; 3]) -> anyhow::Result<[f64; 3]> {
    match given {
        Some(d) => {
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if !(l.is_finite() && l > 0.0) {
                bail!("--dir has no length");
            }
            Ok(d.map(|v| v / l))
        }
        None => Ok(default),
    }
}

fn eval_model<T: Scalar>(
    m: &SeparatedModel<T>,
    args: &EvalArgs,
    push: Option<[f64; 3]>,
) -> anyhow::Result<()> {
    let at = args.probe.at()?;
    args.probe.check_press()?;
    if let Some(Discretization::SurfaceLoad { .. }) =
        m.axes().first().map(|a| &a.info.discretization)
    {
        return eval_nodal(m, args, at, push);
    }
    if args.nodule.nodule_at.is_some() {
        bail!(
            "--nodule-at: {} is a surface-vector vademecum; nodules are tabulated for nodal-load \
             scenes (`palpa scene build`, the built-in liver)",
            args.file.display()
        );
    }
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
    let face_inward = triangle_normal(a, b, c).map(|v| -v);
    let dir = unit_dir(args.probe.dir()?, push.unwrap_or(face_inward))?;
    let available = m.modes();
    let used = ModesUsed::of(args.modes, available)?;
    let modes = used.used;
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
    let contact_eval_ns = super::args::mean_ns(2000, || {
        m.particularize(std::hint::black_box(&value), &mut coeffs)?;
        m.reconstruct_rows(&contact_rows, &coeffs, &mut contact);
        Ok(())
    })?;
    let mut full = vec![0.0; m.rows()];
    let t = Instant::now();
    m.reconstruct(&coeffs, &mut full);
    let full_us = t.elapsed().as_secs_f64() * 1e6;
    let probe_unit = if contact.is_empty() {
        None
    } else {
        let u: [f64; 3] = [0, 1, 2].map(|d| {
            (0..3)
                .map(|i| hit.bary[i] * contact[3 * i + d])
                .sum::<f64>()
        });
        Some(u[0] * dir[0] + u[1] * dir[1] + u[2] * dir[2])
    };
    let f = press_force(&args.probe, probe_unit)?;
    let times_us = [contact_eval_ns / 1e3, full_us];
    let facts = Evaluated::new(&hit, dir, probe_unit.map(|c| f * c), f, used, times_us);
    report_eval(m, args, &full, &facts, json!({}))
}

/// `palpa eval` on a nodal-load vademecum: the load particularized exactly at the
/// probe point, the near field added, the probe displacement from the compliance table.
fn eval_nodal<T: Scalar>(
    m: &SeparatedModel<T>,
    args: &EvalArgs,
    at: [f64; 3],
    push: Option<[f64; 3]>,
) -> anyhow::Result<()> {
    let Some(Discretization::SurfaceLoad {
        positions,
        faces,
        palpable,
        field_nodes,
        ..
    }) = m.axes().first().map(|a| &a.info.discretization)
    else {
        bail!("{} is not a nodal-load vademecum", args.file.display());
    };
    let pal: Vec<u32> = (0..faces.len() as u32)
        .filter(|&f| palpable[f as usize])
        .collect();
    let tris: Vec<[u32; 3]> = pal
        .iter()
        .map(|&f| {
            let c = faces[f as usize];
            [c[0], c[1], c[2]]
        })
        .collect();
    let hit = closest_point(positions, &tris, at).context("the probe surface is empty")?;
    let face = pal[hit.triangle as usize];
    let [a, b, c] = tris[hit.triangle as usize].map(|i| positions[i as usize]);
    let face_inward = triangle_normal(a, b, c).map(|v| -v);
    let dir = unit_dir(args.probe.dir()?, push.unwrap_or(face_inward))?;
    let available = m.modes();
    let used = ModesUsed::of(args.modes, available)?;
    let modes = used.used;
    let value = [ParamValue::SurfaceMix {
        triangle: face,
        bary: hit.bary,
        mix: dir,
    }];
    let mut coeffs = vec![0.0; modes];
    let t = Instant::now();
    m.particularize(&value, &mut coeffs)?;
    let particularize_us = t.elapsed().as_secs_f64() * 1e6;
    let mut full = vec![0.0; m.rows()];
    let t = Instant::now();
    m.reconstruct(&coeffs, &mut full);
    m.add_near_field(&value, &mut full)?;
    let full_us = t.elapsed().as_secs_f64() * 1e6;
    // The probe displacement: the compliance table where there is one, else the P2
    // interpolation of the reconstructed field at the probe point.
    let (probe_unit, source) = match m.near().and_then(|n| n.compliance_tensor(face, hit.bary)) {
        Some(cten) => {
            let w: [f64; 3] = std::array::from_fn(|d| (0..3).map(|e| cten[d][e] * dir[e]).sum());
            (Some(w), "compliance table")
        }
        None => {
            let fc = faces[face as usize];
            let p2 = fc[3] != u32::MAX;
            let mut nv = [0.0; 6];
            palpa_core::disk::tri_shape(p2, hit.bary, &mut nv);
            let npf = if p2 { 6 } else { 3 };
            let rows: Option<Vec<u32>> = fc[..npf]
                .iter()
                .map(|&j| {
                    field_nodes
                        .get(j as usize)
                        .copied()
                        .filter(|&x| x != u32::MAX)
                })
                .collect();
            match rows {
                Some(rows) => {
                    let w: [f64; 3] = std::array::from_fn(|d| {
                        (0..npf)
                            .map(|a| nv[a] * full[3 * rows[a] as usize + d])
                            .sum()
                    });
                    (Some(w), "field rows")
                }
                None => (None, "unavailable"),
            }
        }
    };
    let free = probe_unit.map(|w| w[0] * dir[0] + w[1] * dir[1] + w[2] * dir[2]);
    // A nodule scales the probe's compliance by `1/(1 + effect)` (the effect on the force
    // of a depth-controlled press); the surface field is the nodule-free one.
    let nodule = nodule_of(args, &m.provenance().mesh)?;
    let effect = match &nodule {
        Some((table, placed)) => {
            let corners = tris[hit.triangle as usize].map(|i| positions[i as usize]);
            let found = table
                .face_at(corners)
                .and_then(|f| placed.at(table, f, hit.bary));
            Some(found.with_context(|| {
                format!(
                    "the probe point's face {face} lies beyond the nodule table's probe nodes \
                 (it covers the palpable surface within reach of its lattice)"
                )
            })?)
        }
        None => None,
    };
    let compliance = free.map(|c| c / (1.0 + effect.unwrap_or(0.0)));
    // The surface with the nodule as the app draws it: the nodule-free field at the
    // depth the press reaches (`f / (1 + e)` of its force), swayed away from the tool
    // with the whole force.
    if let Some(e) = effect {
        full.iter_mut().for_each(|v| *v /= 1.0 + e);
        let nodes = &m.geometry().nodes;
        if nodes.len() * 3 == full.len() {
            apply_surface_gain(e, hit.point, nodes.iter().copied(), &mut full);
        }
    }
    let f = press_force(&args.probe, compliance)?;
    let times_us = [particularize_us, full_us];
    let facts = Evaluated::new(&hit, dir, compliance.map(|c| f * c), f, used, times_us);
    let mut extra = json!({"probe_displacement_source": source, "near_field": m.near().is_some()});
    if let (Some((_, placed)), Some(e)) = (&nodule, effect) {
        let n = placed.nodule;
        extra["nodule"] = json!({"center_mm": n.center_mm, "radius_mm": n.radius_mm,
            "ratio": n.ratio, "effect": e, "place_ms": placed.place_s * 1e3,
            "force_without_nodule_n": press_force(&args.probe, free)?,
            "surface": "the nodule-free field at the depth reached, swayed with the force away from the tool"});
    }
    report_eval(m, args, &full, &facts, extra)
}

/// The force of a press: `--force-n` as given, or under `--depth-mm` the force that
/// moves the probe point that far, `d / c` (the model is linear; `c` the probe
/// displacement per newton).
fn press_force(probe: &ProbeArgs, compliance_mm_per_n: Option<f64>) -> anyhow::Result<f64> {
    probe.check_press()?;
    match (probe.force_n, probe.depth_mm) {
        (Some(f), _) => Ok(f),
        (None, Some(d)) => match compliance_mm_per_n {
            Some(c) if c.is_finite() && c.abs() > 0.0 => Ok(d / c),
            // A point whose triangle is held on the fixed region: no force moves it.
            Some(c) if c.is_finite() => bail!(
                "--depth-mm {d}: the probe point does not move under a push (its \
                 displacement along the push is {c:.3e} mm/N: it lies on the fixed region, \
                 its triangle held), so no force presses it {d} mm; press a point off the \
                 fixed region, or give --force-n to see the tissue around it move"
            ),
            _ => bail!(
                "--depth-mm needs the probe displacement at this point, which this model does not give; use --force-n"
            ),
        },
        (None, None) => bail!("give --force-n (N) or --depth-mm (mm)"),
    }
}

/// The modes `palpa eval` uses: all by default, clamped (with a notice) to what the
/// file holds.
#[derive(Debug, Clone, Copy)]
struct ModesUsed {
    used: usize,
    available: usize,
    clamped: bool,
}

impl ModesUsed {
    fn of(asked: Option<usize>, available: usize) -> anyhow::Result<Self> {
        let (used, clamped) = match asked {
            Some(0) => bail!("--modes must be at least 1"),
            Some(k) if k > available => {
                eprintln!("palpa: {k} modes asked, the file holds {available}; using {available}");
                (available, true)
            }
            Some(k) => (k, false),
            None => (available, false),
        };
        Ok(ModesUsed {
            used,
            available,
            clamped,
        })
    }
}

/// What both kinds of `palpa eval` report.
struct Evaluated<'a> {
    hit: &'a palpa_core::axis::SurfaceHit,
    dir: [f64; 3],
    probe_displacement_mm: Option<f64>,
    /// The press's force (given, or the one a given depth needs).
    force_n: f64,
    modes: ModesUsed,
    /// Evaluation (particularization, contact) and full reconstruction, µs.
    times_us: [f64; 2],
}

impl<'a> Evaluated<'a> {
    fn new(
        hit: &'a palpa_core::axis::SurfaceHit,
        dir: [f64; 3],
        probe_displacement_mm: Option<f64>,
        force_n: f64,
        modes: ModesUsed,
        times_us: [f64; 2],
    ) -> Self {
        Evaluated {
            hit,
            dir,
            probe_displacement_mm,
            force_n,
            modes,
            times_us,
        }
    }
}

/// The deepest press (mm) a linear model's answer is reported without a flag. At 2.6 mm
/// the linear tissue's force was within 5.8 % and its surface within 0.21 mm of the
/// neo-Hookean tissue's at 16 held-out points of coarse P2, at 7.3 mm 18.8 % and
/// 1.53 mm (docs/lab/tissue-measurements.md §1).
const LINEAR_AGREES_MM: f64 = 2.6;

/// Builds the report (the common keys, then `extra`'s), adds the maximum
/// displacement, writes `--out`, prints it.
fn report_eval<T: Scalar>(
    m: &SeparatedModel<T>,
    args: &EvalArgs,
    full: &[f64],
    e: &Evaluated<'_>,
    extra: serde_json::Value,
) -> anyhow::Result<()> {
    let f = e.force_n;
    super::args::warn_far_from_surface(e.hit.distance, e.hit.point);
    let mut report = json!({
        "probe_point": e.hit.point,
        "probe_projection_distance_mm": e.hit.distance,
        "direction": e.dir,
        "force_n": f,
        "control": if args.probe.force_n.is_some() { "force" } else { "depth" },
        "probe_displacement_mm": e.probe_displacement_mm,
        "modes_used": e.modes.used,
        "modes_available": e.modes.available,
        "modes_clamped": e.modes.clamped,
        "eval_us": e.times_us[0],
        "full_reconstruction_us": e.times_us[1],
        "precision": T::PRECISION.name(),
    });
    if let (Some(r), serde_json::Value::Object(x)) = (report.as_object_mut(), extra) {
        r.extend(x);
    }
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
                value: e.modes.used as f64,
            },
        ];
        // A scene keeps its surface's nodes only; a full model every node of the
        // volume, its boundary triangles as cells (it stores no tetrahedra).
        let mut on_surface = vec![false; g.nodes.len()];
        for &v in g.surface.iter().flatten() {
            if let Some(x) = on_surface.get_mut(v as usize) {
                *x = true;
            }
        }
        let holds = if !g.surface.is_empty() && on_surface.iter().all(|&x| x) {
            Holds::Surface
        } else {
            Holds::Volume
        };
        write_surface_vtu(out, &g.nodes, &g.surface, holds, &fields, &meta)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    report["max_displacement_mm"] = json!(max);
    // A linear model answers any press, however deep; say where it stops being tissue.
    let deep = e
        .probe_displacement_mm
        .is_some_and(|d| d.abs() > LINEAR_AGREES_MM);
    report["beyond_linear_range"] = json!(deep);
    if deep {
        // The app presses with a tissue beside the scene; say how to get its answer.
        let sidecar = args.file.with_extension("tissue");
        let hint = if sidecar.exists() && sidecar != args.file {
            format!(
                "{} beside this scene models them, and the app presses with it: `palpa eval \
                 {}` answers as the app does",
                sidecar.display(),
                sidecar.display()
            )
        } else {
            "a .tissue scene models deep presses".to_string()
        };
        eprintln!(
            "warning: a linear press of {:.3} mm: tissue is not linear that deep (at 2.6 mm \
             the linear force is up to 5.8 % off the neo-Hookean tissue's, at 7.3 mm 18.8 %); \
             {hint}",
            e.probe_displacement_mm.unwrap_or(0.0)
        );
    }
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
    /// Bits of the near and far fields' stored values: 16 (half the bytes of 32, each
    /// within 1.5e-5 of its 256-value chunk's largest) or 32 (f32).
    #[arg(long, default_value = "16", value_parser = parse_near_bits)]
    near_bits: u32,
    #[arg(long)]
    out: PathBuf,
}

/// `--near-bits`: 16 or 32.
fn parse_near_bits(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(b @ (16 | 32)) => Ok(b),
        _ => Err(format!(
            "{s}: expected 16 or 32 (bits per stored near- and far-field value)"
        )),
    }
}

pub fn export_scene(args: &ExportSceneArgs) -> anyhow::Result<()> {
    if args.modes == Some(0) {
        bail!("--modes 0: expected at least one mode to keep");
    }
    // A network's model is shipped as `cme offline` wrote it: it has no surface rows.
    // (A greedy one would otherwise be written as if it were a scene.)
    let header = file::read_header(&args.file)
        .with_context(|| format!("reading the header of {}", args.file.display()))?;
    let network_kinds = [
        palpa_core::cme::greedy::KIND,
        palpa_core::cme::model::TRAIN_KIND,
        palpa_core::cme::model::VIEWS_KIND,
    ];
    if network_kinds.contains(&header.meta.kind.as_str()) {
        bail!(
            "{}: a gene-network meta-model; `palpa export-scene` ships palpation scenes \
             (a network's file opens as it is: `palpa open --scene`, `palpa cme eval`)",
            args.file.display()
        );
    }
    let m = file::load_any(&args.file)
        .with_context(|| format!("loading {}", args.file.display()))?
        .into_f64();
    let available = m.modes();
    let mut m = match args.modes {
        Some(n) => {
            if n > available {
                eprintln!(
                    "palpa: warning: --modes {n}: the file holds {available}; kept {available}"
                );
            }
            m.truncated(n.min(available)).context("truncating")?
        }
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
    let q16 = args.near_bits == 16;
    match (args.precision, q16) {
        (PrecisionArg::F32, false) => file::save(&m.convert::<f32>(), &args.out),
        (PrecisionArg::F32, true) => file::save_q16(&m.convert::<f32>(), &args.out),
        (PrecisionArg::F64, false) => file::save(&m, &args.out),
        (PrecisionArg::F64, true) => file::save_q16(&m, &args.out),
    }
    .with_context(|| format!("writing {}", args.out.display()))?;
    let sidecars = export_sidecars(&args.file, &args.out)?;
    let bytes = std::fs::metadata(&args.out).map(|x| x.len()).unwrap_or(0);
    println!(
        "{}",
        json!({"out": args.out, "rows": m.rows(), "modes": m.modes(), "modes_asked": args.modes, "sidecars": sidecars,
               "precision": match args.precision { PrecisionArg::F32 => Precision::F32, PrecisionArg::F64 => Precision::F64 }.name(),
               "near_bits": args.near_bits, "bytes": bytes})
    );
    Ok(())
}

/// With a hyperelastic `--model`, the vademecum built beside the scene just written
/// (`OUT.tissue`) and its summary; `None` for a linear tissue.
fn tissue_beside(args: &OfflineArgs) -> anyhow::Result<Option<serde_json::Value>> {
    use super::args::NonlinearModel;
    let model = match args.model {
        TissueModel::Linear => return Ok(None),
        TissueModel::NeoHookean => NonlinearModel::NeoHookean,
        TissueModel::Svk => NonlinearModel::Svk,
    };
    let defaults = palpa_core::tissue::surface::SurfaceLawOptions::default();
    let material = args.material()?;
    let build = super::tissue::BuildArgs {
        shard: None,
        plan: false,
        plan_presses: 2,
        plan_cores: Vec::new(),
        json: false,
        recipe: "default".into(),
        no_band: false,
        organ: super::args::OrganArgs {
            organ: args.organ,
            level: args.level,
            surface: None,
            units: None,
            place: Default::default(),
            regions: Default::default(),
        },
        model,
        element: args.element,
        depth_max_mm: args.depth_max_mm(),
        depth_step_mm: 1.0,
        orders: defaults.orders,
        tolerance_mm: palpa_core::tissue::law::DEFAULT_TOLERANCE_MM,
        bits: palpa_core::tissue::law::DEFAULT_BITS.count(),
        active_cutoff: defaults.active_cutoff,
        within: args.within.clone(),
        cover: None,
        young_kpa: material.young_kpa,
        poisson: material.poisson,
        no_edges: false,
        refine_above_mm: None,
        no_refine: false,
        separate_modes: false,
        jobs: None,
        out: args.out.with_extension("tissue"),
    };
    let (_, summary) = super::tissue::build(&build).context("building the tissue vademecum")?;
    Ok(Some(summary))
}

/// The nonlinear tissue beside a scene (`X.tissue`, `X.law`) goes with its export:
/// copied beside the exported scene, which is then opened with it (the vademecum binds
/// by rest positions, so a scene cut to its surface rows or to fewer modes keeps it;
/// one that no longer fits is named, and its copy removed).
fn export_sidecars(from: &Path, to: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut copied = Vec::new();
    for ext in ["tissue", "law"] {
        let src = from.with_extension(ext);
        if !src.exists() {
            continue;
        }
        let dest = to.with_extension(ext);
        if dest != src {
            let bytes =
                std::fs::read(&src).with_context(|| format!("reading {}", src.display()))?;
            palpa_core::fsutil::atomic_write(&dest, |w| w.write_all(&bytes))
                .with_context(|| format!("writing {}", dest.display()))?;
        }
        copied.push(dest);
    }
    if let Some(first) = copied.first()
        && let Err(e) = palpa_app::scenes::load(&to.display().to_string())
    {
        for c in &copied {
            if c != &from.with_extension(c.extension().unwrap_or_default()) {
                let _ = std::fs::remove_file(c);
            }
        }
        return Err(e.context(format!(
            "the exported scene does not open with the tissue {} that came with it",
            first.display()
        )));
    }
    Ok(copied)
}

/// `--far-tolerance`: `auto`, a positive number or `none`.
#[derive(Debug, Clone, Copy)]
enum FarTolerance {
    Auto,
    Fixed(f64),
    Off,
}

impl std::str::FromStr for FarTolerance {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => return Ok(FarTolerance::Auto),
            "none" => return Ok(FarTolerance::Off),
            _ => {}
        }
        match s.parse::<f64>() {
            Ok(t) if t.is_finite() && t > 0.0 => Ok(FarTolerance::Fixed(t)),
            _ => Err(format!(
                "expected `auto`, a positive tolerance or `none`, got `{s}`"
            )),
        }
    }
}
