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

/// Steps per frame tried when searching for the largest stable step, smallest first.
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
            spec.size = vec![1.5, 1.0];
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
    let mut supplied = initial;
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
            supplied.gravitational += work;
        }
        if let Some(reason) =
            unstable_reason(sys.is_finite(), sys.max_strain(), &sys.energy(), &supplied)
        {
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

/// The largest step of the ladder at which `method` stays stable for `duration` seconds on
/// `build()`, searching steps no smaller than `smallest` [s]; `None` when every one blew up.
pub fn largest_stable_step(
    build: &dyn Fn() -> MassSpring,
    method: Method,
    duration: f64,
    smallest: f64,
) -> Option<(f64, Outcome)> {
    for &s in SUBSTEP_LADDER.iter() {
        let h = 1.0 / (FRAME_RATE * s as f64);
        if h < smallest {
            return None;
        }
        let outcome = simulate(&mut build(), method, s, duration, false, |_| {});
        if outcome.stable() {
            return Some((h, outcome));
        }
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
    /// Structural stiffness k [N/m].
    pub stiffness: f64,
    pub method: String,
    pub particle_mass: f64,
    /// ω_max by power iteration at rest [rad/s].
    pub omega_max: f64,
    /// Largest stable step measured [s], None when none was.
    pub largest_stable: Option<f64>,
}

/// Largest stable step of each method at each stiffness multiplier on scene W at `n` × `n`.
pub fn stability_study(
    n: u32,
    stiffness: &[f32],
    methods: &[Method],
    duration: f64,
) -> Vec<StabilityRow> {
    let mut rows = Vec::new();
    for &scale in stiffness {
        let build = || StudyScene::WashingLine.build(n, scale);
        let sys = build();
        let (omega, _) = highest_frequency(&sys);
        let k = sys
            .springs
            .iter()
            .find(|s| s.structural)
            .map_or(0.0, |s| s.stiffness);
        for &method in methods {
            // Search down to 1/50 of Verlet's predicted limit.
            let found = largest_stable_step(&build, method, duration, 0.04 / omega);
            rows.push(StabilityRow {
                stiffness: k,
                method: method.name(),
                particle_mass: sys.mass[0],
                omega_max: omega,
                largest_stable: found.map(|(h, _)| h),
            });
        }
    }
    rows
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

/// What `drape bench integrators` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// Grid edge of the stability study (scene W).
    pub stability_n: u32,
    /// Stiffness multipliers of the stability study (1 = scene W's springs).
    pub stiffness: Vec<f32>,
    /// Simulated seconds a step must survive to count as stable.
    pub stability_duration: f64,
    /// Grid edges of the cost-to-equilibrium study (scene W).
    pub sizes: Vec<u32>,
    /// Grid edge of the accuracy study, and the most simulated seconds it compares over (each
    /// scene has its own window, [`StudyScene::accuracy_window`]).
    pub accuracy_n: u32,
    pub accuracy_duration: f64,
    /// Steps per frame of the converged reference (RK4).
    pub reference_substeps: u32,
    /// Scenes of the accuracy study.
    pub scenes: Vec<StudyScene>,
}

impl Config {
    /// The full study the docs show.
    pub fn full() -> Config {
        Config {
            stability_n: 20,
            stiffness: vec![0.1, 0.3, 1.0, 3.0, 10.0],
            stability_duration: 1.0,
            sizes: vec![10, 20, 50, 100],
            accuracy_n: 20,
            accuracy_duration: 1.0,
            reference_substeps: 4000,
            scenes: vec![StudyScene::WashingLine, StudyScene::Flag],
        }
    }

    /// A reduced study for tests: 8 × 8 grids, short runs.
    pub fn quick() -> Config {
        Config {
            stability_n: 8,
            stiffness: vec![1.0, 10.0],
            stability_duration: 0.25,
            sizes: vec![8, 12],
            accuracy_n: 8,
            accuracy_duration: 0.25,
            reference_substeps: 1000,
            scenes: vec![StudyScene::WashingLine, StudyScene::Flag],
        }
    }
}

/// Projective Dynamics iterations per step in the study.
pub const PD_ITERATIONS: u32 = 10;

/// Steps per frame each method runs at in the accuracy study.
fn accuracy_runs() -> Vec<(Method, Vec<u32>)> {
    vec![
        (Method::ExplicitEuler, vec![100, 400, 1600]),
        (Method::Midpoint, vec![60, 100, 200, 400, 800]),
        (Method::Rk4, vec![40, 50, 100, 200, 400]),
        (Method::Verlet, vec![50, 100, 200, 400, 800]),
        (Method::ImplicitEuler, vec![1, 2, 5, 10, 20, 50, 100, 200]),
        (
            Method::ProjectiveDynamics(PD_ITERATIONS),
            vec![2, 5, 10, 20, 50, 100],
        ),
        (Method::ProjectiveDynamics(1), vec![20, 50, 100, 200, 400]),
    ]
}

/// Steps per frame each method runs at in the cost study, given Verlet's predicted limit `h_verlet`:
/// the explicit methods at 0.8 × their predicted limit (explicit Euler and midpoint at Verlet's,
/// where theory says they fail), implicit Euler at one step per frame and Projective Dynamics at
/// 10 (drape's sphere-drape setting).
fn cost_runs(h_verlet: f64) -> Vec<(Method, u32)> {
    let verlet = substeps_for(0.8 * h_verlet);
    vec![
        (Method::ExplicitEuler, verlet),
        (Method::Midpoint, verlet),
        (
            Method::Rk4,
            substeps_for(0.8 * h_verlet * std::f64::consts::SQRT_2),
        ),
        (Method::Verlet, verlet),
        (Method::ImplicitEuler, 1),
        (Method::ProjectiveDynamics(PD_ITERATIONS), 10),
    ]
}

/// Runs the study, writes CSV and SVG charts into `out` and returns the Markdown section.
pub fn report(
    cfg: &Config,
    out: &std::path::Path,
    log: &mut dyn FnMut(&str),
) -> crate::Result<String> {
    use super::chart::{write_atomically, Chart, Series, Style};
    use std::fmt::Write as _;
    std::fs::create_dir_all(out).map_err(|e| crate::Error::io(out, "cannot create", e))?;
    let folder = out
        .file_name()
        .map_or("bench".into(), |f| f.to_string_lossy().into_owned());
    let methods = Method::all(PD_ITERATIONS);
    let mut md = String::new();

    // 1. Largest stable step against stiffness, beside the predictions.
    let rows = stability_study(
        cfg.stability_n,
        &cfg.stiffness,
        &methods,
        cfg.stability_duration,
    );
    let mut csv =
        String::from("stiffness_n_per_m,method,particle_mass_kg,omega_max,largest_stable_step_s\n");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{:e},{:.3},{}",
            r.stiffness,
            r.method,
            r.particle_mass,
            r.omega_max,
            r.largest_stable.map_or(String::new(), |h| format!("{h:e}"))
        );
        log(&format!(
            "stability k={:<7} {:<16} ω_max {:>9.1}: largest stable step {}",
            r.stiffness,
            r.method,
            r.omega_max,
            r.largest_stable
                .map_or("none".into(), |h| format!("{h:.3e} s"))
        ));
    }
    write_atomically(&out.join("integrators-stability.csv"), csv.as_bytes())?;
    let mut ks: Vec<(f64, f64, f64)> = rows
        .iter()
        .map(|r| (r.stiffness, r.omega_max, r.particle_mass))
        .collect();
    ks.dedup_by(|a, b| a.0 == b.0);
    let mut chart = Chart {
        title: format!(
            "Scene W {0}×{0}: largest stable step against stiffness",
            cfg.stability_n
        ),
        x_label: "structural stiffness k [N/m]".into(),
        y_label: "largest stable step h [s]".into(),
        x_log: true,
        y_log: true,
        ..Chart::default()
    };
    for (c, m) in methods.iter().enumerate() {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.method == m.name())
            .filter_map(|r| r.largest_stable.map(|h| (r.stiffness, h)))
            .collect();
        if !points.is_empty() {
            chart.series.push(Series::new(
                format!("{} (measured)", m.name()),
                points,
                Style::Line,
                c,
            ));
        }
    }
    // Predicted stable steps as functions of (k, ω_max, m), with a legend and a colour.
    type Prediction = (&'static str, fn(f64, f64, f64) -> f64, usize);
    let predictions: [Prediction; 3] = [
        ("2/ω_max (Verlet)", |_, w, _| 2.0 / w, 3),
        (
            "2√2/ω_max (RK4)",
            |_, w, _| 2.0 * std::f64::consts::SQRT_2 / w,
            2,
        ),
        (
            "0.4π√(m/k) (rule quoted by the study)",
            |k, _, m| 0.4 * std::f64::consts::PI * (m / k).sqrt(),
            7,
        ),
    ];
    for (name, f, c) in &predictions {
        chart.series.push(Series::new(
            *name,
            ks.iter().map(|&(k, w, m)| (k, f(k, w, m))).collect(),
            Style::Dashed,
            *c,
        ));
    }
    chart.write_svg(&out.join("integrators-stability.svg"))?;
    let _ = writeln!(
        md,
        "### Largest stable step (scene W, {0} × {0}, {1} s per try)\n\n![largest stable step against stiffness]({folder}/integrators-stability.svg)\n",
        cfg.stability_n, cfg.stability_duration
    );
    let _ = write!(
        md,
        "| k [N/m] | ω_max [rad/s] | 2/ω_max | 2√2/ω_max | 0.4π√(m/k) |"
    );
    for m in &methods {
        let _ = write!(md, " {} |", m.name());
    }
    let _ = writeln!(md, "\n|{}", "---|".repeat(5 + methods.len()));
    for &(k, w, m) in &ks {
        let _ = write!(
            md,
            "| {k} | {w:.0} | {:.3e} | {:.3e} | {:.3e} |",
            2.0 / w,
            2.0 * std::f64::consts::SQRT_2 / w,
            0.4 * std::f64::consts::PI * (m / k).sqrt()
        );
        for method in &methods {
            let r = rows
                .iter()
                .find(|r| r.stiffness == k && r.method == method.name());
            let cell = match r.and_then(|r| r.largest_stable) {
                Some(h) if h >= 1.0 / FRAME_RATE => format!("≥ {h:.3e}"),
                Some(h) => format!("{h:.3e}"),
                None => "none".into(),
            };
            let _ = write!(md, " {cell} |");
        }
        md.push('\n');
    }
    md.push('\n');

    // 2. Cost to equilibrium against mesh size.
    let mut csv = String::from("particles,method,substeps,step_s,stable,blowup_step,blowup_time_s,blowup_reason,equilibrium_s,wall_per_simulated_s,wall_s,cg_per_step\n");
    let mut table = String::from("| particles | method | step [s] | result | equilibrium [s] | wall s per simulated s | wall s to equilibrium | CG iterations/step |\n|---|---|---|---|---|---|---|---|\n");
    let mut cost_points: Vec<(String, f64, f64)> = Vec::new();
    for &n in &cfg.sizes {
        let sys = StudyScene::WashingLine.build(n, 1.0);
        let (w, _) = highest_frequency(&sys);
        for (method, s) in cost_runs(2.0 / w) {
            let mut sys = StudyScene::WashingLine.build(n, 1.0);
            let o = simulate(
                &mut sys,
                method,
                s,
                StudyScene::WashingLine.duration(),
                true,
                |_| {},
            );
            let result = match &o.blowup {
                Some(b) => format!(
                    "unstable at step {} (t = {:.3} s): {}",
                    b.step, b.time, b.reason
                ),
                None => "stable".into(),
            };
            log(&format!(
                "cost n={n:<4} {:<16} {s:>5} steps/frame: {result}, equilibrium {:?}, {:.3} wall s per simulated s",
                method.name(),
                o.equilibrium,
                o.wall_per_second()
            ));
            let to_rest = o.equilibrium.map(|t| t * o.wall_per_second());
            let _ = writeln!(
                csv,
                "{},{},{s},{:e},{},{},{},\"{}\",{},{:e},{:e},{:.2}",
                o.particles,
                o.method,
                o.step,
                o.stable(),
                o.blowup
                    .as_ref()
                    .map_or(String::new(), |b| b.step.to_string()),
                o.blowup
                    .as_ref()
                    .map_or(String::new(), |b| b.time.to_string()),
                o.blowup
                    .as_ref()
                    .map_or(String::new(), |b| b.reason.clone()),
                o.equilibrium.map_or(String::new(), |t| t.to_string()),
                o.wall_per_second(),
                o.wall,
                o.cg_per_step
            );
            let _ = writeln!(
                table,
                "| {} | {} | {:.3e} | {} | {} | {:.3} | {} | {} |",
                o.particles,
                o.method,
                o.step,
                result,
                o.equilibrium
                    .map_or("not reached".into(), |t| format!("{t:.2}")),
                o.wall_per_second(),
                to_rest.map_or("—".into(), |t| format!("{t:.2}")),
                if method == Method::ImplicitEuler {
                    format!("{:.1}", o.cg_per_step)
                } else {
                    "—".into()
                }
            );
            if let Some(t) = to_rest {
                cost_points.push((o.method.clone(), o.particles as f64, t));
            }
        }
    }
    write_atomically(&out.join("integrators-cost.csv"), csv.as_bytes())?;
    let mut chart = Chart {
        title: "Scene W: wall time to equilibrium against mesh size".into(),
        x_label: "particles".into(),
        y_label: "wall time to equilibrium [s]".into(),
        x_log: true,
        y_log: true,
        ..Chart::default()
    };
    for (c, m) in methods.iter().enumerate() {
        let points: Vec<(f64, f64)> = cost_points
            .iter()
            .filter(|p| p.0 == m.name())
            .map(|p| (p.1, p.2))
            .collect();
        if !points.is_empty() {
            chart
                .series
                .push(Series::new(m.name(), points, Style::Line, c));
        }
    }
    if !chart.series.is_empty() {
        chart.write_svg(&out.join("integrators-cost.svg"))?;
    }
    let _ = writeln!(
        md,
        "### Cost to equilibrium (scene W)\n\nExplicit methods at 0.8 × their predicted limit (explicit Euler and midpoint at Verlet's), implicit Euler at one step per frame, Projective Dynamics ({PD_ITERATIONS} iterations) at 10 steps per frame. Equilibrium: the fastest particle below 1 mm/s for 10 frames.\n\n![wall time to equilibrium against particles]({folder}/integrators-cost.svg)\n\n{table}"
    );

    // 3. Accuracy against wall time, per scene.
    for &scene in &cfg.scenes {
        let window = cfg.accuracy_duration.min(scene.accuracy_window());
        let points = accuracy_study(
            scene,
            cfg.accuracy_n,
            window,
            cfg.reference_substeps,
            &accuracy_runs(),
        );
        let letter = scene.letter();
        let mut csv =
            String::from("scene,method,substeps,step_s,rms_error_m,wall_per_simulated_s\n");
        for p in &points {
            let _ = writeln!(
                csv,
                "{letter},{},{},{:e},{},{:e}",
                p.method,
                p.substeps,
                p.step,
                p.error.map_or(String::new(), |e| format!("{e:e}")),
                p.wall_per_second
            );
            log(&format!(
                "accuracy {letter} {:<16} {:>5} steps/frame: error {}, {:.4} wall s per simulated s",
                p.method,
                p.substeps,
                p.error.map_or("unstable".into(), |e| format!("{e:.3e} m")),
                p.wall_per_second
            ));
        }
        write_atomically(
            &out.join(format!("integrators-accuracy-{letter}.csv")),
            csv.as_bytes(),
        )?;
        let mut chart = Chart {
            title: format!(
                "Scene {letter} {0}×{0}: error against a converged reference vs. wall time",
                cfg.accuracy_n
            ),
            x_label: "wall seconds per simulated second".into(),
            y_label: "RMS distance to the reference [m]".into(),
            x_log: true,
            y_log: true,
            ..Chart::default()
        };
        let names: Vec<String> = accuracy_runs().iter().map(|(m, _)| m.name()).collect();
        for (c, name) in names.iter().enumerate() {
            let pts: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| &p.method == name)
                .filter_map(|p| p.error.map(|e| (p.wall_per_second, e)))
                .collect();
            if !pts.is_empty() {
                chart
                    .series
                    .push(Series::new(name.clone(), pts, Style::Line, c));
            }
        }
        chart.write_svg(&out.join(format!("integrators-accuracy-{letter}.svg")))?;
        let _ = writeln!(
            md,
            "### Accuracy against speed (scene {letter}, {0} × {0}, {1} s; reference RK4 at {2} steps per frame)\n\n![error against wall time]({folder}/integrators-accuracy-{letter}.svg)\n\n| method | steps/frame | RMS error [m] | wall s per simulated s |\n|---|---|---|---|",
            cfg.accuracy_n, window, cfg.reference_substeps
        );
        for p in &points {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.4} |",
                p.method,
                p.substeps,
                p.error.map_or("unstable".into(), |e| format!("{e:.2e}")),
                p.wall_per_second
            );
        }
        md.push('\n');
    }
    Ok(md)
}
