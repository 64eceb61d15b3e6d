//! The frame loop: step, tear, measure and write each frame as it is made (with a checkpoint
//! now and then), until the last, until the simulation becomes unstable or until a signal.

use super::budget::{BudgetReport, FrameBudget, Reading, Targets};
use super::checkpoint::{self, Measured, Progress};
use super::output::Exports;
use super::report::{collider_penetrations, frame_metrics, preroll_mesh, preroll_strain};
use super::warnings;
use crate::backend::Backend;
use crate::collide;
use crate::error::Result;
use crate::export::sequence::BakeMeshes;
use crate::report::{Failure, FrameCrossings, FramePenetrations, MeshPenetration, Report, Timing};
use crate::sim::schedule::{self, StageTimes};
use crate::sim::{metrics, Simulation};
use std::time::Instant;

/// Bakes `sim` on `backend` from the frame after `progress.baked` to
/// `report.frames_requested`, handing each frame to `exports` (as `meshes` shows it) and to
/// the `checkpoints` (with a checkpoint when one is due, and at the end); fills `report`'s
/// per-frame fields and stops at the first unstable frame (recorded in `report.failure`) or
/// after the frame a signal arrived in. Returns the time of the stages around the simulation's
/// own (tearing, metrics, export, checkpoints).
// Long: a frame's steps in order (step within the budget, tear, measure, hash and export, log
// and checkpoint, stop on a signal or `--until`), each a few lines.
pub fn run(
    sim: &mut Simulation,
    backend: &mut Backend,
    out: Out,
    mut progress: Progress,
    report: &mut Report,
    bar: &super::ticker::Ticker,
) -> Result<StageTimes> {
    let Out {
        meshes,
        exports,
        mut checkpoints,
        targets,
    } = out;
    let frames = report.frames_requested;
    let probes = MeshProbes::new(meshes);
    if progress.baked == 0 {
        progress.initial_energy = sim.energy();
        progress.hash = crate::character::cache::FNV_OFFSET;
        progress.worst = vec![
            collide::Penetration::default();
            sim.drivers.colliders.len() + sim.drivers.shells.len()
        ];
    }
    progress.measured.clone().apply(report);
    report.frames_baked = progress.baked;
    bar.inc(progress.baked as u64);
    let mut around = StageTimes::default();
    let lap = |times: &mut StageTimes, stage: &str, since: Instant| {
        times.lap(schedule::timed(stage), since);
    };
    for baked in progress.baked + 1..=frames {
        // The shot's number of this frame (`frame_start`): what files and the report show.
        let frame = report.frame_start + baked - 1;
        let start = Instant::now();
        let stop = || super::INTERRUPT.load(std::sync::atomic::Ordering::Relaxed) != 0;
        let whole = match targets {
            Some(t) => step_within(
                t,
                sim,
                backend,
                (meshes, &probes),
                (frame, baked - 1),
                &mut progress,
                &stop,
            )?,
            None => backend.step_frame_or_stop(sim, &stop)?,
        };
        if !whole {
            // Stopped inside the frame: the simulation is back where it started.
            report.interrupted = Some(crate::report::Interruption {
                signal: super::INTERRUPT.load(std::sync::atomic::Ordering::Relaxed),
                after_frame: frame.saturating_sub(1),
            });
            break;
        }
        count_gpu_work(backend, &mut progress);
        let tearing = Instant::now();
        if sim.tears() && sim.tear() > 0 {
            // The GPU takes the torn model (and the state it produced) afresh.
            backend.reload(sim)?;
            // From this frame on the garments have these faces (exports follow them).
            for g in meshes.tear(&sim.model().garments) {
                let faces = &sim.model().garments[g].triangles;
                exports.faces(g, baked as usize - 1, faces)?;
                if let Some(c) = checkpoints.as_deref_mut() {
                    c.faces(g, baked - 1, faces)?;
                }
            }
        }
        progress.frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        lap(&mut around, "tearing", tearing);

        let measuring = Instant::now();
        // The free particles, gathered once for every penetration count.
        let (free, held) = (sim.free_positions(), sim.held_positions());
        let (vertices, triangles) = meshes.garments_as_one(&sim.export_positions());
        let index = baked as usize - 1;
        // The three searches over meshes are independent: run side by side on the bake's
        // threads (each alone leaves much of a second core idle).
        let ((crossings, found), self_crossings) = rayon::join(
            || {
                rayon::join(
                    || collide::crossings::count(&vertices, &triangles),
                    || mesh_penetrations([&free, &held], (meshes, &probes), index),
                )
            },
            || probes.self_crossings(meshes, index),
        );
        report
            .crossings_per_frame
            .push(FrameCrossings { frame, crossings });
        let unstable = measure(sim, &free, (frame, crossings), &mut progress, report);
        measure_meshes(found, !held.is_empty(), frame, report);
        let colliders = &sim.drivers.colliders;
        if let Some(deepest_m) = sunk_into(colliders, meshes, index) {
            (report.character_in_colliders_per_frame)
                .push(crate::report::FrameCharacterDepth { frame, deepest_m });
        }
        if !self_crossings.is_empty() {
            (report.character_crossings_per_frame).push(crate::report::FrameSelfCrossings {
                frame,
                crossings: self_crossings,
            });
        }
        if let Some(r) = &sim.residuals {
            progress.residuals.push(r.clone());
        }
        lap(&mut around, "metrics", measuring);
        if let Some(reason) = unstable {
            report.failure = Some(Failure { frame, reason });
            break;
        }
        let exporting = Instant::now();
        let positions = sim.export_positions();
        progress.hash = positions.iter().fold(progress.hash, |h, p| {
            crate::character::cache::fnv(h, bytemuck::bytes_of(&p.to_array()))
        });
        if !exports.is_empty() {
            exports.frame(meshes.frame(baked as usize - 1, frame, &positions))?;
        }
        lap(&mut around, "export", exporting);
        report.frames_baked = baked;
        progress.baked = baked;
        bar.inc(1);
        if let Some(c) = checkpoints.as_deref_mut() {
            let writing = Instant::now();
            c.frame(baked - 1, &positions)?;
            if c.due(baked) {
                progress.measured = Measured::of(report);
                backend.sync_for_checkpoint(sim)?;
                c.write(frame, &sim.snapshot(), &progress)?;
            }
            lap(&mut around, "checkpoint", writing);
        }
        if report.until.is_some_and(|u| frame >= u) {
            break;
        }
        let signal = super::INTERRUPT.load(std::sync::atomic::Ordering::Relaxed);
        if signal != 0 && baked < frames {
            report.interrupted = Some(crate::report::Interruption {
                signal,
                after_frame: frame,
            });
            break;
        }
    }
    // Always a checkpoint at the end (not of a state that went unstable).
    if let Some(c) = checkpoints {
        if report.failure.is_none() && progress.baked > 0 {
            let writing = Instant::now();
            progress.measured = Measured::of(report);
            let frame = report.frame_start + progress.baked - 1;
            backend.sync_for_checkpoint(sim)?;
            c.write(frame, &sim.snapshot(), &progress)?;
            lap(&mut around, "checkpoint", writing);
        }
    }
    sum_up(sim, backend, targets, progress, report);
    Ok(around)
}

/// The report's fields over the whole bake, from the frame loop's running measures.
fn sum_up(
    sim: &Simulation,
    backend: &Backend,
    targets: Option<&Targets>,
    progress: Progress,
    report: &mut Report,
) {
    report.ms_per_frame = Timing::of(&progress.frame_ms);
    if let Some(p) = &mut report.preroll {
        p.ms = progress.frame_ms.iter().take(p.frames as usize).sum();
    }
    if backend.is_gpu() {
        let frames = (progress.frame_ms.len() as u64).max(1);
        report.gpu_upload_bytes_per_frame = Some(progress.uploaded / frames);
        report.gpu_dispatches_per_frame = Some(progress.dispatched as f64 / frames as f64);
        report.gpu_submissions_per_frame = Some(progress.submitted as f64 / frames as f64);
    }
    report.frames_hash = format!("{:016x}", progress.hash);
    if let Some(t) = targets {
        report.budget = Some(BudgetReport::of(t, &progress.budget_frames));
    }
    report.torn_springs = sim.torn_springs();
    report.stable = report.failure.is_none();
    report.worst_penetrations = collider_penetrations(&progress.worst);
    let found = warnings::at_the_end(report, sim.solver_settings().strain_limit);
    report.warnings.extend(found);
    if sim.residuals.is_some() {
        report.residuals = Some(progress.residuals);
    }
}

/// Where each frame goes: the meshes that show it, the exports and the checkpoints.
pub struct Out<'a> {
    pub meshes: &'a mut BakeMeshes,
    pub exports: &'a mut Exports,
    pub checkpoints: Option<&'a mut checkpoint::Writer>,
    /// Accuracy targets (or the stability rule alone, for a budget left to drape) that choose
    /// each frame's budget.
    pub targets: Option<&'a Targets>,
}

impl Measured {
    /// The report's per-frame fields so far.
    fn of(report: &Report) -> Measured {
        Measured {
            penetrations_per_frame: report.penetrations_per_frame.clone(),
            worst_mesh_penetrations: report.worst_mesh_penetrations.clone(),
            mesh_penetrations_per_frame: report.mesh_penetrations_per_frame.clone(),
            worst_held_mesh_penetrations: report.worst_held_mesh_penetrations.clone(),
            held_mesh_penetrations_per_frame: report.held_mesh_penetrations_per_frame.clone(),
            crossings_per_frame: report.crossings_per_frame.clone(),
            character_crossings_per_frame: report.character_crossings_per_frame.clone(),
            strain_limited_per_frame: report.strain_limited_per_frame.clone(),
            forced_strain_per_frame: report.forced_strain_per_frame.clone(),
            character_in_colliders_per_frame: report.character_in_colliders_per_frame.clone(),
            worst_frame: report.worst_frame.clone(),
            last_frame: report.last_frame.clone(),
            preroll: report.preroll.clone(),
        }
    }

    /// Puts these fields into `report`.
    fn apply(self, report: &mut Report) {
        report.penetrations_per_frame = self.penetrations_per_frame;
        report.worst_mesh_penetrations = self.worst_mesh_penetrations;
        report.mesh_penetrations_per_frame = self.mesh_penetrations_per_frame;
        report.worst_held_mesh_penetrations = self.worst_held_mesh_penetrations;
        report.held_mesh_penetrations_per_frame = self.held_mesh_penetrations_per_frame;
        report.crossings_per_frame = self.crossings_per_frame;
        report.character_crossings_per_frame = self.character_crossings_per_frame;
        report.strain_limited_per_frame = self.strain_limited_per_frame;
        report.forced_strain_per_frame = self.forced_strain_per_frame;
        report.character_in_colliders_per_frame = self.character_in_colliders_per_frame;
        report.worst_frame = self.worst_frame;
        report.last_frame = self.last_frame;
        if self.preroll.is_some() {
            report.preroll = self.preroll;
        }
    }
}

/// Steps frame `frame` (baked frame `index`) within the accuracy `targets`: simulated again
/// from its start state at the next budget while it misses one (up to the ladder's cap); the
/// next frame's budget one higher when this one came close, one lower after a calm stretch.
/// Records the frame's budget in `progress`. False when `stop` stopped it inside the frame:
/// then the simulation and the budget are back where the frame started. On the GPU the frame's
/// start (its nearby shell lists too) is read back first, each budget goes up with the state
/// it starts from, and a frame that settles runs on the CPU ([`step_frame_settled`]).
fn step_within(
    t: &Targets,
    sim: &mut Simulation,
    backend: &mut Backend,
    meshes: Shown,
    (frame, index): (u32, u32),
    progress: &mut Progress,
    stop: &dyn Fn() -> bool,
) -> Result<bool> {
    let index = index as usize;
    // The GPU keeps the nearby shell lists the next frame starts from: read back with its start.
    backend.sync_for_checkpoint(sim)?;
    let before = sim.snapshot();
    let budget_before = progress.budget.clone();
    let mut attempts = 1;
    let mut why = std::mem::take(&mut progress.budget.pending_why);
    let mut kept_missing = false;
    let reading = loop {
        let settling = progress.budget.settle > 0;
        if settling {
            sim.settle_frame();
        }
        if !step_frame_settled(sim, backend, settling, stop)? {
            sim.restore(&before)
                .expect("a simulation takes its own snapshot");
            progress.budget = budget_before;
            t.apply(sim, progress.budget.level);
            backend.upload(sim)?;
            return Ok(false);
        }
        let error = sim.constraint_error();
        let reading = accuracy_of(sim, &error, (!t.stability_only()).then_some(meshes), index);
        // A frame the stability rule rejects is simulated again at a higher budget too, while
        // there is one (the cheap end of the ladder can gain energy on stiff springs); one that
        // misses a target, while the budget may rise.
        let unstable = || {
            unstable_now(sim, &error, progress).map(|r| format!("the frame went unstable ({r})"))
        };
        let missed = match t.missed(reading) {
            Some(_)
                if t.excess(reading).is_finite()
                    && !progress.budget.may_raise()
                    && progress.budget.level + 1 < t.levels.len() =>
            {
                kept_missing = true;
                unstable()
            }
            Some(reason) => Some(reason),
            None => unstable(),
        };
        match missed {
            Some(reason) if progress.budget.level + 1 < t.levels.len() => {
                sim.restore(&before)
                    .expect("a simulation takes its own snapshot");
                progress.budget.raise();
                kept_missing = false;
                t.apply(sim, progress.budget.level);
                // The GPU starts the frame again from the state put back, at the new budget;
                // what the rejected attempt uploaded and launched counts too.
                count_gpu_work(backend, progress);
                backend.upload(sim)?;
                let (s, i) = t.levels[progress.budget.level];
                why = format!("{reason}: raised to {s} substeps × {i} iterations");
                attempts += 1;
            }
            _ => break reading,
        }
    };
    let settings = sim.solver_settings();
    progress.budget_frames.push(FrameBudget {
        frame,
        substeps: sim.substeps(),
        iterations: settings.iterations,
        contact_passes: settings.contact_passes,
        attempts,
        why,
        max_strain: reading.strain,
        deepest_penetration: reading.depth,
        max_shear_deg: reading.shear,
        settled_joules: if progress.budget.settle > 0 {
            sim.settled_energy()
        } else {
            0.0
        },
        kept_missing,
    });
    if let Some(why) = progress.budget.after_frame(t, reading) {
        t.apply(sim, progress.budget.level);
        // The GPU takes the next frames' budget (and keeps its nearby lists); what it did for
        // this frame is counted first.
        count_gpu_work(backend, progress);
        backend.reload(sim)?;
        progress.budget.pending_why = why;
    }
    Ok(true)
}

/// Steps one frame on `backend`, unless it is `settling` on the GPU, which does not cap a
/// frame's kinetic energy substep by substep: that frame runs on the CPU (the simulation is
/// the GPU's state, read back after every frame), and the GPU takes its end. False when
/// `stop` stopped it inside the frame.
fn step_frame_settled(
    sim: &mut Simulation,
    backend: &mut Backend,
    settling: bool,
    stop: &dyn Fn() -> bool,
) -> Result<bool> {
    if !(settling && backend.is_gpu()) {
        return backend.step_frame_or_stop(sim, stop);
    }
    let whole = sim.step_frame_or_stop(stop);
    backend.upload(sim)?;
    Ok(whole)
}

/// Adds what the GPU uploaded and launched for the last frame (or attempt at one) to
/// `progress` (nothing on the CPU).
fn count_gpu_work(backend: &Backend, progress: &mut Progress) {
    if let Some(bytes) = backend.uploaded_last_frame() {
        progress.uploaded += bytes;
    }
    if let Some((dispatches, submissions)) = backend.launches_last_frame() {
        progress.dispatched += u64::from(dispatches);
        progress.submitted += u64::from(submissions);
    }
}

/// The worst structural strain and cell shear of `sim` now and the deepest any free particle is
/// inside a collider, a shell or a character's mesh (at baked frame `index`) [m]; with no
/// `meshes` (a budget that answers to stability alone), no depth (0).
fn accuracy_of(
    sim: &Simulation,
    error: &metrics::ConstraintError,
    meshes: Option<Shown>,
    index: usize,
) -> Reading {
    let Some(meshes) = meshes else {
        return Reading {
            strain: error.solvable_strain(),
            depth: 0.0,
            shear: error.max_shear_deg,
        };
    };
    let free = sim.free_positions();
    let deepest = solid_penetrations(sim, &free)
        .into_iter()
        .chain(
            mesh_penetrations([&free, &[]], meshes, index)
                .into_iter()
                .map(|(_, [p, _])| p),
        )
        .map(|p| p.deepest)
        .fold(0.0f32, f32::max);
    Reading {
        strain: error.solvable_strain(),
        depth: deepest,
        shear: error.max_shear_deg,
    }
}

/// Why `sim` is unstable now by the stability rule (`scenes.md`), if it is.
fn unstable_now(
    sim: &Simulation,
    error: &metrics::ConstraintError,
    progress: &Progress,
) -> Option<String> {
    metrics::instability(
        &sim.state,
        error,
        &sim.energy(),
        &progress.initial_energy,
        sim.driven_energy() + sim.rounding_energy(),
        sim.integrating(),
    )
}

/// The `free` particles inside each collider, then inside each character's shell.
fn solid_penetrations(sim: &Simulation, free: &[glam::Vec4]) -> Vec<collide::Penetration> {
    let mut penetrations = collide::penetrations(&sim.drivers.colliders, free);
    penetrations.extend(sim.drivers.shells.iter().map(|s| s.penetration(free)));
    penetrations
}

/// The meshes a bake shows, with what the mesh metric keeps of them between frames.
type Shown<'m> = (&'m BakeMeshes, &'m MeshProbes);

/// Each character mesh's [`collide::mesh::Topology`], made once from its first frame (the
/// characters' triangles never change, and vertices welded there ride the same skin).
/// Per character: its mesh's welding (for the penetration metric) and where its triangles lay
/// when the bake started (for its crossings through itself).
struct MeshProbes(
    Vec<collide::mesh::Topology>,
    Vec<collide::crossings::SelfCrossings>,
);

impl MeshProbes {
    fn new(meshes: &BakeMeshes) -> MeshProbes {
        let made = meshes
            .characters_at(0)
            .map(|(_, vertices, triangles)| collide::mesh::Topology::new(vertices, triangles));
        let rest = (meshes.characters_on(0)).map(|(_, vertices, triangles)| {
            collide::crossings::SelfCrossings::new(vertices, triangles)
        });
        MeshProbes(made.collect(), rest.collect())
    }

    /// Each character's crossings through itself at baked frame `index` (none without
    /// characters).
    fn self_crossings(&self, meshes: &BakeMeshes, index: usize) -> Vec<usize> {
        (meshes.characters_at(index).zip(&self.1))
            .map(|((_, vertices, triangles), rest)| rest.count(vertices, triangles))
            .collect()
    }
}

/// The `free` and the `held` (pinned, attached) particles inside each character's own mesh
/// at baked frame `index`, by name: each mesh posed once for both.
fn mesh_penetrations<'m>(
    [free, held]: [&[glam::Vec4]; 2],
    (meshes, probes): Shown<'m>,
    index: usize,
) -> Vec<(&'m str, [collide::Penetration; 2])> {
    let mut characters = meshes.characters_at(index).peekable();
    if characters.peek().is_none() {
        return Vec::new();
    }
    let points =
        |set: &[glam::Vec4]| -> Vec<glam::Vec3> { set.iter().map(|p| p.truncate()).collect() };
    let (free, held) = (points(free), points(held));
    characters
        .zip(&probes.0)
        .map(|((name, vertices, _), topology)| {
            let surface = collide::mesh::Surface::posed(topology, vertices);
            let found = surface.penetrations(&[&free, &held]);
            (name, [found[0], found[1]])
        })
        .collect()
}

/// How deep each character's mesh at baked frame `index` is inside `colliders` [m]: its deepest
/// vertex's depth, 0 when none is inside; None without colliders or characters.
fn sunk_into(
    colliders: &[collide::Collider],
    meshes: &BakeMeshes,
    index: usize,
) -> Option<Vec<f32>> {
    if colliders.is_empty() {
        return None;
    }
    let depth = |vertices: &[glam::Vec3]| {
        (vertices.iter())
            .map(|&v| collide::deepest(colliders, v, 0.0).0)
            .fold(0.0f32, f32::max)
    };
    let deepest: Vec<f32> = (meshes.characters_at(index))
        .map(|(_, vertices, _)| depth(vertices))
        .collect();
    (!deepest.is_empty()).then_some(deepest)
}

/// Records the particles inside each character's own mesh at shot frame `frame` (`found`, free
/// and held) into `report`: the held ones apart (when there are any, `held`), since the
/// accuracy targets answer only for the free ones.
fn measure_meshes(
    found: Vec<(&str, [collide::Penetration; 2])>,
    held: bool,
    frame: u32,
    report: &mut Report,
) {
    let free: Vec<_> = found.iter().map(|&(name, [p, _])| (name, p)).collect();
    for (c, &(name, p)) in free.iter().enumerate() {
        preroll_mesh(report, frame, c, name, p);
    }
    let lists = (
        &mut report.worst_mesh_penetrations,
        &mut report.mesh_penetrations_per_frame,
    );
    record_meshes(free, frame, lists);
    if held {
        let lists = (
            &mut report.worst_held_mesh_penetrations,
            &mut report.held_mesh_penetrations_per_frame,
        );
        record_meshes(
            found.into_iter().map(|(n, [_, p])| (n, p)).collect(),
            frame,
            lists,
        );
    }
}

/// Adds frame `frame`'s penetrations per character (`found`) to a report's list of the worst
/// per character and its list per frame.
fn record_meshes(
    found: Vec<(&str, collide::Penetration)>,
    frame: u32,
    (worst, per_frame): (&mut Vec<MeshPenetration>, &mut Vec<FramePenetrations>),
) {
    if found.is_empty() {
        return;
    }
    let mut this = FramePenetrations {
        frame,
        inside: Vec::new(),
        deepest_m: Vec::new(),
    };
    for (c, (name, p)) in found.into_iter().enumerate() {
        this.inside.push(p.inside);
        this.deepest_m.push(p.deepest);
        if worst.len() <= c {
            worst.push(MeshPenetration {
                character: name.to_string(),
                penetration: collide::Penetration::default(),
            });
        }
        let w = &mut worst[c].penetration;
        w.inside = w.inside.max(p.inside);
        w.deepest = w.deepest.max(p.deepest);
    }
    per_frame.push(this);
}

/// Measures frame `frame` (whose garments cross themselves `crossings` times): strain,
/// penetrations of the `free` particles (into `report` and the worst so far in `worst`) and
/// stability; returns why the simulation is unstable, if it is.
fn measure(
    sim: &Simulation,
    free: &[glam::Vec4],
    (frame, crossings): (u32, usize),
    progress: &mut Progress,
    report: &mut Report,
) -> Option<String> {
    let error = sim.constraint_error();
    if sim.strain_limited > 0 {
        let springs = sim.strain_limited;
        (report.strain_limited_per_frame)
            .push(crate::report::FrameStrainLimited { frame, springs });
    }
    let penetrations = solid_penetrations(sim, free);
    report.penetrations_per_frame.push(FramePenetrations {
        frame,
        inside: penetrations.iter().map(|p| p.inside).collect(),
        deepest_m: penetrations.iter().map(|p| p.deepest).collect(),
    });
    for (w, p) in progress.worst.iter_mut().zip(&penetrations) {
        w.inside = w.inside.max(p.inside);
        w.deepest = w.deepest.max(p.deepest);
    }
    if sim.integrating() && error.forced() {
        let strain = error.max_strain;
        (report.forced_strain_per_frame).push(crate::report::FrameForcedStrain { frame, strain });
    }
    preroll_strain(report, frame, error.max_strain);
    let metrics = frame_metrics(frame, &error, &penetrations, crossings);
    if report
        .worst_frame
        .as_ref()
        .is_none_or(|w| error.max_strain > w.max_strain)
    {
        report.worst_frame = Some(metrics.clone());
    }
    report.last_frame = Some(metrics);
    metrics::instability(
        &sim.state,
        &error,
        &sim.energy(),
        &progress.initial_energy,
        sim.driven_energy() + sim.rounding_energy(),
        sim.integrating(),
    )
}
