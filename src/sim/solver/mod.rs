//! Constraint solvers: Projective Dynamics (local/global, thesis algorithm 4) solved by sequential
//! Gauss-Seidel, Jacobi or multi-colour Gauss-Seidel, each with over-relaxation ω; and Position
//! Based Dynamics with Jacobi averaging (thesis algorithm 3) as the classic reference.
//!
//! Projective Dynamics minimises, over the positions q of one step of length h,
//!   Σ_i m_i/(2h²) |q_i − s_i|² + Σ_springs w/2 |q_a − q_b − d_ab|²,
//! with s the inertial prediction and d_ab the spring's projection onto its rest length. Each
//! *outer* iteration refreshes every d (the local step, [`refresh`]); each *inner* iteration sweeps
//! the linear global system once. The right-hand side a_i s_i + Σ w d is folded per particle in the
//! refresh, so a sweep reads only neighbour positions and weights.

mod gauss_seidel;
mod jacobi;
mod pbd;
mod rbgs;

use super::constraint::spring_projection;
use super::model::Model;
use crate::scene::{SolverKind, SolverSettings};
use glam::Vec4;
use rayon::prelude::*;

/// Particles per parallel task: large enough that scheduling costs stay below the work.
pub(crate) const PARALLEL_CHUNK: usize = 1024;

/// A solver with the per-particle system of one step size, built once per bake.
pub struct Solver {
    pub settings: SolverSettings,
    /// a_i = m_i / h² (0 without time integration or for pinned particles) [kg/s²].
    inertia: Vec<f32>,
    /// 1 / (a_i + Σ_k w_k), or 0 for particles that never move.
    diag_inv: Vec<f32>,
    /// a_i s_i + Σ_k w_k d_k, refreshed every outer iteration.
    rhs: Vec<Vec4>,
    /// Second buffer of the Jacobi-style solvers.
    scratch: Vec<Vec4>,
}

impl Solver {
    /// Prepares the system for steps of `step` seconds (`None`: no inertia, scene E).
    pub fn new(model: &Model, settings: SolverSettings, step: Option<f32>) -> Solver {
        // Parallel Gauss-Seidel writes one colour while reading the others: that is only a
        // data-race-free Gauss-Seidel sweep if no spring joins two particles of one colour.
        if let Err(s) = model.check_colouring() {
            panic!("invalid colouring: spring {s:?} joins two particles of one colour");
        }
        let n = model.particle_count();
        let inertia: Vec<f32> = (0..n)
            .map(|i| match step {
                Some(h) if model.inv_mass[i] > 0.0 => model.mass[i] / (h * h),
                _ => 0.0,
            })
            .collect();
        let diag_inv = (0..n)
            .map(|i| {
                let d: f32 = inertia[i] + model.slots(i).iter().map(|s| s.weight).sum::<f32>();
                if model.inv_mass[i] > 0.0 && d > 0.0 {
                    1.0 / d
                } else {
                    0.0
                }
            })
            .collect();
        Solver {
            settings,
            inertia,
            diag_inv,
            rhs: vec![Vec4::ZERO; n],
            scratch: vec![Vec4::ZERO; n],
        }
    }

    /// Runs all iterations on `q` (storage order), pulling towards the inertial `target`.
    /// `observe` is called after every sweep (inner iteration, or PBD iteration) with the iterate.
    pub fn solve(
        &mut self,
        model: &Model,
        target: &[Vec4],
        q: &mut [Vec4],
        mut observe: Option<&mut dyn FnMut(&[Vec4])>,
    ) {
        let s = self.settings.clone();
        for _ in 0..s.iterations {
            if s.kind == SolverKind::Pbd {
                pbd::iterate(model, q, &mut self.scratch, s.omega);
                if let Some(f) = observe.as_deref_mut() {
                    f(q);
                }
                continue;
            }
            refresh(model, &self.inertia, target, q, &mut self.rhs);
            for _ in 0..s.inner_iterations {
                self.sweep(model, q);
                if let Some(f) = observe.as_deref_mut() {
                    f(q);
                }
            }
        }
    }

    /// One inner iteration of the global step with the current right-hand side.
    pub fn sweep(&mut self, model: &Model, q: &mut [Vec4]) {
        let omega = self.settings.omega;
        match self.settings.kind {
            SolverKind::Gs => gauss_seidel::sweep(model, &self.rhs, &self.diag_inv, q, omega),
            SolverKind::Rbgs => rbgs::sweep(model, &self.rhs, &self.diag_inv, q, omega),
            SolverKind::Jacobi => jacobi::sweep(
                model,
                &self.rhs,
                &self.diag_inv,
                q,
                &mut self.scratch,
                omega,
            ),
            SolverKind::Pbd => pbd::iterate(model, q, &mut self.scratch, omega),
        }
    }

    /// Refreshes the right-hand side from `q` without sweeping (for benchmarks of one part).
    pub fn refresh(&mut self, model: &Model, target: &[Vec4], q: &[Vec4]) {
        refresh(model, &self.inertia, target, q, &mut self.rhs);
    }
}

/// The local step: rhs_i = a_i s_i + Σ_k w_k d_k with d_k = spring_projection(q_i, q_k, L_k).
/// Each spring is projected from both ends, which keeps the pass a race-free gather.
fn refresh(model: &Model, inertia: &[f32], target: &[Vec4], q: &[Vec4], rhs: &mut [Vec4]) {
    rhs.par_iter_mut()
        .with_min_len(PARALLEL_CHUNK)
        .enumerate()
        .for_each(|(i, r)| {
            let qi = q[i];
            let mut acc = target[i] * inertia[i];
            for s in model.slots(i) {
                acc += spring_projection(qi, q[s.neighbour as usize], s.rest) * s.weight;
            }
            *r = acc;
        });
}

/// One Gauss-Seidel row: the new position of particle `i` given how to read neighbours.
#[inline(always)]
pub(crate) fn row(
    model: &Model,
    i: usize,
    rhs: Vec4,
    diag_inv: f32,
    read: impl Fn(usize) -> Vec4,
) -> Vec4 {
    super::constraint::spring_row_solve(
        rhs,
        model
            .slots(i)
            .iter()
            .map(|s| (s.weight, read(s.neighbour as usize))),
        diag_inv,
    )
}
