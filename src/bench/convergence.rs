//! The convergence study (`drape bench convergence`): total squared error (thesis eq. 4.1) after
//! each iteration of every solver, on scenes E and H and every backend present, with the wall
//! time each iteration costs, so error can be drawn against iterations and against time.
//!
//! Scene E relaxes its 5 × stretched cloth with the solver alone. Scene H is taken at frame 30 of
//! its default bake (a swinging cloth) and then advanced by one step of a whole frame (1/60 s)
//! with many iterations: the error a method reaches in a frame's time budget.
//!
//! Errors come from a run that records them after every sweep; times from separate runs without
//! recording, at 1 and at N iterations (the fastest of 20 and of 5 frames), so a frame costs
//! `fixed + k · per_iteration` for k iterations. Both backends are timed this way (on the GPU a frame is one submission and one
//! read-back, so per-iteration times there include no round trip).

use super::chart::{write_atomically, Chart, Series, Style};
use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use crate::scene::{reference, Scene, SolverKind};
use crate::sim::Simulation;
use std::path::Path;
use std::time::Instant;

/// A solver configuration of the study.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Method {
    pub kind: SolverKind,
    pub omega: f32,
}

impl Method {
    /// "rbgs", or "rbgs ω=1.7" with over-relaxation.
    pub fn label(&self) -> String {
        if self.omega == 1.0 {
            self.kind.name().to_string()
        } else {
            format!("{} ω={}", self.kind.name(), self.omega)
        }
    }
}

/// The methods every scene is measured with: sequential GS, Jacobi, red-black GS, red-black GS
/// with SOR ω = 1.7, PBD Jacobi.
pub const METHODS: [Method; 5] = [
    Method {
        kind: SolverKind::Gs,
        omega: 1.0,
    },
    Method {
        kind: SolverKind::Jacobi,
        omega: 1.0,
    },
    Method {
        kind: SolverKind::Rbgs,
        omega: 1.0,
    },
    Method {
        kind: SolverKind::Rbgs,
        omega: 1.7,
    },
    Method {
        kind: SolverKind::Pbd,
        omega: 1.0,
    },
];

/// Time budgets per frame the charts mark [ms].
pub const BUDGETS_MS: [f64; 4] = [1.0, 2.0, 4.0, 8.0];

/// The error curve and cost of one method on one scene and backend.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Curve {
    pub scene: String,
    pub backend: String,
    pub method: String,
    /// Total squared error [m²] before the first iteration (index 0) and after each one.
    pub errors: Vec<f64>,
    /// Wall time of one iteration [µs].
    pub us_per_iteration: f64,
    /// Wall time of a frame's work outside the iterations [µs].
    pub fixed_us: f64,
}

impl Curve {
    /// Iterations that fit in `budget_ms` (None when not even one does), capped at the curve's.
    pub fn iterations_in(&self, budget_ms: f64) -> Option<usize> {
        let k = ((budget_ms * 1e3 - self.fixed_us) / self.us_per_iteration).floor();
        (k >= 1.0).then(|| (k as usize).min(self.errors.len() - 1))
    }

    /// Wall time of a frame with `k` iterations [ms].
    pub fn time_ms(&self, k: usize) -> f64 {
        (self.fixed_us + k as f64 * self.us_per_iteration) * 1e-3
    }
}

/// Scene E, or scene H one frame = one step, each with `iterations` iterations of `method`.
pub fn study_scene(letter: char, method: Method, iterations: u32) -> Scene {
    let mut scene = match letter {
        'E' => reference::load(reference::ENLARGED_CLOTH, "enlarged_cloth.json"),
        _ => {
            let mut h = reference::load(reference::HANGING_CLOTH, "hanging_cloth.json");
            h.substeps = Some(1);
            h
        }
    };
    scene.solver.kind = method.kind;
    scene.solver.omega = method.omega;
    scene.solver.iterations = iterations;
    scene.solver.inner_iterations = 1;
    scene
}

/// Positions and velocities of scene H after `frames` frames of its default bake (storage order
/// of the model every H variant shares).
pub fn hanging_state(frames: u32) -> crate::sim::State {
    let mut sim = Simulation::new(&reference::load(
        reference::HANGING_CLOTH,
        "hanging_cloth.json",
    ))
    .expect("a reference scene builds");
    for _ in 0..frames {
        sim.step_frame();
    }
    sim.state
}

/// Frame of scene H the study starts from.
pub const HANGING_FRAME: u32 = 30;

/// Measures `method` on scene `letter` (E or H, H starting from `start`) with `iterations`
/// iterations, on the CPU (`gpu` None) or on a GPU opened by `gpu`.
pub fn measure(
    letter: char,
    method: Method,
    iterations: u32,
    start: Option<&crate::sim::State>,
    gpu: Option<&dyn Fn() -> Result<GpuContext>>,
) -> Result<Curve> {
    let make = |k: u32, record: bool| {
        let mut scene = study_scene(letter, method, k);
        scene.output.residuals = record;
        let mut sim = Simulation::new(&scene).expect("a reference scene builds");
        if let Some(s) = start {
            sim.state = s.clone();
        }
        sim
    };
    // Index 0 of a curve: the error where the iterations start, the inertial prediction
    // x + h·(f·v + g·h) of every free particle (just x without integration).
    let initial = {
        let sim = make(1, false);
        let (h, keep, gravity_step) = sim.integration_constants();
        let model = sim.model();
        let q: Vec<glam::Vec4> = (0..model.particle_count())
            .map(|i| {
                let x = sim.state.positions[i];
                if sim.integrating() && model.inv_mass[i] != 0.0 {
                    x + (sim.state.velocities[i] * keep + gravity_step) * h
                } else {
                    x
                }
            })
            .collect();
        crate::sim::metrics::constraint_error(model, &q).total_squared_error
    };
    let mut backend = "cpu".to_string();
    // Runs frames, after an untimed warm-up frame when `warm` (the state moves on; the cost of
    // a frame does not depend on it), and returns the fastest one's seconds: the least disturbed
    // by the rest of the machine.
    let mut frame = |sim: &mut Simulation, warm: bool, repeats: u32| -> Result<f64> {
        // Timed on the threads asked for, busy machine or not.
        sim.sharing = crate::sim::team::Sharing::whole_team();
        let mut b = match gpu {
            Some(open) => Backend::gpu(open()?, sim)?,
            None => Backend::Cpu,
        };
        backend = b.name();
        if warm {
            b.step_frame(sim)?;
        }
        let mut best = f64::MAX;
        for _ in 0..repeats {
            let begin = Instant::now();
            b.step_frame(sim)?;
            best = best.min(begin.elapsed().as_secs_f64());
        }
        Ok(best)
    };
    let mut recorded = make(iterations, true);
    frame(&mut recorded, false, 1)?;
    let mut errors = vec![initial];
    errors.extend(recorded.residuals.take().unwrap_or_default());
    let one = frame(&mut make(1, false), true, 20)?;
    let many = frame(&mut make(iterations, false), true, 5)?;
    let per = ((many - one) / (iterations.max(2) - 1) as f64).max(1e-9);
    Ok(Curve {
        scene: letter.to_string(),
        backend,
        method: method.label(),
        errors,
        us_per_iteration: per * 1e6,
        fixed_us: ((one - per) * 1e6).max(0.0),
    })
}

/// Iterations red-black GS with over-relaxation `omega` needs on scene E to reach `target`
/// (None when it does not within `iterations`), with its error after all of them.
pub fn omega_sweep_point(omega: f32, iterations: u32, target: f64) -> (Option<usize>, f64) {
    let mut scene = study_scene(
        'E',
        Method {
            kind: SolverKind::Rbgs,
            omega,
        },
        iterations,
    );
    scene.output.residuals = true;
    let mut sim = Simulation::new(&scene).expect("a reference scene builds");
    sim.step_frame();
    let errors = sim.residuals.take().unwrap_or_default();
    (
        errors.iter().position(|&e| e <= target).map(|k| k + 1),
        errors.last().copied().unwrap_or(f64::NAN),
    )
}

/// What `drape bench convergence` measures.
#[derive(Clone, Debug)]
pub struct Config {
    /// Iterations per curve.
    pub iterations: u32,
    /// Scenes, 'E' and/or 'H'.
    pub scenes: Vec<char>,
    /// Also measure on a GPU (any adapter, software ones too) when one opens.
    pub gpu: bool,
    /// ω values of the over-relaxation sweep on scene E (empty: none).
    pub omegas: Vec<f32>,
}

impl Config {
    /// The full study the docs show.
    pub fn full() -> Config {
        Config {
            iterations: 200,
            scenes: vec!['E', 'H'],
            gpu: true,
            omegas: (0..20).map(|i| 1.0 + 0.05 * i as f32).collect(),
        }
    }

    /// A reduced study for tests: 20 iterations, three ω.
    pub fn quick() -> Config {
        Config {
            iterations: 20,
            scenes: vec!['E', 'H'],
            gpu: true,
            omegas: vec![1.0, 1.5, 1.9],
        }
    }
}

/// Runs the study, writes CSV and SVG charts into `out` and returns the Markdown section that
/// describes them (image paths relative to `out`'s parent, as `docs/` holds them).
// Long: the study in order (reference runs, each solver and backend, charts, the Markdown)
// sharing its measurements; each step is a few lines.
pub fn report(cfg: &Config, out: &Path, log: &mut dyn FnMut(&str)) -> Result<String> {
    use std::fmt::Write as _;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, "cannot create", e))?;
    let folder = out
        .file_name()
        .map_or("bench".into(), |f| f.to_string_lossy().into_owned());
    let open = || GpuContext::new(false);
    let gpu: Option<&dyn Fn() -> Result<GpuContext>> = match cfg.gpu {
        true => match open() {
            Ok(_) => Some(&open),
            Err(e) => {
                log(&format!("no GPU backend: {e}"));
                None
            }
        },
        false => None,
    };
    let mut md = String::new();
    let mut budgets_csv = String::from("scene,backend,method,budget_ms,iterations,error_m2\n");
    for &letter in &cfg.scenes {
        let start = (letter == 'H').then(|| hanging_state(HANGING_FRAME));
        let mut curves = Vec::new();
        for backend in [None, gpu].into_iter().enumerate() {
            let (index, open) = backend;
            if index == 1 && open.is_none() {
                continue;
            }
            for method in METHODS {
                if open.is_some() && method.kind == SolverKind::Gs {
                    continue; // sequential Gauss-Seidel has no GPU form
                }
                let curve = measure(letter, method, cfg.iterations, start.as_ref(), open)?;
                log(&format!(
                    "{letter} {:<28} {:<12} {:>9.1} µs/iteration, error {:.4e} → {:.4e}",
                    curve.backend,
                    curve.method,
                    curve.us_per_iteration,
                    curve.errors[0],
                    curve.errors.last().copied().unwrap_or(f64::NAN)
                ));
                curves.push(curve);
            }
        }
        let mut csv = String::from("scene,backend,method,iteration,error_m2,time_ms\n");
        for c in &curves {
            for (k, e) in c.errors.iter().enumerate() {
                let _ = writeln!(
                    csv,
                    "{letter},{},{},{k},{e:e},{:.4}",
                    c.backend,
                    c.method,
                    c.time_ms(k)
                );
            }
        }
        write_atomically(
            &out.join(format!("convergence-{letter}.csv")),
            csv.as_bytes(),
        )?;
        charts(letter, &curves, out)?;
        let _ = writeln!(
            md,
            "### Scene {letter}{}\n",
            if letter == 'H' {
                format!(" (frame {HANGING_FRAME}, one step of 1/60 s)")
            } else {
                String::new()
            }
        );
        let _ = writeln!(
            md,
            "![error against iterations]({folder}/convergence-{letter}-iterations.svg)\n"
        );
        for backend in curves
            .iter()
            .map(|c| backend_tag(&c.backend))
            .collect::<std::collections::BTreeSet<_>>()
        {
            let _ = writeln!(
                md,
                "![error against time, {backend}]({folder}/convergence-{letter}-time-{backend}.svg)\n"
            );
        }
        let _ = writeln!(
            md,
            "| backend | method | µs/iteration | fixed µs/frame | error after 10 | after 50 | after {} | iterations (error) in 1 ms | 2 ms | 4 ms | 8 ms |",
            cfg.iterations
        );
        let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|");
        for c in &curves {
            let at = |k: usize| c.errors.get(k).map_or("—".into(), |e| format!("{e:.3e}"));
            let _ = write!(
                md,
                "| {} | {} | {:.1} | {:.0} | {} | {} | {} |",
                c.backend,
                c.method,
                c.us_per_iteration,
                c.fixed_us,
                at(10),
                at(50),
                at(cfg.iterations as usize)
            );
            for budget in BUDGETS_MS {
                match c.iterations_in(budget) {
                    Some(k) => {
                        let capped = if k == c.errors.len() - 1 { "≥" } else { "" };
                        let _ = write!(md, " {capped}{k} ({:.3e}) |", c.errors[k]);
                        let _ = writeln!(
                            budgets_csv,
                            "{letter},{},{},{budget},{k},{:e}",
                            c.backend, c.method, c.errors[k]
                        );
                    }
                    None => {
                        let _ = write!(md, " 0 |");
                        let _ = writeln!(
                            budgets_csv,
                            "{letter},{},{},{budget},0,",
                            c.backend, c.method
                        );
                    }
                }
            }
            md.push('\n');
        }
        md.push('\n');
        if letter == 'E' && !cfg.omegas.is_empty() {
            md.push_str(&omega_section(cfg, &curves, out, &folder, log)?);
        }
    }
    write_atomically(&out.join("convergence-budgets.csv"), budgets_csv.as_bytes())?;
    Ok(md)
}

/// "cpu" or "gpu" for file names.
fn backend_tag(backend: &str) -> &'static str {
    if backend.starts_with("gpu") {
        "gpu"
    } else {
        "cpu"
    }
}

/// Colour of a method in every chart.
fn colour_of(method: &str) -> usize {
    METHODS
        .iter()
        .position(|m| m.label() == method)
        .unwrap_or(METHODS.len())
}

/// Error against iterations (both backends) and error against time (one chart per backend,
/// with the time budgets and the iterations each method fits in them).
fn charts(letter: char, curves: &[Curve], out: &Path) -> Result<()> {
    let mut by_iteration = Chart {
        title: format!("Scene {letter}: total squared error per iteration"),
        x_label: "iterations".into(),
        y_label: "total squared error [m²]".into(),
        y_log: true,
        ..Chart::default()
    };
    for c in curves {
        let gpu = backend_tag(&c.backend) == "gpu";
        by_iteration.series.push(Series::new(
            format!("{} ({})", c.method, backend_tag(&c.backend)),
            c.errors
                .iter()
                .enumerate()
                .map(|(k, &e)| (k as f64, e))
                .collect(),
            if gpu { Style::Dashed } else { Style::Line },
            colour_of(&c.method),
        ));
    }
    by_iteration.write_svg(&out.join(format!("convergence-{letter}-iterations.svg")))?;
    for tag in ["cpu", "gpu"] {
        let mine: Vec<&Curve> = curves
            .iter()
            .filter(|c| backend_tag(&c.backend) == tag)
            .collect();
        if mine.is_empty() {
            continue;
        }
        let mut chart = Chart {
            title: format!(
                "Scene {letter}: error against wall time per frame ({})",
                mine[0].backend
            ),
            x_label: "wall time per frame [ms]".into(),
            y_label: "total squared error [m²]".into(),
            x_log: true,
            y_log: true,
            guides: BUDGETS_MS.iter().map(|&b| (b, format!("{b} ms"))).collect(),
            ..Chart::default()
        };
        for c in mine {
            let mut s = Series::new(
                c.method.clone(),
                (1..c.errors.len())
                    .map(|k| (c.time_ms(k), c.errors[k]))
                    .collect(),
                Style::Line,
                colour_of(&c.method),
            );
            // The iterations each budget buys, once per distinct count (budgets past the end of
            // the curve all buy its last iteration).
            let mut noted = None;
            for budget in BUDGETS_MS {
                if let Some(k) = c.iterations_in(budget).filter(|&k| Some(k) != noted) {
                    s.notes
                        .push((c.time_ms(k), c.errors[k], format!(" {k} it")));
                    noted = Some(k);
                }
            }
            chart.series.push(s);
        }
        chart.write_svg(&out.join(format!("convergence-{letter}-time-{tag}.svg")))?;
    }
    Ok(())
}

/// The over-relaxation sweep on scene E: iterations to reach the error sequential GS reaches in
/// all of the study's iterations, against ω.
fn omega_section(
    cfg: &Config,
    curves: &[Curve],
    out: &Path,
    folder: &str,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    use std::fmt::Write as _;
    let Some(gs) = curves.iter().find(|c| c.method == "gs") else {
        return Ok(String::new());
    };
    let target = *gs.errors.last().expect("at least the start");
    let mut csv = String::from("omega,iterations_to_target,error_after_all\n");
    let mut points = Vec::new();
    let mut md = format!(
        "Over-relaxation on scene E: iterations red-black GS with SOR needs to reach the error \
         sequential GS reaches in {} iterations ({target:.4e} m²).\n\n\
         ![iterations against omega]({folder}/convergence-E-omega.svg)\n\n| ω | iterations | error after {} |\n|---|---|---|\n",
        cfg.iterations, cfg.iterations
    );
    for &omega in &cfg.omegas {
        let (k, last) = omega_sweep_point(omega, cfg.iterations, target);
        log(&format!(
            "E rbgs ω={omega:.2}: {k:?} iterations to the GS target, {last:.4e} after all"
        ));
        let _ = writeln!(
            csv,
            "{omega},{},{last:e}",
            k.map_or(String::new(), |k| k.to_string())
        );
        let _ = writeln!(
            md,
            "| {omega:.2} | {} | {last:.4e} |",
            k.map_or(format!("> {}", cfg.iterations), |k| k.to_string())
        );
        if let Some(k) = k {
            points.push((omega as f64, k as f64));
        }
    }
    md.push('\n');
    write_atomically(&out.join("convergence-E-omega.csv"), csv.as_bytes())?;
    Chart {
        title: "Scene E: red-black GS with SOR, iterations to sequential GS's final error".into(),
        x_label: "ω".into(),
        y_label: "iterations".into(),
        y_log: true,
        series: vec![Series::new("rbgs + SOR", points, Style::Line, 2)],
        ..Chart::default()
    }
    .write_svg(&out.join("convergence-E-omega.svg"))?;
    Ok(md)
}
