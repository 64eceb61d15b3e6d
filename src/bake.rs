//! A bake: simulate every frame of a scene, write each frame out, and finish with `report.json`,
//! all inside a staging folder that becomes the output folder at the end.
//!
//! A run that turns unstable stops at that frame: the frames baked so far and a report that says
//! what happened are still moved into place, so the user can see where it went wrong.

use crate::character::{cache::input_hash, sequence_files, Character, ShellCache};
use crate::collide;
use crate::collide::ShellCollider;
use crate::error::{Error, Result};
use crate::export::gltf::AnimatedMesh;
use crate::export::sequence::{
    collider_meshes, garment_meshes, write_exports, Recording, CHARACTER_COLOUR,
};
use crate::export::{FrameWriter, Staging};
use crate::gpu::{GpuContext, GpuSimulation};
use crate::render::{render_sequence, RenderOptions};
use crate::report::{
    Adapter, Backend, CharacterReport, ColliderPenetration, Failure, FrameMetrics,
    FramePenetrations, GarmentReport, Outputs, Report, Timing, SCHEMA,
};
use crate::scene::{BackendKind, GltfOutput, Scene};
use crate::sim::attach::Skin;
use crate::sim::{metrics, Simulation};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to run a bake, beyond the scene itself.
#[derive(Clone, Debug)]
pub struct BakeOptions {
    /// The folder to create (replaced if it holds a previous bake).
    pub out: PathBuf,
    /// Name of the scene's source, for the report.
    pub scene_file: String,
    /// Worker threads; `None` uses every core.
    pub threads: Option<usize>,
    /// Show a progress bar on stderr (hidden anyway when stderr is not a terminal).
    pub progress: bool,
    /// Folder of shell caches (`None`: [`shell_cache_dir`]).
    pub shell_cache: Option<PathBuf>,
}

/// What a finished bake returns.
#[derive(Clone, Debug)]
pub struct Bake {
    pub report: Report,
    /// The folder written.
    pub out: PathBuf,
    /// Positions after the last baked frame, export order (garments in turn, grid order).
    pub positions: Vec<Vec3>,
}

/// Builds a rayon pool of `threads` workers (all cores when `None`).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(Error::InvalidArgument {
                flag: "--threads".into(),
                reason: "must be at least 1".into(),
            });
        }
        builder = builder.num_threads(n);
    }
    builder.build().map_err(|e| Error::InvalidArgument {
        flag: "--threads".into(),
        reason: e.to_string(),
    })
}

/// Bakes `scene` (validated) into `options.out`.
pub fn bake(scene: &Scene, options: &BakeOptions) -> Result<Bake> {
    let pool = thread_pool(options.threads)?;
    let staging = Staging::new(&options.out)?;
    let (report, positions) =
        pool.install(|| run(scene, options, staging.path(), pool.current_num_threads()))?;
    let path = staging.path().join("report.json");
    let text = serde_json::to_string_pretty(&report).expect("reports serialise");
    std::fs::write(&path, text + "\n").map_err(|e| Error::io(&path, "cannot write", e))?;
    let out = staging.commit()?;
    Ok(Bake {
        report,
        out,
        positions,
    })
}

/// The GPU simulation the scene's backend asks for, or `None` for the CPU; `auto` falls back to
/// the CPU with a warning, `gpu` fails with the reason.
pub fn gpu_backend(
    scene: &Scene,
    sim: &Simulation,
    warnings: &mut Vec<String>,
) -> Result<Option<GpuSimulation>> {
    match scene.backend {
        BackendKind::Cpu => Ok(None),
        BackendKind::Gpu => Ok(Some(GpuSimulation::new(GpuContext::new(false)?, sim)?)),
        BackendKind::Auto => {
            if !crate::gpu::context::hardware_present() {
                warnings.push(
                    "backend auto: no GPU device on this machine; simulating on the CPU".into(),
                );
                return Ok(None);
            }
            let gpu = GpuContext::new(true).and_then(|ctx| GpuSimulation::new(ctx, sim));
            match gpu {
                Ok(g) => Ok(Some(g)),
                Err(e) => {
                    warnings.push(format!("backend auto: {e}; simulating on the CPU"));
                    Ok(None)
                }
            }
        }
    }
}

/// drape's cache folder (shell caches, and the mannequin files of the embedded default scene):
/// `$XDG_CACHE_HOME/drape`, else `~/.cache/drape`, else the temp folder.
pub fn shell_cache_dir() -> PathBuf {
    std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir)
        .join("drape")
}

/// Loads the scene's characters and their collision shells over the bake's frames, reusing a
/// shell cache whose inputs have not changed.
pub fn load_characters(
    scene: &Scene,
    cache_dir: &Path,
    warnings: &mut Vec<String>,
) -> Result<Vec<LoadedCharacter>> {
    let mut out = Vec::new();
    for (i, spec) in scene.characters.iter().enumerate() {
        let path = scene.character_path(i);
        let options = spec.options();
        let frames = scene.frames as usize + 1;
        let character = Character::load(&path, &options, scene.fps, frames)?;
        let name = spec.name.clone().unwrap_or_else(|| format!("character{i}"));
        // Normals ride the skin with the shell, when one shell serves every frame.
        let mut normals = Vec::new();
        let (positions, cache) = if character.same_topology() {
            let files = sequence_files(&path)?;
            let hash = input_hash(
                &files,
                &options,
                spec.radius,
                scene.fps,
                character.frames.len(),
            )?;
            let file = cache_dir.join(format!("{hash:016x}.shell"));
            let (c, how) = match ShellCache::read(&file) {
                Ok(c) if c.inputs == hash => (c, "reused"),
                _ => {
                    let c = ShellCache::build(&character, spec.radius, hash)?;
                    let written = std::fs::create_dir_all(cache_dir)
                        .map_err(|e| Error::io(cache_dir, "cannot create", e))
                        .and_then(|_| c.write(&file));
                    if let Err(e) = written {
                        warnings.push(format!("character {name}: shell cache not written: {e}"));
                    }
                    (c, "built")
                }
            };
            let triangles = character.triangles_of(0);
            normals = character
                .frames
                .iter()
                .map(|f| c.shell.normals(f, triangles))
                .collect();
            (c.frames, how)
        } else {
            (
                character.shell_frames(spec.radius),
                "none (topology changes)",
            )
        };
        let report = CharacterReport {
            name: name.clone(),
            file: path.display().to_string(),
            frames: positions.len(),
            shell_particles: positions.first().map_or(0, Vec::len),
            shell_radius: spec.radius,
            shell_cache: cache,
        };
        // Exports and previews show the character when its topology holds over the frames.
        let mesh = if character.same_topology() {
            Some(AnimatedMesh {
                name: name.clone(),
                triangles: character.triangles_of(0).to_vec(),
                uvs: None,
                colour: [
                    CHARACTER_COLOUR[0],
                    CHARACTER_COLOUR[1],
                    CHARACTER_COLOUR[2],
                    1.0,
                ],
                frames: character.frames.clone(),
                topology: Vec::new(),
            })
        } else {
            warnings.push(format!(
                "character {name}: its topology changes between frames, so exports and previews leave it out"
            ));
            None
        };
        let mut shell = ShellCollider::new(name, spec.radius, spec.friction, positions);
        shell.normals = normals;
        out.push(LoadedCharacter {
            shell,
            report,
            mesh,
        });
    }
    Ok(out)
}

/// A character ready for a bake: its collision shell, what the report says of it, and its mesh
/// over frames 0…N for the exports (None when its topology changes between frames).
pub struct LoadedCharacter {
    pub shell: ShellCollider,
    pub report: CharacterReport,
    pub mesh: Option<AnimatedMesh>,
}

fn run(
    scene: &Scene,
    options: &BakeOptions,
    dir: &Path,
    threads: usize,
) -> Result<(Report, Vec<Vec3>)> {
    let mut sim = Simulation::new(scene);
    let mut warnings = Vec::new();
    let mut characters = Vec::new();
    let cache_dir = options.shell_cache.clone().unwrap_or_else(shell_cache_dir);
    let mut character_meshes = Vec::new();
    for mut c in load_characters(scene, &cache_dir, &mut warnings)? {
        c.shell.swept = scene.swept_collisions;
        sim.shells.push(c.shell);
        characters.push(c.report);
        character_meshes.extend(c.mesh);
    }
    let unbound = sim.attachments.unbound();
    if !unbound.is_empty() {
        let skins = character_meshes
            .iter()
            .map(|m| Skin {
                name: m.name.clone(),
                triangles: m.triangles.clone(),
                frames: m.frames.clone(),
            })
            .collect();
        sim.attachments
            .bind_skins(skins)
            .map_err(|reason| Error::InvalidField {
                file: options.scene_file.clone(),
                field: "garments[].attachments".into(),
                reason,
            })?;
    }
    let out = &scene.output;
    let recording =
        out.gltf != GltfOutput::None || out.pc2 || out.usd || out.preview || out.character_obj;
    let rest = sim.export_positions();
    let mut recorded: Vec<Vec<Vec3>> = Vec::new();
    let mut gpu = gpu_backend(scene, &sim, &mut warnings)?;
    let obj_dir = dir.join("obj");
    if scene.output.obj {
        std::fs::create_dir(&obj_dir).map_err(|e| Error::io(&obj_dir, "cannot create", e))?;
    }
    let mut writer = scene.output.obj.then(|| {
        let garments = sim.model().garments.clone();
        match gpu {
            Some(_) => FrameWriter::spawn(obj_dir.clone(), garments),
            None => FrameWriter::inline(obj_dir.clone(), garments),
        }
    });
    let mut report = empty_report(scene, options, &sim, threads);
    report.warnings = warnings;
    report.characters = characters;
    if let Some(g) = &gpu {
        let info = g.adapter_info();
        report.backend.kind = "gpu";
        report.backend.adapter = Some(Adapter {
            name: info.name.clone(),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            backend: format!("{:?}", info.backend),
        });
    }
    let initial_energy = sim.energy();
    // Faces of each garment whenever tearing changes them: (first frame index, triangles).
    let mut topology: Vec<Vec<(usize, Vec<[u32; 3]>)>> = sim
        .model()
        .garments
        .iter()
        .map(|g| vec![(0, g.triangles.clone())])
        .collect();
    let progress = progress_bar(scene.frames as u64, options.progress);
    let mut frame_ms = Vec::with_capacity(scene.frames as usize);
    let mut residuals = Vec::new();
    let mut worst_penetration =
        vec![collide::Penetration::default(); sim.colliders.len() + sim.shells.len()];

    for frame in 1..=scene.frames {
        let start = Instant::now();
        match &mut gpu {
            Some(g) => g.step_frame(&mut sim)?,
            None => sim.step_frame(),
        }
        if sim.tears() && sim.tear() > 0 {
            // The GPU takes the torn model (and the state it produced) afresh.
            if let Some(g) = &mut gpu {
                g.reload(&sim)?;
            }
            if let Some(w) = &mut writer {
                w.set_garments(sim.model().garments.clone());
            }
            // From this frame on the garments have these faces (previews follow them).
            for (g, history) in sim.model().garments.iter().zip(&mut topology) {
                if history.last().is_none_or(|(_, t)| *t != g.triangles) {
                    history.push((frame as usize - 1, g.triangles.clone()));
                }
            }
        }
        frame_ms.push(start.elapsed().as_secs_f64() * 1e3);

        let error = sim.constraint_error();
        let free = sim.free_positions();
        let mut penetrations = collide::penetrations(&sim.colliders, &free);
        penetrations.extend(sim.shells.iter().map(|s| s.penetration(&free)));
        report.penetrations_per_frame.push(FramePenetrations {
            frame,
            inside: penetrations.iter().map(|p| p.inside).collect(),
            deepest_m: penetrations.iter().map(|p| p.deepest).collect(),
        });
        for (w, p) in worst_penetration.iter_mut().zip(&penetrations) {
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
        if let Some(r) = &sim.residuals {
            residuals.push(r.clone());
        }
        let unstable = metrics::instability(
            &sim.state,
            &error,
            &sim.energy(),
            &initial_energy,
            sim.driven_energy(),
            sim.integrating(),
        );
        if let Some(reason) = unstable {
            report.failure = Some(Failure { frame, reason });
            break;
        }
        if recording {
            recorded.push(sim.export_positions());
        }
        if let Some(w) = &mut writer {
            w.write(frame, sim.export_positions())?;
        }
        report.frames_baked = frame;
        progress.inc(1);
    }
    if let Some(w) = &mut writer {
        w.finish()?;
    }
    progress.finish_and_clear();
    report.ms_per_frame = Timing::of(&frame_ms);
    report.torn_springs = sim.torn_springs;
    report.stable = report.failure.is_none();
    report.worst_penetrations = collider_penetrations(&worst_penetration);
    if sim.residuals.is_some() {
        report.residuals = Some(residuals);
    }
    if report.frames_baked > 0 {
        let model = sim.model();
        let mut meshes = garment_meshes(&model.garments, &recorded);
        for (mesh, history) in meshes.iter_mut().zip(topology) {
            if history.len() > 1 {
                mesh.topology = history;
            }
        }
        let baked = report.frames_baked as usize;
        for mut c in character_meshes {
            // Character frame k is the pose at garment frame k (frame 0 is the start); a static
            // mesh (one frame, like a stool) stays one frame.
            if c.frames.len() > 1 {
                c.frames = c.frames.into_iter().skip(1).take(baked).collect();
            }
            if c.frames.len() == baked || c.frames.len() == 1 {
                meshes.push(c);
            }
        }
        let characters = meshes.len() - model.garments.len();
        let times: Vec<f32> = (1..=baked).map(|k| k as f32 / scene.fps).collect();
        meshes.extend(collider_meshes(&scene.colliders, &times));
        let rest: Vec<Vec<Vec3>> = model
            .garments
            .iter()
            .map(|g| rest[g.export.clone()].to_vec())
            .collect();
        let mut materials: Vec<(String, [f32; 3])> = model
            .garments
            .iter()
            .map(|g| (g.name.clone(), g.colour))
            .collect();
        materials.extend(
            meshes[model.garments.len()..]
                .iter()
                .map(|m| (m.name.clone(), [m.colour[0], m.colour[1], m.colour[2]])),
        );
        let recording = Recording {
            meshes: if recording { &meshes } else { &[] },
            garments: model.garments.len(),
            characters,
            rest: &rest,
            materials: &materials,
            fps: scene.fps,
        };
        let (outputs, exports) = write_exports(dir, &scene.name, out, &recording)?;
        report.outputs = outputs;
        report.exports = exports;
        if out.preview {
            let options = RenderOptions {
                width: out.preview_size[0],
                height: out.preview_size[1],
                wireframe: out.wireframe,
            };
            // A preview that cannot be made (no adapter at all) costs the bake nothing else: the
            // frames and exports stay, and the report says why there are no images.
            match GpuContext::new(false).and_then(|ctx| render_sequence(ctx, &meshes, options, dir))
            {
                Ok(summary) => {
                    report.outputs.preview = Some(summary.contact_sheet.clone());
                    report.preview = Some(summary);
                }
                Err(e) => {
                    let _ = std::fs::remove_dir_all(dir.join("preview"));
                    report.warnings.push(format!("preview not rendered: {e}"));
                }
            }
        }
    }
    Ok((report, sim.export_positions()))
}

fn empty_report(scene: &Scene, options: &BakeOptions, sim: &Simulation, threads: usize) -> Report {
    let model = sim.model();
    Report {
        schema: SCHEMA,
        drape_version: env!("CARGO_PKG_VERSION"),
        scene: scene.name.clone(),
        scene_file: options.scene_file.clone(),
        backend: Backend {
            kind: "cpu",
            threads,
            adapter: None,
        },
        solver: scene.solver.clone(),
        integrator: scene.integrator,
        fps: scene.fps,
        substeps: sim.substeps,
        step_seconds: sim.step,
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
        frames_requested: scene.frames,
        frames_baked: 0,
        ms_per_frame: Timing::default(),
        last_frame: None,
        worst_frame: None,
        worst_penetrations: Vec::new(),
        penetrations_per_frame: Vec::new(),
        torn_springs: 0,
        stable: true,
        failure: None,
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

fn frame_metrics(
    frame: u32,
    e: &metrics::ConstraintError,
    p: &[collide::Penetration],
) -> FrameMetrics {
    FrameMetrics {
        frame,
        total_squared_error: e.total_squared_error,
        mean_strain: e.mean_strain,
        max_strain: e.max_strain,
        penetrations: collider_penetrations(p),
    }
}

fn collider_penetrations(p: &[collide::Penetration]) -> Vec<ColliderPenetration> {
    p.iter()
        .enumerate()
        .map(|(collider, &penetration)| ColliderPenetration {
            collider,
            penetration,
        })
        .collect()
}

fn progress_bar(frames: u64, show: bool) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    // The stderr target draws nothing when stderr is not a terminal.
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(frames),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames {elapsed} (eta {eta})")
    {
        bar.set_style(style);
    }
    bar
}
