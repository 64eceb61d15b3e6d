//! Garments against animated characters: each character is a shell of collision particles
//! (`character::Shell`) whose positions are known on every frame and interpolated at every
//! substep. A uniform grid (cell = the largest contact distance, hashed, rebuilt each substep by
//! a counting sort) finds the shell particles near a garment particle; an overlapping pair is
//! pushed apart along the line between the centres (along the skin's normal once it is past
//! the shell particle's tangent plane), the garment particle alone moving, and friction acts on
//! its motion *relative to the skin* (so cloth resting on a moving arm moves with it). Where
//! a garment particle overlaps several shell particles, they push nearest first, each from where
//! the ones before left it: the result does not depend on the order the shell's particles are
//! stored in (they are stored in Morton order of their cells, for the caches) or visited in.
//! Where two of those pushes come from opposite sides of the skin ([`PINCH`]: the body closing
//! on itself, a hand against a hip, or the two faces of a thin plate), the particle is
//! *pinched*: pushed from both sides it would be squeezed out sideways along the skin by the
//! overlap of the two reaches and tear its springs, so instead it is held where it was, carried
//! by the skin's mean motion, and slips along the skin only by what the solve asks beyond
//! friction on the squeeze. Where the skin presses cloth against an analytic collider instead
//! (a back on a cape on the floor), the collider keeps it off its surface and the skin carries it
//! along ([`crate::collide::INTO_COLLIDER`], [`ShellCollider::pressing`]).
//!
//! With the swept test on, each garment particle's path over the substep is also traced against
//! the shell particles *relative to their own motion*: a path that crosses the skin's tangent
//! plane within a shell particle's radius of its centre and ends beyond that particle's reach
//! (where the end-point push cannot bring it back) stops where it crosses, rides with the skin
//! for the rest of the substep, and is pushed out from there. Paths that end within reach are
//! left to the end-point push, which pushes along the skin's normal once a particle is past a
//! shell particle's tangent plane, so it never pushes cloth further into the body; cloth sliding
//! over the skin never crosses it and is never stopped.
//!
//! On the CPU backend a large moving shell is *focused* each frame: only the shell particles
//! whose path over the frame comes within two contact distances of where the garments can be
//! meanwhile are moved and gridded (the garments' reach is kept on a coarse lattice,
//! [`NearGarments`]; the simulation checks before each substep that no garment particle is
//! about to leave it, and focuses again when one is). Every test looks only within two contact
//! distances, so the frames are the same bits as without the focus; a cape on a running
//! figure's head no longer pays for its legs.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

mod ahead;
mod contact;
mod grid;
mod near;
mod placement;
use super::floor_cell;
use ahead::AheadSlot;
use contact::*;
use grid::*;
use placement::*;

pub use contact::{listed, Nearby, NEARBY, PINCH, SHELL_FOUND, SWEPT_PATH_CELLS};
pub use near::NearGarments;
pub use placement::frame_weight;

/// A shell at the end of a substep as the GPU reads it: per particle (position, motion,
/// normal), then the grid's bucket starts and items.
pub type ShellSnapshot = (Vec<[Vec4; 3]>, Vec<u32>);

/// A character's shell as a collider.
#[derive(Clone, Debug)]
pub struct ShellCollider {
    pub name: String,
    /// Shell particle radius [m].
    pub radius: f32,
    pub friction: f32,
    /// Shell particle positions on every character frame (frame 0 at the start of the bake).
    pub frames: Vec<Vec<Vec3>>,
    /// Trace each garment particle's path, not only where it ends (the scene's
    /// `swept_collisions`).
    pub swept: bool,
    /// Outward surface normals of the shell particles on every frame, when the shell rides one
    /// mesh (empty otherwise: then every contact pushes along the line between the centres).
    pub normals: Vec<Vec<Vec3>>,
    /// The mesh the shell rides and where on it each particle sits, when its topology holds
    /// over the frames (the GPU backend places the particles from it).
    pub skin: Option<std::sync::Arc<super::skin::Skin>>,
    /// Positions at the end of the current substep.
    now: Vec<Vec3>,
    /// Normals at the end of the current substep (empty without `normals`).
    now_normal: Vec<Vec3>,
    /// Their motion over the current substep.
    motion: Vec<Vec3>,
    /// The fractional frame `now` is at (None before the first substep).
    now_at: Option<f32>,
    /// Positions at the start of the current substep (a buffer kept between substeps).
    before: Vec<Vec3>,
    /// The longest distance a shell particle moved over the current substep [m].
    fastest: f32,
    /// On the CPU backend, the shell particles that can come near the garments this frame
    /// (see [`ShellCollider::focus`]); None: all of them.
    focus: Option<Focus>,
    /// Counts the focuses made (a placement ahead is for one of them).
    focus_made: u64,
    /// The shell placed ahead for the next substep, if it was.
    ahead: AheadSlot,
    /// Substeps that took the shell placed ahead.
    taken_ahead: u64,
    /// The box around the shell particles at both ends of the current substep: a path whose
    /// box stays two reaches away meets none of them (the broad phase of `resolve`).
    bounds: (Vec3, Vec3),
    grid: HashGrid,
}

impl ShellCollider {
    /// A collider from shell positions per frame.
    pub fn new(name: String, radius: f32, friction: f32, frames: Vec<Vec<Vec3>>) -> ShellCollider {
        let now: Vec<Vec3> = frames.first().cloned().unwrap_or_default();
        let bounds = now.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
        ShellCollider {
            name,
            radius,
            friction,
            swept: true,
            normals: Vec::new(),
            skin: None,
            now_normal: Vec::new(),
            motion: vec![Vec3::ZERO; now.len()],
            now,
            now_at: None,
            before: Vec::new(),
            fastest: 0.0,
            focus: None,
            focus_made: 0,
            ahead: AheadSlot::default(),
            taken_ahead: 0,
            frames,
            bounds,
            grid: HashGrid::default(),
        }
    }

    /// Positions at fractional frame `f` (the last frame holds).
    pub fn positions_at(&self, f: f32) -> Vec<Vec3> {
        interpolate(&self.frames, f)
    }

    /// Garment particles (`q`) inside the shell's particles: count, and the deepest overlap of
    /// a contact [m] (contact distance minus centre distance), over particles closer than the
    /// shell radius to a shell particle centre.
    pub fn penetration(&self, q: &[Vec4]) -> super::Penetration {
        let depth = |p: &Vec4| {
            let p = p.truncate();
            let mut deepest = 0.0f32;
            self.grid.near(p, |i| {
                let d = p.distance(self.now[i]);
                if d < self.radius {
                    deepest = deepest.max(self.radius - d);
                }
            });
            deepest
        };
        // A count and a maximum: the same on any number of threads.
        q.par_iter()
            .with_min_len(1024)
            .map(|p| super::Penetration::of_depth(depth(p)))
            .reduce(super::Penetration::default, super::Penetration::merge)
    }

    /// The longest distance a shell particle moved over the current substep [m].
    pub fn fastest_motion(&self) -> f32 {
        self.fastest
    }

    /// The shell as the GPU reads it at the end of the current substep: per particle its
    /// position, its motion over the substep and its normal (zero without normals); then the
    /// grid's bucket starts (buckets + 1) and its items.
    /// A shell re-sampled per frame is padded to its most particles over the frames (the GPU
    /// lays every substep out alike): padding particles sit 10¹⁸ m away, where no garment
    /// particle comes within reach, and no grid bucket lists them.
    /// Of a shell that is not focused (a focused one moved only some of its particles; the GPU
    /// backend unfocuses every shell).
    pub fn gpu_snapshot(&self) -> ShellSnapshot {
        let most = self.most_particles();
        let far = [Vec4::splat(1e18), Vec4::ZERO, Vec4::ZERO];
        let mut particles: Vec<[Vec4; 3]> = self
            .now
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let n = self.now_normal.get(i).copied().unwrap_or(Vec3::ZERO);
                [p.extend(0.0), self.motion[i].extend(0.0), n.extend(0.0)]
            })
            .collect();
        particles.resize(most, far);
        assert!(
            self.grid.dense.is_none(),
            "a focused shell's grid is not the GPU's (the GPU backend unfocuses every shell)"
        );
        let mut grid: Vec<u32> = self.grid.ranges.iter().map(|r| r[0]).collect();
        grid.push(self.grid.items.len() as u32);
        grid.extend_from_slice(&self.grid.items);
        grid.resize(self.grid.ranges.len() + 1 + most, 0);
        (particles, grid)
    }

    /// True for a shell that never moves (a character of one frame: a stool).
    pub fn is_static(&self) -> bool {
        self.frames.len() == 1
    }

    /// The most shell particles of any frame (all frames' alike unless the character's topology
    /// changes and its shell is re-sampled per frame); the grid has buckets for this many.
    pub fn most_particles(&self) -> usize {
        self.frames.iter().map(Vec::len).max().unwrap_or(0)
    }

    /// Hash buckets of the grid for `particles` shell particles: eight per particle, so the
    /// buckets a test walks rarely hold particles of other cells (measured on P: `finish` 12 →
    /// 7.8 ms per frame against two per particle; sixteen gained nothing more).
    pub fn buckets_for(particles: usize) -> usize {
        (8 * particles).next_power_of_two().max(64)
    }

    /// Width of a grid cell for garment particles of contact radius up to `garment_radius`.
    pub fn cell_for(&self, garment_radius: f32) -> f32 {
        (self.radius + garment_radius).max(1e-6)
    }

    /// Number of shell particles.
    pub fn particles(&self) -> usize {
        self.now.len()
    }
}

#[cfg(test)]
mod tests;
