//! Particle–particle collisions: self-collision of a garment and garment–garment contact (CPU
//! here; `shaders/particles.wgsl` runs the same steps on the GPU).
//!
//! Every substep, after the solver, the predicted positions q = x + Δ are sorted into a uniform
//! hash grid whose cells are one particle diameter wide (a counting sort, so building costs two
//! passes over the particles), and each particle is pushed out of every other particle closer
//! than one diameter: a Jacobi pass, each particle moving by the mean of its pushes (each its
//! share of one overlap by inverse mass, so pinned particles stay), all corrections computed
//! from the same q, so the result does not depend on the order or the thread count. A pair is
//! pushed apart along its separation at the substep's start (x), not its separation in q, so a
//! particle carried through a layer in the solve goes back to its own side instead of on through.
//! Pairs of one garment that are lattice neighbours (one step apart on every axis at most) are
//! skipped: springs hold them, and at rest they already touch. Particles two steps apart are
//! two diameters apart at rest, so they collide only where the cloth folds onto itself, which
//! keeps a tight fold from closing through itself.

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

/// The hash grid of one substep.
#[derive(Clone, Debug, Default)]
pub struct Grid {
    /// Start of each bucket in `items`; length = table + 1.
    pub start: Vec<u32>,
    /// Particles sorted by bucket.
    pub items: Vec<u32>,
    /// Bucket of each particle.
    pub bucket: Vec<u32>,
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

    /// 1 / cell width: the scale from positions to cells.
    pub fn inv_cell(&self) -> f32 {
        0.5 / self.radius
    }

    /// An empty grid for this model.
    pub fn grid(&self) -> Grid {
        Grid {
            start: vec![0; self.table + 1],
            items: vec![0; self.garment.len()],
            bucket: vec![0; self.garment.len()],
        }
    }

    /// Integer cell of a position (cells one diameter wide).
    #[inline]
    fn cell_of(&self, p: Vec4) -> [i32; 3] {
        let s = self.inv_cell();
        [
            (p.x * s).floor() as i32,
            (p.y * s).floor() as i32,
            (p.z * s).floor() as i32,
        ]
    }

    #[inline]
    fn bucket_of(&self, c: [i32; 3]) -> usize {
        (super::hash_cell(c) as usize) & (self.table - 1)
    }

    /// Sorts the particles at positions `q` into `grid` (counting sort by bucket).
    pub fn build(&self, q: impl Fn(usize) -> Vec4, grid: &mut Grid) {
        let n = self.garment.len();
        grid.start.fill(0);
        for i in 0..n {
            let b = self.bucket_of(self.cell_of(q(i)));
            grid.bucket[i] = b as u32;
            grid.start[b + 1] += 1;
        }
        for b in 0..self.table {
            grid.start[b + 1] += grid.start[b];
        }
        // Fill from the back of each bucket so particles keep ascending order within it.
        let mut end = grid.start.clone();
        for i in (0..n).rev() {
            let b = grid.bucket[i] as usize;
            end[b + 1] -= 1;
            grid.items[end[b + 1] as usize] = i as u32;
        }
    }

    /// The displacement that moves particle `i` out of the particles it overlaps, from positions
    /// `q` sorted into `grid` and the substep's start positions `x`; zero for a pinned particle.
    /// Each overlap pushes along the pair's separation at the start ([`apart`]) until the two are
    /// a diameter apart along it.
    pub fn push_out(
        &self,
        i: usize,
        x: impl Fn(usize) -> Vec4,
        q: impl Fn(usize) -> Vec4,
        inv_mass: &[f32],
        grid: &Grid,
    ) -> Vec4 {
        let wi = inv_mass[i];
        if wi == 0.0 {
            return Vec4::ZERO;
        }
        let (xi, qi) = (x(i), q(i));
        // Cells are one diameter wide, so every particle closer than a diameter lies in the 2 × 2 × 2
        // block of cells on the sides of the cell that `qi` is nearest to.
        let s = self.inv_cell();
        let scaled = [qi.x * s, qi.y * s, qi.z * s];
        let c = scaled.map(|v| v.floor() as i32);
        let side: [i32; 3] = std::array::from_fn(|a| {
            if scaled[a] - c[a] as f32 >= 0.5 {
                1
            } else {
                -1
            }
        });
        let diameter = 2.0 * self.radius;
        let mut buckets = [usize::MAX; 8];
        let mut seen = 0;
        let mut push = Vec4::ZERO;
        let mut touching = 0u32;
        for corner in 0..8 {
            let cell: [i32; 3] =
                // Wrapping: cells only feed the hash, and a particle flung past i32 cells (a
                // blow-up, caught by the stability rule) must not panic here first.
                std::array::from_fn(|a| {
                    c[a].wrapping_add(if corner >> a & 1 == 1 { side[a] } else { 0 })
                });
            let b = self.bucket_of(cell);
            // Two cells can share a bucket: visit each bucket once.
            if buckets[..seen].contains(&b) {
                continue;
            }
            buckets[seen] = b;
            seen += 1;
            for &j in &grid.items[grid.start[b] as usize..grid.start[b + 1] as usize] {
                let j = j as usize;
                if j == i || self.joined(i, j) {
                    continue;
                }
                let d = qi - q(j);
                let distance = d.length();
                if distance >= diameter || distance < 1e-9 {
                    continue;
                }
                // A diameter apart along the start separation: d projects onto it no longer than
                // `distance`, so this push is never less than the overlap.
                let along = apart(xi - x(j), d, distance);
                let wj = inv_mass[j];
                push += along * ((diameter - d.dot(along)) * wi / (wi + wj));
                touching += 1;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Two free particles of different garments at positions `q`, having started the substep at
    /// `x`: each one's push.
    fn pushes(x: [Vec4; 2], q: [Vec4; 2]) -> [Vec4; 2] {
        let pc = ParticleCollisions {
            radius: 0.01,
            garment: vec![0, 1],
            cell: vec![[0; 3]; 2],
            table: 16,
        };
        let mut grid = pc.grid();
        pc.build(|i| q[i], &mut grid);
        let inv_mass = [1.0, 1.0];
        [0, 1].map(|i| pc.push_out(i, |k| x[k], |k| q[k], &inv_mass, &grid))
    }

    #[test]
    fn a_particle_carried_through_another_goes_back_to_its_own_side() {
        // Particle 0 started 3 cm above particle 1 and the solve carried it to 5 mm below: the
        // pair ends a diameter (2 cm) apart with 0 above, as it started.
        let x = [Vec4::new(0.0, 0.03, 0.0, 0.0), Vec4::ZERO];
        let q = [Vec4::new(0.0, -0.005, 0.0, 0.0), Vec4::ZERO];
        let p = pushes(x, q);
        let apart = (q[0] + p[0]) - (q[1] + p[1]);
        assert!(
            (apart - Vec4::new(0.0, 0.02, 0.0, 0.0)).length() < 1e-6,
            "{apart}"
        );
    }

    #[test]
    fn an_overlap_without_a_crossing_is_pushed_apart_along_the_start_separation() {
        // Closing along x at a slant: they end a diameter apart along where they came from,
        // each moving half of the overlap.
        let x = [Vec4::new(0.05, 0.0, 0.0, 0.0), Vec4::ZERO];
        let q = [Vec4::new(0.012, 0.004, 0.0, 0.0), Vec4::ZERO];
        let p = pushes(x, q);
        assert!(
            (p[0] - Vec4::new(0.004, 0.0, 0.0, 0.0)).length() < 1e-6,
            "{}",
            p[0]
        );
        assert!((p[1] + p[0]).length() < 1e-6, "{}", p[1]);
    }
}
