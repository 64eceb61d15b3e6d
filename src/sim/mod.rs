//! Simulation: a static [`Model`], a changing [`State`] and a [`Solver`], advanced one frame at a
//! time, with its parts beside them: the [`Drivers`] (colliders, shells, attachments, the clock
//! and the shells' focus), the CPU's workspace (scratch buffers and collision-pass caches),
//! settling, tearing and the force fields. Each substep runs the stages `schedule` lists:
//! predict, solve with its collision passes (and particle collisions), then `finish` (tethers,
//! collisions, commit, and the next substep's prediction). Within a frame the substeps run as
//! [`team`] regions: one region for the whole frame when nothing moves the garments from
//! outside, else one per substep, with the drivers placed between them.

pub mod attach;
pub mod constraint;
pub mod drivers;
pub mod forces;
pub mod integrate;
pub mod limit;
pub mod metrics;
pub mod model;
pub mod schedule;
pub mod separator;
mod settle;
pub mod snapshot;
pub mod solver;
mod stages;
pub mod state;
pub mod team;
pub mod tear;
mod workspace;

use crate::collide::particles::ParticleCollisions;
use crate::error::{Error, Result};
use crate::garment::Garment;
use crate::scene::{IntegratorKind, Scene, SolverSettings};
pub use drivers::{Clock, DrivenFrame, Drivers};
use forces::FieldState;
use glam::{Vec3, Vec4};
use integrate::{Integration, Verlet};
pub use model::Model;
use settle::Settling;
pub use solver::Solver;
pub use state::State;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use team::Member;
use tear::Tearing;
use workspace::{SubstepInputs, Workspace};

/// A running simulation of one scene's garments.
pub struct Simulation {
    /// Private: the solver indexes it unchecked, so it must not change after validation.
    model: Model,
    pub state: State,
    /// Colliders, characters' shells, attachments, the clock and the shells' focus.
    pub drivers: Drivers,
    solver: Solver,
    integration: Integration,
    /// The CPU substeps' buffers and collision-pass caches.
    workspace: Workspace,
    settling: Settling,
    tearing: Tearing,
    fields: FieldState,
    /// Particle–particle collisions (self and between garments), when the scene asks for them.
    pub particle_collisions: Option<ParticleCollisions>,
    /// When set, the total squared error after every sweep of the current frame.
    pub residuals: Option<Vec<f64>>,
    /// Wall time of each stage so far ([`schedule::TIMED`]; the bake adds its own).
    pub stage_times: schedule::StageTimes,
    /// Who runs the team's regions, frame by frame ([`team::Sharing`]).
    pub sharing: team::Sharing,
    /// Springs the strain limit pulled back in the last frame stepped, each counted once per
    /// substep it was past the limit (`solver.strain_limit`).
    pub strain_limited: u64,
    /// The structural springs in the strain limit's sweep order (empty without a limit).
    limit_order: limit::LimitOrder,
}

/// What a backend that runs whole frames elsewhere (the GPU) drives and writes back: the
/// drivers and the state, and what a frame reports (residuals, the force fields' work, stage
/// times), not the rest of the simulation.
pub struct FrameParts<'a> {
    pub drivers: &'a mut Drivers,
    pub state: &'a mut State,
    /// The largest contact radius [m] (shell grids are built for it).
    pub contact_reach: f32,
    pub residuals: Option<&'a mut Vec<f64>>,
    /// Work the force fields did on the garments so far [J]: a backend adds the positive part
    /// of each frame's.
    pub force_work: &'a mut f64,
    pub stage_times: &'a mut schedule::StageTimes,
    /// Springs the strain limit pulled back in the frame (see [`Simulation::strain_limited`]).
    pub strain_limited: &'a mut u64,
}

impl Simulation {
    /// Builds the garments, model, solver and colliders of a (validated) scene without
    /// characters: a scene with characters is built with their shells and skins by
    /// [`crate::bake::simulation`], the one way to a complete simulation of it. `Err` when a
    /// garment cannot be built (a mesh garment's file unreadable, an attachment that selects
    /// nothing) or the scene has characters.
    pub fn new(scene: &Scene) -> Result<Simulation> {
        if !scene.characters.is_empty() {
            return Err(Error::InvalidField {
                file: "scene".into(),
                field: "characters".into(),
                reason: "a scene with characters is built by drape::bake::simulation, which \
                         loads them"
                    .into(),
            });
        }
        let garments = crate::garment::build_all(scene, "scene")?;
        Ok(Simulation::from_garments(
            scene,
            &garments,
            scene.solver.clone(),
        ))
    }

    /// Builds a simulation of `garments` with the timing, forces and colliders of `scene` (no
    /// characters' shells: [`crate::bake::simulation`] adds them).
    pub fn from_garments(
        scene: &Scene,
        garments: &[Garment],
        solver: SolverSettings,
    ) -> Simulation {
        let model = Model::new(garments);
        let start: Vec<Vec3> = garments
            .iter()
            .flat_map(|g| g.positions.iter().copied())
            .collect();
        let state = State::at_rest(&model, &start);
        let step = scene.step_seconds();
        let gravity = Vec3::from(scene.gravity);
        let integrating = scene.integrator == IntegratorKind::Verlet;
        let solver = Solver::new(&model, solver, integrating.then_some(step));
        let particle_collisions = scene.particle_collisions.then(|| {
            let radius = scene
                .particle_radius
                .unwrap_or_else(|| ParticleCollisions::default_radius(garments));
            ParticleCollisions::new(&model.storage_of, garments, radius)
        });
        let attachments = attach::Attachments::new(&scene.garments, garments, |g, p| {
            model.storage_of[model.garments[g].export.start + p as usize]
        });
        Simulation {
            fields: FieldState {
                fields: forces::Forces::new(&scene.forces, &model),
                ..FieldState::default()
            },
            tearing: Tearing {
                garments: garments.to_vec(),
                strain: scene.garments.iter().map(|g| g.tear_strain).collect(),
                torn_springs: 0,
            },
            drivers: Drivers::new(scene, attachments),
            workspace: Workspace::new(&model, particle_collisions.as_ref()),
            particle_collisions,
            settling: Settling::default(),
            integration: Integration {
                verlet: integrating.then(|| Verlet::new(gravity, scene.damping, step)),
                gravity,
                damping: scene.damping,
            },
            residuals: scene.output.residuals.then(Vec::new),
            stage_times: schedule::StageTimes::default(),
            sharing: team::Sharing::default(),
            strain_limited: 0,
            limit_order: limit_order(&model, &solver.settings),
            model,
            state,
            solver,
        }
    }

    /// The stages of one substep of this simulation ([`schedule::substep`]).
    pub fn schedule(&self) -> Vec<schedule::Stage> {
        schedule::substep(
            &self.solver.settings,
            schedule::Features {
                attachments: !self.drivers.attachments.list.is_empty(),
                particle_collisions: self.particle_collisions.is_some(),
                forces: self.fields.fields.is_some(),
            },
        )
    }

    /// Breaks the springs of tearable garments stretched past their strain, and rebuilds the
    /// model and solver around what is left (particle storage order stays the same).
    pub fn tear(&mut self) -> usize {
        let positions = self.export_positions();
        let ranges = self.model.garments.iter().map(|g| g.export.clone());
        let broken = self.tearing.tear(&positions, ranges);
        if broken > 0 {
            self.rebuild_model();
        }
        broken
    }

    /// The model, solver and faces built again from the garments (after tearing changed them;
    /// particle storage order stays the same).
    fn rebuild_model(&mut self) {
        self.model = Model::new(&self.tearing.garments);
        self.limit_order = limit_order(&self.model, &self.solver.settings);
        self.solver = Solver::new(
            &self.model,
            self.solver.settings.clone(),
            self.integration.verlet.map(|v| v.step),
        );
        self.workspace.fit_springs(&self.model);
        if let Some(f) = &mut self.fields.fields {
            f.set_faces(&self.model);
        }
    }

    /// True when some garment can tear.
    pub fn tears(&self) -> bool {
        self.tearing.any()
    }

    /// Springs broken so far.
    pub fn torn_springs(&self) -> usize {
        self.tearing.torn_springs
    }

    /// Particles the later collision passes left out by their slack so far (see
    /// [`Simulation::set_pass_slack`]).
    pub fn passes_left_out(&self) -> u64 {
        self.workspace.passes_left_out()
    }

    /// Whether later collision passes leave out the tests a particle's slack stands for (on by
    /// default; off, every pass tests every particle in full, to the same result).
    pub fn set_pass_slack(&mut self, on: bool) {
        self.workspace.pass_slack_enabled = on;
    }

    /// Whether particle collisions keep neighbour lists between substeps (on by default; off,
    /// every substep finds its pairs in a grid directly, to the same result).
    pub fn set_particle_lists(&mut self, on: bool) {
        self.workspace.particle_lists_enabled = on;
    }

    /// Substeps whose particle collisions found their pairs in neighbour lists an earlier
    /// substep made, so far.
    pub fn particle_lists_reused(&self) -> u64 {
        self.workspace.lists_reused()
    }

    /// Advances one frame (all substeps).
    pub fn step_frame(&mut self) {
        self.step_frame_shared(None);
    }

    /// Advances one frame unless `stop` says so between its substeps: then the simulation is
    /// put back where the frame started and false returned. Only frames of more than
    /// [`LONG_FRAME`] particle-iterations are watched (a shorter one ends within a fraction
    /// of a second anyway); they are run in pieces of about [`WATCHED_PIECE`] between which
    /// `stop` is asked, and give the frame [`Simulation::step_frame`] gives to the bit.
    pub fn step_frame_or_stop(&mut self, stop: &dyn Fn() -> bool) -> bool {
        if self.frame_work() < LONG_FRAME {
            self.step_frame();
            return true;
        }
        let before = self.snapshot();
        let whole = self.step_frame_shared(Some(stop));
        if !whole {
            self.restore(&before)
                .expect("a simulation takes its own snapshot");
        }
        whole
    }

    /// One frame's substeps ([`Simulation::step_frame_watched`]) with the team's statistics
    /// gathered for the frame and handed to `sharing` after it.
    fn step_frame_shared(&mut self, stop: Option<&dyn Fn() -> bool>) -> bool {
        self.sharing.begin_frame();
        let start = std::time::Instant::now();
        let whole = self.step_frame_watched(stop);
        self.sharing.end_frame(start.elapsed().as_secs_f64());
        whole
    }

    /// Particle-iterations of one frame: particles × substeps × outer × inner iterations.
    fn frame_work(&self) -> f64 {
        let s = &self.solver.settings;
        self.model.particle_count() as f64
            * self.drivers.clock.substeps as f64
            * s.iterations as f64
            * s.inner_iterations.max(1) as f64
    }

    /// The frame's substeps, asking `stop` (when given) between pieces of them; false when it
    /// said stop before the last.
    fn step_frame_watched(&mut self, stop: Option<&dyn Fn() -> bool>) -> bool {
        if let Some(r) = &mut self.residuals {
            r.clear();
        }
        self.strain_limited = 0;
        let substeps = self.drivers.clock.substeps;
        let limited = self.solver.settings.strain_limit.is_some();
        if !self.drivers.move_within_frames()
            && self.fields.fields.is_none()
            && !self.settling.is_on()
            && !limited
        {
            let Some(stop) = stop else {
                self.run_substeps(substeps, None, false, false);
                return true;
            };
            // In pieces: each piece's last `finish` predicts the next piece's first substep,
            // as one region would.
            let per_substep = self.frame_work() / substeps as f64;
            let piece = ((WATCHED_PIECE / per_substep) as u32).clamp(1, substeps);
            let mut done = 0;
            while done < substeps {
                let count = piece.min(substeps - done);
                done += count;
                self.run_substeps(count, None, done < substeps, false);
                if done < substeps && stop() {
                    self.workspace.predicted_at = None;
                    return false;
                }
            }
            true
        } else {
            // Characters, attachment targets and force fields change every substep: they
            // advance between team regions.
            let start = std::time::Instant::now();
            self.focus_shells(true);
            self.stage_times.lap(schedule::timed("shells"), start);
            // A settling frame caps the kinetic energy after each substep, and a strain limit
            // moves particles after it, so no `finish` predicts the next substep then.
            let settling = self.settling.is_on();
            for k in 0..self.drivers.clock.substeps {
                self.substep_in_frame(!settling && !limited);
                self.cap_kinetic_energy();
                if k + 1 < self.drivers.clock.substeps && stop.is_some_and(|stop| stop()) {
                    self.settling.end();
                    self.workspace.predicted_at = None;
                    self.drivers.focus.checked_at = None;
                    return false;
                }
            }
            self.settling.end();
            self.workspace.predicted_at = None;
            self.drivers.focus.checked_at = None;
            true
        }
    }

    /// Caps the coming frame's kinetic energy, after each of its substeps, at what the frame
    /// starts with plus what gravity and the force fields have given since and what the
    /// fastest driven motion could carry (½ M v²); velocities above it are scaled down alike
    /// (see [`settle`]).
    pub fn settle_frame(&mut self) {
        let (model, state) = (&self.model, &self.state);
        let g = self.integration.gravity;
        self.settling.begin(model, state, g, self.fields.work);
    }

    /// Kinetic energy the last settled frame took out [J] (0 when none was settled).
    pub fn settled_energy(&self) -> f64 {
        self.settling.settled
    }

    /// Scales the moving particles' velocities down to the settling frame's cap, if above it.
    fn cap_kinetic_energy(&mut self) {
        let g = self.integration.gravity;
        let (work, speed) = (self.fields.work, self.drivers.driven_speed);
        (self.settling).cap(&self.model, &mut self.state, g, work, speed);
    }

    /// Advances one substep.
    pub fn substep(&mut self) {
        self.workspace.predicted_at = None;
        self.drivers.focus.checked_at = None;
        self.substep_in_frame(false);
    }

    /// Advances one substep; `frame`: one of [`Self::step_frame`]'s, whose `finish` may predict
    /// the next substep and check the shells' focus for it (nothing outside the simulation moves
    /// the cloth between them).
    fn substep_in_frame(&mut self, frame: bool) {
        let start = std::time::Instant::now();
        self.focus_shells(false);
        self.advance_shells();
        let placed = self.stage_times.lap(schedule::timed("shells"), start);
        self.drivers.place_attachments(&mut self.state);
        let pushed = self
            .stage_times
            .lap(schedule::Stage::Attach.timed(), placed);
        if let Some(f) = &mut self.fields.fields {
            let t = self.drivers.clock.time();
            let (x, v) = (&self.state.positions, &self.state.velocities);
            f.accelerations(&self.model, x, v, t, &mut self.fields.external);
            self.stage_times.lap(schedule::timed("forces"), pushed);
        }
        // The next substep's shells are placed during this one's `finish`, within the frame
        // (a frame's first substep focuses them afresh).
        let clock = self.drivers.clock;
        let next = clock.elapsed + 1;
        let within = next % clock.substeps as u64 != 0;
        let ahead = within.then(|| (next + 1) as f32 / clock.substeps as f32);
        // Without force fields or attachments, which change the next prediction between
        // substeps, `finish` predicts the next substep of the frame too.
        let unforced = self.fields.fields.is_none() && self.drivers.attachments.list.is_empty();
        self.run_substeps(1, ahead, frame && within && unforced, frame && within);
        if self.fields.fields.is_some() {
            let (v, mass) = (&self.state.velocities, &self.model.mass);
            self.fields.add_substep_work(v, mass, clock.step as f64);
        }
        if let Some(most) = self.solver.settings.strain_limit {
            let start = std::time::Instant::now();
            let order = &self.limit_order;
            let pulled = limit::limit_strain(&self.model, order, &mut self.state, most, clock.step);
            self.strain_limited += pulled as u64;
            self.stage_times.lap(schedule::Stage::Finish.timed(), start);
        }
    }

    /// Runs the next frames with `substeps` per frame, `iterations` outer iterations and
    /// `contact_passes` collision passes (an accuracy target's budget; between frames only).
    pub fn set_budget(&mut self, substeps: u32, iterations: u32, contact_passes: u32) {
        let settings = &self.solver.settings;
        if substeps == self.drivers.clock.substeps
            && iterations == settings.iterations
            && contact_passes == settings.contact_passes
        {
            return;
        }
        // At a frame's end the clock is a whole number of frames.
        let clock = &mut self.drivers.clock;
        let frames = clock.elapsed / clock.substeps as u64;
        clock.elapsed = frames * substeps as u64;
        clock.substeps = substeps;
        clock.step = 1.0 / (clock.fps * substeps as f32);
        self.integration.set_step(clock.step);
        let mut settings = self.solver.settings.clone();
        settings.iterations = iterations;
        settings.contact_passes = contact_passes;
        self.solver = Solver::new(
            &self.model,
            settings,
            self.integration.verlet.map(|v| v.step),
        );
    }

    /// Each garment particle's nearby shell particles, per shell, as the last substep left them
    /// (empty before the first, or with one collision pass).
    pub fn nearby_lists(&self) -> &[crate::collide::shell::Nearby] {
        self.workspace.nearby_lists()
    }

    /// Takes lists another backend kept (the GPU's, for a checkpoint).
    pub fn set_nearby_lists(&mut self, lists: Vec<crate::collide::shell::Nearby>) {
        self.workspace.set_nearby_lists(lists);
    }

    /// Keeps each shell focused on the particles that can come near the garments
    /// ([`Drivers::focus_shells`]).
    fn focus_shells(&mut self, frame_start: bool) {
        let (g, reach) = (
            self.integration.gravity.length(),
            self.largest_contact_radius(),
        );
        (self.drivers).focus_shells(&self.state, g, reach, frame_start);
    }

    /// Moves the characters' shells to the end of the coming substep.
    fn advance_shells(&mut self) {
        let reach = self.largest_contact_radius();
        self.drivers.advance_shells_but(&[], reach);
    }

    /// The largest contact radius of any particle [m] (shell grids are built for it).
    pub fn largest_contact_radius(&self) -> f32 {
        self.model
            .contact_radius
            .iter()
            .copied()
            .fold(0.0, f32::max)
    }

    /// Frames per second.
    pub fn fps(&self) -> f32 {
        self.drivers.clock.fps
    }

    /// Substeps per frame.
    pub fn substeps(&self) -> u32 {
        self.drivers.clock.substeps
    }

    /// The force fields (None without `forces`).
    pub fn forces(&self) -> Option<&forces::Forces> {
        self.fields.fields.as_ref()
    }

    /// Substeps simulated since the bake's start (the clock).
    pub fn elapsed_substeps(&self) -> u64 {
        self.drivers.clock.elapsed
    }

    /// True when some collider follows keyframes.
    pub fn moving_colliders(&self) -> bool {
        self.drivers.moving_colliders()
    }

    /// What a backend that runs the next frame elsewhere drives and writes back
    /// ([`FrameParts`]).
    pub fn frame_parts(&mut self) -> FrameParts<'_> {
        FrameParts {
            contact_reach: self.largest_contact_radius(),
            drivers: &mut self.drivers,
            state: &mut self.state,
            residuals: self.residuals.as_mut(),
            force_work: &mut self.fields.work,
            stage_times: &mut self.stage_times,
            strain_limited: &mut self.strain_limited,
        }
    }

    /// Kinetic energy attachments, moving colliders and characters may have given the garments
    /// so far: all of their mass at the fastest speed any attached particle, collider or skin
    /// has been driven, plus the work of the force fields [J]. The stability rule counts it as released energy, as it does the
    /// potential energy: a cloth dragged by its attachments or hit by a moving body gains
    /// kinetic energy without falling.
    pub fn driven_energy(&self) -> f64 {
        let mass: f64 = self.model.mass.iter().map(|&m| m as f64).sum();
        0.5 * mass * (self.drivers.driven_speed as f64).powi(2) + self.fields.work
    }

    /// Potential energy that single-precision positions may have hidden so far [J]: each
    /// substep adds its displacement to a position, and a displacement below half a unit in the
    /// last place of the coordinate is lost to rounding (at 2 000 fps × 100 substeps a falling
    /// cloth moves 10⁻¹⁰ m per substep, far below the 6·10⁻⁸ m a coordinate near 1 m resolves),
    /// while the velocity still gains it. The stability rule counts this as released energy
    /// too, so a fine step is not called unstable for what the positions cannot show: the free
    /// mass falling half a unit in the last place of the largest coordinate on every substep.
    pub fn rounding_energy(&self) -> f64 {
        let free_mass: f64 = (0..self.model.particle_count())
            .filter(|&i| self.model.inv_mass[i] != 0.0)
            .map(|i| self.model.mass[i] as f64)
            .sum();
        let largest = self
            .state
            .positions
            .iter()
            .map(|p| p.truncate().abs().max_element())
            .fold(0.0f32, f32::max) as f64;
        let half_ulp = 0.5 * f32::EPSILON as f64 * largest.max(1.0);
        free_mass
            * self.integration.gravity.length() as f64
            * half_ulp
            * self.drivers.clock.elapsed as f64
    }

    /// Runs `count` substeps in one team region; `place_ahead`: where the next substep ends
    /// (fractional frame), when the last substep's `finish` places the shells for it.
    /// `predict_after`: the last substep's `finish` predicts the one after it too (the next
    /// region then starts without its prologue).
    /// `check_focus`: the last substep's `finish` checks whether the shells' focus holds for the
    /// next.
    fn run_substeps(
        &mut self,
        count: u32,
        place_ahead: Option<f32>,
        predict_after: bool,
        check_focus: bool,
    ) {
        let check_focus = check_focus && self.drivers.focus_checkable(self.state.positions.len());
        let terms = self.drivers.focus_terms(self.integration.gravity.length());
        self.drivers.focus.outran.store(false, Ordering::Relaxed);
        // Predicted by the last region's `finish` (never at a frame's start).
        let clock = self.drivers.clock;
        let predicted = self.workspace.predicted_at.take() == Some(clock.elapsed)
            && clock.elapsed % clock.substeps as u64 != 0;
        let contact_reach = self.largest_contact_radius();
        self.solver
            .prepare_for(&self.model, rayon::current_num_threads());
        let schedule = self.schedule();
        let threads = self.sharing.threads();
        self.drivers.clock.elapsed += count as u64;
        let placing_ns = AtomicU64::new(0);
        if place_ahead.is_some() {
            for s in &mut self.drivers.shells {
                s.prepare_ahead();
            }
        }
        let stages = self.workspace.stages(
            &mut self.state,
            &self.drivers,
            SubstepInputs {
                model: &self.model,
                verlet: self.integration.verlet.as_ref(),
                external: &self.fields.external,
                particle_collisions: self.particle_collisions.is_some(),
                passes: self.solver.settings.contact_passes,
                place_ahead,
                placing_ns: &placing_ns,
                contact_reach,
                focus_check: check_focus.then_some(terms),
            },
        );
        let region = Region {
            stages,
            solver: &self.solver,
            particles: self.particle_collisions.as_ref(),
            schedule: &schedule,
            count,
            predicted,
            predict_after,
        };
        let (stats, laps) = region.run(threads, self.residuals.as_mut());
        self.stage_times.add(&laps);
        // The leader placed the next substep's shells inside `finish` while the others took its
        // particles: the placement's share of that stage's wall time is its time over the
        // threads that shared the work, and it is the shells' (what `stages_ms` calls them).
        let placing = placing_ns.into_inner() as f64 * 1e-9 / stats.threads.max(1) as f64;
        let times = &mut self.stage_times.seconds;
        times[schedule::Stage::Finish.timed()] -= placing;
        times[schedule::timed("shells")] += placing;
        self.sharing.count(stats);
        let elapsed = self.drivers.clock.elapsed;
        if predict_after {
            self.workspace.predicted_at = Some(elapsed);
        }
        self.drivers.focus.checked_at = check_focus.then_some(elapsed);
    }

    /// The static model (read-only: the solver validated it once).
    /// The structural springs in the strain limit's sweep order (empty without a limit).
    pub fn limit_order(&self) -> &limit::LimitOrder {
        &self.limit_order
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Positions of the particles the simulation moves (storage order; pinned and attached
    /// particles, which follow their targets whatever is in the way, are left out): what
    /// penetration is measured on.
    pub fn free_positions(&self) -> Vec<Vec4> {
        self.state
            .positions
            .iter()
            .zip(&self.model.inv_mass)
            .filter(|(_, &w)| w != 0.0)
            .map(|(p, _)| *p)
            .collect()
    }

    /// Positions of the pinned and attached particles (storage order), which follow their
    /// targets: what [`Simulation::free_positions`] leaves out, measured apart because no budget
    /// moves them.
    pub fn held_positions(&self) -> Vec<Vec4> {
        self.state
            .positions
            .iter()
            .zip(&self.model.inv_mass)
            .filter(|(_, &w)| w == 0.0)
            .map(|(p, _)| *p)
            .collect()
    }

    /// Positions in export order.
    pub fn export_positions(&self) -> Vec<Vec3> {
        self.state.export_positions(&self.model)
    }

    /// Constraint error of the current positions.
    pub fn constraint_error(&self) -> metrics::ConstraintError {
        metrics::constraint_error(&self.model, &self.state.positions)
    }

    /// Energies of the current state.
    pub fn energy(&self) -> metrics::Energy {
        metrics::energy(&self.model, &self.state, self.integration.gravity)
    }

    /// The solver's settings.
    pub fn solver_settings(&self) -> &SolverSettings {
        &self.solver.settings
    }

    /// Per particle, the inertia a = m/h² and 1/(a + Σw) of the solver's rows (for the GPU).
    pub fn solver_rows(&self) -> (&[f32], &[f32]) {
        self.solver.rows()
    }

    /// Step h [s], velocity kept per step and g·h [m/s] (for the GPU).
    pub fn integration_constants(&self) -> (f32, f32, Vec4) {
        match &self.integration.verlet {
            Some(v) => (v.step, v.keep, v.gravity_step),
            None => (self.drivers.clock.step, 1.0, Vec4::ZERO),
        }
    }

    /// True when particles move under time integration.
    pub fn integrating(&self) -> bool {
        self.integration.verlet.is_some()
    }
}

/// Frames of more particle-iterations than this (about 0.2 s on a 2-core machine) can be
/// stopped between their substeps ([`Simulation::step_frame_or_stop`]).
pub const LONG_FRAME: f64 = 2e7;
/// Particle-iterations run between two looks at a stop request in a watched frame (about
/// 20 ms).
pub const WATCHED_PIECE: f64 = 2e6;

/// One team region: `count` substeps of `schedule` over `stages`.
struct Region<'a> {
    stages: stages::Stages<'a>,
    solver: &'a Solver,
    particles: Option<&'a ParticleCollisions>,
    schedule: &'a [schedule::Stage],
    count: u32,
    /// The first substep was predicted by the last region's `finish` (no prologue).
    predicted: bool,
    /// The last substep's `finish` predicts the one after it.
    predict_after: bool,
}

impl Region<'_> {
    /// Runs the region on `threads` threads, pushing the total squared error after every sweep
    /// to `residuals` when given; returns how the team went and the leader's stage times.
    fn run(
        &self,
        threads: usize,
        residuals: Option<&mut Vec<f64>>,
    ) -> (team::RegionStats, schedule::StageTimes) {
        let (stages, model, buffers) = (&self.stages, self.stages.model, &self.stages.b);
        let recording = residuals.is_some();
        let residuals = Mutex::new(residuals);
        let observe = |m: &Member| {
            if !recording {
                return;
            }
            // The sweeps handed over point to point (`solver::two`, `solver::seams`) end
            // without a barrier: every thread's last colour done before the leader reads.
            m.sync();
            if m.leads() {
                // SAFETY: between two syncs nobody writes x or Δ.
                let (x, d) = unsafe { (buffers.x.read_all(), buffers.delta.read_all()) };
                let q: Vec<Vec4> = x.iter().zip(d).map(|(x, d)| *x + *d).collect();
                let e = metrics::constraint_error(model, &q).total_squared_error;
                if let Some(r) = residuals.lock().expect("not poisoned").as_mut() {
                    r.push(e);
                }
            }
            m.sync();
        };
        let times = Mutex::new(schedule::StageTimes::default());
        let stats = team::run(threads, |m| {
            // The leader times the stages (each ends with a sync, so its time is the team's);
            // the others keep no clock.
            let mut clock = std::time::Instant::now();
            let mut laps = schedule::StageTimes::default();
            let mut lap = |stage: usize| {
                if m.leads() {
                    clock = laps.lap(stage, clock);
                }
            };
            // The prologue: predict the first substep; later predictions are fused into
            // `finish`.
            if !self.predicted {
                stages.predict(m);
                m.sync();
            }
            lap(schedule::timed("predict"));
            for k in 0..self.count {
                let mut first_pass = true;
                for &stage in self.schedule {
                    match stage {
                        // Placed before the region (`Drivers::place_attachments`), with the
                        // shells.
                        schedule::Stage::Attach => continue,
                        // Computed before the region (`Forces::accelerations`) into
                        // `external`, which the prologue's prediction adds.
                        schedule::Stage::Forces => continue,
                        // Every solver stage ends with a sync.
                        schedule::Stage::Solve { iterations } => {
                            match self.solver.in_two(m, model) {
                                Some(two) => two.iterate(m, model, buffers, &observe, iterations),
                                None => {
                                    self.solver.iterate(m, model, buffers, &observe, iterations)
                                }
                            }
                        }
                        schedule::Stage::ContactPass => {
                            stages.contact_pass(m, first_pass);
                            first_pass = false;
                            m.sync();
                        }
                        schedule::Stage::ParticleCollisions => stages.particle_collisions(
                            m,
                            self.particles.expect("scheduled with particle collisions"),
                        ),
                        // Each particle alone: tethers, collisions, commit, next prediction.
                        schedule::Stage::Finish => {
                            stages.finish(m, k + 1 < self.count || self.predict_after);
                            m.sync();
                        }
                    }
                    lap(stage.timed());
                }
            }
            if m.leads() {
                *times.lock().expect("not poisoned") = laps;
            }
        });
        (stats, times.into_inner().expect("not poisoned"))
    }
}

/// The strain limit's sweep order for `model`, when `settings` ask for a limit.
fn limit_order(model: &Model, settings: &SolverSettings) -> limit::LimitOrder {
    match settings.strain_limit {
        Some(_) => limit::LimitOrder::new(model),
        None => limit::LimitOrder::default(),
    }
}
