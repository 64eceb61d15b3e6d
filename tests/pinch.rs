//! Cloth pinched where a body closes on itself (a hand against a hip, an arm against the side),
//! reduced to its core: two 5 cm slabs of one character close on a hanging sheet until their
//! faces are 1 cm or 5 mm apart, less than the cloth's thickness plus the two shells' radii
//! (their shells overlap through the cloth), hold it for ten frames and open again. Pushed out
//! of each side in turn, the cloth between them would be squeezed out sideways and tear (the
//! bake stopped as unstable at frame 9 or 10 before pinches were held); held, it bakes stable
//! on both backends, the cloth between the slabs stays where the slabs caught it, and none is
//! left inside them.
//!
//! Cloth pressed between a body and a collider, reduced the same way: a 20 cm block comes down
//! flush onto a sheet lying on the floor, rests on it, then slides 10 cm along the floor. Pushed
//! by the block's shell into the floor and back out by the floor in turn, the cloth was squeezed
//! out sideways and the bake stopped as unstable at frame 9; pressed, the floor keeps it above
//! itself and the block carries the cloth under it as it slides, on both backends.

mod common;

use common::{cuboid, read_obj, write_obj};
use glam::Vec3;

const FRAMES: usize = 30;

/// Where the slabs' inner faces are at frame `k` (from 0): ±6 cm closing to ±`gap`/2 over ten
/// frames, held for ten, opening over the last ten.
fn face(k: usize, gap: f32) -> f32 {
    let closed = if k < 20 {
        k.min(10) as f32 / 10.0
    } else {
        (FRAMES - k) as f32 / 10.0
    };
    0.06 + (gap / 2.0 - 0.06) * closed
}

/// The two slabs at frame `k`: 30 × 30 cm, 5 cm thick, either side of the plane z = 0.
fn slabs(k: usize, gap: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let f = face(k, gap);
    let (mut v, mut t) = cuboid(Vec3::new(-0.15, 0.65, -f - 0.05), Vec3::new(0.15, 0.95, -f));
    let (w, u) = cuboid(Vec3::new(-0.15, 0.65, f), Vec3::new(0.15, 0.95, f + 0.05));
    let base = v.len() as u32;
    v.extend(w);
    t.extend(u.iter().map(|tri| tri.map(|i| i + base)));
    (v, t)
}

/// True where the slabs' faces cover the sheet (a centimetre in from their edges).
fn between_the_slabs(p: Vec3) -> bool {
    p.x.abs() < 0.14 && p.y > 0.66 && p.y < 0.94
}

/// Bakes the sheet between slabs closing to `gap` on `backend`; checks it is stable, no
/// cloth is inside a slab, and the cloth between the faces moves less than `held` metres
/// while they hold it. Returns the most it moved there.
fn bake_pinch(gap: f32, backend: &str) -> f32 {
    let dir = common::temp_dir();
    std::fs::create_dir(dir.path().join("jaws")).unwrap();
    for k in 0..FRAMES {
        let (v, t) = slabs(k, gap);
        write_obj(
            &dir.path().join(format!("jaws/frame_{:04}.obj", k + 1)),
            &v,
            &t,
        );
    }
    let pins: Vec<String> = (0..20).map(|i| format!("[{i}, 0]")).collect();
    let scene = format!(
        r#"{{ "frames": {FRAMES}, "substeps": 20,
             "solver": {{ "kind": "rbgs", "iterations": 10, "contact_passes": 5 }},
             "particle_collisions": true,
             "garments": [{{ "name": "cloth", "resolution": [20, 20], "size": [0.4, 0.4],
                             "position": [0, 0.8, 0], "rotation": [90, 0, 0],
                             "stiffness": {{ "stretch": 10000, "bend": 20 }},
                             "pins": [{}] }}],
             "characters": [{{ "name": "jaws", "file": "jaws", "sequence_fps": 60, "scale": 1 }}],
             "output": {{ "gltf": "none" }} }}"#,
        pins.join(", ")
    );
    common::write(dir.path(), "scene.json", &scene);
    let out = common::drape(
        dir.path(),
        &["bake", "scene.json", "--out", "out", "--backend", backend],
    );
    let name = format!("slabs closing to {} mm on the {backend}", gap * 1000.0);
    assert!(out.status.success(), "{name}: {}", common::stderr(&out));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["stable"], true, "{name}");
    for (k, frame) in report["mesh_penetrations_per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let deepest = frame["deepest_m"][0].as_f64().unwrap();
        assert!(
            deepest <= 0.005,
            "{name}, frame {}: {deepest} m inside",
            k + 1
        );
    }
    // Frames 11 to 20 hold the slabs closed (OBJ frame k + 1 is character frame k).
    let obj = |k: usize| read_obj(&dir.path().join(format!("out/obj/cloth_{:04}.obj", k + 1))).0;
    let caught = obj(10);
    let mut moved = 0.0f32;
    for k in 11..20 {
        for (a, b) in caught.iter().zip(obj(k)) {
            if between_the_slabs(*a) {
                moved = moved.max(a.distance(b));
            }
        }
    }
    eprintln!("{name}: the cloth between the slabs moved at most {moved} m while held");
    moved
}

#[test]
fn cloth_pinched_between_two_closing_slabs_is_held_and_stays_stable() {
    for gap in [0.01, 0.005] {
        let moved = bake_pinch(gap, "cpu");
        assert!(moved < 0.001, "gap {gap}: moved {moved} m while held");
    }
}

#[test]
fn cloth_pinched_between_two_closing_slabs_is_held_on_the_gpu() {
    if common::gpu_context().is_none() {
        return;
    }
    let moved = bake_pinch(0.01, "gpu");
    assert!(moved < 0.001, "moved {moved} m while held");
}

/// The block's lower corner at sequence frame `k` (from 0): 20 × 10 × 20 cm, coming down from
/// 10 cm above the floor to rest on it over frames 0–9, resting until frame 19, sliding 10 cm
/// along x over frames 20–29 and resting again.
fn block(k: usize) -> Vec3 {
    let y = 0.1 * (1.0 - k.min(9) as f32 / 9.0);
    let x = 0.1 * (k.saturating_sub(20).min(10) as f32 / 10.0);
    Vec3::new(x - 0.1, y, -0.1)
}

/// Bakes a 40 cm sheet lying on the floor under the block on `backend`; checks that it is
/// stable and never below the floor, and returns how far the cloth that lay under the block's
/// middle moved while the block slid, against the 10 cm the block did.
fn bake_pressed(backend: &str) -> f32 {
    let dir = common::temp_dir();
    std::fs::create_dir(dir.path().join("block")).unwrap();
    for k in 0..40 {
        let lo = block(k);
        let (v, t) = cuboid(lo, lo + Vec3::new(0.2, 0.1, 0.2));
        write_obj(
            &dir.path().join(format!("block/frame_{:04}.obj", k + 1)),
            &v,
            &t,
        );
    }
    let scene = r#"{ "frames": 40, "substeps": 20,
         "solver": { "kind": "rbgs", "iterations": 10, "contact_passes": 5 },
         "particle_collisions": true,
         "garments": [{ "name": "cloth", "resolution": [20, 20], "size": [0.4, 0.4],
                        "position": [0, 0.01, 0],
                        "stiffness": { "stretch": 10000, "shear": 300, "bend": 20 } }],
         "characters": [{ "name": "block", "file": "block", "sequence_fps": 60 }],
         "colliders": [{ "kind": "plane" }],
         "output": { "gltf": "none" } }"#;
    common::write(dir.path(), "scene.json", scene);
    let out = common::drape(
        dir.path(),
        &["bake", "scene.json", "--out", "out", "--backend", backend],
    );
    let name = format!("a block pressing cloth onto the floor on the {backend}");
    assert!(out.status.success(), "{name}: {}", common::stderr(&out));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["stable"], true, "{name}");
    // OBJ frame k + 1 is sequence frame k: the block rests at frame 19 and has slid by 29.
    let obj = |k: usize| read_obj(&dir.path().join(format!("out/obj/cloth_{:04}.obj", k + 1))).0;
    // The floor keeps every particle (a sheet's vertices) at its contact radius, half the
    // default 5 mm thickness, or within a twentieth of it where the block presses it.
    let lowest = (0..40)
        .flat_map(obj)
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let radius = 0.0025;
    assert!(
        lowest >= radius * (1.0 - drape::collide::INTO_COLLIDER) - 1e-6,
        "{name}: a particle {lowest} m above the floor"
    );
    let (rest, slid) = (obj(19), obj(29));
    let under: Vec<f32> = (rest.iter().zip(&slid))
        .filter(|(a, _)| a.x.abs() < 0.05 && a.z.abs() < 0.05)
        .map(|(a, b)| b.x - a.x)
        .collect();
    assert!(!under.is_empty(), "{name}: no cloth under the block");
    let least = under.iter().copied().fold(f32::INFINITY, f32::min);
    eprintln!(
        "{name}: the cloth under the block moved {least}–{} m along x",
        under.iter().copied().fold(0.0, f32::max)
    );
    least
}

#[test]
fn cloth_pressed_between_a_block_and_the_floor_stays_above_it_and_moves_with_the_block() {
    let moved = bake_pressed("cpu");
    assert!(
        moved > 0.09,
        "the cloth under the block moved {moved} m of the block's 0.1"
    );
}

#[test]
fn cloth_pressed_between_a_block_and_the_floor_on_the_gpu() {
    if common::gpu_context().is_none() {
        return;
    }
    let moved = bake_pressed("gpu");
    assert!(
        moved > 0.09,
        "the cloth under the block moved {moved} m of the block's 0.1"
    );
}
