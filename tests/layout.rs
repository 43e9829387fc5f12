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

/// The paths written at the start of `text`: `a::b::C` gives one, a group
/// `a::{b::C, d::{E, F}}` one per leaf (`a::b::C`, `a::d::E`, `a::d::F`),
/// as lists of segments.
fn paths_at(text: &str) -> Vec<Vec<String>> {
    let ident = |t: &str| -> usize {
        t.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(t.len())
    };
    let mut prefix = Vec::new();
    let mut rest = text;
    loop {
        if rest.starts_with('{') {
            // A group: split its inside at top-level commas.
            let (mut depth, mut start, mut out) = (0, 1, Vec::new());
            for (i, c) in rest.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' | ',' if depth == 1 => {
                        for tail in paths_at(rest[start..i].trim_start()) {
                            let mut p = prefix.clone();
                            p.extend(tail);
                            out.push(p);
                        }
                        start = i + 1;
                        if c == '}' {
                            return out;
                        }
                    }
                    '}' => depth -= 1,
                    _ => {}
                }
            }
            return out;
        }
        let n = ident(rest);
        if n == 0 {
            break;
        }
        prefix.push(rest[..n].to_string());
        match rest[n..].strip_prefix("::") {
            Some(r) => rest = r,
            None => break,
        }
    }
    if prefix.is_empty() {
        Vec::new()
    } else {
        vec![prefix]
    }
}

/// The names the crate root re-exports (`pub use m::{A, B}` in lib.rs)
/// and the module each comes from.
fn root_exports(lib: &str, modules: &BTreeMap<String, PathBuf>) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for (at, _) in lib.match_indices("pub use ") {
        for path in paths_at(&lib[at + 8..]) {
            if path.len() >= 2 && modules.contains_key(&path[0]) {
                out.insert(path[path.len() - 1].clone(), path[0].clone());
            }
        }
    }
    out
}

/// The crate's modules each module uses: paths from `crate::`, `super::`
/// (any number), `self::`, and `use` of a child module by its bare name,
/// with groups expanded at any depth and names re-exported by the crate
/// root traced to their module; outside comment lines and test modules.
fn imports(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeMap<String, PathBuf> = files
        .iter()
        .map(|f| (module_name(src, f), f.clone()))
        .collect();
    let code_of = |file: &Path| -> String {
        let text = std::fs::read_to_string(file).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        let lines = code.lines().filter(|l| !l.trim_start().starts_with("//"));
        lines.collect::<Vec<_>>().join("\n")
    };
    let exports = ["lib", "main"]
        .iter()
        .filter_map(|r| modules.get(*r))
        .map(|f| root_exports(&code_of(f), &modules))
        .fold(BTreeMap::new(), |mut a, b| {
            a.extend(b);
            a
        });
    let mut graph = BTreeMap::new();
    for (name, file) in &modules {
        let code = code_of(file);
        let is_root = name == "lib" || name == "main";
        let own: Vec<&str> = if is_root {
            Vec::new()
        } else {
            name.split("::").collect()
        };
        let mut deps = BTreeSet::new();
        let word_start = |at: usize| {
            !code[..at].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == ':')
        };
        let mut starts: Vec<usize> = ["crate::", "super::", "self::"]
            .iter()
            .flat_map(|k| code.match_indices(k).map(|(at, _)| at))
            .filter(|&at| word_start(at))
            .collect();
        // `use child::X` in a module names its child module.
        starts.extend(code.match_indices("use ").map(|(at, _)| at + 4));
        for at in starts {
            let mut base = own.clone();
            let mut rest = &code[at..];
            let bare = !["crate::", "super::", "self::"]
                .iter()
                .any(|k| rest.starts_with(k));
            if let Some(r) = rest.strip_prefix("crate::") {
                base.clear();
                rest = r;
            } else if let Some(r) = rest.strip_prefix("self::") {
                rest = r;
            } else {
                while let Some(r) = rest.strip_prefix("super::") {
                    base.pop();
                    rest = r;
                }
            }
            for path in paths_at(rest) {
                let full: Vec<String> = base.iter().map(|s| s.to_string()).chain(path).collect();
                // The longest prefix that is one of the crate's modules
                // (the base itself for `super::x` and `self::x`, but not
                // the crate root: its names are traced below).
                let first = if base.is_empty() { 1 } else { base.len() };
                let found = (first..=full.len())
                    .rev()
                    .map(|k| full[..k].join("::"))
                    .find(|m| modules.contains_key(m))
                    .or_else(|| {
                        let first = full.get(base.len())?;
                        (!bare && base.is_empty()).then(|| exports.get(first).cloned())?
                    });
                if let Some(m) = found.filter(|m| m != name) {
                    deps.insert(m);
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
    std::fs::write(src.join("lib.rs"), "mod a;\nmod m;\npub use a::{G, f};\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::m::b::Thing;\n").unwrap();
    std::fs::write(src.join("m/mod.rs"), "pub mod b;\n").unwrap();
    std::fs::write(
        src.join("m/b.rs"),
        "// crate::a in a comment does not count\npub struct Thing;\n",
    )
    .unwrap();
    let graph = imports(src);
    assert_eq!(find_cycle(&graph), None, "{graph:?}");
    for back in [
        "use crate::a::g;\n",
        "use crate::{\n    Error,\n    a::{f, g},\n};\n",
        "fn h() { super::super::a::g() }\n",
        "use crate::{m::c::Z, a::{f, g}};\n",
        "use crate::G;\n",
    ] {
        std::fs::write(src.join("m/b.rs"), back).unwrap();
        let cycle = find_cycle(&imports(src)).unwrap_or_else(|| panic!("a -> m::b -> a: {back}"));
        assert!(cycle.contains(&"a".to_string()) && cycle.contains(&"m::b".to_string()));
    }
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
