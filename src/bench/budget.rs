//! `drape bench budget`: scenes baked as shipped (hand-tuned substeps and iterations) against the
//! same scenes with accuracy targets choosing the budget (`bake::budget`): ms per frame, worst
//! strain and deepest penetration side by side, as a table, a CSV and a chart of strain against
//! time (the axes of the other speed-against-accuracy charts). The table goes into
//! `docs/accuracy-vs-speed.md` between markers that `drape bench docs` keeps.

use super::chart::{write_atomically, Chart, Series, Style};
use crate::error::{Error, Result};
use crate::scene::{AccuracySpec, Scene};
use std::path::Path;

/// Where the table sits in `accuracy-vs-speed.md`.
pub const BEGIN: &str = "<!-- drape bench budget -->";
pub const END: &str = "<!-- /drape bench budget -->";

/// One bake of the comparison.
struct Case {
    scene: String,
    setting: String,
    ms_per_frame: f64,
    max_strain: f64,
    deepest: f32,
    met: Option<bool>,
    /// Why the bake stopped early, and at which frame (the other figures cover the frames
    /// before it).
    failed: Option<String>,
}

/// The scenes compared: a label and the scene.
fn scenes(root: &Path, cache: &Path) -> Result<Vec<(String, Scene)>> {
    let load = |f: &str| Scene::load(&root.join("scenes").join(f));
    Ok(vec![
        ("H".into(), load("hanging_cloth.json")?),
        ("P".into(), Scene::default_scene(cache)?),
        ("curtain".into(), load("curtain.json")?),
        ("flag".into(), load("flag.json")?),
    ])
}

/// How a scene is baked in the comparison: as shipped, with targets (its own substeps and
/// iterations left to the budget), or at fixed substeps × iterations.
struct Setting {
    name: String,
    accuracy: Option<AccuracySpec>,
    fixed: Option<(u32, u32)>,
}

/// The settings each scene is baked with: as shipped, then targets; for P also the cheapest
/// fixed budget of the ladder whose worst strain comes to 5 % (what a user tuning by hand would
/// have to pick), so the 5 % targets compare with a setting of their accuracy.
fn settings(label: &str) -> Vec<Setting> {
    let setting = |name: &str, accuracy, fixed| Setting {
        name: name.into(),
        accuracy,
        fixed,
    };
    let target = |strain: f32, depth: Option<f32>| {
        Some(AccuracySpec {
            max_strain: Some(strain),
            max_penetration: depth,
            max_shear: None,
        })
    };
    let mut v = vec![
        setting("as shipped", None, None),
        setting("max_strain 10 %", target(0.10, None), None),
        setting("max_strain 5 %", target(0.05, None), None),
    ];
    if label == "P" {
        // Half the shell's radius (1 cm).
        v.push(setting("5 % and 5 mm", target(0.05, Some(0.005)), None));
        v.push(setting("fixed 40 × 20", None, Some((40, 20))));
    }
    v
}

/// Bakes every scene and setting for `frames` frames (None: each scene's own), writes
/// `out/budget.csv` and `out/budget.svg`, and returns the Markdown section.
pub fn run(
    root: &Path,
    out: &Path,
    frames: Option<u32>,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, "cannot create", e))?;
    let work = out.join(format!(".budget-{}", std::process::id()));
    let result = (|| {
        let mut cases = Vec::new();
        for (label, scene) in scenes(root, &work.join("mannequin"))? {
            for setting in settings(&label) {
                let case = bake_case(&label, &scene, &setting, frames, &work)?;
                log(&format!(
                    "{label} {}: {:.2} ms/frame, worst strain {:.2} %, deepest {:.2} mm{}",
                    case.setting,
                    case.ms_per_frame,
                    case.max_strain * 100.0,
                    case.deepest * 1e3,
                    case.failed
                        .as_ref()
                        .map_or(String::new(), |f| format!(" ({f})"))
                ));
                cases.push(case);
            }
        }
        Ok(cases)
    })();
    let _ = std::fs::remove_dir_all(&work);
    let cases = result?;
    let mut csv =
        String::from("scene,setting,ms_per_frame,max_strain,deepest_penetration_m,met,failed\n");
    for c in &cases {
        csv.push_str(&format!(
            "{},{},{:.4},{:.6},{:.6},{},{}\n",
            c.scene,
            c.setting,
            c.ms_per_frame,
            c.max_strain,
            c.deepest,
            c.met.map_or("".into(), |m| m.to_string()),
            c.failed.is_some()
        ));
    }
    write_atomically(&out.join("budget.csv"), csv.as_bytes())?;
    chart(&cases).write_svg(&out.join("budget.svg"))?;
    Ok(table(&cases))
}

/// One bake of `scene` with `setting` on the CPU, no files but the report.
fn bake_case(
    label: &str,
    scene: &Scene,
    setting: &Setting,
    frames: Option<u32>,
    work: &Path,
) -> Result<Case> {
    let mut s = super::report_only(scene, frames);
    if setting.accuracy.is_some() {
        s.substeps = None;
        s.timestep = None;
        s.iterations_given = false;
    }
    if let Some((substeps, iterations)) = setting.fixed {
        s.substeps = Some(substeps);
        s.timestep = None;
        s.solver.iterations = iterations;
        s.iterations_given = true;
    }
    s.accuracy = setting.accuracy.clone();
    let name = format!("{label} ({})", setting.name);
    let r = super::bake_report(&s, name, None, work)?;
    let deepest = r
        .worst_penetrations
        .iter()
        .map(|p| p.penetration.deepest)
        .chain(
            r.worst_mesh_penetrations
                .iter()
                .map(|m| m.penetration.deepest),
        )
        .fold(0.0f32, f32::max);
    Ok(Case {
        scene: label.to_string(),
        setting: setting.name.clone(),
        ms_per_frame: r.ms_per_frame.mean,
        max_strain: r.worst_frame.as_ref().map_or(0.0, |w| w.max_strain),
        deepest,
        met: r.budget.as_ref().map(|b| b.met),
        failed: r.failure.as_ref().map(|f| {
            format!(
                "unstable at frame {} of {}: {}",
                f.frame, r.frames_requested, f.reason
            )
        }),
    })
}

fn table(cases: &[Case]) -> String {
    let mut md = String::from(
        "| scene | setting | ms per frame (mean) | worst strain | deepest penetration | targets met |\n|---|---|---|---|---|---|\n",
    );
    for c in cases {
        let met = match (&c.failed, c.met) {
            (Some(why), _) => format!("**no: {why}**"),
            (None, None) => "—".into(),
            (None, Some(true)) => "yes".into(),
            (None, Some(false)) => "**no**".into(),
        };
        md.push_str(&format!(
            "| {} | {} | {:.2} | {:.2} % | {:.2} mm | {met} |\n",
            c.scene,
            c.setting,
            c.ms_per_frame,
            c.max_strain * 100.0,
            c.deepest * 1e3,
        ));
    }
    md
}

/// Worst strain against ms per frame, a series per scene, each point named by its setting.
fn chart(cases: &[Case]) -> Chart {
    let mut series: Vec<Series> = Vec::new();
    for c in cases {
        let point = (c.ms_per_frame, (c.max_strain * 100.0).max(1e-3));
        match series.iter_mut().find(|s| s.name == c.scene) {
            Some(s) => s.points.push(point),
            None => {
                let colour = series.len();
                series.push(Series::new(
                    c.scene.clone(),
                    vec![point],
                    Style::Points,
                    colour,
                ));
            }
        }
        let s = series
            .iter_mut()
            .find(|s| s.name == c.scene)
            .expect("just added");
        s.notes.push((point.0, point.1, c.setting.clone()));
    }
    Chart {
        title: "Accuracy targets against the shipped settings".into(),
        x_label: "ms per frame (CPU)".into(),
        y_label: "worst strain [%]".into(),
        x_log: true,
        y_log: true,
        series,
        ..Chart::default()
    }
}
