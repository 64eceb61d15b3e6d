//! Accuracy targets choose the budget: every frame of a bake with a target meets it (or the
//! report says it could not, and the command exits 1 with the frames kept); a loose target stays
//! at the cheapest budget, a tight one spends more; substeps the scene gives stay fixed; the
//! choices are the same on every run.

mod common;

use drape::bake::bake;
use drape::scene::Scene;

/// A 16 × 16 sheet pinned at two corners, falling and swinging, with `accuracy` and `extra`
/// top-level fields.
fn sheet(accuracy: &str, extra: &str) -> Scene {
    common::scene(&format!(
        r#"{{ "frames": 24, "backend": "cpu", "accuracy": {accuracy}{extra},
              "output": {{ "obj": false, "gltf": "none" }},
              "garments": [{{ "resolution": [16, 16], "size": [1, 1], "pins": [[0, 0], [-1, 0]] }}] }}"#
    ))
}

fn run(scene: &Scene) -> drape::report::Report {
    let dir = common::temp_dir();
    let options = common::bake_options(&dir.path().join("out"));
    bake(scene, &options).expect("bake").report
}

fn mean_substeps(report: &drape::report::Report) -> f64 {
    let frames = &report.budget.as_ref().unwrap().per_frame;
    frames.iter().map(|f| f.substeps as f64).sum::<f64>() / frames.len() as f64
}

#[test]
fn every_frame_meets_its_target_and_a_tighter_target_costs_more() {
    let loose = run(&sheet(r#"{ "max_strain": 0.5 }"#, ""));
    let tight = run(&sheet(r#"{ "max_strain": 0.01 }"#, ""));
    for report in [&loose, &tight] {
        let b = report.budget.as_ref().unwrap();
        assert!(b.met, "{:?}", b.per_frame);
        assert_eq!(b.per_frame.len(), 24);
        let target = b.max_strain.unwrap();
        for f in &b.per_frame {
            assert!(
                f.max_strain <= target,
                "frame {}: {}",
                f.frame,
                f.max_strain
            );
        }
        // The report's own strain measure agrees with the budget's.
        let worst = report.worst_frame.as_ref().unwrap().max_strain;
        assert!(worst <= target + 1e-12, "{worst}");
    }
    let cheapest = drape::bake::budget::LADDER[0];
    assert!(loose
        .budget
        .as_ref()
        .unwrap()
        .per_frame
        .iter()
        .all(|f| (f.substeps, f.iterations) == cheapest));
    assert!(mean_substeps(&tight) > mean_substeps(&loose));
    assert!(tight
        .budget
        .as_ref()
        .unwrap()
        .per_frame
        .iter()
        .any(|f| f.attempts > 1 || !f.why.is_empty()));
    // The same choices on another run.
    let again = run(&sheet(r#"{ "max_strain": 0.01 }"#, ""));
    assert_eq!(again.frames_hash, tight.frames_hash);
    assert_eq!(again.budget, tight.budget);
}

#[test]
fn substeps_the_scene_gives_stay_fixed() {
    let report = run(&sheet(r#"{ "max_strain": 0.01 }"#, r#", "substeps": 7"#));
    assert!(report
        .budget
        .as_ref()
        .unwrap()
        .per_frame
        .iter()
        .all(|f| f.substeps == 7));
}

/// A budget's largest level is checked against the GPU before a bake starts (`bake` refuses
/// `gpu`, or takes the CPU for `auto`, when it does not fit): characters' shells take a share of
/// a buffer per substep, and one dispatch places them for every substep.
#[test]
fn the_gpu_says_whether_a_budgets_largest_substeps_fit() {
    let Some(ctx) = common::gpu_context() else {
        return;
    };
    let man =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("characters/CesiumMan/CesiumMan.glb");
    let scene = common::scene(&format!(
        r#"{{ "frames": 2, "backend": "gpu",
              "garments": [{{ "resolution": [8, 8], "size": [0.5, 0.5], "position": [0, 1.8, 0] }}],
              "characters": [{{ "name": "man", "file": {:?}, "clip": "0" }}] }}"#,
        man.display().to_string()
    ));
    let dir = common::temp_dir();
    let sim = common::simulation(&scene, dir.path());
    let backend = drape::backend::Backend::gpu(ctx, &sim).expect("the GPU takes the scene");
    assert!(backend.fits_substeps(&sim, 80).is_ok());
    let err = backend
        .fits_substeps(&sim, 1 << 20)
        .unwrap_err()
        .to_string();
    assert!(err.contains("1048576 substeps per frame"), "{err}");
}

/// Accuracy targets on the GPU backend (lavapipe here and in CI): every frame meets its target,
/// frames the target rejects are simulated again on the device at a larger budget, and the
/// choices are the same on another run.
#[test]
fn on_the_gpu_every_frame_meets_its_target() {
    if common::gpu_context().is_none() {
        return;
    }
    let mut scene = sheet(r#"{ "max_strain": 0.01 }"#, "");
    scene.backend = drape::scene::BackendKind::Gpu;
    let report = run(&scene);
    assert_eq!(report.backend.kind, "gpu");
    let b = report.budget.as_ref().unwrap();
    assert!(b.met, "{:?}", b.per_frame);
    assert_eq!(b.per_frame.len(), 24);
    assert!(
        b.per_frame.iter().all(|f| f.max_strain <= 0.01),
        "{:?}",
        b.per_frame
    );
    assert!(
        b.per_frame.iter().any(|f| f.attempts > 1),
        "{:?}",
        b.per_frame
    );
    let cheapest = drape::bake::budget::LADDER[0];
    assert!(b
        .per_frame
        .iter()
        .any(|f| (f.substeps, f.iterations) != cheapest));
    let again = run(&scene);
    assert_eq!(again.frames_hash, report.frames_hash);
    assert_eq!(again.budget, report.budget);
}

#[test]
fn a_target_no_budget_meets_fails_with_the_frames_kept() {
    let dir = common::temp_dir();
    let d = dir.path();
    let text = r#"{ "frames": 3, "backend": "cpu", "accuracy": { "max_strain": 1e-9 },
                    "garments": [{ "resolution": [8, 8], "pins": [[0, 0]] }] }"#;
    common::write(d, "scene.json", text);
    let out = common::drape(d, &["bake", "scene.json", "--out", "out"]);
    let err = common::stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("accuracy targets"), "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("out/report.json")).unwrap()).unwrap();
    assert_eq!(report["frames_baked"], 3);
    assert_eq!(report["budget"]["met"], false);
    let last = drape::bake::budget::LADDER[drape::bake::budget::LADDER.len() - 1];
    assert_eq!(report["budget"]["per_frame"][2]["substeps"], last.0);
    // A flag sets the target too; a bad one is named.
    let out = common::drape(
        d,
        &["bake", "scene.json", "--out", "out2", "--max-strain", "-1"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(common::stderr(&out).contains("--max-strain"));
}

/// A bake whose frames miss at the cap ten in a row steps down to see whether the budget is
/// what holds them off, keeps the frames it misses meanwhile (`kept_missing`) and says so; here
/// the target (a strain of 10⁻⁹) is of the budget's making, so the window below misses by more
/// and the budget goes back up to the cap. Stopped within the descent and resumed, the bake
/// gives the same frames and the same budget frame for frame.
#[test]
fn misses_at_the_cap_step_down_a_window_and_a_resumed_descent_is_the_same() {
    let dir = common::temp_dir();
    let d = dir.path();
    let text = r#"{ "frames": 40, "backend": "cpu", "accuracy": { "max_strain": 1e-9 },
                    "output": { "obj": false, "gltf": "none" },
                    "garments": [{ "resolution": [8, 8], "pins": [[0, 0]] }] }"#;
    common::write(d, "scene.json", text);
    let whole = common::drape(d, &["bake", "scene.json", "--out", "whole"]);
    let err = common::stderr(&whole);
    assert_eq!(whole.status.code(), Some(1), "{err}");
    assert!(err.contains("kept at a smaller budget"), "{err}");
    let stopped = common::drape(
        d,
        &["bake", "scene.json", "--out", "parts", "--until", "15"],
    );
    assert_eq!(
        stopped.status.code(),
        Some(1),
        "{}",
        common::stderr(&stopped)
    );
    let resumed = common::drape(d, &["bake", "scene.json", "--out", "parts", "--resume"]);
    assert_eq!(
        resumed.status.code(),
        Some(1),
        "{}",
        common::stderr(&resumed)
    );
    let report = |out: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(d.join(out).join("report.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let (whole, parts) = (report("whole"), report("parts"));
    let budgets = |r: &serde_json::Value| -> Vec<(u64, u64, bool)> {
        (r["budget"]["per_frame"].as_array().unwrap().iter())
            .map(|f| {
                let kept = f["kept_missing"].as_bool().unwrap();
                (
                    f["substeps"].as_u64().unwrap(),
                    f["iterations"].as_u64().unwrap(),
                    kept,
                )
            })
            .collect()
    };
    let levels = budgets(&whole);
    let cap = drape::bake::budget::LADDER[drape::bake::budget::LADDER.len() - 1];
    let below = drape::bake::budget::LADDER[drape::bake::budget::LADDER.len() - 2];
    let at = |k: usize| (levels[k].0 as u32, levels[k].1 as u32);
    // Ten frames at the cap (the first climbs to it), ten a level below, kept; then the cap.
    assert!((1..10).all(|k| at(k) == cap), "{levels:?}");
    assert!(
        (10..20).all(|k| at(k) == below && levels[k].2),
        "{levels:?}"
    );
    assert!((20..40).all(|k| at(k) == cap), "{levels:?}");
    assert_eq!(whole["budget"]["kept_missing"], 10);
    assert_eq!(parts["frames_hash"], whole["frames_hash"]);
    assert_eq!(budgets(&parts), levels);
}

/// A curtain whose top edge a keyframed rail carries 0.6 m along +X in the first second: where
/// the cloth is depends on the clock.
const RAIL: &str = r#"{ "frames": 10, "substeps": 5, "backend": "cpu",
  "solver": { "iterations": 2 },
  "garments": [{ "resolution": [12, 12], "size": [1, 1], "position": [0, 1, 0], "rotation": [90, 0, 0],
                 "attachments": [{ "particles": "top_edge",
                                   "keyframes": [{ "time": 0 }, { "time": 1, "translation": [0.6, 0, 0] }] }] }] }"#;

/// A frame simulated again at the next budget is the frame a bake at that budget would have
/// simulated from the same start: its clock is read in the substeps of the budget the start
/// state was taken at. (It was not: a retry from 10 × 2 to 10 × 5 restored a clock counted in
/// 5-substep units as 10-substep ones, and scene P's mannequin then ran 9 frames behind the
/// cloth, which the bake measured against the mesh at the right time: cloth "inside" its arms.)
#[test]
fn a_frame_simulated_again_at_another_budget_starts_at_its_own_time() {
    let scene = common::scene(RAIL);
    let mut retried = drape::sim::Simulation::new(&scene).unwrap();
    let mut straight = drape::sim::Simulation::new(&scene).unwrap();
    for _ in 0..3 {
        retried.step_frame();
        straight.step_frame();
    }
    let start = retried.snapshot();
    retried.set_budget(10, 2, 1);
    retried.step_frame(); // the attempt that missed its target
    retried.restore(&start).expect("its own snapshot");
    retried.set_budget(10, 5, 1);
    retried.step_frame();
    straight.set_budget(10, 5, 1);
    straight.step_frame();
    assert_eq!(
        retried.elapsed_substeps(),
        4 * 10,
        "four frames of 10 substeps"
    );
    assert_eq!(retried.elapsed_substeps(), straight.elapsed_substeps());
    assert_eq!(
        retried.state.positions, straight.state.positions,
        "the same frame to the bit"
    );
}

/// A sheet falling onto a keyframed ball that rises 0.3 m in the first second.
const RISING_BALL: &str = r#"{ "frames": 4, "substeps": 5, "backend": "cpu",
  "solver": { "iterations": 2 },
  "garments": [{ "resolution": [10, 10], "size": [1, 1], "position": [0, 1, 0] }],
  "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.2,
                  "keyframes": [{ "time": 0 }, { "time": 1, "translation": [0, 0.3, 0] }] }] }"#;

/// On the GPU too, a frame simulated again after a raise is settled (on the CPU, the GPU taking
/// its end): `scenes/tearing.json` with its substeps and iterations taken out, at a 30 % strain
/// target, tears, frees stretch and bakes its first 20 frames, where without settling the GPU
/// stopped at frame 12 (energy from nowhere at every level).
#[test]
fn on_the_gpu_the_frames_after_a_raise_settle() {
    if common::gpu_context().is_none() {
        return;
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tearing.json");
    let text = std::fs::read_to_string(path).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json.as_object_mut().unwrap().remove("substeps");
    json["solver"].as_object_mut().unwrap().remove("iterations");
    json["frames"] = 20.into();
    json["backend"] = "gpu".into();
    json["accuracy"] = serde_json::json!({ "max_strain": 0.3 });
    json["output"] = serde_json::json!({ "obj": false, "gltf": "none" });
    let report = run(&common::scene(&json.to_string()));
    assert!(report.failure.is_none(), "{:?}", report.failure);
    assert_eq!(report.frames_baked, 20);
    let b = report.budget.as_ref().unwrap();
    assert!(
        b.per_frame.iter().any(|f| f.settled_joules > 0.0),
        "{:?}",
        b.per_frame
    );
}

/// The first frame simulated again is a new bake's first frame: the keyframed colliders go back
/// to rest, not to where the rejected attempt left them (from there the retry measured a jump
/// back to the start as the ball's speed, and the stability rule then allowed the cloth that
/// much more energy for the rest of the bake).
#[test]
fn a_first_frame_simulated_again_starts_with_its_colliders_at_rest() {
    let scene = common::scene(RISING_BALL);
    let mut retried = drape::sim::Simulation::new(&scene).unwrap();
    let mut straight = drape::sim::Simulation::new(&scene).unwrap();
    let start = retried.snapshot();
    retried.step_frame(); // the attempt that missed its target
    retried.restore(&start).expect("its own snapshot");
    retried.set_budget(10, 2, 1);
    straight.set_budget(10, 2, 1);
    for _ in 0..2 {
        retried.step_frame();
        straight.step_frame();
    }
    assert_eq!(retried.driven_energy(), straight.driven_energy());
    assert_eq!(
        retried.state.positions, straight.state.positions,
        "the same frames to the bit"
    );
}

/// After a raise, the springs a cheaper budget left stretched shorten without throwing the
/// cloth about: the flag at 10 substeps × 2 iterations holds about 26 J in springs up to 8 %
/// long (0.1 J at 40 × 10); at 80 × 20 that energy came out as motion within a frame, 18 J of
/// kinetic energy against 1 J released or supplied, and the stability rule stopped the bake.
/// Settled frames cap the kinetic energy at what gravity, the wind and the frame's start give.
#[test]
fn a_raised_budget_takes_out_the_stretch_a_cheaper_one_left_without_throwing_the_cloth() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/flag.json");
    let scene = Scene::load(&path).expect("the flag");
    let mut sim = drape::sim::Simulation::new(&scene).unwrap();
    let initial = sim.energy();
    sim.set_budget(10, 2, 1);
    for _ in 0..26 {
        sim.step_frame();
    }
    let stretched = sim.energy().elastic;
    sim.set_budget(80, 20, 1);
    for frame in 0..6 {
        if frame < drape::bake::budget::SETTLE_FRAMES {
            sim.settle_frame();
        }
        sim.step_frame();
        let why = drape::sim::metrics::instability(
            &sim.state,
            &sim.constraint_error(),
            &sim.energy(),
            &initial,
            sim.driven_energy() + sim.rounding_energy(),
            sim.integrating(),
        );
        assert!(
            why.is_none(),
            "frame {} after the raise: {why:?}",
            frame + 1
        );
    }
    let settled = sim.energy().elastic;
    assert!(
        settled < 0.25 * stretched,
        "the springs shortened: {stretched:.2} J → {settled:.2} J"
    );
}

/// Scene P with its substeps and iterations left to targets of 10 % strain and 5 mm: every frame
/// meets both, against the mannequin's own mesh too. (With the clock restored in the wrong
/// substeps after a retry, the mannequin ran frames behind the cloth, and from frame 41 the
/// cloth sat up to 45 mm inside its arms at every budget.)
#[test]
fn the_poncho_meets_its_targets_in_every_frame_with_nothing_inside_the_mannequin() {
    let dir = common::temp_dir();
    let mut scene = common::scene_p(dir.path(), 60);
    scene.substeps = None;
    scene.timestep = None;
    scene.iterations_given = false;
    scene.accuracy = Some(drape::scene::AccuracySpec {
        max_strain: Some(0.10),
        max_penetration: Some(0.005),
        max_shear: None,
    });
    let report = run(&scene);
    let budget = report.budget.as_ref().unwrap();
    assert!(
        budget.per_frame.iter().any(|f| f.attempts > 1),
        "some frame is simulated again"
    );
    assert!(
        budget.met,
        "worst strain {}, deepest {} m",
        budget.max_strain_reached, budget.deepest_penetration_reached
    );
    for m in &report.worst_mesh_penetrations {
        assert_eq!(m.penetration.inside, 0, "inside {}'s mesh", m.character);
    }
}

#[test]
fn a_frame_the_stability_rule_rejects_is_simulated_again_at_a_higher_budget() {
    // A sheet hanging still from its top row with stiff shear springs: at the ladder's cheapest
    // budget (5 substeps × 2 iterations) its first frame gains more kinetic energy than gravity
    // released (the stability rule of scenes.md). That frame is simulated again higher up, as a
    // missed target would be, instead of ending the bake.
    let pins: Vec<String> = (0..12).map(|i| format!("[{i}, 0]")).collect();
    let scene = common::scene(&format!(
        r#"{{ "frames": 10, "backend": "cpu", "accuracy": {{ "max_shear": 2.0 }},
              "output": {{ "obj": false, "gltf": "none" }},
              "garments": [{{ "resolution": [12, 8], "size": [1.2, 0.8], "rotation": [90, 0, 0],
                              "position": [0, 1.2, 0], "pins": [{}],
                              "stiffness": {{ "stretch": 10000, "shear": 10000 }} }}] }}"#,
        pins.join(", ")
    ));
    let report = run(&scene);
    assert!(
        report.stable && report.failure.is_none(),
        "{:?}",
        report.failure
    );
    let b = report.budget.as_ref().unwrap();
    assert!(b.met);
    let first = &b.per_frame[0];
    assert!(
        first.attempts > 1 && first.why.starts_with("the frame went unstable"),
        "{first:?}"
    );
}

/// A 32 × 32 sheet dropped from 2 m onto a ball 0.2 m across at 24 fps, caught at its middle
/// while the rest falls on: at drape's default budget (10 substeps × 10 iterations a frame) a
/// spring passes 100 % at frame 18 (on either backend). `budget` is inserted as top-level
/// fields.
fn dropped_on_a_ball(backend: &str, budget: &str) -> String {
    format!(
        r#"{{ "fps": 24, "frames": 30, "backend": "{backend}"{budget},
              "output": {{ "gltf": "none" }},
              "garments": [{{ "name": "sheet", "resolution": [32, 32], "size": [1.2, 1.2],
                              "position": [0, 2, 0] }}],
              "colliders": [{{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.1 }}] }}"#
    )
}

/// A scene that leaves drape its budget does not stop where a frame goes unstable at it: that
/// frame is simulated again at the next level up, the bake is whole, and it says so. Every
/// frame before it is the one the same budget given in the scene bakes (which stops there), and
/// stopped after the raise and resumed, the bake is the same. A scene that gives its budget
/// keeps it and stops.
#[test]
fn a_budget_left_to_drape_takes_a_frame_that_goes_unstable_again_at_a_larger_one() {
    left_to_drape_takes_an_unstable_frame_again("cpu");
}

/// The same on the GPU backend (lavapipe here and in CI), which puts the frame's start back on
/// the device at the larger budget.
#[test]
fn on_the_gpu_a_budget_left_to_drape_takes_an_unstable_frame_again() {
    if common::gpu_context().is_none() {
        return;
    }
    left_to_drape_takes_an_unstable_frame_again("gpu");
}

/// See [`a_budget_left_to_drape_takes_a_frame_that_goes_unstable_again_at_a_larger_one`], on
/// `backend`.
fn left_to_drape_takes_an_unstable_frame_again(backend: &str) {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "left.json", &dropped_on_a_ball(backend, ""));
    let given = r#", "substeps": 10, "solver": { "iterations": 10 }"#;
    common::write(d, "given.json", &dropped_on_a_ball(backend, given));
    // `drape inspect` says which of the two leaves drape its budget.
    for (file, left) in [("left.json", true), ("given.json", false)] {
        let out = common::drape(d, &["inspect", file]);
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert_eq!(
            text.contains("budget left to drape"),
            left,
            "{file}: {text}"
        );
    }
    let fixed = common::drape(d, &["bake", "given.json", "--out", "fixed"]);
    assert_eq!(fixed.status.code(), Some(1), "{}", common::stderr(&fixed));
    let left = common::drape(d, &["bake", "left.json", "--out", "left"]);
    let err = common::stderr(&left);
    assert_eq!(left.status.code(), Some(0), "{err}");
    assert!(err.contains("went unstable at the scene's budget"), "{err}");
    let report = |out: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(d.join(out).join("report.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let (fixed, left) = (report("fixed"), report("left"));
    assert_eq!(fixed["budget"], serde_json::Value::Null);
    let failed = fixed["failure"]["frame"].as_u64().unwrap();
    assert_eq!(left["stable"], true);
    assert_eq!(left["frames_baked"], 30);
    let budget = &left["budget"];
    assert_eq!(budget["kind"], "stability");
    assert_eq!(budget["levels"][0], serde_json::json!([10, 10]));
    let frames = budget["per_frame"].as_array().unwrap();
    let retried: Vec<u64> = (frames.iter())
        .filter(|f| f["attempts"].as_u64().unwrap() > 1)
        .map(|f| f["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(retried.first(), Some(&failed), "{frames:?}");
    // Raised by substeps: what the scene leaves out first.
    let raised = &frames[failed as usize - 1];
    assert!(raised["substeps"].as_u64().unwrap() > 10, "{raised}");
    assert_eq!(raised["iterations"], 10);
    for f in &frames[..failed as usize - 1] {
        assert_eq!((&f["substeps"], &f["iterations"]), (&10.into(), &10.into()));
    }
    let obj = |out: &str, f: u64| std::fs::read(d.join(format!("{out}/obj/sheet_{f:04}.obj")));
    for f in 1..failed {
        assert_eq!(
            obj("fixed", f).unwrap(),
            obj("left", f).unwrap(),
            "frame {f}"
        );
    }
    // Stopped two frames after the raise, and resumed.
    let until = (failed + 2).to_string();
    let first = common::drape(
        d,
        &["bake", "left.json", "--out", "parts", "--until", &until],
    );
    assert_eq!(first.status.code(), Some(0), "{}", common::stderr(&first));
    let rest = common::drape(d, &["bake", "left.json", "--out", "parts", "--resume"]);
    assert_eq!(rest.status.code(), Some(0), "{}", common::stderr(&rest));
    let parts = report("parts");
    assert_eq!(parts["frames_hash"], left["frames_hash"]);
    assert_eq!(parts["budget"]["per_frame"], left["budget"]["per_frame"]);
}

/// A stable bake that leaves drape its budget gives the frames of the same budget given in the
/// scene, every frame at it once.
#[test]
fn a_stable_bake_that_leaves_drape_its_budget_is_the_bake_at_that_budget() {
    let sheet = |budget: &str| {
        format!(
            r#"{{ "frames": 20, "backend": "cpu"{budget}, "output": {{ "obj": false, "gltf": "none" }},
                  "garments": [{{ "resolution": [16, 16], "size": [1, 1], "pins": [[0, 0], [-1, 0]] }}] }}"#
        )
    };
    let left = run(&common::scene(&sheet("")));
    let given = run(&common::scene(&sheet(
        r#", "substeps": 10, "solver": { "iterations": 10 }"#,
    )));
    assert_eq!(left.frames_hash, given.frames_hash);
    assert!(given.budget.is_none());
    let b = left.budget.as_ref().unwrap();
    assert_eq!(b.kind, drape::report::BudgetKind::Stability);
    assert!(
        (b.per_frame.iter()).all(|f| (f.substeps, f.iterations, f.attempts) == (10, 10, 1)),
        "{:?}",
        b.per_frame
    );
    assert!(
        left.warnings.iter().all(|w| !w.contains("unstable")),
        "{:?}",
        left.warnings
    );
}

/// A scene that does not integrate (scene E: a sheet enlarged 5 × relaxing to its rest shape)
/// leaves the stability rule nothing to judge by its strain: left drape its substeps and
/// iterations, it bakes at its own budget, once a frame, like the same budget given.
#[test]
fn a_scene_that_does_not_integrate_keeps_its_budget_left_to_drape() {
    let sheet = |budget: &str| {
        common::scene(&format!(
            r#"{{ "frames": 3, "integrator": "none", "gravity": [0, 0, 0], "backend": "cpu"{budget},
                  "output": {{ "obj": false, "gltf": "none" }},
                  "garments": [{{ "resolution": [12, 12], "size": [1, 1], "initial_stretch": 5 }}] }}"#
        ))
    };
    let left = run(&sheet(""));
    let given = run(&sheet(
        r#", "substeps": 10, "solver": { "iterations": 10 }"#,
    ));
    assert!(left.stable && given.stable);
    assert_eq!(left.frames_hash, given.frames_hash);
    let b = left.budget.as_ref().unwrap();
    assert!(
        (b.per_frame.iter()).all(|f| (f.substeps, f.iterations, f.attempts) == (10, 10, 1)),
        "{:?}",
        b.per_frame
    );
}

/// A checkpoint of a bake that left drape its iterations does not resume a bake that gives
/// them (the same number, but a budget that stays fixed): the two bakes differ from the first
/// frame that goes unstable.
#[test]
fn a_checkpoint_of_a_budget_left_to_drape_does_not_resume_a_fixed_one() {
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(d, "left.json", &dropped_on_a_ball("cpu", ""));
    let first = common::drape(d, &["bake", "left.json", "--out", "out", "--until", "3"]);
    assert_eq!(first.status.code(), Some(0), "{}", common::stderr(&first));
    let args = [
        "bake",
        "left.json",
        "--out",
        "out",
        "--resume",
        "--iterations",
        "10",
    ];
    let fixed = common::drape(d, &args);
    let err = common::stderr(&fixed);
    assert_eq!(fixed.status.code(), Some(2), "{err}");
    assert!(err.contains("solver.iterations_left_to_drape"), "{err}");
}
