//! The library's module graph has no cycles: every `crate::X` path in a top-level module's
//! files (comments left out) is an edge to module X, and no module reaches itself through
//! them. A stage may use the stages below it (the scene, then meshes, then characters and garments, then
//! collisions and the simulation, then exports, the report and the bake), never one above.
//! The binary's `cli` talks to the library as `drape::…` and is not part of the graph.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The top-level module `X` of every `crate::X` and `crate::{X, …}` path in `text`.
fn targets(text: &str) -> BTreeSet<String> {
    let code: String = text
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = group.split('}').next().unwrap_or("");
            for item in inner.split(',') {
                let name = ident(item.trim());
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        } else {
            let name = ident(rest);
            if !name.is_empty() {
                out.insert(name);
            }
        }
    }
    out
}

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Top-level module → the modules it uses, with a file that does.
fn graph() -> BTreeMap<String, BTreeMap<String, String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    let mut graph: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for path in all {
        let rel = path.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if ["main", "lib", "cli"].contains(&module.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let edges = graph.entry(module.clone()).or_default();
        for t in targets(&text) {
            if t != module {
                edges.entry(t).or_insert_with(|| rel.display().to_string());
            }
        }
    }
    graph
}

/// A cycle through `from`, as the modules along it, if there is one.
fn cycle_from(
    graph: &BTreeMap<String, BTreeMap<String, String>>,
    from: &str,
) -> Option<Vec<String>> {
    // Depth-first from `from`, looking for a way back to it.
    let mut stack = vec![(from.to_string(), vec![from.to_string()])];
    let mut seen = BTreeSet::new();
    while let Some((at, path)) = stack.pop() {
        for next in graph.get(&at).map(|e| e.keys()).into_iter().flatten() {
            if next == from {
                let mut c = path.clone();
                c.push(from.to_string());
                return Some(c);
            }
            if seen.insert(next.clone()) {
                let mut p = path.clone();
                p.push(next.clone());
                stack.push((next.clone(), p));
            }
        }
    }
    None
}

#[test]
fn the_path_finder_sees_grouped_paths_and_skips_comments() {
    let t = targets("use crate::{error::Error, scene::Scene};\n// crate::bake\nlet x = crate::sim::metrics::f();");
    assert_eq!(t.into_iter().collect::<Vec<_>>(), ["error", "scene", "sim"]);
    let mut g: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    g.entry("a".into())
        .or_default()
        .insert("b".into(), "a.rs".into());
    g.entry("b".into())
        .or_default()
        .insert("a".into(), "b.rs".into());
    assert_eq!(cycle_from(&g, "a").unwrap(), ["a", "b", "a"]);
}

#[test]
fn no_module_reaches_itself() {
    let graph = graph();
    assert!(graph.len() > 10, "{:?}", graph.keys());
    for module in graph.keys() {
        if let Some(cycle) = cycle_from(&graph, module) {
            let steps: Vec<String> = cycle
                .windows(2)
                .map(|w| format!("{} → {} ({})", w[0], w[1], graph[&w[0]][&w[1]]))
                .collect();
            panic!("a cycle between modules: {}", steps.join(", "));
        }
    }
}

#[test]
fn meshes_are_read_below_characters_and_garments() {
    // The mesh readers, the animated mesh and vertex normals serve characters, garments and
    // exports alike: they use only the scene's types and errors, and garments read their
    // meshes through them, not through characters.
    let graph = graph();
    let mesh: Vec<&String> = graph["mesh"].keys().collect();
    assert_eq!(mesh, ["error", "scene"], "{:?}", graph["mesh"]);
    assert!(graph["garment"].contains_key("mesh"));
    assert!(
        !graph["garment"].contains_key("character"),
        "{:?}",
        graph["garment"]
    );
}
