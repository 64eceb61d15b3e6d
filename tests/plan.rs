//! `drape plan`: a wedge of two fields becomes every combination as a scene and a bake line;
//! running `jobs.txt` with plain `bash` gives the same frames (bit for bit, `frames_hash`) as
//! baking the scene with the same values as flags; with a character, `shells.txt` builds its
//! shell once and every bake reuses it; a plan in chunks (each resuming the one before) bakes the
//! same frames run chunk after chunk; bad wedges, `--chunk 0` and a used folder are refused with
//! exit 2 and nothing written.

mod common;

use std::path::Path;

const SCENE: &str = r#"{ "name": "tiny", "frames": 3, "backend": "cpu",
  "garments": [{ "resolution": [8, 8], "pins": [[0, 0]] }] }"#;

fn frames_hash(dir: &Path) -> String {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    report["frames_hash"].as_str().unwrap().to_string()
}

/// Runs `d/plan/jobs.txt` with plain `bash` in the plan folder (its paths are relative to it).
fn run_jobs(d: &Path) {
    let run = std::process::Command::new("bash")
        .arg("jobs.txt")
        .current_dir(d.join("plan"))
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
fn jobs_txt_run_by_bash_bakes_what_the_flags_bake() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "scene.json", SCENE);
    let out = common::drape(
        d,
        &[
            "plan",
            "scene.json",
            "--wedge",
            "solver.iterations=1,3",
            "--wedge",
            "substeps=4,8",
            "--out",
            "plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let jobs = std::fs::read_to_string(d.join("plan/jobs.txt")).unwrap();
    assert_eq!(jobs.lines().count(), 4, "{jobs}");
    let yaml = std::fs::read_to_string(d.join("plan/job.yaml")).unwrap();
    assert!(yaml.starts_with("specificationVersion: 'jobtemplate-2023-09'"));
    for name in std::fs::read_dir(d.join("plan/scenes")).unwrap() {
        let name = name.unwrap().path();
        let stem = name.file_stem().unwrap().to_string_lossy().into_owned();
        assert!(
            yaml.contains(&format!("\"{stem}\"")),
            "{stem} not in job.yaml"
        );
    }
    run_jobs(d);
    let planned = d.join("plan/bakes/tiny_solver.iterations-3_substeps-8");
    let direct = common::drape(
        d,
        &[
            "bake",
            "scene.json",
            "--iterations",
            "3",
            "--substeps",
            "8",
            "--out",
            "direct",
        ],
    );
    assert!(direct.status.success(), "{}", common::stderr(&direct));
    assert_eq!(frames_hash(&planned), frames_hash(&d.join("direct")));
    let other = d.join("plan/bakes/tiny_solver.iterations-1_substeps-4");
    assert_ne!(frames_hash(&planned), frames_hash(&other));
}

#[test]
fn bad_plans_are_refused_and_write_nothing() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "scene.json", SCENE);
    for (args, says) in [
        (vec!["--wedge", "garments[3].mass=0.1"], "garments[3].mass"),
        (vec!["--wedge", "solver.iterations"], "FIELD=V1,V2"),
        (vec!["--wedge", "frames=0,2"], "frames"),
        (vec!["--chunk", "0"], "--chunk"),
    ] {
        let mut all = vec!["plan", "scene.json", "--out", "plan"];
        all.extend(args);
        let out = common::drape(d, &all);
        let err = common::stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{all:?}: {err}");
        assert!(err.contains(says), "{all:?}: {err}");
        assert!(!d.join("plan").exists(), "{all:?} left a plan");
    }
    std::fs::create_dir(d.join("used")).unwrap();
    common::write(d, "used/notes.txt", "mine");
    let out = common::drape(d, &["plan", "scene.json", "--out", "used"]);
    assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
    assert!(d.join("used/notes.txt").is_file());
}

#[test]
fn a_plan_with_a_character_builds_its_shell_once_and_every_bake_reuses_it() {
    let dir = common::temp_dir();
    let d = dir.path();
    let stool = Path::new(env!("CARGO_MANIFEST_DIR")).join("characters/mannequin/stool.obj");
    common::write(
        d,
        "scene.json",
        &format!(
            r#"{{ "name": "onstool", "frames": 2, "backend": "cpu",
                  "garments": [{{ "resolution": [10, 10], "size": [0.8, 0.8], "position": [0, 0.7, -0.46] }}],
                  "characters": [{{ "name": "stool", "file": {:?} }}] }}"#,
            stool.display().to_string()
        ),
    );
    let out = common::drape(
        d,
        &[
            "plan",
            "scene.json",
            "--wedge",
            "solver.iterations=2,4",
            "--out",
            "plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let yaml = std::fs::read_to_string(d.join("plan/job.yaml")).unwrap();
    assert!(yaml.contains("- name: shells") && yaml.contains("dependsOn: shells"));
    for list in ["shells.txt", "jobs.txt"] {
        let run = std::process::Command::new("bash")
            .arg(list)
            .current_dir(d.join("plan"))
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{list}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let shells: Vec<_> = std::fs::read_dir(d.join("plan/shells")).unwrap().collect();
    assert_eq!(shells.len(), 1, "one cache for both variants");
    for bake in std::fs::read_dir(d.join("plan/bakes")).unwrap() {
        let report = std::fs::read_to_string(bake.unwrap().path().join("report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&report).unwrap();
        assert_eq!(report["characters"][0]["shell_cache"], "reused");
    }
}

#[test]
fn a_plan_in_chunks_run_chunk_after_chunk_bakes_the_whole_shot() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(
        d,
        "scene.json",
        &SCENE.replace(r#""frames": 3"#, r#""frames": 10, "frame_start": 1001"#),
    );
    let out = common::drape(
        d,
        &[
            "plan",
            "scene.json",
            "--wedge",
            "solver.iterations=1,3",
            "--chunk",
            "4",
            "--out",
            "plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let jobs = std::fs::read_to_string(d.join("plan/jobs.txt")).unwrap();
    // Two variants in three chunks: frames 1001-1004, 1005-1008, 1009-1010.
    assert_eq!(jobs.lines().count(), 6, "{jobs}");
    for (k, until) in [(1, 1004), (2, 1008), (3, 1010)] {
        let chunk =
            std::fs::read_to_string(d.join(format!("plan/chunks/chunk_{k:02}.txt"))).unwrap();
        assert_eq!(chunk.lines().count(), 2);
        assert!(
            chunk
                .lines()
                .all(|l| l.contains(" --resume") && l.ends_with(&format!(" --until {until}"))),
            "{chunk}"
        );
    }
    let yaml = std::fs::read_to_string(d.join("plan/job.yaml")).unwrap();
    // A chain of chunk steps per variant.
    assert!(
        yaml.contains("- name: \"bake_03 tiny_solver.iterations-3\"")
            && yaml.contains("dependsOn: \"bake_02 tiny_solver.iterations-3\""),
        "{yaml}"
    );
    run_jobs(d);
    let planned = d.join("plan/bakes/tiny_solver.iterations-3");
    let direct = common::drape(
        d,
        &["bake", "scene.json", "--iterations", "3", "--out", "direct"],
    );
    assert!(direct.status.success(), "{}", common::stderr(&direct));
    assert_eq!(frames_hash(&planned), frames_hash(&d.join("direct")));
    let mut files = 0;
    for entry in std::fs::read_dir(d.join("direct/obj")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap();
        assert_eq!(
            std::fs::read(planned.join("obj").join(name)).unwrap(),
            std::fs::read(&path).unwrap(),
            "{name:?}"
        );
        files += 1;
    }
    // Ten frames' OBJ files and their material.
    assert_eq!(files, 11);
}

#[test]
fn a_wedge_value_may_be_an_array_and_status_reads_the_reports() {
    // Issue 35 items 10 and 11: a comma inside brackets belongs to the value; `--status`
    // lists each variant's state and exits 0 only when every one is done.
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "scene.json", SCENE);
    let out = common::drape(
        d,
        &[
            "plan",
            "scene.json",
            "--wedge",
            "garments[0].position=[0,1,0],[0,2,0]",
            "--out",
            "plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let mut names: Vec<String> = std::fs::read_dir(d.join("plan/scenes"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 2, "{names:?}");
    let scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(d.join("plan/scenes").join(&names[1])).unwrap(),
    )
    .unwrap();
    assert_eq!(
        scene["garments"][0]["position"],
        serde_json::json!([0, 2, 0])
    );
    let status = |d: &Path| common::drape(d, &["plan", "--status", "plan"]);
    let before = status(d);
    assert_eq!(before.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&before.stdout).contains("not baked yet"));
    // The first line only: one variant done, one not.
    let first = std::fs::read_to_string(d.join("plan/jobs.txt")).unwrap();
    let line = first.lines().next().unwrap();
    let run = std::process::Command::new("bash")
        .args(["-c", line])
        .current_dir(d.join("plan"))
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", common::stderr(&run));
    let half = status(d);
    let text = String::from_utf8_lossy(&half.stdout).to_string();
    assert_eq!(half.status.code(), Some(1), "{text}");
    assert!(
        text.contains("done: ") && text.contains("1 of 2 variants done"),
        "{text}"
    );
    run_jobs(d);
    let all = status(d);
    assert_eq!(
        all.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&all.stdout)
    );
}

#[test]
fn a_plan_moved_with_its_project_runs_where_it_lands() {
    // Issue 35 item 9: no list names the folder the plan was made in (its paths are relative to
    // the plan folder, the drape is `$DRAPE` or the planner's), and the variants' scenes reach
    // the project's meshes by relative paths: the project moved with its plan (as a worker
    // that mounts it elsewhere sees it) bakes from `run_line.sh`, run from anywhere, to the
    // frames of a direct bake.
    let dir = common::temp_dir();
    let project = dir.path().join("project");
    let stool = Path::new(env!("CARGO_MANIFEST_DIR")).join("characters/mannequin/stool.obj");
    std::fs::create_dir_all(project.join("shot/assets")).unwrap();
    std::fs::copy(&stool, project.join("shot/assets/stool.obj")).unwrap();
    common::write(
        &project.join("shot"),
        "scene.json",
        r#"{ "name": "onstool", "frames": 2, "backend": "cpu",
             "garments": [{ "resolution": [10, 10], "size": [0.8, 0.8], "position": [0, 0.7, -0.46] }],
             "characters": [{ "name": "stool", "file": "assets/stool.obj" }] }"#,
    );
    let out = common::drape(
        &project,
        &[
            "plan",
            "shot/scene.json",
            "--wedge",
            "solver.iterations=2,4",
            "--out",
            "farm/plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let planned_at = project.display().to_string();
    for entry in walk(&project.join("farm/plan")) {
        let text = std::fs::read_to_string(&entry).unwrap();
        assert!(
            !text.contains(&planned_at),
            "{} names the folder it was planned in:\n{text}",
            entry.display()
        );
    }
    let moved = dir.path().join("elsewhere");
    std::fs::rename(&project, &moved).unwrap();
    let plan = moved.join("farm/plan");
    let run_line = |list: &str, n: usize, drape: Option<&str>| {
        let mut c = std::process::Command::new("bash");
        c.arg(plan.join("run_line.sh"))
            .arg(plan.join(list))
            .arg(n.to_string())
            .current_dir(dir.path());
        if let Some(d) = drape {
            c.env("DRAPE", d);
        }
        c.output().unwrap()
    };
    // A worker's `$DRAPE` is the drape that runs.
    let elsewhere = run_line("jobs.txt", 1, Some("/nonexistent/drape"));
    assert_eq!(
        elsewhere.status.code(),
        Some(127),
        "{}",
        common::stderr(&elsewhere)
    );
    for (list, n) in [("shells.txt", 1), ("jobs.txt", 1), ("jobs.txt", 2)] {
        let run = run_line(list, n, Some(env!("CARGO_BIN_EXE_drape")));
        assert!(run.status.success(), "{list} {n}: {}", common::stderr(&run));
    }
    let direct = common::drape(
        &moved,
        &[
            "bake",
            "shot/scene.json",
            "--iterations",
            "4",
            "--out",
            "direct",
        ],
    );
    assert!(direct.status.success(), "{}", common::stderr(&direct));
    let planned = plan.join("bakes/onstool_solver.iterations-4");
    assert_eq!(frames_hash(&planned), frames_hash(&moved.join("direct")));
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(walk(&path));
        } else {
            files.push(path);
        }
    }
    files
}
