//! Neighbour lists: each particle's candidates within a diameter and a margin, kept between
//! substeps while they stay valid, made from the pairs found each once in the lists' grid, and
//! the state that chooses between remaking them and finding the pairs directly.

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
/// lists costs more than a direct search (a reach of 1.75 diameters against one), so they pay
/// only when they last.
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

    /// A list that holds nothing yet.
    pub const EMPTY: List = List {
        len: 0,
        ids: [0; LIST_CAPACITY],
    };

    /// The particles listed, or `None` when there were too many to keep.
    pub fn entries(&self) -> Option<&[u32]> {
        (self.len != Self::OVERFLOW).then(|| &self.ids[..self.len as usize])
    }

    /// Adds particle `j` (a pair found twice adds it twice: [`Self::settle`] keeps one); a list
    /// with no room for another particle becomes one of too many to keep.
    pub fn add(&mut self, j: u32) {
        if self.len as usize == LIST_CAPACITY {
            self.settle();
            if self.ids[..self.len as usize].contains(&j) {
                return;
            }
        }
        match self.len as usize {
            len if len < LIST_CAPACITY => {
                self.ids[len] = j;
                self.len += 1;
            }
            _ => self.len = Self::OVERFLOW,
        }
    }

    /// Puts the particles added in ascending order, each once.
    pub fn settle(&mut self) {
        let Some(entries) = self.entries() else {
            return;
        };
        let mut ids = self.ids;
        let ids = &mut ids[..entries.len()];
        ids.sort_unstable();
        let mut len = 0;
        for k in 0..ids.len() {
            if k == 0 || ids[k] != ids[k - 1] {
                self.ids[len] = ids[k];
                len += 1;
            }
        }
        self.len = len as u32;
    }
}

/// Fills each particle's neighbour list in `lists` (empty before) from the pairs within a
/// list's reach ([`ParticleCollisions::forward_pairs`] of every particle): each pair adds each
/// of its two particles to the other's list.
pub fn lists_from_pairs(pairs: &[(u32, u32)], lists: &mut [List]) {
    lists_from_pairs_from(pairs, 0, lists);
}

/// [`lists_from_pairs`] for the particles `first..first + lists.len()` only (`lists` holds
/// theirs): every thread of a team fills its own stretch from all the pairs. A list's
/// particles do not depend on the order of the pairs (a list is kept sorted, each particle
/// once, or is one of too many to keep), so the stretches together are the lists one thread
/// would make.
pub fn lists_from_pairs_from(pairs: &[(u32, u32)], first: usize, lists: &mut [List]) {
    let len = lists.len();
    let mine = |k: u32| (k as usize).checked_sub(first).filter(|&k| k < len);
    for &(i, j) in pairs {
        if let Some(k) = mine(i) {
            lists[k].add(j);
        }
        if let Some(k) = mine(j) {
            lists[k].add(i);
        }
    }
    for &(i, j) in pairs {
        for k in [mine(i), mine(j)].into_iter().flatten() {
            lists[k].settle();
        }
    }
}

impl ParticleCollisions {
    /// Adds to `out` the pairs (i, j) of the particle i in slot `k` of `grid` (the lists'
    /// grid) with the particles within a list's reach of it where the grid was built, but its
    /// lattice neighbours, each pair once over all slots: j in one of the 13 cells after i's own
    /// in (z, y, x) order, or after i in its own bucket (which holds its cell's particles in
    /// ascending order): five runs of the rows (`grid.rs`), the first from the slot after k on.
    /// Two cells may share a bucket: a pair may then come twice ([`List::settle`] keeps one).
    pub fn forward_pairs(&self, k: usize, grid: &Grid, out: &mut Vec<(u32, u32)>) {
        let i = grid.items[k] as usize;
        let p = Vec4::new(grid.xs[k], grid.ys[k], grid.zs[k], 0.0);
        let spans = self.forward_spans(k, p, grid);
        let (px, py, pz) = (Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z));
        let reach_squared = self.list_reach() * self.list_reach();
        let reach = Vec4::splat(reach_squared);
        let mut near = [0u32; NEAR];
        let mut count = 0usize;
        for &(start, end) in &spans {
            let mut at = start;
            // Four at a time (the last four masked past the end: `PADDING`), without a branch
            // per candidate: each is written, and counted when near.
            while at < end {
                let dx = Vec4::from_slice(&grid.xs[at..at + 4]) - px;
                let dy = Vec4::from_slice(&grid.ys[at..at + 4]) - py;
                let dz = Vec4::from_slice(&grid.zs[at..at + 4]) - pz;
                let lanes = (1usize << (end - at).min(4)) - 1;
                let within = (dx * dx + dy * dy + dz * dz).cmplt(reach).bitmask() as usize & lanes;
                for lane in 0..4 {
                    near[count.min(NEAR - 1)] = grid.items[at + lane];
                    count += within >> lane & 1;
                }
                at += 4;
            }
        }
        if count < NEAR {
            let pairs = near[..count]
                .iter()
                .filter(|&&j| !self.joined(i, j as usize));
            out.extend(pairs.map(|&j| (i as u32, j)));
            return;
        }
        // More near than gathered (a clump): again, each candidate tested and kept on its own.
        for &(start, end) in &spans {
            for at in start..end {
                let j = grid.items[at] as usize;
                let d = Vec4::new(grid.xs[at], grid.ys[at], grid.zs[at], 0.0) - p;
                if d.length_squared() < reach_squared && !self.joined(i, j) {
                    out.push((i as u32, j as u32));
                }
            }
        }
    }

    /// The ranges of `grid.items` [`Self::forward_pairs`] searches for the particle in slot
    /// `k`, at `p`: its own bucket after it and the next cell along x (one run), then the four
    /// rows above (y + 1, and z + 1 at y − 1, y, y + 1) from x − 1 to x + 1; a run past the
    /// table's end goes on from its start (its second range; empty when it does not).
    fn forward_spans(&self, k: usize, p: Vec4, grid: &Grid) -> [(usize, usize); 10] {
        let (c, _) = Self::cell_of(p, grid.inv_cell);
        let row = |dy: i32, dz: i32| Self::row_hash(c[1].wrapping_add(dy), c[2].wrapping_add(dz));
        // (row, first cell, cells)
        let runs = [
            (row(0, 0), 0, 2),
            (row(1, 0), -1, 3),
            (row(-1, 1), -1, 3),
            (row(0, 1), -1, 3),
            (row(1, 1), -1, 3),
        ];
        let mut spans = [(0, 0); 10];
        for (r, &(row, x, cells)) in runs.iter().enumerate() {
            let first = self.row_bucket(row, c[0].wrapping_add(x));
            let last = first + cells - 1;
            let wrapped = last.saturating_sub(self.table - 1);
            let end = grid.start[last.min(self.table - 1) + 1] as usize;
            let start = match r {
                0 => k + 1,
                _ => grid.start[first] as usize,
            };
            spans[2 * r] = (start, end);
            spans[2 * r + 1] = (0, grid.start[wrapped] as usize * (wrapped > 0) as usize);
        }
        spans
    }
}
