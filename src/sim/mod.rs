//! Simulation: a static [`Model`], a changing [`State`] and a [`Solver`], advanced one frame at a
//! time. Each substep runs the stages in the order `lib.rs` lists them:
//! predict (integrate) → solve (constraints) → tethers → collide.
//! A whole frame runs as one [`team`] region: every thread runs the stage list on its share.

pub mod constraint;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod solver;
pub mod state;
pub mod team;

use crate::collide::{self, Collider};
use crate::garment::Garment;
use crate::scene::{IntegratorKind, Scene, SolverSettings};
use glam::{Vec3, Vec4};
use integrate::Verlet;
pub use model::Model;
pub use solver::Solver;
pub use state::State;
use std::sync::Mutex;
use team::{Member, Shared};

/// A running simulation of one scene's garments.
pub struct Simulation {
    pub model: Model,
    pub state: State,
    pub colliders: Vec<Collider>,
    solver: Solver,
    /// None without time integration (scene E: only the solver moves particles).
    verlet: Option<Verlet>,
    /// Inertial prediction of the current substep, storage order.
    target: Vec<Vec4>,
    /// Each spring's projection (the local step's result).
    projection: Vec<Vec4>,
    /// Second position buffer of the Jacobi-style solvers.
    scratch: Vec<Vec4>,
    pub substeps: u32,
    /// Length of one substep [s].
    pub step: f32,
    pub gravity: Vec3,
    /// When set, the total squared error after every sweep of the current frame.
    pub residuals: Option<Vec<f64>>,
}

impl Simulation {
    /// Builds the garments, model, solver and colliders of a (validated) scene.
    pub fn new(scene: &Scene) -> Simulation {
        let garments: Vec<Garment> = scene
            .garments
            .iter()
            .enumerate()
            .map(|(i, spec)| Garment::build(scene.garment_name(i), spec))
            .collect();
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
        Simulation {
            target: state.positions.clone(),
            projection: vec![Vec4::ZERO; model.springs.len()],
            scratch: vec![Vec4::ZERO; model.particle_count()],
            colliders: scene.colliders.iter().map(Collider::from_spec).collect(),
            verlet: integrating.then(|| Verlet::new(gravity, scene.damping, step)),
            substeps: scene.substeps_per_frame(),
            step,
            gravity,
            residuals: scene.output.residuals.then(Vec::new),
            model,
            state,
            solver,
        }
    }

    /// Advances one frame (all substeps).
    pub fn step_frame(&mut self) {
        if let Some(r) = &mut self.residuals {
            r.clear();
        }
        self.run_substeps(self.substeps);
    }

    /// Advances one substep.
    pub fn substep(&mut self) {
        self.run_substeps(1);
    }

    /// Runs `count` substeps in one team region.
    fn run_substeps(&mut self, count: u32) {
        let buffers = solver::Buffers {
            q: Shared::new(&mut self.state.positions),
            target: Shared::new(&mut self.target),
            projection: Shared::new(&mut self.projection),
            scratch: Shared::new(&mut self.scratch),
        };
        let previous = Shared::new(&mut self.state.previous);
        let model = &self.model;
        let recording = self.residuals.is_some();
        let residuals = Mutex::new(self.residuals.as_mut());
        let observe = |m: &Member| {
            if !recording {
                return;
            }
            if m.leads() {
                // SAFETY: between two syncs nobody writes q.
                let q = unsafe { buffers.q.read_all() };
                let e = metrics::constraint_error(model, q).total_squared_error;
                if let Some(r) = residuals.lock().expect("not poisoned").as_mut() {
                    r.push(e);
                }
            }
            m.sync();
        };
        let (solver, verlet, colliders) = (&self.solver, &self.verlet, &self.colliders);
        team::run(|m| {
            for _ in 0..count {
                // 1. Predict: inertia, damping and gravity; the solve starts from the prediction.
                predict(m, model, verlet.as_ref(), &buffers, previous);
                m.sync();
                // 2. Solve the constraints (every solver stage ends with a sync).
                solver.solve(m, model, &buffers, &observe);
                // 3. Long-range attachments, 4. collisions: each particle on its own.
                apply_tethers(m, model, &buffers);
                collide::resolve_all(m, colliders, model, buffers.q, previous);
                m.sync();
            }
        });
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
        metrics::energy(&self.model, &self.state, self.gravity, self.step)
    }

    /// True when particles move under time integration.
    pub fn integrating(&self) -> bool {
        self.verlet.is_some()
    }
}

/// The integrator's stage; without integration positions stay and become the target.
fn predict(
    m: &Member,
    model: &Model,
    verlet: Option<&Verlet>,
    b: &solver::Buffers,
    previous: Shared<Vec4>,
) {
    match verlet {
        Some(v) => v.predict(m, model, b.q, previous, b.target),
        None => {
            for i in m.particles(&model.colour_ranges) {
                // SAFETY: each index is read and written by its own thread only in this stage.
                unsafe {
                    let x = b.q.get(i);
                    previous.set(i, x);
                    b.target.set(i, x);
                }
            }
        }
    }
}

/// Projects this thread's tethered particles to within their rest distance of their pins. The
/// pins' positions are read from the prediction (where a pinned particle is held this step), which
/// nobody writes in this stage, so particles are independent.
fn apply_tethers(m: &Member, model: &Model, b: &solver::Buffers) {
    if model.tethers.is_empty() {
        return;
    }
    for i in m.particles(&model.colour_ranges) {
        let range = model.tether_start[i] as usize..model.tether_start[i + 1] as usize;
        if range.is_empty() {
            continue;
        }
        // SAFETY: q[i] belongs to this thread in this stage; target is not written.
        unsafe {
            let mut qi = b.q.get(i);
            for &(_, pin, rest) in &model.tethers[range] {
                qi = constraint::tether_projection(qi, b.target.get(pin as usize), rest);
            }
            b.q.set(i, qi);
        }
    }
}
