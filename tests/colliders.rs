//! Boxes and capsules: signed distances against hand-computed values, and cloth that comes to
//! rest on them stays outside (CPU; the GPU's agreement is in `gpu_parity.rs`).

mod common;

use drape::collide::{Collider, Shape};
use drape::sim::Simulation;
use glam::Vec3;

#[test]
fn signed_distances_of_box_and_capsule() {
    let boxed = Collider {
        shape: Shape::Box {
            center: Vec3::new(1.0, 0.0, 0.0),
            half: Vec3::new(0.5, 1.0, 2.0),
            rotation: glam::Quat::IDENTITY,
        },
        friction: 0.0,
        moved: Vec3::ZERO,
        swept: true,
    };
    // Outside a face, an edge and a corner; inside nearest the +X face.
    let cases = [
        (Vec3::new(2.0, 0.0, 0.0), 0.5, Vec3::X),
        (
            Vec3::new(1.0, 2.0, 3.0),
            2f32.sqrt(),
            Vec3::new(0.0, 1.0, 1.0).normalize(),
        ),
        (
            Vec3::new(2.5, -2.0, -3.0),
            3f32.sqrt(),
            Vec3::new(1.0, -1.0, -1.0).normalize(),
        ),
        (Vec3::new(1.4, 0.1, 0.0), -0.1, Vec3::X),
    ];
    for (p, distance, normal) in cases {
        let (d, n) = boxed.distance(p);
        assert!(
            (d - distance).abs() < 1e-6 && (n - normal).length() < 1e-6,
            "{p}: {d} {n}"
        );
    }
    let capsule = Collider {
        shape: Shape::Capsule {
            start: Vec3::ZERO,
            end: Vec3::new(0.0, 2.0, 0.0),
            radius: 0.5,
        },
        friction: 0.0,
        moved: Vec3::ZERO,
        swept: true,
    };
    // Beside the shaft, beyond an end cap, inside.
    for (p, distance) in [
        (Vec3::new(1.0, 1.0, 0.0), 0.5),
        (Vec3::new(0.0, 3.0, 0.0), 0.5),
        (Vec3::new(0.6, -0.8, 0.0), 0.5),
        (Vec3::new(0.2, 1.0, 0.0), -0.3),
    ] {
        let (d, _) = capsule.distance(p);
        assert!((d - distance).abs() < 1e-6, "{p}: {d}");
    }
}

#[test]
fn cloth_rests_on_a_box_and_a_capsule_without_entering() {
    for collider in [
        r#"{ "kind": "box", "center": [0, 0.3, 0], "size": [0.5, 0.6, 0.5] }"#,
        r#"{ "kind": "capsule", "start": [-0.4, 0.4, 0], "end": [0.4, 0.4, 0], "radius": 0.1 }"#,
    ] {
        let scene = common::scene(&format!(
            r#"{{ "frames": 90, "substeps": 10, "backend": "cpu",
                  "garments": [{{ "resolution": [30, 30], "size": [1, 1], "position": [0, 0.9, 0] }}],
                  "colliders": [{collider}, {{ "kind": "plane" }}] }}"#
        ));
        let mut sim = Simulation::new(&scene);
        let mut deepest = 0.0f32;
        for _ in 0..scene.frames {
            sim.step_frame();
            for q in &sim.state.positions {
                deepest = deepest.max(-sim.colliders[0].distance(q.truncate()).0);
            }
        }
        // Particles keep half the 5 mm thickness from the surface: none ever got inside.
        assert!(deepest <= 0.0, "{collider}: {deepest} m inside");
        // The cloth's middle rests on top (box top at 0.6 m, capsule top at 0.5 m).
        let top = sim
            .export_positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::MIN, f32::max);
        let expected = if collider.contains("box") { 0.6 } else { 0.5 };
        assert!(
            (top - expected).abs() < 0.02,
            "{collider}: highest point {top} m"
        );
    }
}

#[test]
fn the_swept_test_stops_paths_that_cross_a_thin_plate() {
    // A 1 cm plate; a particle crossing it within one step ends beyond it unless swept.
    let plate = |swept| Collider {
        shape: Shape::Box {
            center: Vec3::ZERO,
            half: Vec3::new(1.0, 0.005, 1.0),
            rotation: glam::Quat::IDENTITY,
        },
        friction: 0.0,
        moved: Vec3::ZERO,
        swept,
    };
    let (x, delta) = (
        glam::Vec4::new(0.0, 0.05, 0.0, 0.0),
        glam::Vec4::new(0.0, -0.1, 0.0, 0.0),
    );
    let through = plate(false).resolve(x, delta, 0.0025);
    assert_eq!(
        through, delta,
        "end-point test only: the particle passes through"
    );
    let stopped = plate(true).resolve(x, delta, 0.0025);
    assert!(
        (x + stopped).y >= 0.0075 - 1e-5,
        "swept: stops on top, at {}",
        (x + stopped).y
    );
}

#[test]
fn a_fast_sphere_carries_the_particles_it_sweeps_over() {
    // The sphere moved 0.5 m along +Z in one step, right through a particle at rest.
    let sphere = |swept| Collider {
        shape: Shape::Sphere {
            center: Vec3::new(0.0, 0.0, 0.3),
            radius: 0.1,
        },
        friction: 0.0,
        moved: Vec3::new(0.0, 0.0, 0.5),
        swept,
    };
    let x = glam::Vec4::ZERO;
    let missed = sphere(false).resolve(x, glam::Vec4::ZERO, 0.0025);
    assert_eq!(
        missed,
        glam::Vec4::ZERO,
        "end-point test only: the sphere passed over it"
    );
    let carried = sphere(true).resolve(x, glam::Vec4::ZERO, 0.0025);
    // Met by the front of the sphere (which moves towards +Z) and carried: it ends on the front
    // surface, z = 0.3 + 0.1025.
    assert!(
        (carried.z - (0.3 + 0.1025)).abs() < 1e-4,
        "carried to z = {}",
        carried.z
    );
}

#[test]
fn cloth_falling_fast_onto_a_thin_plate_stays_on_it_only_with_the_swept_test() {
    let lowest = |swept: bool| {
        let scene = common::scene(&format!(
            r#"{{ "frames": 40, "substeps": 1, "backend": "cpu", "swept_collisions": {swept},
                  "garments": [{{ "resolution": [12, 12], "size": [0.6, 0.6], "position": [0, 1.6, 0] }}],
                  "colliders": [{{ "kind": "box", "center": [0, 0.5, 0], "size": [1.5, 0.01, 1.5] }}] }}"#
        ));
        let mut sim = Simulation::new(&scene);
        for _ in 0..scene.frames {
            sim.step_frame();
        }
        sim.export_positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::MAX, f32::min)
    };
    // After a 1.1 m fall the cloth moves ~7.6 cm per step at one step per frame, more than the
    // plate is thick.
    let (with, without) = (lowest(true), lowest(false));
    assert!(with > 0.5, "swept: lowest particle at {with} m");
    assert!(
        without < 0.49,
        "end-point only: lowest particle at {without} m (it should fall through)"
    );
}

#[test]
fn the_report_lists_penetrations_frame_by_frame() {
    let dir = common::temp_dir();
    common::write(
        dir.path(),
        "scene.json",
        r#"{ "frames": 30, "substeps": 10, "backend": "cpu",
             "garments": [{ "resolution": [16, 16], "size": [1, 1], "position": [0, 0.9, 0] }],
             "colliders": [{ "kind": "sphere", "center": [0, 0.5, 0], "radius": 0.3 }, { "kind": "plane" }] }"#,
    );
    let out = common::drape(
        dir.path(),
        &["bake", "scene.json", "--out", "out", "--gltf", "none"],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/report.json")).unwrap())
            .unwrap();
    let frames = report["penetrations_per_frame"]
        .as_array()
        .expect("per-frame penetrations");
    assert_eq!(frames.len(), 30);
    for (k, f) in frames.iter().enumerate() {
        assert_eq!(f["frame"], k + 1);
        assert_eq!(
            f["inside"].as_array().unwrap().len(),
            2,
            "one entry per collider"
        );
        // Particles keep half the thickness from the sphere: none inside in any frame.
        assert_eq!(f["inside"][0], 0, "frame {}", k + 1);
    }
}
