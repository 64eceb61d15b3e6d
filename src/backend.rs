//! Where a simulation runs: one interface over the CPU team and the GPU, so the bake, the benches
//! and the studies step frames without asking which.
//!
//! The [`Simulation`] stays the one source of truth on both: the CPU steps it in place; the GPU
//! steps its own copy of the state and reads positions, velocities and residuals back into it
//! after every frame (one readback per frame), so measuring and exporting never depend on the
//! backend.

use crate::error::Result;
use crate::gpu::{GpuContext, GpuSimulation};
use crate::scene::BackendKind;
use crate::sim::Simulation;

/// The backend a simulation runs on.
pub enum Backend {
    /// The multi-threaded CPU stages (the current rayon pool's threads).
    Cpu,
    /// wgpu compute on an adapter.
    Gpu(Box<GpuSimulation>),
}

impl Backend {
    /// The GPU backend on `ctx`'s adapter, with `sim`'s model and state uploaded.
    pub fn gpu(ctx: GpuContext, sim: &Simulation) -> Result<Backend> {
        Ok(Backend::Gpu(Box::new(GpuSimulation::new(ctx, sim)?)))
    }

    /// The backend a scene's `backend` asks for: `cpu`, `gpu` on any adapter (failing with the
    /// reason), or `auto`, a hardware GPU when there is one, else the CPU with a warning.
    pub fn for_scene(
        kind: BackendKind,
        sim: &Simulation,
        warnings: &mut Vec<String>,
    ) -> Result<Backend> {
        match kind {
            BackendKind::Cpu => Ok(Backend::Cpu),
            BackendKind::Gpu => Backend::gpu(GpuContext::new(false)?, sim),
            BackendKind::Auto => {
                if !crate::gpu::context::hardware_present() {
                    warnings.push(
                        "backend auto: no GPU device on this machine; simulating on the CPU".into(),
                    );
                    return Ok(Backend::Cpu);
                }
                match GpuContext::new(true).and_then(|ctx| Backend::gpu(ctx, sim)) {
                    Ok(b) => Ok(b),
                    Err(e) => {
                        warnings.push(format!("backend auto: {e}; simulating on the CPU"));
                        Ok(Backend::Cpu)
                    }
                }
            }
        }
    }

    /// Advances `sim` by one frame; on the GPU the state is read back into `sim` at the end.
    pub fn step_frame(&mut self, sim: &mut Simulation) -> Result<()> {
        match self {
            Backend::Cpu => {
                sim.step_frame();
                Ok(())
            }
            Backend::Gpu(g) => g.step_frame(sim.frame_parts()),
        }
    }

    /// Steps one frame unless `stop` asks between its substeps (then `sim` is as the frame
    /// started and the result false). The GPU runs a frame in one submission: it is not
    /// stopped inside one.
    pub fn step_frame_or_stop(
        &mut self,
        sim: &mut Simulation,
        stop: &dyn Fn() -> bool,
    ) -> Result<bool> {
        match self {
            Backend::Cpu => Ok(sim.step_frame_or_stop(stop)),
            Backend::Gpu(g) => g.step_frame(sim.frame_parts()).map(|()| true),
        }
    }

    /// Takes `sim`'s model and state afresh (after tearing changed the springs, or a budget the
    /// substeps and iterations), keeping what only the GPU held (its nearby shell lists).
    pub fn reload(&mut self, sim: &mut Simulation) -> Result<()> {
        match self {
            Backend::Cpu => Ok(()),
            Backend::Gpu(g) => g.reload(sim),
        }
    }

    /// Takes `sim` as it is, after a frame's start was put back into it at another budget (the
    /// GPU uploads its state, nearby lists and budget; nothing on the CPU).
    pub fn upload(&mut self, sim: &Simulation) -> Result<()> {
        match self {
            Backend::Cpu => Ok(()),
            Backend::Gpu(g) => g.take(sim),
        }
    }

    /// Whether the backend can run `sim` at `substeps` per frame (a budget's largest; the CPU
    /// always can).
    pub fn fits_substeps(&self, sim: &Simulation, substeps: u32) -> Result<()> {
        match self {
            Backend::Cpu => Ok(()),
            Backend::Gpu(g) => g.fits_substeps(sim, substeps),
        }
    }

    /// Brings into `sim` what only the backend kept and a checkpoint needs (the GPU's nearby
    /// shell lists; nothing on the CPU).
    pub fn sync_for_checkpoint(&mut self, sim: &mut Simulation) -> Result<()> {
        match self {
            Backend::Cpu => Ok(()),
            Backend::Gpu(g) => g.read_nearby(sim),
        }
    }

    /// Bytes the last frame wrote to the GPU (None on the CPU).
    pub fn uploaded_last_frame(&self) -> Option<u64> {
        match self {
            Backend::Cpu => None,
            Backend::Gpu(g) => Some(g.uploaded_last_frame()),
        }
    }

    /// Compute dispatches and queue submissions of the last frame (None on the CPU).
    pub fn launches_last_frame(&self) -> Option<(u32, u32)> {
        match self {
            Backend::Cpu => None,
            Backend::Gpu(g) => Some(g.launches_last_frame()),
        }
    }

    /// True on the GPU.
    pub fn is_gpu(&self) -> bool {
        matches!(self, Backend::Gpu(_))
    }

    /// The GPU adapter, on the GPU.
    pub fn adapter_info(&self) -> Option<&wgpu::AdapterInfo> {
        match self {
            Backend::Cpu => None,
            Backend::Gpu(g) => Some(g.adapter_info()),
        }
    }

    /// `"cpu"`, or `"gpu: <adapter>"`, for benchmark tables.
    pub fn name(&self) -> String {
        match self {
            Backend::Cpu => "cpu".into(),
            Backend::Gpu(g) => format!("gpu: {}", g.adapter()),
        }
    }
}
