//! Keyframed motion evaluated on the GPU (`shaders/drive.wgsl`): the tracks of keyframed
//! attachments and colliders, their attached particles' rest positions and the colliders'
//! shapes at rest are uploaded once; each frame uploads the substep it starts at (32 bytes),
//! and one dispatch writes every substep's keyframed attachment targets and collider poses
//! where `attach`, `finish` and `contact_pass` read them, with the fastest of those motions
//! read back for the stability rule. No CPU work per substep: the CPU only places the
//! attachments that ride a character's skin (its frames are on the CPU).

use super::buffers::{init, ContactGroup, StateGroup, READ, RW};
use super::solver::gpu_collider;
use crate::collide::Collider;
use crate::sim::Simulation;
use bytemuck::{Pod, Zeroable};

/// The kernel file, after common.wgsl (its `Collider` and `quat_rotate`).
pub fn source() -> String {
    format!(
        "{}\n{}",
        super::kernels::COMMON,
        include_str!("../../shaders/drive.wgsl")
    )
}

/// The entry point.
pub const ENTRY: &str = "drive_frame";

/// The bind group's index in the kernel's layout (the groups before it are unused).
pub const GROUP_INDEX: u32 = 3;

/// The WGSL names of the bindings of group 3, in binding order (`tests/shaders.rs` checks them).
pub const BINDINGS: [&str; 9] = [
    "drive",
    "drive_tracks",
    "drive_keys",
    "drive_keyed",
    "drive_moving",
    "drive_start",
    "drive_targets",
    "drive_posed",
    "drive_speed",
];

/// Bindings 1 to this one are read-only storage (0 is the uniform, the rest read-write).
const LAST_READ_ONLY: u32 = 5;

/// Threads per workgroup.
const GROUP: u32 = 64;

/// Workgroups along x of one dispatch (WebGPU's guaranteed limit).
const MAX_WIDTH: u32 = 65_535;

/// One frame's constants (WGSL `DriveFrame`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuDriveFrame {
    pub first: u32,
    pub substeps: u32,
    pub attached: u32,
    pub keyed: u32,
    pub colliders: u32,
    pub moving: u32,
    pub per_second: f32,
    pub step: f32,
}

/// A rigid motion (WGSL `Track`): its keys and pivot.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTrack {
    pub first: u32,
    pub count: u32,
    pub pad: [u32; 2],
    pub pivot: [f32; 4],
}

/// A key (WGSL `Key`): translation with the key's time in w, rotation (x, y, z, w).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuKey {
    pub translation: [f32; 4],
    pub rotation: [f32; 4],
}

/// A keyframed attachment (WGSL `Keyed`): the particle, its track, its rest position.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuKeyed {
    pub particle: u32,
    pub track: u32,
    pub pad: [u32; 2],
    pub rest: [f32; 4],
}

/// A keyframed collider (WGSL `Moving`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuMoving {
    pub index: u32,
    pub track: u32,
    pub pad: [u32; 2],
    pub rest: super::layout::GpuCollider,
}

/// The WGSL structs and the sizes of their Rust mirrors, for the layout test.
pub const MIRRORS: [(&str, usize); 5] = [
    ("DriveFrame", std::mem::size_of::<GpuDriveFrame>()),
    ("Track", std::mem::size_of::<GpuTrack>()),
    ("Key", std::mem::size_of::<GpuKey>()),
    ("Keyed", std::mem::size_of::<GpuKeyed>()),
    ("Moving", std::mem::size_of::<GpuMoving>()),
];

/// The kernel and its bind group layout, built once per device.
#[derive(Clone)]
pub struct DriveKernel {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl DriveKernel {
    pub fn new(device: &wgpu::Device) -> DriveKernel {
        let entries = super::kernels::own_group_entries(BINDINGS.len() as u32, LAST_READ_ONLY);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("drape keyframes"),
            entries: &entries,
        });
        // Group 3 only: the kernel writes buffers that groups 0 and 2 bind read-only.
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("drape keyframes"),
            bind_group_layouts: &[None, None, None, Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("drive.wgsl"),
            source: wgpu::ShaderSource::Wgsl(source().into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(ENTRY),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(ENTRY),
            compilation_options: Default::default(),
            cache: None,
        });
        DriveKernel { layout, pipeline }
    }
}

/// A simulation's keyframed motion on the GPU.
pub struct KeyframedMotion {
    group: wgpu::BindGroup,
    pipeline: wgpu::ComputePipeline,
    frame: wgpu::Buffer,
    constants: GpuDriveFrame,
    /// The fastest motion of the frame's keyframed targets [m/s] (f32 bits), read back.
    pub speed: wgpu::Buffer,
}

impl KeyframedMotion {
    /// The keyframed attachments and colliders of `sim`, writing into `state`'s colliders and
    /// `contact`'s attachment targets; None when nothing is keyframed.
    pub fn new(
        device: &wgpu::Device,
        kernel: &DriveKernel,
        sim: &Simulation,
        state: &StateGroup,
        contact: &ContactGroup,
    ) -> Option<KeyframedMotion> {
        let drivers = &sim.drivers;
        let attachments = &drivers.attachments;
        let keyed = attachments.keyframed();
        let moving = drivers.collider_motion();
        if keyed.is_empty() && moving.is_empty() {
            return None;
        }
        let mut tracks = Vec::new();
        let mut keys = Vec::new();
        let mut add = |track: &crate::sim::attach::Track| {
            tracks.push(GpuTrack {
                first: keys.len() as u32,
                count: track.keys.len() as u32,
                pad: [0; 2],
                pivot: track.pivot.extend(0.0).to_array(),
            });
            keys.extend(track.keys.iter().map(|(time, t, r)| GpuKey {
                translation: t.extend(*time).to_array(),
                rotation: r.to_array(),
            }));
            tracks.len() as u32 - 1
        };
        let attachment_tracks: Vec<u32> = attachments.tracks.iter().map(&mut add).collect();
        let keyed_rest: Vec<GpuKeyed> = (keyed.iter())
            .map(|&(particle, track, rest)| GpuKeyed {
                particle,
                track: attachment_tracks[track],
                pad: [0; 2],
                rest: rest.extend(0.0).to_array(),
            })
            .collect();
        let mut moving_rest: Vec<GpuMoving> = (moving.iter())
            .map(|(index, track, rest)| GpuMoving {
                index: *index as u32,
                track: add(track),
                pad: [0; 2],
                rest: gpu_collider(&Collider {
                    shape: *rest,
                    moved: glam::Vec3::ZERO,
                    ..drivers.colliders[*index]
                }),
            })
            .collect();
        // wgpu binds no empty buffer, and a Moving is larger than `init`'s placeholder.
        if moving_rest.is_empty() {
            moving_rest.push(GpuMoving::default());
        }
        let clock = drivers.clock;
        let constants = GpuDriveFrame {
            first: 0,
            substeps: clock.substeps,
            attached: attachments.list.len() as u32,
            keyed: keyed.len() as u32,
            colliders: drivers.colliders.len() as u32,
            moving: moving.len() as u32,
            per_second: clock.substeps as f32 * clock.fps,
            step: clock.step,
        };
        let frame = init(
            device,
            "drive_frame",
            bytemuck::bytes_of(&constants),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let speed = init(
            device,
            "drive_speed",
            &[0u8; 4],
            RW | wgpu::BufferUsages::COPY_SRC,
        );
        let read = |label: &str, bytes: &[u8]| init(device, label, bytes, READ);
        let buffers = [
            read("drive_tracks", bytemuck::cast_slice(&tracks)),
            read("drive_keys", bytemuck::cast_slice(&keys)),
            read("drive_keyed", bytemuck::cast_slice(&keyed_rest)),
            read("drive_moving", bytemuck::cast_slice(&moving_rest)),
        ];
        let resources: Vec<&wgpu::Buffer> = [&frame]
            .into_iter()
            .chain(&buffers)
            .chain([&state.x, &contact.attach_target, &state.colliders, &speed])
            .collect();
        let entries: Vec<wgpu::BindGroupEntry> = (resources.iter().enumerate())
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("drape keyframes"),
            layout: &kernel.layout,
            entries: &entries,
        });
        Some(KeyframedMotion {
            group,
            pipeline: kernel.pipeline.clone(),
            frame,
            constants,
            speed,
        })
    }

    /// Uploads where the frame starts (`first`: its first substep, counted from the bake's
    /// start); returns the bytes written.
    pub fn upload(&self, queue: &wgpu::Queue, first: u64) -> u64 {
        let constants = GpuDriveFrame {
            first: first as u32,
            ..self.constants
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&constants));
        std::mem::size_of::<GpuDriveFrame>() as u64
    }

    /// Records the frame's keyframed motion: clears the speed, then one dispatch. Returns the
    /// dispatches.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) -> u32 {
        encoder.clear_buffer(&self.speed, 0, None);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("drape keyframes"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(GROUP_INDEX, &self.group, &[]);
        let c = &self.constants;
        let groups = ((c.keyed + c.moving) * c.substeps).div_ceil(GROUP).max(1);
        // Rows of at most a dispatch's width (the kernel numbers invocations across them).
        let width = groups.min(MAX_WIDTH);
        pass.dispatch_workgroups(width, groups.div_ceil(width), 1);
        1
    }
}
