//! Where scenes come from: the built-in default (the shipped liver vademecum, compiled
//! into the binary so the app opens anywhere, phones included) or a `.palpa` file,
//! whose kind says which room opens it: a palpation vademecum or a gene-network
//! (CME) meta-model.

use std::path::Path;

use anyhow::Context;
use palpa_core::pgd::nodule::table::EffectTable;
use palpa_core::scene::PalpationScene;
use palpa_core::tissue::bound::BoundTissue;
use palpa_core::tissue::law::TissueLaw;
use palpa_core::tissue::online::Tissue;

use crate::session::GoalDepths;

/// The shipped default scene, `assets/liver-coarse.palpa`.
pub const BUILT_IN_LIVER: &[u8] = include_bytes!("../../assets/liver-coarse.palpa");

/// Its hyperelastic tissue, `assets/liver-coarse.tissue` (neo-Hookean, every palpable
/// vertex and edge midpoint pressed to 15 mm, its 760 worst triangles split into four
/// in six stages and pressed more densely, and the 190 worst of their quarters split
/// again: docs/methods.md §2e).
pub const BUILT_IN_TISSUE: &[u8] = include_bytes!("../../assets/liver-coarse.tissue");

/// The built-in liver's nodule table (`palpa nodule build`, recorded in
/// assets/manifest.json).
pub const BUILT_IN_NODULES: &[u8] = include_bytes!("../../assets/liver-coarse.nodules");
const NODULES_NAME: &str = "assets/liver-coarse.nodules";

/// Where the built-in scene comes from (what its tissue is measured to be worth is
/// recorded in the tissue file and shown from there).
pub const BUILT_IN_SOURCE: &str =
    "built-in liver (assets/liver-coarse.palpa, neo-Hookean tissue assets/liver-coarse.tissue)";

/// A loaded scene and where it came from.
#[derive(Debug)]
pub struct LoadedScene {
    pub scene: PalpationScene,
    pub source: String,
    /// The tissue's nonlinear model: the vademecum `X.tissue` beside a scene `X.palpa`
    /// (from `palpa tissue build` or `palpa scene build --model`), if there is one;
    /// else the tissue is linear.
    pub law: Option<Tissue>,
    /// The depths to which `law` is measured within the goals (surface within
    /// 0.5 mm, force within 5 % of the full FE at held-out points), where known: the
    /// panel flags deeper presses.
    pub goals_to_mm: Option<GoalDepths>,
    /// The nodule table `X.nodules` beside the scene (`palpa nodule build`), if there
    /// is one: the scene then offers "find the nodule".
    pub nodules: Option<EffectTable>,
}

/// The nodule table beside a scene file, if any; one that is there but cannot be read
/// is an error.
pub fn sidecar_nodules(scene_path: &Path) -> anyhow::Result<Option<EffectTable>> {
    let path = scene_path.with_extension("nodules");
    if !path.exists() {
        return Ok(None);
    }
    EffectTable::load(&path)
        .with_context(|| format!("the nodule table beside {}", scene_path.display()))
        .map(Some)
}

impl LoadedScene {
    /// A session on this scene: its tissue, its goals and its training mode.
    pub fn session(
        self,
        haptic: Box<dyn crate::force::HapticDevice>,
    ) -> anyhow::Result<crate::session::Session> {
        let mut session = crate::session::Session::with_law(self.scene, self.law, haptic)
            .context("starting the force thread")?;
        session.goals_to_mm = self.goals_to_mm;
        let tissue = session.law.as_ref().map(|t| t.bound.law.payload_xxh3());
        session.training = self
            .nodules
            .map(|t| crate::session::training::Training::new(t, &session.scene, tissue))
            .transpose()?;
        Ok(session)
    }
}

/// The nonlinear tissue beside a scene file, if any; a file that is there but cannot
/// be read, or was built for another mesh, is an error (never silently linear).
pub fn sidecar_tissue(scene_path: &Path, scene: &PalpationScene) -> anyhow::Result<Option<Tissue>> {
    let path = scene_path.with_extension("tissue");
    if path.exists() {
        let law = TissueLaw::load(&path)
            .with_context(|| format!("the tissue beside {}", scene_path.display()))?;
        return bind(law, scene, &path.display().to_string()).map(Some);
    }
    Ok(None)
}

/// `law` bound to `scene` (the same mesh, element and material), named `name` in errors.
fn bind(law: TissueLaw, scene: &PalpationScene, name: &str) -> anyhow::Result<Tissue> {
    law.check_linear_model(&scene.model().provenance().mesh)
        .with_context(|| format!("binding {name} to its scene"))?;
    let bound = BoundTissue::bind(
        law,
        scene.vertices_mm(),
        scene.axis_vertices_mm(),
        scene.axis_triangles(),
    )
    .with_context(|| format!("binding {name} to its scene"))?;
    Ok(Tissue::new(bound))
}

/// `"liver"` (the built-in default) or a path to a palpation `.palpa` file.
pub fn load(spec: &str) -> anyhow::Result<LoadedScene> {
    if spec == "liver" {
        return built_in();
    }
    let path = Path::new(spec);
    if !path.exists() {
        anyhow::bail!(
            "cannot open the scene {spec}: no such file, nor a built-in scene (liver, toggle, \
             cascade, signaling-cascade-D)"
        );
    }
    if palpa_core::tissue::law::is_tissue_file(path) {
        anyhow::bail!(
            "cannot open the scene {spec}: a tissue vademecum, which travels beside its scene \
             (open the X.palpa it sits next to)"
        );
    }
    let model = palpa_core::file::load_any(path)
        .with_context(|| format!("cannot open the scene {spec}"))?;
    let scene =
        PalpationScene::new(model).with_context(|| format!("{spec} is not a palpation scene"))?;
    let law = sidecar_tissue(path, &scene)?;
    let goals_to_mm = law.as_ref().and_then(|t| GoalDepths::of(&t.bound.law));
    Ok(LoadedScene {
        scene,
        source: path.display().to_string(),
        law,
        goals_to_mm,
        nodules: sidecar_nodules(path)?,
    })
}

/// A scene of either kind, ready for its room.
#[derive(Debug)]
pub enum Opened {
    Palpation(Box<LoadedScene>),
    Network {
        room: Box<crate::network::NetworkRoom>,
        source: String,
    },
    /// A network given by its definition (a built-in name or a TOML file): its
    /// meta-model comes from the cache or is built first.
    NetworkSource {
        network: Box<palpa_core::cme::network::Network>,
        toml: Option<std::path::PathBuf>,
        source: String,
    },
}

/// The network `spec` names: a TOML or SBML file (`….toml`, `….xml`, `….sbml`) or a
/// built-in name (`toggle`,
/// `cascade`, `signaling-cascade-D`); `None` for anything else.
pub fn network_source(
    spec: &str,
) -> anyhow::Result<
    Option<(
        palpa_core::cme::network::Network,
        Option<std::path::PathBuf>,
    )>,
> {
    use palpa_core::cme::network::Network;
    if is_network_file(spec) {
        let text =
            std::fs::read_to_string(spec).with_context(|| format!("reading the network {spec}"))?;
        let network = Network::from_text(&text, spec)?;
        return Ok(Some((network, Some(Path::new(spec).to_path_buf()))));
    }
    Ok(Network::built_in(spec).ok().map(|n| (n, None)))
}

/// A network file by its name: TOML or SBML.
fn is_network_file(spec: &str) -> bool {
    [".toml", ".xml", ".sbml"].iter().any(|e| spec.ends_with(e))
}

/// Whether `spec` is a gene network: a meta-model file (by its header's kind), a
/// network TOML file or a built-in network's name.
pub fn is_network(spec: &str) -> bool {
    spec != "liver"
        && (is_network_file(spec)
            || palpa_core::cme::network::Network::built_in(spec).is_ok()
            || palpa_core::file::read_header(Path::new(spec))
                .is_ok_and(|h| h.meta.kind.starts_with("cme-")))
}

/// Opens `spec` in the room its kind needs.
pub fn open(spec: &str) -> anyhow::Result<Opened> {
    if let Some((network, toml)) = network_source(spec)? {
        return Ok(Opened::NetworkSource {
            network: Box::new(network),
            toml,
            source: spec.to_string(),
        });
    }
    if is_network(spec) {
        let path = Path::new(spec);
        return Ok(Opened::Network {
            room: Box::new(crate::network::open(path)?),
            source: path.display().to_string(),
        });
    }
    load(spec).map(|s| Opened::Palpation(Box::new(s)))
}

/// How [`open_or_default`]'s message ends: what the app shows instead.
pub const SHOWING_BUILT_IN: &str = "; showing the built-in liver instead";

/// Opens `spec`; on failure, the built-in scene and the message saying why (the app
/// opens anyway and shows it).
pub fn open_or_default(spec: &str) -> anyhow::Result<(Opened, Option<String>)> {
    match open(spec) {
        Ok(s) => Ok((s, None)),
        Err(e) => Ok((
            Opened::Palpation(Box::new(built_in()?)),
            Some(format!("{e:#}{SHOWING_BUILT_IN}")),
        )),
    }
}

pub fn built_in() -> anyhow::Result<LoadedScene> {
    let model = palpa_core::file::load_any_from_bytes(BUILT_IN_LIVER)
        .context("the built-in liver scene")?;
    let scene = PalpationScene::new(model).context("the built-in liver scene")?;
    let name = "assets/liver-coarse.tissue";
    let law = TissueLaw::from_bytes(BUILT_IN_TISSUE, Path::new(name))
        .with_context(|| format!("the built-in tissue ({name})"))?;
    let goals_to_mm = GoalDepths::of(&law);
    let law = bind(law, &scene, name)?;
    Ok(LoadedScene {
        scene,
        source: BUILT_IN_SOURCE.into(),
        law: Some(law),
        goals_to_mm,
        nodules: Some(
            EffectTable::from_bytes(BUILT_IN_NODULES, Path::new(NODULES_NAME))
                .with_context(|| format!("the built-in nodule table ({NODULES_NAME})"))?,
        ),
    })
}
