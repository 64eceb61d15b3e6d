//! Simulation: a static [`Model`], a changing [`State`] and a [`Solver`], advanced one frame at a
//! time. Each substep runs the stages in the order `lib.rs` lists them:
//! predict (integrate) → solve (constraints) → tethers → collide.
//! A whole frame runs as one [`team`] region: every thread runs the stage list on its share.

pub mod attach;
pub mod constraint;
pub mod forces;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod schedule;
pub mod snapshot;
pub mod solver;
mod stages;
pub mod state;
pub mod team;
pub mod tear;

use crate::collide::particles::{Grid, ParticleCollisions};
use crate::collide::{Collider, ShellCollider};
use crate::garment::Garment;
use crate::scene::{IntegratorKind, Scene, SolverSettings};
use glam::{Vec3, Vec4};
use integrate::Verlet;
pub use model::Model;
pub use solver::Solver;
use stages::{focus_holds_for, FocusCheck, Stages};
pub use state::State;
use std::sync::{Mutex, RwLock};
use team::{Member, Shared};

/// How much farther than their motion predicts the garments may go before the shells' focus is
/// made again [m].
const FOCUS_SLACK: f32 = 0.02;

/// A running simulation of one scene's garments.
pub struct Simulation {
    /// Private: the solver indexes it unchecked, so it must not change after validation.
    model: Model,
    pub state: State,
    pub colliders: Vec<Collider>,
    /// Characters' collision shells.
    pub shells: Vec<ShellCollider>,
    /// Substeps simulated so far (the characters' clock).
    elapsed_substeps: u64,
    solver: Solver,
    /// None without time integration (scene E: only the solver moves particles).
    verlet: Option<Verlet>,
    /// Inertial displacement of the current substep, storage order.
    target: Vec<Vec4>,
    /// Each spring's projection (the local step's result).
    projection: Vec<Vec4>,
    /// Second position buffer of the Jacobi-style solvers.
    scratch: Vec<Vec4>,
    /// Displacement of every particle over the current substep (the solver's unknown).
    delta: Vec<Vec4>,
    /// The cap on the current frame's kinetic energy while it settles
    /// ([`Simulation::settle_frame`]).
    settle: Option<EnergyCap>,
    /// Kinetic energy the last settled frame took out [J].
    settled: f64,
    pub substeps: u32,
    /// Length of one substep [s].
    pub step: f32,
    /// Velocity damping rate [1/s] (the integrator's constants follow the step).
    damping: f32,
    pub gravity: Vec3,
    /// When set, the total squared error after every sweep of the current frame.
    pub residuals: Option<Vec<f64>>,
    /// Particle–particle collisions (self and between garments), when the scene asks for them.
    pub particle_collisions: Option<ParticleCollisions>,
    /// Their hash grid, rebuilt every substep.
    grid: RwLock<Grid>,
    /// Each particle's push out of the others in the current substep.
    pushes: Vec<Vec4>,
    /// With several collision passes, each garment particle's nearby shell particles, per
    /// shell (shell-major), found at the end of the previous substep.
    nearby: Vec<crate::collide::shell::Nearby>,
    /// How many shell particles each of those lists holds: what the collision passes read first,
    /// so the particles near no shell (most of a garment) cost them one byte, not a list's 64
    /// (P's lists are 530 KB, more than a core's L2, read nine times a substep).
    listed: Vec<u8>,
    /// Per listed particle and shell, its distance at the substep's start from the nearest
    /// shell particle in its list (measured by the first collision pass, read by the others).
    listed_gap: Vec<f32>,
    /// The substep (count since the bake's start) whose prediction the last `finish` already
    /// made (within [`Simulation::step_frame`] only).
    predicted_at: Option<u64>,
    /// The substep count at which `outran` tells whether the focus holds (set by the last
    /// substep's `finish`, within [`Simulation::step_frame`] only).
    focus_checked_at: Option<u64>,
    outran: std::sync::atomic::AtomicBool,
    /// Each particle's clearance from the quiet colliders at the start of the substep (see
    /// [`Stages::contact_pass`]), kept between a substep's collision passes.
    clearance: Vec<f32>,
    /// Per particle, how far it may move in the substep before a collision pass has anything
    /// to do for it, and how many shells' lists it has ([`Stages::contact_pass`]; measured by
    /// the substep's first pass).
    pass_slack: Vec<(f32, u8)>,
    /// Whether later collision passes leave out the tests a particle's slack stands for (on by
    /// default; off, every pass tests every particle in full, to the same result).
    pub pass_slack_enabled: bool,
    /// Particles later collision passes left out by their slack so far.
    passes_left_out: std::sync::atomic::AtomicU64,
    /// Which colliders are quiet in the coming substep ([`Collider::is_quiet`]; kept between
    /// substeps, so none allocates).
    quiet: Vec<bool>,
    /// Particles following animated targets.
    pub attachments: attach::Attachments,
    /// Frames per second (the clock of characters and keyframes).
    fps: f32,
    /// Where the garment particles were when the shells' focus was made, and how far from there
    /// it lets them go [m].
    focus_origin: Vec<(Vec4, f32)>,
    /// Whether the CPU focuses shells at all (on by default; off shows what it saves).
    pub focus_enabled: bool,
    /// Fastest any attached particle or keyframed collider has moved so far [m/s].
    driven_speed: f32,
    /// Keyframed colliders: (index in `colliders`, motion, shape at rest).
    collider_motion: Vec<(usize, attach::Track, crate::collide::Shape)>,
    /// The garments as built (and as torn so far), and each one's tearing strain.
    garments: Vec<Garment>,
    tear_strain: Vec<Option<f32>>,
    /// Springs broken so far.
    pub torn_springs: usize,
    /// Wall time of each stage so far ([`schedule::TIMED`]; the bake adds its own).
    pub stage_times: schedule::StageTimes,
    /// The current frame's team regions: their barriers and the waits that slept at them.
    team_stats: team::RegionStats,
    /// Who runs the team's regions, frame by frame ([`team::Sharing`]).
    pub sharing: team::Sharing,
    /// Wind and attractors, when the scene has force fields.
    forces: Option<forces::Forces>,
    /// Their acceleration of each particle in the current substep (empty without).
    external: Vec<Vec4>,
    /// Work the force fields have done on the garments so far, the positive part of each
    /// substep's [J] (energy supplied, for the stability rule).
    force_work: f64,
}

impl Simulation {
    /// Builds the garments, model, solver and colliders of a (validated) scene.
    ///
    /// # Panics
    /// When a garment cannot be built (a mesh garment's file unreadable, an attachment that
    /// selects nothing): the bake builds through [`crate::bake::simulation`], which returns
    /// those as errors.
    pub fn new(scene: &Scene) -> Simulation {
        let garments = crate::garment::build_all(scene, "scene").unwrap_or_else(|e| panic!("{e}"));
        Simulation::from_garments(scene, &garments, scene.solver.clone())
    }

    /// Builds a simulation of `garments` with the timing, forces and colliders of `scene`.
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
        let grid = RwLock::new(
            particle_collisions
                .as_ref()
                .map(|p| p.grid())
                .unwrap_or_default(),
        );
        let pushes = vec![
            Vec4::ZERO;
            if particle_collisions.is_some() {
                model.particle_count()
            } else {
                0
            }
        ];
        let attachments = attach::Attachments::new(&scene.garments, garments, |g, p| {
            model.storage_of[model.garments[g].export.start + p as usize]
        });
        let forces = forces::Forces::new(&scene.forces, &model);
        Simulation {
            forces,
            external: Vec::new(),
            force_work: 0.0,
            garments: garments.to_vec(),
            tear_strain: scene.garments.iter().map(|g| g.tear_strain).collect(),
            torn_springs: 0,
            attachments,
            fps: scene.fps,
            driven_speed: 0.0,
            focus_origin: Vec::new(),
            focus_enabled: true,
            particle_collisions,
            grid,
            pushes,
            nearby: Vec::new(),
            listed: Vec::new(),
            listed_gap: Vec::new(),
            predicted_at: None,
            focus_checked_at: None,
            outran: std::sync::atomic::AtomicBool::new(false),
            clearance: Vec::new(),
            pass_slack: Vec::new(),
            pass_slack_enabled: true,
            passes_left_out: std::sync::atomic::AtomicU64::new(0),
            quiet: Vec::new(),
            target: vec![Vec4::ZERO; model.particle_count()],
            projection: vec![Vec4::ZERO; model.springs.len()],
            scratch: vec![Vec4::ZERO; model.particle_count()],
            delta: vec![Vec4::ZERO; model.particle_count()],
            settle: None,
            settled: 0.0,
            colliders: scene
                .colliders
                .iter()
                .map(|spec| Collider {
                    swept: scene.swept_collisions,
                    ..Collider::from_spec(spec)
                })
                .collect(),
            collider_motion: scene
                .colliders
                .iter()
                .enumerate()
                .filter(|(_, spec)| !spec.keyframes.is_empty())
                .map(|(i, spec)| {
                    let shape = Collider::from_spec(spec).shape;
                    (
                        i,
                        attach::Track::new(&spec.keyframes, shape.centre()),
                        shape,
                    )
                })
                .collect(),
            shells: Vec::new(),
            elapsed_substeps: 0,
            verlet: integrating.then(|| Verlet::new(gravity, scene.damping, step)),
            damping: scene.damping,
            substeps: scene.substeps_per_frame(),
            step,
            gravity,
            residuals: scene.output.residuals.then(Vec::new),
            stage_times: schedule::StageTimes::default(),
            team_stats: team::RegionStats::default(),
            sharing: team::Sharing::default(),
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
                attachments: !self.attachments.list.is_empty(),
                particle_collisions: self.particle_collisions.is_some(),
                forces: self.forces.is_some(),
            },
        )
    }

    /// Breaks the springs of tearable garments stretched past their strain, and rebuilds the
    /// model and solver around what is left (particle storage order stays the same).
    pub fn tear(&mut self) -> usize {
        let positions = self.export_positions();
        let mut broken = 0;
        for (g, threshold) in self.tear_strain.clone().into_iter().enumerate() {
            let Some(threshold) = threshold else { continue };
            let range = self.model.garments[g].export.clone();
            broken += tear::tear(&mut self.garments[g], &positions[range], threshold);
        }
        if broken > 0 {
            self.torn_springs += broken;
            self.rebuild_model();
        }
        broken
    }

    /// The model, solver and faces built again from the garments (after tearing changed them;
    /// particle storage order stays the same).
    fn rebuild_model(&mut self) {
        self.model = Model::new(&self.garments);
        self.solver = Solver::new(
            &self.model,
            self.solver.settings.clone(),
            self.verlet.map(|v| v.step),
        );
        self.projection = vec![Vec4::ZERO; self.model.springs.len()];
        if let Some(f) = &mut self.forces {
            f.set_faces(&self.model);
        }
    }

    /// True when some garment can tear.
    pub fn tears(&self) -> bool {
        self.tear_strain.iter().any(Option::is_some)
    }

    /// Particles the later collision passes left out by their slack so far (see
    /// [`Simulation::pass_slack_enabled`]).
    pub fn passes_left_out(&self) -> u64 {
        self.passes_left_out
            .load(std::sync::atomic::Ordering::Relaxed)
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
        self.team_stats = team::RegionStats {
            threads: self.sharing.threads(),
            ..team::RegionStats::default()
        };
        let start = std::time::Instant::now();
        let whole = self.step_frame_watched(stop);
        self.sharing
            .after_frame(self.team_stats, start.elapsed().as_secs_f64());
        whole
    }

    /// Particle-iterations of one frame: particles × substeps × outer × inner iterations.
    fn frame_work(&self) -> f64 {
        let s = &self.solver.settings;
        self.model.particle_count() as f64
            * self.substeps as f64
            * s.iterations as f64
            * s.inner_iterations.max(1) as f64
    }

    /// The frame's substeps, asking `stop` (when given) between pieces of them; false when it
    /// said stop before the last.
    fn step_frame_watched(&mut self, stop: Option<&dyn Fn() -> bool>) -> bool {
        if let Some(r) = &mut self.residuals {
            r.clear();
        }
        if self.shells.is_empty()
            && self.attachments.list.is_empty()
            && self.collider_motion.is_empty()
            && self.forces.is_none()
            && self.settle.is_none()
        {
            let Some(stop) = stop else {
                self.run_substeps(self.substeps, None, false, false);
                return true;
            };
            // In pieces: each piece's last `finish` predicts the next piece's first substep,
            // as one region would.
            let per_substep = self.frame_work() / self.substeps as f64;
            let piece = ((WATCHED_PIECE / per_substep) as u32).clamp(1, self.substeps);
            let mut done = 0;
            while done < self.substeps {
                let count = piece.min(self.substeps - done);
                done += count;
                self.run_substeps(count, None, done < self.substeps, false);
                if done < self.substeps && stop() {
                    self.predicted_at = None;
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
            // A settling frame caps the kinetic energy after each substep, so no `finish`
            // predicts the next substep from velocities the cap is about to scale.
            let settling = self.settle.is_some();
            for k in 0..self.substeps {
                self.substep_in_frame(!settling);
                self.cap_kinetic_energy();
                if k + 1 < self.substeps && stop.is_some_and(|stop| stop()) {
                    self.settle = None;
                    self.predicted_at = None;
                    self.focus_checked_at = None;
                    return false;
                }
            }
            self.settle = None;
            self.predicted_at = None;
            self.focus_checked_at = None;
            true
        }
    }

    /// Caps the coming frame's kinetic energy, after each of its substeps, at what the frame
    /// starts with plus what gravity and the force fields have given since and what the
    /// fastest driven motion could carry (½ M v²); velocities above it are scaled down alike.
    ///
    /// For a frame after an accuracy target raised the budget: a cheaper budget leaves springs
    /// stretched that the larger one pulls back (a flag at 10 × 2 held 26 J in springs 8 %
    /// long where 40 × 10 holds 0.1), and that energy, which no force supplied, came out as
    /// motion: the flag thrashed at 15 m/s and the stability rule stopped the bake. Capped, the
    /// springs still shorten, and the energy they free is taken out.
    pub fn settle_frame(&mut self) {
        let (kinetic, gravitational) = self.kinetic_and_gravitational_energy();
        self.settle = Some(EnergyCap {
            kinetic,
            gravitational,
            work: self.force_work,
            mass: self.model.mass.iter().map(|&m| m as f64).sum(),
        });
        self.settled = 0.0;
    }

    /// Kinetic energy the last settled frame took out [J] (0 when none was settled).
    pub fn settled_energy(&self) -> f64 {
        self.settled
    }

    /// The kinetic and gravitational energy of the particles the simulation moves [J].
    fn kinetic_and_gravitational_energy(&self) -> (f64, f64) {
        let g = self.gravity.as_dvec3();
        let free = (self.state.positions.iter().zip(&self.state.velocities))
            .zip(self.model.mass.iter().zip(&self.model.inv_mass))
            .filter(|(_, (_, &w))| w != 0.0);
        free.fold((0.0, 0.0), |(k, u), ((x, v), (&m, _))| {
            let m = m as f64;
            (
                k + 0.5 * m * v.truncate().as_dvec3().length_squared(),
                u - m * g.dot(x.truncate().as_dvec3()),
            )
        })
    }

    /// Scales the moving particles' velocities down to the settling frame's cap, if above it.
    fn cap_kinetic_energy(&mut self) {
        let Some(cap) = self.settle else {
            return;
        };
        let (kinetic, gravitational) = self.kinetic_and_gravitational_energy();
        let allowed = cap.kinetic
            + (cap.gravitational - gravitational).max(0.0)
            + (self.force_work - cap.work).max(0.0)
            + 0.5 * cap.mass * (self.driven_speed as f64).powi(2);
        if kinetic <= allowed || kinetic <= 0.0 {
            return;
        }
        let scale = (allowed / kinetic).sqrt() as f32;
        for (v, &w) in self.state.velocities.iter_mut().zip(&self.model.inv_mass) {
            if w != 0.0 {
                *v *= scale;
            }
        }
        self.settled += kinetic - allowed;
    }

    /// Advances one substep.
    pub fn substep(&mut self) {
        self.predicted_at = None;
        self.focus_checked_at = None;
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
        self.place_attachments();
        let pushed = self
            .stage_times
            .lap(schedule::Stage::Attach.timed(), placed);
        if let Some(f) = &mut self.forces {
            let t = self.elapsed_substeps as f32 / (self.substeps as f32 * self.fps);
            let (x, v) = (&self.state.positions, &self.state.velocities);
            f.accelerations(&self.model, x, v, t, &mut self.external);
            self.stage_times.lap(schedule::timed("forces"), pushed);
        }
        // The next substep's shells are placed during this one's `finish`, within the frame
        // (a frame's first substep focuses them afresh).
        let next = self.elapsed_substeps + 1;
        let per_frame = self.substeps as u64;
        let within = next % per_frame != 0;
        let ahead = within.then(|| (next + 1) as f32 / self.substeps as f32);
        // Without force fields or attachments, which change the next prediction between
        // substeps, `finish` predicts the next substep of the frame too.
        let predict = frame && within && self.forces.is_none() && self.attachments.list.is_empty();
        self.run_substeps(1, ahead, predict, frame && within);
        if self.forces.is_some() {
            // The substep moved each particle by v·h: the fields' work is Σ m a·v h.
            let h = self.step as f64;
            let work: f64 = (self.external.iter().zip(&self.state.velocities))
                .zip(&self.model.mass)
                .map(|((a, v), &m)| m as f64 * a.dot(*v) as f64 * h)
                .sum();
            self.force_work += work.max(0.0);
        }
    }

    /// Runs the next frames with `substeps` per frame, `iterations` outer iterations and
    /// `contact_passes` collision passes (an accuracy target's budget; between frames only).
    pub fn set_budget(&mut self, substeps: u32, iterations: u32, contact_passes: u32) {
        let settings = &self.solver.settings;
        if substeps == self.substeps
            && iterations == settings.iterations
            && contact_passes == settings.contact_passes
        {
            return;
        }
        // At a frame's end the clock is a whole number of frames.
        let frames = self.elapsed_substeps / self.substeps as u64;
        self.elapsed_substeps = frames * substeps as u64;
        self.substeps = substeps;
        self.step = 1.0 / (self.fps * substeps as f32);
        if self.verlet.is_some() {
            self.verlet = Some(Verlet::new(self.gravity, self.damping, self.step));
        }
        let mut settings = self.solver.settings.clone();
        settings.iterations = iterations;
        settings.contact_passes = contact_passes;
        self.solver = Solver::new(&self.model, settings, self.verlet.map(|v| v.step));
    }

    /// Each garment particle's nearby shell particles, per shell, as the last substep left them
    /// (empty before the first, or with one collision pass).
    pub fn nearby_lists(&self) -> &[crate::collide::shell::Nearby] {
        &self.nearby
    }

    /// Takes lists another backend kept (the GPU's, for a checkpoint).
    pub fn set_nearby_lists(&mut self, lists: Vec<crate::collide::shell::Nearby>) {
        self.nearby = lists;
        self.listed = self
            .nearby
            .iter()
            .map(crate::collide::shell::listed)
            .collect();
    }

    /// Keeps each shell focused on the particles that can come near the garments (see
    /// `collide::shell`'s `Focus`): at a frame's start (`frame_start`), or when a garment
    /// particle is about to go farther from where it was when the focus was made than the focus
    /// allows it. The focus allows each particle its own speed and gravity over a frame, twice,
    /// plus [`FOCUS_SLACK`]; before each substep, each particle must be within that of its
    /// place then, less twice its own motion in a substep and twice the shells' fastest.
    fn focus_shells(&mut self, frame_start: bool) {
        if !self.focus_enabled || !self.shells.iter().any(|s| s.can_focus()) {
            return;
        }
        let g = self.gravity.length();
        if !frame_start && self.focus_origin.len() == self.state.positions.len() {
            // Checked by the last substep's `finish` as it committed each particle, when it could.
            let holds = if self.focus_checked_at == Some(self.elapsed_substeps) {
                !self.outran.load(std::sync::atomic::Ordering::Relaxed)
            } else {
                let terms = self.focus_terms();
                let (positions, velocities) = (&self.state.positions, &self.state.velocities);
                (positions.iter().zip(velocities))
                    .zip(&self.focus_origin)
                    .all(|((p, v), o)| focus_holds_for(*p, *v, *o, terms))
            };
            if holds {
                return;
            }
        }
        let frame = 1.0 / self.fps;
        let allowance = |v: &Vec4| 2.0 * (v.length() * frame + g * frame * frame) + FOCUS_SLACK;
        self.focus_origin.clear();
        self.focus_origin.extend(
            (self.state.positions.iter().zip(&self.state.velocities))
                .map(|(p, v)| (*p, allowance(v))),
        );
        let shell_radius = self.shells.iter().map(|s| s.radius).fold(0.0, f32::max);
        let reach = self.largest_contact_radius() + shell_radius;
        let reaches: Vec<(Vec3, f32)> = (self.focus_origin.iter())
            .map(|(p, allowed)| (p.truncate(), allowed + 2.0 * reach))
            .collect();
        let near = crate::collide::shell::NearGarments::new(&reaches, 4.0 * reach);
        let from = self.elapsed_substeps as f32 / self.substeps as f32;
        let per_substep = 1.0 / self.substeps as f32;
        for s in &mut self.shells {
            s.focus(from, &near, per_substep);
        }
    }

    /// What [`focus_holds_for`] allows for besides each particle's own motion: the substep,
    /// gravity and the shells' fastest motion in the current substep.
    fn focus_terms(&self) -> (f32, f32, f32) {
        let carried = (self.shells.iter())
            .map(|s| s.fastest_motion())
            .fold(0.0, f32::max);
        (self.step, self.gravity.length(), carried)
    }

    /// Moves the characters' shells to the end of the coming substep.
    fn advance_shells(&mut self) {
        self.advance_shells_but(&[]);
    }

    /// [`Self::advance_shells`] for the shells not marked in `skip`.
    fn advance_shells_but(&mut self, skip: &[bool]) {
        if self.shells.is_empty() {
            return;
        }
        let per_frame = self.substeps as f32;
        let from = self.elapsed_substeps as f32 / per_frame;
        let to = (self.elapsed_substeps + 1) as f32 / per_frame;
        let reach = self.largest_contact_radius();
        for (i, s) in self.shells.iter_mut().enumerate() {
            if skip.get(i) == Some(&true) {
                continue;
            }
            s.advance(from, to, reach);
            self.driven_speed = self.driven_speed.max(s.fastest_motion() / self.step);
        }
    }

    /// Moves the shells marked in `whole` over the coming frame in one go (their positions at
    /// its end serve the metrics; their motion over it, spread over its substeps, the driven
    /// speed): for shells a GPU places itself substep by substep.
    fn advance_shells_over_frame(&mut self, whole: &[bool]) {
        let per_frame = self.substeps as f32;
        let from = self.elapsed_substeps as f32 / per_frame;
        let to = (self.elapsed_substeps + self.substeps as u64) as f32 / per_frame;
        let reach = self.largest_contact_radius();
        for (s, _) in self.shells.iter_mut().zip(whole).filter(|(_, &w)| w) {
            s.advance(from, to, reach);
            let per_substep = s.fastest_motion() / per_frame;
            self.driven_speed = self.driven_speed.max(per_substep / self.step);
        }
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
        self.fps
    }

    /// The force fields (None without `forces`).
    pub fn forces(&self) -> Option<&forces::Forces> {
        self.forces.as_ref()
    }

    /// Adds work the force fields did on the garments over a frame another backend ran [J]
    /// (negative work is not counted, as on the CPU).
    pub fn add_force_work(&mut self, work: f64) {
        self.force_work += work.max(0.0);
    }

    /// Substeps simulated since the bake's start (the clock).
    pub fn elapsed_substeps(&self) -> u64 {
        self.elapsed_substeps
    }

    /// True when some collider follows keyframes.
    pub fn moving_colliders(&self) -> bool {
        !self.collider_motion.is_empty()
    }

    /// Puts every attached particle where its target is at the end of the coming substep, with
    /// the velocity that got it there, and every keyframed collider in its pose then.
    fn place_attachments(&mut self) {
        let t = (self.elapsed_substeps + 1) as f32 / (self.substeps as f32 * self.fps);
        self.pose_colliders(t);
        for a in &self.attachments.list {
            let i = a.particle as usize;
            let target = self.attachments.position(a, t, self.fps).extend(0.0);
            self.state.velocities[i] = (target - self.state.positions[i]) / self.step;
            self.driven_speed = self.driven_speed.max(self.state.velocities[i].length());
            self.state.positions[i] = target;
        }
    }

    /// Where the attached particles go (storage index, target) and where the colliders are, at
    /// the end of each substep of the next frame, substep by substep; advances the clock by a
    /// frame as if it ran, leaving the colliders in their last pose: for a backend that runs
    /// the frame elsewhere (the GPU) and copies the state back. `static_shells`: include the
    /// shells that never move too, with the first substep (the GPU needs them once). The shells marked in
    /// `placed_elsewhere` (the GPU places them from their skins) have no snapshots: they are
    /// moved over the whole frame at once.
    pub fn drive_frame(&mut self, static_shells: bool, placed_elsewhere: &[bool]) -> DrivenFrame {
        // The GPU reads every shell particle.
        for s in &mut self.shells {
            s.unfocus();
        }
        let mut frame = DrivenFrame::default();
        let start = std::time::Instant::now();
        self.advance_shells_over_frame(placed_elsewhere);
        self.stage_times.lap(schedule::timed("shells"), start);
        let mut last: Vec<Vec3> = self
            .attachments
            .list
            .iter()
            .map(|a| self.state.positions[a.particle as usize].truncate())
            .collect();
        for substep in 0..self.substeps {
            let start = std::time::Instant::now();
            self.advance_shells_but(placed_elsewhere);
            frame.shells.push(
                (self.shells.iter().enumerate())
                    .map(|(i, s)| {
                        let elsewhere = placed_elsewhere.get(i) == Some(&true);
                        // A shell that never moves: once, with the first substep.
                        let once = static_shells && substep == 0;
                        let wanted = !elsewhere && (once || !s.is_static());
                        wanted.then(|| s.gpu_snapshot())
                    })
                    .collect(),
            );
            self.stage_times.lap(schedule::timed("shells"), start);
            let t = (self.elapsed_substeps + 1) as f32 / (self.substeps as f32 * self.fps);
            frame.attachments.push(
                self.attachments
                    .list
                    .iter()
                    .zip(&mut last)
                    .map(|(a, last)| {
                        let target = self.attachments.position(a, t, self.fps);
                        let speed = target.distance(*last) / self.step;
                        self.driven_speed = self.driven_speed.max(speed);
                        *last = target;
                        (a.particle, target)
                    })
                    .collect(),
            );
            self.pose_colliders(t);
            frame.colliders.push(self.colliders.clone());
            self.elapsed_substeps += 1;
        }
        frame
    }

    /// Every keyframed collider in its pose at time `t` [s], with how far it moved to get there.
    fn pose_colliders(&mut self, t: f32) {
        for (i, track, rest) in &self.collider_motion {
            let (rotation, translation) = track.pose(t);
            let shape = rest.moved(track.pivot, rotation, translation);
            let c = &mut self.colliders[*i];
            c.moved = shape.centre() - c.shape.centre();
            c.shape = shape;
            self.driven_speed = self.driven_speed.max(c.moved.length() / self.step);
        }
    }

    /// Kinetic energy attachments, moving colliders and characters may have given the garments
    /// so far: all of their mass at the fastest speed any attached particle, collider or skin
    /// has been driven, plus the work of the force fields [J]. The stability rule counts it as released energy, as it does the
    /// potential energy: a cloth dragged by its attachments or hit by a moving body gains
    /// kinetic energy without falling.
    pub fn driven_energy(&self) -> f64 {
        let mass: f64 = self.model.mass.iter().map(|&m| m as f64).sum();
        0.5 * mass * (self.driven_speed as f64).powi(2) + self.force_work
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
        free_mass * self.gravity.length() as f64 * half_ulp * self.elapsed_substeps as f64
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
        let n = self.state.positions.len();
        let check_focus = check_focus
            && self.focus_enabled
            && self.focus_origin.len() == n
            && self.shells.iter().any(|s| s.focused().is_some());
        let terms = self.focus_terms();
        self.outran
            .store(false, std::sync::atomic::Ordering::Relaxed);
        // Predicted by the last region's `finish` (never at a frame's start).
        let predicted = self.predicted_at.take() == Some(self.elapsed_substeps)
            && self.elapsed_substeps % self.substeps as u64 != 0;
        let contact_reach = self.largest_contact_radius();
        self.solver
            .prepare_for(&self.model, rayon::current_num_threads());
        let schedule = self.schedule();
        let buffers = solver::Buffers {
            x: Shared::new(&mut self.state.positions),
            delta: Shared::new(&mut self.delta),
            target: Shared::new(&mut self.target),
            projection: Shared::new(&mut self.projection),
            scratch: Shared::new(&mut self.scratch),
        };
        let velocities = Shared::new(&mut self.state.velocities);
        let pushes = Shared::new(&mut self.pushes);
        let passes = self.solver.settings.contact_passes;
        let nearby_len = if passes > 1 {
            self.shells.len() * self.model.particle_count()
        } else {
            0
        };
        if self.nearby.len() != nearby_len {
            self.set_nearby_lists(vec![[u32::MAX; crate::collide::shell::NEARBY]; nearby_len]);
        }
        let nearby = Shared::new(&mut self.nearby);
        let listed = Shared::new(&mut self.listed);
        self.listed_gap.resize(nearby_len, f32::INFINITY);
        let listed_gap = Shared::new(&mut self.listed_gap);
        let clearance_len = if passes > 1 {
            self.model.particle_count()
        } else {
            0
        };
        self.clearance.resize(clearance_len, f32::NEG_INFINITY);
        let clearance = Shared::new(&mut self.clearance);
        self.pass_slack
            .resize(clearance_len, (f32::NEG_INFINITY, 0));
        let pass_slack = Shared::new(&mut self.pass_slack);
        self.quiet.clear();
        self.quiet
            .extend(self.colliders.iter().map(Collider::is_quiet));
        let model = &self.model;
        let recording = self.residuals.is_some();
        let residuals = Mutex::new(self.residuals.as_mut());
        let observe = |m: &Member| {
            if !recording {
                return;
            }
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
        self.elapsed_substeps += count as u64;
        let placing_ns = std::sync::atomic::AtomicU64::new(0);
        let stages = Stages {
            model,
            verlet: self.verlet.as_ref(),
            colliders: &self.colliders,
            shells: &self.shells,
            b: buffers,
            velocities,
            pushes: self.particle_collisions.is_some().then_some(pushes),
            nearby,
            listed,
            listed_gap,
            clearance,
            pass_slack,
            slack_skips: self.pass_slack_enabled,
            left_out: &self.passes_left_out,
            quiet: &self.quiet,
            all_quiet: self.quiet.iter().all(|&q| q),
            external: &self.external,
            place_ahead,
            placing_ns: &placing_ns,
            contact_reach,
            focus_check: check_focus.then_some(FocusCheck {
                origins: &self.focus_origin,
                terms,
                outran: &self.outran,
            }),
        };
        let solver = &self.solver;
        let particles = self.particle_collisions.as_ref();
        let grid = &self.grid;
        let times = Mutex::new(schedule::StageTimes::default());
        let region = team::run(self.sharing.threads(), |m| {
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
            if !predicted {
                stages.predict(m);
                m.sync();
            }
            lap(schedule::timed("predict"));
            for k in 0..count {
                let mut first_pass = true;
                for &stage in &schedule {
                    match stage {
                        // Placed before the region (`place_attachments`), with the shells.
                        schedule::Stage::Attach => continue,
                        // Computed before the region (`Forces::accelerations`) into
                        // `external`, which the prologue's prediction adds.
                        schedule::Stage::Forces => continue,
                        // Every solver stage ends with a sync.
                        schedule::Stage::Solve { iterations } => {
                            solver.iterate(m, model, &buffers, &observe, iterations)
                        }
                        schedule::Stage::ContactPass => {
                            stages.contact_pass(m, first_pass);
                            first_pass = false;
                            m.sync();
                        }
                        schedule::Stage::ParticleCollisions => stages.particle_collisions(
                            m,
                            particles.expect("scheduled with particle collisions"),
                            grid,
                        ),
                        // Each particle alone: tethers, collisions, commit, next prediction.
                        schedule::Stage::Finish => {
                            stages.finish(m, k + 1 < count || predict_after);
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
        self.stage_times
            .add(&times.into_inner().expect("not poisoned"));
        // The leader placed the next substep's shells inside `finish` while the others took its
        // particles: the placement's share of that stage's wall time is its time over the
        // threads that shared the work, and it is the shells' (what `stages_ms` calls them).
        let placing = placing_ns.into_inner() as f64 * 1e-9 / region.threads.max(1) as f64;
        let times = &mut self.stage_times.seconds;
        times[schedule::Stage::Finish.timed()] -= placing;
        times[schedule::timed("shells")] += placing;
        self.team_stats.barriers += region.barriers;
        self.team_stats.slept += region.slept;
        if predict_after {
            self.predicted_at = Some(self.elapsed_substeps);
        }
        self.focus_checked_at = check_focus.then_some(self.elapsed_substeps);
    }

    /// The static model (read-only: the solver validated it once).
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
        metrics::energy(&self.model, &self.state, self.gravity)
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
        match &self.verlet {
            Some(v) => (v.step, v.keep, v.gravity_step),
            None => (self.step, 1.0, Vec4::ZERO),
        }
    }

    /// True when particles move under time integration.
    pub fn integrating(&self) -> bool {
        self.verlet.is_some()
    }
}

/// Frames of more particle-iterations than this (about 0.2 s on a 2-core machine) can be
/// stopped between their substeps ([`Simulation::step_frame_or_stop`]).
pub const LONG_FRAME: f64 = 2e7;
/// Particle-iterations run between two looks at a stop request in a watched frame (about
/// 20 ms).
pub const WATCHED_PIECE: f64 = 2e6;

/// What a settling frame's kinetic energy is capped by ([`Simulation::settle_frame`]): the
/// energies it started with and the force fields' work until then [J], and the garments' mass
/// [kg] (what driven motion could carry is ½ M v² of the fastest).
#[derive(Clone, Copy, Debug)]
struct EnergyCap {
    kinetic: f64,
    gravitational: f64,
    work: f64,
    mass: f64,
}

/// What drives one frame, substep by substep (see [`Simulation::drive_frame`]).
#[derive(Clone, Debug, Default)]
pub struct DrivenFrame {
    /// Per substep: each attached particle (storage index) and its target [m].
    pub attachments: Vec<Vec<(u32, Vec3)>>,
    /// Per substep: every collider in its pose at the end of that substep.
    pub colliders: Vec<Vec<Collider>>,
    /// Per substep, per character shell: [`ShellCollider::gpu_snapshot`] (None for a shell
    /// that never moves, unless asked for, then with the first substep only: the GPU keeps it
    /// from its first upload; and None for a shell the GPU places itself).
    pub shells: Vec<Vec<Option<crate::collide::shell::ShellSnapshot>>>,
}
