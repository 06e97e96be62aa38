//! `palpa lab asset record`: what made each shipped file, written beside the files.
//!
//! `assets/manifest.json` lists every file the app ships or the tests read as an
//! example: its path under `assets/`, the xxh3-64 of its bytes, the xxh3-64 of what it
//! computes (a `.palpa` file's content: everything but its build date and measured
//! timings, so a rebuild can be compared with it), and the commands that made it,
//! in order, run from the repository's root. `scripts/make-assets.sh` and
//! `scripts/make-kidney.sh` record each file as they write it; a test checks every
//! hash against the files and rebuilds the kidney scene to its recorded content.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use serde::{Deserialize, Serialize};

/// The manifest's name inside the assets folder.
pub const MANIFEST: &str = "manifest.json";

/// Every recorded asset.
#[derive(Debug, Default, Serialize, Deserialize)]
pub struct Manifest {
    /// What the file is, for a reader who opens it.
    pub about: String,
    pub assets: Vec<Entry>,
}

/// One shipped file and what made it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Entry {
    /// Under `assets/`, with `/` separators.
    pub path: String,
    /// xxh3-64 of the file's bytes, 16 hex digits.
    pub file_xxh3: String,
    /// For a `.palpa` file, the xxh3-64 of its content
    /// ([`palpa_core::file::Header::content_xxh3`]).
    pub content_xxh3: Option<String>,
    /// The commands that made it, in order, run from the repository's root.
    pub commands: Vec<String>,
    /// Where the file was not made by exactly these commands, how it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

const ABOUT: &str = "What made each shipped file: written by `palpa lab asset record` \
(scripts/make-assets.sh, scripts/make-kidney.sh); the commands run from the repository's root.";

#[derive(Debug, Args)]
pub struct RecordArgs {
    /// The file just written, inside an `assets/` folder.
    file: PathBuf,
    /// A command that made it, as run from the repository's root (repeat, in order).
    #[arg(long = "command", required = true)]
    commands: Vec<String>,
    /// Where the file was not made by exactly these commands, how it was.
    #[arg(long)]
    note: Option<String>,
}

/// The xxh3-64 of a file's bytes, and of a `.palpa` file's content.
pub fn hashes(path: &Path) -> anyhow::Result<(String, Option<String>)> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes));
    let content = if bytes.starts_with(&palpa_core::file::MAGIC) {
        let h = palpa_core::file::read_header_from_bytes(&bytes)
            .with_context(|| path.display().to_string())?;
        Some(format!("{:016x}", h.content_xxh3()))
    } else {
        None
    };
    Ok((file, content))
}

pub fn record(args: &RecordArgs) -> anyhow::Result<()> {
    let file = std::path::absolute(&args.file)?;
    let Some(root) = file
        .ancestors()
        .find(|a| a.file_name() == Some("assets".as_ref()))
    else {
        bail!(
            "{}: expected a file inside an `assets/` folder (the manifest lives there)",
            args.file.display()
        );
    };
    let rel = file
        .strip_prefix(root)?
        .components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/");
    let (file_xxh3, content_xxh3) = hashes(&file)?;
    let path = root.join(MANIFEST);
    let mut manifest: Manifest = if path.exists() {
        let text = std::fs::read_to_string(&path)?;
        serde_json::from_str(&text).with_context(|| {
            format!(
                "{}: not a manifest (expected `about` and `assets` as `palpa lab asset record` writes them)",
                path.display()
            )
        })?
    } else {
        Manifest::default()
    };
    manifest.about = ABOUT.into();
    let entry = Entry {
        path: rel.clone(),
        file_xxh3,
        content_xxh3,
        commands: args.commands.clone(),
        note: args.note.clone(),
    };
    match manifest.assets.iter_mut().find(|e| e.path == rel) {
        Some(e) => *e = entry,
        None => manifest.assets.push(entry),
    }
    manifest.assets.sort_by(|a, b| a.path.cmp(&b.path));
    let text = serde_json::to_string_pretty(&manifest)? + "\n";
    palpa_core::fsutil::atomic_write(&path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))?;
    eprintln!("{}: {rel} recorded", path.display());
    Ok(())
}
