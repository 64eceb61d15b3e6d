//! The robot's shipped cape (`scenes/robot_cape_run.json`) through two of its file's clips that no
//! shipped scene uses, as a user would put them on it:
//! - **Death**: the robot falls on its back onto the cape and lies there, held at its last pose.
//!   The cape is pressed between its back and the floor (`collide::INTO_COLLIDER`): before such
//!   cloth was held, the skin pushed it under the floor and out sideways in turn, and the bake
//!   stopped as unstable at frame 1016. It bakes whole now, with no particle under the floor;
//!   where he lies he sinks into the floor, and the bake warns that the cape is inside him there.
//! - **Dance**: the robot's body passes through itself where the cape is attached, and the
//!   attached particles go inside it while the skin holds their free neighbours out. Those
//!   springs stretch past 100 % whatever the solver does; the bake stopped as unstable at frame
//!   1034. The stability rule now leaves springs with a held end out: the bake goes on,
//!   counts the frames in `forced_strain_per_frame` and warns, and every spring between free
//!   particles stays within 100 %.
//! - A clip that does not loop (Death, Sitting) looped with `loop: true` jumps back to its first
//!   pose at every loop; loading it warns, and a looping clip (Running, Walking) does not.
//! - `scenes/poncho_walk.json` at 24 fps keeps its substep (the shipped character scenes give
//!   `timestep`); with 20 substeps a frame, as at 60 fps, its landing stops the bake, and the
//!   bake's warning names the substep and what to raise.

use drape::bake::{bake, BakeOptions};
use drape::report::Report;
use std::path::Path;

mod common;

/// Bakes the robot's cape with `clip` (looping or holding its last pose) for `frames` frames
/// after its pre-roll, on the CPU, without exports.
fn cape_with(clip: &str, looping: bool, frames: u32, dir: &Path) -> Report {
    bake_cape(&cape_scene(clip, looping, frames), dir)
}

/// The robot's cape scene with `clip` for `frames` frames, on the CPU, without exports.
fn cape_scene(clip: &str, looping: bool, frames: u32) -> drape::scene::Scene {
    let mut scene = drape::scene::Scene::load(Path::new("scenes/robot_cape_run.json")).unwrap();
    scene.frames = frames;
    scene.characters[0].clip = Some(clip.into());
    scene.characters[0].looping = looping;
    scene.output.obj = false;
    scene.output.gltf = drape::scene::GltfOutput::None;
    scene.backend = drape::scene::BackendKind::Cpu;
    scene
}

fn bake_cape(scene: &drape::scene::Scene, dir: &Path) -> Report {
    let clip = scene.characters[0].clip.clone().unwrap();
    let options = BakeOptions {
        shell_cache: Some(dir.join("cache")),
        ..common::bake_options(&dir.join(clip))
    };
    bake(scene, &options).expect("bake").report
}

#[test]
fn the_robot_falling_on_its_cape_presses_it_onto_the_floor_and_bakes_whole() {
    let dir = common::temp_dir();
    let scene = cape_scene("Death", false, 60);
    let report = bake_cape(&scene, dir.path());
    assert!(report.stable, "{:?}", report.failure);
    assert_eq!(report.frames_baked, 60);
    // The floor (collider 0): no particle's centre ever under it (before, they went 5 mm
    // under it by frame 1016).
    let floor = &report.worst_penetrations[0];
    assert_eq!(floor.collider, 0);
    assert_eq!(floor.penetration.inside, 0, "{floor:?} under the floor");
    // The cape lies under him from about frame 1018 on: pressed, not torn.
    let worst = report.worst_frame.as_ref().unwrap();
    assert!(worst.max_stretch < 1.0, "{worst:?}");
    assert!(report.forced_strain_per_frame.is_empty());
    // Lying, he sinks into the floor (the clip was not made on it): the cape pressed under him
    // is inside him there, and the bake says why.
    let sunk = (report.character_in_colliders_per_frame.iter())
        .map(|f| f.deepest_m[0])
        .fold(0.0f32, f32::max);
    assert!(sunk > 0.05, "sank {sunk} m");
    // Each frame's depth is the lowest vertex's below the floor (y = 0), as loaded apart.
    let baked = scene.with_preroll();
    let (path, options, frames) = drape::bake::characters::as_baked(&baked, 0);
    let robot = drape::character::Character::load(&path, &options, baked.fps, frames).unwrap();
    let per_frame = &report.character_in_colliders_per_frame;
    assert_eq!(per_frame.len(), robot.frames.len() - 1);
    for (b, f) in per_frame.iter().enumerate() {
        // Baked frame b shows character frame b + 1.
        let lowest = robot.frames[b + 1]
            .iter()
            .map(|v| v.y)
            .fold(f32::INFINITY, f32::min);
        let depth = (-lowest).max(0.0);
        assert!(
            (f.deepest_m[0] - depth).abs() < 1e-4,
            "frame {}: {} against {depth}",
            f.frame,
            f.deepest_m[0]
        );
    }
    let warned = (report.warnings.iter())
        .any(|w| w.starts_with("character robot: its mesh sinks more than 5.0 mm"));
    assert!(warned, "{:#?}", report.warnings);
}

#[test]
fn the_robot_dancing_through_its_attached_cape_bakes_whole_and_says_where() {
    let dir = common::temp_dir();
    let report = cape_with("Dance", true, 45, dir.path());
    assert!(report.stable, "{:?}", report.failure);
    assert_eq!(report.frames_baked, 45);
    let forced = &report.forced_strain_per_frame;
    assert!(!forced.is_empty(), "no frame with a forced spring");
    // The worst frame's strain is a forced spring's, past 100 %: the largest of the list.
    let worst = report.worst_frame.as_ref().unwrap();
    let most = forced
        .iter()
        .max_by(|a, b| a.strain.total_cmp(&b.strain))
        .unwrap();
    assert_eq!(
        (most.frame, most.strain),
        (worst.frame, worst.max_strain),
        "{forced:?}"
    );
    // Its cause is in the report: held particles inside the robot's mesh in those frames.
    let held: Vec<u32> = (report.held_mesh_penetrations_per_frame.iter())
        .filter(|f| f.inside.iter().any(|&n| n > 0))
        .map(|f| f.frame)
        .collect();
    assert!(
        forced.iter().all(|f| held.contains(&f.frame)),
        "forced {forced:?}, held inside in {held:?}"
    );
    let warned = report.warnings.iter().any(|w| {
        w.contains("springs from pinned or attached particles were stretched past 100 %")
            && w.contains(&format!("from frame {}", forced[0].frame))
    });
    assert!(warned, "{:#?}", report.warnings);
    // Its feet are a few millimetres in the floor, but the particles deep inside it are caught
    // where its body passes through itself: no warning blames the floor.
    let floor = report
        .warnings
        .iter()
        .any(|w| w.contains("into the scene's colliders"));
    assert!(!floor, "{:#?}", report.warnings);
}

#[test]
fn a_clip_that_does_not_loop_warns_when_looped_and_a_walk_does_not() {
    use drape::character::{Asset, Character, CharacterOptions};
    let path = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    let asset = Asset::open(path).unwrap();
    let warned = |clip: &str, looping: bool| {
        let options = CharacterOptions {
            clip: Some(clip.into()),
            looping,
            scale: 0.2,
            ..Default::default()
        };
        // 240 frames at 60 fps, 4 s: every clip here loops at least once (Dance, the longest,
        // lasts 3.33 s).
        let c = Character::from_asset(&asset, path, &options, 60.0, 240).unwrap();
        let duration = c.clips.iter().find(|(n, _)| n == clip).unwrap().1;
        assert!(duration < 4.0, "{clip} lasts {duration} s");
        c.warnings
            .into_iter()
            .find(|w| w.contains("does not end where it starts"))
    };
    for clip in ["Death", "Sitting"] {
        let w = warned(clip, true).unwrap_or_else(|| panic!("{clip} looped: no warning"));
        assert!(
            w.contains(&format!("clip \"{clip}\"")) && w.contains("`loop: false`"),
            "{w}"
        );
        assert_eq!(warned(clip, false), None, "{clip} held");
    }
    for clip in ["Running", "Walking", "Dance"] {
        assert_eq!(warned(clip, true), None, "{clip}");
    }
}

/// `scenes/poncho_walk.json` at `fps` for `frames` frames, on the CPU, without exports.
fn poncho_walk_at(fps: f32, frames: u32, dir: &Path, name: &str) -> (drape::scene::Scene, Report) {
    let mut scene = drape::scene::Scene::load(Path::new("scenes/poncho_walk.json")).unwrap();
    scene.fps = fps;
    scene.frames = frames;
    scene.output.obj = false;
    scene.output.gltf = drape::scene::GltfOutput::None;
    scene.backend = drape::scene::BackendKind::Cpu;
    let options = BakeOptions {
        shell_cache: Some(dir.join("cache")),
        ..common::bake_options(&dir.join(name))
    };
    (scene.clone(), bake(&scene, &options).expect("bake").report)
}

#[test]
fn a_shipped_scene_at_24_fps_keeps_its_substep_and_a_longer_one_is_named_when_it_stops() {
    // The shipped character scenes give `timestep` (1/1200 s), not substeps per frame, so a
    // scene made at 60 fps keeps its substep at a film's 24: 50 substeps a frame. The poncho
    // lands on his head in frame 8 at 24 fps; with the 20 substeps a frame it had at 60 fps
    // (2.08 ms each) its 5 iterations do not carry the springs' pull across it, and the bake
    // stops there, with a warning that names the substep and what to raise.
    let dir = common::temp_dir();
    let (_, at_60) = poncho_walk_at(60.0, 1, dir.path(), "60");
    assert_eq!(at_60.substeps, 20);
    let (mut scene, report) = poncho_walk_at(24.0, 14, dir.path(), "24");
    assert!(report.stable, "{:?}", report.failure);
    assert_eq!(report.substeps, 50);
    let step = 1.0 / 1200.0;
    assert!(
        (report.step_seconds - step).abs() < 1e-9,
        "{}",
        report.step_seconds
    );
    assert!(
        (at_60.step_seconds - step).abs() < 1e-9,
        "{}",
        at_60.step_seconds
    );
    assert!(report.warnings.iter().all(|w| !w.contains("substeps of")));

    scene.timestep = None;
    scene.substeps = Some(20);
    let options = BakeOptions {
        shell_cache: Some(dir.path().join("cache")),
        ..common::bake_options(&dir.path().join("24_long"))
    };
    let report = bake(&scene, &options).expect("bake").report;
    let failure = report
        .failure
        .as_ref()
        .expect("the long substeps stop the bake");
    assert!(failure.frame <= 14, "{failure:?}");
    let warned = (report.warnings.iter())
        .find(|w| w.contains("substeps of"))
        .expect("the substep is named");
    assert!(
        warned.contains("substeps of 2.08 ms (20 a frame at 24 fps) with 5 solver iterations"),
        "{warned}"
    );
}
