//! The integrator study's findings as assertions (never on time): stability limits against the
//! theory of `shared/reference/stability.md`, energy growth of explicit Euler, orders of accuracy,
//! the power iteration against an exact chain, and the study's Projective Dynamics against
//! drape's own solver.

mod common;

use drape::bench::integrators::{simulate, substeps_for, StudyScene, FRAME_RATE};
use drape::garment::Garment;
use drape::massspring::integrate::Method;
use drape::massspring::spectrum::{gershgorin_bound, highest_frequency};
use drape::massspring::{Environment, MassSpring};
use glam::DVec3;

/// Scene W at 10 × 10 and its Verlet limit 2/ω_max.
fn washing_line() -> (MassSpring, f64) {
    let sys = StudyScene::WashingLine.build(10, 1.0);
    let (omega, _) = highest_frequency(&sys);
    (sys, 2.0 / omega)
}

/// Steps per frame giving a step of at least `h` (the largest such step).
fn substeps_at_least(h: f64) -> u32 {
    ((1.0 / (FRAME_RATE * h)).floor() as u32).max(1)
}

#[test]
fn verlet_is_stable_below_its_limit_and_unstable_above() {
    let (sys, limit) = washing_line();
    let below = substeps_for(0.9 * limit);
    let above = substeps_at_least(1.2 * limit);
    assert!(1.0 / (FRAME_RATE * below as f64) <= 0.9 * limit);
    assert!(1.0 / (FRAME_RATE * above as f64) >= 1.2 * limit);
    let stable = simulate(&mut sys.clone(), Method::Verlet, below, 2.0, false, |_| {});
    assert!(
        stable.stable(),
        "Verlet at 0.9 × 2/ω_max: {:?}",
        stable.blowup
    );
    let unstable = simulate(&mut sys.clone(), Method::Verlet, above, 2.0, false, |_| {});
    let blowup = unstable
        .blowup
        .expect("Verlet at 1.2 × 2/ω_max must blow up");
    assert!(blowup.step > 0 && blowup.time <= 2.0, "{blowup:?}");
}

#[test]
fn rk4_is_stable_beyond_the_verlet_limit() {
    let (sys, limit) = washing_line();
    // RK4's bound is 2√2/ω_max ≈ 1.41 × Verlet's.
    let s = substeps_for(1.25 * limit);
    let run = simulate(&mut sys.clone(), Method::Rk4, s, 2.0, false, |_| {});
    assert!(run.stable(), "RK4 at 1.25 × 2/ω_max: {:?}", run.blowup);
    let beyond = substeps_at_least(1.6 * limit);
    let run = simulate(&mut sys.clone(), Method::Rk4, beyond, 2.0, false, |_| {});
    assert!(!run.stable(), "RK4 at 1.6 × 2/ω_max must blow up");
}

#[test]
fn explicit_euler_gains_energy_without_damping_at_every_step() {
    let (mut sys, limit) = washing_line();
    sys.env.drag = 0.0;
    let start = sys.energy().total();
    for fraction in [0.02, 0.1, 0.5] {
        let mut euler = sys.clone();
        let s = substeps_for(fraction * limit);
        let mut totals = Vec::new();
        simulate(&mut euler, Method::ExplicitEuler, s, 0.1, false, |m| {
            totals.push(m.energy().total())
        });
        let end = euler.energy().total();
        assert!(
            !end.is_finite() || end > start + 1e-9,
            "explicit Euler at {fraction} × 2/ω_max: energy {start:e} → {end:e} J"
        );
        // Verlet at the same step keeps the energy within a small band: the gain is Euler's.
        let mut verlet = sys.clone();
        simulate(&mut verlet, Method::Verlet, s, 0.1, false, |_| {});
        let drift = (verlet.energy().total() - start).abs();
        assert!(
            !end.is_finite() || end - start > 10.0 * drift,
            "Euler gain {:e} J vs Verlet drift {drift:e} J at {fraction}",
            end - start
        );
    }
}

#[test]
fn implicit_euler_and_projective_dynamics_stay_stable_at_ten_times_the_verlet_limit() {
    let (sys, limit) = washing_line();
    let s = substeps_at_least(10.0 * limit);
    for method in [Method::ImplicitEuler, Method::ProjectiveDynamics(10)] {
        let run = simulate(&mut sys.clone(), method, s, 2.0, false, |_| {});
        assert!(
            run.stable(),
            "{} at 10 × 2/ω_max: {:?}",
            method.name(),
            run.blowup
        );
    }
    let verlet = simulate(&mut sys.clone(), Method::Verlet, s, 2.0, false, |_| {});
    assert!(!verlet.stable(), "Verlet at 10 × its limit must blow up");
}

/// RMS distance over every frame of two runs of `duration` seconds.
fn trajectory_error(method: Method, substeps: u32, reference: &[Vec<DVec3>]) -> f64 {
    let mut frames = Vec::new();
    simulate(
        &mut StudyScene::Flag.build(8, 1.0),
        method,
        substeps,
        0.25,
        false,
        |m| frames.push(m.positions.clone()),
    );
    let sum: f64 = frames
        .iter()
        .zip(reference)
        .map(|(f, r)| drape::bench::integrators::rms_distance(f, r).powi(2))
        .sum();
    (sum / frames.len() as f64).sqrt()
}

#[test]
fn errors_shrink_at_each_method_order() {
    // The flag, 8 × 8, 0.25 s, against RK4 at 2000 steps per frame.
    let mut reference = Vec::new();
    simulate(
        &mut StudyScene::Flag.build(8, 1.0),
        Method::Rk4,
        2000,
        0.25,
        false,
        |m| reference.push(m.positions.clone()),
    );
    let ratio = |m: Method, s: u32| {
        trajectory_error(m, s, &reference) / trajectory_error(m, 2 * s, &reference)
    };
    // Halving the step: RK4 (4th order) gains ~16×, Verlet in velocity form and implicit Euler
    // (1st order) ~2×.
    let rk4 = ratio(Method::Rk4, 50);
    assert!(rk4 > 10.0, "RK4 error ratio {rk4}");
    for m in [Method::Verlet, Method::ImplicitEuler] {
        let r = ratio(m, 100);
        assert!((1.6..2.6).contains(&r), "{} error ratio {r}", m.name());
    }
}

#[test]
fn power_iteration_finds_the_chain_frequency() {
    // A chain of n masses fixed at one end: ω_max = 2√(k/m)·sin((2n−1)π / (2(2n+1))).
    let spec = common::scene(
        r#"{ "garments": [ { "kind": "rope", "resolution": [100], "size": [1],
              "mass": 0.1, "pins": [[0]], "stiffness": { "stretch": 500 } } ] }"#,
    );
    let garment = Garment::build("rope".into(), &spec.garments[0]);
    let sys = MassSpring::from_garment(
        &garment,
        Environment {
            gravity: DVec3::ZERO,
            drag: 0.0,
            spring_damping: 0.0,
            wind: None,
        },
    );
    let (k, m, n) = (500.0f64, 0.1 / 100.0, 99.0f64);
    let exact = 2.0
        * (k / m).sqrt()
        * ((2.0 * n - 1.0) * std::f64::consts::PI / (2.0 * (2.0 * n + 1.0))).sin();
    let (omega, _) = highest_frequency(&sys);
    assert!(
        (omega - exact).abs() < 1e-3 * exact,
        "ω_max {omega} vs exact {exact}"
    );
    assert!(omega <= gershgorin_bound(&sys) * (1.0 + 1e-12));
}

#[test]
fn the_study_projective_dynamics_matches_drape_solver() {
    // Scene W at 10 × 10, 10 steps per frame × 10 iterations: the study's f64 Projective Dynamics
    // and drape's f32 red-black solver run the same algorithm.
    let mut scene =
        drape::scene::reference::load(drape::scene::reference::WASHING_LINE, "washing_line.json");
    scene.garments[0].resolution = vec![10, 10];
    scene.substeps = Some(10);
    scene.solver.iterations = 10;
    let mut sim = drape::sim::Simulation::new(&scene).unwrap();
    let mut sys = StudyScene::WashingLine.build(10, 1.0);
    let mut study = Vec::new();
    simulate(
        &mut sys,
        Method::ProjectiveDynamics(10),
        10,
        0.5,
        false,
        |m| study.push(m.positions.clone()),
    );
    let mut largest = 0.0f64;
    for frame in &study {
        sim.step_frame();
        for (a, b) in sim.export_positions().iter().zip(frame) {
            largest = largest.max((a.as_dvec3() - *b).length());
        }
    }
    assert!(largest < 1e-4, "study PD vs drape rbgs: {largest} m apart");
    // And the two differ from a method that is not the same (the test can fail).
    let mut verlet = StudyScene::WashingLine.build(10, 1.0);
    simulate(&mut verlet, Method::Verlet, 100, 0.5, false, |_| {});
    let apart = verlet
        .positions
        .iter()
        .zip(sim.export_positions())
        .map(|(a, b)| (*a - b.as_dvec3()).length())
        .fold(0.0, f64::max);
    assert!(apart > largest, "Verlet {apart} m vs PD {largest} m");
}

#[test]
fn unstable_runs_are_results_with_the_step_that_failed() {
    let (sys, limit) = washing_line();
    for method in [Method::ExplicitEuler, Method::Midpoint] {
        let run = simulate(
            &mut sys.clone(),
            method,
            substeps_for(limit),
            5.0,
            false,
            |_| {},
        );
        let b = run
            .blowup
            .unwrap_or_else(|| panic!("{} at 2/ω_max", method.name()));
        assert!(b.step % substeps_for(limit) as u64 == 0 && b.step > 0);
        assert!(!b.reason.is_empty());
    }
}

#[test]
fn scenes_w_and_f_match_their_definitions() {
    // W: 1 m × 1 m, vertical, 0.1 kg, pinned at its two top corners.
    for n in [10, 20, 50, 100] {
        let w = StudyScene::WashingLine.build(n, 1.0);
        assert_eq!(w.len(), (n * n) as usize);
        let mass: f64 = w.mass.iter().sum();
        assert!((mass - 0.1).abs() < 1e-6, "W mass {mass}");
        let span = |axis: usize| {
            let values = w.positions.iter().map(|p| p.to_array()[axis]);
            values.clone().fold(f64::MIN, f64::max) - values.fold(f64::MAX, f64::min)
        };
        assert!((span(0) - 1.0).abs() < 1e-6 && (span(1) - 1.0).abs() < 1e-6 && span(2) < 1e-6);
        let top = w.positions.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        let pinned: Vec<DVec3> = (0..w.len())
            .filter(|&i| w.inv_mass[i] == 0.0)
            .map(|i| w.positions[i])
            .collect();
        assert_eq!(pinned.len(), 2);
        assert!(pinned
            .iter()
            .all(|p| (p.y - top).abs() < 1e-9 && (p.x.abs() - 0.5).abs() < 1e-6));
    }
    // F: 1.5 m × 1 m, the whole left edge pinned, wind on.
    let f = StudyScene::Flag.build(20, 1.0);
    let pinned: Vec<DVec3> = (0..f.len())
        .filter(|&i| f.inv_mass[i] == 0.0)
        .map(|i| f.positions[i])
        .collect();
    assert_eq!(pinned.len(), 20);
    assert!(pinned.iter().all(|p| p.x.abs() < 1e-6));
    let right = f.positions.iter().map(|p| p.x).fold(f64::MIN, f64::max);
    assert!((right - 1.5).abs() < 1e-6);
    assert!(f.env.wind.is_some());
}
