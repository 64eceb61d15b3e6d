//! The simulation loop on the GPU: the same stages as `sim::Simulation` (predict → project →
//! sweep each colour → finish), one compute pass per stage, a whole frame recorded into one
//! command buffer with no CPU waits, and positions (and residuals) read back once per frame.
//!
//! The CPU `Simulation` stays the owner of the model, the colliders and the state the bake
//! measures and exports: after each frame the GPU's positions and velocities are copied into it,
//! so every metric is computed by the same code for both backends.

use super::buffers::{ContactGroup, ResidualGroup, StateGroup, PARAMS_COLOUR, PARAMS_NEXT};
use super::context::GpuContext;
use super::kernels::Kernels;
use super::layout::shell_flags::STATIC;
use super::layout::{GpuCollider, PARAMS_STRIDE, SHELL_PARTICLE_BYTES};
use crate::collide::Shape;
use crate::error::{Error, Result};
use crate::scene::SolverKind;
use crate::sim::schedule::Stage;
use crate::sim::{FrameParts, Simulation};
use glam::{Vec3, Vec4};

/// Threads per workgroup of the per-particle and per-spring kernels (shaders use 64).
const GROUP: u32 = 64;
/// Threads per workgroup of the residual reduction.
const REDUCE_GROUP: u32 = 256;

/// GPU buffers and bind groups of one simulation.
pub struct GpuSimulation {
    ctx: GpuContext,
    kernels: Kernels,
    state: StateGroup,
    residual: ResidualGroup,
    contact: ContactGroup,
    /// Force fields (None without).
    fields: Option<super::fields::FieldGroup>,
    /// Moving characters' shells placed on the GPU from their meshes (None without).
    skin: Option<super::skin::SkinMotion>,
    /// Keyframed attachments and colliders and the attachments that ride skins, evaluated on
    /// the GPU (None without).
    keyframes: Option<super::drive::DrivenMotion>,
    /// The strain limit (None without).
    limit: Option<super::limit::StrainLimit>,
    /// Which shells `skin` places (the CPU sends no snapshots of them).
    placed_on_gpu: Vec<bool>,
    /// Timestamps between the stages of a frame, when the device has them.
    clock: Option<StageClock>,
    /// Shells that never move are uploaded with the first frame only.
    static_shells_uploaded: bool,
    /// Bytes written to the GPU for the last frame (targets of attachments that ride skins,
    /// shells, where the frame starts).
    uploaded_last_frame: u64,
    /// Compute dispatches recorded and command buffers submitted for the last frame: the
    /// launch overhead a hardware GPU pays per frame.
    dispatches: std::cell::Cell<u32>,
    submissions: u32,
    particles: u32,
    springs: u32,
    structural: u32,
    /// Particles in each colour of a sweep ([`crate::sim::model::Model::sweep_colours`]).
    colour_sizes: Vec<u32>,
    /// A small model's separator, swept after them in one dispatch.
    separator: bool,
    /// What every frame runs until the next reload: the solver's settings, the substep's
    /// stages, substeps per frame, and whether particles move under time integration.
    settings: crate::scene::SolverSettings,
    schedule: Vec<Stage>,
    substeps: u32,
    integrating: bool,
}

/// Refuses what the GPU cannot run: sequential Gauss-Seidel, buffers past the adapter's
/// binding size, dispatches past its workgroup count.
fn check_capacity(ctx: &GpuContext, sim: &Simulation) -> Result<()> {
    check_capacity_at(ctx, sim, sim.substeps())
}

/// [`check_capacity`] for `sim` at `substeps` per frame (a budget's largest).
fn check_capacity_at(ctx: &GpuContext, sim: &Simulation, substeps: u32) -> Result<()> {
    if sim.solver_settings().kind == SolverKind::Gs {
        return Err(Error::Gpu {
            reason: "sequential Gauss-Seidel (gs) has no parallel GPU form: use rbgs, jacobi or pbd, or the cpu backend".into(),
        });
    }
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
    // Characters' shells take one share per substep (particles and grids).
    let shell_particles: usize = sim.drivers.shells.iter().map(|s| s.most_particles()).sum();
    let shell_bytes = shell_particles as u64 * SHELL_PARTICLE_BYTES * substeps as u64;
    if shell_bytes > limit as u64 {
        return Err(Error::Gpu {
            reason: format!(
                "characters' shells ({shell_particles} particles) at {} substeps per frame need {} MiB buffers; {} allows {} MiB",
                substeps,
                shell_bytes >> 20,
                ctx.adapter.name,
                limit >> 20
            ),
        });
    }
    let dispatch_limit = ctx.device.limits().max_compute_workgroups_per_dimension as usize;
    if !sim.drivers.shells.is_empty() && substeps as usize > dispatch_limit {
        return Err(Error::Gpu {
            reason: format!(
                "characters' shells are placed for every substep in one dispatch: {} substeps per frame are more than the {dispatch_limit} workgroups {} runs per dispatch",
                substeps, ctx.adapter.name
            ),
        });
    }
    if n.max(model.springs.len()).div_ceil(GROUP as usize) > dispatch_limit {
        return Err(Error::Gpu {
            reason: format!(
                "{n} particles and {} springs need more than the {dispatch_limit} workgroups {} runs per dispatch",
                model.springs.len(),
                ctx.adapter.name
            ),
        });
    }
    Ok(())
}

/// A collider as the kernels read it.
pub(super) fn gpu_collider(c: &crate::collide::Collider) -> GpuCollider {
    use super::layout::collider_kind as kind;
    let mut rotation = glam::Quat::IDENTITY;
    let (kind, radius, offset, vector, second) = match c.shape {
        Shape::Plane { normal, offset } => (kind::PLANE, 0.0, offset, normal, Vec3::ZERO),
        Shape::Sphere { centre, radius } => (kind::SPHERE, radius, 0.0, centre, Vec3::ZERO),
        Shape::Box {
            centre,
            half,
            rotation: r,
        } => {
            rotation = r;
            (kind::BOX, 0.0, 0.0, centre, half)
        }
        Shape::Capsule { start, end, radius } => (kind::CAPSULE, radius, 0.0, start, end),
        Shape::Funnel {
            centre,
            radius,
            top_radius,
            height,
            half_thickness,
        } => (
            kind::FUNNEL,
            radius,
            top_radius,
            centre,
            Vec3::new(height, half_thickness, 0.0),
        ),
        Shape::Wedge {
            centre,
            half,
            rotation: r,
        } => {
            rotation = r;
            (kind::WEDGE, 0.0, 0.0, centre, half)
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
        // Neither tearing nor a budget's change (the reloads) changes the shells or the
        // colliders: these kernels serve every reload.
        let kernels = Kernels::new(
            &ctx.device,
            !sim.drivers.shells.is_empty(),
            !sim.drivers.colliders.is_empty(),
        );
        GpuSimulation::with_kernels(ctx, kernels, sim)
    }

    /// Uploads `sim`'s model and state again, after something changed them on the CPU (tearing
    /// rebuilds the model; a budget changes the substeps and iterations): the kernels are kept.
    pub fn reload(&mut self, sim: &mut Simulation) -> Result<()> {
        // The nearby lists carry over, as they do on the CPU.
        self.read_nearby(sim)?;
        self.take(sim)
    }

    /// Uploads `sim` as it is, its nearby lists too (a frame's start put back into it, at
    /// another budget), keeping the kernels and whether stages are timed; the counts of uploads
    /// and launches start again from none (the caller counts the last frame's first).
    pub fn take(&mut self, sim: &Simulation) -> Result<()> {
        let timed = self.clock.is_some();
        *self = GpuSimulation::with_kernels(self.ctx.clone(), self.kernels.clone(), sim)?;
        if timed != self.clock.is_some() {
            self.time_stages(sim, timed);
        }
        Ok(())
    }

    /// Whether this device could run `sim` at `substeps` per frame (a budget's largest: the
    /// characters' shells take a share of a buffer per substep).
    pub fn fits_substeps(&self, sim: &Simulation, substeps: u32) -> Result<()> {
        check_capacity_at(&self.ctx, sim, substeps)
    }

    fn with_kernels(ctx: GpuContext, kernels: Kernels, sim: &Simulation) -> Result<GpuSimulation> {
        check_capacity(&ctx, sim)?;
        ctx.device.set_device_lost_callback(|reason, message| {
            eprintln!("drape: GPU device lost ({reason:?}): {message}");
        });
        let device = &ctx.device;
        let model = sim.model();
        let state = StateGroup::new(device, &kernels, sim);
        let residual = ResidualGroup::new(device, &kernels, sim, REDUCE_GROUP);
        let contact = ContactGroup::new(device, &kernels, sim);
        let fields = super::fields::FieldGroup::new(device, &kernels, sim);
        let skin = (kernels.skin.as_ref())
            .and_then(|k| super::skin::SkinMotion::new(device, k, sim, &contact));
        let keyframes =
            super::drive::DrivenMotion::new(device, &kernels.drive, sim, &state, &contact);
        let limit = (sim.solver_settings().strain_limit).map(|strain| {
            super::limit::StrainLimit::new(device, &kernels.limit, sim.limit_order(), strain)
        });
        let placed_on_gpu = if skin.is_some() {
            super::skin::placed_on_gpu(sim)
        } else {
            Vec::new()
        };
        // Software adapters' timestamps overlap (lavapipe: their sum exceeds the frame's wall
        // time) and cost it a tenth of P's frame: timed there only when asked.
        let clock = (ctx.adapter.device_type != wgpu::DeviceType::Cpu)
            .then(|| StageClock::new(&ctx, sim))
            .flatten();
        Ok(GpuSimulation {
            clock,
            static_shells_uploaded: false,
            uploaded_last_frame: 0,
            dispatches: std::cell::Cell::new(0),
            submissions: 0,
            particles: model.particle_count() as u32,
            springs: model.springs.len() as u32,
            structural: model.structural_springs as u32,
            colour_sizes: (model.sweep_colours().iter())
                .map(|[low, high]| (low.len() + high.len()) as u32)
                .collect(),
            separator: !model.separator_colours().is_empty(),
            settings: sim.solver_settings().clone(),
            schedule: sim.schedule(),
            substeps: sim.substeps(),
            integrating: sim.integrating(),
            ctx,
            kernels,
            state,
            residual,
            contact,
            fields,
            skin,
            keyframes,
            limit,
            placed_on_gpu,
        })
    }

    /// Times the stages of each frame on the GPU (into the simulation's `stage_times`), when
    /// the device has timestamps inside passes; by default on for hardware adapters only.
    /// Returns whether the stages are timed.
    pub fn time_stages(&mut self, sim: &Simulation, on: bool) -> bool {
        self.clock = if on {
            StageClock::new(&self.ctx, sim)
        } else {
            None
        };
        self.clock.is_some()
    }

    /// Bytes written to the GPU for the last frame: what the CPU computed that the kernels read
    /// (characters' shells it does not place itself, where the frame starts, the ridden
    /// vertices of the character frames it spans).
    pub fn uploaded_last_frame(&self) -> u64 {
        self.uploaded_last_frame
    }

    /// Compute dispatches and queue submissions of the last frame.
    pub fn launches_last_frame(&self) -> (u32, u32) {
        (self.dispatches.get(), self.submissions)
    }

    /// The adapter's "name (type)".
    pub fn adapter(&self) -> String {
        self.ctx.describe()
    }

    /// The adapter's description.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.ctx.adapter
    }

    /// Runs one frame on the GPU, driven by `frame`'s drivers (whose clock it advances by a
    /// frame), and copies positions, velocities and (when it records them) per-sweep residuals
    /// back into its state, the force fields' work and the stage times into its reports.
    pub fn step_frame(&mut self, frame: FrameParts) -> Result<()> {
        self.dispatches.set(0);
        self.submissions = 0;
        let FrameParts {
            drivers,
            state,
            contact_reach,
            residuals,
            force_work,
            stage_times,
            strain_limited,
        } = frame;
        *strain_limited = 0;
        // The shells the GPU does not place itself, substep by substep.
        let static_shells = !self.static_shells_uploaded;
        let driven = drivers.drive_frame(
            contact_reach,
            static_shells,
            &self.placed_on_gpu,
            stage_times,
        );
        self.uploaded_last_frame = self.upload(&driven);
        // The frame's first substep, counted from the bake's start.
        let first = drivers.clock.elapsed() - self.substeps as u64;
        if let Some(skin) = &mut self.skin {
            self.uploaded_last_frame += skin.upload(&self.ctx.queue, &drivers.shells, first);
        }
        if let Some(fields) = &self.fields {
            self.uploaded_last_frame += fields.upload(&self.ctx.queue, self.substeps, first);
        }
        if let Some(keyframes) = &self.keyframes {
            let (attachments, clock) = (&drivers.attachments, &drivers.clock);
            self.uploaded_last_frame +=
                keyframes.upload(&self.ctx.queue, attachments, clock, first);
        }
        let encoder = self.record_frame(residuals.is_some());
        let n = self.particles as u64 * 16;
        let mut encoder = encoder;
        encoder.copy_buffer_to_buffer(&self.state.x, 0, &self.residual.readback, 0, n);
        encoder.copy_buffer_to_buffer(&self.state.velocity, 0, &self.residual.readback, n, n);
        let residual_bytes = 4 * self.residual.sweeps_per_frame as u64;
        if residual_bytes > 0 {
            encoder.copy_buffer_to_buffer(
                &self.residual.residuals,
                0,
                &self.residual.readback,
                2 * n,
                residual_bytes,
            );
        }
        let work_at = 2 * n + residual_bytes;
        if let Some(fields) = &self.fields {
            let size = fields.work.size().min(self.particles as u64 * 4);
            encoder.copy_buffer_to_buffer(&fields.work, 0, &self.residual.readback, work_at, size);
        }
        // The springs the strain limit pulled back, then the keyframed targets' fastest
        // motion, in the readback's last two words.
        let speed_at = self.residual.readback.size() - 4;
        let limited_at = speed_at - 4;
        if let Some(limit) = &self.limit {
            let readback = &self.residual.readback;
            encoder.copy_buffer_to_buffer(&limit.pulled, 0, readback, limited_at, 4);
        }
        if let Some(keyframes) = &self.keyframes {
            let readback = &self.residual.readback;
            encoder.copy_buffer_to_buffer(&keyframes.speed, 0, readback, speed_at, 4);
        }
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        self.ctx.queue.submit([encoder.finish()]);
        self.submissions += 1;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu {
                reason: format!("{}: {e}", self.ctx.adapter.name),
            });
        }
        let slice = self.residual.readback.slice(..);
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
            state.positions.copy_from_slice(x);
            state.velocities.copy_from_slice(v);
            if let Some(r) = residuals {
                let values: &[f32] = bytemuck::cast_slice(&view[2 * n as usize..work_at as usize]);
                r.clear();
                r.extend(values.iter().map(|&e| e as f64));
            }
            if self.limit.is_some() {
                let at = limited_at as usize;
                let pulled: u32 = bytemuck::pod_read_unaligned(&view[at..at + 4]);
                *strain_limited = pulled as u64;
            }
            if self.keyframes.is_some() {
                let at = speed_at as usize;
                let speed: f32 = bytemuck::pod_read_unaligned(&view[at..at + 4]);
                drivers.note_driven_speed(speed);
            }
            if self.fields.is_some() {
                let end = work_at as usize + 4 * self.particles as usize;
                let work: &[f32] = bytemuck::cast_slice(&view[work_at as usize..end]);
                let work: f64 = work.iter().map(|&w| w as f64).sum();
                // Negative work is not counted, as on the CPU.
                *force_work += work.max(0.0);
            }
        }
        self.residual.readback.unmap();
        if let Some(c) = &self.clock {
            c.read(&self.ctx, stage_times)?;
        }
        Ok(())
    }

    /// Copies the GPU's nearby shell lists into `sim` (for a checkpoint: a bake resumed from
    /// it starts its collision passes from the same lists).
    pub fn read_nearby(&self, sim: &mut Simulation) -> Result<()> {
        let Some(source) = &self.contact.shell_nearby else {
            return Ok(());
        };
        let bytes = self.read_back(source, 0, source.size())?;
        sim.set_nearby_lists(bytemuck::pod_collect_to_vec(&bytes));
        Ok(())
    }

    /// Shell `shell` as the kernels read it at the end of substep `substep` of the last frame,
    /// in [`ShellCollider::gpu_snapshot`](crate::collide::ShellCollider::gpu_snapshot)'s form
    /// (for tests against the CPU).
    pub fn read_shell(
        &self,
        substep: u32,
        shell: usize,
    ) -> Result<crate::collide::shell::ShellSnapshot> {
        let (c, info) = (&self.contact, self.contact.shells[shell]);
        // A shell that never moves sits in substep 0's share only.
        let substep = if info.flags & STATIC != 0 { 0 } else { substep };
        let first = (substep * c.shell_stride + info.first) as u64;
        let particles = self.read_back(
            &c.shell_particle,
            SHELL_PARTICLE_BYTES * first,
            SHELL_PARTICLE_BYTES * info.count as u64,
        )?;
        let grid = (substep * c.grid_stride + info.grid) as u64;
        let words = (info.table + 1 + info.count) as u64;
        let grid = self.read_back(&c.shell_grid, 4 * grid, 4 * words)?;
        Ok((
            bytemuck::pod_collect_to_vec(&particles),
            bytemuck::pod_collect_to_vec(&grid),
        ))
    }

    /// `size` bytes of `source` from `offset`, copied back from the GPU.
    fn read_back(&self, source: &wgpu::Buffer, offset: u64, size: u64) -> Result<Vec<u8>> {
        let gpu = |e: String| Error::Gpu {
            reason: format!("{}: {e}", self.ctx.adapter.name),
        };
        let readback = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        encoder.copy_buffer_to_buffer(source, offset, &readback, 0, size);
        self.ctx.queue.submit([encoder.finish()]);
        let slice = readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| gpu(e.to_string()))?;
        let bytes = slice
            .get_mapped_range()
            .map_err(|e| gpu(format!("{e:?}")))?
            .to_vec();
        readback.unmap();
        Ok(bytes)
    }

    /// Writes what the CPU computed for the frame `driven` describes (the shells of every
    /// substep where the kernels read them); returns the bytes.
    fn upload(&mut self, driven: &crate::sim::DrivenFrame) -> u64 {
        let queue = &self.ctx.queue;
        let mut uploaded = 0u64;
        let mut upload = |buffer: &wgpu::Buffer, offset: u64, bytes: &[u8]| {
            queue.write_buffer(buffer, offset, bytes);
            uploaded += bytes.len() as u64;
        };
        // Each shell's entries of each substep where the kernels read them; a shell that never
        // moves once, into the first substep's share, with the first frame (the kernels read
        // it there in every substep of every frame).
        for (substep, shells) in driven.shells.iter().enumerate() {
            for (info, snapshot) in self.contact.shells.iter().zip(shells) {
                let Some((particles, grid)) = snapshot else {
                    continue;
                };
                let at = substep as u64 * self.contact.shell_stride as u64 + info.first as u64;
                upload(
                    &self.contact.shell_particle,
                    at * SHELL_PARTICLE_BYTES,
                    bytemuck::cast_slice(particles),
                );
                let at = substep as u64 * self.contact.grid_stride as u64 + info.grid as u64;
                upload(&self.contact.shell_grid, at * 4, bytemuck::cast_slice(grid));
            }
        }
        self.static_shells_uploaded = true;
        uploaded
    }

    /// Records every substep of a frame (`recording`: with each sweep's residual).
    // Long: one match over the substep's stages (`sim::schedule`, walked as the CPU walks it),
    // each arm the dispatches of one stage.
    fn record_frame(&self, recording: bool) -> wgpu::CommandEncoder {
        let s = &self.settings;
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("drape frame"),
            });
        encoder.clear_buffer(&self.residual.residual_count, 0, None);
        if let Some(fields) = &self.fields {
            encoder.clear_buffer(&fields.work, 0, None);
        }
        if let Some(limit) = &self.limit {
            encoder.clear_buffer(&limit.pulled, 0, None);
        }
        if let Some(skin) = &self.skin {
            let recorded = skin.record(&mut encoder);
            self.dispatches.set(self.dispatches.get() + recorded);
        }
        if let Some(keyframes) = &self.keyframes {
            let recorded = keyframes.record(&mut encoder);
            self.dispatches.set(self.dispatches.get() + recorded);
        }
        let integrating = self.integrating;
        let n = self.particles;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("drape frame"),
            timestamp_writes: None,
        });
        pass.set_bind_group(1, &self.residual.group, &[]);
        pass.set_bind_group(2, &self.contact.group, &[]);
        let dispatch =
            |pass: &mut wgpu::ComputePass,
             pipeline: &wgpu::ComputePipeline,
             slot: u32,
             count: u32,
             size: u32| self.dispatch(pass, pipeline, slot, count, size);
        let k = &self.kernels;
        let mut stamp = 0;
        let mut tick = |pass: &mut wgpu::ComputePass| {
            if let Some(c) = &self.clock {
                pass.write_timestamp(&c.queries, stamp);
                stamp += 1;
            }
        };
        tick(&mut pass);
        // With force fields each substep predicts at its `forces` stage.
        if integrating && self.fields.is_none() {
            dispatch(&mut pass, &k.predict, PARAMS_NEXT, n, GROUP);
        }
        tick(&mut pass);
        // The substep's stages as the CPU runs them (`sim::schedule`).
        for substep in 0..self.substeps {
            for &stage in &self.schedule {
                match stage {
                    Stage::Attach => {
                        if self.contact.attached > 0 {
                            dispatch(
                                &mut pass,
                                &k.attach,
                                self.state.attach_slots + substep,
                                self.contact.attached,
                                GROUP,
                            );
                        }
                    }
                    // Without integration nothing is predicted, fields or not (as on the CPU).
                    Stage::Forces if !integrating => {}
                    Stage::Forces => {
                        let fields = self.fields.as_ref().expect("scheduled with force fields");
                        let slot = self.state.finish_slots + substep;
                        pass.set_bind_group(3, &fields.group, &[]);
                        if fields.faces > 0 {
                            dispatch(&mut pass, &k.wind_faces, slot, fields.faces, GROUP);
                        }
                        dispatch(&mut pass, &k.field_accelerate, slot, n, GROUP);
                    }
                    Stage::Solve { iterations } => {
                        for _ in 0..iterations {
                            self.record_iteration(&mut pass, s, recording);
                        }
                    }
                    Stage::ContactPass => dispatch(
                        &mut pass,
                        &k.contact_pass,
                        self.state.finish_slots + substep,
                        n,
                        GROUP,
                    ),
                    // Sort q = x + Δ into the grid, then each particle's push (added by
                    // `finish`).
                    Stage::ParticleCollisions => {
                        let table = self
                            .contact
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
                            dispatch(
                                &mut pass,
                                &k.finish,
                                self.state.finish_slots + substep,
                                n,
                                GROUP,
                            );
                        } else {
                            dispatch(&mut pass, &k.finish_static, PARAMS_NEXT, n, GROUP);
                        }
                        if self.fields.is_some() && integrating {
                            let slot = self.state.finish_slots + substep;
                            dispatch(&mut pass, &k.field_work_done, slot, n, GROUP);
                        }
                        if let Some(limit) = &self.limit {
                            // One workgroup runs all of the substep's sweeps.
                            pass.set_bind_group(super::limit::GROUP_INDEX, &limit.group, &[]);
                            dispatch(&mut pass, &limit.pipeline, PARAMS_NEXT, 1, 1);
                            // `finish` left the next substep's prediction to this.
                            let next = substep + 1 < self.substeps;
                            if next && integrating && self.fields.is_none() {
                                dispatch(&mut pass, &k.predict, PARAMS_NEXT, n, GROUP);
                            }
                        }
                    }
                }
                tick(&mut pass);
            }
        }
        drop(pass);
        if let Some(c) = &self.clock {
            encoder.resolve_query_set(&c.queries, 0..c.stages.len() as u32 + 1, &c.resolved, 0);
            encoder.copy_buffer_to_buffer(&c.resolved, 0, &c.readback, 0, c.readback.size());
        }
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
        pass.set_bind_group(
            0,
            &self.state.group,
            &[(slot as u64 * PARAMS_STRIDE) as u32],
        );
        pass.dispatch_workgroups(groups(count, size), 1, 1);
        self.dispatches.set(self.dispatches.get() + 1);
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
                for (c, &size) in self.colour_sizes.iter().enumerate() {
                    self.dispatch(pass, &k.sweep, PARAMS_COLOUR + c as u32, size, GROUP);
                }
                if self.separator {
                    // One workgroup (`sweep.wgsl`'s SEPARATOR_GROUP threads).
                    self.dispatch(pass, &k.sweep_separator, PARAMS_NEXT, GROUP, GROUP);
                }
            }
            residual(pass);
        }
    }
}

/// Timestamps written between the stages of a frame (`Features::TIMESTAMP_QUERY_INSIDE_PASSES`):
/// one before the prediction, one after it and one after each stage of each substep; the
/// differences go to the stages' clocks (`stages_ms`), read back with the frame.
struct StageClock {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// The timed stage of each interval between two timestamps.
    stages: Vec<usize>,
    /// Nanoseconds per tick.
    period: f64,
}

impl StageClock {
    /// A clock for `sim`'s frames, when the device has timestamps and a frame needs no more
    /// than a query set holds.
    fn new(ctx: &GpuContext, sim: &Simulation) -> Option<StageClock> {
        if !ctx.timestamps() {
            return None;
        }
        let mut stages = vec![crate::sim::schedule::timed("predict")];
        for _ in 0..sim.substeps() {
            stages.extend(sim.schedule().iter().map(|s| s.timed()));
        }
        let count = stages.len() as u32 + 1;
        if count > wgpu::QUERY_SET_MAX_QUERIES {
            return None;
        }
        let device = &ctx.device;
        let bytes = count as u64 * wgpu::QUERY_SIZE as u64;
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(StageClock {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("stage timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolved: buffer(
                "stage timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "stage timestamps readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            stages,
            period: ctx.queue.get_timestamp_period() as f64,
        })
    }

    /// Adds the last frame's stage times to `times`.
    fn read(&self, ctx: &GpuContext, times: &mut crate::sim::schedule::StageTimes) -> Result<()> {
        let slice = self.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu {
                reason: format!("{}: {e}", ctx.adapter.name),
            })?;
        {
            let view = slice.get_mapped_range().map_err(|e| Error::Gpu {
                reason: format!("stage timestamps: {e:?}"),
            })?;
            let ticks: &[u64] = bytemuck::cast_slice(&view);
            for (stage, pair) in self.stages.iter().zip(ticks.windows(2)) {
                // Timestamps are not promised to increase (a GPU may reorder within a pass).
                let ns = pair[1].saturating_sub(pair[0]) as f64 * self.period;
                times.seconds[*stage] += ns * 1e-9;
            }
        }
        self.readback.unmap();
        Ok(())
    }
}
