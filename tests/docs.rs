//! The documents name real things: every path in `docs/architecture.md` exists, and every scene
//! in `scenes/` and every JSON example in `docs/scene-format.md` is a valid scene.

use std::path::Path;

#[test]
fn architecture_names_existing_paths() {
    let text = std::fs::read_to_string("docs/architecture.md").unwrap();
    let mut checked = 0;
    for part in text.split('`') {
        let candidates: Vec<&str> = part.split([' ', ',']).collect();
        for c in candidates {
            if c.starts_with("src/") {
                assert!(
                    Path::new(c).exists(),
                    "docs/architecture.md names {c}, which does not exist"
                );
                checked += 1;
            }
        }
    }
    assert!(
        checked >= 8,
        "expected the architecture to name the source paths"
    );
}

/// The other direction: every module of `src/` (a folder or a file) is named as a path, and every
/// file inside a module's folder by its name, so the page cannot fall behind the code.
#[test]
fn architecture_names_every_module_and_file() {
    let text = std::fs::read_to_string("docs/architecture.md").unwrap();
    let mut missing = Vec::new();
    for entry in std::fs::read_dir("src").unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name == "lib.rs" || name == "main.rs" {
            continue;
        }
        if path.is_dir() {
            if !text.contains(&format!("`src/{name}/`")) {
                missing.push(format!("src/{name}/"));
            }
            for file in std::fs::read_dir(&path).unwrap() {
                let file = file.unwrap().path();
                let stem = file.file_name().unwrap().to_string_lossy().into_owned();
                if stem == "mod.rs" {
                    continue;
                }
                let named = if file.is_dir() {
                    format!("`{stem}/`")
                } else {
                    format!("`{stem}`")
                };
                if !text.contains(&named) && !text.contains(&format!("src/{name}/{stem}")) {
                    missing.push(format!("src/{name}/{stem}"));
                }
            }
        } else if !text.contains(&format!("src/{name}")) {
            missing.push(format!("src/{name}"));
        }
    }
    assert!(
        missing.is_empty(),
        "docs/architecture.md does not name {missing:?}"
    );
}

#[test]
fn scenes_and_documented_examples_are_valid() {
    for entry in std::fs::read_dir("scenes").unwrap() {
        let path = entry.unwrap().path();
        drape::scene::Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
    let doc = std::fs::read_to_string("docs/scene-format.md").unwrap();
    let examples: Vec<&str> = doc
        .split("```json")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
        .collect();
    assert!(examples.len() >= 2);
    for e in examples {
        drape::scene::Scene::parse(e, "docs/scene-format.md")
            .unwrap_or_else(|err| panic!("{err}\n{e}"));
    }
    let readme = std::fs::read_to_string("README.md").unwrap();
    for e in readme
        .split("```json")
        .skip(1)
        .map(|b| b.split("```").next().unwrap())
    {
        drape::scene::Scene::parse(e, "README.md").unwrap_or_else(|err| panic!("{err}\n{e}"));
    }
}
