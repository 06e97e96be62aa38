//! How a command names a gene network and its rates: a built-in name or a TOML or SBML
//! file, and `--param NAME=VALUE`.

use std::path::Path;

use anyhow::{Context, bail};
use palpa_core::cme::Network;

/// A built-in name, or a network file: SBML or TOML, told apart by content.
pub fn load_network(model: &str) -> anyhow::Result<Network> {
    let path = Path::new(model);
    let is_file = [".toml", ".xml", ".sbml"]
        .iter()
        .any(|e| model.ends_with(e));
    if is_file || path.exists() {
        network_file(path)
    } else {
        Ok(Network::built_in(model)?)
    }
}

/// A network file, SBML or TOML by its content; a file named `.xml` or `.sbml` must be
/// SBML (a TOML parser's complaint about its first line would mislead).
pub fn network_file(path: &Path) -> anyhow::Result<Network> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {name}"))?;
    let sbml_name = [".xml", ".sbml"].iter().any(|e| name.ends_with(e));
    if sbml_name && !palpa_core::cme::sbml::looks_like_sbml(&text) {
        bail!("{name}: not an SBML document (expected XML whose root element is <sbml>)");
    }
    Ok(Network::from_text(&text, &name)?)
}

pub fn parse_params(list: &[String]) -> anyhow::Result<Vec<(String, f64)>> {
    list.iter()
        .map(|s| {
            let (k, v) = s
                .split_once('=')
                .with_context(|| format!("--param {s:?}: expected NAME=VALUE"))?;
            let v: f64 = v
                .trim()
                .parse()
                .with_context(|| format!("--param {s:?}: {v:?} is not a number"))?;
            Ok((k.trim().to_string(), v))
        })
        .collect()
}
