//! The workspace's layout rules (issue 16): no two modules of a crate import
//! each other, directly or round a longer loop, and the CLI stays thin.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// `a/b/mod.rs` and `a/b.rs` are module `a::b`.
fn module_name(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts.join("::")
}

/// The crate's modules each module uses (`crate::x`, `crate::x::y`,
/// `super::x`), outside comments and test modules.
fn imports(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeMap<String, PathBuf> = files
        .iter()
        .map(|f| (module_name(src, f), f.clone()))
        .collect();
    let mut graph = BTreeMap::new();
    for (name, file) in &modules {
        let text = std::fs::read_to_string(file).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        let parent = name.rsplit_once("::").map_or("", |(p, _)| p);
        let mut deps = BTreeSet::new();
        for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
            for (prefix, base) in [("crate::", ""), ("super::", parent)] {
                for (at, _) in line.match_indices(prefix) {
                    let path: Vec<&str> = line[at + prefix.len()..]
                        .split("::")
                        .map(|s| {
                            s.split(|c: char| {
                                !(c.is_ascii_lowercase() || c == '_' || c.is_ascii_digit())
                            })
                            .next()
                            .unwrap_or("")
                        })
                        .take(2)
                        .collect();
                    let join = |k: usize| {
                        let p = path[..k].join("::");
                        if base.is_empty() {
                            p
                        } else {
                            format!("{base}::{p}")
                        }
                    };
                    let found = [2, 1]
                        .into_iter()
                        .filter(|&k| k <= path.len() && path[..k].iter().all(|s| !s.is_empty()))
                        .map(join)
                        .find(|m| modules.contains_key(m));
                    if let Some(m) = found.filter(|m| m != name) {
                        deps.insert(m);
                    }
                }
            }
        }
        graph.insert(name.clone(), deps);
    }
    graph
}

/// A loop of imports, if any (depth-first search).
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        v: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == v) {
            let mut cycle = path[i..].to_vec();
            cycle.push(v.to_string());
            return Some(cycle);
        }
        if done.contains(v) {
            return None;
        }
        path.push(v.to_string());
        for w in graph.get(v).into_iter().flatten() {
            if let Some(c) = visit(w, graph, done, path) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(v.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|v| visit(v, graph, &mut done, &mut Vec::new()))
}

#[test]
fn no_module_of_a_crate_imports_one_that_imports_it_back() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut crates = 0;
    for entry in std::fs::read_dir(root.join("crates")).unwrap() {
        let src = entry.unwrap().path().join("src");
        if !src.is_dir() {
            continue;
        }
        crates += 1;
        if let Some(cycle) = find_cycle(&imports(&src)) {
            panic!(
                "{}: modules import each other: {}",
                src.display(),
                cycle.join(" -> ")
            );
        }
    }
    assert!(crates >= 8, "found {crates} crates");
}

#[test]
fn the_cycle_finder_finds_a_planted_cycle() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("m")).unwrap();
    std::fs::write(src.join("lib.rs"), "mod a;\nmod m;\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::m::b::Thing;\n").unwrap();
    std::fs::write(src.join("m/mod.rs"), "pub mod b;\n").unwrap();
    std::fs::write(
        src.join("m/b.rs"),
        "// crate::a in a comment does not count\npub struct Thing;\n",
    )
    .unwrap();
    let graph = imports(src);
    assert_eq!(find_cycle(&graph), None, "{graph:?}");
    std::fs::write(src.join("m/b.rs"), "use crate::a::g;\n").unwrap();
    let cycle = find_cycle(&imports(src)).expect("a -> m::b -> a");
    assert!(cycle.contains(&"a".to_string()) && cycle.contains(&"m::b".to_string()));
}

#[test]
fn the_cli_stays_thin() {
    let mut files = Vec::new();
    rust_files(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/red-cli/src"),
        &mut files,
    );
    let lines: usize = files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap().lines().count())
        .sum();
    assert!(
        lines <= 1_500,
        "red-cli/src has {lines} lines (at most 1,500: the experiments belong in red-experiments)"
    );
}
