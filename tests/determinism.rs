//! Determinism as a promise: `report.json`'s `frames_hash` is the same for the same scene on the
//! CPU backend, run after run and on any number of threads, and differs when the scene does.
//! The scene exercises every CPU stage that could depend on scheduling: colour-parallel
//! Gauss-Seidel with collision passes, colliders, a character's shell, particle collisions and
//! keyframed attachments.

mod common;

const STOOL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/characters/mannequin/stool.obj"
);

fn scene(mass: f32) -> String {
    format!(
        r#"{{ "frames": 20, "backend": "cpu", "particle_collisions": true,
              "solver": {{ "iterations": 6, "contact_passes": 2 }},
              "characters": [{{ "name": "stool", "file": "{STOOL}", "radius": 0.03 }}],
              "colliders": [{{ "kind": "plane" }}, {{ "kind": "sphere", "centre": [0.3, 0.5, 0], "radius": 0.1 }}],
              "garments": [{{ "name": "cloth", "resolution": [16, 16], "mass": {mass}, "position": [0, 0.8, 0],
                              "attachments": [{{ "particles": [[0, 0]],
                                                "keyframes": [{{ "time": 0 }}, {{ "time": 0.3, "translation": [0, 0.1, 0] }}] }}] }}] }}"#
    )
}

fn frames_hash(dir: &std::path::Path, mass: f32, threads: &str) -> String {
    std::fs::write(dir.join("scene.json"), scene(mass)).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["bake", "scene.json", "--out", "out", "--threads", threads])
        .args(["--gltf", "none"])
        .env("XDG_CACHE_HOME", dir.join("cache"))
        .current_dir(dir)
        .output()
        .expect("drape runs");
    assert!(out.status.success(), "{}", common::stderr(&out));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["frames_baked"], 20);
    let hash = report["frames_hash"].as_str().unwrap().to_string();
    assert_eq!(hash.len(), 16, "{hash}");
    hash
}

#[test]
fn the_same_scene_hashes_the_same_on_any_thread_count() {
    let dir = common::temp_dir();
    let one = frames_hash(dir.path(), 0.1, "1");
    let two = frames_hash(dir.path(), 0.1, "2");
    let again = frames_hash(dir.path(), 0.1, "2");
    assert_eq!(one, two, "1 and 2 threads");
    assert_eq!(two, again, "two runs");
    let heavier = frames_hash(dir.path(), 0.2, "2");
    assert_ne!(
        two, heavier,
        "a heavier cloth falls the same way to the last bit?"
    );
}
