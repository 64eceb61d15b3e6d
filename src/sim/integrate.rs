//! Time integration: position Verlet with damping (thesis algorithm 2). The inertial prediction
//! s = x + f·(x − x_prev) + g·h², with f = exp(−damping·h), is the target the solver pulls every
//! free particle towards; pinned particles stay where they are.

use super::model::Model;
use glam::Vec4;
use rayon::prelude::*;

/// Per-step constants of the integrator.
#[derive(Clone, Copy, Debug)]
pub struct Verlet {
    /// g·h² [m].
    pub gravity_step: Vec4,
    /// Velocity kept per step, exp(−damping·h).
    pub keep: f32,
}

impl Verlet {
    /// Constants for steps of `h` seconds.
    pub fn new(gravity: glam::Vec3, damping: f32, h: f32) -> Verlet {
        Verlet {
            gravity_step: (gravity * h * h).extend(0.0),
            keep: (-damping * h).exp(),
        }
    }

    /// Predicts every particle: `target` and `x` get the prediction s, `x_prev` the old x.
    pub fn predict(&self, model: &Model, x: &mut [Vec4], x_prev: &mut [Vec4], target: &mut [Vec4]) {
        let (g, keep) = (self.gravity_step, self.keep);
        (x, x_prev, target)
            .into_par_iter()
            .with_min_len(super::solver::PARALLEL_CHUNK)
            .zip(model.inv_mass.par_iter())
            .for_each(|((x, x_prev, s), &inv_mass)| {
                let old = *x;
                *s = if inv_mass == 0.0 {
                    old
                } else {
                    old + (old - *x_prev) * keep + g
                };
                *x_prev = old;
                *x = *s;
            });
    }
}
