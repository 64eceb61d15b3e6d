//! Driven motion evaluated on the GPU (`shaders/drive.wgsl`): the tracks of keyframed
//! attachments and colliders, their attached particles' rest positions, the colliders' shapes
//! at rest and where each attachment that rides a skin is bound are uploaded once; each frame
//! uploads the substep it starts at (48 bytes), the ridden vertices of the character frames it
//! spans (32 bytes a vertex a frame: a waistband's few hundred) and where each substep's end
//! falls between them (16 bytes a skin a substep). One dispatch then writes every substep's
//! attachment targets and collider poses where `attach`, `finish` and `contact_pass` read
//! them, with the fastest of those motions read back for the stability rule. No CPU work per
//! substep: before, the CPU placed every riding target of every substep and uploaded them.

use super::buffers::{init, ContactGroup, StateGroup, READ, RW};
use super::solver::gpu_collider;
use crate::collide::Collider;
use crate::sim::attach::Attachments;
use crate::sim::{Clock, Simulation};
use bytemuck::{Pod, Zeroable};
use glam::Vec4;

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
pub const BINDINGS: [&str; 13] = [
    "drive",
    "drive_tracks",
    "drive_keys",
    "drive_keyed",
    "drive_moving",
    "ride_bound",
    "ride_skins",
    "ride_times",
    "ride_window",
    "drive_start",
    "drive_targets",
    "drive_posed",
    "drive_speed",
];

/// Bindings 1 to this one are read-only storage (0 is the uniform, the rest read-write).
const LAST_READ_ONLY: u32 = 9;

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
    pub riding: u32,
    pub skins: u32,
    pub pad: [u32; 2],
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

/// An attachment that rides a skin (WGSL `Riding`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuRiding {
    pub particle: u32,
    pub skin: u32,
    pub pad: [u32; 2],
    pub corners: [u32; 4],
    pub bary: [f32; 4],
    pub offset: [f32; 4],
}

/// A skin's place in the window (WGSL `RiddenSkin`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuRiddenSkin {
    pub window: u32,
    pub ridden: u32,
    pub pad: [u32; 2],
}

/// Where a substep's end falls in a skin's window (WGSL `RideTime`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuRideTime {
    pub before: u32,
    pub after: u32,
    pub weight: f32,
    pub pad: u32,
}

/// The WGSL structs and the sizes of their Rust mirrors, for the layout test.
pub const MIRRORS: [(&str, usize); 8] = [
    ("DriveFrame", std::mem::size_of::<GpuDriveFrame>()),
    ("Track", std::mem::size_of::<GpuTrack>()),
    ("Key", std::mem::size_of::<GpuKey>()),
    ("Keyed", std::mem::size_of::<GpuKeyed>()),
    ("Moving", std::mem::size_of::<GpuMoving>()),
    ("Riding", std::mem::size_of::<GpuRiding>()),
    ("RiddenSkin", std::mem::size_of::<GpuRiddenSkin>()),
    ("RideTime", std::mem::size_of::<GpuRideTime>()),
];

/// The kernel and its bind group layout, built once per device.
#[derive(Clone)]
pub struct DriveKernel {
    own: super::kernels::OwnGroup,
}

impl DriveKernel {
    pub fn new(device: &wgpu::Device) -> DriveKernel {
        let source = source();
        let file = super::kernels::OwnGroupFile {
            label: "drape keyframes",
            file: "drive.wgsl",
            source: &source,
            entries: &[ENTRY],
            bindings: BINDINGS.len() as u32,
            last_read_only: LAST_READ_ONLY,
            // Group 3 only: the kernel writes buffers that groups 0 and 2 bind read-only.
            before: &[None, None, None],
        };
        DriveKernel {
            own: super::kernels::OwnGroup::new(device, &file),
        }
    }
}

/// A simulation's driven motion on the GPU: keyframed attachments and colliders, and the
/// attachments that ride skins.
pub struct DrivenMotion {
    group: wgpu::BindGroup,
    pipeline: wgpu::ComputePipeline,
    frame: wgpu::Buffer,
    constants: GpuDriveFrame,
    /// The skins' ridden vertices of the character frames the frame spans.
    window: wgpu::Buffer,
    /// Per substep, per skin: where its end falls in the window.
    times: wgpu::Buffer,
    /// Per skin ridden: its first entry in the window and its slots there.
    skins: Vec<(GpuRiddenSkin, usize)>,
    /// The fastest motion of the frame's driven targets [m/s] (f32 bits), read back.
    pub speed: wgpu::Buffer,
}

/// The most character frames one frame's substeps can fall between: the frame's substeps end
/// within one character frame of each other, so they span two frames' intervals at the most.
const WINDOW_SLOTS: usize = 3;

impl DrivenMotion {
    /// The keyframed attachments and colliders of `sim` and its attachments that ride skins,
    /// writing into `state`'s colliders and `contact`'s attachment targets; None when nothing
    /// is driven.
    // Long: the tracks, keyed attachments, colliders and riding attachments laid out, then
    // thirteen buffers made and bound.
    pub fn new(
        device: &wgpu::Device,
        kernel: &DriveKernel,
        sim: &Simulation,
        state: &StateGroup,
        contact: &ContactGroup,
    ) -> Option<DrivenMotion> {
        let drivers = &sim.drivers;
        let attachments = &drivers.attachments;
        let keyed = attachments.keyframed();
        let moving = drivers.collider_motion();
        let riding = attachments.riding();
        if keyed.is_empty() && moving.is_empty() && riding.is_empty() {
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
        let mut bound: Vec<GpuRiding> = (riding.iter())
            .map(|r| GpuRiding {
                particle: r.particle,
                skin: r.skin,
                pad: [0; 2],
                corners: [r.corners[0], r.corners[1], r.corners[2], 0],
                bary: r.bary.extend(0.0).to_array(),
                offset: r.offset.extend(0.0).to_array(),
            })
            .collect();
        if bound.is_empty() {
            bound.push(GpuRiding::default());
        }
        let mut entries = 0usize;
        let skins: Vec<(GpuRiddenSkin, usize)> = (attachments.skins.iter())
            .map(|skin| {
                let slots = skin.frames.len().min(WINDOW_SLOTS);
                let info = GpuRiddenSkin {
                    window: entries as u32,
                    ridden: skin.ridden_count() as u32,
                    pad: [0; 2],
                };
                entries += 2 * slots * skin.ridden_count();
                (info, slots)
            })
            .collect();
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
            riding: riding.len() as u32,
            skins: skins.len() as u32,
            pad: [0; 2],
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
        let refreshed = |label: &str, bytes: usize| {
            let zeros = vec![0u8; bytes.max(16)];
            init(device, label, &zeros, READ | wgpu::BufferUsages::COPY_DST)
        };
        let infos: Vec<GpuRiddenSkin> = skins.iter().map(|(info, _)| *info).collect();
        let window = refreshed("ride_window", 16 * entries);
        let times = refreshed("ride_times", 16 * skins.len() * clock.substeps as usize);
        let buffers = [
            read("drive_tracks", bytemuck::cast_slice(&tracks)),
            read("drive_keys", bytemuck::cast_slice(&keys)),
            read("drive_keyed", bytemuck::cast_slice(&keyed_rest)),
            read("drive_moving", bytemuck::cast_slice(&moving_rest)),
            read("ride_bound", bytemuck::cast_slice(&bound)),
            read("ride_skins", bytemuck::cast_slice(&infos)),
        ];
        let resources: Vec<&wgpu::Buffer> = (buffers.iter())
            .chain([&times, &window, &state.x])
            .chain([&contact.attach_target, &state.colliders, &speed])
            .collect();
        let resources: Vec<&wgpu::Buffer> = [&frame].into_iter().chain(resources).collect();
        let group = kernel.own.bind(device, "drape driven motion", &resources);
        Some(DrivenMotion {
            group,
            pipeline: kernel.own.pipelines[0].clone(),
            frame,
            constants,
            window,
            times,
            skins,
            speed,
        })
    }

    /// Uploads where the frame starts (`first`: its first substep, counted from the bake's
    /// start) and, for the attachments that ride skins, the ridden vertices of the character
    /// frames it spans and where each substep falls between them (`attachments` on `clock`);
    /// returns the bytes written.
    pub fn upload(
        &self,
        queue: &wgpu::Queue,
        attachments: &Attachments,
        clock: &Clock,
        first: u64,
    ) -> u64 {
        let constants = GpuDriveFrame {
            first: first as u32,
            ..self.constants
        };
        queue.write_buffer(&self.frame, 0, bytemuck::bytes_of(&constants));
        let mut written = std::mem::size_of::<GpuDriveFrame>() as u64;
        if self.constants.riding == 0 {
            return written;
        }
        let substeps = clock.substeps as u64;
        let mut times = vec![GpuRideTime::default(); self.skins.len() * substeps as usize];
        for (k, (skin, (info, slots))) in attachments.skins.iter().zip(&self.skins).enumerate() {
            // Each substep's frames as the CPU takes them (`Attachments::position`); at weight
            // 0 the later one is not read, so the window need not hold it.
            let spans: Vec<(usize, usize, f32)> = (0..substeps)
                .map(|s| skin.span(clock.end_of(first + s) * clock.fps))
                .map(|(k, j, w)| (k, if w == 0.0 { k } else { j }, w))
                .collect();
            let low = spans.iter().map(|span| span.0).min().unwrap_or(0);
            let high = spans.iter().map(|span| span.1).max().unwrap_or(0);
            debug_assert!(high - low < *slots.max(&1), "frames {low}..={high}");
            for (s, &(before, after, weight)) in spans.iter().enumerate() {
                times[s * self.skins.len() + k] = GpuRideTime {
                    before: (before - low) as u32,
                    after: (after - low) as u32,
                    weight,
                    pad: 0,
                };
            }
            let entries: Vec<Vec4> = (low..=high)
                .flat_map(|frame| skin.ridden_at(frame))
                .flat_map(|(position, normal)| [position.extend(0.0), normal.extend(0.0)])
                .collect();
            let bytes: &[u8] = bytemuck::cast_slice(&entries);
            queue.write_buffer(&self.window, 16 * info.window as u64, bytes);
            written += bytes.len() as u64;
        }
        let bytes: &[u8] = bytemuck::cast_slice(&times);
        queue.write_buffer(&self.times, 0, bytes);
        written + bytes.len() as u64
    }

    /// Records the frame's driven motion: clears the speed, then one dispatch. Returns the
    /// dispatches.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) -> u32 {
        encoder.clear_buffer(&self.speed, 0, None);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("drape driven motion"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(GROUP_INDEX, &self.group, &[]);
        let c = &self.constants;
        let groups = ((c.keyed + c.moving + c.riding) * c.substeps)
            .div_ceil(GROUP)
            .max(1);
        // Rows of at most a dispatch's width (the kernel numbers invocations across them).
        let width = groups.min(MAX_WIDTH);
        pass.dispatch_workgroups(width, groups.div_ceil(width), 1);
        1
    }
}
