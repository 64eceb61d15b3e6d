//! A bake: simulate every frame of a scene, write each frame out, and finish with `report.json`,
//! all inside a staging folder that becomes the output folder at the end.
//!
//! In three steps: [`prepare`] builds the complete simulation from the scene and its
//! [`characters`]; [`frames`] steps and measures each frame on the scene's [`Backend`] and
//! hands it to the [`output`]s, which write it at once (memory stays flat however long the
//! shot); closing them makes the USD layer and the preview from the frames spooled to disk;
//! [`warnings`] reads the finished report for what the user can fix. A
//! run that turns unstable stops at that frame: the frames baked so far and a report that says
//! what happened are still moved into place, so the user can see where it went wrong.

pub mod budget;
pub mod characters;
pub mod checkpoint;
pub mod dress;
mod frames;
pub mod limbs;
mod output;
pub mod prepare;
mod report;
pub mod resume;
mod ticker;
mod warnings;

pub use characters::{load_characters, shell_cache_dir, LoadedCharacter};
pub use prepare::{simulation, Prepared};
pub use resume::Resume;
pub use ticker::ProgressView;
use ticker::Ticker;
pub use warnings::PREROLL_STRETCH_WARNING;

use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::export::sequence::BakeMeshes;
use crate::export::Staging;
use crate::report::{Adapter, Report, StageTiming};
use crate::scene::{GltfOutput, Scene};
use crate::sim::schedule;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A signal that asks running bakes to stop after their current frame (0: none). The command
/// line sets it from its SIGINT and SIGTERM handlers; a library user may set it too. The frames
/// baked so far are exported and the report says `interrupted`.
pub static INTERRUPT: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

/// How to run a bake, beyond the scene itself.
#[derive(Clone, Debug)]
pub struct BakeOptions {
    /// The folder to create (replaced if it holds a previous bake).
    pub out: PathBuf,
    /// Name of the scene's source, for the report.
    pub scene_file: String,
    /// Worker threads; `None` uses every core.
    pub threads: Option<usize>,
    /// Where the progress goes (a bar on stderr, drawn only on a terminal; lines; nowhere).
    pub progress: ProgressView,
    /// Folder of shell caches (`None`: [`shell_cache_dir`]).
    pub shell_cache: Option<PathBuf>,
    /// Start from a checkpoint of an earlier bake into `out` ([`resume`]).
    pub resume: Resume,
    /// Stop after this shot frame, with a checkpoint (a farm chunk that the next resumes).
    pub until: Option<u32>,
    /// Every frame on all `threads`, even while the machine looks busy (a benchmark timing a
    /// given number of threads); false: frames go to one thread while the team's waits keep
    /// sleeping ([`crate::sim::team::Sharing`]), counted in `backend.frames_on_one_thread`.
    pub fixed_team: bool,
}

/// What a finished bake returns.
#[derive(Clone, Debug)]
pub struct Bake {
    pub report: Report,
    /// The folder written.
    pub out: PathBuf,
    /// Positions after the last baked frame, export order (garments in turn, grid order).
    pub positions: Vec<Vec3>,
    /// When an interrupted bake was kept beside a complete one (`out` is then the hidden
    /// `.NAME.partial` folder): the destination, which still holds the complete bake.
    pub kept: Option<PathBuf>,
    /// What could not be cleaned up once the report was written (a previous bake that could
    /// not be removed).
    pub warnings: Vec<String>,
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

/// Bakes `scene` (validated) into `options.out`: its pre-roll first, when a character has one
/// ([`Scene::with_preroll`]).
pub fn bake(scene: &Scene, options: &BakeOptions) -> Result<Bake> {
    let scene = &scene.with_preroll();
    // More threads than cores only take turns at every barrier of the frame (a 6 × 6 sheet: 0.03 s
    // on 1 thread, 7.8 s on 16, on 2 cores): clamp, and say so.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let clamped = options
        .threads
        .filter(|&n| n > cores)
        .map(|n| format!("--threads {n} is more than this machine's {cores} cores: using {cores}"));
    let pool = thread_pool(options.threads.map(|n| n.min(cores)))?;
    check_frame_flags(scene, options)?;
    let staging = if options.resume == Resume::No {
        Staging::new(&options.out)?
    } else {
        Staging::resuming(&options.out)?
    };
    // Where checkpoints to resume from may be: dead runs' staging folders and the output.
    let mut folders = staging.resumable.clone();
    folders.push(staging.destination().to_path_buf());
    let written = pool
        .install(|| {
            run(
                scene,
                options,
                staging.path(),
                &folders,
                pool.current_num_threads(),
            )
        })
        .and_then(|(mut report, positions)| {
            report.warnings.extend(clamped);
            report.warnings.extend(staging.notes.iter().cloned());
            let path = staging.path().join("report.json");
            let text = serde_json::to_string_pretty(&report).expect("reports serialise");
            std::fs::write(&path, text + "\n").map_err(|e| Error::io(&path, "cannot write", e))?;
            Ok((report, positions))
        });
    let (report, positions) = written.map_err(|e| staging.public_error(e))?;
    // An interrupted bake never replaces a complete one: it waits beside it for `--resume`.
    if report.interrupted.is_some() && staging.destination_complete() {
        let kept = options.out.clone();
        let out = staging.park()?;
        return Ok(Bake {
            report,
            out,
            positions,
            kept: Some(kept),
            warnings: Vec::new(),
        });
    }
    let (out, warnings) = staging.commit()?;
    Ok(Bake {
        report,
        out,
        positions,
        kept: None,
        warnings,
    })
}

/// `--until` and `--from-frame` name frames of the shot.
fn check_frame_flags(scene: &Scene, options: &BakeOptions) -> Result<()> {
    let (first, last) = (
        scene.frame_start,
        scene.frame_start + scene.frames.saturating_sub(1),
    );
    let flags = [
        ("--until", options.until),
        (
            "--from-frame",
            match options.resume {
                Resume::From(k) => Some(k),
                _ => None,
            },
        ),
    ];
    for (flag, value) in flags {
        if let Some(k) = value.filter(|k| !(first..=last).contains(k)) {
            return Err(Error::InvalidArgument {
                flag: flag.into(),
                reason: format!("{k} is not a frame of the shot ({first} to {last})"),
            });
        }
    }
    Ok(())
}

/// Refuses a bake whose files would not fit on the disk that holds `out` (exit 2 naming
/// `frames`), before the first frame; `vertices`: every mesh's vertices a frame writes. Frames
/// stream to disk as they are made, so memory holds one frame of every mesh, and the disk is
/// what a long shot fills.
pub fn check_disk(scene: &Scene, vertices: u64, file: &str, out: &Path) -> Result<()> {
    let bytes = output_bytes(scene, vertices);
    crate::limits::fits_on_disk(bytes, out).map_err(|reason| Error::InvalidField {
        file: file.to_string(),
        field: "frames".into(),
        reason: format!("{} frames {reason}", scene.frames),
    })
}

/// About how many bytes a bake of `scene` writes with `vertices` vertices per frame.
pub fn output_bytes(scene: &Scene, vertices: u64) -> u64 {
    let spec = &scene.output;
    let frames = scene.frames as u64;
    // Bytes per vertex and frame: OBJ text (v, vt, vn lines and about two faces), glTF
    // position and normal deltas, PC2 points, USD text (points, normals, extent), the spool,
    // the checkpoints' frame log (garments only; counted for every vertex).
    let mut per_vertex = 0;
    per_vertex += if spec.obj { 160 } else { 0 };
    per_vertex += if spec.gltf != GltfOutput::None { 24 } else { 0 };
    per_vertex += if spec.pc2 { 12 } else { 0 };
    per_vertex += if spec.usd { 100 } else { 0 };
    per_vertex += if spec.usd || spec.preview { 12 } else { 0 };
    per_vertex += if scene.checkpoint_every != Some(0) {
        12
    } else {
        0
    };
    let images = if spec.preview {
        spec.preview_size[0] as u64 * spec.preview_size[1] as u64 / 2
    } else {
        0
    };
    // The glTF animation's weights: frames² floats per animated mesh.
    let weights = if spec.gltf != GltfOutput::None {
        let meshes = scene.garments.len() + scene.characters.len();
        (meshes as u64).saturating_mul(frames.saturating_mul(frames).saturating_mul(4))
    } else {
        0
    };
    frames
        .saturating_mul(vertices.saturating_mul(per_vertex).saturating_add(images))
        .saturating_add(weights)
}

// Long: the bake's steps in order (characters, simulation, the checkpoint resumed from,
// backend, exports, the frames, closing), each a call.
fn run(
    scene: &Scene,
    options: &BakeOptions,
    dir: &Path,
    resume_from: &[PathBuf],
    threads: usize,
) -> Result<(Report, Vec<Vec3>)> {
    let mut warnings = Vec::new();
    let cache_dir = options.shell_cache.clone().unwrap_or_else(shell_cache_dir);
    let characters = load_characters(scene, &cache_dir, &mut warnings)?;
    let Prepared {
        mut sim,
        characters,
        character_meshes,
        warnings: binding,
    } = simulation(scene, characters, &options.scene_file)?;
    warnings.extend(binding);
    if options.fixed_team {
        sim.sharing = crate::sim::team::Sharing::whole_team();
    }
    // The rest pose, the meshes and the report as the scene builds them, before a checkpoint
    // is put back.
    let rest = sim.export_positions();
    let mut meshes = BakeMeshes::new(
        &sim.model().garments,
        character_meshes,
        &scene.colliders,
        scene.frames as usize,
        scene.fps,
    );
    let mut report = report::empty_report(scene, options, &sim, threads);
    report.until = options.until;
    let source = resumed_source(
        scene,
        options,
        resume_from,
        &sim.drivers.shells,
        &mut warnings,
    )?;
    if source.is_none() && !sim.drivers.shells.is_empty() {
        report.clean_start = Some(dress::clean_start(&mut sim, &meshes, &scene.garments));
    }
    // Accuracy targets, or without them a budget left to drape, which answers to the
    // stability rule alone (`budget`'s docs).
    let targets = budget::Targets::of(scene).or_else(|| budget::Targets::stability(scene));
    if let Some(t) = &targets {
        // The budget the frame after the checkpoint starts at (the cheapest on a fresh bake).
        let level = source
            .as_ref()
            .map_or(0, |s| s.loaded.meta.progress.budget.level);
        t.apply(&mut sim, level.min(t.levels.len() - 1));
    }
    if let Some(s) = &source {
        sim.restore(&s.loaded.snapshot)
            .map_err(|reason| Error::InvalidField {
                file: s.checkpoint.display().to_string(),
                field: "checkpoint".into(),
                reason: format!("does not fit the scene: {reason}"),
            })?;
    }
    let mut backend = Backend::for_scene(scene.backend, &sim, &mut warnings)?;
    if let Some(top) = targets
        .as_ref()
        .and_then(|t| t.levels.iter().map(|l| l.0).max())
    {
        // A budget goes up to its largest substeps on the backend it starts on.
        if let Err(Error::Gpu { reason }) = backend.fits_substeps(&sim, top) {
            let why = format!("{reason} (at the budget's largest, {top} substeps per frame)");
            if scene.backend != crate::scene::BackendKind::Auto {
                let reason = format!("{why}; use the cpu backend");
                return Err(Error::Gpu { reason });
            }
            warnings.push(format!("backend auto: {why}; simulating on the CPU"));
            backend = Backend::Cpu;
        }
    }
    if !backend.is_gpu() {
        // Only the GPU places shells from their meshes; the CPU reads the shells' own frames
        // (P: 15 MB of the mannequin's vertices no longer held).
        for s in &mut sim.drivers.shells {
            s.skin = None;
        }
    }
    let vertices = meshes.info.iter().map(|m| m.vertices as u64).sum();
    check_disk(scene, vertices, &options.scene_file, &options.out)?;
    // While the GPU simulates the CPU is free to write; on the CPU a writer thread would only
    // take turns with the solver.
    let shown = shown_scene(scene);
    let mut exports = output::Exports::open(&shown, dir, &meshes, &rest, backend.is_gpu())?
        .skipping((scene.lead_in - shown.lead_in) as usize);
    let mut writer = match scene.checkpoint_every {
        Some(0) => None,
        _ => Some(checkpoint::Writer::create(
            dir.join(checkpoint::FOLDER),
            scene,
            if backend.is_gpu() { "gpu" } else { "cpu" },
            meshes.garment_particles(),
            &sim.drivers.shells,
        )?),
    };
    let mut progress = checkpoint::Progress::default();
    if let Some(s) = source {
        let replaying = Instant::now();
        let out = dir.join(checkpoint::FOLDER);
        resume::replay(
            &s,
            &mut meshes,
            &mut exports,
            writer.as_mut(),
            scene.frame_start,
            &out,
        )?;
        if s.loaded.meta.backend != if backend.is_gpu() { "gpu" } else { "cpu" } {
            warnings.push(format!(
                "resumed a checkpoint made on the {} backend: the frames after it are not those an uninterrupted bake would give",
                s.loaded.meta.backend
            ));
        }
        report.resumed = Some(crate::report::Resumed {
            checkpoint: s.checkpoint.display().to_string(),
            after_frame: s.loaded.meta.frame,
            replay_ms: replaying.elapsed().as_secs_f64() * 1e3,
        });
        progress = s.loaded.meta.progress;
    }
    report.warnings = warnings;
    report.characters = characters;
    if let Some(adapter) = adapter_report(&backend) {
        report.backend.kind = "gpu";
        report.backend.adapter = Some(adapter);
    }
    let bar = Ticker::new(scene.frames as u64, options.progress);
    let mut around = frames::run(
        &mut sim,
        &mut backend,
        frames::Out {
            meshes: &mut meshes,
            exports: &mut exports,
            checkpoints: writer.as_mut(),
            targets: targets.as_ref(),
        },
        progress,
        &mut report,
        &bar,
    )?;
    bar.finish();
    report.checkpoints = writer.as_ref().map(checkpoint::Writer::report);
    let closing = Instant::now();
    let baked = report.frames_baked as usize;
    exports.close(&shown, dir, baked, &mut report)?;
    around.lap(schedule::timed("export"), closing);
    let mut stage_times = sim.stage_times.clone();
    stage_times.add(&around);
    report.stages_ms = StageTiming::of(&stage_times, report.frames_baked);
    report::as_shot(&mut report, scene);
    if report.backend.kind == "cpu" {
        report.backend.frames_on_one_thread = sim.sharing.solo_frames;
        report.backend.team_waits_asleep = sim.sharing.asleep_share();
    }
    Ok((report, sim.export_positions()))
}

/// The scene the exports show: the shot as written, or with its pre-roll frames too when
/// `output.preroll` asks for them (numbered before `frame_start`).
fn shown_scene(scene: &Scene) -> Scene {
    let mut shown = scene.clone();
    if !scene.output.preroll {
        shown.frames -= scene.lead_in;
        shown.frame_start += scene.lead_in;
        shown.lead_in = 0;
    }
    shown
}

/// What the report says of the GPU adapter a bake runs on (None on the CPU).
fn adapter_report(backend: &Backend) -> Option<Adapter> {
    backend.adapter_info().map(|info| Adapter {
        name: info.name.clone(),
        device_type: format!("{:?}", info.device_type),
        driver: format!("{} {}", info.driver, info.driver_info)
            .trim()
            .to_string(),
        backend: format!("{:?}", info.backend),
    })
}

/// The checkpoint to resume from, when the options ask for one (a warning when there is none).
fn resumed_source(
    scene: &Scene,
    options: &BakeOptions,
    folders: &[PathBuf],
    shells: &[crate::collide::ShellCollider],
    warnings: &mut Vec<String>,
) -> Result<Option<resume::Source>> {
    if options.resume == Resume::No {
        return Ok(None);
    }
    let id = resume::Identity {
        scene,
        file: &options.scene_file,
        scene_hash: checkpoint::scene_identity(scene).1,
        characters: checkpoint::characters_hashes(shells),
    };
    let found = resume::find(folders, options.resume, &id, warnings)?;
    if found.is_none() {
        warnings.push(format!(
            "nothing to resume in {}: baked from the first frame",
            options.out.display()
        ));
    }
    Ok(found)
}
