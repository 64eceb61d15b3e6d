//! The changing part of a simulation: particle positions and velocities.
//!
//! Verlet could keep velocity implicitly as x − x_prev, but in single precision that difference
//! is a whole number of ulps: at 1 m and 100 steps per frame, gravity adds about 4.5 ulps per step
//! and rounding turned it into 5, a 10 % stronger gravity that made a pendulum gain energy. So the
//! state keeps the velocity explicitly (the velocity form of the same Verlet scheme).
//!
//! Each array is one `glam::Vec4` per particle, the same 16 bytes as `[f32; 4]` (bytemuck `Pod`),
//! x, y, z and w always 0, in the model's colour-sorted storage order, so the GPU can upload the
//! arrays unchanged.

use super::model::Model;
use glam::{Vec3, Vec4};

/// Positions and velocities of every particle, storage order.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Positions [m], w = 0.
    pub positions: Vec<Vec4>,
    /// Velocities [m/s], w = 0.
    pub velocities: Vec<Vec4>,
}

impl State {
    /// A state at rest at `export_positions` (export order, as the garments were built).
    pub fn at_rest(model: &Model, export_positions: &[Vec3]) -> State {
        let mut positions = vec![Vec4::ZERO; model.particle_count()];
        for (e, p) in export_positions.iter().enumerate() {
            positions[model.storage_of[e] as usize] = p.extend(0.0);
        }
        State {
            velocities: vec![Vec4::ZERO; positions.len()],
            positions,
        }
    }

    /// Positions in export order (garments one after another, each in grid order).
    pub fn export_positions(&self, model: &Model) -> Vec<Vec3> {
        model
            .storage_of
            .iter()
            .map(|&s| self.positions[s as usize].truncate())
            .collect()
    }

    /// True when every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.positions.iter().all(|p| p.is_finite())
    }
}

const _: () = assert!(std::mem::size_of::<Vec4>() == 16);
