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

/// Vertices closer than this [m] share a normal (see [`Shell::normals`]).
const WELD: f32 = 1e-5;

/// Candidates drawn per particle the surface can hold.
const OVERSAMPLING: f32 = 40.0;

/// Smallest distance between particle centres, in radii.
pub const SPACING: f32 = 1.0;

/// The sampler and its parameters, hashed into shell caches so a changed sampler rebuilds them.
pub const SAMPLER: &str =
    "dart-throwing spacing 1.0 r, 40 candidates per particle, seed 0x05EE_D0FD_4A9E";

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

impl Shell {
    /// Samples the surface (`vertices`, `triangles`) with particles of `radius`.
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
        let mut grid: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
        let mut accepted: Vec<Vec3> = Vec::new();
        let mut rng = SplitMix(0x05EE_D0FD_4A9E);
        let min2 = cell * cell;
        for _ in 0..candidates {
            let pick = rng.next_f32() as f64 * acc;
            let t = cumulative
                .partition_point(|&c| c <= pick)
                .min(triangles.len() - 1);
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let [a, b, c] = corners(vertices, triangles[t]);
            let p = a + (b - a) * u + (c - a) * v;
            let k = key(p);
            let mut free = true;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = grid.get(&(k + glam::IVec3::new(dx, dy, dz))) {
                            if list
                                .iter()
                                .any(|&j| accepted[j as usize].distance_squared(p) < min2)
                            {
                                free = false;
                                break 'search;
                            }
                        }
                    }
                }
            }
            if free {
                grid.entry(k).or_default().push(accepted.len() as u32);
                accepted.push(p);
                shell.triangle.push(t as u32);
                shell.barycentric.push([u, v]);
            }
        }
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
        // Welded: vertices within the same 10 µm cell (a seam's two copies of a vertex rarely
        // agree to the last bit when a generator computed them from different angles).
        let mut weld: HashMap<[i64; 3], usize> = HashMap::new();
        let slot: Vec<usize> = vertices
            .iter()
            .map(|v| {
                let n = weld.len();
                let cell = (*v / WELD).round().as_dvec3().to_array().map(|c| c as i64);
                *weld.entry(cell).or_insert(n)
            })
            .collect();
        let mut sum = vec![Vec3::ZERO; weld.len()];
        for t in triangles {
            let [a, b, c] = corners(vertices, *t);
            let n = (b - a).cross(c - a);
            for &i in t {
                sum[slot[i as usize]] += n;
            }
        }
        self.triangle
            .iter()
            .zip(&self.barycentric)
            .map(|(&t, &[u, v])| {
                let [a, b, c] = triangles[t as usize].map(|i| sum[slot[i as usize]]);
                let face = {
                    let [p, q, r] = corners(vertices, triangles[t as usize]);
                    (q - p).cross(r - p)
                };
                let smooth = a.normalize_or_zero() * (1.0 - u - v)
                    + b.normalize_or_zero() * u
                    + c.normalize_or_zero() * v;
                smooth
                    .try_normalize()
                    .or_else(|| face.try_normalize())
                    .unwrap_or(Vec3::Y)
            })
            .collect()
    }

    /// Bytes of the binding (triangle and barycentric coordinates), and of positions for
    /// `frames` frames stored as 16-byte vec4s.
    pub fn memory_bytes(&self, frames: usize) -> (usize, usize) {
        (self.len() * 12, self.len() * 16 * frames)
    }
}
