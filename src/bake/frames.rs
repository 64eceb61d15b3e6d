//! The frame loop: step, tear, measure, record and write each frame, until the last or until the
//! simulation becomes unstable.

use super::report::{collider_penetrations, frame_metrics};
use crate::backend::Backend;
use crate::collide;
use crate::error::Result;
use crate::export::FrameWriter;
use crate::report::{Failure, FramePenetrations, Report, Timing};
use crate::sim::schedule::{self, StageTimes};
use crate::sim::{metrics, Simulation};
use glam::Vec3;
use std::time::Instant;

/// What the loop hands to the exports.
pub struct Frames {
    /// Every baked frame's positions, export order (when an export after the loop needs them).
    pub recorded: Vec<Vec<Vec3>>,
    /// Per garment, its faces whenever tearing changed them: (first frame index, triangles).
    pub topology: Vec<Vec<(usize, Vec<[u32; 3]>)>>,
    /// Time of the stages around the simulation's own (tearing, metrics, export).
    pub around: StageTimes,
}

/// Bakes `frames` frames of `sim` on `backend`, writing OBJ frames through `writer` and keeping
/// positions when `recording`; fills `report`'s per-frame fields and stops at the first unstable
/// frame (recorded in `report.failure`).
pub fn run(
    sim: &mut Simulation,
    backend: &mut Backend,
    mut writer: Option<&mut FrameWriter>,
    recording: bool,
    report: &mut Report,
    progress: &indicatif::ProgressBar,
) -> Result<Frames> {
    let frames = report.frames_requested;
    let initial_energy = sim.energy();
    let mut out = Frames {
        recorded: Vec::new(),
        topology: sim
            .model()
            .garments
            .iter()
            .map(|g| vec![(0, g.triangles.clone())])
            .collect(),
        around: StageTimes::default(),
    };
    let lap = |times: &mut StageTimes, stage: &str, since: Instant| {
        times.lap(schedule::timed(stage), since);
    };
    let mut frame_ms = Vec::with_capacity(frames as usize);
    let mut residuals = Vec::new();
    let mut worst = vec![collide::Penetration::default(); sim.colliders.len() + sim.shells.len()];
    // FNV-1a over every baked frame's positions (f32 bits, export order, frame by frame).
    let mut hash = crate::character::cache::FNV_OFFSET;
    for baked in 1..=frames {
        // The shot's number of this frame (`frame_start`): what files and the report show.
        let frame = report.frame_start + baked - 1;
        let start = Instant::now();
        backend.step_frame(sim)?;
        let tearing = Instant::now();
        if sim.tears() && sim.tear() > 0 {
            // The GPU takes the torn model (and the state it produced) afresh.
            backend.reload(sim)?;
            if let Some(w) = writer.as_mut() {
                w.set_garments(sim.model().garments.clone())?;
            }
            // From this frame on the garments have these faces (previews follow them).
            for (g, history) in sim.model().garments.iter().zip(&mut out.topology) {
                if history.last().is_none_or(|(_, t)| *t != g.triangles) {
                    history.push((baked as usize - 1, g.triangles.clone()));
                }
            }
        }
        frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        lap(&mut out.around, "tearing", tearing);

        let measuring = Instant::now();
        let unstable = measure(sim, frame, &initial_energy, &mut worst, report);
        if let Some(r) = &sim.residuals {
            residuals.push(r.clone());
        }
        lap(&mut out.around, "metrics", measuring);
        if let Some(reason) = unstable {
            report.failure = Some(Failure { frame, reason });
            break;
        }
        let exporting = Instant::now();
        let positions = sim.export_positions();
        hash = positions.iter().fold(hash, |h, p| {
            crate::character::cache::fnv(h, bytemuck::bytes_of(&p.to_array()))
        });
        if recording {
            out.recorded.push(positions.clone());
        }
        if let Some(w) = writer.as_mut() {
            w.write(frame, positions)?;
        }
        lap(&mut out.around, "export", exporting);
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
    if let Some(w) = writer {
        let finishing = Instant::now();
        w.finish()?;
        lap(&mut out.around, "export", finishing);
    }
    report.ms_per_frame = Timing::of(&frame_ms);
    report.frames_hash = format!("{hash:016x}");
    report.torn_springs = sim.torn_springs;
    report.stable = report.failure.is_none();
    report.worst_penetrations = collider_penetrations(&worst);
    if sim.residuals.is_some() {
        report.residuals = Some(residuals);
    }
    Ok(out)
}

/// Measures frame `frame`: strain, penetrations (into `report` and the worst so far in `worst`)
/// and stability; returns why the simulation is unstable, if it is.
fn measure(
    sim: &Simulation,
    frame: u32,
    initial_energy: &metrics::Energy,
    worst: &mut [collide::Penetration],
    report: &mut Report,
) -> Option<String> {
    let error = sim.constraint_error();
    let free = sim.free_positions();
    let mut penetrations = collide::penetrations(&sim.colliders, &free);
    penetrations.extend(sim.shells.iter().map(|s| s.penetration(&free)));
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
