//! The static part of a simulation: particles, springs and colours of every garment, laid out for
//! the solvers.
//!
//! Particles are stored **colour-sorted**: all particles of colour 0 (of every garment), then colour
//! 1, and so on, each colour contiguous, so a parallel Gauss-Seidel pass over one colour reads and
//! writes one contiguous range (and a GPU dispatch per colour coalesces). Within a colour, particles
//! keep garment and grid order. `storage_of` maps the export order (garments one after another, each
//! in grid order) to storage indices.
//!
//! Springs are kept twice: as a list (`springs`, storage indices, for metrics) and as per-particle
//! adjacency *slots* in compressed rows (`slot_start`), the layout the gather-style solvers read:
//! for particle i, slots `slot_start[i]..slot_start[i+1]` name each neighbour with the spring's
//! rest length and weight.

use crate::garment::{Garment, SpringFamily};
use std::ops::Range;

/// A spring in storage indices: the 12 bytes the local step reads per spring.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ModelSpring {
    pub a: u32,
    pub b: u32,
    /// Rest length [m].
    pub rest: f32,
}

const _: () = assert!(std::mem::size_of::<ModelSpring>() == 12);

/// A long-range attachment in storage indices (12 bytes): `particle` stays within `rest` of `pin`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ModelTether {
    pub particle: u32,
    pub pin: u32,
    /// Rest distance [m].
    pub rest: f32,
}

/// One spring seen from one of its particles: 12 bytes, read by every gather-style solver.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Slot {
    /// The other particle (storage index).
    pub neighbour: u32,
    /// Index of the spring in `Model::springs`, with [`Slot::B_END`] set when this particle is
    /// the spring's `b` end (it then sees the spring's projection with the opposite sign).
    pub spring: u32,
    /// Projective Dynamics weight [N/m].
    pub weight: f32,
}

impl Slot {
    /// Flag in `spring` marking the `b` end.
    pub const B_END: u32 = 1 << 31;

    /// The spring's index.
    #[inline(always)]
    pub fn spring_index(&self) -> usize {
        (self.spring & !Slot::B_END) as usize
    }

    /// +1 at the spring's `a` end, −1 at its `b` end (the flag is the float sign bit).
    #[inline(always)]
    pub fn sign(&self) -> f32 {
        f32::from_bits(1.0f32.to_bits() | (self.spring & Slot::B_END))
    }
}

const _: () = assert!(std::mem::size_of::<Slot>() == 12);

/// Where one garment's particles live in export order, and its mesh.
#[derive(Clone, Debug)]
pub struct GarmentRange {
    pub name: String,
    /// Export-order indices of this garment's particles.
    pub export: Range<usize>,
    pub dims: [u32; 3],
    /// Triangles of the exported surface: garment-local grid indices, or vertices of
    /// `embedding` for a mesh garment.
    pub triangles: Vec<[u32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    /// A mesh garment's surface, carried by its particles.
    pub embedding: Option<std::sync::Arc<crate::garment::Embedding>>,
    pub colours: u32,
    pub stretch_springs: usize,
    pub shear_springs: usize,
    pub bend_springs: usize,
    /// Colour in exports and previews, linear RGB.
    pub colour: [f32; 3],
}

impl GarmentRange {
    /// The exported surface's vertices from this garment's particles (grid order): the
    /// particles themselves, or a mesh garment's embedded vertices.
    pub fn surface(&self, particles: &[glam::Vec3]) -> Vec<glam::Vec3> {
        match &self.embedding {
            Some(e) => e.apply(particles),
            None => particles.to_vec(),
        }
    }
}

/// Static simulation data (everything but positions), in storage order.
#[derive(Clone, Debug, Default)]
pub struct Model {
    /// Particle mass [kg]; pinned particles keep their mass but never move.
    pub mass: Vec<f32>,
    /// 1 / mass, or 0 for pinned particles.
    pub inv_mass: Vec<f32>,
    /// Distance kept from collider surfaces [m].
    pub contact_radius: Vec<f32>,
    /// Storage range of each colour.
    pub colour_ranges: Vec<Range<usize>>,
    /// Storage index of each export-order particle.
    pub storage_of: Vec<u32>,
    /// Start of each particle's slots; length = particles + 1.
    pub slot_start: Vec<u32>,
    /// Every particle's springs as seen from that particle, rows one after another.
    pub slot: Vec<Slot>,
    /// All springs, storage indices; the structural ones first.
    pub springs: Vec<ModelSpring>,
    /// Weight [N/m] of each spring.
    pub spring_weight: Vec<f32>,
    /// Number of structural (stretch) springs at the head of `springs`.
    pub structural_springs: usize,
    pub garments: Vec<GarmentRange>,
    /// Long-range attachments, sorted by particle so a particle's tethers are adjacent.
    pub tethers: Vec<ModelTether>,
    /// Start of each particle's tethers in `tethers`; length = particles + 1.
    pub tether_start: Vec<u32>,
    /// The lattice's cell corners, storage indices `[corner, a, b]`: two structural springs
    /// from one particle along different lattice axes, square at rest (the shear metric).
    pub corners: Vec<[u32; 3]>,
}

/// Every garment's cell corners, storage indices.
fn lattice_corners(garments: &[Garment], model: &Model) -> Vec<[u32; 3]> {
    garments
        .iter()
        .zip(&model.garments)
        .flat_map(|(g, range)| {
            let storage = &model.storage_of[range.export.clone()];
            corners(g)
                .into_iter()
                .map(move |c| c.map(|p| storage[p as usize]))
        })
        .collect()
}

/// `garment`'s cell corners (grid order): at each particle, every two of its structural
/// springs along different lattice axes.
fn corners(garment: &Garment) -> Vec<[u32; 3]> {
    let mut arms: Vec<Vec<(u32, usize)>> = vec![Vec::new(); garment.particle_count()];
    for s in garment
        .springs
        .iter()
        .filter(|s| s.family == SpringFamily::Stretch)
    {
        let (ca, cb) = (garment.cells[s.a as usize], garment.cells[s.b as usize]);
        let Some(axis) = (0..3).find(|&k| ca[k] != cb[k]) else {
            continue;
        };
        arms[s.a as usize].push((s.b, axis));
        arms[s.b as usize].push((s.a, axis));
    }
    let mut out = Vec::new();
    for (c, arms) in arms.iter().enumerate() {
        for (i, &(a, axis_a)) in arms.iter().enumerate() {
            for &(b, axis_b) in &arms[i + 1..] {
                if axis_a != axis_b {
                    out.push([c as u32, a, b]);
                }
            }
        }
    }
    out
}

impl Model {
    /// Lays out garments for the solvers.
    pub fn new(garments: &[Garment]) -> Model {
        let colours = garments.iter().map(|g| g.colour_count()).max().unwrap_or(1) as usize;
        // Export order: garments one after another. Bucket every particle by colour.
        let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); colours];
        let mut offset = 0;
        let mut ranges = Vec::new();
        for g in garments {
            for k in 0..g.particle_count() {
                buckets[g.colour_of(k as u32) as usize].push(offset + k);
            }
            ranges.push(GarmentRange {
                name: g.name.clone(),
                export: offset..offset + g.particle_count(),
                dims: g.dims,
                triangles: g.triangles.clone(),
                uvs: g.uvs.clone(),
                embedding: g.embedding.clone(),
                colours: g.colour_count(),
                stretch_springs: g.spring_count(SpringFamily::Stretch),
                shear_springs: g.spring_count(SpringFamily::Shear),
                bend_springs: g.spring_count(SpringFamily::Bend),
                colour: g.colour,
            });
            offset += g.particle_count();
        }
        let n = offset;
        let mut storage_of = vec![0u32; n];
        let mut colour_ranges = Vec::with_capacity(colours);
        let mut next = 0usize;
        for bucket in &buckets {
            colour_ranges.push(next..next + bucket.len());
            for &e in bucket {
                storage_of[e] = next as u32;
                next += 1;
            }
        }

        let mut model = Model {
            mass: vec![0.0; n],
            inv_mass: vec![0.0; n],
            contact_radius: vec![0.0; n],
            colour_ranges,
            storage_of,
            garments: ranges,
            ..Model::default()
        };
        let mut springs = Vec::new();
        for (g, range) in garments.iter().zip(&model.garments) {
            let base = range.export.start;
            for k in 0..g.particle_count() {
                let s = model.storage_of[base + k] as usize;
                model.mass[s] = g.particle_mass;
                model.inv_mass[s] = 1.0 / g.particle_mass;
                model.contact_radius[s] = g.contact_radius;
            }
            for &p in &g.pins {
                model.inv_mass[model.storage_of[base + p as usize] as usize] = 0.0;
            }
            for t in &g.tethers {
                model.tethers.push(ModelTether {
                    particle: model.storage_of[base + t.particle as usize],
                    pin: model.storage_of[base + t.pin as usize],
                    rest: t.rest,
                });
            }
            for s in &g.springs {
                let spring = ModelSpring {
                    a: model.storage_of[base + s.a as usize],
                    b: model.storage_of[base + s.b as usize],
                    rest: s.rest,
                };
                springs.push((s.family, spring, s.weight));
            }
        }
        model.corners = lattice_corners(garments, &model);
        model.set_springs(springs);
        model
    }

    /// Takes `springs` (family, spring, weight): structural ones first, the adjacency slots
    /// and the tethers' index built from them.
    fn set_springs(&mut self, mut springs: Vec<(SpringFamily, ModelSpring, f32)>) {
        let n = self.mass.len();
        // Structural springs first, so metrics read one prefix; then in storage order of their
        // first particle, so a thread's share of springs covers the particles it updates.
        springs.sort_by_key(|(family, s, _)| {
            (*family != SpringFamily::Stretch, s.a.min(s.b), s.a.max(s.b))
        });
        self.structural_springs = springs
            .iter()
            .filter(|(family, _, _)| *family == SpringFamily::Stretch)
            .count();
        self.spring_weight = springs.iter().map(|s| s.2).collect();
        self.springs = springs.into_iter().map(|s| s.1).collect();
        self.build_slots();
        self.tethers.sort_by_key(|t| (t.particle, t.pin));
        self.tether_start = vec![0; n + 1];
        for t in &self.tethers {
            self.tether_start[t.particle as usize + 1] += 1;
        }
        for i in 0..n {
            self.tether_start[i + 1] += self.tether_start[i];
        }
    }

    /// Compressed per-particle adjacency from the spring list; slots of a particle are ordered by
    /// neighbour index so every solver visits them the same way.
    fn build_slots(&mut self) {
        let n = self.mass.len();
        let mut rows: Vec<Vec<Slot>> = vec![Vec::new(); n];
        for (c, s) in self.springs.iter().enumerate() {
            let (spring, weight) = (c as u32, self.spring_weight[c]);
            rows[s.a as usize].push(Slot {
                neighbour: s.b,
                spring,
                weight,
            });
            rows[s.b as usize].push(Slot {
                neighbour: s.a,
                spring: spring | Slot::B_END,
                weight,
            });
        }
        self.slot_start = Vec::with_capacity(n + 1);
        self.slot_start.push(0);
        for row in &mut rows {
            row.sort_by_key(|r| r.neighbour);
            self.slot.extend_from_slice(row);
            self.slot_start.push(self.slot.len() as u32);
        }
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.mass.len()
    }

    /// The slots (springs) of particle `i`.
    #[inline(always)]
    pub fn slots(&self, i: usize) -> &[Slot] {
        &self.slot[self.slot_start[i] as usize..self.slot_start[i + 1] as usize]
    }

    /// Checks every index invariant the solvers' unchecked loops rely on: colour ranges partition
    /// the particles, slot rows are well formed, and every particle, neighbour, spring, pin and
    /// tether index is in range. Panics with the broken invariant (a bug in drape, not bad input).
    pub fn validate(&self) {
        let n = self.particle_count();
        let per_particle = [
            ("inv_mass", self.inv_mass.len()),
            ("contact_radius", self.contact_radius.len()),
            ("storage_of", self.storage_of.len()),
        ];
        for (name, len) in per_particle {
            assert_eq!(len, n, "model: {name} has {len} entries for {n} particles");
        }
        let mut next = 0;
        for r in &self.colour_ranges {
            assert_eq!(r.start, next, "model: colour ranges must be contiguous");
            next = r.end;
        }
        assert_eq!(next, n, "model: colour ranges must cover every particle");
        assert!(
            self.storage_of.iter().all(|&s| (s as usize) < n),
            "model: storage_of out of range"
        );
        assert_eq!(self.slot_start.len(), n + 1, "model: slot_start length");
        assert!(
            self.slot_start.windows(2).all(|w| w[0] <= w[1]),
            "model: slot rows overlap"
        );
        assert_eq!(
            self.slot_start[n] as usize,
            self.slot.len(),
            "model: slot rows length"
        );
        let springs = self.springs.len();
        assert_eq!(self.spring_weight.len(), springs, "model: spring weights");
        assert!(
            self.springs
                .iter()
                .all(|s| (s.a as usize) < n && (s.b as usize) < n),
            "model: spring end out of range"
        );
        assert!(
            self.slot
                .iter()
                .all(|s| (s.neighbour as usize) < n && s.spring_index() < springs),
            "model: slot out of range"
        );
        assert_eq!(self.tether_start.len(), n + 1, "model: tether_start length");
        assert!(
            self.tether_start.windows(2).all(|w| w[0] <= w[1]),
            "model: tether rows overlap"
        );
        assert_eq!(
            self.tether_start[n] as usize,
            self.tethers.len(),
            "model: tether rows length"
        );
        assert!(
            self.tethers
                .iter()
                .all(|t| (t.particle as usize) < n && (t.pin as usize) < n),
            "model: tether out of range"
        );
        assert!(
            self.tethers
                .iter()
                .all(|t| self.inv_mass[t.pin as usize] == 0.0),
            "model: a tether must end at a pinned particle"
        );
    }

    /// True when no spring joins two particles of the same colour (what parallel Gauss-Seidel
    /// relies on); returns the first offending spring otherwise.
    pub fn check_colouring(&self) -> Result<(), ModelSpring> {
        let mut colour = vec![0usize; self.particle_count()];
        for (c, r) in self.colour_ranges.iter().enumerate() {
            colour[r.clone()].fill(c);
        }
        match self
            .springs
            .iter()
            .find(|s| colour[s.a as usize] == colour[s.b as usize])
        {
            Some(s) => Err(*s),
            None => Ok(()),
        }
    }

    /// Bytes the CPU solver holds for this model and its state (for `drape inspect`).
    pub fn memory_bytes(&self) -> usize {
        let n = self.particle_count();
        let slots = self.slot.len();
        // positions, previous, target, Jacobi buffer: one 16-byte vec4 each; mass, inverse mass,
        // inertia, contact radius, diagonal, slot and tether starts: 4 bytes each; per spring its
        // description and its projection (16 bytes).
        n * (4 * 16 + 7 * 4)
            + slots * std::mem::size_of::<Slot>()
            + self.springs.len() * (std::mem::size_of::<ModelSpring>() + 4 + 16)
            + self.tethers.len() * 12
    }
}
