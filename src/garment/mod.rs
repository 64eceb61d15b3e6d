//! Garments: particles on a regular lattice (the voxel grid of the Red-Black thesis) joined by
//! springs from a [`Stencil`], coloured for parallel Gauss-Seidel by a [`Colouring`].
//!
//! A garment is built in *grid order*: particle k sits at lattice cell k with x varying fastest.
//! That order is the one exports and reports use; the solver keeps its own colour-sorted order
//! (see `sim::model`).

pub mod advice;
pub mod coloring;
pub mod stencil;
pub mod voxel;

pub use coloring::Colouring;
pub use stencil::{SpringFamily, Stencil};

use crate::scene::{GarmentKind, GarmentSpec, ParticleSelection};
use glam::{EulerRot, Mat3, Vec3};
use std::sync::Arc;

/// A spring between two particles of one garment (grid-order indices).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    pub a: u32,
    pub b: u32,
    /// Rest length [m].
    pub rest: f32,
    /// Projective Dynamics weight [N/m].
    pub weight: f32,
    pub family: SpringFamily,
}

/// A garment ready to simulate: particles in grid order, springs, colours, pins and mesh faces.
#[derive(Clone, Debug)]
pub struct Garment {
    pub name: String,
    /// Particles per lattice axis (unused axes are 1).
    pub dims: [u32; 3],
    /// Lattice cell of each particle (grid order; cells in a hole have no particle).
    pub cells: Vec<[u32; 3]>,
    /// Start positions [m], grid order.
    pub positions: Vec<Vec3>,
    /// Mass of each particle [kg].
    pub particle_mass: f32,
    /// Grid-order indices of pinned particles (sorted, unique).
    pub pins: Vec<u32>,
    pub springs: Vec<Spring>,
    pub stencil: Stencil,
    pub colouring: Colouring,
    /// Triangles of the exported surface: over the particles (grid order; counter-clockwise
    /// seen from a sheet's local +Y), or over the vertices of `embedding` for a mesh garment.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates, one per particle (or per embedded vertex).
    pub uvs: Vec<[f32; 2]>,
    /// A mesh garment's own surface, carried by the particles around each vertex.
    pub embedding: Option<Arc<Embedding>>,
    /// Half the cloth thickness [m]: the distance kept from collider surfaces.
    pub contact_radius: f32,
    /// Long-range attachments: (particle, pin, rest distance), grid-order indices.
    pub tethers: Vec<Tether>,
    /// Colour in exports and previews, linear RGB.
    pub colour: [f32; 3],
    /// The particles of each of the spec's attachments (grid-order indices; also pinned).
    pub attached: Vec<Vec<u32>>,
    /// A mesh garment's mesh as placed and voxelized.
    pub source: Option<Arc<voxel::PlacedMesh>>,
}

pub use crate::scene::{MESH_REGIONS, REGIONS};

/// Vertices as weighted sums of particles (compressed rows): vertex v is
/// Σ weight[k] · particle[particle[k]] for k in start[v]..start[v + 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Embedding {
    pub start: Vec<u32>,
    pub particle: Vec<u32>,
    pub weight: Vec<f32>,
}

impl Embedding {
    /// Number of embedded vertices.
    pub fn vertex_count(&self) -> usize {
        self.start.len() - 1
    }

    /// The embedded vertices for particle positions `particles` (grid order).
    pub fn apply(&self, particles: &[Vec3]) -> Vec<Vec3> {
        self.start
            .windows(2)
            .map(|r| {
                (r[0] as usize..r[1] as usize)
                    .map(|k| particles[self.particle[k] as usize] * self.weight[k])
                    .sum()
            })
            .collect()
    }
}

/// Garment colours by index when a scene gives none: cloth-like, distinct, not too saturated.
pub const PALETTE: [[f32; 3]; 6] = [
    [0.70, 0.18, 0.16],
    [0.16, 0.36, 0.66],
    [0.85, 0.62, 0.15],
    [0.22, 0.52, 0.30],
    [0.50, 0.28, 0.58],
    [0.80, 0.80, 0.76],
];

/// A long-range attachment: `particle` may be no farther than `rest` from pinned particle `pin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tether {
    pub particle: u32,
    pub pin: u32,
    /// Rest distance [m]: the straight-line distance in the flat rest shape, which is the
    /// geodesic distance for sheets and ropes.
    pub rest: f32,
}

/// Most tethers per particle: its nearest pins.
pub const TETHERS_PER_PARTICLE: usize = 2;

impl Garment {
    /// Builds a sheet or rope from its scene spec (validated before).
    ///
    /// # Panics
    /// For a mesh garment, which needs its mesh read: [`build_all`] reads it, or
    /// [`Garment::voxelized`] takes it placed.
    pub fn build(name: String, spec: &GarmentSpec) -> Garment {
        let dims = match spec.kind {
            GarmentKind::Sheet => [spec.resolution[0], spec.resolution[1], 1],
            GarmentKind::Rope => [spec.resolution[0], 1, 1],
            GarmentKind::Mesh => panic!("a mesh garment is built from its placed mesh: build_all"),
        };
        let size = spec.size();
        let spacing: Vec<f32> = (0..size.len())
            .map(|a| size[a] / (spec.resolution[a] - 1) as f32)
            .collect();
        let count = dims.iter().product::<u32>() as usize;
        let rotation = rotation_of(spec.rotation);
        let centre = Vec3::from(spec.position);
        let mut positions = Vec::with_capacity(count);
        let mut uvs = Vec::with_capacity(count);
        for k in 0..count as u32 {
            let [x, y, _] = cell_of(dims, k);
            let u = x as f32 / (dims[0] - 1) as f32;
            let v = if dims[1] > 1 {
                y as f32 / (dims[1] - 1) as f32
            } else {
                0.0
            };
            // Local frame: grid axis 0 along +X, grid axis 1 along +Z (a horizontal sheet).
            let local = Vec3::new(
                (u - 0.5) * size[0],
                0.0,
                if dims[1] > 1 {
                    (v - 0.5) * size[1]
                } else {
                    0.0
                },
            );
            positions.push(centre + rotation * (local * spec.initial_stretch));
            uvs.push([u, v]);
        }
        let (stencil, colouring, pins) = lattice(dims, spec);
        let springs = build_springs(dims, &stencil, &spacing, &spec.stiffness);
        let mut garment = Garment {
            name,
            dims,
            cells: (0..count as u32).map(|k| cell_of(dims, k)).collect(),
            positions,
            particle_mass: 0.0,
            pins,
            springs,
            stencil,
            colouring,
            triangles: sheet_triangles(dims),
            uvs,
            embedding: None,
            contact_radius: spec.thickness * 0.5,
            tethers: Vec::new(),
            colour: spec.colour.unwrap_or(PALETTE[0]),
            attached: Vec::new(),
            source: None,
        };
        if spec.hole_radius > 0.0 {
            let size = [size[0], size.get(1).copied().unwrap_or(0.0)];
            let keep: Vec<bool> = garment
                .uvs
                .iter()
                .map(|[u, v]| ((u - 0.5) * size[0]).hypot((v - 0.5) * size[1]) > spec.hole_radius)
                .collect();
            garment.keep(&keep);
        }
        garment.finish(spec);
        if spec.tethers {
            let rest: Vec<Vec3> = garment
                .cells
                .iter()
                .map(|c| {
                    Vec3::new(
                        c[0] as f32 * spacing[0],
                        c[1] as f32 * spacing.get(1).copied().unwrap_or(0.0),
                        0.0,
                    )
                })
                .collect();
            garment.tethers = build_tethers(&rest, &garment.pins);
        }
        garment
    }

    /// A voxelized mesh garment: particles at the occupied cells of `placed`, axis (and shear,
    /// bend) springs between them, the mesh's own surface embedded for export.
    pub fn voxelized(name: String, spec: &GarmentSpec, placed: Arc<voxel::PlacedMesh>) -> Garment {
        let voxels = &placed.voxels;
        let dims = voxels.dims;
        let count = dims.iter().product::<u32>() as usize;
        let h = voxels.spacing;
        let (stencil, colouring, pins) = lattice(dims, spec);
        let cells: Vec<[u32; 3]> = (0..count as u32).map(|k| cell_of(dims, k)).collect();
        let mut garment = Garment {
            name,
            dims,
            positions: cells.iter().map(|&c| voxels.centre(c)).collect(),
            cells,
            particle_mass: 0.0,
            pins,
            springs: build_springs(dims, &stencil, &[h, h, h], &spec.stiffness),
            stencil,
            colouring,
            triangles: Vec::new(),
            uvs: Vec::new(),
            embedding: None,
            contact_radius: spec.thickness * 0.5,
            tethers: Vec::new(),
            colour: spec.colour.unwrap_or(PALETTE[0]),
            attached: Vec::new(),
            source: None,
        };
        garment.keep(&voxels.occupied);
        // Dense cell → particle, now that the empty cells are gone.
        let mut particle_of = vec![u32::MAX; count];
        for (i, c) in garment.cells.iter().enumerate() {
            particle_of[index_of(dims, *c) as usize] = i as u32;
        }
        let mut embedding = Embedding {
            start: vec![0],
            particle: Vec::new(),
            weight: Vec::new(),
        };
        for &v in &placed.vertices {
            for (cell, w) in voxels.embed(v) {
                embedding.particle.push(particle_of[cell]);
                embedding.weight.push(w);
            }
            embedding.start.push(embedding.particle.len() as u32);
        }
        garment.triangles = placed.triangles.clone();
        garment.uvs = placed.uvs.clone();
        garment.embedding = Some(Arc::new(embedding));
        garment.source = Some(placed.clone());
        garment.finish(spec);
        if spec.tethers {
            garment.tethers = lattice_tethers(&garment);
        }
        garment
    }

    /// Spreads the mass and pins the attached particles.
    fn finish(&mut self, spec: &GarmentSpec) {
        self.particle_mass = spec.mass / self.particle_count() as f32;
        self.attached = spec
            .attachments
            .iter()
            .map(|a| self.select(&a.particles))
            .collect();
        self.pins.extend(self.attached.iter().flatten().copied());
        self.pins.sort_unstable();
        self.pins.dedup();
    }

    /// The particles a selection names (grid order, sorted): a region of [`REGIONS`] or grid
    /// coordinates (negative from the end; cells cut away by a hole are skipped).
    pub fn select(&self, selection: &ParticleSelection) -> Vec<u32> {
        // Cell → particle, for the whole lattice (cells cut away map to none).
        let mut dense = vec![u32::MAX; self.dims.iter().product::<u32>() as usize];
        for (i, c) in self.cells.iter().enumerate() {
            dense[index_of(self.dims, *c) as usize] = i as u32;
        }
        let index_of_cell = |cell: [u32; 3]| {
            Some(dense[index_of(self.dims, cell) as usize]).filter(|&i| i != u32::MAX)
        };
        let mut out: Vec<u32> = match selection {
            ParticleSelection::Cells(cells) => cells
                .iter()
                .filter_map(|c| index_of_cell(resolve_cell(self.dims, c)))
                .collect(),
            ParticleSelection::Near(n) => {
                let point = Vec3::from(n.near);
                (0..self.positions.len() as u32)
                    .filter(|&i| self.positions[i as usize].distance(point) <= n.radius)
                    .collect()
            }
            ParticleSelection::Region(region) => {
                let n = self.positions.len() as u32;
                let ys = || self.positions.iter().map(|p| p.y);
                let (top, bottom) = (ys().fold(f32::MIN, f32::max), ys().fold(f32::MAX, f32::min));
                let last = |a: usize| self.dims[a].saturating_sub(1);
                match region.as_str() {
                    "top_edge" => (0..n)
                        .filter(|&i| self.positions[i as usize].y >= top - 1e-4)
                        .collect(),
                    "bottom_edge" => (0..n)
                        .filter(|&i| self.positions[i as usize].y <= bottom + 1e-4)
                        .collect(),
                    "corners" => (0..n)
                        .filter(|&i| {
                            let c = self.cells[i as usize];
                            (0..3)
                                .filter(|&a| self.dims[a] > 1)
                                .all(|a| c[a] == 0 || c[a] == last(a))
                        })
                        .collect(),
                    // "hole_rim": inside the grid, but an axis neighbour was cut away.
                    _ => (0..n)
                        .filter(|&i| {
                            let c = self.cells[i as usize];
                            (0..3).filter(|&a| self.dims[a] > 1).any(|a| {
                                [-1i64, 1].iter().any(|&step| {
                                    let v = c[a] as i64 + step;
                                    if v < 0 || v > last(a) as i64 {
                                        return false;
                                    }
                                    let mut neighbour = c;
                                    neighbour[a] = v as u32;
                                    index_of_cell(neighbour).is_none()
                                })
                            })
                        })
                        .collect(),
                }
            }
        };
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Removes the particles whose `keep` is false (a hole), with their springs, triangles and
    /// pins; the rest keep grid order.
    fn keep(&mut self, keep: &[bool]) {
        let mut index = vec![u32::MAX; keep.len()];
        let mut next = 0u32;
        for (k, &kept) in keep.iter().enumerate() {
            if kept {
                index[k] = next;
                next += 1;
            }
        }
        retain_kept(&mut self.positions, keep);
        retain_kept(&mut self.uvs, keep);
        retain_kept(&mut self.cells, keep);
        self.springs
            .retain(|s| keep[s.a as usize] && keep[s.b as usize]);
        for s in &mut self.springs {
            s.a = index[s.a as usize];
            s.b = index[s.b as usize];
        }
        self.triangles
            .retain(|t| t.iter().all(|&i| keep[i as usize]));
        for t in &mut self.triangles {
            *t = t.map(|i| index[i as usize]);
        }
        self.pins.retain(|&p| keep[p as usize]);
        for p in &mut self.pins {
            *p = index[*p as usize];
        }
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of colours the solver sweeps per Gauss-Seidel iteration.
    pub fn colour_count(&self) -> u32 {
        self.colouring.modulus
    }

    /// The colour of particle `k` (grid order).
    pub fn colour_of(&self, k: u32) -> u32 {
        self.colouring.colour(self.cells[k as usize])
    }

    /// Number of springs of one family.
    pub fn spring_count(&self, family: SpringFamily) -> usize {
        self.springs.iter().filter(|s| s.family == family).count()
    }
}

/// A selection as a scene writes it: `"top_edge"`, `cells [[0, 0]]`, `near [x, y, z] within r m`.
fn describe(selection: &crate::scene::ParticleSelection) -> String {
    use crate::scene::ParticleSelection;
    match selection {
        ParticleSelection::Region(r) => format!("region {r:?}"),
        ParticleSelection::Cells(c) if c.is_empty() => "an empty list of cells".to_string(),
        ParticleSelection::Cells(c) => format!("cells {c:?}"),
        ParticleSelection::Near(n) => format!(
            "the particles within {} m of [{}, {}, {}]",
            n.radius, n.near[0], n.near[1], n.near[2]
        ),
    }
}

/// Refuses an attachment that selects no particle (a region or cells a hole cut away, a `near`
/// point away from the cloth): it would attach nothing, silently.
pub fn check_selections(
    scene: &crate::scene::Scene,
    garments: &[Garment],
    file: &str,
) -> crate::error::Result<()> {
    for (i, g) in garments.iter().enumerate() {
        if let Some(k) = g.attached.iter().position(Vec::is_empty) {
            return Err(crate::error::Error::InvalidField {
                file: file.to_string(),
                field: format!("garments[{i}].attachments[{k}].particles"),
                reason: format!(
                    "{} selects no particle of garment {:?}",
                    describe(&scene.garments[i].attachments[k].particles),
                    g.name
                ),
            });
        }
    }
    Ok(())
}

/// Builds every garment of a (validated) scene, in scene order: the garment preparation step.
/// Sheets and ropes come from their specs; a mesh garment's mesh is read from the scene's folder
/// and voxelized ([`voxel::place`]), its pins and attachment cells checked against the lattice,
/// and the whole bake's work checked again now that the lattices are known. Attachments that
/// select nothing are refused. `file` names the scene in errors (exit 2).
pub fn build_all(scene: &crate::scene::Scene, file: &str) -> crate::error::Result<Vec<Garment>> {
    let mut garments = Vec::with_capacity(scene.garments.len());
    for (i, spec) in scene.garments.iter().enumerate() {
        let name = scene.garment_name(i);
        let mut g = match spec.kind {
            GarmentKind::Mesh => {
                Garment::voxelized(name, spec, Arc::new(voxel::place(scene, i, file)?))
            }
            _ => Garment::build(name, spec),
        };
        if spec.colour.is_none() {
            g.colour = PALETTE[i % PALETTE.len()];
        }
        garments.push(g);
    }
    // Validation counted the sheets and ropes; the whole bake's work with the lattices too.
    let particles = garments.iter().map(|g| g.particle_count() as u64).sum();
    crate::scene::validate::check_work(scene, particles).map_err(|(field, reason)| {
        crate::error::Error::InvalidField {
            file: file.to_string(),
            field,
            reason,
        }
    })?;
    check_selections(scene, &garments, file)?;
    Ok(garments)
}

/// The stencil and colouring of a `dims` lattice for the spec's springs, and its pinned
/// particles (full-lattice grid order, sorted, unique).
fn lattice(dims: [u32; 3], spec: &GarmentSpec) -> (Stencil, Colouring, Vec<u32>) {
    let stencil = Stencil::new(dims, spec.stiffness.shear > 0.0, spec.stiffness.bend > 0.0);
    let colouring = Colouring::derive(&stencil);
    let mut pins: Vec<u32> = spec
        .pins
        .iter()
        .map(|pin| index_of(dims, resolve_cell(dims, pin)))
        .collect();
    pins.sort_unstable();
    pins.dedup();
    (stencil, colouring, pins)
}

/// The lattice cell grid coordinates name (negative from the end; validated before).
pub fn resolve_cell(dims: [u32; 3], coords: &[i64]) -> [u32; 3] {
    let mut cell = [0u32; 3];
    for (a, &c) in coords.iter().enumerate() {
        let n = dims[a] as i64;
        cell[a] = if c < 0 { (n + c) as u32 } else { c as u32 };
    }
    cell
}

/// Rotation from Euler angles in degrees, applied X, then Y, then Z.
pub fn rotation_of(degrees: [f32; 3]) -> Mat3 {
    Mat3::from_euler(
        EulerRot::XYZ,
        degrees[0].to_radians(),
        degrees[1].to_radians(),
        degrees[2].to_radians(),
    )
}

/// Lattice cell of grid-order index `k` (x fastest).
pub fn cell_of(dims: [u32; 3], k: u32) -> [u32; 3] {
    [
        k % dims[0],
        (k / dims[0]) % dims[1],
        k / (dims[0] * dims[1]),
    ]
}

/// Grid-order index of lattice cell `cell`.
pub fn index_of(dims: [u32; 3], cell: [u32; 3]) -> u32 {
    cell[0] + dims[0] * (cell[1] + dims[1] * cell[2])
}

fn build_springs(
    dims: [u32; 3],
    stencil: &Stencil,
    spacing: &[f32],
    stiffness: &crate::scene::Stiffness,
) -> Vec<Spring> {
    let count = dims.iter().product::<u32>();
    let mut springs = Vec::new();
    for (d, family) in &stencil.offsets {
        let rest = (0..3)
            .map(|a| d[a] as f32 * spacing.get(a).copied().unwrap_or(0.0))
            .map(|x| x * x)
            .sum::<f32>()
            .sqrt();
        let weight = match family {
            SpringFamily::Stretch => stiffness.stretch,
            SpringFamily::Shear => stiffness.shear,
            SpringFamily::Bend => stiffness.bend,
        };
        for k in 0..count {
            let c = cell_of(dims, k);
            let n: Option<Vec<u32>> = (0..3)
                .map(|a| {
                    let v = c[a] as i64 + d[a] as i64;
                    (v >= 0 && v < dims[a] as i64).then_some(v as u32)
                })
                .collect();
            if let Some(n) = n {
                springs.push(Spring {
                    a: k,
                    b: index_of(dims, [n[0], n[1], n[2]]),
                    rest,
                    weight,
                    family: *family,
                });
            }
        }
    }
    springs
}

/// Keeps the items whose `keep` entry is true, in order.
fn retain_kept<T>(items: &mut Vec<T>, keep: &[bool]) {
    let mut k = 0;
    items.retain(|_| {
        k += 1;
        keep[k - 1]
    });
}

/// Tethers from every free particle to its nearest pins (at most [`TETHERS_PER_PARTICLE`]).
fn build_tethers(rest: &[Vec3], pins: &[u32]) -> Vec<Tether> {
    let mut tethers = Vec::new();
    if pins.is_empty() {
        return tethers;
    }
    for k in 0..rest.len() as u32 {
        if pins.binary_search(&k).is_ok() {
            continue;
        }
        let mut near: Vec<(f32, u32)> = pins
            .iter()
            .map(|&p| (rest[k as usize].distance(rest[p as usize]), p))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(d, p) in near.iter().take(TETHERS_PER_PARTICLE) {
            tethers.push(Tether {
                particle: k,
                pin: p,
                rest: d,
            });
        }
    }
    tethers
}

/// Tethers of a voxelized garment: each free particle to its nearest pin along the lattice's
/// stretch springs (multi-source Dijkstra), at that path's length. A path along the lattice is
/// never shorter than the cloth's geodesic, so the tether never holds the cloth tighter than
/// its rest shape allows, whatever the mesh's curvature (a straight-line rest distance would).
fn lattice_tethers(garment: &Garment) -> Vec<Tether> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let n = garment.particle_count();
    let mut neighbours: Vec<Vec<(u32, f32)>> = vec![Vec::new(); n];
    for s in garment
        .springs
        .iter()
        .filter(|s| s.family == SpringFamily::Stretch)
    {
        neighbours[s.a as usize].push((s.b, s.rest));
        neighbours[s.b as usize].push((s.a, s.rest));
    }
    let mut best = vec![(f32::INFINITY, u32::MAX); n];
    let mut heap = BinaryHeap::new();
    for &p in &garment.pins {
        best[p as usize] = (0.0, p);
        heap.push((Reverse(0u64), p));
    }
    // Distances as ordered bits (non-negative floats order like their bit patterns).
    while let Some((Reverse(bits), i)) = heap.pop() {
        let d = f64::from_bits(bits) as f32;
        if d > best[i as usize].0 {
            continue;
        }
        for &(j, len) in &neighbours[i as usize] {
            let candidate = d + len;
            if candidate < best[j as usize].0 {
                best[j as usize] = (candidate, best[i as usize].1);
                heap.push((Reverse((candidate as f64).to_bits()), j));
            }
        }
    }
    (0..n as u32)
        .filter(|k| garment.pins.binary_search(k).is_err())
        .filter(|&k| best[k as usize].1 != u32::MAX)
        .map(|k| Tether {
            particle: k,
            pin: best[k as usize].1,
            rest: best[k as usize].0,
        })
        .collect()
}

/// Two triangles per grid quad of a sheet; none for a rope.
fn sheet_triangles(dims: [u32; 3]) -> Vec<[u32; 3]> {
    if dims[1] < 2 {
        return Vec::new();
    }
    let mut tris = Vec::with_capacity(2 * (dims[0] as usize - 1) * (dims[1] as usize - 1));
    for y in 0..dims[1] - 1 {
        for x in 0..dims[0] - 1 {
            let i = index_of(dims, [x, y, 0]);
            let (right, up, diag) = (i + 1, i + dims[0], i + dims[0] + 1);
            // Grid axis 1 runs along +Z, so (x, z) winding i → up → right faces +Y.
            tris.push([i, up, right]);
            tris.push([right, up, diag]);
        }
    }
    tris
}

/// A 1 m × 1 m sheet of `resolution` particles with `stiffness` (scene JSON), for unit tests.
#[cfg(test)]
pub(crate) fn test_sheet(resolution: [u32; 2], stiffness: &str) -> Garment {
    let scene = crate::scene::Scene::parse(
        &format!(
            r#"{{ "garments": [{{ "resolution": {resolution:?}, "size": [1, 1],
                 "stiffness": {stiffness} }}] }}"#
        ),
        "<test>",
    )
    .expect("scene");
    Garment::build("g".into(), &scene.garments[0])
}
