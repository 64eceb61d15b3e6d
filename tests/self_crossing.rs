//! A character passing through itself is counted per frame (`character_crossings_per_frame`):
//! a character of two 10 cm boxes in one mesh, the second sliding along x through the first.
//! The count of each frame must equal the pairs of the two boxes' triangles that intersect,
//! found here by brute force with a segment–triangle test of the test's own; it is positive
//! exactly in the frames the boxes overlap. Boxes that overlap from the start and move
//! together (parts built into each other, as a robot's at its joints) count nothing. The bake
//! warns only when garment particles were deeper than half a shell radius inside the mesh in
//! frames it crossed itself. Two garments modelled through each other are warned of before any
//! simulation, with the pairs of their triangles a brute force finds.

mod common;

use common::{cuboid, write_obj};
use glam::{DVec3, Vec3};

const FRAMES: usize = 30;

/// The sliding box's centre x at sequence frame `k` (from 0): −0.3 to 0.3 m, never within
/// 2 cm of touching the fixed box (|x| = 0.1), so each frame either overlaps it or not.
fn slide(k: usize) -> f32 {
    -0.3 + 0.6 * k as f32 / (FRAMES - 1) as f32
}

/// The character at sequence frame `k`: the fixed box around the origin and one moved by
/// `offset(k)`, 2 cm higher and 1.3 cm further back (so no two faces are coplanar).
fn boxes(k: usize, offset: impl Fn(usize) -> f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut v, mut t) = cuboid(Vec3::splat(-0.05), Vec3::splat(0.05));
    let shift = Vec3::new(offset(k), 0.02, 0.013);
    let (w, u) = cuboid(Vec3::splat(-0.05) + shift, Vec3::splat(0.05) + shift);
    let base = v.len() as u32;
    v.extend(w);
    t.extend(u.into_iter().map(|tri| tri.map(|i| i + base)));
    (v, t)
}

/// True when segment `p`–`q` passes through the interior of triangle `tri` (f64).
fn segment_through(p: DVec3, q: DVec3, tri: [DVec3; 3]) -> bool {
    let [a, b, c] = tri;
    let n = (b - a).cross(c - a);
    let (dp, dq) = ((p - a).dot(n), (q - a).dot(n));
    if dp * dq >= 0.0 {
        return false;
    }
    let x = p + (q - p) * (dp / (dp - dq));
    // Inside when x is on the inner side of all three edges.
    let side = |e0: DVec3, e1: DVec3| (e1 - e0).cross(x - e0).dot(n) > 0.0;
    side(a, b) && side(b, c) && side(c, a)
}

/// The pairs of one box's triangles and the other's that intersect: an edge of either through
/// the other, by brute force over all pairs.
fn crossing_pairs(v: &[Vec3], t: &[[u32; 3]]) -> usize {
    let corners = |tri: &[u32; 3]| tri.map(|i| v[i as usize].as_dvec3());
    let through =
        |s: [DVec3; 3], r: [DVec3; 3]| (0..3).any(|e| segment_through(s[e], s[(e + 1) % 3], r));
    let (first, second) = t.split_at(t.len() / 2);
    let mut count = 0;
    for s in first {
        for r in second {
            let (s, r) = (corners(s), corners(r));
            count += usize::from(through(s, r) || through(r, s));
        }
    }
    count
}

/// Bakes a 30 cm sheet pinned along `pins_at` (its top edge's centre) by the two boxes, the
/// second moved by `offset`; returns the report.
fn bake(offset: fn(usize) -> f32, pins_at: Vec3) -> serde_json::Value {
    let dir = common::temp_dir();
    std::fs::create_dir(dir.path().join("boxes")).unwrap();
    for k in 0..FRAMES {
        let (v, t) = boxes(k, offset);
        write_obj(
            &dir.path().join(format!("boxes/frame_{:04}.obj", k + 1)),
            &v,
            &t,
        );
    }
    let pins: Vec<String> = (0..10).map(|i| format!("[{i}, 0]")).collect();
    let scene = format!(
        r#"{{ "frames": {FRAMES}, "substeps": 10,
             "solver": {{ "kind": "rbgs", "iterations": 5, "contact_passes": 2 }},
             "garments": [{{ "name": "cloth", "resolution": [10, 10], "size": [0.3, 0.3],
                             "position": [{}, {}, {}], "rotation": [90, 0, 0],
                             "stiffness": {{ "stretch": 10000, "bend": 20 }},
                             "pins": [{}] }}],
             "characters": [{{ "name": "boxes", "file": "boxes", "sequence_fps": 60, "scale": 1 }}],
             "output": {{ "gltf": "none", "obj": false }} }}"#,
        pins_at.x,
        pins_at.y - 0.15,
        pins_at.z,
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

/// The report's count of the character's crossings through itself, per baked frame.
fn counted(report: &serde_json::Value) -> Vec<u64> {
    let frames = report["character_crossings_per_frame"].as_array().unwrap();
    assert_eq!(frames.len(), FRAMES);
    frames
        .iter()
        .map(|f| f["crossings"][0].as_u64().unwrap())
        .collect()
}

fn warned(report: &serde_json::Value) -> bool {
    let warnings = report["warnings"].as_array().unwrap();
    warnings
        .iter()
        .any(|w| w.as_str().unwrap().contains("passes through itself"))
}

#[test]
fn a_box_sliding_through_another_is_counted_in_the_frames_they_overlap() {
    // The sheet hangs 1 m away: nothing of it is inside the boxes, so no warning.
    let report = bake(slide, Vec3::new(1.0, 0.0, 0.0));
    let counts = counted(&report);
    let mut overlapping = 0;
    for (n, &count) in counts.iter().enumerate() {
        // Baked frame n + 1 is the scene at time (n + 1) / fps: the sequence's frame n + 1.
        let k = (n + 1).min(FRAMES - 1);
        let (v, t) = boxes(k, slide);
        assert_eq!(count as usize, crossing_pairs(&v, &t), "frame {}", n + 1);
        let overlaps = slide(k).abs() < 0.1;
        assert_eq!(count > 0, overlaps, "frame {}: {count} pairs", n + 1);
        overlapping += usize::from(overlaps);
    }
    assert!(
        overlapping >= 8,
        "the boxes overlapped in {overlapping} frames"
    );
    assert!(!warned(&report), "{}", report["warnings"]);
}

#[test]
fn boxes_built_into_each_other_count_nothing_as_they_move_together() {
    let report = bake(|k| 0.04 + 0.001 * k as f32, Vec3::new(1.0, 0.0, 0.0));
    let (v, t) = boxes(0, |_| 0.04);
    assert!(crossing_pairs(&v, &t) > 0, "the boxes do not overlap");
    assert!(
        counted(&report).iter().all(|&c| c == 0),
        "{:?}",
        counted(&report)
    );
}

#[test]
fn cloth_inside_where_the_character_crosses_itself_is_warned_of() {
    // The sheet's pinned edge runs through the fixed box, 1 cm above its floor (the sheet
    // hangs below it): held particles inside it in every frame, deeper than half the shell
    // radius (5 mm), among them the frames the sliding box passes through it.
    let report = bake(slide, Vec3::new(0.0, -0.04, 0.0));
    let crossed = counted(&report).iter().filter(|&&c| c > 0).count();
    assert!(crossed >= 8);
    let warnings = report["warnings"].as_array().unwrap();
    let warning = warnings
        .iter()
        .filter_map(|w| w.as_str())
        .find(|w| w.contains("passes through itself"))
        .unwrap_or_else(|| panic!("no warning: {warnings:?}"));
    assert!(
        warning.contains(&format!("in {crossed} frames"))
            && warning.contains(&format!("{crossed} of the")),
        "{warning}"
    );
}

/// Two 40 cm sheets of 5 × 5 particles: one level at 1 m, the other upright (turned 90° about
/// x) with its centre at `centre`.
fn two_sheets(centre: Vec3) -> Vec<drape::garment::Garment> {
    let scene = common::scene(&format!(
        r#"{{ "garments": [
             {{ "name": "level", "resolution": [5, 5], "size": [0.4, 0.4], "position": [0, 1, 0] }},
             {{ "name": "upright", "resolution": [5, 5], "size": [0.4, 0.4],
                "position": [{}, {}, {}], "rotation": [90, 0, 0] }}] }}"#,
        centre.x, centre.y, centre.z
    ));
    drape::garment::build_all(&scene, "test").unwrap()
}

#[test]
fn garments_modelled_through_each_other_are_warned_of_with_their_pairs() {
    // Through each other along a line off every lattice row of both (1.3 cm and 2 cm off): the
    // warning counts the pairs the brute force finds; moved 1 m away, nothing is said.
    let garments = two_sheets(Vec3::new(0.05, 1.02, 0.013));
    let (a, b) = (&garments[0], &garments[1]);
    assert_eq!(a.triangles.len(), b.triangles.len());
    let mut v: Vec<Vec3> = a.positions.clone();
    v.extend(&b.positions);
    let base = a.positions.len() as u32;
    let mut t = a.triangles.clone();
    t.extend(b.triangles.iter().map(|tri| tri.map(|i| i + base)));
    let expected = crossing_pairs(&v, &t);
    assert!(expected > 0);
    let warnings = drape::collide::crossings::between_warnings(&garments);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains(&format!(
            "garments level and upright: their surfaces pass through each other before any simulation, in {expected} pairs"
        )),
        "{warnings:?}"
    );
    let apart = two_sheets(Vec3::new(0.05, 2.02, 0.013));
    assert!(drape::collide::crossings::between_warnings(&apart).is_empty());
    // Each sheet alone is flat: no warning of its own.
    assert!(drape::collide::crossings::modelled_warnings(&garments).is_empty());
}
