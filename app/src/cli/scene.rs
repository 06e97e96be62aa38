//! `palpa scene build`: a user's organ surface to a palpation scene in one command.
//!
//! Stages: surface (read, repair, units, axes, validate) → mesh (tetrahedra, regions)
//! → vademecum (the nodal-load linear vademecum, as `palpa offline liver`) → tradeoff
//! (held-out presses against full FE) → scene (surface rows, f32, with the tradeoff
//! table in its header) → tissue (with `--model neo-hookean|svk`: `palpa tissue build`
//! of the same organ and flags, its recipe's stages, `OUT.tissue`). The slow stages'
//! results are kept in `OUT.build/` (the tissue's presses in its logs), keyed by
//! everything that determines them, so an interrupted build run again with the same
//! arguments goes on from the last finished stage; the folder is removed when the
//! scene is written.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, Subcommand, ValueEnum};
use palpa_core::fe::law::Law;
use palpa_core::fe::{Element, Material};
use palpa_core::file;
use palpa_core::mesh::quality;
use palpa_core::organ::Level;
use palpa_core::organ::user::{self, SurfaceOptions};
use palpa_core::pgd::cluster::FarSettings;
use palpa_core::pgd::nodal::{self, NodalSettings};
use palpa_core::pgd::palpation::describe_user;
use palpa_core::pgd::tradeoff::nodal_table;
use palpa_core::surface_import::frame::Units;
use serde_json::json;

use super::args::{PlaceArgs, RegionArgs};
use super::organ::LevelArg;

#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Surface file → tetrahedral mesh → vademecum → tradeoff → scene, resumable.
    Build(Box<BuildArgs>),
    /// Write a closed surface made here: the kidney example (cm, y up, z anterior), or
    /// a sphere or an ellipsoid of known volume (for trying `scene build`).
    Shape(ShapeArgs),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ShapeName {
    /// A left kidney, 11 × 6 × 4 cm with its hilum, in cm, y up, z anterior.
    Kidney,
    /// A sphere of radius `--size` (in the file's units).
    Sphere,
    /// An ellipsoid of semi-axes `--size`, `0.75 --size`, `0.5 --size`.
    Ellipsoid,
}

#[derive(Debug, Args)]
pub struct ShapeArgs {
    #[arg(value_enum)]
    shape: ShapeName,
    /// Radius or largest semi-axis (sphere, ellipsoid), in whatever unit the file is
    /// meant to be read in.
    #[arg(long, default_value_t = 5.0)]
    size: f64,
    /// Subdivisions of the icosahedron (20·4^n triangles).
    #[arg(long, default_value_t = 4)]
    subdivisions: u32,
    /// `.obj`, `.stl` (binary) or `.ply` (binary).
    #[arg(long)]
    out: PathBuf,
}

fn shape(args: &ShapeArgs) -> anyhow::Result<()> {
    use palpa_core::surface_import::shapes::{ellipsoid, kidney_cm};
    if !(args.size.is_finite() && args.size > 0.0) || args.subdivisions > 7 {
        bail!("--size must be positive and --subdivisions at most 7");
    }
    let r = args.size;
    let s = match args.shape {
        ShapeName::Kidney => kidney_cm(),
        ShapeName::Sphere => ellipsoid(r, r, r, args.subdivisions),
        ShapeName::Ellipsoid => ellipsoid(r, 0.75 * r, 0.5 * r, args.subdivisions),
    };
    s.write_by_extension(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "{}",
        json!({"out": args.out, "vertices": s.vertices.len(), "triangles": s.triangles.len(),
               "enclosed_volume": s.volume()})
    );
    Ok(())
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TissueModel {
    /// Linear elasticity (the vademecum alone).
    Linear,
    /// The vademecum plus a compressible neo-Hookean tissue (`OUT.tissue`).
    NeoHookean,
    /// The vademecum plus a Saint Venant–Kirchhoff tissue (`OUT.tissue`).
    Svk,
}

#[derive(Debug, Args)]
pub struct BuildArgs {
    /// A closed organ surface: OBJ, STL (ASCII or binary) or PLY (ASCII or binary).
    #[arg(long)]
    surface: PathBuf,
    /// The file's length unit (surface files do not carry one).
    #[arg(long)]
    units: Units,
    #[command(flatten)]
    place: PlaceArgs,
    #[command(flatten)]
    regions: RegionArgs,
    #[arg(long, value_enum, default_value = "coarse")]
    level: LevelArg,
    #[arg(long, default_value = "p2")]
    element: Element,
    #[arg(long, value_enum, default_value = "linear")]
    model: TissueModel,
    /// Deepest press the tissue covers (mm), with `--model neo-hookean|svk`
    /// [default: 15].
    #[arg(long)]
    depth_max_mm: Option<f64>,
    /// The tissue's recipe, with `--model neo-hookean|svk` (see `palpa tissue build
    /// --recipe`): `default`, `quick` (a first look in a third of the presses) or
    /// `shipped`.
    #[arg(long)]
    recipe: Option<String>,
    /// Probe tool radius (mm).
    #[arg(long, default_value_t = 5.0)]
    radius_mm: f64,
    /// Held-out random presses of the tradeoff table (plus six special ones).
    #[arg(long, default_value_t = 24)]
    held_out: usize,
    #[arg(long)]
    out: PathBuf,
    /// Print the summary as one JSON line.
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: &SceneCommand) -> anyhow::Result<()> {
    match cmd {
        SceneCommand::Build(args) => build(args),
        SceneCommand::Shape(args) => shape(args),
    }
}

/// One progress line per stage, with the time since the build started.
struct Progress {
    t0: Instant,
    stage: usize,
    /// Stages in all: five, six with a tissue.
    stages: usize,
    times: Vec<(&'static str, f64)>,
    last: f64,
}

impl Progress {
    fn start(&mut self, name: &'static str, what: &str) {
        self.stage += 1;
        eprintln!(
            "palpa: [{}/{}] {name}: {what} ({:.1} s)",
            self.stage,
            self.stages,
            self.t0.elapsed().as_secs_f64()
        );
        let _ = std::io::stderr().flush();
        self.times.push((name, 0.0));
    }

    fn done(&mut self) {
        let now = self.t0.elapsed().as_secs_f64();
        if let Some(t) = self.times.last_mut() {
            t.1 = now - self.last;
        }
        self.last = now;
    }
}

fn build_dir(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".build");
    PathBuf::from(p)
}

fn build(args: &BuildArgs) -> anyhow::Result<()> {
    let mut pr = Progress {
        t0: Instant::now(),
        stage: 0,
        stages: if args.model == TissueModel::Linear {
            5
        } else {
            6
        },
        times: Vec::new(),
        last: 0.0,
    };
    let level: Level = args.level.into();
    let material = Material::default();
    if !(args.radius_mm.is_finite() && args.radius_mm > 0.0) {
        bail!("--radius-mm {} must be a positive length", args.radius_mm);
    }
    // Before any stage: a build once meshed and solved for minutes, then drew 10⁸ points.
    super::tissue::points::check_heldout(args.held_out)?;
    // Likewise the tissue's arguments (once a NaN depth built the whole scene and no
    // tissue): parsed as `palpa tissue build` parses them, before any stage.
    let law = match args.model {
        TissueModel::Linear => {
            if args.depth_max_mm.is_some() || args.recipe.is_some() {
                bail!(
                    "--depth-max-mm and --recipe shape the tissue: they apply with --model \
                     neo-hookean or svk, not the linear tissue"
                );
            }
            None
        }
        TissueModel::NeoHookean => Some(Law::NeoHookean),
        TissueModel::Svk => Some(Law::Svk),
    };
    let tissue_args = law.map(|l| tissue_args(args, l)).transpose()?;
    if let Some(t) = &tissue_args {
        palpa_core::fe::depth_grid_points(
            t.depth_max_mm,
            t.depth_step_mm,
            palpa_core::tissue::surface::MAX_GRID_POINTS,
        )
        .context("--depth-max-mm")?;
    }

    pr.start("surface", &args.surface.display().to_string());
    let axes = args.place.axes()?;
    let (fixed, palpable, regions_desc) = args.regions.selectors()?;
    let (solid, sr) = user::prepare(
        &args.surface,
        &SurfaceOptions {
            units: args.units,
            axes,
            close_holes_max_edges: args.regions.close_holes,
            largest_component: args.regions.largest_component,
            strict: args.regions.strict,
        },
    )
    .with_context(|| format!("preparing {}", args.surface.display()))?;
    for w in &sr.warnings {
        eprintln!("palpa: warning: {w}");
    }
    if let Some(w) = &sr.winding {
        eprintln!(
            "palpa: the surface is not a closed 2-manifold; its inside is read by its winding \
             number ({:.1} ml; --strict refuses it instead):",
            w.inside.volume_mm3 / 1000.0
        );
        for line in super::args::winding_lines(w) {
            eprintln!("palpa:   {line}");
        }
    }
    pr.done();

    pr.start("mesh", level.name());
    let organ = user::mesh(&solid, level, &fixed, &palpable)
        .with_context(|| format!("meshing {}", args.surface.display()))?;
    let q = quality(&organ.mesh);
    let meshed_mm3 = organ.mesh.volume();
    let volume_rel_diff = (meshed_mm3 - sr.enclosed_volume_mm3) / sr.enclosed_volume_mm3;
    if volume_rel_diff.abs() > 0.02 {
        eprintln!(
            "palpa: warning: the mesh's volume differs from the surface's by {:.1} % (a finer level follows the surface closer)",
            100.0 * volume_rel_diff
        );
    }
    let source = format!(
        "source={} source_xxh3={} units={} axes={} regions={}",
        sr.file_name.replace(char::is_whitespace, "_"),
        sr.source_xxh3,
        sr.units.name(),
        sr.axes,
        regions_desc
    );
    let desc = describe_user(
        &organ,
        level.name(),
        args.element,
        material,
        args.radius_mm,
        &source,
    );
    pr.done();

    let dir = build_dir(&args.out);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let vpath = dir.join("vademecum.palpa");
    let cached = file::load::<f64>(&vpath)
        .ok()
        .filter(|m| m.provenance().mesh == desc);
    let resumed_vademecum = cached.is_some();
    let resumed_tradeoff = cached.as_ref().is_some_and(|m| !m.tradeoff().is_empty());
    pr.start(
        "vademecum",
        if resumed_vademecum {
            "from the build folder"
        } else {
            "nodal loads"
        },
    );
    let mut model = match cached {
        Some(m) => m,
        None => {
            let s = nodal::setup(&organ, args.element, material, args.radius_mm)
                .context("building the FE operators and the load axis")?;
            let settings = NodalSettings {
                far: Some(FarSettings::for_tool(args.radius_mm)),
                ..NodalSettings::default()
            };
            let (mut m, _) = nodal::build(&s, &settings, &desc, |stage| {
                eprintln!(
                    "palpa:       {stage} ({:.1} s)",
                    pr.t0.elapsed().as_secs_f64()
                );
            })
            .context("computing the vademecum")?;
            let mut prov = m.provenance().clone();
            prov.input_hash = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(desc.as_bytes()));
            m.set_provenance(prov);
            file::save(&m, &vpath).with_context(|| format!("writing {}", vpath.display()))?;
            m
        }
    };
    pr.done();

    pr.start(
        "tradeoff",
        if resumed_tradeoff {
            "from the build folder"
        } else {
            "held-out presses against full FE"
        },
    );
    let mut tradeoff_json = serde_json::Value::Null;
    if !resumed_tradeoff {
        let t = nodal_table(
            &model,
            &organ,
            args.element,
            material,
            args.radius_mm,
            args.held_out,
        )
        .context("measuring the tradeoff table")?;
        model.set_tradeoff(t.header_rows());
        file::save(&model, &vpath).with_context(|| format!("writing {}", vpath.display()))?;
        tradeoff_json = json!({"fe_reference_s": t.fe_reference_s, "held_out": t.cases.len()});
    }
    let rows: Vec<_> = model
        .tradeoff()
        .iter()
        .map(|r| {
            json!({"modes": r.modes, "surface_rel_error": r.surface_rel_error,
                   "compliance_rel_error": r.compliance_rel_error,
                   "surface_max_nodal_error_mm": r.surface_max_nodal_error_mm,
                   "surface_eval_us": r.surface_eval_us, "contact_eval_ns": r.contact_eval_ns,
                   "bytes": r.bytes})
        })
        .collect();
    pr.done();

    pr.start(
        "scene",
        "surface rows, f32; near and far fields in sixteen bits",
    );
    let nodes = organ.surface_nodes();
    let scene = model
        .select_nodes(&nodes)
        .context("selecting the surface rows")?
        .convert::<f32>();
    file::save_q16(&scene, &args.out).with_context(|| format!("writing {}", args.out.display()))?;
    pr.done();
    std::fs::remove_dir_all(&dir).with_context(|| format!("removing {}", dir.display()))?;
    let tissue_out = args.out.with_extension("tissue");
    let mut tissue_json = serde_json::Value::Null;
    if let Some(t) = &tissue_args {
        pr.start("tissue", &format!("the {} recipe", t.recipe));
        let (_, summary) = super::tissue::build(t).context("building the tissue")?;
        tissue_json = summary;
        pr.done();
    } else if tissue_out.exists() {
        // A tissue left beside the scene from an earlier build may be of another mesh
        // (another level or other regions): the app would refuse it when opening the
        // scene.
        let fits = palpa_core::tissue::law::TissueLaw::load(&tissue_out)
            .and_then(|t| t.check_linear_model(&desc));
        if let Err(why) = fits {
            eprintln!(
                "palpa: warning: {} beside the scene does not fit it, and opening the scene \
                 will say so: {why}",
                tissue_out.display()
            );
        }
    }

    let (lo, hi) = sr.bbox_mm;
    let summary = json!({
        "out": args.out,
        "tissue_out": law.map(|_| &tissue_out),
        "source": {
            "file": sr.file_name, "xxh3": sr.source_xxh3, "format": sr.format,
            "units": sr.units.name(), "axes": sr.axes.to_string(), "mirrored": sr.mirrored,
            "vertices": sr.vertices, "triangles": sr.triangles, "welded": sr.welded,
            "polygons_split": sr.polygons_split,
            "holes_closed": sr.holes.closed, "hole_triangles_added": sr.holes.triangles_added,
            "holes_left_open_edges": sr.holes.left_open,
            "pieces_dropped_triangles": sr.pieces_dropped, "flipped": sr.flipped,
            "bbox_mm": {"min": lo, "max": hi},
            "enclosed_volume_ml": sr.enclosed_volume_mm3 / 1000.0,
            "inside_by": if sr.winding.is_some() { "winding number" } else { "closed manifold" },
            "repairs": sr.winding.as_ref().map(super::args::winding_lines),
            "warnings": sr.warnings,
        },
        "mesh": {
            "level": level.name(), "lattice_spacing_mm": organ.h_mm,
            "vertices": organ.mesh.vertices.len(), "tetrahedra": organ.mesh.tets.len(),
            "boundary_triangles": organ.boundary.len(),
            "volume_ml": meshed_mm3 / 1000.0, "volume_rel_diff": volume_rel_diff,
            "min_dihedral_deg": q.min_dihedral_deg, "max_dihedral_deg": q.max_dihedral_deg,
            "inverted": q.inverted,
        },
        "regions": {
            "description": regions_desc,
            "fixed_vertices": organ.fixed.iter().filter(|&&f| f).count(),
            "palpable_triangles": organ.palpable.iter().filter(|&&p| p).count(),
        },
        "modes": scene.modes(),
        "tradeoff": {"rows": rows, "measured": tradeoff_json},
        "tissue": tissue_json,
        "tissue_command": law.map(|l| tissue_command(args, l)),
        "resumed": {"vademecum": resumed_vademecum, "tradeoff": resumed_tradeoff},
        "bytes": std::fs::metadata(&args.out).map(|m| m.len()).ok(),
        "seconds": pr.times.iter().map(|(n, s)| (n.to_string(), json!(s))).collect::<serde_json::Map<_, _>>(),
        "total_s": pr.t0.elapsed().as_secs_f64(),
    });
    super::args::print_report(&summary, args.json)
}

/// The `palpa tissue build` that presses this scene's organ (what `--model` runs): the
/// same surface, placing, regions, level, element, model and recipe, its output beside
/// the scene.
fn tissue_command(args: &BuildArgs, law: Law) -> String {
    tissue_words(args, law)
        .iter()
        .map(|w| shell_word(w))
        .collect::<Vec<_>>()
        .join(" ")
}

/// [`tissue_command`]'s arguments, parsed as `palpa tissue build` parses them.
fn tissue_args(args: &BuildArgs, law: Law) -> anyhow::Result<super::tissue::BuildArgs> {
    #[derive(Debug, clap::Parser)]
    struct TissueBuild {
        #[command(flatten)]
        args: super::tissue::BuildArgs,
    }
    let words = tissue_words(args, law);
    <TissueBuild as clap::Parser>::try_parse_from(&words[2..])
        .map(|t| t.args)
        .map_err(|e| anyhow::anyhow!("the tissue's arguments: {e}"))
}

/// The words of [`tissue_command`].
fn tissue_words(args: &BuildArgs, law: Law) -> Vec<String> {
    let mut words: Vec<String> = ["palpa", "tissue", "build", "--surface"]
        .map(String::from)
        .to_vec();
    words.push(args.surface.display().to_string());
    words.extend(["--units".into(), args.units.name().into()]);
    let p = &args.place;
    if let Some(a) = &p.axes {
        words.extend(["--axes".into(), a.clone()]);
    }
    if let (Some(up), Some(anterior)) = (&p.up, &p.anterior) {
        words.extend([
            "--up".into(),
            up.clone(),
            "--anterior".into(),
            anterior.clone(),
        ]);
    }
    let r = &args.regions;
    for f in &r.fixed {
        words.extend(["--fixed".into(), f.clone()]);
    }
    for f in &r.palpable {
        words.extend(["--palpable".into(), f.clone()]);
    }
    if let Some(file) = &r.regions {
        words.extend(["--regions".into(), file.display().to_string()]);
    }
    if r.close_holes > 0 {
        words.extend(["--close-holes".into(), r.close_holes.to_string()]);
    }
    if r.largest_component {
        words.push("--largest-component".into());
    }
    if r.strict {
        words.push("--strict".into());
    }
    let level: Level = args.level.into();
    words.extend([
        "--level".into(),
        level.name().into(),
        "--element".into(),
        args.element.name().into(),
        "--model".into(),
        law.name().into(),
    ]);
    if let Some(d) = args.depth_max_mm {
        words.extend(["--depth-max-mm".into(), d.to_string()]);
    }
    if let Some(r) = &args.recipe {
        words.extend(["--recipe".into(), r.clone()]);
    }
    words.extend([
        "--out".into(),
        args.out.with_extension("tissue").display().to_string(),
    ]);
    words
}

/// `w` as one word for a POSIX shell: as it is where it holds only plain characters,
/// else in single quotes.
fn shell_word(w: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./,:=+@%".contains(c);
    if !w.is_empty() && w.chars().all(plain) {
        w.to_string()
    } else {
        format!("'{}'", w.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Scene {
        #[command(flatten)]
        args: BuildArgs,
    }

    #[derive(Debug, Parser)]
    struct Tissue {
        #[command(flatten)]
        args: super::super::tissue::BuildArgs,
    }

    /// Splits a command line as a POSIX shell would for the quoting `shell_word` uses.
    fn shell_split(line: &str) -> Vec<String> {
        let mut words = Vec::new();
        let (mut word, mut quoted, mut any) = (String::new(), false, false);
        let mut chars = line.chars();
        while let Some(c) = chars.next() {
            match c {
                '\'' => (quoted, any) = (!quoted, true),
                '\\' if !quoted => {
                    word.extend(chars.next());
                    any = true;
                }
                ' ' if !quoted => {
                    if any {
                        words.push(std::mem::take(&mut word));
                    }
                    any = false;
                }
                c => (word, any) = (word + &c.to_string(), true),
            }
        }
        if any {
            words.push(word);
        }
        words
    }

    #[test]
    fn the_tissue_command_meshes_the_scenes_organ() {
        let scene = Scene::parse_from([
            "scene",
            "--surface",
            "my organ.obj",
            "--units",
            "cm",
            "--up",
            "y",
            "--anterior",
            "-z",
            "--fixed",
            "normal:posterior:50 | ball:0,0,0:5",
            "--palpable",
            "!(half:0,0,0:left)",
            "--palpable",
            "it's",
            "--close-holes",
            "3",
            "--largest-component",
            "--level",
            "medium",
            "--element",
            "p1",
            "--model",
            "svk",
            "--recipe",
            "quick",
            "--out",
            "dir/kidney.palpa",
        ])
        .args;
        let line = tissue_command(&scene, Law::Svk);
        let words = shell_split(&line);
        assert_eq!(&words[..3], ["palpa", "tissue", "build"], "{line}");
        let tissue = Tissue::try_parse_from(
            std::iter::once("tissue".to_string()).chain(words[3..].iter().cloned()),
        )
        .unwrap_or_else(|e| panic!("{line}: {e}"))
        .args;
        let o = &tissue.organ;
        assert_eq!(o.surface.as_deref(), Some(Path::new("my organ.obj")));
        assert_eq!(o.units.map(Units::name), Some("cm"));
        assert_eq!(
            (o.place.up.as_deref(), o.place.anterior.as_deref()),
            (Some("y"), Some("-z"))
        );
        assert_eq!(o.regions.fixed, scene.regions.fixed);
        assert_eq!(o.regions.palpable, scene.regions.palpable);
        assert_eq!(o.regions.close_holes, 3);
        assert!(o.regions.largest_component);
        assert_eq!(Level::from(o.level), Level::Medium);
        assert_eq!(tissue.element, Element::P1);
        assert_eq!(tissue.model.law(), Law::Svk);
        assert_eq!(tissue.out, Path::new("dir/kidney.tissue"));
        assert_eq!(tissue.recipe, "quick");
        // What `scene build --model` runs is this command, parsed the same way.
        let run = tissue_args(&scene, Law::Svk).expect("parses");
        assert_eq!((run.out, run.recipe), (tissue.out, tissue.recipe));
    }
}
