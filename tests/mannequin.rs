//! drape's own mannequin: the committed frames are exactly what the generator writes (so they
//! cannot rot), they import through assimp as frame sequences, and the clips do what they say:
//! a 1.8 m figure whose feet stay on the floor, who raises the arms overhead, and who ends seated
//! on the stool.

mod common;

use drape::character::{mannequin, Character, CharacterOptions};
use std::path::Path;

const DIR: &str = "characters/mannequin";

fn clip(name: &str) -> Character {
    let options = CharacterOptions {
        sequence_fps: Some(mannequin::FPS),
        ..Default::default()
    };
    let duration = mannequin::CLIPS.iter().find(|c| c.0 == name).unwrap().1;
    let frames = (duration * 60.0).round() as usize + 1;
    Character::load(&Path::new(DIR).join(name), &options, 60.0, frames).expect("mannequin loads")
}

#[test]
fn committed_frames_match_the_generator() {
    let files = mannequin::files();
    assert_eq!(files.len(), 19 + 25 + 49 + 1);
    for (name, text) in files {
        let committed = std::fs::read_to_string(Path::new(DIR).join(&name))
            .unwrap_or_else(|e| panic!("{DIR}/{name}: {e}; run `drape mannequin` and commit"));
        assert!(
            committed == text,
            "{DIR}/{name} differs from the generator: run `drape mannequin`"
        );
    }
}

#[test]
fn the_figure_stands_raises_its_arms_and_sits_on_the_stool() {
    for name in ["raise_arms", "sit"] {
        let c = clip(name);
        assert!(c.same_topology());
        let (lo, hi) = c.bounds(0);
        assert!(
            (hi.y - lo.y - 1.82).abs() < 0.03,
            "{name}: standing height {}",
            hi.y - lo.y
        );
        for k in 0..c.frames.len() {
            assert!(
                c.bounds(k).0.y > -0.01,
                "{name} frame {k}: a foot goes through the floor"
            );
        }
        let step = common::largest_step(&c);
        assert!(
            step > 0.001 && step < 0.05,
            "{name}: largest step {step} m at 60 fps"
        );
    }
    let arms = clip("raise_arms");
    assert!(
        arms.bounds(arms.frames.len() - 1).1.y > 2.0,
        "hands overhead at the end"
    );

    // Seated: over the stool's footprint, the body rests on the seat (not in it, not above it).
    let sit = clip("sit");
    let end = sit.frame(sit.frames.len() - 1);
    let [cx, cz] = mannequin::STOOL_CENTER;
    let lowest = end
        .iter()
        .filter(|v| (v.x - cx).hypot(v.z - cz) < mannequin::STOOL_RADIUS * 0.8)
        .map(|v| v.y)
        .fold(f32::INFINITY, f32::min);
    let seat = mannequin::STOOL_HEIGHT;
    assert!(
        lowest > seat - 0.01 && lowest < seat + 0.03,
        "lowest point over the stool {lowest}, seat {seat}"
    );
}
