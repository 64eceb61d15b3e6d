//! `drape bench characters`: every shipped character scene against free cloth on the same model
//! (scene H with shear springs, and H with the garments' bend springs too), per
//! particle-iteration and per spring-iteration, on each thread
//! count asked for, with each scene's stages: issue 37's benchmark as a command. Rounds are
//! interleaved (every scene once per round) and each ratio is taken within its round, since a
//! shared machine's speed drifts between rounds more than between two bakes of one round; the
//! table also gives each scene's least time over the rounds against H's least (a busy machine
//! only adds time, so the least is each bake at its quietest). Every bake keeps the threads it
//! is given (`BakeOptions::fixed_team`).

use super::chart::write_atomically;
use crate::error::{Error, Result};
use crate::report::Report;
use crate::scene::Scene;
use std::path::Path;

/// The free cloth every ratio is to: H with shear springs (the peers' model).
const REFERENCE: &str = "hanging_cloth_shear.json";

/// The label of H on the garments' own model: the reference with bend springs added at the
/// shipped garments' bend stiffness ([`GARMENT_BEND`]), so it has as many springs per particle
/// as they do (5.9 against their 5.5–6.2). Each scene's ratio to it is the cost of its
/// character alone: collisions, self-collisions, shells and a small garment's barriers.
const SAME_MODEL: &str = "H with shear and bend springs";

/// The shipped garments' bend stiffness [N/m].
const GARMENT_BEND: f32 = 20.0;

/// The character scenes timed (besides P, the embedded default): the dressed garments, the
/// small fast character (RobotExpressive at 0.91 m, running) and the flat-shaded CesiumMan.
const CHARACTER_SCENES: [&str; 7] = [
    "cape_walk.json",
    "robot_cape_run.json",
    "skirt_walk.json",
    "top_walk.json",
    "blanket_run.json",
    "poncho_walk.json",
    "poncho_walk_flat.json",
];

/// What the bench runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Interleaved rounds.
    pub rounds: u32,
    /// Thread counts, each timed in every round.
    pub threads: Vec<usize>,
    /// Frames of every scene (None: each scene's own).
    pub frames: Option<u32>,
    /// H and `cape_walk` only, without its pre-roll (a check that the bench runs, in seconds).
    pub quick: bool,
}

/// One bake's figures.
struct Timed {
    threads: usize,
    round: u32,
    particles: usize,
    springs: usize,
    /// Particle-iterations per frame: substeps × outer × inner iterations.
    work: u64,
    ms_per_frame: f64,
    /// Per frame [ms]: the solve, and the collision passes, particle collisions, `finish` and
    /// shells together.
    solve: f64,
    collisions: f64,
    hash: String,
    /// The share of the team's waits that spun out (None on one thread): how busy the machine
    /// was ([`crate::report::Backend::team_waits_asleep`]).
    asleep: Option<f64>,
}

impl Timed {
    fn of(report: &Report, round: u32, threads: usize) -> Timed {
        let stage = |name: &str| {
            (report.stages_ms.iter())
                .find(|s| s.stage == name)
                .map_or(0.0, |s| s.per_frame)
        };
        let s = &report.solver;
        Timed {
            threads,
            round,
            particles: report.particles,
            springs: report.springs,
            work: report.substeps as u64 * s.iterations as u64 * s.inner_iterations as u64,
            ms_per_frame: report.ms_per_frame.median,
            solve: stage("solve"),
            collisions: ["contact_pass", "particle_collisions", "finish", "shells"]
                .iter()
                .map(|n| stage(n))
                .sum(),
            hash: report.frames_hash.clone(),
            asleep: report.backend.team_waits_asleep,
        }
    }

    /// ns per particle-iteration.
    fn per_particle(&self) -> f64 {
        self.ms_per_frame * 1e6 / (self.particles as f64 * self.work as f64)
    }

    /// ns per spring-iteration.
    fn per_spring(&self) -> f64 {
        self.ms_per_frame * 1e6 / (self.springs as f64 * self.work as f64)
    }
}

/// The scenes of the bench, H first: a label and the scene.
fn scenes(root: &Path, cache: &Path, quick: bool) -> Result<Vec<(String, Scene)>> {
    let load = |f: &str| Scene::load(&root.join("scenes").join(f));
    let reference = load(REFERENCE)?;
    let mut bent = reference.clone();
    bent.name = "hanging_cloth_shear_bend".into();
    bent.garments
        .iter_mut()
        .for_each(|g| g.stiffness.bend = GARMENT_BEND);
    let mut v = vec![
        ("H with shear springs".to_string(), reference),
        (SAME_MODEL.to_string(), bent),
    ];
    if quick {
        let mut cape = load("cape_walk.json")?;
        cape.characters.iter_mut().for_each(|c| c.preroll = None);
        v.push(("cape_walk".into(), cape));
        return Ok(v);
    }
    v.push(("P".into(), Scene::default_scene(cache)?));
    for f in CHARACTER_SCENES {
        v.push((f.trim_end_matches(".json").to_string(), load(f)?));
    }
    Ok(v)
}

/// Bakes every scene on every thread count, `options.rounds` times interleaved; writes
/// `out/characters.csv` (a row per bake) and returns the Markdown table (medians over the
/// rounds, ratios to H taken within each round).
pub fn run(
    root: &Path,
    out: &Path,
    options: &Options,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, "cannot create", e))?;
    let work = out.join(format!(".characters-{}", std::process::id()));
    let result = (|| {
        let scenes = scenes(root, &work.join("mannequin"), options.quick)?;
        let mut timed = Vec::new();
        for round in 1..=options.rounds.max(1) {
            for (label, scene) in &scenes {
                for &threads in &options.threads {
                    let t = bake_one(label, scene, threads, round, options.frames, &work)?;
                    log(&format!(
                        "round {round}, {label}, {threads} thread(s): {:.2} ms/frame, {:.1} ns per particle-iteration{}",
                        t.ms_per_frame,
                        t.per_particle(),
                        t.asleep.map_or(String::new(), |a| format!(
                            ", {:.1} % of the team's waits spun out",
                            100.0 * a
                        ))
                    ));
                    timed.push((label.clone(), t));
                }
            }
        }
        Ok(timed)
    })();
    let _ = std::fs::remove_dir_all(&work);
    let timed = result?;
    write_atomically(&out.join("characters.csv"), csv(&timed).as_bytes())?;
    Ok(table(&timed, &options.threads))
}

/// One bake of `scene` on the CPU with `threads` threads, writing nothing but its report.
fn bake_one(
    label: &str,
    scene: &Scene,
    threads: usize,
    round: u32,
    frames: Option<u32>,
    work: &Path,
) -> Result<Timed> {
    let s = super::report_only(scene, frames);
    let name = format!("{label} (bench characters)");
    let report = super::bake_report(&s, name, Some(threads), work)?;
    Ok(Timed::of(&report, round, threads))
}

fn csv(timed: &[(String, Timed)]) -> String {
    let mut csv = String::from(
        "scene,threads,round,particles,springs,particle_iterations_per_frame,ms_per_frame,ns_per_particle_iteration,ns_per_spring_iteration,solve_ms,collisions_and_shells_ms,frames_hash,team_waits_asleep\n",
    );
    for (label, t) in timed {
        csv.push_str(&format!(
            "{label},{},{},{},{},{},{:.4},{:.3},{:.4},{:.4},{:.4},{},{}\n",
            t.threads,
            t.round,
            t.particles,
            t.springs,
            t.work,
            t.ms_per_frame,
            t.per_particle(),
            t.per_spring(),
            t.solve,
            t.collisions,
            t.hash,
            t.asleep.map_or(String::new(), |a| format!("{a:.4}")),
        ));
    }
    csv
}

/// The median of `values` (0 for none).
fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    match n % 2 {
        1 => values[n / 2],
        _ => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// A row per scene and thread count: medians over the rounds; ratios to H's bake of the same
/// round and thread count.
fn table(timed: &[(String, Timed)], threads: &[usize]) -> String {
    let mut md = String::from(
        "| scene | threads | particles | springs per particle | ms/frame (median) | ns per particle-iteration (× H) | × H with bend springs | × H with bend springs, least | ns per spring-iteration (× H) | collisions and shells × solve | team waits spun out (most) | frames hash |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    // The bake labelled `reference` of the same round and thread count.
    let bake_of = |reference: &str, round: u32, threads: usize| {
        (timed.iter())
            .find(|(l, t)| l == reference && t.round == round && t.threads == threads)
            .map(|(_, t)| t)
    };
    let reference = timed.first().map_or("", |(h, _)| h.as_str());
    let mut labels: Vec<&String> = Vec::new();
    for (label, _) in timed {
        if !labels.contains(&label) {
            labels.push(label);
        }
    }
    for label in labels {
        for &n in threads {
            let runs: Vec<&Timed> = (timed.iter())
                .filter(|(l, t)| l == label && t.threads == n)
                .map(|(_, t)| t)
                .collect();
            let Some(first) = runs.first() else { continue };
            let ratio_to = |to: &str, f: fn(&Timed) -> f64| {
                median(
                    (runs.iter())
                        .filter_map(|t| bake_of(to, t.round, n).map(|h| f(t) / f(h)))
                        .collect(),
                )
            };
            let ratio = |f: fn(&Timed) -> f64| ratio_to(reference, f);
            // The least over the rounds against the reference's least: each at its quietest
            // (a busy machine only adds time).
            let least_of = |label: &str| {
                (timed.iter())
                    .filter(|(l, t)| l == label && t.threads == n)
                    .map(|(_, t)| t.per_particle())
                    .reduce(f64::min)
            };
            let least = least_of(label)
                .zip(least_of(SAME_MODEL))
                .map_or(f64::NAN, |(a, b)| a / b);
            md.push_str(&format!(
                "| {label} | {n} | {} | {:.2} | {:.2} | {:.1} ({:.2}) | {:.2} | {least:.2} | {:.2} ({:.2}) | {:.2} | {} | {} |\n",
                first.particles,
                first.springs as f64 / first.particles as f64,
                median(runs.iter().map(|t| t.ms_per_frame).collect()),
                median(runs.iter().map(|t| t.per_particle()).collect()),
                ratio(Timed::per_particle),
                ratio_to(SAME_MODEL, Timed::per_particle),
                median(runs.iter().map(|t| t.per_spring()).collect()),
                ratio(Timed::per_spring),
                median(runs.iter().map(|t| t.collisions / t.solve.max(1e-9)).collect()),
                (runs.iter().filter_map(|t| t.asleep))
                    .reduce(f64::max)
                    .map_or("–".to_string(), |a| format!("{:.1} %", 100.0 * a)),
                first.hash,
            ));
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(Vec::new()), 0.0);
    }
}
