//! Settling: a frame whose kinetic energy is capped after each substep, for the frame after an
//! accuracy target raised the budget ([`super::Simulation::settle_frame`]).
//!
//! A cheaper budget leaves springs stretched that the larger one pulls back (a flag at 10 × 2
//! held 26 J in springs 8 % long where 40 × 10 holds 0.1), and that energy, which no force
//! supplied, came out as motion: the flag thrashed at 15 m/s and the stability rule stopped the
//! bake. Capped, the springs still shorten, and the energy they free is taken out.

use super::{Model, State};
use glam::Vec3;

/// The cap of the frame being settled, if one is, and what the last settled frame took out.
#[derive(Default)]
pub(super) struct Settling {
    cap: Option<EnergyCap>,
    /// Kinetic energy the last settled frame took out [J].
    pub(super) settled: f64,
}

/// What a settling frame's kinetic energy is capped by: the energies it started with and the
/// force fields' work until then [J], and the garments' mass [kg] (what driven motion could
/// carry is ½ M v² of the fastest).
#[derive(Clone, Copy, Debug)]
struct EnergyCap {
    kinetic: f64,
    gravitational: f64,
    work: f64,
    mass: f64,
}

impl Settling {
    /// Caps the coming frame at the energies of `state` now and the force fields' `work` so far.
    pub(super) fn begin(&mut self, model: &Model, state: &State, gravity: Vec3, work: f64) {
        let (kinetic, gravitational) = kinetic_and_gravitational_energy(model, state, gravity);
        self.cap = Some(EnergyCap {
            kinetic,
            gravitational,
            work,
            mass: model.mass.iter().map(|&m| m as f64).sum(),
        });
        self.settled = 0.0;
    }

    /// True while a frame is being settled.
    pub(super) fn is_on(&self) -> bool {
        self.cap.is_some()
    }

    /// Ends the frame being settled (it ran, stopped, or the state was restored).
    pub(super) fn end(&mut self) {
        self.cap = None;
    }

    /// Scales the moving particles' velocities down to the cap, if above it: what the frame
    /// started with plus what gravity and the force fields (`work` so far) have given since and
    /// what the fastest driven motion (`driven_speed` [m/s]) could carry.
    pub(super) fn cap(
        &mut self,
        model: &Model,
        state: &mut State,
        gravity: Vec3,
        work: f64,
        driven_speed: f32,
    ) {
        let Some(cap) = self.cap else {
            return;
        };
        let (kinetic, gravitational) = kinetic_and_gravitational_energy(model, state, gravity);
        let allowed = cap.kinetic
            + (cap.gravitational - gravitational).max(0.0)
            + (work - cap.work).max(0.0)
            + 0.5 * cap.mass * (driven_speed as f64).powi(2);
        if kinetic <= allowed || kinetic <= 0.0 {
            return;
        }
        let scale = (allowed / kinetic).sqrt() as f32;
        for (v, &w) in state.velocities.iter_mut().zip(&model.inv_mass) {
            if w != 0.0 {
                *v *= scale;
            }
        }
        self.settled += kinetic - allowed;
    }
}

/// The kinetic and gravitational energy of the particles the simulation moves [J].
fn kinetic_and_gravitational_energy(model: &Model, state: &State, gravity: Vec3) -> (f64, f64) {
    let g = gravity.as_dvec3();
    let free = (state.positions.iter().zip(&state.velocities))
        .zip(model.mass.iter().zip(&model.inv_mass))
        .filter(|(_, (_, &w))| w != 0.0);
    free.fold((0.0, 0.0), |(k, u), ((x, v), (&m, _))| {
        let m = m as f64;
        (
            k + 0.5 * m * v.truncate().as_dvec3().length_squared(),
            u - m * g.dot(x.truncate().as_dvec3()),
        )
    })
}
