//! Time integration: position Verlet with damping (thesis algorithm 2). The inertial prediction
//! s = x + f·(x − x_prev) + g·h², with f = exp(−damping·h), is the target the solver pulls every
//! free particle towards; pinned particles stay where they are.

use super::model::Model;
use super::team::{Member, Shared};
use glam::Vec4;

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

    /// Predicts this thread's share of particles: `target` and `x` get the prediction s,
    /// `x_prev` the old x.
    pub fn predict(
        &self,
        m: &Member,
        model: &Model,
        x: Shared<Vec4>,
        x_prev: Shared<Vec4>,
        target: Shared<Vec4>,
    ) {
        let (g, keep) = (self.gravity_step, self.keep);
        for i in m.particles(&model.colour_ranges) {
            // SAFETY: each index is read and written by its own thread only in this stage.
            unsafe {
                let old = x.get(i);
                let s = if model.inv_mass[i] == 0.0 {
                    old
                } else {
                    old + (old - x_prev.get(i)) * keep + g
                };
                x_prev.set(i, old);
                x.set(i, s);
                target.set(i, s);
            }
        }
    }
}
