//! Neighbour lists: each particle's candidates within a diameter and a margin, kept between
//! substeps while they stay valid, and the state that chooses between remaking them and finding
//! the pairs directly.

use super::grid::{Grid, NEAR};
use super::{ParticleCollisions, PATCH_MOVERS, PATCH_SHARE};
use glam::Vec4;

/// How far past a diameter a neighbour list reaches, in diameters. A wider margin keeps the
/// lists valid for more substeps and makes them longer and slower to make (0.75 measured best
/// on P and the character scenes once a few movers no longer make them again; 0.5 before: see
/// `docs/benchmarks.md`).
pub const LIST_MARGIN: f32 = 0.75;

/// The share of the margin any particle may move from where the lists were made before they
/// are made again: two particles closing on each other then close by 0.9 of the margin at most,
/// and the rest is far above the rounding of the distances.
pub const REBUILD_AT: f32 = 0.45;

/// The most particles a neighbour list holds; a particle with more is walked in the grid.
pub const LIST_CAPACITY: usize = 15;

/// How a substep finds the pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Finding {
    /// From the lists, still valid.
    Reuse,
    /// The lists made again at q, then used.
    Remake,
    /// The lists kept, some particles having moved too far for them: those movers' pairs found
    /// apart ([`super::patch`]).
    Patch,
    /// In a grid built at q, without lists: where the cloth moves too fast for lists to last.
    Direct,
}

/// Substeps found directly after lists went stale at the first substep that used them: making
/// lists looks at about twice the candidates of a direct search (cells three diameters wide
/// against two), so they pay only when they last.
pub const DIRECT_RUN: u32 = 8;

/// Which way the substeps find their pairs, kept between them. What they find does not depend
/// on it (pushes are summed in one order), only what it costs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ListState {
    /// Whether lists were made and have not been found stale since.
    pub valid: bool,
    /// Substeps that have used them since they were made.
    reused: u32,
    /// Substeps still to find their pairs directly.
    direct_left: u32,
}

impl ListState {
    /// This substep's way, given whether valid lists were found `stale` at q, by how many
    /// `movers` of the model's `particles`.
    pub fn finding(&self, stale: bool, movers: u32, particles: usize) -> Finding {
        let few = movers <= PATCH_MOVERS && movers as usize * PATCH_SHARE as usize <= particles;
        match (self.valid, stale) {
            (true, false) => Finding::Reuse,
            (true, true) if few => Finding::Patch,
            // Stale before they served once more than the substep that made them.
            (true, true) if self.reused == 0 => Finding::Direct,
            (false, _) if self.direct_left > 0 => Finding::Direct,
            _ => Finding::Remake,
        }
    }

    /// The state after a substep that went `finding`, having found valid lists `stale`.
    pub fn after(self, finding: Finding, stale: bool) -> ListState {
        match finding {
            Finding::Reuse | Finding::Patch => ListState {
                reused: self.reused + 1,
                ..self
            },
            Finding::Remake => ListState {
                valid: true,
                ..ListState::default()
            },
            Finding::Direct if self.valid && stale => ListState {
                direct_left: DIRECT_RUN - 1,
                ..ListState::default()
            },
            Finding::Direct => ListState {
                direct_left: self.direct_left.saturating_sub(1),
                ..self
            },
        }
    }
}

/// A particle's neighbour list: the particles within a diameter and the margin of it where the
/// lists were made, but its lattice neighbours, ascending.
#[derive(Clone, Copy, Debug)]
pub struct List {
    /// Entries in `ids`, or [`List::OVERFLOW`].
    len: u32,
    ids: [u32; LIST_CAPACITY],
}

impl List {
    /// More neighbours than a list holds: walk the grid.
    const OVERFLOW: u32 = u32::MAX;

    /// A list of too many to keep.
    const OVERFLOW_LIST: List = List {
        len: List::OVERFLOW,
        ids: [0; LIST_CAPACITY],
    };

    /// A list that holds nothing yet.
    pub const EMPTY: List = List {
        len: 0,
        ids: [0; LIST_CAPACITY],
    };

    /// The particles listed, or `None` when there were too many to keep.
    pub fn entries(&self) -> Option<&[u32]> {
        (self.len != Self::OVERFLOW).then(|| &self.ids[..self.len as usize])
    }
}

impl ParticleCollisions {
    /// The neighbour list of particle `i` at `p`, from `grid` built at the same positions.
    pub fn list(&self, i: usize, p: Vec4, grid: &Grid) -> List {
        let reach_squared = self.list_reach() * self.list_reach();
        let Some((near, count)) = self.gather_by_four(p, grid, reach_squared) else {
            return List::OVERFLOW_LIST;
        };
        let mut list = List::EMPTY;
        for &j in &near[..count] {
            let j = j as usize;
            if j == i || self.joined(i, j) {
                continue;
            }
            if list.len as usize == LIST_CAPACITY {
                return List::OVERFLOW_LIST;
            }
            list.ids[list.len as usize] = j as u32;
            list.len += 1;
        }
        list.ids[..list.len as usize].sort_unstable();
        list
    }

    /// [`Self::gather`] within `reach_squared` of `p` by the positions the grid was built at,
    /// four candidates at a time (a list is made from about 64 candidates, 9 of them near).
    fn gather_by_four(
        &self,
        p: Vec4,
        grid: &Grid,
        reach_squared: f32,
    ) -> Option<([u32; NEAR], usize)> {
        let (buckets, seen) = self.block(p, grid);
        let (px, py, pz) = (Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z));
        let reach = Vec4::splat(reach_squared);
        let mut near = [0u32; NEAR];
        let mut count = 0usize;
        for &b in &buckets[..seen] {
            let (start, end) = (grid.start[b] as usize, grid.start[b + 1] as usize);
            let (items, xs) = (&grid.items[start..end], &grid.xs[start..end]);
            let (ys, zs) = (&grid.ys[start..end], &grid.zs[start..end]);
            let whole = items.len() / 4 * 4;
            for k in (0..whole).step_by(4) {
                let dx = Vec4::from_slice(&xs[k..k + 4]) - px;
                let dy = Vec4::from_slice(&ys[k..k + 4]) - py;
                let dz = Vec4::from_slice(&zs[k..k + 4]) - pz;
                let within = (dx * dx + dy * dy + dz * dz).cmplt(reach).bitmask() as usize;
                for lane in 0..4 {
                    near[count.min(NEAR - 1)] = items[k + lane];
                    count += within >> lane & 1;
                }
            }
            for k in whole..items.len() {
                let d = Vec4::new(xs[k], ys[k], zs[k], 0.0) - p.truncate().extend(0.0);
                near[count.min(NEAR - 1)] = items[k];
                count += (d.length_squared() < reach_squared) as usize;
            }
        }
        (count < NEAR).then_some((near, count))
    }
}
