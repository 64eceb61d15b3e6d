//! Physics against analytic answers and invariants:
//! - a spring-mass hanging from a pin settles where the spring force carries the weight;
//! - pinned particles never move;
//! - with damping, the total energy of the hanging cloth (scene H) never grows;
//! - the cloth of scene S never sinks more than 1 mm into the sphere.

mod common;

use drape::collide;
use drape::scene::reference;
use drape::sim::Simulation;

#[test]
fn hanging_spring_mass_settles_at_the_analytic_equilibrium() {
    // Two particles of 0.1 kg, a 0.5 m spring of 100 N/m, hanging vertically from the top one.
    let scene = common::scene(
        r#"{ "frames": 600, "substeps": 4, "damping": 2.0,
             "solver": { "kind": "gs", "iterations": 20 },
             "garments": [{ "kind": "rope", "resolution": [2], "size": [0.5], "mass": 0.2,
                            "rotation": [0, 0, -90], "pins": [[0]], "tethers": false,
                            "stiffness": { "stretch": 100 } }] }"#,
    );
    let mut sim = Simulation::new(&scene).unwrap();
    for _ in 0..scene.frames {
        sim.step_frame();
    }
    let p = sim.export_positions();
    let (top, bottom) = (p[0], p[1]);
    let expected = 0.5 + 0.1 * 9.81 / 100.0;
    let length = top.distance(bottom);
    assert!(
        (length - expected).abs() < 1e-4 * expected,
        "length {length}, expected {expected}"
    );
    assert!(
        (bottom.x - top.x).abs() < 1e-5 && bottom.y < top.y,
        "hangs straight down: {top} {bottom}"
    );
}

/// Runs scene H with `iterations` per substep; checks the pins every frame and returns the
/// largest (mechanical, total) energy over the start, relative to the start.
fn hanging_cloth_energy_excess(iterations: u32) -> (f64, f64) {
    let mut scene = reference::load(reference::HANGING_CLOTH, "hanging_cloth.json");
    scene.solver.iterations = iterations;
    let mut sim = Simulation::new(&scene).unwrap();
    let pins: Vec<usize> = (0..sim.model().particle_count())
        .filter(|&i| sim.model().inv_mass[i] == 0.0)
        .collect();
    assert_eq!(pins.len(), 2);
    let pinned: Vec<_> = pins.iter().map(|&i| sim.state.positions[i]).collect();
    let start = sim.energy().total();
    let (mut mechanical, mut total) = (f64::MIN, f64::MIN);
    for frame in 1..=scene.frames {
        sim.step_frame();
        for (&i, p) in pins.iter().zip(&pinned) {
            assert_eq!(sim.state.positions[i], *p, "pin {i} moved at frame {frame}");
        }
        let e = sim.energy();
        mechanical = mechanical.max((e.kinetic + e.gravitational) / start - 1.0);
        total = total.max(e.total() / start - 1.0);
    }
    assert!(
        sim.energy().total() < start - 0.05,
        "a damped hanging cloth loses energy"
    );
    (mechanical, total)
}

#[test]
fn pins_never_move_and_energy_never_grows_on_the_hanging_cloth() {
    // As scene H defines it (one iteration per substep), kinetic + gravitational energy never
    // exceeds the start. The springs' own energy w/2·Σ(l − L)² is then mostly unconverged
    // constraint error (w = 10 000 N/m): it is only bounded once the solve converges, which the
    // second run (five iterations per substep) checks on the total energy.
    let (mechanical, _) = hanging_cloth_energy_excess(1);
    assert!(
        mechanical <= 1e-5,
        "kinetic + gravitational energy grew by {mechanical:.2e} of the start"
    );
    let (mechanical, total) = hanging_cloth_energy_excess(5);
    assert!(
        mechanical <= 1e-5,
        "converged: kinetic + gravitational energy grew by {mechanical:.2e}"
    );
    assert!(
        total <= 1e-4,
        "converged: total energy grew by {total:.2e} of the start"
    );
}

#[test]
fn a_pendulum_loses_energy_at_every_step_size() {
    // Implicit Euler (converged Projective Dynamics) dissipates at any step, down to 100 steps
    // per frame, where single precision positions would have made it gain energy.
    for substeps in [1, 10, 100] {
        let scene = common::scene(&format!(
            r#"{{ "frames": 30, "damping": 0, "substeps": {substeps}, "solver": {{ "iterations": 20 }},
                 "garments": [{{ "kind": "rope", "resolution": [2], "size": [1], "mass": 0.2,
                                "pins": [[0]], "tethers": false, "stiffness": {{ "stretch": 10000 }} }}] }}"#
        ));
        let mut sim = Simulation::new(&scene).unwrap();
        let start = sim.energy().total();
        for frame in 1..=scene.frames {
            sim.step_frame();
            let e = sim.energy().total();
            assert!(
                e <= start,
                "{substeps} substeps, frame {frame}: energy {e} above the start {start}"
            );
        }
    }
}

#[test]
fn sphere_drape_keeps_out_of_the_sphere() {
    let scene = reference::load(reference::SPHERE_DRAPE, "sphere_drape.json");
    let mut sim = Simulation::new(&scene).unwrap();
    let mut deepest = 0.0f32;
    let mut touched = false;
    for _ in 0..scene.frames {
        sim.step_frame();
        let p = collide::penetrations(&sim.drivers.colliders, &sim.state.positions)[0];
        deepest = deepest.max(p.deepest);
        // Particles resting on the sphere sit at the contact radius from its surface.
        touched |= sim
            .state
            .positions
            .iter()
            .any(|q| sim.drivers.colliders[0].distance(q.truncate()).0 < 0.01);
    }
    assert!(touched, "the cloth never reached the sphere");
    assert!(
        deepest <= 1e-3,
        "a particle sank {deepest} m into the sphere"
    );
    assert!(sim.state.is_finite());
}

#[test]
fn free_fall_matches_half_g_t_squared() {
    // A cloth with no pins and no colliders falls like a point mass (damping off).
    let scene = common::scene(
        r#"{ "frames": 30, "damping": 0, "garments": [{ "resolution": [8, 8], "position": [0, 5, 0] }] }"#,
    );
    let mut sim = Simulation::new(&scene).unwrap();
    for _ in 0..scene.frames {
        sim.step_frame();
    }
    let t = 30.0 / 60.0;
    let y = sim.export_positions().iter().map(|p| p.y).sum::<f32>() / 64.0;
    let expected = 5.0 - 0.5 * 9.81 * t * t;
    // Position Verlet from rest is exact for constant acceleration up to the first half step.
    let h = 1.0 / 600.0;
    assert!(
        (y - expected).abs() < 9.81 * t * h,
        "y {y}, expected {expected}"
    );
}

/// The catenary y = a cosh(x/a) through two pins `span` apart with arc `length`: its sag (depth
/// of the lowest point below the pins). Solves length = 2a sinh(span / 2a) for a by bisection.
fn catenary_sag(span: f64, length: f64) -> f64 {
    let (mut lo, mut hi) = (1e-6f64, 1e6f64);
    for _ in 0..200 {
        let a = (lo * hi).sqrt();
        if 2.0 * a * (span / (2.0 * a)).sinh() > length {
            lo = a;
        } else {
            hi = a;
        }
    }
    let a = (lo * hi).sqrt();
    a * (span / (2.0 * a)).cosh() - a
}

#[test]
fn a_rope_between_two_pins_hangs_as_a_catenary() {
    // 2 m of rope, 81 particles, pinned at both ends 1.6 m apart: let it settle with damping.
    let scene = common::scene(
        r#"{ "frames": 300, "substeps": 20, "damping": 4.0, "solver": { "iterations": 10 },
             "garments": [{ "kind": "rope", "resolution": [81], "size": [2.0], "mass": 0.2,
                            "position": [0, 1, 0], "rotation": [0, 0, 0], "initial_stretch": 0.8,
                            "pins": [[0], [-1]], "stiffness": { "stretch": 100000 } }] }"#,
    );
    let mut sim = Simulation::new(&scene).unwrap();
    for _ in 0..scene.frames {
        sim.step_frame();
    }
    let p = sim.export_positions();
    let (left, right) = (p[0], p[80]);
    let span = left.distance(right) as f64;
    assert!(
        (span - 1.6).abs() < 1e-5,
        "the pins stay 1.6 m apart: {span}"
    );
    let lowest = p.iter().map(|q| q.y).fold(f32::INFINITY, f32::min);
    let sag = (left.y - lowest) as f64;
    let expected = catenary_sag(1.6, 2.0);
    let speed = sim
        .state
        .velocities
        .iter()
        .map(|v| v.length())
        .fold(0.0, f32::max);
    assert!(
        speed < 1e-3,
        "the rope has settled (fastest particle {speed} m/s)"
    );
    eprintln!(
        "rope sag {sag:.5} m, catenary {expected:.5} m ({:+.3} %)",
        100.0 * (sag / expected - 1.0)
    );
    assert!(
        (sag - expected).abs() <= 0.02 * expected,
        "sag {sag:.4} m, catenary {expected:.4} m"
    );
}
