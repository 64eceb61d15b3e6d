//! The GPU buffers of one simulation, a struct per bind group: [`StateGroup`] (group 0: the
//! uniform slots, state, model and colliders), [`ResidualGroup`] (group 1: residuals and the
//! readback), [`ContactGroup`] (group 2: particle collisions, attachments, characters' shells).
//! Each binds its buffers by the names the WGSL gives them ([`BINDINGS`]), so the order in
//! which they are made cannot drift from the shaders'.

use super::kernels::Kernels;
use super::layout::{
    shell_flags, GpuCollider, GpuContacts, GpuParams, GpuParticle, GpuShellInfo, PARAMS_STRIDE,
    SEPARATOR_STARTS,
};
use crate::scene::SolverKind;
use crate::sim::Simulation;
use glam::Vec4;
use wgpu::util::DeviceExt;

/// The WGSL names of every binding of the simulation's kernels, per group, in binding order
/// (`tests/shaders.rs` checks them against the shaders' declarations).
pub const BINDINGS: [&[&str]; 4] = [
    &[
        "params",
        "x",
        "velocity",
        "delta",
        "target_delta",
        "projection",
        "scratch",
        "particle",
        "slot_start",
        "slots",
        "springs",
        "tether_start",
        "tethers",
        "colliders",
    ],
    &["partial", "residuals", "residual_count"],
    &[
        "contacts",
        "pc_cell",
        "pc_bucket",
        "pc_start",
        "pc_cursor",
        "pc_items",
        "pc_push",
        "attach_particle",
        "attach_target",
        "shell_info",
        "shell_particle",
        "shell_grid",
        "shell_nearby",
    ],
    &[
        "field",
        "field_faces",
        "field_rows",
        "field_winds",
        "field_waves",
        "field_attractors",
        "field_time",
        "face_force",
        "field_accel",
        "field_work",
    ],
];

/// Uniform slots: 0 = whole range; 1 + c = colour c's range; then one slot per substep for
/// `attach` (that substep's attachment targets) and one per substep for `finish` (its colliders'
/// poses, and whether it predicts the next substep).
pub const PARAMS_NEXT: u32 = 0;
pub const PARAMS_COLOUR: u32 = 1;

pub(super) const RW: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_SRC)
    .union(wgpu::BufferUsages::COPY_DST);
pub(super) const READ: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE;
/// Refreshed from the CPU (or written by a kernel of their own) and read back by tests.
const READ_REFRESHED: wgpu::BufferUsages = READ
    .union(wgpu::BufferUsages::COPY_DST)
    .union(wgpu::BufferUsages::COPY_SRC);

/// A buffer holding `bytes`; an empty one holds one element of the largest struct (wgpu
/// rejects empty bindings).
pub(super) fn init(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    const LARGEST: usize = std::mem::size_of::<GpuCollider>();
    let bytes = if bytes.is_empty() {
        &[0u8; LARGEST][..]
    } else {
        bytes
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage,
    })
}

/// A bind group of `group` over `named` buffers, each placed at the binding its name has in
/// [`BINDINGS`].
pub(super) fn bind(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    group: usize,
    named: &[(&str, wgpu::BindingResource)],
) -> wgpu::BindGroup {
    let names = BINDINGS[group];
    assert_eq!(
        named.len(),
        names.len(),
        "group {group}: every binding once"
    );
    let entries: Vec<wgpu::BindGroupEntry> = named
        .iter()
        .map(|(name, resource)| wgpu::BindGroupEntry {
            binding: names
                .iter()
                .position(|n| n == name)
                .unwrap_or_else(|| panic!("group {group} has no binding {name}"))
                as u32,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(
            [
                "drape state and model",
                "drape residuals",
                "drape contacts",
                "drape force fields",
            ][group],
        ),
        layout,
        entries: &entries,
    })
}

/// Group 0: what every kernel reads, and the state it moves.
pub struct StateGroup {
    pub x: wgpu::Buffer,
    pub velocity: wgpu::Buffer,
    /// The colliders, one pose per substep when some move (posed per frame by `drive.wgsl`).
    pub colliders: wgpu::Buffer,
    pub moving_colliders: bool,
    /// First uniform slot of the per-substep `attach` ranges and `finish` parameters.
    pub attach_slots: u32,
    pub finish_slots: u32,
    pub group: wgpu::BindGroup,
}

impl StateGroup {
    pub fn new(device: &wgpu::Device, kernels: &Kernels, sim: &Simulation) -> StateGroup {
        let model = sim.model();
        let n = model.particle_count();
        let zeros = bytemuck::cast_slice::<Vec4, u8>(&vec![Vec4::ZERO; n.max(1)]).to_vec();
        let buffer = |label: &str, bytes: &[u8], usage| init(device, label, bytes, usage);
        let x = buffer("x", bytemuck::cast_slice(&sim.state.positions), RW);
        let velocity = buffer("velocity", bytemuck::cast_slice(&sim.state.velocities), RW);
        let (inertia, diag_inv) = sim.solver_rows();
        let particle: Vec<GpuParticle> = (0..n)
            .map(|i| GpuParticle {
                inv_mass: model.inv_mass[i],
                inertia: inertia[i],
                diag_inv: diag_inv[i],
                contact_radius: model.contact_radius[i],
            })
            .collect();
        // Colliders that move have one pose per substep, refreshed every frame.
        let moving = sim.moving_colliders();
        let colliders: Vec<GpuCollider> = (0..if moving { sim.substeps() } else { 1 })
            .flat_map(|_| {
                sim.drivers
                    .colliders
                    .iter()
                    .map(super::solver::gpu_collider)
            })
            .collect();
        let colliders = buffer(
            "colliders",
            bytemuck::cast_slice(&colliders),
            READ_REFRESHED,
        );
        let slots = ParamSlots::new(sim, moving);
        let params = buffer("params", &slots.bytes, wgpu::BufferUsages::UNIFORM);
        let projections = vec![Vec4::ZERO; model.springs.len().max(1)];
        let storage = [
            ("delta", buffer("delta", &zeros, RW)),
            ("target_delta", buffer("target_delta", &zeros, RW)),
            (
                "projection",
                buffer("projection", bytemuck::cast_slice(&projections), RW),
            ),
            ("scratch", buffer("scratch", &zeros, RW)),
            (
                "particle",
                buffer("particle", bytemuck::cast_slice(&particle), READ),
            ),
            (
                "slot_start",
                buffer("slot_start", bytemuck::cast_slice(&model.slot_start), READ),
            ),
            (
                "slots",
                buffer("slots", bytemuck::cast_slice(&model.slot), READ),
            ),
            (
                "springs",
                buffer("springs", bytemuck::cast_slice(&model.springs), READ),
            ),
            (
                "tether_start",
                buffer(
                    "tether_start",
                    bytemuck::cast_slice(&model.tether_start),
                    READ,
                ),
            ),
            (
                "tethers",
                buffer("tethers", bytemuck::cast_slice(&model.tethers), READ),
            ),
        ];
        let mut named = vec![
            (
                "params",
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &params,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<GpuParams>() as u64),
                }),
            ),
            ("x", x.as_entire_binding()),
            ("velocity", velocity.as_entire_binding()),
            ("colliders", colliders.as_entire_binding()),
        ];
        named.extend(storage.iter().map(|(n, b)| (*n, b.as_entire_binding())));
        let group = bind(device, &kernels.group0, 0, &named);
        StateGroup {
            x,
            velocity,
            colliders,
            moving_colliders: moving,
            attach_slots: slots.attach,
            finish_slots: slots.finish,
            group,
        }
    }
}

/// Where each of a small model's separator colours starts, and the last ends, four to a
/// vector (zeros after them; every slot carries them, the separator's dispatch reads them from
/// [`PARAMS_NEXT`]).
fn separator_starts(colours: &[std::ops::Range<usize>]) -> [[u32; 4]; SEPARATOR_STARTS / 4] {
    let mut starts = [[0u32; 4]; SEPARATOR_STARTS / 4];
    let bounds = (colours.iter().map(|r| r.start)).chain(colours.last().map(|r| r.end));
    for (k, at) in bounds.enumerate() {
        starts[k / 4][k % 4] = at as u32;
    }
    starts
}

/// The uniform slots' bytes ([`PARAMS_NEXT`], [`PARAMS_COLOUR`], then `attach` and `finish`
/// per substep).
struct ParamSlots {
    bytes: Vec<u8>,
    attach: u32,
    finish: u32,
}

impl ParamSlots {
    fn new(sim: &Simulation, moving_colliders: bool) -> ParamSlots {
        let model = sim.model();
        let n = model.particle_count() as u32;
        let (h, keep, gravity_step) = sim.integration_constants();
        let collider_count = sim.drivers.colliders.len() as u32;
        let base = GpuParams {
            gravity_step: gravity_step.to_array(),
            particles: n,
            springs: model.springs.len() as u32,
            structural: model.structural_springs as u32,
            colliders: collider_count,
            range_start: 0,
            range_end: n,
            predict_next: 1,
            collider_base: 0,
            step: h,
            inv_step: 1.0 / h,
            keep,
            omega: sim.solver_settings().omega,
            range2_start: 0,
            range2_end: 0,
            separator_colours: model.separator_colours().len() as u32,
            _pad: 0,
            separator_start: separator_starts(model.separator_colours()),
        };
        let attached = sim.drivers.attachments.list.len() as u32;
        let colours = model.sweep_colours();
        let attach = PARAMS_COLOUR + colours.len() as u32;
        let finish = attach + sim.substeps();
        let mut bytes = vec![0u8; PARAMS_STRIDE as usize * (finish + sim.substeps()) as usize];
        let mut put = |slot: u32, p: GpuParams| {
            let at = (slot as u64 * PARAMS_STRIDE) as usize;
            bytes[at..at + std::mem::size_of::<GpuParams>()]
                .copy_from_slice(bytemuck::bytes_of(&p));
        };
        put(PARAMS_NEXT, base);
        for (c, [low, high]) in colours.iter().enumerate() {
            put(
                PARAMS_COLOUR + c as u32,
                GpuParams {
                    range_start: low.start as u32,
                    range_end: low.end as u32,
                    range2_start: high.start as u32,
                    range2_end: high.end as u32,
                    ..base
                },
            );
        }
        for k in 0..sim.substeps() {
            put(
                attach + k,
                GpuParams {
                    range_start: k * attached,
                    range_end: (k + 1) * attached,
                    ..base
                },
            );
            // `finish` of substep k: its colliders' poses, and whether a substep follows in
            // this frame (then it predicts that one); range_start: the substep, whose shell
            // poses `finish` reads.
            put(
                finish + k,
                GpuParams {
                    range_start: k,
                    collider_base: if moving_colliders {
                        k * collider_count
                    } else {
                        0
                    },
                    // With force fields each substep predicts after its fields' `forces` stage;
                    // with a strain limit, after the limit.
                    predict_next: (k + 1 < sim.substeps()
                        && sim.forces().is_none()
                        && sim.solver_settings().strain_limit.is_none())
                        as u32,
                    ..base
                },
            );
        }
        ParamSlots {
            bytes,
            attach,
            finish,
        }
    }
}

/// Group 1: a residual per sweep when recording, and the readback of a frame.
pub struct ResidualGroup {
    pub residuals: wgpu::Buffer,
    pub residual_count: wgpu::Buffer,
    pub readback: wgpu::Buffer,
    pub sweeps_per_frame: u32,
    pub group: wgpu::BindGroup,
}

impl ResidualGroup {
    pub fn new(
        device: &wgpu::Device,
        kernels: &Kernels,
        sim: &Simulation,
        reduce_group: u32,
    ) -> ResidualGroup {
        let settings = sim.solver_settings();
        let n = sim.model().particle_count();
        let inner = if settings.kind == SolverKind::Pbd {
            1
        } else {
            settings.inner_iterations
        };
        let sweeps_per_frame = sim.substeps() * settings.iterations * inner;
        let structural = sim.model().structural_springs as u32;
        let partial_sums = vec![0f32; structural.div_ceil(reduce_group).max(1) as usize];
        let partial = init(device, "partial", bytemuck::cast_slice(&partial_sums), RW);
        let residuals = vec![0f32; sweeps_per_frame as usize];
        let residuals = init(device, "residuals", bytemuck::cast_slice(&residuals), RW);
        let residual_count = init(device, "residual_count", &[0u8; 4], RW);
        let forces_work = if sim.forces().is_some() { n } else { 0 };
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            // Positions, velocities, residuals, the force fields' work per particle, the springs
            // the strain limit pulled back, and the keyframed targets' fastest motion.
            size: (2 * n * 16 + 4 * sweeps_per_frame as usize + 4 * forces_work + 8) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = bind(
            device,
            &kernels.group1,
            1,
            &[
                ("partial", partial.as_entire_binding()),
                ("residuals", residuals.as_entire_binding()),
                ("residual_count", residual_count.as_entire_binding()),
            ],
        );
        ResidualGroup {
            residuals,
            residual_count,
            readback,
            sweeps_per_frame,
            group,
        }
    }
}

/// Group 2: particle–particle collisions (placeholder buffers when off: the layout is shared),
/// attachment targets and characters' shells for every substep of a frame (refreshed per
/// frame: the keyframed targets by `drive.wgsl`, the rest by the CPU).
pub struct ContactGroup {
    /// Hash buckets of the particle-collision grid, or None without particle collisions.
    pub contact_table: Option<u32>,
    pub attached: u32,
    pub attach_target: wgpu::Buffer,
    pub shell_particle: wgpu::Buffer,
    pub shell_grid: wgpu::Buffer,
    /// Each shell's place in a substep's entries, and the entries of one substep (particles,
    /// grid words).
    pub shells: Vec<GpuShellInfo>,
    pub shell_stride: u32,
    pub grid_stride: u32,
    /// Each garment particle's nearby shell particles, per shell (`finish` writes them for the
    /// next substep's collision passes); None without collision passes.
    pub shell_nearby: Option<wgpu::Buffer>,
    pub group: wgpu::BindGroup,
}

/// `bit` when `on`.
fn flag(on: bool, bit: u32) -> u32 {
    if on {
        bit
    } else {
        0
    }
}

/// Each shell's place in the per-substep shell buffers, and the strides of a substep's
/// particles and grid.
fn shell_layout(sim: &Simulation) -> (Vec<GpuShellInfo>, u32, u32) {
    let reach = sim.largest_contact_radius();
    let mut shells = Vec::new();
    let (mut shell_stride, mut grid_stride) = (0u32, 0u32);
    for s in &sim.drivers.shells {
        // A shell re-sampled per frame takes its most particles' room in every substep.
        let count = s.most_particles() as u32;
        let table = crate::collide::ShellCollider::buckets_for(s.most_particles()) as u32;
        shells.push(GpuShellInfo {
            first: shell_stride,
            count,
            grid: grid_stride,
            table,
            radius: s.radius,
            friction: s.friction,
            cell: s.cell_for(reach),
            flags: flag(s.swept, shell_flags::SWEPT)
                | flag(!s.normals.is_empty(), shell_flags::NORMALS)
                | flag(s.is_static(), shell_flags::STATIC),
        });
        shell_stride += count;
        grid_stride += table + 1 + count;
    }
    (shells, shell_stride, grid_stride)
}

impl ContactGroup {
    // Long: the thirteen buffers of group 2, each made and bound by name.
    pub fn new(device: &wgpu::Device, kernels: &Kernels, sim: &Simulation) -> ContactGroup {
        let n = sim.model().particle_count();
        let buffer = |label: &str, bytes: &[u8], usage| init(device, label, bytes, usage);
        let collisions = sim.particle_collisions.as_ref();
        let table = collisions.map_or(1, |c| c.table());
        let (shells, shell_stride, grid_stride) = shell_layout(sim);
        // Collision passes test shells against lists `finish` keeps (none yet: all empty).
        let listing = sim.solver_settings().contact_passes > 1 && !sim.drivers.shells.is_empty();
        let nearby_entries = if listing {
            sim.drivers.shells.len() * n * crate::collide::shell::NEARBY
        } else {
            0
        };
        let contacts = GpuContacts {
            inv_cell: collisions.map_or(0.0, |c| c.inv_cell()),
            diameter: collisions.map_or(0.0, |c| 2.0 * c.radius),
            table: table as u32,
            enabled: collisions.is_some() as u32,
            shells: shells.len() as u32,
            shell_stride,
            grid_stride,
            nearby: listing as u32,
        };
        let contacts = buffer(
            "contacts",
            bytemuck::bytes_of(&contacts),
            wgpu::BufferUsages::UNIFORM,
        );
        let shell_particle = buffer(
            "shell_particle",
            &vec![
                0u8;
                super::layout::SHELL_PARTICLE_BYTES as usize
                    * (shell_stride * sim.substeps()).max(1) as usize
            ],
            READ_REFRESHED,
        );
        let shell_grid = buffer(
            "shell_grid",
            &vec![0u8; 4 * (grid_stride * sim.substeps()).max(1) as usize],
            READ_REFRESHED,
        );
        let attached = sim.drivers.attachments.list.len() as u32;
        let attach_target = buffer(
            "attach_target",
            &vec![0u8; 16 * (attached * sim.substeps()).max(1) as usize],
            READ_REFRESHED,
        );
        let cells = collisions.map_or_else(|| vec![[0i32; 4]], |c| c.cells_and_garments());
        let per_particle = if collisions.is_some() { n.max(1) } else { 1 };
        let attached_particles: Vec<u32> = sim
            .drivers
            .attachments
            .list
            .iter()
            .map(|a| a.particle)
            .collect();
        // The simulation's own lists when it has them (a resumed bake's checkpoint), else empty.
        let nearby: Vec<u32> =
            if sim.nearby_lists().len() * crate::collide::shell::NEARBY == nearby_entries {
                bytemuck::cast_slice(sim.nearby_lists()).to_vec()
            } else {
                vec![u32::MAX; nearby_entries]
            };
        let storage = [
            (
                "pc_cell",
                buffer("pc_cell", bytemuck::cast_slice(&cells), READ),
            ),
            (
                "pc_bucket",
                buffer("pc_bucket", &vec![0u8; 4 * per_particle], RW),
            ),
            (
                "pc_start",
                buffer("pc_start", &vec![0u8; 4 * (table + 1)], RW),
            ),
            (
                "pc_cursor",
                buffer("pc_cursor", &vec![0u8; 4 * (table + 1)], RW),
            ),
            (
                "pc_items",
                buffer("pc_items", &vec![0u8; 4 * per_particle], RW),
            ),
            (
                "pc_push",
                buffer("pc_push", &vec![0u8; 16 * per_particle], RW),
            ),
            (
                "attach_particle",
                buffer(
                    "attach_particle",
                    bytemuck::cast_slice(&attached_particles),
                    READ,
                ),
            ),
            (
                "shell_info",
                buffer("shell_info", bytemuck::cast_slice(&shells), READ),
            ),
            (
                "shell_nearby",
                buffer("shell_nearby", bytemuck::cast_slice(&nearby), RW),
            ),
        ];
        let shell_nearby = storage
            .iter()
            .find(|(name, _)| *name == "shell_nearby")
            .filter(|_| listing)
            .map(|(_, b)| b.clone());
        let mut named = vec![
            ("contacts", contacts.as_entire_binding()),
            ("attach_target", attach_target.as_entire_binding()),
            ("shell_particle", shell_particle.as_entire_binding()),
            ("shell_grid", shell_grid.as_entire_binding()),
        ];
        named.extend(storage.iter().map(|(n, b)| (*n, b.as_entire_binding())));
        let group = bind(device, &kernels.group2, 2, &named);
        ContactGroup {
            contact_table: collisions.map(|_| table as u32),
            attached,
            attach_target,
            shell_particle,
            shell_grid,
            shells,
            shell_stride,
            grid_stride,
            shell_nearby,
            group,
        }
    }
}
