//! Where scenes come from: the built-in default (the shipped liver vademecum, compiled
//! into the binary so the app opens anywhere, phones included) or a `.palpa` file.

use std::path::Path;

use anyhow::Context;
use palpa_core::scene::PalpationScene;

/// The shipped default scene, `assets/liver-coarse.palpa`.
pub const BUILT_IN_LIVER: &[u8] = include_bytes!("../../assets/liver-coarse.palpa");

/// A loaded scene and where it came from.
#[derive(Debug)]
pub struct LoadedScene {
    pub scene: PalpationScene,
    pub source: String,
}

/// `"liver"` (the built-in default) or a path to a palpation `.palpa` file.
pub fn load(spec: &str) -> anyhow::Result<LoadedScene> {
    if spec == "liver" {
        return built_in();
    }
    let path = Path::new(spec);
    let model = palpa_core::file::load_any(path)
        .with_context(|| format!("cannot open the scene {spec}"))?;
    let scene =
        PalpationScene::new(model).with_context(|| format!("{spec} is not a palpation scene"))?;
    Ok(LoadedScene {
        scene,
        source: path.display().to_string(),
    })
}

pub fn built_in() -> anyhow::Result<LoadedScene> {
    let model = palpa_core::file::load_any_from_bytes(BUILT_IN_LIVER)
        .context("the built-in liver scene")?;
    Ok(LoadedScene {
        scene: PalpationScene::new(model).context("the built-in liver scene")?,
        source: "built-in liver (assets/liver-coarse.palpa)".into(),
    })
}

/// Loads `spec`; on failure, the built-in scene and the message saying why (the app
/// opens anyway and shows it).
pub fn load_or_default(spec: &str) -> anyhow::Result<(LoadedScene, Option<String>)> {
    match load(spec) {
        Ok(s) => Ok((s, None)),
        Err(e) => Ok((
            built_in()?,
            Some(format!("{e:#}; showing the built-in liver instead")),
        )),
    }
}
