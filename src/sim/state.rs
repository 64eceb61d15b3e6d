//! The changing part of a simulation: particle positions now and one step ago (Verlet keeps
//! velocity implicitly as their difference).
//!
//! Positions are one `glam::Vec4` per particle, the same 16 bytes as `[f32; 4]` (bytemuck `Pod`),
//! x, y, z in metres and w always 0, in the model's colour-sorted storage order, so the GPU can
//! upload the arrays unchanged.

use super::model::Model;
use glam::{Vec3, Vec4};

/// Positions of every particle, now and one step ago, storage order.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Positions [m], w = 0.
    pub positions: Vec<Vec4>,
    /// Positions one step ago [m], w = 0.
    pub previous: Vec<Vec4>,
}

impl State {
    /// A state at rest at `export_positions` (export order, as the garments were built).
    pub fn at_rest(model: &Model, export_positions: &[Vec3]) -> State {
        let mut positions = vec![Vec4::ZERO; model.particle_count()];
        for (e, p) in export_positions.iter().enumerate() {
            positions[model.storage_of[e] as usize] = p.extend(0.0);
        }
        State {
            previous: positions.clone(),
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
