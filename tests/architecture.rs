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
    ("visual", 2),
    ("organ", 2),
    ("separated", 3),
    ("fe", 3),
    ("synthetic", 3),
    ("file", 4),
    ("export", 4),
    ("scene", 5),
    ("cme", 5),
    ("pgd", 5),
    ("tissue", 6),
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

/// A module's path inside its crate (`fe::newton` for `core/src/fe/newton.rs`, `fe` for
/// `core/src/fe/mod.rs` or `core/src/fe.rs`), `[]` for the crate root.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file
        .strip_prefix(src)
        .expect("inside src")
        .with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The code of a source file without comments and without its unit tests (an inline
/// `#[cfg(test)] mod tests` and what follows it).
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every path a `use` tree names, as segments: `a::{b, c::d}` gives `a::b` and `a::c::d`.
fn expand_use(tree: &str) -> Vec<Vec<String>> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        let path = tree.split(" as ").next().unwrap_or("").trim();
        return match path.is_empty() {
            true => Vec::new(),
            false => vec![path.split("::").map(|s| s.trim().to_string()).collect()],
        };
    };
    let close = tree.rfind('}').filter(|&c| c > open).unwrap_or(tree.len());
    let prefix: Vec<String> = tree[..open]
        .trim_end_matches(':')
        .split("::")
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    let (mut items, mut depth, mut current) = (Vec::new(), 0, String::new());
    for ch in tree[open + 1..close].chars() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(std::mem::take(&mut current));
                continue;
            }
            _ => {}
        }
        current.push(ch);
    }
    items.push(current);
    items
        .iter()
        .flat_map(|item| expand_use(item))
        .map(|tail| prefix.iter().cloned().chain(tail).collect())
        .collect()
}

/// The modules of the crate in `src` that `code` (module `at`) names through `crate::`,
/// `super::` or `self::` paths, its own ancestors left out (a child may name its parent).
fn module_imports(
    code: &str,
    at: &[String],
    modules: &BTreeMap<Vec<String>, PathBuf>,
) -> Vec<Vec<String>> {
    let mut paths: Vec<Vec<String>> = Vec::new();
    // `use` items: a line that starts one (after its visibility), to the `;`.
    let mut offset = 0;
    for line in code.split_inclusive('\n') {
        let trimmed = line.trim_start();
        let item = trimmed
            .strip_prefix("pub ")
            .or_else(|| trimmed.strip_prefix("pub(crate) "))
            .or_else(|| trimmed.strip_prefix("pub(super) "))
            .unwrap_or(trimmed);
        if let Some(tree) = item.strip_prefix("use ") {
            let start = offset + (line.len() - tree.len());
            let end = code[start..].find(';').map_or(code.len(), |e| start + e);
            let tree: String = code[start..end]
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ");
            paths.extend(expand_use(&tree));
        }
        offset += line.len();
    }
    for head in ["crate::", "super::", "self::"] {
        let mut rest = code;
        while let Some(i) = rest.find(head) {
            let before = rest[..i].chars().next_back();
            let tail = &rest[i..];
            let len = tail
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(tail.len());
            if !before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
                paths.push(tail[..len].split("::").map(str::to_string).collect());
            }
            rest = &tail[head.len()..];
        }
    }
    let mut out = Vec::new();
    for path in paths {
        let path: Vec<&str> = path
            .iter()
            .map(|s| s.trim())
            .filter(|s| !s.is_empty())
            .collect();
        let Some((&first, mut tail)) = path.split_first() else {
            continue;
        };
        let mut base: Vec<String> = match first {
            "crate" => Vec::new(),
            "self" => at.to_vec(),
            "super" => at[..at.len().saturating_sub(1)].to_vec(),
            _ => continue,
        };
        while let Some((&"super", t)) = tail.split_first() {
            base.pop();
            tail = t;
        }
        for k in (1..=tail.len()).rev() {
            let mut target = base.clone();
            target.extend(tail[..k].iter().map(|s| s.to_string()));
            if modules.contains_key(&target) {
                if target.as_slice() != at && !at.starts_with(&target) {
                    out.push(target);
                }
                break;
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

/// The import loops between the files of the crate whose sources are in `src`: each
/// strongly connected set of two or more modules, by Tarjan's algorithm.
fn import_loops(src: &Path) -> Vec<Vec<String>> {
    let mut files = Vec::new();
    sources(src, &mut files);
    let modules: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .map(|f| (module_path(src, f), f.clone()))
        .filter(|(m, _)| m.last().is_none_or(|last| last != "tests"))
        .collect();
    let names: Vec<&Vec<String>> = modules.keys().collect();
    let index_of: BTreeMap<&Vec<String>, usize> =
        names.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let edges: Vec<Vec<usize>> = names
        .iter()
        .map(|m| {
            let code = code_of(&std::fs::read_to_string(&modules[*m]).expect("source"));
            module_imports(&code, m, &modules)
                .iter()
                .map(|t| index_of[t])
                .collect()
        })
        .collect();
    struct Tarjan<'a> {
        edges: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        stack: Vec<usize>,
        on_stack: Vec<bool>,
        next: usize,
        loops: Vec<Vec<usize>>,
    }
    impl Tarjan<'_> {
        fn visit(&mut self, v: usize) {
            self.index[v] = Some(self.next);
            self.low[v] = self.next;
            self.next += 1;
            self.stack.push(v);
            self.on_stack[v] = true;
            for &w in &self.edges[v] {
                match self.index[w] {
                    None => {
                        self.visit(w);
                        self.low[v] = self.low[v].min(self.low[w]);
                    }
                    Some(iw) if self.on_stack[w] => self.low[v] = self.low[v].min(iw),
                    Some(_) => {}
                }
            }
            if Some(self.low[v]) == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack[w] = false;
                    component.push(w);
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    self.loops.push(component);
                }
            }
        }
    }
    let n = names.len();
    let mut t = Tarjan {
        edges: &edges,
        index: vec![None; n],
        low: vec![0; n],
        stack: Vec::new(),
        on_stack: vec![false; n],
        next: 0,
        loops: Vec::new(),
    };
    for v in 0..n {
        if t.index[v].is_none() {
            t.visit(v);
        }
    }
    t.loops
        .iter()
        .map(|c| {
            let mut names: Vec<String> = c.iter().map(|&i| names[i].join("::")).collect();
            names.sort();
            names
        })
        .collect()
}

/// No two files of either crate import each other, directly or around a loop: a
/// reader can take each folder's files in an order where each uses only those before.
#[test]
fn no_import_loops_between_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut found = Vec::new();
    for krate in ["core/src", "app/src"] {
        for l in import_loops(&root.join(krate)) {
            found.push(format!("{krate}: {}", l.join(" ↔ ")));
        }
    }
    assert!(found.is_empty(), "import loops:\n{}", found.join("\n"));
}

/// The floors inside core's two largest folders, as ARCHITECTURE.md draws them: each
/// file (or sub-folder) names only files of its own floor or below. `fe`: assembly below
/// the nonlinear solver, below the press; `tissue`: a press below the stages, below the
/// file, below what the app evaluates on-line.
const FOLDER_FLOORS: &[(&str, &[&[&str]])] = &[
    (
        "fe",
        &[
            &["shape", "m3", "ordering"],
            &["space", "m3v"],
            &["sparse", "law", "load", "nodule"],
            &["elasticity", "hyper", "lanes"],
            &["newton"],
            &["series"],
            &["path", "probe"],
        ],
    ),
    (
        "tissue",
        &[
            &[
                "options", "presslog", "shapes", "weights", "accuracy", "subsplit",
            ],
            &["press", "predict"],
            &["presser"],
            &["refine"],
            &["surface"],
            &["band", "refine_plan", "law"],
            &["bound", "band_file", "refine_file", "recipe"],
            &["surplus", "knobs", "subsplit_file", "online"],
        ],
    ),
];

#[test]
fn files_inside_core_folders_import_only_their_floor_or_below() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../core/src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let modules: BTreeMap<Vec<String>, PathBuf> = files
        .iter()
        .map(|f| (module_path(&src, f), f.clone()))
        .collect();
    let mut bad = Vec::new();
    for (folder, floors) in FOLDER_FLOORS {
        let floor_of = |name: &str| floors.iter().position(|f| f.contains(&name));
        for (m, file) in &modules {
            if m.len() < 2 || m[0] != *folder || m.last().is_some_and(|l| l == "tests") {
                continue;
            }
            let Some(floor) = floor_of(&m[1]) else {
                panic!("`{}` has no floor in FOLDER_FLOORS", m.join("::"));
            };
            let code = code_of(&std::fs::read_to_string(file).expect("source"));
            for target in module_imports(&code, m, &modules) {
                if target.len() < 2 || target[0] != *folder || target[1] == m[1] {
                    continue;
                }
                let to = floor_of(&target[1]).unwrap_or(usize::MAX);
                if to > floor {
                    bad.push(format!(
                        "{} (floor {floor}) imports {} (floor {to})",
                        m.join("::"),
                        target.join("::")
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
}

/// The loop finder finds a loop: two files naming each other, one through a `use`
/// tree over several lines and one through an inline path.
#[test]
fn the_loop_finder_finds_a_planted_loop() {
    let dir = tempfile::tempdir().expect("temp dir");
    let src = dir.path();
    std::fs::create_dir_all(src.join("a")).expect("dir");
    std::fs::write(src.join("lib.rs"), "pub mod a;\npub mod b;\n").expect("write");
    std::fs::write(src.join("a/mod.rs"), "pub mod x;\npub mod y;\n").expect("write");
    std::fs::write(
        src.join("a/x.rs"),
        "use super::{\n    y::Y,\n    z,\n};\n// use crate::b;\npub struct X;\n",
    )
    .expect("write");
    std::fs::write(
        src.join("a/y.rs"),
        "pub struct Y;\nfn f() { let _ = super::x::X; }\n",
    )
    .expect("write");
    std::fs::write(src.join("b.rs"), "use crate::a::x::X;\n").expect("write");
    assert_eq!(
        import_loops(src),
        vec![vec!["a::x".to_string(), "a::y".to_string()]]
    );
    std::fs::write(
        src.join("a/y.rs"),
        "pub struct Y;\n#[cfg(test)]\nmod tests { use super::super::x::X; }\n",
    )
    .expect("write");
    assert!(import_loops(src).is_empty(), "a unit test may use anything");
}
