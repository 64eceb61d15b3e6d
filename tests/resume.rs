//! Checkpoints and resume: a bake stopped part way (at a chunk's end, by SIGINT, or killed with
//! SIGKILL) and resumed gives the same frames, bit for bit, as the bake that never stopped, in
//! the report (`frames_hash`, every per-frame measure) and in every file written (OBJ with torn
//! faces, PC2), also with accuracy targets choosing the budget; `--from-frame` re-simulates from
//! an earlier checkpoint to the same frames; a checkpoint is refused for a changed scene (exit 2
//! naming the field), leaving the bake as it was.

mod common;

use drape::bake::{bake, BakeOptions, Resume};
use drape::scene::{GltfOutput, Scene};
use std::path::Path;

/// The tearing test's cloth (pins along the top, a corner grabbed and pulled), 30 frames.
fn torn_cloth() -> Scene {
    let pins: Vec<String> = (0..20).map(|i| format!("[{i}, 0]")).collect();
    common::scene(&format!(
        r#"{{ "frames": 30, "substeps": 10, "backend": "cpu", "solver": {{ "iterations": 2 }},
              "checkpoint_every": 7, "output": {{ "gltf": "none", "pc2": true }},
              "garments": [{{ "name": "cloth", "resolution": [20, 20], "size": [1, 1], "position": [0, 1.2, 0],
                              "rotation": [90, 0, 0], "tethers": false, "pins": [{pins}], "tear_strain": 0.2,
                              "attachments": [{{ "particles": [[0, -1], [1, -1], [2, -1], [3, -1], [4, -1], [5, -1]],
                                                "keyframes": [{{ "time": 0.05 }}, {{ "time": 0.45, "translation": [-0.3, -0.9, 0.4] }}] }}] }}] }}"#,
        pins = pins.join(", ")
    ))
}

fn options(out: &Path, resume: Resume, until: Option<u32>) -> BakeOptions {
    BakeOptions {
        resume,
        until,
        ..common::bake_options(out)
    }
}

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap()
}

/// Every file of `a` (but the report and the checkpoints) has the same bytes in `b`.
fn assert_same_files(a: &Path, b: &Path) {
    let mut compared = 0;
    for entry in walk(a) {
        let rel = entry.strip_prefix(a).unwrap();
        if rel.starts_with("checkpoints") || rel == Path::new("report.json") {
            continue;
        }
        let (x, y) = (std::fs::read(&entry).unwrap(), std::fs::read(b.join(rel)));
        assert!(y.is_ok_and(|y| y == x), "{} differs", rel.display());
        compared += 1;
    }
    assert!(compared >= 2, "only {compared} files compared");
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            files.extend(walk(&p));
        } else {
            files.push(p);
        }
    }
    files
}

/// The report's fields that describe the frames (not timings, not how the run went).
fn assert_same_frames(a: &serde_json::Value, b: &serde_json::Value) {
    for field in [
        "frames_hash",
        "frames_baked",
        "torn_springs",
        "stable",
        "worst_frame",
        "last_frame",
        "worst_penetrations",
        "penetrations_per_frame",
        "worst_mesh_penetrations",
        "mesh_penetrations_per_frame",
        "worst_held_mesh_penetrations",
        "held_mesh_penetrations_per_frame",
        "character_crossings_per_frame",
    ] {
        assert_eq!(a[field], b[field], "{field}");
    }
}

#[test]
fn a_torn_cloth_resumed_from_a_chunk_or_an_earlier_frame_matches_the_whole_bake() {
    let dir = common::temp_dir();
    let scene = torn_cloth();
    let whole = dir.path().join("whole");
    let result = bake(&scene, &options(&whole, Resume::No, None)).unwrap();
    assert!(result.report.torn_springs > 0, "nothing tore");
    let whole_report = report(&whole);
    assert_eq!(
        whole_report["checkpoints"]["frames"],
        serde_json::json!([7, 14, 21, 28, 30])
    );

    // A first chunk stopped after frame 17, then the rest resumed from its last checkpoint.
    let chunked = dir.path().join("chunked");
    let first = bake(&scene, &options(&chunked, Resume::Last, Some(17))).unwrap();
    assert_eq!(first.report.frames_baked, 17);
    assert!(first.report.resumed.is_none());
    bake(&scene, &options(&chunked, Resume::Last, None)).unwrap();
    let resumed = report(&chunked);
    assert_eq!(resumed["resumed"]["after_frame"], 17);
    assert_same_frames(&whole_report, &resumed);
    assert_same_files(&whole, &chunked);

    // Frames from 16 on simulated again: from the checkpoint after frame 14.
    bake(&scene, &options(&chunked, Resume::From(16), None)).unwrap();
    let again = report(&chunked);
    assert_eq!(again["resumed"]["after_frame"], 14);
    assert_same_frames(&whole_report, &again);
    assert_same_files(&whole, &chunked);
}

#[test]
fn the_poncho_on_the_mannequin_resumes_bit_for_bit() {
    // Characters' shells, collision passes with their nearby lists, a static stool.
    let dir = common::temp_dir();
    let scene = common::scene_p(dir.path(), 6);
    assert!(scene.solver.contact_passes > 1);
    let whole = dir.path().join("whole");
    bake(&scene, &options(&whole, Resume::No, None)).unwrap();
    let part = dir.path().join("part");
    bake(&scene, &options(&part, Resume::No, Some(2))).unwrap();
    bake(&scene, &options(&part, Resume::Last, None)).unwrap();
    let resumed = report(&part);
    assert_eq!(resumed["resumed"]["after_frame"], 2);
    assert_same_frames(&report(&whole), &resumed);
}

/// A bake of a small sheet long enough to be stopped part way, with a checkpoint every 5
/// frames and a point cache to compare.
const LONG: &str = r#"{ "name": "long", "frames": 1500, "substeps": 4, "backend": "cpu",
  "checkpoint_every": 5, "output": { "obj": false, "gltf": "none", "pc2": true },
  "garments": [{ "name": "sheet", "resolution": [24, 24], "pins": [[0, 0], [-1, 0]] }] }"#;

/// Starts `drape bake scene.json --out out` in `dir` and waits until its staging folder holds a
/// checkpoint.
fn start_and_wait_for_a_checkpoint(dir: &Path) -> std::process::Child {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(["bake", "scene.json", "--out", "out"])
        .current_dir(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let staging = dir
        .join(format!(".out.tmp-{}", child.id()))
        .join("checkpoints");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while !drape::bake::checkpoint::list(&staging)
        .iter()
        .any(|(frame, _)| *frame >= 5)
    {
        if let Some(status) = child.try_wait().unwrap() {
            let out = child.wait_with_output().unwrap();
            panic!(
                "the bake ended ({status}) before its first checkpoint: {}",
                common::stderr(&out)
            );
        }
        assert!(std::time::Instant::now() < deadline, "no checkpoint came");
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    child
}

fn signal(child: &std::process::Child, signal: i32) {
    // SAFETY: sending a signal to our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as i32, signal) }, 0);
}

#[test]
fn interrupted_and_killed_bakes_resume_to_the_frames_of_one_that_ran_through() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "scene.json", LONG);
    let through = common::drape(d, &["bake", "scene.json", "--out", "through"]);
    assert!(through.status.success(), "{}", common::stderr(&through));

    // SIGINT: stops after a frame, keeps the frames and a checkpoint, says how to resume.
    let child = start_and_wait_for_a_checkpoint(d);
    signal(&child, libc::SIGINT);
    let out = child.wait_with_output().unwrap();
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("--resume"), "{err}");
    let stopped = report(&d.join("out"));
    let after = stopped["interrupted"]["after_frame"].as_u64().unwrap();
    assert!(after < 1500 && stopped["stable"] == true);
    assert_eq!(
        stopped["checkpoints"]["frames"].as_array().unwrap().last(),
        Some(&serde_json::json!(after))
    );
    let resumed = common::drape(d, &["bake", "scene.json", "--out", "out", "--resume"]);
    assert!(resumed.status.success(), "{}", common::stderr(&resumed));
    assert_eq!(report(&d.join("out"))["resumed"]["after_frame"], after);
    assert_same_frames(&report(&d.join("through")), &report(&d.join("out")));
    assert_same_files(&d.join("through"), &d.join("out"));

    // SIGKILL: no chance to finish; the staging folder it leaves is resumed, then removed.
    std::fs::remove_dir_all(d.join("out")).unwrap();
    let mut child = start_and_wait_for_a_checkpoint(d);
    let staging = d.join(format!(".out.tmp-{}", child.id()));
    signal(&child, libc::SIGKILL);
    child.wait().unwrap();
    assert!(staging.is_dir() && !d.join("out").exists());
    let resumed = common::drape(d, &["bake", "scene.json", "--out", "out", "--resume"]);
    assert!(resumed.status.success(), "{}", common::stderr(&resumed));
    let r = report(&d.join("out"));
    assert!(r["resumed"]["checkpoint"]
        .as_str()
        .unwrap()
        .contains(".out.tmp-"));
    assert!(!staging.exists(), "the dead run's staging folder is left");
    assert_same_frames(&report(&d.join("through")), &r);
    assert_same_files(&d.join("through"), &d.join("out"));
}

#[test]
fn a_checkpoint_of_a_changed_scene_is_refused_naming_the_field() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "scene.json", &LONG.replace("1500", "12"));
    let first = common::drape(d, &["bake", "scene.json", "--out", "out"]);
    assert!(first.status.success(), "{}", common::stderr(&first));
    let before = std::fs::read(d.join("out/report.json")).unwrap();
    let out = common::drape(
        d,
        &[
            "bake",
            "scene.json",
            "--out",
            "out",
            "--frames",
            "20",
            "--iterations",
            "3",
            "--resume",
        ],
    );
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("solver.iterations") && err.contains("another scene"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("out/report.json")).unwrap(), before);
    // More frames of the same scene continue it.
    let more = common::drape(
        d,
        &[
            "bake",
            "scene.json",
            "--out",
            "out",
            "--frames",
            "20",
            "--resume",
        ],
    );
    assert!(more.status.success(), "{}", common::stderr(&more));
    let r = report(&d.join("out"));
    assert_eq!(
        (
            r["frames_baked"].as_u64(),
            r["resumed"]["after_frame"].as_u64()
        ),
        (Some(20), Some(12))
    );
}

#[test]
fn a_bake_with_accuracy_targets_resumes_bit_for_bit_within_a_settling_raise() {
    // The flag at a 10 % strain target: the budget climbs from 10 × 2 around frame 27, a frame is
    // simulated again at larger budgets, and the frames after the raise settle. A chunk that
    // stops at frame 28 leaves a checkpoint in the middle of all that; the clock there counts
    // in the raised budget's substeps.
    let dir = common::temp_dir();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/flag.json");
    let mut scene = Scene::load(&path).unwrap();
    scene.frames = 34;
    scene.substeps = None;
    scene.iterations_given = false;
    scene.accuracy = Some(drape::scene::AccuracySpec {
        max_strain: Some(0.10),
        max_penetration: None,
        max_shear: None,
    });
    scene.output.obj = false;
    scene.output.gltf = GltfOutput::None;
    scene.output.pc2 = true;
    let whole = dir.path().join("whole");
    bake(&scene, &options(&whole, Resume::No, None)).unwrap();
    let whole_report = report(&whole);
    let frames = whole_report["budget"]["per_frame"].as_array().unwrap();
    let settled = |f: &serde_json::Value| f["settled_joules"].as_f64().unwrap() > 0.0;
    assert!(
        frames[25..31].iter().any(settled),
        "a raise settles between frames 26 and 31"
    );
    let part = dir.path().join("part");
    bake(&scene, &options(&part, Resume::No, Some(28))).unwrap();
    bake(&scene, &options(&part, Resume::Last, None)).unwrap();
    let resumed = report(&part);
    assert_eq!(resumed["resumed"]["after_frame"], 28);
    assert_same_frames(&whole_report, &resumed);
    assert_eq!(
        whole_report["budget"], resumed["budget"],
        "the same budgets"
    );
    assert_same_files(&whole, &part);
}
