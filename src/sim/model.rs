//! The static part of a simulation: particles, springs and colours of every garment, laid out for
//! the solvers.
//!
//! Particles are stored **colour-sorted**: all particles of colour 0 (of every garment), then colour
//! 1, and so on, each colour contiguous, so a parallel Gauss-Seidel pass over one colour reads and
//! writes one contiguous range (and a GPU dispatch per colour coalesces). Within a colour, particles
//! keep garment and grid order. `storage_of` maps the export order (garments one after another, each
//! in grid order) to storage indices.
//!
//! A small model (at most [`SMALL_MODEL`] particles) is laid out in two domains and a separator
//! ([`super::separator`], [`Domains`]): every colour of its low side, then every colour of its
//! high side, then the separator's particles in colours of their own. The sweep's colour order is
//! each side's colour c (together, on the GPU: [`Model::sweep_colours`]), then the separator's.
//!
//! Springs are kept twice: as a list (`springs`, storage indices, for metrics) and as per-particle
//! adjacency *slots* in compressed rows (`slot_start`), the layout the gather-style solvers read:
//! for particle i, slots `slot_start[i]..slot_start[i+1]` name each neighbour with the spring's
//! rest length and weight.

use super::separator::{self, Side, SMALL_MODEL};
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
    /// A small model's two domains; None for a larger one.
    pub domains: Option<Domains>,
    /// Storage index of each export-order particle.
    pub storage_of: Vec<u32>,
    /// The order in which stages that compute each particle alone share them out
    /// ([`super::team::Member::balanced`]), storage indices: export order, and in a small model
    /// the low side's particles first, then the separator's, then the high side's, so each
    /// thread starts on the particles its Gauss-Seidel sweep updates.
    pub work_order: Vec<u32>,
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

/// A small model's layout for two threads ([`super::separator`]): its first `colours` colour
/// ranges hold the low side, colour by colour (some may be empty), the next `colours` the high
/// side, and the rest the separator, which no spring joins to both sides. Each side is stored
/// apart, so the two threads that sweep them write different cache lines.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Domains {
    pub colours: usize,
}

impl Domains {
    /// The colour ranges of `side` (0 low, 1 high) among `ranges` (the model's).
    pub fn side<'r>(&self, ranges: &'r [Range<usize>], side: usize) -> &'r [Range<usize>] {
        &ranges[side * self.colours..(side + 1) * self.colours]
    }

    /// The separator's colour ranges among `ranges`.
    pub fn separator<'r>(&self, ranges: &'r [Range<usize>]) -> &'r [Range<usize>] {
        &ranges[2 * self.colours..]
    }

    /// The thread whose sweeps update colour range `k`: 1 for the high side, else 0.
    pub fn owner(&self, k: usize) -> usize {
        usize::from((self.colours..2 * self.colours).contains(&k))
    }
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
        let small = garments.iter().map(|g| g.particle_count()).sum::<usize>() <= SMALL_MODEL
            && colours <= separator::MAX_COLOURS;
        // Export order: garments one after another. Bucket every particle by colour, and in a
        // small model by side too: [low, high, separator] per colour.
        let mut buckets: Vec<[Vec<usize>; 3]> = vec![Default::default(); colours];
        let mut offset = 0;
        let mut ranges = Vec::new();
        // Export-order particles by part: low side, high side, separator.
        let mut parts: [Vec<usize>; 3] = Default::default();
        for g in garments {
            let sides = if small {
                separator::sides(g)
            } else {
                vec![Side::Low; g.particle_count()]
            };
            for (k, side) in sides.into_iter().enumerate() {
                let part = match side {
                    Side::Low => 0,
                    Side::High => 1,
                    Side::Separator => 2,
                };
                buckets[g.colour_of(k as u32) as usize][part].push(offset + k);
                parts[part].push(offset + k);
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
        // Colour by colour (every colour, even empty): every particle of a large model; in a
        // small one the low side's, then the high side's, then the separator's (its colours
        // that have particles).
        for (part, keep_empty) in [(0, true), (1, small), (2, false)] {
            for bucket in buckets.iter().map(|b| &b[part]) {
                if bucket.is_empty() && !keep_empty {
                    continue;
                }
                colour_ranges.push(next..next + bucket.len());
                for &e in bucket {
                    storage_of[e] = next as u32;
                    next += 1;
                }
            }
        }
        let domains = small.then_some(Domains { colours });
        let [low, high, separator] = parts;
        let work_order = (low.into_iter().chain(separator).chain(high))
            .map(|e| storage_of[e])
            .collect();
        let mut model = Model {
            mass: vec![0.0; n],
            inv_mass: vec![0.0; n],
            contact_radius: vec![0.0; n],
            colour_ranges,
            domains,
            storage_of,
            work_order,
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
        // Structural springs first, so metrics read one prefix; in a model of two domains, the
        // springs the low side's thread projects before those of the high side's, so the two
        // threads write different cache lines; then in storage order of their first particle, so
        // a thread's share of springs covers the particles it updates.
        let high = self.high_side();
        springs.sort_by_key(|(family, s, _)| {
            let side = high[s.a as usize] || high[s.b as usize];
            (
                *family != SpringFamily::Stretch,
                side,
                s.a.min(s.b),
                s.a.max(s.b),
            )
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

    /// FNV-1a of the storage order (each export-order particle's storage index) and the colour
    /// ranges: states of one layout fit only models of that layout (checkpoints).
    pub fn layout(&self) -> u64 {
        use crate::character::cache::{fnv, FNV_OFFSET};
        let ranges: Vec<u32> = (self.colour_ranges.iter())
            .flat_map(|r| [r.start as u32, r.end as u32])
            .collect();
        let h = fnv(FNV_OFFSET, bytemuck::cast_slice(&self.storage_of));
        fnv(h, bytemuck::cast_slice(&ranges))
    }

    /// Per particle (storage order), whether it is in a small model's high domain (all false in
    /// a larger model).
    pub fn high_side(&self) -> Vec<bool> {
        self.side_of(1)
    }

    /// Per particle, whether it is on `side` (0 low, 1 high) of a model in two domains (all
    /// false in one domain).
    pub fn side_of(&self, side: usize) -> Vec<bool> {
        let mut on = vec![false; self.particle_count()];
        if let Some(d) = &self.domains {
            for r in d.side(&self.colour_ranges, side) {
                on[r.clone()].fill(true);
            }
        }
        on
    }

    /// The colours of a sweep, in order, as the GPU dispatches them: each colour's particles in
    /// one range or, in a small model, two (its low and high sides; either may be empty). A
    /// small model's separator follows them ([`Self::separator_colours`]).
    pub fn sweep_colours(&self) -> Vec<[Range<usize>; 2]> {
        let ranges = &self.colour_ranges;
        match self.domains {
            Some(d) => (d.side(ranges, 0).iter().zip(d.side(ranges, 1)))
                .map(|(low, high)| [low.clone(), high.clone()])
                .collect(),
            None => ranges.iter().map(|r| [r.clone(), r.end..r.end]).collect(),
        }
    }

    /// A small model's separator colours, swept after [`Self::sweep_colours`] (none in a
    /// larger model).
    pub fn separator_colours(&self) -> &[Range<usize>] {
        match self.domains {
            Some(d) => d.separator(&self.colour_ranges),
            None => &[],
        }
    }

    /// Thread `index`'s particles in a team of `count`, for stages that compute each particle
    /// alone at about the same cost: the particles its Gauss-Seidel sweeps update, so their data
    /// stays in that core's cache. In a small model on two or more threads, thread 0 has the low
    /// side and the separator, thread 1 the high side; else every thread has its share of every
    /// colour (a colour is stored in grid order, so that is the same region of the cloth in each).
    pub fn particles_of(
        &self,
        index: usize,
        count: usize,
    ) -> impl Iterator<Item = usize> + Clone + '_ {
        let domains = self.domains.filter(|_| count > 1);
        (self.colour_ranges.iter().enumerate()).flat_map(move |(k, r)| match domains {
            Some(d) if d.owner(k) == index => r.clone(),
            Some(_) => r.start..r.start,
            None => {
                let len = r.end - r.start;
                r.start + len * index / count..r.start + len * (index + 1) / count
            }
        })
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
        if let Some(d) = &self.domains {
            assert!(2 * d.colours <= self.colour_ranges.len(), "model: domains");
            // Sides 0 and 1 are the domains, 2 the separator: only 0 + 1 makes 1.
            let mut side = vec![2u8; n];
            for s in 0..2 {
                for r in d.side(&self.colour_ranges, s) {
                    side[r.clone()].fill(s as u8);
                }
            }
            assert!(
                (self.springs.iter()).all(|s| side[s.a as usize] + side[s.b as usize] != 1),
                "model: a spring joins the two domains"
            );
        }
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
