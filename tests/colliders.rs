//! Boxes, capsules, funnels and wedges: signed distances against hand-computed values, normals
//! against the distance's numerical gradient, and cloth that comes to rest on them stays outside;
//! cloth dropped into a funnel passes through its spout (CPU; the GPU's agreement is in
//! `gpu_parity.rs`).

mod common;

use drape::collide::{Collider, Shape};
use drape::sim::Simulation;
use glam::Vec3;

#[test]
fn signed_distances_of_box_and_capsule() {
    let boxed = Collider {
        shape: Shape::Box {
            centre: Vec3::new(1.0, 0.0, 0.0),
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

fn collider(shape: Shape) -> Collider {
    Collider {
        shape,
        friction: 0.0,
        moved: Vec3::ZERO,
        swept: true,
    }
}

fn funnel() -> Collider {
    collider(Shape::Funnel {
        centre: Vec3::new(0.0, 0.5, 0.0),
        radius: 0.1,
        top_radius: 0.4,
        height: 0.4,
        half_thickness: 0.01,
    })
}

fn wedge() -> Collider {
    collider(Shape::Wedge {
        centre: Vec3::new(0.0, 1.0, 0.0),
        half: Vec3::new(0.2, 0.3, 0.5),
        rotation: glam::Quat::from_rotation_y(0.4),
    })
}

#[test]
fn signed_distances_of_funnel_and_wedge() {
    let f = funnel();
    // The wall's middle at the spout, half-way up (both sides), the open axis, below the spout.
    let slope = Vec3::new(0.4, -0.3, 0.0).normalize(); // outward normal of the wall in XY
    for (p, distance) in [
        (Vec3::new(0.1, 0.5, 0.0), -0.01),
        (Vec3::new(0.25, 0.7, 0.0) + slope * 0.05, 0.04),
        (Vec3::new(0.25, 0.7, 0.0) - slope * 0.03, 0.02),
        (Vec3::new(0.0, 0.7, 0.0), 0.25 * 0.8 - 0.01),
        (Vec3::new(0.1, 0.3, 0.0), 0.19),
    ] {
        let (d, _) = f.distance(p);
        assert!(
            (d - distance).abs() < 1e-5,
            "funnel at {p}: {d}, expected {distance}"
        );
    }
    let w = wedge();
    let turn = glam::Quat::from_rotation_y(0.4);
    let at = |x: f32, y: f32, z: f32| Vec3::new(0.0, 1.0, 0.0) + turn * Vec3::new(x, y, z);
    // Below the blade, above the top face, beyond an end, inside under the top face.
    for (p, distance, normal) in [
        (at(0.0, -0.5, 0.0), 0.2, Some(turn * Vec3::NEG_Y)),
        (at(0.05, 0.4, 0.1), 0.1, Some(turn * Vec3::Y)),
        (at(0.0, 0.0, 0.8), 0.3, Some(turn * Vec3::Z)),
        (at(0.0, 0.25, 0.0), -0.05, Some(turn * Vec3::Y)),
    ] {
        let (d, n) = w.distance(p);
        assert!(
            (d - distance).abs() < 1e-5,
            "wedge at {p}: {d}, expected {distance}"
        );
        if let Some(normal) = normal {
            assert!((n - normal).length() < 1e-4, "wedge normal at {p}: {n}");
        }
    }
}

#[test]
fn normals_are_the_gradient_of_the_distance() {
    let shapes = [funnel(), wedge()];
    let h = 1e-3f32;
    let mut checked = 0;
    for c in &shapes {
        for i in 0..12 {
            for j in 0..12 {
                for k in 0..6 {
                    let p = Vec3::new(
                        -0.55 + 0.1 * i as f32,
                        0.35 + 0.1 * j as f32,
                        -0.55 + 0.2 * k as f32,
                    );
                    let d = |q: Vec3| c.distance(q).0;
                    let g = Vec3::new(
                        d(p + Vec3::X * h) - d(p - Vec3::X * h),
                        d(p + Vec3::Y * h) - d(p - Vec3::Y * h),
                        d(p + Vec3::Z * h) - d(p - Vec3::Z * h),
                    ) / (2.0 * h);
                    // Where the distance is smooth its gradient has unit length; skip the
                    // creases (the wedge's inner medial planes, the funnel's axis).
                    if (g.length() - 1.0).abs() > 1e-2 {
                        continue;
                    }
                    let (_, n) = c.distance(p);
                    assert!(
                        (n - g).length() < 2e-2,
                        "{:?} at {p}: normal {n}, gradient {g}",
                        c.shape
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 1000, "only {checked} points checked");
}

#[test]
fn cloth_dropped_into_a_funnel_passes_through_its_spout() {
    let scene = drape::scene::Scene::load(std::path::Path::new("scenes/funnel.json")).unwrap();
    let mut scene = scene;
    scene.particle_collisions = false;
    scene.frames = 120;
    let mut sim = Simulation::new(&scene).unwrap();
    let wall = sim.drivers.colliders[0];
    let mut deepest = 0.0f32;
    for _ in 0..scene.frames {
        sim.step_frame();
        for q in &sim.state.positions {
            deepest = deepest.max(-wall.distance(q.truncate()).0);
        }
    }
    let highest = sim
        .export_positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    eprintln!("funnel: deepest into the wall {deepest} m; highest particle after 2 s {highest} m");
    assert!(
        deepest <= 0.0,
        "a particle went {deepest} m into the funnel's wall"
    );
    assert!(
        highest < 0.5,
        "the cloth should have passed the spout at 0.5 m: {highest}"
    );
}

#[test]
fn cloth_rests_on_a_box_and_a_capsule_without_entering() {
    for collider in [
        r#"{ "kind": "box", "centre": [0, 0.3, 0], "size": [0.5, 0.6, 0.5] }"#,
        r#"{ "kind": "capsule", "start": [-0.4, 0.4, 0], "end": [0.4, 0.4, 0], "radius": 0.1 }"#,
    ] {
        let scene = common::scene(&format!(
            r#"{{ "frames": 90, "substeps": 10, "backend": "cpu",
                  "garments": [{{ "resolution": [30, 30], "size": [1, 1], "position": [0, 0.9, 0] }}],
                  "colliders": [{collider}, {{ "kind": "plane" }}] }}"#
        ));
        let mut sim = Simulation::new(&scene).unwrap();
        let mut deepest = 0.0f32;
        for _ in 0..scene.frames {
            sim.step_frame();
            for q in &sim.state.positions {
                deepest = deepest.max(-sim.drivers.colliders[0].distance(q.truncate()).0);
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
            centre: Vec3::ZERO,
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
            centre: Vec3::new(0.0, 0.0, 0.3),
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
                  "colliders": [{{ "kind": "box", "centre": [0, 0.5, 0], "size": [1.5, 0.01, 1.5] }}] }}"#
        ));
        let mut sim = Simulation::new(&scene).unwrap();
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
             "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.3 }, { "kind": "plane" }] }"#,
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

#[test]
fn bad_funnels_and_wedges_are_input_errors() {
    let dir = common::temp_dir();
    for (collider, field, expect) in [
        (
            r#"{ "kind": "funnel", "centre": [0, 1, 0], "radius": 0.1, "top_radius": 0.4 }"#,
            "height",
            "needs height",
        ),
        (
            r#"{ "kind": "funnel", "centre": [0, 1, 0], "radius": 0.1, "top_radius": 0.4, "height": 0.3, "thickness": 0 }"#,
            "thickness",
            "above zero",
        ),
        (
            r#"{ "kind": "funnel", "centre": [0, 1, 0], "radius": 0.1, "top_radius": 0.4, "height": 0.3, "size": [1, 1, 1] }"#,
            "size",
            "a funnel takes",
        ),
        (
            r#"{ "kind": "funnel", "centre": [0, 1, 0], "radius": 0.1, "top_radius": 0.4, "height": 0.3, "keyframes": [{ "time": 0 }, { "time": 1, "rotation": [90, 0, 0] }] }"#,
            "keyframes",
            "upright",
        ),
        (
            r#"{ "kind": "wedge", "centre": [0, 1, 0] }"#,
            "size",
            "needs size",
        ),
        (
            r#"{ "kind": "wedge", "centre": [0, 1, 0], "size": [0.2, -1, 1] }"#,
            "size",
            "longer than 0",
        ),
    ] {
        common::write(
            dir.path(),
            "scene.json",
            &format!(r#"{{ "garments": [{{}}], "colliders": [{collider}] }}"#),
        );
        let out = common::drape(dir.path(), &["inspect", "scene.json"]);
        let err = common::stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{collider}: {err}");
        assert!(
            err.contains(&format!("colliders[0].{field}")) && err.contains(expect),
            "{collider}: {err}"
        );
    }
}

#[test]
fn american_spellings_of_keys_read_as_the_british_ones() {
    let british = common::scene(
        r#"{ "garments": [{ "colour": [0.2, 0.4, 0.6] }],
             "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.3 }] }"#,
    );
    let american = common::scene(
        r#"{ "garments": [{ "color": [0.2, 0.4, 0.6] }],
             "colliders": [{ "kind": "sphere", "center": [0, 0.5, 0], "radius": 0.3 }] }"#,
    );
    assert_eq!(american.garments[0].colour, Some([0.2, 0.4, 0.6]));
    assert_eq!(
        format!("{:?}", american.colliders),
        format!("{:?}", british.colliders)
    );
    let sphere = Collider::from_spec(&american.colliders[0]).shape;
    assert!(matches!(sphere, Shape::Sphere { centre, .. } if centre == Vec3::new(0.0, 0.5, 0.0)));
    // Both spellings at once name one key twice.
    let twice = r#"{ "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "center": [0, 1, 0], "radius": 0.3 }] }"#;
    assert!(drape::scene::Scene::parse(twice, "t.json").is_err());
}
