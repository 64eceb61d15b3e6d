//! The simulation loop on the GPU: the same stages as `sim::Simulation` (predict → project →
//! sweep each colour → finish), one compute pass per stage, a whole frame recorded into one
//! command buffer with no CPU waits, and positions (and residuals) read back once per frame.
//!
//! The CPU `Simulation` stays the owner of the model, the colliders and the state the bake
//! measures and exports: after each frame the GPU's positions and velocities are copied into it,
//! so every metric is computed by the same code for both backends.

use super::context::GpuContext;
use super::kernels::Kernels;
use super::layout::{
    GpuCollider, GpuContacts, GpuParams, GpuParticle, GpuShellInfo, PARAMS_STRIDE,
};
use crate::collide::Shape;
use crate::error::{Error, Result};
use crate::scene::SolverKind;
use crate::sim::schedule::Stage;
use crate::sim::Simulation;
use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

/// Threads per workgroup of the per-particle and per-spring kernels (shaders use 64).
const GROUP: u32 = 64;
/// Threads per workgroup of the residual reduction.
const REDUCE_GROUP: u32 = 256;

/// Uniform slots: 0 = whole range; 1 + c = colour c's range; then one slot per substep for
/// `attach` (that substep's attachment targets) and one per substep for `finish` (its colliders'
/// poses, and whether it predicts the next substep).
const PARAMS_NEXT: u32 = 0;
const PARAMS_COLOUR: u32 = 1;

/// GPU buffers and bind groups of one simulation.
pub struct GpuSimulation {
    ctx: GpuContext,
    kernels: Kernels,
    x: wgpu::Buffer,
    velocity: wgpu::Buffer,
    residuals: wgpu::Buffer,
    residual_count: wgpu::Buffer,
    readback: wgpu::Buffer,
    group0: wgpu::BindGroup,
    group1: wgpu::BindGroup,
    group2: wgpu::BindGroup,
    /// Hash buckets of the particle-collision grid, or None without particle collisions.
    contact_table: Option<u32>,
    /// Attached particles, and their targets for every substep of a frame (refreshed per frame).
    attached: u32,
    attach_target: wgpu::Buffer,
    /// First uniform slot of the per-substep `attach` ranges.
    attach_slots: u32,
    /// First uniform slot of the per-substep `finish` parameters.
    finish_slots: u32,
    /// The colliders, one pose per substep when some move (refreshed per frame).
    colliders: wgpu::Buffer,
    moving_colliders: bool,
    /// Characters' shells, every substep of a frame (refreshed per frame).
    shell_particle: wgpu::Buffer,
    shell_grid: wgpu::Buffer,
    has_shells: bool,
    particles: u32,
    springs: u32,
    structural: u32,
    colour_ranges: Vec<(u32, u32)>,
    /// Sweeps per frame, each with a residual when recording.
    sweeps_per_frame: u32,
}

/// Bind group entries for `buffers` at bindings 1, 2, … (binding 0 is each group's uniform).
fn storage_entries<'a>(buffers: &[&'a wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'a>> {
    buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry {
            binding: k as u32 + 1,
            resource: b.as_entire_binding(),
        })
        .collect()
}

/// A collider as the kernels read it.
fn gpu_collider(c: &crate::collide::Collider) -> GpuCollider {
    use super::layout::collider_kind as kind;
    let mut rotation = glam::Quat::IDENTITY;
    let (kind, radius, offset, vector, second) = match c.shape {
        Shape::Plane { normal, offset } => (kind::PLANE, 0.0, offset, normal, Vec3::ZERO),
        Shape::Sphere { center, radius } => (kind::SPHERE, radius, 0.0, center, Vec3::ZERO),
        Shape::Box {
            center,
            half,
            rotation: r,
        } => {
            rotation = r;
            (kind::BOX, 0.0, 0.0, center, half)
        }
        Shape::Capsule { start, end, radius } => (kind::CAPSULE, radius, 0.0, start, end),
        Shape::Funnel {
            center,
            radius,
            top_radius,
            height,
            half_thickness,
        } => (
            kind::FUNNEL,
            radius,
            top_radius,
            center,
            Vec3::new(height, half_thickness, 0.0),
        ),
        Shape::Wedge {
            center,
            half,
            rotation: r,
        } => {
            rotation = r;
            (kind::WEDGE, 0.0, 0.0, center, half)
        }
    };
    GpuCollider {
        kind,
        friction: c.friction,
        radius,
        offset,
        vector: vector.extend(0.0).to_array(),
        // w: 1 when the swept test is on.
        second: second.extend(if c.swept { 1.0 } else { 0.0 }).to_array(),
        rotation: rotation.to_array(),
        moved: c.moved.extend(0.0).to_array(),
    }
}

fn groups(count: u32, size: u32) -> u32 {
    count.div_ceil(size).max(1)
}

impl GpuSimulation {
    /// Uploads `sim`'s model and state to the GPU of `ctx`.
    pub fn new(ctx: GpuContext, sim: &Simulation) -> Result<GpuSimulation> {
        let kernels = Kernels::new(&ctx.device);
        GpuSimulation::with_kernels(ctx, kernels, sim)
    }

    /// Uploads `sim`'s model and state again, after something changed them on the CPU (tearing
    /// rebuilds the model): the kernels are kept.
    pub fn reload(&mut self, sim: &Simulation) -> Result<()> {
        *self = GpuSimulation::with_kernels(self.ctx.clone(), self.kernels.clone(), sim)?;
        Ok(())
    }

    fn with_kernels(ctx: GpuContext, kernels: Kernels, sim: &Simulation) -> Result<GpuSimulation> {
        let settings = &sim.solver_settings();
        if settings.kind == SolverKind::Gs {
            return Err(Error::Gpu {
                reason: "sequential Gauss-Seidel (gs) has no parallel GPU form: use rbgs, jacobi or pbd, or the cpu backend".into(),
            });
        }
        let device = &ctx.device;
        let model = sim.model();
        let n = model.particle_count();
        let limit = ctx.device.limits().max_storage_buffer_binding_size as usize;
        if n * 16 > limit || model.slot.len() * 12 > limit {
            return Err(Error::Gpu {
                reason: format!(
                    "{n} particles need {} MiB buffers; {} allows {} MiB",
                    (model.slot.len() * 12).max(n * 16) >> 20,
                    ctx.adapter.name,
                    limit >> 20
                ),
            });
        }
        let dispatch_limit = ctx.device.limits().max_compute_workgroups_per_dimension as usize;
        if n.max(model.springs.len()).div_ceil(GROUP as usize) > dispatch_limit {
            return Err(Error::Gpu {
                reason: format!(
                    "{n} particles and {} springs need more than the {dispatch_limit} workgroups {} runs per dispatch",
                    model.springs.len(),
                    ctx.adapter.name
                ),
            });
        }
        ctx.device.set_device_lost_callback(|reason, message| {
            eprintln!("drape: GPU device lost ({reason:?}): {message}");
        });
        let rw = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        let init = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            // wgpu rejects empty bindings: keep one element of the largest struct (the collider).
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
        };
        let zeros = vec![Vec4::ZERO; n.max(1)];
        let x = init("x", bytemuck::cast_slice(&sim.state.positions), rw);
        let velocity = init("velocity", bytemuck::cast_slice(&sim.state.velocities), rw);
        let delta = init("delta", bytemuck::cast_slice(&zeros), rw);
        let target = init("target", bytemuck::cast_slice(&zeros), rw);
        let projection = init(
            "projection",
            bytemuck::cast_slice(&vec![Vec4::ZERO; model.springs.len().max(1)]),
            rw,
        );
        let scratch = init("scratch", bytemuck::cast_slice(&zeros), rw);
        let read = wgpu::BufferUsages::STORAGE;
        let (inertia, diag_inv) = sim.solver_rows();
        let particle: Vec<GpuParticle> = (0..n)
            .map(|i| GpuParticle {
                inv_mass: model.inv_mass[i],
                inertia: inertia[i],
                diag_inv: diag_inv[i],
                contact_radius: model.contact_radius[i],
            })
            .collect();
        let particle = init("particle", bytemuck::cast_slice(&particle), read);
        let slot_start = init("slot_start", bytemuck::cast_slice(&model.slot_start), read);
        let slots = init("slots", bytemuck::cast_slice(&model.slot), read);
        let springs = init("springs", bytemuck::cast_slice(&model.springs), read);
        let tether_start = init(
            "tether_start",
            bytemuck::cast_slice(&model.tether_start),
            read,
        );
        let tethers = init("tethers", bytemuck::cast_slice(&model.tethers), read);
        // Colliders that move have one pose per substep, refreshed every frame.
        let moving = sim.moving_colliders();
        let collider_count = sim.colliders.len() as u32;
        let colliders: Vec<GpuCollider> = (0..if moving { sim.substeps } else { 1 })
            .flat_map(|_| sim.colliders.iter().map(gpu_collider))
            .collect();
        let colliders_buffer = init(
            "colliders",
            bytemuck::cast_slice(&colliders),
            read | wgpu::BufferUsages::COPY_DST,
        );

        let colour_ranges: Vec<(u32, u32)> = model
            .colour_ranges
            .iter()
            .map(|r| (r.start as u32, r.end as u32))
            .collect();
        let (h, keep, gravity_step) = sim.integration_constants();
        let base = GpuParams {
            gravity_step: gravity_step.to_array(),
            particles: n as u32,
            springs: model.springs.len() as u32,
            structural: model.structural_springs as u32,
            colliders: collider_count,
            range_start: 0,
            range_end: n as u32,
            predict_next: 1,
            collider_base: 0,
            step: h,
            inv_step: 1.0 / h,
            keep,
            omega: settings.omega,
        };
        let attached = sim.attachments.list.len() as u32;
        let attach_slots = PARAMS_COLOUR + colour_ranges.len() as u32;
        let finish_slots = attach_slots + sim.substeps;
        let mut params = vec![0u8; PARAMS_STRIDE as usize * (finish_slots + sim.substeps) as usize];
        let mut put = |slot: u32, p: GpuParams| {
            let at = (slot as u64 * PARAMS_STRIDE) as usize;
            params[at..at + std::mem::size_of::<GpuParams>()]
                .copy_from_slice(bytemuck::bytes_of(&p));
        };
        put(PARAMS_NEXT, base);
        for (c, &(start, end)) in colour_ranges.iter().enumerate() {
            put(
                PARAMS_COLOUR + c as u32,
                GpuParams {
                    range_start: start,
                    range_end: end,
                    ..base
                },
            );
        }
        for k in 0..sim.substeps {
            put(
                attach_slots + k,
                GpuParams {
                    range_start: k * attached,
                    range_end: (k + 1) * attached,
                    ..base
                },
            );
            // `finish` of substep k: its colliders' poses, and whether a substep follows in
            // this frame (then it predicts that one).
            put(
                finish_slots + k,
                GpuParams {
                    // range_start: the substep, whose shell poses `finish` reads.
                    range_start: k,
                    collider_base: if moving { k * collider_count } else { 0 },
                    predict_next: (k + 1 < sim.substeps) as u32,
                    ..base
                },
            );
        }
        let params = init("params", &params, wgpu::BufferUsages::UNIFORM);

        let sweeps_per_frame = sim.substeps
            * settings.iterations
            * if settings.kind == SolverKind::Pbd {
                1
            } else {
                settings.inner_iterations
            };
        let structural = model.structural_springs as u32;
        let partial = init(
            "residual partial sums",
            bytemuck::cast_slice(&vec![0f32; groups(structural, REDUCE_GROUP) as usize]),
            rw,
        );
        let residuals = init(
            "residuals",
            bytemuck::cast_slice(&vec![0f32; sweeps_per_frame as usize]),
            rw,
        );
        let residual_count = init("residual count", &[0u8; 4], rw);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: (2 * n * 16 + 4 * sweeps_per_frame as usize) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });

        let storage_buffers = [
            &x,
            &velocity,
            &delta,
            &target,
            &projection,
            &scratch,
            &particle,
            &slot_start,
            &slots,
            &springs,
            &tether_start,
            &tethers,
            &colliders_buffer,
        ];
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &params,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<GpuParams>() as u64),
            }),
        }];
        entries.extend(storage_entries(&storage_buffers));
        let group0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("drape state and model"),
            layout: &kernels.group0,
            entries: &entries,
        });
        let group1 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("drape residuals"),
            layout: &kernels.group1,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: partial.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: residuals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: residual_count.as_entire_binding(),
                },
            ],
        });
        // Particle–particle collisions (placeholder buffers when off: the layout is shared).
        let collisions = sim.particle_collisions.as_ref();
        let table = collisions.map_or(1, |c| c.table());
        // Characters' shells: each one's particles and grid within a substep's share.
        let reach = sim.largest_contact_radius();
        let mut shells = Vec::new();
        let (mut shell_stride, mut grid_stride) = (0u32, 0u32);
        for s in &sim.shells {
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
                flags: s.swept as u32 | ((!s.normals.is_empty()) as u32) << 1,
            });
            shell_stride += count;
            grid_stride += table + 1 + count;
        }
        // Collision passes test shells against lists `finish` keeps (none yet: all empty).
        let passes = settings.contact_passes;
        let listing = passes > 1 && !sim.shells.is_empty();
        let nearby_entries = if listing {
            sim.shells.len() * n * crate::collide::shell::NEARBY
        } else {
            0
        };
        let shell_nearby = init(
            "shell_nearby",
            bytemuck::cast_slice(&vec![u32::MAX; nearby_entries]),
            rw,
        );
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
        let shell_info = init("shell_info", bytemuck::cast_slice(&shells), read);
        let shell_particle = init(
            "shell_particle",
            &vec![0u8; 48 * (shell_stride * sim.substeps).max(1) as usize],
            read | wgpu::BufferUsages::COPY_DST,
        );
        let shell_grid = init(
            "shell_grid",
            &vec![0u8; 4 * (grid_stride * sim.substeps).max(1) as usize],
            read | wgpu::BufferUsages::COPY_DST,
        );
        let contacts = init(
            "contacts",
            bytemuck::bytes_of(&contacts),
            wgpu::BufferUsages::UNIFORM,
        );
        let cells = collisions.map_or_else(|| vec![[0i32; 4]], |c| c.cells_and_garments());
        let cells = init("pc_cell", bytemuck::cast_slice(&cells), read);
        let per_particle = if collisions.is_some() { n.max(1) } else { 1 };
        let pc_bucket = init("pc_bucket", &vec![0u8; 4 * per_particle], rw);
        let pc_start = init("pc_start", &vec![0u8; 4 * (table + 1)], rw);
        let pc_cursor = init("pc_cursor", &vec![0u8; 4 * (table + 1)], rw);
        let pc_items = init("pc_items", &vec![0u8; 4 * per_particle], rw);
        let pc_push = init("pc_push", &vec![0u8; 16 * per_particle], rw);
        let particles_attached: Vec<u32> =
            sim.attachments.list.iter().map(|a| a.particle).collect();
        let attach_particle = init(
            "attach_particle",
            bytemuck::cast_slice(&particles_attached),
            read,
        );
        let attach_target = init(
            "attach_target",
            &vec![0u8; 16 * (attached * sim.substeps).max(1) as usize],
            read | wgpu::BufferUsages::COPY_DST,
        );
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: contacts.as_entire_binding(),
        }];
        entries.extend(storage_entries(&[
            &cells,
            &pc_bucket,
            &pc_start,
            &pc_cursor,
            &pc_items,
            &pc_push,
            &attach_particle,
            &attach_target,
            &shell_info,
            &shell_particle,
            &shell_grid,
            &shell_nearby,
        ]));
        let group2 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("drape particle collisions"),
            layout: &kernels.group2,
            entries: &entries,
        });
        Ok(GpuSimulation {
            ctx,
            kernels,
            group2,
            contact_table: collisions.map(|_| table as u32),
            attached,
            attach_target,
            attach_slots,
            finish_slots,
            colliders: colliders_buffer,
            moving_colliders: moving,
            shell_particle,
            shell_grid,
            has_shells: !sim.shells.is_empty(),
            x,
            velocity,
            residuals,
            residual_count,
            readback,
            group0,
            group1,
            particles: n as u32,
            springs: model.springs.len() as u32,
            structural,
            colour_ranges,
            sweeps_per_frame,
        })
    }

    /// The adapter's "name (type)".
    pub fn adapter(&self) -> String {
        self.ctx.describe()
    }

    /// The adapter's description.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.ctx.adapter
    }

    /// Runs one frame on the GPU and copies positions, velocities and (when `sim` records them)
    /// per-sweep residuals back into `sim`.
    pub fn step_frame(&mut self, sim: &mut Simulation) -> Result<()> {
        // Where the attached particles go this frame, substep by substep (also advances the
        // simulation's clock).
        let driven = sim.drive_frame();
        if self.attached > 0 {
            let targets: Vec<Vec4> = driven
                .attachments
                .iter()
                .flatten()
                .map(|(_, t)| t.extend(0.0))
                .collect();
            self.ctx
                .queue
                .write_buffer(&self.attach_target, 0, bytemuck::cast_slice(&targets));
        }
        if self.has_shells {
            let mut particles: Vec<[Vec4; 3]> = Vec::new();
            let mut grid: Vec<u32> = Vec::new();
            for substep in &driven.shells {
                for (p, g) in substep {
                    particles.extend_from_slice(p);
                    grid.extend_from_slice(g);
                }
            }
            let queue = &self.ctx.queue;
            queue.write_buffer(&self.shell_particle, 0, bytemuck::cast_slice(&particles));
            queue.write_buffer(&self.shell_grid, 0, bytemuck::cast_slice(&grid));
        }
        if self.moving_colliders {
            let poses: Vec<GpuCollider> = driven
                .colliders
                .iter()
                .flatten()
                .map(gpu_collider)
                .collect();
            self.ctx
                .queue
                .write_buffer(&self.colliders, 0, bytemuck::cast_slice(&poses));
        }
        let encoder = self.record_frame(sim);
        let n = self.particles as u64 * 16;
        let mut encoder = encoder;
        encoder.copy_buffer_to_buffer(&self.x, 0, &self.readback, 0, n);
        encoder.copy_buffer_to_buffer(&self.velocity, 0, &self.readback, n, n);
        let residual_bytes = 4 * self.sweeps_per_frame as u64;
        if residual_bytes > 0 {
            encoder.copy_buffer_to_buffer(
                &self.residuals,
                0,
                &self.readback,
                2 * n,
                residual_bytes,
            );
        }
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        self.ctx.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu {
                reason: format!("{}: {e}", self.ctx.adapter.name),
            });
        }
        let slice = self.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu {
                reason: format!("{}: {e}", self.ctx.adapter.name),
            })?;
        {
            let view = slice.get_mapped_range().map_err(|e| Error::Gpu {
                reason: format!("readback: {e:?}"),
            })?;
            let floats: &[Vec4] = bytemuck::cast_slice(&view[..2 * n as usize]);
            let (x, v) = floats.split_at(self.particles as usize);
            sim.state.positions.copy_from_slice(x);
            sim.state.velocities.copy_from_slice(v);
            if let Some(r) = &mut sim.residuals {
                let values: &[f32] = bytemuck::cast_slice(&view[2 * n as usize..]);
                r.clear();
                r.extend(values.iter().map(|&e| e as f64));
            }
        }
        self.readback.unmap();
        Ok(())
    }

    /// Records every substep of a frame.
    fn record_frame(&self, sim: &Simulation) -> wgpu::CommandEncoder {
        let s = sim.solver_settings();
        let recording = sim.residuals.is_some();
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("drape frame"),
            });
        encoder.clear_buffer(&self.residual_count, 0, None);
        let integrating = sim.integrating();
        let n = self.particles;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("drape frame"),
            timestamp_writes: None,
        });
        pass.set_bind_group(1, &self.group1, &[]);
        pass.set_bind_group(2, &self.group2, &[]);
        let dispatch =
            |pass: &mut wgpu::ComputePass,
             pipeline: &wgpu::ComputePipeline,
             slot: u32,
             count: u32,
             size: u32| self.dispatch(pass, pipeline, slot, count, size);
        let k = &self.kernels;
        if integrating {
            dispatch(&mut pass, &k.predict, PARAMS_NEXT, n, GROUP);
        }
        // The substep's stages as the CPU runs them (`sim::schedule`).
        let schedule = sim.schedule();
        for substep in 0..sim.substeps {
            for &stage in &schedule {
                match stage {
                    Stage::Attach => {
                        if self.attached > 0 {
                            dispatch(
                                &mut pass,
                                &k.attach,
                                self.attach_slots + substep,
                                self.attached,
                                GROUP,
                            );
                        }
                    }
                    Stage::Solve { iterations } => {
                        for _ in 0..iterations {
                            self.record_iteration(&mut pass, s, recording);
                        }
                    }
                    Stage::ContactPass => dispatch(
                        &mut pass,
                        &k.contact_pass,
                        self.finish_slots + substep,
                        n,
                        GROUP,
                    ),
                    // Sort q = x + Δ into the grid, then each particle's push (added by
                    // `finish`).
                    Stage::ParticleCollisions => {
                        let table = self
                            .contact_table
                            .expect("scheduled with particle collisions");
                        dispatch(&mut pass, &k.pc_clear, PARAMS_NEXT, table + 1, GROUP);
                        dispatch(&mut pass, &k.pc_count, PARAMS_NEXT, n, GROUP);
                        dispatch(&mut pass, &k.pc_scan, PARAMS_NEXT, 1, 1);
                        dispatch(&mut pass, &k.pc_scatter, PARAMS_NEXT, n, GROUP);
                        dispatch(&mut pass, &k.pc_order, PARAMS_NEXT, table, GROUP);
                        dispatch(&mut pass, &k.pc_push_out, PARAMS_NEXT, n, GROUP);
                    }
                    Stage::Finish => {
                        if integrating {
                            dispatch(&mut pass, &k.finish, self.finish_slots + substep, n, GROUP);
                        } else {
                            dispatch(&mut pass, &k.finish_static, PARAMS_NEXT, n, GROUP);
                        }
                    }
                }
            }
        }
        drop(pass);
        encoder
    }

    /// One compute dispatch of `count` invocations in groups of `size`, with the parameters at
    /// `slot` of the uniform buffer.
    fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass,
        pipeline: &wgpu::ComputePipeline,
        slot: u32,
        count: u32,
        size: u32,
    ) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.group0, &[(slot as u64 * PARAMS_STRIDE) as u32]);
        pass.dispatch_workgroups(groups(count, size), 1, 1);
    }

    /// One solver iteration (`Solver::iterate`): a PBD iteration, or the local step and the
    /// inner sweeps of the global step; with `recording`, the residual after each sweep.
    fn record_iteration(
        &self,
        pass: &mut wgpu::ComputePass,
        s: &crate::scene::SolverSettings,
        recording: bool,
    ) {
        let (k, n) = (&self.kernels, self.particles);
        let residual = |pass: &mut wgpu::ComputePass| {
            if recording {
                let partial = &k.residual_partial;
                self.dispatch(pass, partial, PARAMS_NEXT, self.structural, REDUCE_GROUP);
                self.dispatch(pass, &k.residual_total, PARAMS_NEXT, 1, 1);
            }
        };
        if s.kind == SolverKind::Pbd {
            self.dispatch(pass, &k.pbd, PARAMS_NEXT, n, GROUP);
            self.dispatch(pass, &k.copy_scratch, PARAMS_NEXT, n, GROUP);
            residual(pass);
            return;
        }
        self.dispatch(pass, &k.project, PARAMS_NEXT, self.springs, GROUP);
        for _ in 0..s.inner_iterations {
            if s.kind == SolverKind::Jacobi {
                self.dispatch(pass, &k.jacobi, PARAMS_NEXT, n, GROUP);
                self.dispatch(pass, &k.copy_scratch, PARAMS_NEXT, n, GROUP);
            } else {
                for (c, &(start, end)) in self.colour_ranges.iter().enumerate() {
                    self.dispatch(pass, &k.sweep, PARAMS_COLOUR + c as u32, end - start, GROUP);
                }
            }
            residual(pass);
        }
    }
}
