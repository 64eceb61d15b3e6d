//! `drape bench integrators`: runs the integrator study (`bench::integrators`) and writes its
//! CSV files, SVG charts and the Markdown tables of `docs/accuracy-vs-speed.md`, one section per
//! question: where each method becomes unstable (against stiffness, against mesh size, and where
//! the rule 0.4π√(m/k) holds), what reaching equilibrium costs, and how accurate each method is
//! for its wall time.

use super::chart::{write_atomically, Chart, Series, Style};
use super::integrators::{
    accuracy_study, rule_cases, simulate, stability_rows, stability_study, substeps_for,
    StabilityRow, StudyScene, FRAME_RATE,
};
use crate::error::{Error, Result};
use crate::massspring::integrate::Method;
use crate::massspring::spectrum::highest_frequency;
use std::fmt::Write as _;
use std::path::Path;

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
pub fn report(cfg: &Config, out: &Path, log: &mut dyn FnMut(&str)) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, "cannot create", e))?;
    let folder = out
        .file_name()
        .map_or("bench".into(), |f| f.to_string_lossy().into_owned());
    let mut md = String::new();
    md.push_str(&stiffness_section(cfg, out, &folder, log)?);
    md.push_str(&size_section(cfg, out, &folder, log)?);
    md.push_str(&rule_section(cfg, out, log)?);
    md.push_str(&cost_section(cfg, out, &folder, log)?);
    for &scene in &cfg.scenes {
        md.push_str(&accuracy_section(cfg, scene, out, &folder, log)?);
    }
    Ok(md)
}

/// Writes stability rows as CSV and logs them.
fn stability_csv(rows: &[StabilityRow], path: &Path, log: &mut dyn FnMut(&str)) -> Result<()> {
    let mut csv = String::from(
        "particles,stiffness_n_per_m,method,particle_mass_kg,omega_max,largest_stable_step_s\n",
    );
    for r in rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:e},{:.3},{}",
            r.particles,
            r.stiffness,
            r.method,
            r.particle_mass,
            r.omega_max,
            r.largest_stable.map_or(String::new(), |h| format!("{h:e}"))
        );
        log(&format!(
            "stability n={:<6} k={:<7} {:<16} ω_max {:>9.1}: largest stable step {}",
            r.particles,
            r.stiffness,
            r.method,
            r.omega_max,
            r.largest_stable
                .map_or("none".into(), |h| format!("{h:.3e} s"))
        ));
    }
    write_atomically(path, csv.as_bytes())
}

/// A stable-step cell: "≥ h" when the largest step tried (a whole frame) survived.
fn step_cell(h: Option<f64>) -> String {
    match h {
        Some(h) if h >= 1.0 / FRAME_RATE => format!("≥ {h:.3e}"),
        Some(h) => format!("{h:.3e}"),
        None => "none".into(),
    }
}

/// Predicted stable steps as functions of (k, ω_max, m), with a legend and a colour.
type Prediction = (&'static str, fn(f64, f64, f64) -> f64, usize);
const PREDICTIONS: [Prediction; 3] = [
    ("2/ω_max (Verlet)", |_, w, _| 2.0 / w, 3),
    (
        "2√2/ω_max (RK4)",
        |_, w, _| 2.0 * std::f64::consts::SQRT_2 / w,
        2,
    ),
    (
        "0.4π√(m/k) (the study's rule)",
        |k, _, m| 0.4 * std::f64::consts::PI * (m / k).sqrt(),
        7,
    ),
];

/// Chart and table of largest stable steps against `x` of each row (stiffness or particles),
/// measured per method and predicted.
fn stability_chart_and_table(
    rows: &[StabilityRow],
    methods: &[Method],
    x: fn(&StabilityRow) -> f64,
    (title, x_label, x_name): (&str, &str, &str),
    path: &Path,
) -> Result<String> {
    let mut chart = Chart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: "largest stable step h [s]".into(),
        x_log: true,
        y_log: true,
        legend_lower_left: true,
        ..Chart::default()
    };
    for m in methods {
        let colour = Method::all(PD_ITERATIONS)
            .iter()
            .position(|a| a == m)
            .unwrap_or(0);
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.method == m.name())
            .filter_map(|r| r.largest_stable.map(|h| (x(r), h)))
            .collect();
        if !points.is_empty() {
            chart.series.push(Series::new(
                format!("{} (measured)", m.name()),
                points,
                Style::Line,
                colour,
            ));
        }
    }
    let mut cases: Vec<&StabilityRow> = Vec::new();
    for r in rows {
        if !cases.iter().any(|c| x(c) == x(r)) {
            cases.push(r);
        }
    }
    for (name, f, c) in PREDICTIONS {
        chart.series.push(Series::new(
            name,
            cases
                .iter()
                .map(|r| (x(r), f(r.stiffness, r.omega_max, r.particle_mass)))
                .collect(),
            Style::Dashed,
            c,
        ));
    }
    chart.write_svg(path)?;
    let mut md = format!("| {x_name} | ω_max [rad/s] | 2/ω_max | 2√2/ω_max | 0.4π√(m/k) |");
    for m in methods {
        let _ = write!(md, " {} |", m.name());
    }
    let _ = writeln!(md, "\n|{}", "---|".repeat(5 + methods.len()));
    for case in cases {
        let _ = write!(md, "| {} | {:.0} |", x(case), case.omega_max);
        for (_, f, _) in PREDICTIONS {
            let _ = write!(
                md,
                " {:.3e} |",
                f(case.stiffness, case.omega_max, case.particle_mass)
            );
        }
        for m in methods {
            let h = rows
                .iter()
                .find(|r| x(r) == x(case) && r.method == m.name())
                .and_then(|r| r.largest_stable);
            let _ = write!(md, " {} |", step_cell(h));
        }
        md.push('\n');
    }
    md.push('\n');
    Ok(md)
}

/// Largest stable step of every method against stiffness, beside the predictions.
fn stiffness_section(
    cfg: &Config,
    out: &Path,
    folder: &str,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    let methods = Method::all(PD_ITERATIONS);
    let cases: Vec<(u32, f32)> = cfg
        .stiffness
        .iter()
        .map(|&k| (cfg.stability_n, k))
        .collect();
    let rows = stability_study(&cases, &methods, cfg.stability_duration);
    stability_csv(&rows, &out.join("integrators-stability.csv"), log)?;
    let table = stability_chart_and_table(
        &rows,
        &methods,
        |r| r.stiffness,
        (
            &format!(
                "Scene W {0}×{0}: largest stable step against stiffness",
                cfg.stability_n
            ),
            "structural stiffness k [N/m] (shear alike, bend a tenth)",
            "k [N/m]",
        ),
        &out.join("integrators-stability.svg"),
    )?;
    Ok(format!(
        "### Largest stable step against stiffness (scene W, {0} × {0}, {1} s per try)\n\n\
         ![largest stable step against stiffness]({folder}/integrators-stability.svg)\n\n{table}",
        cfg.stability_n, cfg.stability_duration
    ))
}

/// Verlet's and RK4's largest stable step against mesh size: ω_max grows with the grid edge.
fn size_section(
    cfg: &Config,
    out: &Path,
    folder: &str,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    let methods = [Method::Rk4, Method::Verlet];
    let cases: Vec<(u32, f32)> = cfg.sizes.iter().map(|&n| (n, 1.0)).collect();
    let rows = stability_study(&cases, &methods, cfg.stability_duration);
    stability_csv(&rows, &out.join("integrators-stability-sizes.csv"), log)?;
    let table = stability_chart_and_table(
        &rows,
        &methods,
        |r| r.particles as f64,
        (
            "Scene W: largest stable step against mesh size",
            "particles",
            "particles",
        ),
        &out.join("integrators-stability-sizes.svg"),
    )?;
    Ok(format!(
        "### Largest stable step against mesh size (scene W, {} s per try)\n\n\
         The particle mass falls as 1/n² with the grid edge n while the springs keep their \
         stiffness, so ω_max grows as n and the explicit step shrinks as 1/n. Explicit Euler \
         (no stable step), midpoint (far below these), implicit Euler and Projective Dynamics \
         (stiffness-independent) are in the stiffness table above.\n\n\
         ![largest stable step against particles]({folder}/integrators-stability-sizes.svg)\n\n{table}",
        cfg.stability_duration
    ))
}

/// Where the rule 0.4π√(m/k) holds: measured limits in units of √(m/k) on networks of growing
/// connectivity.
fn rule_section(cfg: &Config, out: &Path, log: &mut dyn FnMut(&str)) -> Result<String> {
    let rule = 0.4 * std::f64::consts::PI;
    let mut csv = String::from("case,omega_max_sqrt_m_over_k,verlet_limit_over_sqrt_m_over_k,rk4_limit_over_sqrt_m_over_k\n");
    let mut md = format!(
        "### Where the rule h < 0.4π√(m/k) holds\n\n\
         Largest stable steps measured on spring networks of growing connectivity, in units of \
         √(m/k) (the rule: {rule:.3}). The rule holds where a measured value is at least {rule:.3}.\n\n\
         | network | ω_max·√(m/k) | Verlet (theory 2/ω_max) | RK4 (theory 2√2/ω_max) | rule holds for |\n|---|---|---|---|---|\n"
    );
    for (name, sys) in rule_cases() {
        let unit = (sys.mass[0] / sys.springs[0].stiffness).sqrt();
        let rows = stability_rows(
            &|| sys.clone(),
            &[Method::Verlet, Method::Rk4],
            cfg.stability_duration,
        );
        let omega = rows[0].omega_max;
        let limit = |m: &str| {
            rows.iter()
                .find(|r| r.method == m)
                .and_then(|r| r.largest_stable)
                .map(|h| h / unit)
        };
        let (verlet, rk4) = (limit("verlet"), limit("rk4"));
        let holds: Vec<&str> = [("Verlet", verlet), ("RK4", rk4)]
            .iter()
            .filter(|(_, h)| h.is_some_and(|h| h >= rule))
            .map(|(n, _)| *n)
            .collect();
        let show = |h: Option<f64>, theory: f64| {
            h.map_or("none".into(), |h| format!("{h:.3} ({theory:.3})"))
        };
        let _ = writeln!(
            md,
            "| {name} | {:.3} | {} | {} | {} |",
            omega * unit,
            show(verlet, 2.0 / (omega * unit)),
            show(rk4, 2.0 * std::f64::consts::SQRT_2 / (omega * unit)),
            if holds.is_empty() {
                "neither".to_string()
            } else {
                holds.join(", ")
            }
        );
        let opt = |h: Option<f64>| h.map_or(String::new(), |h| format!("{h:.4}"));
        let _ = writeln!(
            csv,
            "{name},{:.4},{},{}",
            omega * unit,
            opt(verlet),
            opt(rk4)
        );
        log(&format!(
            "rule {name}: ω√(m/k) {:.3}, Verlet {:?}, RK4 {:?}",
            omega * unit,
            verlet,
            rk4
        ));
    }
    md.push_str("\nMeasured values are the largest step 1/(60·s) with s a whole number of steps per frame, so they sit at most one such increment below the true limit.\n\n");
    write_atomically(&out.join("integrators-rule.csv"), csv.as_bytes())?;
    Ok(md)
}

/// Wall time to equilibrium against mesh size.
// Long: the section's runs, table and chart share their measurements.
fn cost_section(
    cfg: &Config,
    out: &Path,
    folder: &str,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    let methods = Method::all(PD_ITERATIONS);
    let mut md = String::new();
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

    Ok(md)
}

/// Error against a converged reference against wall time, on one scene.
fn accuracy_section(
    cfg: &Config,
    scene: StudyScene,
    out: &Path,
    folder: &str,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    let mut md = String::new();
    {
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
            legend_lower_left: true,
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
