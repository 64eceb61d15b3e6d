//! Particle–particle collisions: self-collision of a garment and garment–garment contact (CPU
//! here; `shaders/particles.wgsl` runs the same pushes on the GPU).
//!
//! Every substep, after the solver, each particle is pushed out of every other particle closer
//! than one diameter at the predicted positions q = x + Δ: a Jacobi pass, each particle moving by
//! the mean of its pushes (each its share of one overlap by inverse mass, so pinned particles
//! stay), all corrections computed from the same q and summed in ascending particle order, so
//! the result does not depend on the thread count or on when the neighbours were found. A pair
//! is pushed apart along its separation at the substep's start (x), not its separation in q, so
//! a particle carried through a layer in the solve goes back to its own side instead of on
//! through. Pairs of one garment that are lattice neighbours (one step apart on every axis at
//! most) are skipped: springs hold them, and at rest they already touch. Particles two steps
//! apart are two diameters apart at rest, so they collide only where the cloth folds onto
//! itself, which keeps a tight fold from closing through itself.
//!
//! Finding the pairs (CPU): a **neighbour list** per particle, the particles other than its
//! lattice neighbours within a diameter and a margin ([`LIST_MARGIN`]) of it. The lists are made
//! from a uniform hash grid whose cells are that reach wide, laid out in rows (a counting sort:
//! `grid.rs`), in which each particle finds its pairs with the particles of the 13 cells after
//! its own and the later ones of its own cell, so each pair is found once, and the pairs then
//! fill both particles' lists. The lists stay valid until some particle has moved
//! [`REBUILD_AT`] of the margin from where they were made (no pair can then have closed from
//! beyond a list's reach to within a diameter), and are made again then, unless few particles
//! have (the movers): then the lists are kept and the movers' pairs found apart ([`patch`]), to
//! the same pairs. On cloth resting on a body most substeps reuse them, and most lists are
//! empty (a flat sheet's particles two steps apart are two diameters apart). A list longer than
//! [`LIST_CAPACITY`] is walked in the grid instead. Without lists (cloth moving too fast for
//! them to last) the pairs are found directly in a grid of cells two diameters wide, whose 2 ×
//! 2 × 2 cells on the sides of a particle's nearest cell corner hold every particle within a
//! diameter of it, as the GPU does every substep (`particles.wgsl`).
//!
//! Here: the collisions' static data and the push; the grid and its walks in `grid.rs`; the
//! lists and the choice between keeping, patching, remaking and going without them in
//! `lists.rs`; the movers' search in `patch.rs`; unit tests against a brute force over every
//! pair in `tests.rs`.

mod grid;
mod lists;
mod patch;
#[cfg(test)]
mod tests;

pub use grid::Grid;
pub use lists::{
    lists_from_pairs, lists_from_pairs_from, Finding, List, ListState, DIRECT_RUN, LIST_CAPACITY,
    LIST_MARGIN, REBUILD_AT,
};
pub use patch::{Patch, PATCH_MOVERS, PATCH_SHARE};

use crate::garment::Garment;
use glam::Vec4;

/// Static data of particle–particle collisions, in the model's storage order.
#[derive(Clone, Debug)]
pub struct ParticleCollisions {
    /// Particle radius [m]: particles keep 2 × radius apart.
    pub radius: f32,
    /// Garment index of each particle.
    garment: Vec<u32>,
    /// Lattice cell of each particle.
    cell: Vec<[i32; 3]>,
    /// Hash table size (a power of two).
    table: usize,
}

/// Where a particle's push finds the particles it may overlap.
#[derive(Clone, Copy, Debug)]
pub enum Near<'a> {
    /// Its neighbour list, and where it was when the lists were made; the grid is the lists'
    /// (a list too long to keep walks it around that place).
    List(&'a List, Vec4),
    /// The grid, built this substep at q to find the pairs directly.
    Grid,
    /// Its list, kept past the movers of a patched substep, with its anchor ([`patch`]): for a
    /// mover or a particle a mover touches (others take [`Near::List`]).
    Patched(&'a List, Vec4, Patch<'a>),
}

/// Lattice steps within which two particles of one garment never collide (`particles.wgsl`
/// has the same, checked by `tests/shaders.rs`).
pub const SKIP_STEPS: i32 = 1;

impl ParticleCollisions {
    /// Collisions between every particle of `garments` at `radius`; `storage_of`: the storage
    /// index of each particle in export order (the garments' particles one garment after
    /// another).
    pub fn new(storage_of: &[u32], garments: &[Garment], radius: f32) -> ParticleCollisions {
        let n = storage_of.len();
        let mut garment = vec![0u32; n];
        let mut cell = vec![[0i32; 3]; n];
        let mut start = 0;
        for (g, spec) in garments.iter().enumerate() {
            for (k, c) in spec.cells.iter().enumerate() {
                let s = storage_of[start + k] as usize;
                garment[s] = g as u32;
                cell[s] = c.map(|v| v as i32);
            }
            start += spec.particle_count();
        }
        ParticleCollisions {
            radius,
            garment,
            cell,
            table: (2 * n).next_power_of_two().max(16),
        }
    }

    /// Memory the CPU backend's particle collisions take for `particles` particles [bytes]:
    /// their static data (garment and lattice cell), the grid (items, buckets, positions and
    /// the table's starts and cursors), the neighbour lists with their anchors and the pairs
    /// they are made from (and the order they are found in), the pushes, and a patched substep's movers (a flag each for moving
    /// and touched, and their list).
    pub fn memory_bytes(particles: usize) -> usize {
        let table = (2 * particles).next_power_of_two().max(16);
        let per_particle = 4 + 12 + (4 + 4 + 12) + (std::mem::size_of::<List>() + 16) + 16 + 2;
        let padding = grid::PADDING * (4 + 12);
        // The pairs a remake finds: room for one a particle (P's lists hold 0.1–1 each); and
        // the grid's slots, the order a remake shares out.
        let pairs = particles * (8 + 4);
        particles * per_particle + padding + pairs + (2 * table + 1) * 4 + PATCH_MOVERS as usize * 4
    }

    /// Default radius for `garments`: half the smallest rest spacing, so neighbours at rest touch.
    pub fn default_radius(garments: &[Garment]) -> f32 {
        garments
            .iter()
            .flat_map(|g| g.springs.iter().map(|s| s.rest))
            .fold(f32::MAX, f32::min)
            * 0.5
    }

    /// Hash buckets of the grid (a power of two).
    pub fn table(&self) -> usize {
        self.table
    }

    /// Per particle (storage order): its lattice cell and, as the fourth value, its garment: what
    /// the GPU kernels read to skip pairs springs hold.
    pub fn cells_and_garments(&self) -> Vec<[i32; 4]> {
        self.cell
            .iter()
            .zip(&self.garment)
            .map(|(c, &g)| [c[0], c[1], c[2], g as i32])
            .collect()
    }

    /// 1 / cell width of the GPU's grid, rebuilt every substep: cells two diameters wide, so
    /// the 2 × 2 × 2 cells on the sides of a particle's nearest cell corner hold every particle
    /// within a diameter of it.
    pub fn inv_cell(&self) -> f32 {
        0.25 / self.radius
    }

    /// Particle diameter [m]: the distance pairs are pushed apart to.
    pub fn diameter(&self) -> f32 {
        2.0 * self.radius
    }

    /// How far a neighbour list reaches [m]: a diameter and the margin.
    pub fn list_reach(&self) -> f32 {
        self.diameter() * (1.0 + LIST_MARGIN)
    }

    /// True when the lists no longer hold every pair that can touch: some particle has moved
    /// `moved` [m] from where they were made, past [`REBUILD_AT`] of the margin (or by NaN).
    pub fn lists_stale(&self, moved: f32) -> bool {
        let limit = REBUILD_AT * LIST_MARGIN * self.diameter();
        moved > limit || moved.is_nan()
    }

    /// The displacement that moves particle `i` out of the particles it overlaps at positions
    /// `q`, from the substep's start positions `x`; zero for a pinned particle. Its neighbours
    /// are found as `near` says. Each overlap pushes along the pair's separation at the start
    /// ([`apart`]) until the two are a diameter apart along it; the pushes are summed in
    /// ascending order of the other particle, so the push is the same however they were found.
    pub fn push_out(
        &self,
        i: usize,
        near: Near,
        (x, q): (impl Fn(usize) -> Vec4, impl Fn(usize) -> Vec4),
        inv_mass: &[f32],
        grid: &Grid,
    ) -> Vec4 {
        let wi = inv_mass[i];
        // A pinned particle, or an empty list (most of a garment, most substeps): the push of no
        // contact (zero over one contact, the same bits) without reading the positions.
        let alone =
            matches!(near, Near::List(list, _) if list.entries().is_some_and(<[u32]>::is_empty));
        if wi == 0.0 || alone {
            return Vec4::ZERO;
        }
        let (xi, qi) = (x(i), q(i));
        let diameter = self.diameter();
        // Most candidates are farther than a diameter: rejected before the root (the margin
        // keeps every pair the exact test below takes).
        let reach_squared = diameter * diameter * (1.0 + 1e-4);
        let mut push = Vec4::ZERO;
        let mut touching = 0u32;
        let mut meet = |j: usize| {
            let d = qi - q(j);
            if d.length_squared() > reach_squared || j == i || self.joined(i, j) {
                return;
            }
            let distance = d.length();
            if distance >= diameter || distance < 1e-9 {
                return;
            }
            // A diameter apart along the start separation: d projects onto it no longer than
            // `distance`, so this push is never less than the overlap.
            let along = apart(xi - x(j), d, distance);
            let wj = inv_mass[j];
            push += along * ((diameter - d.dot(along)) * wi / (wi + wj));
            touching += 1;
        };
        let around = match near {
            Near::List(list, anchor) => match list.entries() {
                Some(entries) => {
                    entries.iter().for_each(|&j| meet(j as usize));
                    None
                }
                None => Some(anchor),
            },
            Near::Grid => Some(qi),
            Near::Patched(list, anchor, patch) => {
                self.patched_candidates(i, (list, anchor), &q, patch, grid)
                    .into_iter()
                    .for_each(|j| meet(j as usize));
                None
            }
        };
        if let Some(p) = around {
            // (Reading the direct grid's own copy of q instead was slower on box_stack.)
            let within = |k: usize| (qi - q(grid.items[k] as usize)).length_squared();
            match self.gather(p, grid, reach_squared * 1.0001, within) {
                // The few within a diameter, in ascending order.
                Some((mut near, count)) => {
                    near[..count].sort_unstable();
                    near[..count].iter().for_each(|&j| meet(j as usize));
                }
                None => self.walk_in_order(p, grid, meet),
            }
        }
        // Averaged over the contacts: a particle pressed into a layer overlaps several of its
        // particles at once, and their summed pushes would throw it past them.
        push / touching.max(1) as f32
    }

    /// True when `i` and `j` are particles of one garment within [`SKIP_STEPS`] lattice steps.
    #[inline]
    fn joined(&self, i: usize, j: usize) -> bool {
        self.garment[i] == self.garment[j]
            && (0..3).all(|a| (self.cell[i][a] - self.cell[j][a]).abs() <= SKIP_STEPS)
    }
}

/// The direction two overlapping particles are pushed apart along: their separation `before`, at
/// the substep's start, when they were not in one place; else their separation `now` (of length
/// `distance`). Cloth that starts a substep on one side of another layer and is carried through
/// it by the solve is pushed back to the side it came from, where the separation now would push
/// it on through (`particles.wgsl`'s `pc_apart` is the same).
#[inline]
fn apart(before: Vec4, now: Vec4, distance: f32) -> Vec4 {
    let start = before.length();
    if start > 1e-9 {
        before / start
    } else {
        now / distance
    }
}
