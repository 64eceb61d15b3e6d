//! Lists kept past a few movers: a substep where some particles have moved too far from where
//! the lists were made (the movers) but most have not keeps the lists, and finds the movers'
//! pairs apart, instead of making every list again.
//!
//! Why it finds every pair within a diameter (the lists were made at each particle's anchor a,
//! reach R = a diameter d and the margin; a particle is a mover when it is more than
//! D = [`REBUILD_AT`] × margin from its anchor, D < (R − d) / 2):
//! - Two particles that are not movers and touch were less than d + 2D < R apart at their
//!   anchors, so each is in the other's list.
//! - A particle j that is not a mover and touches a mover i at q is within d + D < R of q_i by its
//!   anchor: it lies in the 27 cells of the lists' grid around q_i (cells R wide). The mover looks
//!   there for the particles that are not movers, and marks each one it touches.
//! - Movers and the particles they touch test every mover for the movers they touch: a patch
//!   is taken only while they are at most [`PATCH_MOVERS`].
//!
//! A marked particle takes its list's particles that are not movers and the movers it touches;
//! an unmarked one its list (a mover in it is farther than a diameter, which the push's exact
//! test rejects). Every particle thus meets the same pairs in the same ascending order as from
//! fresh lists: the pushes, and the frames, do not depend on whether a substep patched.
//!
//! The movers grow fast once the first has moved too far (on the shipped character scenes
//! typically 1, 10, 30, 80, 200, 400 in successive substeps): a patch is worth it only while
//! they are few. [`ListState`] patches while they are at most [`PATCH_MOVERS`] and at most
//! 1 / [`PATCH_SHARE`] of the particles, then remakes.
//!
//! [`REBUILD_AT`]: super::REBUILD_AT
//! [`ListState`]: super::ListState

use super::grid::{Grid, NEAR};
use super::{List, ParticleCollisions};
use glam::Vec4;

/// The most movers a patched substep has: each mover and each particle it touches tests
/// every mover.
pub const PATCH_MOVERS: u32 = 64;

/// The share of the particles the movers may be (1 / this) for a substep to patch the lists:
/// a mover costs a patch two searches in a grid and the tests against the movers, where making
/// the lists again costs one search a particle.
pub const PATCH_SHARE: u32 = 16;

/// What a patched substep's push reads besides a particle's list: which particles are movers.
#[derive(Clone, Copy)]
pub struct Patch<'a> {
    /// True for a mover.
    pub moving: &'a dyn Fn(usize) -> bool,
    /// The movers, ascending.
    pub movers: &'a [u32],
}

impl std::fmt::Debug for Patch<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Patch").finish_non_exhaustive()
    }
}

impl ParticleCollisions {
    /// Calls `each(j)` for every particle j that is not a mover and lies within a diameter of
    /// mover `i` at `q`, found in the lists' grid `lists` (built at the anchors) around q_i.
    pub fn touched_by_mover(
        &self,
        i: usize,
        q: impl Fn(usize) -> Vec4,
        moving: &dyn Fn(usize) -> bool,
        lists: &Grid,
        mut each: impl FnMut(usize),
    ) {
        let qi = q(i);
        let reach_squared = self.contact_reach_squared();
        let within = |k: usize| (qi - q(lists.items[k] as usize)).length_squared();
        let mut meet = |j: usize| {
            if j != i && !moving(j) && (qi - q(j)).length_squared() <= reach_squared {
                each(j);
            }
        };
        match self.gather(qi, lists, reach_squared * 1.0001, within) {
            Some((near, count)) => near[..count].iter().for_each(|&j| meet(j as usize)),
            None => self.walk_in_order(qi, lists, meet),
        }
    }

    /// The candidates of particle `i` in a patched substep, ascending: the particles that are
    /// not movers from its list (a mover: from the lists' grid `lists` around q_i; a list too
    /// long to keep: around its `anchor`), and the movers near q_i.
    pub(super) fn patched_candidates(
        &self,
        i: usize,
        (list, anchor): (&List, Vec4),
        q: &impl Fn(usize) -> Vec4,
        patch: Patch,
        lists: &Grid,
    ) -> Vec<u32> {
        let qi = q(i);
        let reach_squared = self.contact_reach_squared() * 1.0001;
        let mut found = Vec::with_capacity(2 * NEAR);
        let moving = patch.moving;
        let mut keep = |j: u32| {
            if !moving(j as usize) {
                found.push(j);
            }
        };
        let around = match (moving(i), list.entries()) {
            (false, Some(entries)) => {
                entries.iter().for_each(|&j| keep(j));
                None
            }
            (false, None) => Some(anchor),
            (true, _) => Some(qi),
        };
        if let Some(p) = around {
            let within = |k: usize| (qi - q(lists.items[k] as usize)).length_squared();
            match self.gather(p, lists, reach_squared, within) {
                Some((near, count)) => near[..count].iter().for_each(|&j| keep(j)),
                None => self.walk_in_order(p, lists, |j| keep(j as u32)),
            }
        }
        let near = |&&j: &&u32| (qi - q(j as usize)).length_squared() < reach_squared;
        found.extend(patch.movers.iter().filter(near));
        found.sort_unstable();
        found
    }

    /// The squared distance within which two particles touch, widened by the rounding the
    /// push's own test allows.
    fn contact_reach_squared(&self) -> f32 {
        self.diameter() * self.diameter() * (1.0 + 1e-4)
    }
}
