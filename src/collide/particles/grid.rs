//! The hash grids particle collisions find their pairs in: the particles sorted by bucket (a
//! counting sort), with the positions they were sorted at, in one of two layouts; the cells
//! around a point that hold every particle within a reach of it, and the walks over them.
//!
//! - **Corners** (the direct search, cells two diameters wide): a cell's bucket is its spatial
//!   hash, and the 2 × 2 × 2 cells on the sides of the cell corner nearest a point hold every
//!   particle within a diameter of it (the GPU's grid, `particles.wgsl`).
//! - **Rows** (the neighbour lists, cells a list's reach wide): a cell's bucket is the hash of
//!   its row (its y and z) plus its x, so the three cells of a row along x are three buckets in
//!   a row, one run of the sorted particles. The 27 cells around a point's own cell, which hold
//!   every particle within a reach of it, are nine runs; the particles after a particle in its
//!   own bucket and the 13 cells after its own in (z, y, x) order, which find each pair once,
//!   are five, searched slot by slot of the sorted particles ([`ParticleCollisions::
//!   forward_pairs`]). A list's particle looks at a third of the candidates the corners' block,
//!   four reaches a side, gave it (P: 23 against 74), in five runs against eight buckets.

use super::ParticleCollisions;
use glam::Vec4;

/// A hash grid of the particles: sorted by bucket, with the positions they were sorted at (for
/// the lists, their anchors).
#[derive(Clone, Debug, Default)]
pub struct Grid {
    /// Start of each bucket in `items`; length = table + 1.
    pub start: Vec<u32>,
    /// Particles sorted by bucket, ascending within each.
    pub items: Vec<u32>,
    /// Bucket of each particle.
    pub bucket: Vec<u32>,
    /// The position of each particle of `items`, in `items`' order, one coordinate a vector (a
    /// run's candidates are read side by side, four at a time:
    /// [`ParticleCollisions::forward_pairs`]).
    pub xs: Vec<f32>,
    pub ys: Vec<f32>,
    pub zs: Vec<f32>,
    /// Where the sort writes the next particle of each bucket (kept to spare an allocation).
    pub(super) cursor: Vec<u32>,
    /// 1 / cell width it was built with: a list's reach for the lists, twice a diameter to find
    /// the pairs directly.
    pub(super) inv_cell: f32,
    /// Laid out in rows (the lists'), else by corners (the direct search's).
    rows: bool,
}

/// The cells around a point, as runs of buckets (each `start..end`, the buckets in between
/// included): every particle of them lies in `grid.items[grid.start[start]..grid.start[end]]`
/// for some run, and no particle in two runs.
#[derive(Clone, Copy, Debug)]
pub(super) struct Runs {
    runs: [(usize, usize); MOST_RUNS],
    count: usize,
}

/// The most runs [`Runs`] holds: 27 buckets, when the rows' cells fall in buckets apart.
const MOST_RUNS: usize = 27;

impl Runs {
    /// The runs, each `start..end` of buckets.
    pub(super) fn each(&self) -> &[(usize, usize)] {
        &self.runs[..self.count]
    }

    /// The same buckets one bucket a run (a walk in order merges runs ascending within).
    fn single_buckets(&self) -> Runs {
        let mut out = Runs {
            runs: [(0, 0); MOST_RUNS],
            count: 0,
        };
        for &(start, end) in self.each() {
            for b in start..end {
                out.runs[out.count] = (b, b + 1);
                out.count += 1;
            }
        }
        out
    }
}

/// The most particles near a point that [`ParticleCollisions::gather`] gathers before it gives
/// way to a walk, and [`ParticleCollisions::forward_pairs`] before it takes them one by one.
pub(super) const NEAR: usize = 64;

/// Entries past the last particle in `items` and the positions: the lists read a run four
/// candidates at a time, the last four reaching up to three past its end (masked off).
pub(super) const PADDING: usize = 3;

impl ParticleCollisions {
    /// An empty grid for this model.
    pub fn grid(&self) -> Grid {
        Grid {
            start: vec![0; self.table + 1],
            items: vec![0; self.garment.len() + PADDING],
            bucket: vec![0; self.garment.len()],
            xs: vec![0.0; self.garment.len() + PADDING],
            ys: vec![0.0; self.garment.len() + PADDING],
            zs: vec![0.0; self.garment.len() + PADDING],
            cursor: vec![0; self.table],
            inv_cell: self.inv_cell(),
            rows: false,
        }
    }

    /// Integer cell of a position in cells `1 / s` wide, with the position in cells.
    #[inline]
    pub(super) fn cell_of(p: Vec4, s: f32) -> ([i32; 3], [f32; 3]) {
        let scaled = [p.x * s, p.y * s, p.z * s];
        let cell = crate::collide::floor_cell(glam::Vec3A::from_array(scaled));
        (cell.to_array(), scaled)
    }

    #[inline]
    pub(super) fn bucket_of(&self, c: [i32; 3]) -> usize {
        (crate::collide::hash_cell(c) as usize) & (self.table - 1)
    }

    /// The hash of row (y, z) of the rows' layout: its cell x is in bucket `row + x`.
    #[inline]
    pub(super) fn row_hash(y: i32, z: i32) -> i32 {
        let [_, py, pz] = crate::collide::HASH_PRIMES;
        y.wrapping_mul(py) ^ z.wrapping_mul(pz)
    }

    /// The bucket of cell x of a row of hash `row` (wrapping: cells only feed the hash, and a
    /// particle flung past i32 cells, a blow-up the stability rule catches, must not panic
    /// here first).
    #[inline]
    pub(super) fn row_bucket(&self, row: i32, x: i32) -> usize {
        row.wrapping_add(x) as u32 as usize & (self.table - 1)
    }

    /// The bucket of cell `c` in `grid`'s layout.
    #[inline]
    fn bucket_in(&self, grid: &Grid, c: [i32; 3]) -> usize {
        match grid.rows {
            true => self.row_bucket(Self::row_hash(c[1], c[2]), c[0]),
            false => self.bucket_of(c),
        }
    }

    /// Sorts the particles at positions `q` into `grid` (counting sort by bucket): in rows for
    /// the lists ([`Self::forward_pairs`]) when `for_lists`, else by corners to find the pairs
    /// directly ([`Near::Grid`]).
    ///
    /// [`Near::Grid`]: super::Near::Grid
    pub fn build(&self, q: impl Fn(usize) -> Vec4, grid: &mut Grid, for_lists: bool) {
        let n = self.garment.len();
        grid.rows = for_lists;
        grid.inv_cell = match for_lists {
            true => 1.0 / self.list_reach(),
            false => self.inv_cell(),
        };
        grid.start.fill(0);
        for i in 0..n {
            let b = self.bucket_in(grid, Self::cell_of(q(i), grid.inv_cell).0);
            grid.bucket[i] = b as u32;
            grid.start[b + 1] += 1;
        }
        for b in 0..self.table {
            grid.start[b + 1] += grid.start[b];
        }
        grid.cursor.copy_from_slice(&grid.start[..self.table]);
        for i in 0..n {
            let b = grid.bucket[i] as usize;
            let at = grid.cursor[b] as usize;
            grid.cursor[b] += 1;
            grid.items[at] = i as u32;
            let p = q(i);
            (grid.xs[at], grid.ys[at], grid.zs[at]) = (p.x, p.y, p.z);
        }
    }

    /// The cells of `grid` around `p` that hold every particle within half a cell of it (by
    /// corners: a diameter in the direct grid) or within a cell of it (in rows: a list's reach
    /// in the lists' grid), and others, as runs of buckets, no bucket twice (two cells can
    /// share one).
    pub(super) fn block(&self, p: Vec4, grid: &Grid) -> Runs {
        let (c, scaled) = Self::cell_of(p, grid.inv_cell);
        let mut runs = Runs {
            runs: [(0, 0); MOST_RUNS],
            count: 0,
        };
        let mut add = |b: usize| {
            if !runs.each().iter().any(|&(start, _)| start == b) {
                runs.runs[runs.count] = (b, b + 1);
                runs.count += 1;
            }
        };
        if !grid.rows {
            // The 2 × 2 × 2 cells on the sides of the cell corner nearest p.
            let side: [i32; 3] = std::array::from_fn(|a| {
                if scaled[a] - c[a] as f32 >= 0.5 {
                    1
                } else {
                    -1
                }
            });
            for corner in 0..8 {
                // Wrapping: see `row_bucket`.
                let cell: [i32; 3] = std::array::from_fn(|a| {
                    c[a].wrapping_add(if corner >> a & 1 == 1 { side[a] } else { 0 })
                });
                add(self.bucket_of(cell));
            }
            return runs;
        }
        // Nine rows of three cells: one run each, unless a row wraps past the table's end or
        // two rows' buckets meet (then bucket by bucket, each once).
        let mut firsts = [0usize; 9];
        for (k, first) in firsts.iter_mut().enumerate() {
            let (y, z) = (
                c[1].wrapping_add(k as i32 % 3 - 1),
                c[2].wrapping_add(k as i32 / 3 - 1),
            );
            *first = self.row_bucket(Self::row_hash(y, z), c[0].wrapping_sub(1));
        }
        let apart = firsts.iter().enumerate().all(|(k, &a)| {
            a + 3 <= self.table && firsts[k + 1..].iter().all(|&b| a.abs_diff(b) >= 3)
        });
        if apart {
            runs.count = 9;
            for (run, &first) in runs.runs.iter_mut().zip(&firsts) {
                *run = (first, first + 3);
            }
        } else {
            for &first in &firsts {
                for x in 0..3 {
                    add((first + x) & (self.table - 1));
                }
            }
        }
        runs
    }

    /// Calls `each(j)` for every particle of `p`'s [`Self::block`] in `grid` in ascending order
    /// of j (a merge of the buckets, each ascending).
    pub(super) fn walk_in_order(&self, p: Vec4, grid: &Grid, mut each: impl FnMut(usize)) {
        // Each bucket is ascending; a run of several is not.
        let runs = self.block(p, grid).single_buckets();
        let mut ranges = runs
            .runs
            .map(|(b, end)| (grid.start[b] as usize, grid.start[end] as usize));
        let ranges = &mut ranges[..runs.count];
        loop {
            let mut next = None;
            let mut least = u32::MAX;
            for (k, &(at, end)) in ranges.iter().enumerate() {
                if at < end && grid.items[at] < least {
                    least = grid.items[at];
                    next = Some(k);
                }
            }
            let Some(k) = next else { return };
            ranges[k].0 += 1;
            each(least as usize);
        }
    }

    /// The particles of `p`'s [`Self::block`] in `grid` whose `distance_squared` (given
    /// their place in `grid.items`) is below `reach_squared`, and how many; `None` when there
    /// are [`NEAR`] or more. Without a branch per candidate (whether one is near is a coin toss
    /// the branch predictor loses): each is written, and counted only when near.
    pub(super) fn gather(
        &self,
        p: Vec4,
        grid: &Grid,
        reach_squared: f32,
        distance_squared: impl Fn(usize) -> f32,
    ) -> Option<([u32; NEAR], usize)> {
        let runs = self.block(p, grid);
        let mut near = [0u32; NEAR];
        let mut count = 0usize;
        for &(b, end) in runs.each() {
            for k in grid.start[b] as usize..grid.start[end] as usize {
                near[count.min(NEAR - 1)] = grid.items[k];
                count += (distance_squared(k) < reach_squared) as usize;
            }
        }
        (count < NEAR).then_some((near, count))
    }
}
