//! Small argument helpers shared by the commands.

use anyhow::bail;

/// Three finite numbers from a comma-separated argument (`--at`, `--dir`).
pub fn to3(v: &[f64], what: &str) -> anyhow::Result<[f64; 3]> {
    match v {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => bail!("{what} needs three finite comma-separated numbers, got {v:?}"),
    }
}
