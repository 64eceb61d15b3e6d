//! The hash grid particle collisions find their pairs in: the particles sorted by bucket of a
//! uniform grid of cells (a counting sort), with the positions they were sorted at; the block of
//! cells that holds every particle within a reach of a point, and the walks over it.

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
    /// bucket's candidates are read side by side, four at a time: [`ParticleCollisions::list`]).
    pub xs: Vec<f32>,
    pub ys: Vec<f32>,
    pub zs: Vec<f32>,
    /// Where the sort writes the next particle of each bucket (kept to spare an allocation).
    pub(super) cursor: Vec<u32>,
    /// 1 / cell width it was built with: twice a list's reach for the lists, twice a diameter
    /// to find the pairs directly.
    inv_cell: f32,
}

/// The most particles within a list's reach (itself and its lattice neighbours included) that
/// [`ParticleCollisions::list`] gathers before it gives up a list as too long.
pub(super) const NEAR: usize = 64;

impl ParticleCollisions {
    /// An empty grid for this model.
    pub fn grid(&self) -> Grid {
        Grid {
            start: vec![0; self.table + 1],
            items: vec![0; self.garment.len()],
            bucket: vec![0; self.garment.len()],
            xs: vec![0.0; self.garment.len()],
            ys: vec![0.0; self.garment.len()],
            zs: vec![0.0; self.garment.len()],
            cursor: vec![0; self.table],
            inv_cell: self.inv_cell(),
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

    /// Sorts the particles at positions `q` into `grid` (counting sort by bucket): for the
    /// lists ([`Self::list`]) when `for_lists`, else to find the pairs directly
    /// ([`Near::Grid`]).
    pub fn build(&self, q: impl Fn(usize) -> Vec4, grid: &mut Grid, for_lists: bool) {
        let n = self.garment.len();
        grid.inv_cell = match for_lists {
            true => 0.5 / self.list_reach(),
            false => self.inv_cell(),
        };
        grid.start.fill(0);
        for i in 0..n {
            let b = self.bucket_of(Self::cell_of(q(i), grid.inv_cell).0);
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

    /// The distinct buckets of the 2 × 2 × 2 cells of `grid` on the sides of the cell corner
    /// nearest `p` (two cells can share a bucket), and how many there are: they hold every
    /// particle within half a cell of `p` (a list's reach in the lists' grid, a diameter in
    /// the direct one), and others.
    pub(super) fn block(&self, p: Vec4, grid: &Grid) -> ([usize; 8], usize) {
        let (c, scaled) = Self::cell_of(p, grid.inv_cell);
        let side: [i32; 3] = std::array::from_fn(|a| {
            if scaled[a] - c[a] as f32 >= 0.5 {
                1
            } else {
                -1
            }
        });
        let mut buckets = [usize::MAX; 8];
        let mut seen = 0;
        for corner in 0..8 {
            // Wrapping: cells only feed the hash, and a particle flung past i32 cells (a
            // blow-up, caught by the stability rule) must not panic here first.
            let cell: [i32; 3] = std::array::from_fn(|a| {
                c[a].wrapping_add(if corner >> a & 1 == 1 { side[a] } else { 0 })
            });
            let b = self.bucket_of(cell);
            if !buckets[..seen].contains(&b) {
                buckets[seen] = b;
                seen += 1;
            }
        }
        (buckets, seen)
    }

    /// Calls `each(j)` for every particle of `p`'s [`Self::block`] in `grid` in ascending order
    /// of j (a merge of the buckets, each ascending).
    pub(super) fn walk_in_order(&self, p: Vec4, grid: &Grid, mut each: impl FnMut(usize)) {
        let (buckets, seen) = self.block(p, grid);
        let mut ranges = buckets.map(|b| match b {
            usize::MAX => (0, 0),
            b => (grid.start[b] as usize, grid.start[b + 1] as usize),
        });
        let ranges = &mut ranges[..seen];
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
        let (buckets, seen) = self.block(p, grid);
        let mut near = [0u32; NEAR];
        let mut count = 0usize;
        for &b in &buckets[..seen] {
            for k in grid.start[b] as usize..grid.start[b + 1] as usize {
                near[count.min(NEAR - 1)] = grid.items[k];
                count += (distance_squared(k) < reach_squared) as usize;
            }
        }
        (count < NEAR).then_some((near, count))
    }
}
