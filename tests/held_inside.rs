//! Held garment particles (pins, attachments) inside a character's mesh are counted apart from
//! the free ones: a 10 cm box slides along a sheet's pinned top edge, which no solver moves, so
//! the pinned particles inside the box at each frame are known from the geometry alone. The
//! report counts them per frame in `held_mesh_penetrations_per_frame`, their depth is the
//! distance to the box's nearest face, the free count stays its own, and the bake warns; a box
//! that passes behind the sheet leaves the count at zero and no warning. The box is written
//! flat-shaded (every face its own vertices), the case that once fooled the free count.

mod common;

use common::{cuboid, flat_shaded, write_obj};
use glam::Vec3;

const FRAMES: usize = 30;

/// The sheet's pinned top edge: 20 particles from x = −0.2 to 0.2 at y = 1, z = 0.
fn pinned() -> Vec<Vec3> {
    (0..20)
        .map(|i| Vec3::new(-0.2 + 0.4 * i as f32 / 19.0, 1.0, 0.0))
        .collect()
}

/// The box at sequence frame `k` (from 0): 10 cm wide, from y = 0.99 up, its centre sliding
/// from x = −0.3 to 0.3 and set `behind` metres back in z.
fn the_box(k: usize, behind: f32) -> (Vec3, Vec3) {
    let c = -0.3 + 0.6 * k as f32 / (FRAMES - 1) as f32;
    (
        Vec3::new(c - 0.05, 0.99, behind - 0.05),
        Vec3::new(c + 0.05, 1.09, behind + 0.05),
    )
}

/// How many `points` lie inside the box `(lo, hi)` and the deepest one's distance to its
/// nearest face.
fn inside((lo, hi): (Vec3, Vec3), points: &[Vec3]) -> (u64, f32) {
    let depths: Vec<f32> = points
        .iter()
        .map(|p| (*p - lo).min(hi - *p).min_element())
        .filter(|&d| d > 0.0)
        .collect();
    (
        depths.len() as u64,
        depths.iter().fold(0.0, |a, &d| a.max(d)),
    )
}

/// Bakes the pinned sheet under the box set `behind` metres back; returns the report.
fn bake(behind: f32) -> serde_json::Value {
    let dir = common::temp_dir();
    std::fs::create_dir(dir.path().join("box")).unwrap();
    for k in 0..FRAMES {
        let (lo, hi) = the_box(k, behind);
        // Flat-shaded, as many exports write a hard-edged prop: no two faces share a vertex.
        let (v, t) = cuboid(lo, hi);
        let (v, t) = flat_shaded(&v, &t);
        let path = dir.path().join(format!("box/frame_{:04}.obj", k + 1));
        write_obj(&path, &v, &t);
    }
    let pins: Vec<String> = (0..20).map(|i| format!("[{i}, 0]")).collect();
    let scene = format!(
        r#"{{ "frames": {FRAMES}, "substeps": 20,
             "solver": {{ "kind": "rbgs", "iterations": 10, "contact_passes": 5 }},
             "garments": [{{ "name": "cloth", "resolution": [20, 20], "size": [0.4, 0.4],
                             "position": [0, 0.8, 0], "rotation": [90, 0, 0],
                             "stiffness": {{ "stretch": 10000, "bend": 20 }},
                             "pins": [{}] }}],
             "characters": [{{ "name": "box", "file": "box", "sequence_fps": 60, "scale": 1 }}],
             "output": {{ "gltf": "none", "obj": false }} }}"#,
        pins.join(", ")
    );
    common::write(dir.path(), "scene.json", &scene);
    let out = common::drape(
        dir.path(),
        &["bake", "scene.json", "--out", "out", "--backend", "cpu"],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let report = std::fs::read_to_string(dir.path().join("out/report.json")).unwrap();
    serde_json::from_str(&report).unwrap()
}

#[test]
fn pinned_particles_inside_a_character_are_counted_per_frame_and_warned_of() {
    let report = bake(0.0);
    let frames = report["held_mesh_penetrations_per_frame"]
        .as_array()
        .unwrap();
    assert_eq!(frames.len(), FRAMES);
    let mut most = 0;
    for (n, frame) in frames.iter().enumerate() {
        // Baked frame n + 1 is the scene at time (n + 1) / fps: the sequence's frame n + 1.
        let (count, deepest) = inside(the_box((n + 1).min(FRAMES - 1), 0.0), &pinned());
        assert_eq!(frame["inside"][0], count, "frame {}", frame["frame"]);
        let measured = frame["deepest_m"][0].as_f64().unwrap() as f32;
        assert!(
            (measured - deepest).abs() < 1e-4,
            "frame {}: {measured} m deep, the box says {deepest} m",
            frame["frame"]
        );
        most = most.max(count);
    }
    assert!(most >= 4, "the box never covered the edge");
    assert_eq!(report["worst_held_mesh_penetrations"][0]["inside"], most);
    let free = &report["worst_mesh_penetrations"][0]["inside"];
    assert!(
        free.as_u64().unwrap() < most,
        "free particles counted as held: {free}"
    );
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .unwrap()
            .contains(&format!("up to {most} pinned or attached"))),
        "no warning of the held particles inside: {warnings:?}"
    );
}

#[test]
fn pinned_particles_a_character_passes_behind_are_not_counted() {
    let report = bake(0.1);
    let frames = report["held_mesh_penetrations_per_frame"]
        .as_array()
        .unwrap();
    assert_eq!(frames.len(), FRAMES);
    assert!(frames.iter().all(|f| f["inside"][0] == 0), "{frames:?}");
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        !warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("pinned or attached")),
        "{warnings:?}"
    );
}
