//! The workspace of the CPU backend's substeps: the solver's scratch buffers, the particle
//! collisions' grid and pushes, and what a substep's collision passes keep for the next
//! (nearby shell lists, gaps, clearances, slack). It owns them so no substep allocates, and
//! hands them out, with the drivers and the model, as the [`Stages`] a team region runs.

use super::drivers::Drivers;
use super::integrate::Verlet;
use super::stages::{FocusCheck, Movers, Stages};
use super::state::State;
use super::team::Shared;
use super::{solver, Model};
use crate::collide::particles::{Grid, List, ListState, ParticleCollisions, PATCH_MOVERS};
use crate::collide::shell::{listed, Nearby, NEARBY};
use crate::collide::Collider;
use glam::Vec4;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::RwLock;

/// Buffers and pass caches of the CPU substeps.
pub(super) struct Workspace {
    /// Inertial displacement of the current substep, storage order.
    target: Vec<Vec4>,
    /// Each spring's projection (the local step's result).
    projection: Vec<Vec4>,
    /// Second position buffer of the Jacobi-style solvers.
    scratch: Vec<Vec4>,
    /// Displacement of every particle over the current substep (the solver's unknown).
    delta: Vec<Vec4>,
    /// Each particle's push out of the others in the current substep (particle collisions).
    pushes: Vec<Vec4>,
    /// Their hash grid, as the neighbour lists were last made in it.
    grid: RwLock<Grid>,
    /// Each particle's neighbour list ([`crate::collide::particles`]), and its position when
    /// the lists were made.
    lists: Vec<List>,
    anchors: Vec<Vec4>,
    /// The pairs within a list's reach a remake found, each once, that the lists are made from
    /// (every thread adds those it found).
    pairs: RwLock<Vec<(u32, u32)>>,
    /// The slots of the lists' grid, 0..particles: the order a remake shares out.
    slots: Vec<u32>,
    /// The particles that moved too far for the lists (the movers): a flag per particle, their
    /// count (the lists are stale when it is not zero), the particles they touch, and their list ([`crate::collide::particles::Patch`]).
    moving: Vec<u8>,
    movers: AtomicU32,
    touched: Vec<AtomicBool>,
    mover_list: RwLock<Vec<u32>>,
    /// How the substeps have been finding the pairs.
    list_state: std::sync::Mutex<ListState>,
    /// Whether particle collisions keep neighbour lists (on by default; off, every substep
    /// finds its pairs in a grid directly, to the same result).
    pub(super) particle_lists_enabled: bool,
    /// Substeps that found their pairs in lists made by an earlier one so far.
    lists_reused: AtomicU64,
    /// With several collision passes, each garment particle's nearby shell particles, per
    /// shell (shell-major), found at the end of the previous substep.
    nearby: Vec<Nearby>,
    /// How many shell particles each of those lists holds: what the collision passes read first,
    /// so the particles near no shell (most of a garment) cost them one byte, not a list's 64
    /// (P's lists are 530 KB, more than a core's L2, read nine times a substep).
    listed: Vec<u8>,
    /// Per listed particle and shell, its distance at the substep's start from the nearest
    /// shell particle in its list (measured by the first collision pass, read by the others).
    listed_gap: Vec<f32>,
    /// Each particle's clearance from the quiet colliders at the start of the substep (see
    /// [`Stages::contact_pass`]), kept between a substep's collision passes.
    clearance: Vec<f32>,
    /// Per particle, how far it may move in the substep before a collision pass has anything
    /// to do for it, and how many shells' lists it has ([`Stages::contact_pass`]; measured by
    /// the substep's first pass).
    pass_slack: Vec<(f32, u8)>,
    /// Whether later collision passes leave out the tests a particle's slack stands for (on by
    /// default; off, every pass tests every particle in full, to the same result).
    pub(super) pass_slack_enabled: bool,
    /// Particles later collision passes left out by their slack so far.
    passes_left_out: AtomicU64,
    /// Which colliders are quiet in the coming substep ([`Collider::is_quiet`]; kept between
    /// substeps, so none allocates).
    quiet: Vec<bool>,
    /// The substep (count since the bake's start) whose prediction the last `finish` already
    /// made (within [`super::Simulation::step_frame`] only).
    pub(super) predicted_at: Option<u64>,
}

/// What a team region's stages take besides the workspace, the state and the drivers.
pub(super) struct SubstepInputs<'a> {
    pub(super) model: &'a Model,
    pub(super) verlet: Option<&'a Verlet>,
    /// Each particle's acceleration by the force fields (empty without).
    pub(super) external: &'a [Vec4],
    pub(super) particle_collisions: bool,
    /// Collision passes per substep.
    pub(super) passes: u32,
    /// See [`Stages::place_ahead`].
    pub(super) place_ahead: Option<f32>,
    pub(super) placing_ns: &'a AtomicU64,
    /// The largest contact radius [m].
    pub(super) contact_reach: f32,
    /// Whether `finish` checks the shells' focus, and its terms.
    pub(super) focus_check: Option<(f32, f32, f32)>,
}

impl Workspace {
    /// Buffers for `model`'s particles and springs (pushes and a grid with `particles`).
    pub(super) fn new(model: &Model, particles: Option<&ParticleCollisions>) -> Workspace {
        let n = model.particle_count();
        Workspace {
            target: vec![Vec4::ZERO; n],
            projection: vec![Vec4::ZERO; model.springs.len()],
            scratch: vec![Vec4::ZERO; n],
            delta: vec![Vec4::ZERO; n],
            pushes: vec![Vec4::ZERO; if particles.is_some() { n } else { 0 }],
            grid: RwLock::new(particles.map(|p| p.grid()).unwrap_or_default()),
            lists: vec![List::EMPTY; if particles.is_some() { n } else { 0 }],
            anchors: vec![Vec4::INFINITY; if particles.is_some() { n } else { 0 }],
            pairs: RwLock::new(Vec::with_capacity(if particles.is_some() { n } else { 0 })),
            slots: (0..if particles.is_some() { n as u32 } else { 0 }).collect(),
            moving: vec![0; if particles.is_some() { n } else { 0 }],
            movers: AtomicU32::new(0),
            touched: (0..if particles.is_some() { n } else { 0 })
                .map(|_| AtomicBool::new(false))
                .collect(),
            mover_list: RwLock::new(Vec::with_capacity(PATCH_MOVERS as usize)),
            list_state: Default::default(),
            particle_lists_enabled: true,
            lists_reused: AtomicU64::new(0),
            nearby: Vec::new(),
            listed: Vec::new(),
            listed_gap: Vec::new(),
            clearance: Vec::new(),
            pass_slack: Vec::new(),
            pass_slack_enabled: true,
            passes_left_out: AtomicU64::new(0),
            quiet: Vec::new(),
            predicted_at: None,
        }
    }

    /// The spring buffers sized for `model` again (after tearing removed springs).
    pub(super) fn fit_springs(&mut self, model: &Model) {
        self.projection = vec![Vec4::ZERO; model.springs.len()];
    }

    /// Substeps whose particle collisions found their pairs in lists an earlier one made.
    pub(super) fn lists_reused(&self) -> u64 {
        self.lists_reused.load(Ordering::Relaxed)
    }

    /// Particles the later collision passes left out by their slack so far.
    pub(super) fn passes_left_out(&self) -> u64 {
        self.passes_left_out.load(Ordering::Relaxed)
    }

    /// Each garment particle's nearby shell particles, per shell, as the last substep left them.
    pub(super) fn nearby_lists(&self) -> &[Nearby] {
        &self.nearby
    }

    /// Takes lists another backend (or a checkpoint) kept.
    pub(super) fn set_nearby_lists(&mut self, lists: Vec<Nearby>) {
        self.nearby = lists;
        self.listed = self.nearby.iter().map(listed).collect();
    }

    /// The stages of a team region over `state`, `drivers` and `with`, the pass caches sized
    /// for them (lists only with several collision passes).
    pub(super) fn stages<'a>(
        &'a mut self,
        state: &mut State,
        drivers: &'a Drivers,
        with: SubstepInputs<'a>,
    ) -> Stages<'a> {
        let model = with.model;
        let n = model.particle_count();
        let several = with.passes > 1;
        let nearby_len = if several { drivers.shells.len() * n } else { 0 };
        if self.nearby.len() != nearby_len {
            self.set_nearby_lists(vec![[u32::MAX; NEARBY]; nearby_len]);
        }
        self.listed_gap.resize(nearby_len, f32::INFINITY);
        let clearance_len = if several { n } else { 0 };
        self.clearance.resize(clearance_len, f32::NEG_INFINITY);
        self.pass_slack
            .resize(clearance_len, (f32::NEG_INFINITY, 0));
        self.quiet.clear();
        self.quiet
            .extend(drivers.colliders.iter().map(Collider::is_quiet));
        let b = solver::Buffers {
            x: Shared::new(&mut state.positions),
            delta: Shared::new(&mut self.delta),
            target: Shared::new(&mut self.target),
            projection: Shared::new(&mut self.projection),
            scratch: Shared::new(&mut self.scratch),
        };
        Stages {
            model,
            verlet: with.verlet,
            colliders: &drivers.colliders,
            shells: &drivers.shells,
            b,
            velocities: Shared::new(&mut state.velocities),
            pushes: with
                .particle_collisions
                .then(|| Shared::new(&mut self.pushes)),
            grid: &self.grid,
            lists: Shared::new(&mut self.lists),
            anchors: Shared::new(&mut self.anchors),
            pairs: &self.pairs,
            slots: &self.slots,
            list_state: &self.list_state,
            particle_lists: self.particle_lists_enabled,
            lists_reused: &self.lists_reused,
            movers: Movers {
                moving: Shared::new(&mut self.moving),
                count: &self.movers,
                touched: &self.touched,
                list: &self.mover_list,
            },
            nearby: Shared::new(&mut self.nearby),
            listed: Shared::new(&mut self.listed),
            listed_gap: Shared::new(&mut self.listed_gap),
            clearance: Shared::new(&mut self.clearance),
            pass_slack: Shared::new(&mut self.pass_slack),
            slack_skips: self.pass_slack_enabled,
            left_out: &self.passes_left_out,
            all_quiet: self.quiet.iter().all(|&q| q),
            quiet: &self.quiet,
            external: with.external,
            place_ahead: with.place_ahead,
            placing_ns: with.placing_ns,
            contact_reach: with.contact_reach,
            focus_check: with.focus_check.map(|terms| FocusCheck {
                origins: &drivers.focus.origin,
                terms,
                outran: &drivers.focus.outran,
            }),
        }
    }
}
