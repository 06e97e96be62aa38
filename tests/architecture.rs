//! The floors of `palpa-core` drawn in ARCHITECTURE.md are true: every `crate::m`
//! path in a module's sources names a module on the same floor or below, and the
//! floor-5 pipelines never import each other.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const FLOORS: &[(&str, u32)] = &[
    ("scalar", 0),
    ("rng", 0),
    ("fsutil", 0),
    ("mesh", 0),
    ("timing", 0),
    ("cpu", 0),
    ("tensor", 1),
    ("disk", 1),
    ("framed", 1),
    ("quant16", 1),
    ("axis", 1),
    ("surface_import", 1),
    ("farfield", 1),
    ("kernels", 2),
    ("nearfield", 2),
    ("organ", 2),
    ("separated", 3),
    ("fe", 3),
    ("synthetic", 3),
    ("file", 4),
    ("export", 4),
    ("scene", 5),
    ("cme", 5),
    ("pgd", 5),
];

fn sources(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for e in std::fs::read_dir(path).expect("readable source dir") {
            sources(&e.expect("dir entry").path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The `crate::name` paths in code (doc comments and line comments skipped).
fn imports(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            let tail = &rest[i + 7..];
            let name: String = tail
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.push(name);
            }
            rest = tail;
        }
    }
    out
}

#[test]
fn no_core_module_imports_from_a_higher_floor() {
    let floors: BTreeMap<&str, u32> = FLOORS.iter().copied().collect();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../core/src");
    let mut seen = Vec::new();
    let mut bad = Vec::new();
    for entry in std::fs::read_dir(&src).expect("core/src") {
        let path = entry.expect("entry").path();
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .expect("utf-8 name")
            .to_string();
        if name == "lib" {
            continue;
        }
        let Some(&floor) = floors.get(name.as_str()) else {
            panic!("core module `{name}` has no floor in ARCHITECTURE.md's table");
        };
        seen.push(name.clone());
        let mut files = Vec::new();
        sources(&path, &mut files);
        for f in files {
            let text = std::fs::read_to_string(&f).expect("source");
            for dep in imports(&text) {
                if dep == name {
                    continue;
                }
                let Some(&d) = floors.get(dep.as_str()) else {
                    continue;
                };
                if d > floor || (d == 5 && floor == 5) {
                    bad.push(format!(
                        "{} (floor {floor}) imports `{dep}` (floor {d})",
                        f.display()
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "imports against the floors:\n{}",
        bad.join("\n")
    );
    assert_eq!(seen.len(), FLOORS.len(), "a module in the table is gone");
}
