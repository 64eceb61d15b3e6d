//! Force fields on the GPU (group 3, `shaders/forces.wgsl`): the garments' faces and each
//! particle's faces, the winds' constants and gust waves, the attractors, uploaded once; each
//! frame uploads one entry per substep and wind (the steady velocity, keyframed or not, and the
//! time the gusts read), and reads back the work the fields did with the positions.

use super::buffers::{bind, init, READ, RW};
use super::kernels::Kernels;
use crate::sim::Simulation;
use bytemuck::{Pod, Zeroable};

/// The counts the kernels loop over (WGSL `FieldCounts`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuFieldCounts {
    pub faces: u32,
    pub winds: u32,
    pub attractors: u32,
    pub rows: u32,
}

/// The force fields' buffers and bind group.
pub struct FieldGroup {
    pub faces: u32,
    winds: usize,
    /// The fields (their steady winds are uploaded per substep).
    forces: crate::sim::forces::Forces,
    /// Substeps per second.
    per_second: f32,
    time: wgpu::Buffer,
    /// Each particle's work this frame [J] (cleared per frame, read back with the positions).
    pub work: wgpu::Buffer,
    pub group: wgpu::BindGroup,
}

impl FieldGroup {
    /// The buffers of `sim`'s force fields; None without any.
    pub fn new(device: &wgpu::Device, kernels: &Kernels, sim: &Simulation) -> Option<FieldGroup> {
        let forces = sim.forces()?;
        let tables = forces.gpu_tables();
        let n = sim.model().particle_count();
        let counts = GpuFieldCounts {
            faces: tables.faces.len() as u32,
            winds: tables.winds.len() as u32,
            attractors: (tables.attractors.len() / 2) as u32,
            rows: n as u32 + 1,
        };
        let winds = forces.winds();
        let uniform = init(
            device,
            "field",
            bytemuck::bytes_of(&counts),
            wgpu::BufferUsages::UNIFORM,
        );
        let refreshed = READ | wgpu::BufferUsages::COPY_DST;
        let time_bytes = vec![0u8; 16 * sim.substeps() as usize * winds.max(1)];
        let time = init(device, "field_time", &time_bytes, refreshed);
        let work = init(device, "field_work", &vec![0u8; 4 * n.max(1)], RW);
        let buffers = [
            ("field", uniform),
            (
                "field_faces",
                init(
                    device,
                    "field_faces",
                    bytemuck::cast_slice(&tables.faces),
                    READ,
                ),
            ),
            (
                "field_rows",
                init(
                    device,
                    "field_rows",
                    bytemuck::cast_slice(&tables.rows),
                    READ,
                ),
            ),
            (
                "field_winds",
                init(
                    device,
                    "field_winds",
                    bytemuck::cast_slice(&tables.winds),
                    READ,
                ),
            ),
            (
                "field_waves",
                init(
                    device,
                    "field_waves",
                    bytemuck::cast_slice(&tables.waves),
                    READ,
                ),
            ),
            (
                "field_attractors",
                init(
                    device,
                    "field_attractors",
                    bytemuck::cast_slice(&tables.attractors),
                    READ,
                ),
            ),
            ("field_time", time.clone()),
            (
                "face_force",
                init(
                    device,
                    "face_force",
                    &vec![0u8; 16 * tables.faces.len()],
                    RW,
                ),
            ),
            (
                "field_accel",
                init(device, "field_accel", &vec![0u8; 16 * n.max(1)], RW),
            ),
            ("field_work", work.clone()),
        ];
        let named: Vec<(&str, wgpu::BindingResource)> = (buffers.iter())
            .map(|(name, b)| (*name, b.as_entire_binding()))
            .collect();
        let group = bind(device, &kernels.group3, 3, &named);
        Some(FieldGroup {
            faces: counts.faces,
            winds,
            forces: forces.clone(),
            per_second: sim.substeps() as f32 * sim.fps(),
            time,
            work,
            group,
        })
    }

    /// Uploads each substep's steady wind and start time for the frame whose substeps start at
    /// substep `first` of the bake; returns the bytes written.
    /// `substeps`: the frame's.
    pub fn upload(&self, queue: &wgpu::Queue, substeps: u32, first: u64) -> u64 {
        let mut entries = Vec::with_capacity(substeps as usize * self.winds.max(1));
        for k in 0..substeps as u64 {
            // As `Simulation::substep` computes it on the CPU.
            let t = (first + k) as f32 / self.per_second;
            let steady = self.forces.steady_at(t);
            if steady.is_empty() {
                entries.push(glam::Vec4::new(0.0, 0.0, 0.0, t));
            }
            entries.extend(steady);
        }
        let bytes: &[u8] = bytemuck::cast_slice(&entries);
        queue.write_buffer(&self.time, 0, bytes);
        bytes.len() as u64
    }
}
