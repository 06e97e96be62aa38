//! Which palpa file a path holds, read from its first bytes, and which commands read
//! it. A file of one kind handed to another kind's command fails in `core` with the
//! magic bytes it expected; the command line adds what the file is instead, so the
//! user learns which command to run rather than which bytes were missing.

use std::io::Read;
use std::path::Path;

use palpa_core::cme::model::CmeLoadError;
use palpa_core::file::FileError;
use palpa_core::tissue::law::TissueError;

/// What a file starting with `head` is, and which commands read it; `None` for bytes
/// no palpa command writes.
pub fn describe(head: &[u8]) -> Option<&'static str> {
    let kinds: [(&[u8], &str); 8] = [
        (
            &palpa_core::file::MAGIC,
            "a palpa meta-model (a scene or a gene network): `palpa info` says which; \
             `palpa eval`, `palpa tradeoff` and `palpa open --scene` read scenes, \
             `palpa cme eval` networks",
        ),
        (
            palpa_core::tissue::law::MAGIC,
            "a tissue vademecum, which travels beside its scene: `palpa eval`, `palpa info` \
             and `palpa tissue check|refine|cut` read it",
        ),
        (
            palpa_core::pgd::nodule::table::MAGIC,
            "a nodule table, which travels beside its scene: `palpa eval --nodule-at`, \
             `palpa headless --nodule-*`, `palpa nodule check` and `palpa info` read it",
        ),
        (
            b"PALPALAW",
            "a force law of an earlier palpa, which no longer reads it: the tissue that \
             replaced it is made by `palpa scene build --model` or `palpa tissue build`",
        ),
        (
            palpa_core::pgd::journal::MAGIC,
            "the journal of an interrupted off-line build: run the same `palpa offline` \
             command again to resume it",
        ),
        (
            b"ply",
            "a surface mesh: `palpa mesh --surface` and `palpa scene build --surface` read it",
        ),
        (
            b"solid",
            "a surface mesh (STL): `palpa mesh --surface` and `palpa scene build --surface` \
             read it",
        ),
        (
            b"<?xml",
            "an XML file: `palpa cme` reads SBML models given as networks",
        ),
    ];
    kinds
        .iter()
        .find(|(magic, _)| head.starts_with(magic))
        .map(|&(_, what)| what)
}

/// The first bytes of `path` (at most 8), empty if it cannot be read.
pub fn head(path: &Path) -> Vec<u8> {
    let mut buf = Vec::with_capacity(8);
    if let Ok(f) = std::fs::File::open(path) {
        let _ = f.take(8).read_to_end(&mut buf);
    }
    buf
}

/// For an error caused by a file of the wrong kind, what that file is and which
/// commands read it.
pub fn hint(e: &anyhow::Error) -> Option<String> {
    let path = e.chain().find_map(|cause| {
        // A transparent wrapper hides its inner error from the chain.
        let file = match cause.downcast_ref::<CmeLoadError>() {
            Some(CmeLoadError::File(f)) => Some(f),
            _ => cause.downcast_ref::<FileError>(),
        };
        if let Some(FileError::Foreign { path, .. }) = file {
            return Some(path.clone());
        }
        if let Some(TissueError::Foreign { path }) = cause.downcast_ref::<TissueError>() {
            return Some(path.clone());
        }
        None
    })?;
    let what = describe(&head(&path)).or_else(|| by_extension(&path))?;
    Some(format!("{} is {what}", path.display()))
}

/// What a file whose first bytes say nothing is, by its name's extension: text formats
/// palpa reads that have no magic of their own (a TOML network, OBJ or binary STL
/// surfaces, JSON paths).
pub fn by_extension(path: &Path) -> Option<&'static str> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "toml" => Some(
            "a TOML file: `palpa cme solve|offline|convert` and `palpa open --scene` read \
                 gene networks written in it",
        ),
        "obj" | "stl" => {
            Some("a surface mesh: `palpa mesh --surface` and `palpa scene build --surface` read it")
        }
        "json" => Some(
            "a JSON file: `palpa headless --probe-path` and `--coordinate-path` read scripted \
             paths written in it",
        ),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_palpa_writes_is_named() {
        assert!(describe(&palpa_core::file::MAGIC).is_some_and(|d| d.contains("meta-model")));
        assert!(describe(b"PALPATIS\x0c\0\0\0").is_some_and(|d| d.contains("tissue")));
        assert!(describe(b"PALPALAW").is_some_and(|d| d.contains("tissue build")));
        assert!(describe(b"<?xml ve").is_some_and(|d| d.contains("SBML")));
        assert!(describe(b"ply\nform").is_some_and(|d| d.contains("surface")));
        assert_eq!(describe(b"PALPAXYZ"), None);
        assert_eq!(describe(b""), None);
        assert!(by_extension(Path::new("net.TOML")).is_some_and(|d| d.contains("cme solve")));
        assert!(by_extension(Path::new("liver.stl")).is_some_and(|d| d.contains("surface")));
        assert_eq!(by_extension(Path::new("notes.txt")), None);
    }
}
