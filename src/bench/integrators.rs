//! The integrator study (`drape bench integrators`): explicit Euler, midpoint, RK4, Verlet,
//! implicit Euler and Projective Dynamics on the mass-spring cloth of scenes W (washing line) and
//! F (flag), measuring where each becomes unstable, what it costs to reach equilibrium, and how
//! far it is from a converged reference for the wall time it takes.
//!
//! Every run advances whole frames of 1/60 s with `substeps` equal steps, so all methods are
//! compared at the same instants. The stability rule, checked after every frame, is the one of
//! `scenes.md` (`sim::metrics::unstable_reason`); an unstable run is a result with the step at
//! which it was detected, never a crash. Wall times exclude those checks.

use crate::garment::Garment;
use crate::massspring::forces::wind_forces;
use crate::massspring::integrate::{Integrator, Method};
use crate::massspring::spectrum::highest_frequency;
use crate::massspring::{Environment, MassSpring, Wind};
use crate::scene::reference;
use crate::sim::metrics::unstable_reason;
use glam::DVec3;
use std::time::Instant;

/// Frames per second of every study run (the scenes' 60 fps).
pub const FRAME_RATE: f64 = 60.0;

/// Steps per frame tried first when searching for the largest stable step, largest step first.
pub const SUBSTEP_LADDER: [u32; 40] = [
    1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40, 50, 60, 80, 100, 120, 150, 200, 250, 300, 400,
    500, 600, 800, 1000, 1200, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 8000, 10000, 12000, 15000,
];

/// A study scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StudyScene {
    /// W: 1 m × 1 m, hanging vertically from its two top corners, gravity only.
    WashingLine,
    /// F: 1.5 m × 1 m, left edge pinned, gravity and wind.
    Flag,
}

impl StudyScene {
    pub fn letter(self) -> &'static str {
        match self {
            StudyScene::WashingLine => "W",
            StudyScene::Flag => "F",
        }
    }

    /// Simulated seconds the accuracy study compares over. The flag flutters: nearby
    /// trajectories separate exponentially (differences of 1e-10 m reach millimetres within a
    /// second), so past 0.25 s its error measures chaos, not the integrator.
    pub fn accuracy_window(self) -> f64 {
        match self {
            StudyScene::WashingLine => 1.0,
            StudyScene::Flag => 0.25,
        }
    }

    /// Simulated time the scene runs for at most [s] (`scenes.md`).
    pub fn duration(self) -> f64 {
        match self {
            StudyScene::WashingLine => 60.0,
            StudyScene::Flag => 10.0,
        }
    }

    /// The scene at `n` × `n` particles with every spring stiffness multiplied by `stiffness`.
    pub fn build(self, n: u32, stiffness: f32) -> MassSpring {
        let mut scene = reference::load(reference::WASHING_LINE, "washing_line.json");
        let spec = &mut scene.garments[0];
        spec.resolution = vec![n, n];
        spec.stiffness.stretch *= stiffness;
        spec.stiffness.shear *= stiffness;
        spec.stiffness.bend *= stiffness;
        let mut wind = None;
        if self == StudyScene::Flag {
            spec.name = Some("flag".into());
            spec.size = Some(vec![1.5, 1.0]);
            // The pole along the left edge at x = 0.
            spec.position = [0.75, 1.0, 0.0];
            spec.pins = (0..n as i64).map(|row| vec![0, row]).collect();
            wind = Some(Wind {
                velocity: DVec3::new(4.0, 0.0, 2.0),
                coefficient: 0.5,
            });
        }
        let garment = Garment::build(scene.garment_name(0), &scene.garments[0]);
        MassSpring::from_garment(
            &garment,
            Environment {
                gravity: glam::Vec3::from(scene.gravity).as_dvec3(),
                drag: scene.damping as f64,
                spring_damping: 0.0,
                wind,
            },
        )
    }
}

/// Where a run became unstable.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Blowup {
    /// Steps taken when the rule fired (it is checked at the end of each frame).
    pub step: u64,
    /// Simulated time then [s].
    pub time: f64,
    pub reason: String,
}

/// What one run measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Outcome {
    pub method: String,
    pub particles: usize,
    /// Step h [s].
    pub step: f64,
    pub steps: u64,
    /// Simulated time covered [s].
    pub simulated: f64,
    /// Wall time of the steps alone [s].
    pub wall: f64,
    pub blowup: Option<Blowup>,
    /// First time from which the fastest particle stayed below 1 mm/s for 10 frames [s].
    pub equilibrium: Option<f64>,
    /// Conjugate-gradient iterations per step (implicit Euler).
    pub cg_per_step: f64,
}

impl Outcome {
    pub fn stable(&self) -> bool {
        self.blowup.is_none()
    }

    /// Wall seconds per simulated second.
    pub fn wall_per_second(&self) -> f64 {
        self.wall / self.simulated.max(f64::MIN_POSITIVE)
    }
}

/// Speed below which a particle counts as at rest [m/s] (`scenes.md`).
pub const REST_SPEED: f64 = 1e-3;
/// Consecutive frames at rest that make an equilibrium.
pub const REST_FRAMES: u32 = 10;

/// Runs `method` on `sys` with `substeps` steps per frame for up to `duration` seconds, stopping
/// at a blow-up and, when `until_rest`, at equilibrium. `frame` sees the state after each frame.
pub fn simulate(
    sys: &mut MassSpring,
    method: Method,
    substeps: u32,
    duration: f64,
    until_rest: bool,
    mut frame: impl FnMut(&MassSpring),
) -> Outcome {
    let h = 1.0 / (FRAME_RATE * substeps as f64);
    let frames = (duration * FRAME_RATE).round() as u64;
    let initial = sys.energy();
    let mut integrator = Integrator::new(method);
    let mut outcome = Outcome {
        method: method.name(),
        particles: sys.len(),
        step: h,
        steps: 0,
        simulated: 0.0,
        wall: 0.0,
        blowup: None,
        equilibrium: None,
        cg_per_step: 0.0,
    };
    let mut resting = 0u32;
    // Energy the wind put in so far counts as released, like the potential energy: the work of
    // the force at the start of each frame along that frame's displacement.
    let mut supplied = 0.0;
    for f in 1..=frames {
        let wind = wind_forces(sys, &sys.positions).map(|w| (w, sys.positions.clone()));
        let start = Instant::now();
        for _ in 0..substeps {
            integrator.step(sys, h);
        }
        outcome.wall += start.elapsed().as_secs_f64();
        outcome.steps += substeps as u64;
        outcome.simulated = f as f64 / FRAME_RATE;
        if let Some((force, before)) = wind {
            let work: f64 = (0..sys.len())
                .map(|i| force[i].dot(sys.positions[i] - before[i]))
                .sum();
            supplied += work;
        }
        if let Some(reason) = unstable_reason(
            sys.is_finite(),
            sys.max_strain(),
            &sys.energy(),
            &initial,
            supplied,
        ) {
            outcome.blowup = Some(Blowup {
                step: outcome.steps,
                time: outcome.simulated,
                reason,
            });
            break;
        }
        frame(sys);
        if sys.max_speed() < REST_SPEED {
            resting += 1;
            if resting == REST_FRAMES && outcome.equilibrium.is_none() {
                outcome.equilibrium = Some((f - REST_FRAMES as u64) as f64 / FRAME_RATE);
                if until_rest {
                    break;
                }
            }
        } else {
            resting = 0;
        }
    }
    outcome.cg_per_step = integrator.cg_iterations as f64 / outcome.steps.max(1) as f64;
    outcome
}

/// The largest step h = 1/(60·s), s a whole number of steps per frame, at which `method` stays
/// stable for `duration` seconds on `build()`, searching steps no smaller than `smallest` [s];
/// `None` when every one blew up. The ladder finds the first stable rung from the top, then a
/// bisection over the whole numbers between it and the unstable rung above pins the limit down.
pub fn largest_stable_step(
    build: &dyn Fn() -> MassSpring,
    method: Method,
    duration: f64,
    smallest: f64,
) -> Option<(f64, Outcome)> {
    let run = |s: u32| simulate(&mut build(), method, s, duration, false, |_| {});
    let mut unstable = 0u32; // the last rung that blew up (0: none yet)
    for &s in SUBSTEP_LADDER.iter() {
        if 1.0 / (FRAME_RATE * s as f64) < smallest {
            return None;
        }
        let outcome = run(s);
        if !outcome.stable() {
            unstable = s;
            continue;
        }
        // Stable at s, unstable at `unstable`: the fewest stable steps per frame in between.
        let (mut low, mut high, mut best) = (unstable, s, outcome);
        while high - low > 1 {
            let mid = low + (high - low) / 2;
            let outcome = run(mid);
            if outcome.stable() {
                high = mid;
                best = outcome;
            } else {
                low = mid;
            }
        }
        return Some((best.step, best));
    }
    None
}

/// Substeps per frame that make a step of at most `h`.
pub fn substeps_for(h: f64) -> u32 {
    (1.0 / (FRAME_RATE * h)).ceil().max(1.0) as u32
}

/// One row of the stability study.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StabilityRow {
    pub particles: usize,
    /// Structural stiffness k [N/m].
    pub stiffness: f64,
    pub method: String,
    pub particle_mass: f64,
    /// ω_max by power iteration at rest [rad/s].
    pub omega_max: f64,
    /// Largest stable step measured [s], None when none was.
    pub largest_stable: Option<f64>,
}

/// Largest stable step of each method on scene W for each (grid edge, stiffness multiplier).
pub fn stability_study(
    cases: &[(u32, f32)],
    methods: &[Method],
    duration: f64,
) -> Vec<StabilityRow> {
    let mut rows = Vec::new();
    for &(n, scale) in cases {
        let build = || StudyScene::WashingLine.build(n, scale);
        rows.extend(stability_rows(&build, methods, duration));
    }
    rows
}

/// Largest stable step of each method on the model `build` makes.
pub fn stability_rows(
    build: &dyn Fn() -> MassSpring,
    methods: &[Method],
    duration: f64,
) -> Vec<StabilityRow> {
    let sys = build();
    let (omega, _) = highest_frequency(&sys);
    let k = sys
        .springs
        .iter()
        .find(|s| s.structural)
        .map_or(0.0, |s| s.stiffness);
    methods
        .iter()
        .map(|&method| StabilityRow {
            particles: sys.len(),
            stiffness: k,
            method: method.name(),
            particle_mass: sys.mass[0],
            omega_max: omega,
            // Search down to 1/50 of Verlet's predicted limit.
            largest_stable: largest_stable_step(build, method, duration, 0.04 / omega)
                .map(|(h, _)| h),
        })
        .collect()
}

/// Spring networks of growing connectivity on which to test the rule h < 0.4π√(m/k): a chain,
/// a sheet with structural springs only, with shear, and scene W. Each case is (name, model);
/// the springs are stiffened (the rope 100 ×, the sheets 10 ×) so that the limits fall at tens
/// of steps per frame, where whole steps per frame resolve them to a few per cent.
pub fn rule_cases() -> Vec<(&'static str, MassSpring)> {
    let base = reference::load(reference::WASHING_LINE, "washing_line.json");
    let env = |scene: &crate::scene::Scene| Environment {
        gravity: glam::Vec3::from(scene.gravity).as_dvec3(),
        drag: scene.damping as f64,
        spring_damping: 0.0,
        wind: None,
    };
    let case = |name: &'static str, edit: &dyn Fn(&mut crate::scene::GarmentSpec)| {
        let mut scene = base.clone();
        edit(&mut scene.garments[0]);
        let garment = Garment::build(name.into(), &scene.garments[0]);
        (name, MassSpring::from_garment(&garment, env(&scene)))
    };
    vec![
        case("rope of 20 pinned at one end (a chain)", &|g| {
            g.kind = crate::scene::GarmentKind::Rope;
            g.resolution = vec![20];
            g.size = Some(vec![1.0]);
            g.pins = vec![vec![0]];
            g.stiffness.stretch *= 100.0;
        }),
        case("sheet 20 × 20 with structural springs only", &|g| {
            g.resolution = vec![20, 20];
            g.stiffness.stretch *= 10.0;
            g.stiffness.shear = 0.0;
            g.stiffness.bend = 0.0;
        }),
        case("sheet 20 × 20 with structural and shear springs", &|g| {
            g.resolution = vec![20, 20];
            g.stiffness.stretch *= 10.0;
            g.stiffness.shear *= 10.0;
            g.stiffness.bend = 0.0;
        }),
        case("scene W 20 × 20 (structural and shear and bend)", &|g| {
            g.resolution = vec![20, 20];
            g.stiffness.stretch *= 10.0;
            g.stiffness.shear *= 10.0;
            g.stiffness.bend *= 10.0;
        }),
    ]
}

/// Root-mean-square distance between two position sets [m].
pub fn rms_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(a, b)| a.distance_squared(*b)).sum();
    (sum / a.len().max(1) as f64).sqrt()
}

/// Positions after every frame of a run.
pub fn trajectory(
    scene: StudyScene,
    n: u32,
    method: Method,
    substeps: u32,
    duration: f64,
) -> (Outcome, Vec<Vec<DVec3>>) {
    let mut sys = scene.build(n, 1.0);
    let mut frames = Vec::new();
    let outcome = simulate(&mut sys, method, substeps, duration, false, |s| {
        frames.push(s.positions.clone())
    });
    (outcome, frames)
}

/// One point of the accuracy study: a method at a step, its error against the reference and its
/// cost.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AccuracyPoint {
    pub scene: &'static str,
    pub method: String,
    pub substeps: u32,
    pub step: f64,
    /// RMS distance to the reference over every particle and frame [m]; None when unstable.
    pub error: Option<f64>,
    pub wall_per_second: f64,
}

/// Error against a converged reference (RK4 at `reference_substeps`) over `duration` seconds, for
/// each method at each of `substeps`.
pub fn accuracy_study(
    scene: StudyScene,
    n: u32,
    duration: f64,
    reference_substeps: u32,
    runs: &[(Method, Vec<u32>)],
) -> Vec<AccuracyPoint> {
    let (_, reference) = trajectory(scene, n, Method::Rk4, reference_substeps, duration);
    let mut points = Vec::new();
    for (method, steps) in runs {
        for &s in steps {
            let (outcome, frames) = trajectory(scene, n, *method, s, duration);
            let error = outcome.stable().then(|| {
                let sum: f64 = frames
                    .iter()
                    .zip(&reference)
                    .map(|(f, r)| rms_distance(f, r).powi(2))
                    .sum();
                (sum / frames.len().max(1) as f64).sqrt()
            });
            points.push(AccuracyPoint {
                scene: scene.letter(),
                method: method.name(),
                substeps: s,
                step: outcome.step,
                error,
                wall_per_second: outcome.wall_per_second(),
            });
        }
    }
    points
}
