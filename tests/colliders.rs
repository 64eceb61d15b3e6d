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
        },
        friction: 0.0,
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
