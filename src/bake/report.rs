//! The report a bake starts from and the per-frame metrics it fills in.

use super::BakeOptions;
use crate::collide;
use crate::report::{
    Backend, ColliderPenetration, FrameMetrics, GarmentReport, Outputs, PrerollReport, Report,
    Timing, SCHEMA,
};
use crate::scene::Scene;
use crate::sim::{metrics, Simulation};

pub(super) fn empty_report(
    scene: &Scene,
    options: &BakeOptions,
    sim: &Simulation,
    threads: usize,
) -> Report {
    let model = sim.model();
    Report {
        schema: SCHEMA,
        drape_version: env!("CARGO_PKG_VERSION"),
        scene: scene.name.clone(),
        scene_file: options.scene_file.clone(),
        backend: Backend {
            kind: "cpu",
            threads,
            frames_on_one_thread: 0,
            team_waits_asleep: None,
            adapter: None,
        },
        solver: scene.solver.clone(),
        integrator: scene.integrator,
        fps: scene.fps,
        substeps: sim.substeps(),
        step_seconds: sim.drivers.clock.step,
        particles: model.particle_count(),
        springs: model.springs.len(),
        garments: model
            .garments
            .iter()
            .map(|g| GarmentReport {
                name: g.name.clone(),
                particles: g.export.len(),
                pinned: g
                    .export
                    .clone()
                    .filter(|&e| model.inv_mass[model.storage_of[e] as usize] == 0.0)
                    .count(),
                stretch_springs: g.stretch_springs,
                shear_springs: g.shear_springs,
                bend_springs: g.bend_springs,
                colours: g.colours,
            })
            .collect(),
        frame_start: scene.frame_start,
        frames_requested: scene.frames,
        frames_baked: 0,
        ms_per_frame: Timing::default(),
        frames_hash: String::new(),
        stages_ms: Vec::new(),
        last_frame: None,
        worst_frame: None,
        worst_penetrations: Vec::new(),
        penetrations_per_frame: Vec::new(),
        worst_mesh_penetrations: Vec::new(),
        worst_held_mesh_penetrations: Vec::new(),
        held_mesh_penetrations_per_frame: Vec::new(),
        strain_limited_per_frame: Vec::new(),
        forced_strain_per_frame: Vec::new(),
        character_in_colliders_per_frame: Vec::new(),
        gpu_upload_bytes_per_frame: None,
        gpu_dispatches_per_frame: None,
        gpu_submissions_per_frame: None,
        mesh_penetrations_per_frame: Vec::new(),
        crossings_per_frame: Vec::new(),
        character_crossings_per_frame: Vec::new(),
        torn_springs: 0,
        preroll: (scene.lead_in > 0).then(|| PrerollReport {
            frames: scene.lead_in,
            exported: scene.output.preroll,
            ..PrerollReport::default()
        }),
        clean_start: None,
        stable: true,
        failure: None,
        interrupted: None,
        until: None,
        resumed: None,
        checkpoints: None,
        budget: None,
        warnings: Vec::new(),
        characters: Vec::new(),
        residuals: None,
        outputs: Outputs {
            obj: scene.output.obj.then(|| "obj".to_string()),
            ..Outputs::default()
        },
        exports: Vec::new(),
        preview: None,
    }
}

pub(super) fn frame_metrics(
    frame: u32,
    e: &metrics::ConstraintError,
    p: &[collide::Penetration],
    crossings: usize,
) -> FrameMetrics {
    FrameMetrics {
        crossings,
        frame,
        total_squared_error: e.total_squared_error,
        mean_strain: e.mean_strain,
        max_strain: e.max_strain,
        max_stretch: e.max_stretch,
        mean_shear_deg: e.mean_shear_deg,
        max_shear_deg: e.max_shear_deg,
        penetrations: collider_penetrations(p),
    }
}

pub(super) fn collider_penetrations(p: &[collide::Penetration]) -> Vec<ColliderPenetration> {
    p.iter()
        .enumerate()
        .map(|(collider, &penetration)| ColliderPenetration {
            collider,
            penetration,
        })
        .collect()
}

/// The report of a bake of `scene` with a pre-roll ([`Scene::with_preroll`]) as the shot sees
/// it: its first frame and frame counts those of the scene as written (the pre-roll's frames
/// are in `preroll`, and keep their numbers before `frame_start` in the per-frame lists).
pub(super) fn as_shot(report: &mut Report, scene: &Scene) {
    let lead = scene.lead_in;
    if lead == 0 {
        return;
    }
    report.frame_start += lead;
    report.frames_requested -= lead;
    report.frames_baked = report.frames_baked.saturating_sub(lead);
}

/// Records frame `frame`'s strain in the pre-roll's report, when it is a pre-roll frame.
pub(super) fn preroll_strain(report: &mut Report, frame: u32, strain: f64) {
    let start = report.frame_start;
    if let Some(p) = report.preroll.as_mut().filter(|p| frame < start + p.frames) {
        p.frames_baked = p.frames_baked.max(frame - start + 1);
        p.max_strain = p.max_strain.max(strain);
    }
}

/// Records frame `frame`'s penetrations of character `c` (`name`) in the pre-roll's report,
/// when it is a pre-roll frame.
pub(super) fn preroll_mesh(
    report: &mut Report,
    frame: u32,
    c: usize,
    name: &str,
    p: collide::Penetration,
) {
    let start = report.frame_start;
    let Some(pre) = report.preroll.as_mut().filter(|p| frame < start + p.frames) else {
        return;
    };
    if pre.mesh_penetrations.len() <= c {
        pre.mesh_penetrations.push(crate::report::MeshPenetration {
            character: name.to_string(),
            penetration: collide::Penetration::default(),
        });
    }
    let worst = &mut pre.mesh_penetrations[c].penetration;
    worst.inside = worst.inside.max(p.inside);
    worst.deepest = worst.deepest.max(p.deepest);
}
