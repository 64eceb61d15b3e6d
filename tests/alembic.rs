//! Alembic caches read back by the official library (PyAlembic, `alembic3d` from PyPI, which
//! `.ci/deps` installs into target/alembic) through `tests/alembic_check.py`: every sample of
//! every mesh equals the OBJ frame of that number (positions, bounds, faces read clockwise,
//! UVs, normals), on one uniform time sampling from the shot's first frame: a sheet and a rope
//! (a linear curve), a garment that tears (its faces change from the
//! frame they tear), scene P with its characters; and a bake stopped and resumed writes the
//! same file, byte for byte.

mod common;

use serde_json::Value;
use std::path::{Path, PathBuf};

/// Reads `abc` with the official library and compares it with the OBJ frames in `obj`.
fn check(abc: &Path, obj: &Path) -> Value {
    let python = std::env::current_dir()
        .unwrap()
        .join("target/alembic/bin/python");
    assert!(
        python.is_file(),
        "{} is missing: run .ci/deps (it installs alembic3d from PyPI)",
        python.display()
    );
    let run = std::process::Command::new(python)
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/alembic_check.py"))
        .arg(abc)
        .arg(obj)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", common::stderr(&run));
    serde_json::from_slice(&run.stdout).unwrap()
}

/// Every sample of `mesh` equals its OBJ frame: positions and bounds within 1e-6 m, UVs and
/// normals within 1e-6, the same faces; `frames` samples from shot frame `first` at `fps`.
fn assert_matches_obj(found: &Value, mesh: &str, frames: u64, first: u32, fps: f64) {
    let m = &found["meshes"][mesh];
    assert_eq!(m["samples"], frames, "{mesh}: {m}");
    let start = m["first_time"].as_f64().unwrap();
    assert!(
        (start - f64::from(first) / fps).abs() < 1e-9,
        "{mesh}: starts at {start} s"
    );
    let last = m["last_time"].as_f64().unwrap();
    let expected = f64::from(first + frames as u32 - 1) / fps;
    assert!((last - expected).abs() < 1e-9, "{mesh}: ends at {last} s");
    for key in ["position_worst", "bounds_worst", "uv_worst", "normal_worst"] {
        let worst = m[key].as_f64().unwrap();
        assert!(worst <= 1e-6, "{mesh}: {key} {worst}");
    }
    assert_eq!(m["faces_differ"], 0, "{mesh}: faces differ from the OBJ's");
}

#[test]
fn a_sheets_cache_holds_every_frame_from_the_shots_first() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(
        d,
        "scene.json",
        r#"{ "name": "cache", "frames": 6, "frame_start": 1001, "fps": 24, "substeps": 10,
             "backend": "cpu", "output": { "gltf": "none", "alembic": true },
             "garments": [
               { "name": "sheet", "resolution": [12, 10], "size": [1, 0.8], "pins": [[0, 0], [-1, 0]] },
               { "name": "rope", "kind": "rope", "resolution": [9], "size": [0.8],
                 "position": [0, 1.5, 0.5], "pins": [[0]] }] }"#,
    );
    let report = common::bake_report(d);
    assert_eq!(report["outputs"]["alembic"], "cache.abc");
    let found = check(&d.join("out/cache.abc"), &d.join("out/obj"));
    assert_eq!(found["meshes"].as_object().unwrap().len(), 1, "{found}");
    // The rope: one linear, open curve through its 9 vertices, every frame.
    let rope = &found["curves"]["rope"];
    assert_eq!(rope["path"], "/rope/ropeShape");
    assert_eq!(rope["samples"], 6);
    assert!(rope["position_worst"].as_f64().unwrap() <= 1e-6, "{rope}");
    assert_eq!(
        rope["kinds"],
        serde_json::json!(["kLinear kNonPeriodic [9]"])
    );
    assert_matches_obj(&found, "sheet", 6, 1001, 24.0);
    let sheet = &found["meshes"]["sheet"];
    assert_eq!(sheet["path"], "/sheet/sheetShape");
    assert_eq!(sheet["constant_faces"], true);
    assert_eq!(sheet["uv_scope"], "kFacevaryingScope");
    assert_eq!(sheet["normal_scope"], "kVertexScope");
    let sampling = &found["time_samplings"][1];
    assert!((sampling["step"].as_f64().unwrap() - 1.0 / 24.0).abs() < 1e-12);
}

#[test]
fn a_torn_garments_cache_changes_its_faces_from_the_frame_they_tear() {
    let dir = common::temp_dir();
    let d = dir.path();
    let pins: Vec<String> = (0..20).map(|i| format!("[{i}, 0]")).collect();
    common::write(
        d,
        "scene.json",
        &format!(
            r#"{{ "frames": 40, "substeps": 10, "backend": "cpu", "solver": {{ "iterations": 2 }},
                  "output": {{ "gltf": "none", "alembic": true }},
                  "garments": [{{ "name": "cloth", "resolution": [20, 20], "size": [1, 1],
                    "position": [0, 1.2, 0], "rotation": [90, 0, 0], "tethers": false,
                    "pins": [{}], "tear_strain": 0.2,
                    "attachments": [{{ "particles": [[0, -1], [1, -1], [2, -1], [3, -1]],
                      "keyframes": [{{ "time": 0.1 }}, {{ "time": 0.6, "translation": [-0.3, -0.9, 0.4] }}] }}] }}] }}"#,
            pins.join(", ")
        ),
    );
    let report = common::bake_report(d);
    assert!(report["torn_springs"].as_u64().unwrap() > 0, "nothing tore");
    let found = check(&d.join("out/scene.abc"), &d.join("out/obj"));
    assert_matches_obj(&found, "cloth", 40, 1, 60.0);
    let cloth = &found["meshes"]["cloth"];
    assert_eq!(cloth["constant_faces"], false);
    let faces: Vec<u64> = cloth["faces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_u64().unwrap())
        .collect();
    assert_eq!(faces[0], 2 * 19 * 19);
    assert!(faces.last() < faces.first(), "{faces:?}");
}

#[test]
fn scene_ps_cache_holds_the_poncho_and_the_characters() {
    let dir = common::temp_dir();
    let mut scene = common::scene_p(dir.path(), 12);
    scene.output.obj = true;
    scene.output.character_obj = true;
    scene.output.alembic = true;
    let out = dir.path().join("out");
    drape::bake::bake(&scene, &common::bake_options(&out)).expect("bake");
    let found = check(&out.join(format!("{}.abc", scene.name)), &out.join("obj"));
    let names: Vec<&String> = found["meshes"].as_object().unwrap().keys().collect();
    assert!(
        names.len() >= 3,
        "the poncho, the mannequin and the stool: {names:?}"
    );
    for name in names {
        assert_matches_obj(&found, name, 12, scene.frame_start, f64::from(scene.fps));
    }
}

#[test]
fn a_bake_stopped_and_resumed_writes_the_same_cache() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(
        d,
        "scene.json",
        r#"{ "name": "again", "frames": 12, "substeps": 10, "backend": "cpu",
             "output": { "gltf": "none", "obj": false, "alembic": true },
             "garments": [{ "resolution": [16, 16], "pins": [[0, 0], [-1, 0]] }] }"#,
    );
    let bake = |args: &[&str]| {
        let out = common::drape(d, args);
        assert!(out.status.success(), "{}", common::stderr(&out));
    };
    bake(&["bake", "scene.json", "--out", "whole"]);
    bake(&["bake", "scene.json", "--out", "parts", "--until", "5"]);
    bake(&["bake", "scene.json", "--out", "parts", "--resume"]);
    let read = |p: PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let whole = read(d.join("whole/again.abc"));
    assert!(whole.len() > 10_000, "{} bytes", whole.len());
    assert!(
        read(d.join("parts/again.abc")) == whole,
        "the resumed cache differs"
    );
}
