//! The frame loop: step, tear, measure and write each frame as it is made, until the last or
//! until the simulation becomes unstable.

use super::output::Exports;
use super::report::{collider_penetrations, frame_metrics};
use crate::backend::Backend;
use crate::collide;
use crate::error::Result;
use crate::export::sequence::BakeMeshes;
use crate::report::{Failure, FramePenetrations, MeshPenetration, Report, Timing};
use crate::sim::schedule::{self, StageTimes};
use crate::sim::{metrics, Simulation};
use std::time::Instant;

/// Bakes `report.frames_requested` frames of `sim` on `backend`, handing each to `exports` (as
/// `meshes` shows it); fills `report`'s per-frame fields and stops at the first unstable frame
/// (recorded in `report.failure`). Returns the time of the stages around the simulation's own
/// (tearing, metrics, export).
pub fn run(
    sim: &mut Simulation,
    backend: &mut Backend,
    meshes: &mut BakeMeshes,
    exports: &mut Exports,
    report: &mut Report,
    progress: &indicatif::ProgressBar,
) -> Result<StageTimes> {
    let frames = report.frames_requested;
    let initial_energy = sim.energy();
    let mut around = StageTimes::default();
    let lap = |times: &mut StageTimes, stage: &str, since: Instant| {
        times.lap(schedule::timed(stage), since);
    };
    let mut frame_ms = Vec::with_capacity(frames as usize);
    let mut uploaded = 0u64;
    let mut residuals = Vec::new();
    let mut worst = vec![collide::Penetration::default(); sim.colliders.len() + sim.shells.len()];
    // FNV-1a over every baked frame's positions (f32 bits, export order, frame by frame).
    let mut hash = crate::character::cache::FNV_OFFSET;
    for baked in 1..=frames {
        // The shot's number of this frame (`frame_start`): what files and the report show.
        let frame = report.frame_start + baked - 1;
        let start = Instant::now();
        backend.step_frame(sim)?;
        if let Some(bytes) = backend.uploaded_last_frame() {
            uploaded += bytes;
        }
        let tearing = Instant::now();
        if sim.tears() && sim.tear() > 0 {
            // The GPU takes the torn model (and the state it produced) afresh.
            backend.reload(sim)?;
            // From this frame on the garments have these faces (exports follow them).
            for g in meshes.tear(&sim.model().garments) {
                let faces = &sim.model().garments[g].triangles;
                exports.faces(g, baked as usize - 1, faces)?;
            }
        }
        frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        lap(&mut around, "tearing", tearing);

        let measuring = Instant::now();
        // The free particles, gathered once for every penetration count.
        let free = sim.free_positions();
        let unstable = measure(sim, &free, frame, &initial_energy, &mut worst, report);
        measure_meshes(&free, meshes, baked as usize - 1, frame, report);
        if let Some(r) = &sim.residuals {
            residuals.push(r.clone());
        }
        lap(&mut around, "metrics", measuring);
        if let Some(reason) = unstable {
            report.failure = Some(Failure { frame, reason });
            break;
        }
        let exporting = Instant::now();
        let positions = sim.export_positions();
        hash = positions.iter().fold(hash, |h, p| {
            crate::character::cache::fnv(h, bytemuck::bytes_of(&p.to_array()))
        });
        if !exports.is_empty() {
            exports.frame(meshes.frame(baked as usize - 1, frame, &positions))?;
        }
        lap(&mut around, "export", exporting);
        report.frames_baked = baked;
        progress.inc(1);
        let signal = super::INTERRUPT.load(std::sync::atomic::Ordering::Relaxed);
        if signal != 0 && baked < frames {
            report.interrupted = Some(crate::report::Interruption {
                signal,
                after_frame: frame,
            });
            break;
        }
    }
    report.ms_per_frame = Timing::of(&frame_ms);
    if backend.is_gpu() {
        report.gpu_upload_bytes_per_frame = Some(uploaded / (frame_ms.len() as u64).max(1));
    }
    report.frames_hash = format!("{hash:016x}");
    report.torn_springs = sim.torn_springs;
    report.stable = report.failure.is_none();
    report.worst_penetrations = collider_penetrations(&worst);
    if sim.residuals.is_some() {
        report.residuals = Some(residuals);
    }
    Ok(around)
}

/// Measures how many of the `free` garment particles lie inside each character's own mesh at
/// baked frame `index` (shot frame `frame`), into `report`.
fn measure_meshes(
    free: &[glam::Vec4],
    meshes: &BakeMeshes,
    index: usize,
    frame: u32,
    report: &mut Report,
) {
    let mut characters = meshes.characters_at(index).peekable();
    if characters.peek().is_none() {
        return;
    }
    let free: Vec<glam::Vec3> = free.iter().map(|p| p.truncate()).collect();
    let mut this = FramePenetrations {
        frame,
        inside: Vec::new(),
        deepest_m: Vec::new(),
    };
    for (c, (name, vertices, triangles)) in characters.enumerate() {
        let normals = crate::export::obj::vertex_normals(triangles, vertices);
        let p = collide::mesh::penetration(vertices, triangles, &normals, &free);
        this.inside.push(p.inside);
        this.deepest_m.push(p.deepest);
        if report.worst_mesh_penetrations.len() <= c {
            report.worst_mesh_penetrations.push(MeshPenetration {
                character: name.to_string(),
                penetration: collide::Penetration::default(),
            });
        }
        let worst = &mut report.worst_mesh_penetrations[c].penetration;
        worst.inside = worst.inside.max(p.inside);
        worst.deepest = worst.deepest.max(p.deepest);
    }
    report.mesh_penetrations_per_frame.push(this);
}

/// Measures frame `frame`: strain, penetrations of the `free` particles (into `report` and the
/// worst so far in `worst`) and stability; returns why the simulation is unstable, if it is.
fn measure(
    sim: &Simulation,
    free: &[glam::Vec4],
    frame: u32,
    initial_energy: &metrics::Energy,
    worst: &mut [collide::Penetration],
    report: &mut Report,
) -> Option<String> {
    let error = sim.constraint_error();
    let mut penetrations = collide::penetrations(&sim.colliders, free);
    penetrations.extend(sim.shells.iter().map(|s| s.penetration(free)));
    report.penetrations_per_frame.push(FramePenetrations {
        frame,
        inside: penetrations.iter().map(|p| p.inside).collect(),
        deepest_m: penetrations.iter().map(|p| p.deepest).collect(),
    });
    for (w, p) in worst.iter_mut().zip(&penetrations) {
        w.inside = w.inside.max(p.inside);
        w.deepest = w.deepest.max(p.deepest);
    }
    let metrics = frame_metrics(frame, &error, &penetrations);
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
        initial_energy,
        sim.driven_energy() + sim.rounding_energy(),
        sim.integrating(),
    )
}
