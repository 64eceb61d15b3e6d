//! Time integration: Verlet with damping (thesis algorithm 2) in velocity form. Each step predicts
//! the inertial displacement t = h·v*, with v* = f·v + g·h and f = exp(−damping·h), which the
//! solver pulls every free particle's displacement Δ towards; after the solve (and tethers and
//! collisions) the particle moves to x + Δ with velocity Δ/h. In exact arithmetic this is position
//! Verlet, x' = x + f·(x − x_prev) + g·h² + correction; keeping v and Δ instead of x_prev avoids
//! single precision rounding the velocity to whole ulps (see `sim::state`). Pinned particles stay.

use glam::Vec4;

/// Per-step constants of the integrator.
#[derive(Clone, Copy, Debug)]
pub struct Verlet {
    /// g·h [m/s].
    pub gravity_step: Vec4,
    /// Velocity kept per step, exp(−damping·h).
    pub keep: f32,
    /// Step h [s].
    pub step: f32,
    /// 1/h [1/s].
    pub inv_step: f32,
}

impl Verlet {
    /// Constants for steps of `h` seconds.
    pub fn new(gravity: glam::Vec3, damping: f32, h: f32) -> Verlet {
        Verlet {
            gravity_step: (gravity * h).extend(0.0),
            keep: (-damping * h).exp(),
            step: h,
            inv_step: 1.0 / h,
        }
    }

    /// The inertial displacement t = h·(f·v + g·h) of a free particle moving at `v`.
    #[inline(always)]
    pub fn inertial_displacement(&self, v: Vec4) -> Vec4 {
        (v * self.keep + self.gravity_step) * self.step
    }

    /// The velocity after a step that moved a particle by `delta`: Δ/h.
    #[inline(always)]
    pub fn velocity(&self, delta: Vec4) -> Vec4 {
        delta * self.inv_step
    }
}

/// How the simulation integrates time: gravity, damping and, with time integration, the
/// integrator's constants for the current step.
#[derive(Clone, Copy, Debug)]
pub(super) struct Integration {
    /// None without time integration (scene E: only the solver moves particles).
    pub(super) verlet: Option<Verlet>,
    pub(super) gravity: glam::Vec3,
    /// Velocity damping rate [1/s] (the integrator's constants follow the step).
    pub(super) damping: f32,
}

impl Integration {
    /// The constants for steps of `h` seconds (when integrating).
    pub(super) fn set_step(&mut self, h: f32) {
        if self.verlet.is_some() {
            self.verlet = Some(Verlet::new(self.gravity, self.damping, h));
        }
    }
}
