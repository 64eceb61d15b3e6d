//! Simulation: a static [`Model`], a changing [`State`] and a [`Solver`], advanced one frame at a
//! time. Each substep runs the stages in the order `lib.rs` lists them:
//! predict (integrate) → solve (constraints) → collide → commit.

pub mod constraint;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod solver;
pub mod state;

use crate::collide::{self, Collider};
use crate::garment::Garment;
use crate::scene::{IntegratorKind, Scene, SolverSettings};
use glam::{Vec3, Vec4};
use integrate::Verlet;
pub use model::Model;
use rayon::prelude::*;
pub use solver::Solver;
pub use state::State;

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
        for _ in 0..self.substeps {
            self.substep();
        }
    }

    /// One substep: predict → solve → collide → commit.
    pub fn substep(&mut self) {
        let State {
            positions,
            previous,
        } = &mut self.state;
        // 1. Predict: inertia, damping and gravity; the solve starts from the prediction.
        match &self.verlet {
            Some(v) => v.predict(&self.model, positions, previous, &mut self.target),
            None => {
                previous.copy_from_slice(positions);
                self.target.copy_from_slice(positions);
            }
        }
        // 2. Solve the constraints.
        let model = &self.model;
        match &mut self.residuals {
            Some(r) => {
                let mut observe =
                    |q: &[Vec4]| r.push(metrics::constraint_error(model, q).total_squared_error);
                self.solver
                    .solve(model, &self.target, positions, Some(&mut observe));
            }
            None => self.solver.solve(model, &self.target, positions, None),
        }
        // 3. Long-range attachments to the pins.
        apply_tethers(model, &self.target, positions);
        // 4. Collide.
        collide::resolve_all(&self.colliders, model, positions, previous);
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

    /// The solver, for benchmarks that time its parts.
    pub fn solver_mut(&mut self) -> (&Model, &mut Solver, &mut State, &[Vec4]) {
        (&self.model, &mut self.solver, &mut self.state, &self.target)
    }
}

/// Projects every tethered particle to within its rest distance of its pin. `anchors` holds the
/// pins' positions for this step (the prediction, which for a pinned particle is where it is held),
/// so particles are independent and the pass runs in parallel.
fn apply_tethers(model: &Model, anchors: &[Vec4], q: &mut [Vec4]) {
    if model.tethers.is_empty() {
        return;
    }
    q.par_iter_mut()
        .with_min_len(solver::PARALLEL_CHUNK)
        .enumerate()
        .for_each(|(i, qi)| {
            let range = model.tether_start[i] as usize..model.tether_start[i + 1] as usize;
            for &(_, pin, rest) in &model.tethers[range] {
                *qi = constraint::tether_projection(*qi, anchors[pin as usize], rest);
            }
        });
}
