//! Solver timings on the reference scenes, shared by `drape bench` and the tests that keep it from
//! rotting. Times are wall clock on whatever machine runs them: they are printed and written to
//! CSV, never asserted.

pub mod budget;
pub mod characters;
pub mod chart;
pub mod convergence;
pub mod integrator_report;
pub mod integrators;
pub mod peers;
pub mod studies;

use crate::bake::thread_pool;
use crate::collide;
use crate::error::Result;
use crate::scene::{Scene, SolverKind};
use crate::sim::team::Sharing;
use crate::sim::Simulation;
use std::time::Instant;

/// `scene` as a timing bench bakes it: on the CPU, for `frames` frames (None: its own), with
/// nothing written but the report and no checkpoints.
pub(crate) fn report_only(scene: &Scene, frames: Option<u32>) -> Scene {
    let mut s = scene.clone();
    s.backend = crate::scene::BackendKind::Cpu;
    s.frames = frames.unwrap_or(s.frames);
    s.output.obj = false;
    s.output.gltf = crate::scene::GltfOutput::None;
    s.output.preview = false;
    s.checkpoint_every = Some(0);
    s
}

/// Bakes `scene` quietly into `work/bake` (shell caches in `work/cache`) on `threads` threads
/// (None: every core), named `scene_file` in its report; returns the report.
pub(crate) fn bake_report(
    scene: &Scene,
    scene_file: String,
    threads: Option<usize>,
    work: &std::path::Path,
) -> Result<crate::report::Report> {
    let options = crate::bake::BakeOptions {
        out: work.join("bake"),
        scene_file,
        threads,
        progress: crate::bake::ProgressView::Hidden,
        shell_cache: Some(work.join("cache")),
        resume: crate::bake::Resume::No,
        until: None,
        // A benchmark times the threads it names: no frame sent to one thread.
        fixed_team: true,
    };
    Ok(crate::bake::bake(scene, &options)?.report)
}

/// Every solver, in the order benches list them.
pub const SOLVERS: [SolverKind; 4] = [
    SolverKind::Rbgs,
    SolverKind::Gs,
    SolverKind::Jacobi,
    SolverKind::Pbd,
];

/// Cost and result of solver iterations on a relaxation scene (scene E).
#[derive(Clone, Debug, serde::Serialize)]
pub struct IterationTiming {
    pub solver: &'static str,
    pub threads: usize,
    pub iterations: u32,
    pub us_per_iteration: f64,
    /// Total squared error after the timed iterations [m²].
    pub residual: f64,
}

/// Times `iterations` outer iterations (local step + one sweep each) of `kind` on `scene`.
pub fn time_iterations(
    scene: &Scene,
    kind: SolverKind,
    threads: usize,
    iterations: u32,
) -> Result<IterationTiming> {
    let mut scene = scene.clone();
    scene.solver.kind = kind;
    scene.solver.iterations = iterations;
    scene.solver.inner_iterations = 1;
    scene.output.residuals = false;
    let pool = thread_pool(Some(threads))?;
    pool.install(|| {
        // One untimed frame warms caches and the pool; the timed one restarts from rest.
        let mut warm = Simulation::new(&scene)?;
        warm.sharing = Sharing::whole_team();
        warm.step_frame();
        let mut sim = Simulation::new(&scene)?;
        sim.sharing = Sharing::whole_team();
        let start = Instant::now();
        sim.substep();
        let seconds = start.elapsed().as_secs_f64();
        Ok(IterationTiming {
            solver: kind.name(),
            threads,
            iterations,
            us_per_iteration: seconds * 1e6 / iterations as f64,
            residual: sim.constraint_error().total_squared_error,
        })
    })
}

/// Cost and accuracy of baking frames of a scene with one solver.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameTiming {
    pub scene: String,
    pub solver: &'static str,
    pub threads: usize,
    pub frames: u32,
    pub ms_per_frame_median: f64,
    pub ms_per_frame_mean: f64,
    pub mean_strain: f64,
    pub max_strain: f64,
    /// Mean |90° − angle| of the lattice's cells [degrees].
    pub mean_shear_deg: f64,
    /// Particles inside any collider after the last frame.
    pub inside: usize,
    /// Deepest of them [m].
    pub deepest: f32,
    pub stable: bool,
}

/// Simulates `frames` frames of `scene` with `kind` (no files written).
pub fn time_frames(
    scene: &Scene,
    kind: SolverKind,
    threads: usize,
    frames: u32,
) -> Result<FrameTiming> {
    let mut scene = scene.clone();
    scene.solver.kind = kind;
    scene.output.residuals = false;
    let pool = thread_pool(Some(threads))?;
    pool.install(|| {
        let mut sim = Simulation::new(&scene)?;
        // Timed on the threads asked for, busy machine or not.
        sim.sharing = Sharing::whole_team();
        let mut ms = Vec::with_capacity(frames as usize);
        let mut stable = true;
        for _ in 0..frames {
            let start = Instant::now();
            sim.step_frame();
            ms.push(start.elapsed().as_secs_f64() * 1e3);
            if !sim.state.is_finite() {
                stable = false;
                break;
            }
        }
        let timing = crate::report::Timing::of(&ms);
        let error = sim.constraint_error();
        let pen = collide::penetrations(&sim.drivers.colliders, &sim.free_positions());
        Ok(FrameTiming {
            scene: scene.name.clone(),
            solver: kind.name(),
            threads,
            frames,
            ms_per_frame_median: timing.median,
            ms_per_frame_mean: timing.mean,
            mean_strain: error.mean_strain,
            max_strain: error.max_strain,
            mean_shear_deg: error.mean_shear_deg,
            inside: pen.iter().map(|p| p.inside).sum(),
            deepest: pen.iter().map(|p| p.deepest).fold(0.0, f32::max),
            stable: stable && error.max_strain <= 1.0,
        })
    })
}

/// One row of `drape bench sizes`: a solver on a backend at one cloth size.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SizeTiming {
    pub backend: String,
    pub solver: &'static str,
    pub particles: usize,
    /// Local step + one sweep, on scene E's relaxation at this size.
    pub us_per_iteration: f64,
    /// A frame of scene H's hanging cloth at this size (its substeps and iterations).
    pub ms_per_frame: f64,
}

/// Scene `base` with its one garment resized to `n` × `n` particles over the same metre.
pub fn resized(base: &Scene, n: u32) -> Scene {
    let mut scene = base.clone();
    scene.garments[0].resolution = vec![n, n];
    scene.output.residuals = false;
    scene
}

/// Times `kind` at `n` × `n` particles on the CPU (`gpu` None) or a GPU: µs per iteration over
/// `iterations` iterations of scene E's relaxation, and ms per frame over `frames` frames of H.
pub fn time_size(
    kind: SolverKind,
    n: u32,
    iterations: u32,
    frames: u32,
    gpu: Option<&dyn Fn() -> Result<crate::gpu::GpuContext>>,
) -> Result<SizeTiming> {
    use crate::backend::Backend;
    let mut e = resized(
        &crate::scene::reference::load(crate::scene::reference::ENLARGED_CLOTH, "e"),
        n,
    );
    e.solver.kind = kind;
    e.solver.iterations = iterations;
    let mut h = resized(
        &crate::scene::reference::load(crate::scene::reference::HANGING_CLOTH, "h"),
        n,
    );
    h.solver.kind = kind;
    let mut backend = "cpu".to_string();
    // Runs `count` frames of `scene` after one warm-up frame; returns seconds per frame.
    let mut run = |scene: &Scene, count: u32| -> Result<f64> {
        let mut sim = Simulation::new(scene)?;
        sim.sharing = Sharing::whole_team();
        let mut b = match gpu {
            Some(open) => Backend::gpu(open()?, &sim)?,
            None => Backend::Cpu,
        };
        backend = b.name();
        b.step_frame(&mut sim)?;
        let start = Instant::now();
        for _ in 0..count {
            b.step_frame(&mut sim)?;
        }
        Ok(start.elapsed().as_secs_f64() / count as f64)
    };
    let per_iteration = run(&e, 2)? / iterations as f64;
    let per_frame = run(&h, frames)?;
    Ok(SizeTiming {
        backend,
        solver: kind.name(),
        particles: (n * n) as usize,
        us_per_iteration: per_iteration * 1e6,
        ms_per_frame: per_frame * 1e3,
    })
}
