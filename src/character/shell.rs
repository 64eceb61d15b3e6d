//! Collision particle shells: the body surface covered by particles of radius r, as the Red-Black
//! thesis did for its sitting man.
//!
//! Sampling is Poisson-disk by dart throwing: candidate points are drawn area-uniformly on the
//! triangles (about 40 per final particle, from a fixed seed, so the same mesh always gives the
//! same shell) and accepted when no accepted particle lies within [`SPACING`] × r (a spatial hash
//! answers that).
//!
//! Why the particles overlap (centres at least r apart, not 2r): a random, nearly maximal
//! Poisson-disk sampling at spacing s leaves gaps up to about s from the nearest particle (measured
//! at s = 2r: 95 % of surface points within 1.6 r, the worst 2.2 r). A garment particle touches a
//! shell particle at r plus its own radius, so at s = 2r a thin cloth slipped through those gaps
//! (seen: a poncho fell through the mannequin's shoulders). At s = r every surface point is
//! within about r of a particle, and nothing passes between them.
//!
//! Each particle is bound to its triangle by barycentric coordinates on the first frame, so on a
//! sequence of the same topology it rides the skin: continuous trajectories and velocities.

use glam::Vec3;
use std::collections::HashMap;

/// Particles bound to triangles of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Shell {
    /// Particle radius [m].
    pub radius: f32,
    /// Triangle of each particle.
    pub triangle: Vec<u32>,
    /// Barycentric (u, v) of each particle on its triangle: p = a + u (b − a) + v (c − a).
    pub barycentric: Vec<[f32; 2]>,
}

/// Candidates drawn per particle the surface can hold.
const OVERSAMPLING: f32 = 40.0;

/// Smallest distance between particle centres, in radii.
pub const SPACING: f32 = 1.0;

/// The sampler and its parameters, hashed into shell caches so a changed sampler rebuilds them.
pub const SAMPLER: &str = "dart-throwing spacing 1.0 r, 40 candidates per particle, seed \
     0x05EE_D0FD_4A9E, batches of 2^20 in Morton order of 8-cell tiles above 2^22 candidates, \
     stored in Morton order of their cells";

/// The most particles one shell may hold: about 250 MB of positions per 10 frames, minutes of
/// sampling. A character in centimetres read as metres asks for 10 000 × its real count.
pub const MAX_SHELL_PARTICLES: f64 = 4e6;

/// Particles a nearly maximal dart-throwing sampling holds, per particle disk of the area
/// (random sequential adsorption covers about 55 % of the plane).
const PACKING: f64 = 0.55;

/// Hashes a grid cell with one multiply per coordinate (the sampler looks up 27 cells per
/// candidate, tens of millions of times for a fine shell: SipHash's cost would dominate).
#[derive(Default)]
pub(crate) struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        // Fold the high bits into the low ones, which pick the bucket.
        let z = (self.0 ^ (self.0 >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^ (z >> 32)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_i32(&mut self, v: i32) {
        self.write_u64(v as u32 as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// A map keyed by grid cells, hashed with [`CellHasher`].
pub(crate) type CellMap<V = u32> =
    HashMap<glam::IVec3, V, std::hash::BuildHasherDefault<CellHasher>>;

/// Candidates drawn, sorted and tested together (24 MB of candidates at most).
const BATCH: usize = 1 << 20;

/// Shells drawn from more candidates than this (about 55 000 particles) take each batch in
/// Morton order; smaller ones in draw order.
const SORT_ABOVE: usize = 1 << 22;

/// Candidates are ordered by tiles of 2³ × 2³ × 2³ cells.
const TILE_BITS: i32 = 3;

/// Interleaves the low 21 bits of each (non-negative) coordinate: cells close in space get
/// close codes.
fn morton(c: glam::IVec3) -> u64 {
    fn spread(v: i32) -> u64 {
        let mut x = (v.max(0) as u64) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    }
    spread(c.x) | spread(c.y) << 1 | spread(c.z) << 2
}

/// The 26 cells around a cell.
const NEIGHBOURS: [glam::IVec3; 26] = {
    let mut out = [glam::IVec3::ZERO; 26];
    let mut n = 0;
    let mut i = 0;
    while i < 27 {
        let d = glam::IVec3::new(i / 9 - 1, (i / 3) % 3 - 1, i % 3 - 1);
        if !(d.x == 0 && d.y == 0 && d.z == 0) {
            out[n] = d;
            n += 1;
        }
        i += 1;
    }
    out
};

/// A small deterministic generator (SplitMix64): shells must not change between runs.
struct SplitMix(u64);

impl SplitMix {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn corners(vertices: &[Vec3], t: [u32; 3]) -> [Vec3; 3] {
    t.map(|i| vertices[i as usize])
}

/// Surface area of a mesh [m²] (f64, so a huge mesh does not lose its small triangles).
pub fn surface_area(vertices: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|&t| {
            let [a, b, c] = corners(vertices, t).map(|p| p.as_dvec3());
            0.5 * (b - a).cross(c - a).length()
        })
        .sum()
}

impl Shell {
    /// About how many particles of `radius` [`Shell::sample`] lays on a surface of `area` m²,
    /// known before sampling (within about 10 % of the count).
    pub fn estimate(area: f64, radius: f32) -> f64 {
        let spacing = (SPACING * radius) as f64;
        PACKING * area / (std::f64::consts::FRAC_PI_4 * spacing * spacing)
    }

    /// Ok when a shell of `radius` on a surface of `area` m² over `frames` frames is within
    /// [`MAX_SHELL_PARTICLES`] and this machine's memory; else the reason, which names `radius`
    /// and `scale` (the two settings that change the count).
    pub fn check_size(area: f64, radius: f32, frames: usize) -> std::result::Result<(), String> {
        let count = Shell::estimate(area, radius);
        if !count.is_finite() || count > MAX_SHELL_PARTICLES {
            return Err(format!(
                "a shell of radius {radius} m on {area:.3e} m² of surface needs about {count:.2e} \
                 particles, more than drape's limit of {MAX_SHELL_PARTICLES:.0e}: raise `radius`, \
                 or set `scale` if the file is not in metres"
            ));
        }
        // Positions and normals of every particle on every frame.
        crate::limits::fits_in_memory((count * 24.0 * frames as f64) as u64).map_err(|r| {
            format!(
                "a shell of about {count:.0} particles (radius {radius} m) over {frames} frames \
                 would {r}: raise `radius` or bake fewer frames"
            )
        })
    }

    /// Samples the surface (`vertices`, `triangles`) with particles of `radius`.
    ///
    /// Linear in the number of candidates: each lands in a hashed cell one spacing wide and is
    /// tested against the particles of its own cell, then of the neighbouring cells that come
    /// within one spacing of it. Candidates are drawn in batches of [`BATCH`]; past [`SORT_ABOVE`]
    /// candidates each batch is taken in Morton order of tiles of 8³ cells, so consecutive
    /// candidates look at the same cells: a fine shell's table is far larger than the caches,
    /// and random order made the cost per candidate grow with the shell (6 × the particles took
    /// 17 × the time).
    // Long: one dart-throwing loop over a hashed table it owns (draw, order the batch, test
    // the neighbouring cells, accept), then the Morton ordering of what it accepted.
    pub fn sample(vertices: &[Vec3], triangles: &[[u32; 3]], radius: f32) -> Shell {
        let areas: Vec<f32> = triangles
            .iter()
            .map(|&t| {
                let [a, b, c] = corners(vertices, t);
                0.5 * (b - a).cross(c - a).length()
            })
            .collect();
        let total: f32 = areas.iter().sum();
        let mut shell = Shell {
            radius,
            triangle: Vec::new(),
            barycentric: Vec::new(),
        };
        if total <= 0.0 || radius <= 0.0 {
            return shell;
        }
        // Cumulative areas pick a triangle in proportion to its area.
        let mut cumulative = Vec::with_capacity(areas.len());
        let mut acc = 0.0f64;
        for a in &areas {
            acc += *a as f64;
            cumulative.push(acc);
        }
        let spacing = SPACING * radius;
        let capacity = total / (std::f32::consts::PI * 0.25 * spacing * spacing);
        let candidates = (capacity * OVERSAMPLING).ceil() as usize + 16;
        let cell = spacing;
        let key = |p: Vec3| (p / cell).floor().as_ivec3();
        let lowest = vertices
            .iter()
            .fold(glam::IVec3::MAX, |lo, &v| lo.min(key(v)))
            - glam::IVec3::ONE;
        // Cell → its last accepted particle; `next` chains a cell's particles (u32::MAX ends).
        let expected = (capacity as f64 * PACKING) as usize + 16;
        let mut grid = CellMap::with_capacity_and_hasher(expected, Default::default());
        let mut next: Vec<u32> = Vec::with_capacity(expected);
        let mut accepted: Vec<Vec3> = Vec::with_capacity(expected);
        shell.triangle.reserve(expected);
        shell.barycentric.reserve(expected);
        let mut rng = SplitMix(0x05EE_D0FD_4A9E);
        let min2 = cell * cell;
        let mut batch: Vec<(u64, u32, [f32; 2])> = Vec::with_capacity(BATCH.min(candidates));
        let mut drawn = 0;
        while drawn < candidates {
            batch.clear();
            for _ in 0..BATCH.min(candidates - drawn) {
                let pick = rng.next_f32() as f64 * acc;
                let t = cumulative
                    .partition_point(|&c| c <= pick)
                    .min(triangles.len() - 1);
                let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let [a, b, c] = corners(vertices, triangles[t]);
                let cell_of = key(a + (b - a) * u + (c - a) * v) - lowest;
                batch.push((morton(cell_of >> TILE_BITS), t as u32, [u, v]));
            }
            drawn += batch.len();
            // Stable: candidates of one tile keep the random order they were drawn in, so the
            // packing is that of random dart throwing (sorting by cell would sweep a front
            // across the surface and pack 16 % more particles). A shell whose table fits in the
            // caches gains nothing from the order and keeps the plain draw order.
            if candidates > SORT_ABOVE {
                batch.sort_by_key(|c| c.0);
            }
            for &(_, t, [u, v]) in &batch {
                let [a, b, c] = corners(vertices, triangles[t as usize]);
                let p = a + (b - a) * u + (c - a) * v;
                let k = key(p);
                let f = p / cell - k.as_vec3();
                let gap = |d: i32, f: f32| match d {
                    -1 => f,
                    1 => 1.0 - f,
                    _ => 0.0,
                };
                let taken = |cell: glam::IVec3| {
                    let mut j = grid.get(&cell).copied().unwrap_or(u32::MAX);
                    while j != u32::MAX {
                        if accepted[j as usize].distance_squared(p) < min2 {
                            return true;
                        }
                        j = next[j as usize];
                    }
                    false
                };
                let free = !taken(k)
                    && !NEIGHBOURS.iter().any(|&d| {
                        let g = Vec3::new(gap(d.x, f.x), gap(d.y, f.y), gap(d.z, f.z));
                        g.length_squared() < 1.0 && taken(k + d)
                    });
                if free {
                    let index = accepted.len() as u32;
                    next.push(grid.insert(k, index).unwrap_or(u32::MAX));
                    accepted.push(p);
                    shell.triangle.push(t);
                    shell.barycentric.push([u, v]);
                }
            }
        }
        // Stored in Morton order of their cells, not in the random order they were accepted
        // in: the shell particles near a garment particle then sit together in memory (a focus
        // of 2 871 of P's 15 491 particles touched 1 897 of the 2 905 cache lines of each
        // per-particle array; in this order about 540). Ties keep the acceptance order.
        let mut order: Vec<u32> = (0..accepted.len() as u32).collect();
        order.sort_by_key(|&i| morton(key(accepted[i as usize]) - lowest));
        shell.triangle = order.iter().map(|&i| shell.triangle[i as usize]).collect();
        shell.barycentric = order
            .iter()
            .map(|&i| shell.barycentric[i as usize])
            .collect();
        shell
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    /// True when the shell has no particle.
    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty()
    }

    /// Particle positions on a frame of the same topology.
    pub fn positions(&self, vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        self.triangle
            .iter()
            .zip(&self.barycentric)
            .map(|(&t, &[u, v])| {
                let [a, b, c] = corners(vertices, triangles[t as usize]);
                a + (b - a) * u + (c - a) * v
            })
            .collect()
    }

    /// Unit outward normals at the particles on a frame of the same topology: the surface's
    /// smooth normal, area-weighted vertex normals (vertices within 10 µm welded, so seams
    /// do not show) interpolated with the particle's barycentric coordinates. A faceted mesh's
    /// own triangle normals jump by tens of degrees between neighbouring particles, and cloth
    /// pushed out along them is spread apart over every edge.
    pub fn normals(&self, vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        let smooth = crate::mesh::smooth_normals(vertices, triangles);
        self.triangle
            .iter()
            .zip(&self.barycentric)
            .map(|(&t, &b)| particle_normal(vertices, &smooth, triangles[t as usize], b))
            .collect()
    }

    /// Bytes of the binding (triangle and barycentric coordinates), and of positions for
    /// `frames` frames stored as 16-byte vec4s.
    pub fn memory_bytes(&self, frames: usize) -> (usize, usize) {
        (self.len() * 12, self.len() * 16 * frames)
    }
}

/// The normal at barycentric `(u, v)` of triangle `t` from its corners' smooth normals
/// ([`smooth_normals`]); the facet's normal where they cancel, +Y for a degenerate triangle.
/// `shaders/skin.wgsl` computes the same.
pub fn particle_normal(vertices: &[Vec3], smooth: &[Vec3], t: [u32; 3], [u, v]: [f32; 2]) -> Vec3 {
    let [a, b, c] = t.map(|i| smooth[i as usize]);
    let face = {
        let [p, q, r] = corners(vertices, t);
        (q - p).cross(r - p)
    };
    let smooth = a * (1.0 - u - v) + b * u + c * v;
    smooth
        .try_normalize()
        .or_else(|| face.try_normalize())
        .unwrap_or(Vec3::Y)
}
