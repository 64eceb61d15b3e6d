//! Voxelized garments: any triangle mesh turned into particles on a regular lattice (the thesis's
//! voxel grid, built there with SDFGen).
//!
//! 1. **Surface**: a cell is occupied when its box touches a triangle (the triangle–box
//!    separating-axis test of Akenine-Möller). Such a conservative voxelization is 6-connected, so
//!    the axis springs alone hold a tilted or curved sheet together; a flat sheet lying on a
//!    lattice plane gives exactly one layer, because the lattice starts at the mesh's bounding
//!    box and candidate cells are taken half-open.
//! 2. **Fill** (closed solids): the free cells fall into 6-connected components that the surface
//!    separates (two face-adjacent free cells cannot lie on opposite sides of it: the segment
//!    between their centres would meet a triangle inside one of their boxes). One cell per
//!    component decides by the mesh's generalized winding number (Jacobson et al. 2013): inside
//!    when |w| > ½, which also fills meshes wound inside out.
//! 3. **Embedding**: every mesh vertex is tied to the occupied lattice points around it with
//!    trilinear weights (renormalised over the occupied ones), so exports show the garment's own
//!    surface moved by the particles rather than the voxel blocks.

use crate::error::{Error, Result};
use glam::Vec3;
use std::collections::HashMap;
use std::path::Path;

/// A garment mesh as read from a file (any format assimp reads), in file coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceMesh {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// First texture coordinate set, when the file has one.
    pub uvs: Option<Vec<[f32; 2]>>,
}

impl SourceMesh {
    /// Reads a mesh file through assimp (rest pose; every mesh of the file, placed by its node).
    /// Corners with the same position and texture coordinate become one vertex (assimp gives
    /// OBJ faces their own corners), so exported normals are smooth across faces.
    pub fn open(path: &Path) -> Result<SourceMesh> {
        SourceMesh::open_in(path, None, false)
    }

    /// Reads the meshes of a file that `mesh_name` names (by mesh, node or material name; all
    /// of them without one), in its bind pose when `bind` (a garment modelled on a character:
    /// skinned meshes as stored), else in its default node pose.
    pub fn open_in(path: &Path, mesh_name: Option<&str>, bind: bool) -> Result<SourceMesh> {
        use crate::mesh::import::{matches, Asset};
        let mut asset = Asset::open(path)?;
        if let Some(name) = mesh_name {
            if !asset.meshes.iter().any(|m| matches(m, name)) {
                let names: Vec<String> = asset
                    .meshes
                    .iter()
                    .map(|m| format!("{:?} (node {:?})", m.name, m.node))
                    .collect();
                return Err(Error::InvalidField {
                    file: path.display().to_string(),
                    field: "mesh_name".into(),
                    reason: format!(
                        "{name:?} names no mesh, node or material; the file has {}",
                        names.join(", ")
                    ),
                });
            }
            asset.meshes.retain(|m| matches(m, name));
        }
        let vertices = if bind {
            asset.bind_pose()
        } else {
            asset.pose(None, 0.0)
        };
        Ok(SourceMesh::welded(
            &vertices,
            &asset.triangles(),
            asset.uvs().as_deref(),
        ))
    }

    /// A mesh whose identical corners (position and texture coordinate) are merged.
    pub fn welded(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        uvs: Option<&[[f32; 2]]>,
    ) -> SourceMesh {
        let mut index: HashMap<[u32; 5], u32> = HashMap::new();
        let mut mesh = SourceMesh {
            vertices: Vec::new(),
            triangles: Vec::with_capacity(triangles.len()),
            uvs: uvs.map(|_| Vec::new()),
        };
        let remap: Vec<u32> = (0..vertices.len())
            .map(|i| {
                let uv = uvs.map_or([0.0; 2], |u| u[i]);
                let p = vertices[i];
                let key = [p.x, p.y, p.z, uv[0], uv[1]].map(|x| (x + 0.0).to_bits());
                *index.entry(key).or_insert_with(|| {
                    mesh.vertices.push(p);
                    if let Some(u) = &mut mesh.uvs {
                        u.push(uv);
                    }
                    mesh.vertices.len() as u32 - 1
                })
            })
            .collect();
        mesh.triangles = triangles
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .collect();
        mesh
    }

    /// Lower and upper corners of the bounding box.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds(&self.vertices)
    }

    /// Whether every edge is shared by exactly two triangles (vertices welded by position), so
    /// the mesh bounds a solid.
    pub fn is_closed(&self) -> bool {
        if self.triangles.len() < 4 {
            return false;
        }
        let (lo, hi) = self.bounds();
        let tolerance = (hi - lo).length().max(f32::MIN_POSITIVE) * 1e-6;
        let mut welded: HashMap<[i64; 3], u32> = HashMap::new();
        let id: Vec<u32> = self
            .vertices
            .iter()
            .map(|v| {
                let key = ((*v - lo) / tolerance).round().as_i64vec3().to_array();
                let next = welded.len() as u32;
                *welded.entry(key).or_insert(next)
            })
            .collect();
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (id[t[k] as usize], id[t[(k + 1) % 3] as usize]);
                if a != b {
                    *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
        }
        !edges.is_empty() && edges.values().all(|&n| n == 2)
    }
}

/// The occupied cells of a lattice laid over a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxels {
    /// Centre of cell (0, 0, 0) [m]: the mesh's lower bounding-box corner.
    pub origin: Vec3,
    /// Cell edge [m].
    pub spacing: f32,
    /// Cells per axis.
    pub dims: [u32; 3],
    /// Occupancy per cell, x fastest.
    pub occupied: Vec<bool>,
    /// Cells occupied because a triangle touches them.
    pub surface_cells: usize,
    /// Cells occupied because they lie inside the closed mesh.
    pub interior_cells: usize,
}

impl Voxels {
    /// Lattice dimensions for a mesh spanning `lo…hi` at `spacing` (without voxelizing).
    pub fn dims_for(lo: Vec3, hi: Vec3, spacing: f32) -> [u32; 3] {
        // In f64 and saturated: a spacing far below the mesh's size asks for more cells than
        // u32 counts, which must read as "too many", never wrap to a small number.
        ((hi - lo).as_dvec3() / spacing as f64 + 0.5)
            .floor()
            .max(glam::DVec3::ZERO)
            .to_array()
            .map(|n| n.min((u32::MAX - 1) as f64) as u32 + 1)
    }

    /// Voxelizes `vertices`/`triangles` at `spacing`; `fill` fills the inside of a closed mesh.
    pub fn build(vertices: &[Vec3], triangles: &[[u32; 3]], spacing: f32, fill: bool) -> Voxels {
        let (lo, hi) = bounds(vertices);
        let dims = Voxels::dims_for(lo, hi, spacing);
        let mut voxels = Voxels {
            origin: lo,
            spacing,
            dims,
            occupied: vec![false; dims.iter().map(|&n| n as usize).product()],
            surface_cells: 0,
            interior_cells: 0,
        };
        let half = Vec3::splat(0.5 * spacing);
        for t in triangles {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            // Candidate cells: those whose half-open box holds a point of the triangle's bounds.
            let first = voxels.cell_of(a.min(b).min(c));
            let last = voxels.cell_of(a.max(b).max(c));
            for z in first[2]..=last[2] {
                for y in first[1]..=last[1] {
                    for x in first[0]..=last[0] {
                        let i = voxels.index([x, y, z]);
                        if !voxels.occupied[i]
                            && triangle_touches_box([a, b, c], voxels.centre([x, y, z]), half)
                        {
                            voxels.occupied[i] = true;
                            voxels.surface_cells += 1;
                        }
                    }
                }
            }
        }
        if fill {
            voxels.fill_inside(vertices, triangles);
        }
        voxels
    }

    /// Centre of a cell [m].
    pub fn centre(&self, cell: [u32; 3]) -> Vec3 {
        self.origin + Vec3::new(cell[0] as f32, cell[1] as f32, cell[2] as f32) * self.spacing
    }

    /// The cell whose half-open box holds `p` (clamped to the lattice).
    fn cell_of(&self, p: Vec3) -> [u32; 3] {
        let c = ((p - self.origin) / self.spacing + 0.5).floor();
        [0, 1, 2].map(|a| (c[a].max(0.0) as u32).min(self.dims[a] - 1))
    }

    fn index(&self, c: [u32; 3]) -> usize {
        super::index_of(self.dims, c) as usize
    }

    /// Number of occupied cells.
    pub fn count(&self) -> usize {
        self.occupied.iter().filter(|&&o| o).count()
    }

    /// Marks the free components inside the mesh (by winding number) as occupied.
    fn fill_inside(&mut self, vertices: &[Vec3], triangles: &[[u32; 3]]) {
        let mut seen = self.occupied.clone();
        let mut stack = Vec::new();
        for start in 0..seen.len() {
            if seen[start] {
                continue;
            }
            let seed = super::cell_of(self.dims, start as u32);
            let inside = winding_number(vertices, triangles, self.centre(seed)).abs() > 0.5;
            seen[start] = true;
            stack.push(start);
            while let Some(i) = stack.pop() {
                if inside {
                    self.occupied[i] = true;
                    self.interior_cells += 1;
                }
                let c = super::cell_of(self.dims, i as u32);
                for a in 0..3 {
                    for step in [-1i64, 1] {
                        let v = c[a] as i64 + step;
                        if v < 0 || v >= self.dims[a] as i64 {
                            continue;
                        }
                        let mut n = c;
                        n[a] = v as u32;
                        let j = self.index(n);
                        if !seen[j] {
                            seen[j] = true;
                            stack.push(j);
                        }
                    }
                }
            }
        }
    }

    /// Trilinear weights tying `p` to the occupied lattice points of the cell corner block around
    /// it, renormalised over the occupied ones: (dense cell index, weight), at most eight.
    pub fn embed(&self, p: Vec3) -> Vec<(usize, f32)> {
        let g = ((p - self.origin) / self.spacing).max(Vec3::ZERO);
        let base = g.floor();
        let f = g - base;
        let mut out = Vec::with_capacity(8);
        for corner in 0..8u32 {
            let offset = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let cell: [u32; 3] =
                [0, 1, 2].map(|a| (base[a] as u32 + offset[a]).min(self.dims[a] - 1));
            let w = (0..3)
                .map(|a| if offset[a] == 1 { f[a] } else { 1.0 - f[a] })
                .product::<f32>();
            let i = self.index(cell);
            if self.occupied[i] && w > 0.0 {
                match out.iter_mut().find(|(j, _)| *j == i) {
                    Some((_, existing)) => *existing += w,
                    None => out.push((i, w)),
                }
            }
        }
        if out.is_empty() {
            // Every point of the mesh lies in an occupied cell's box: fall back to that cell.
            out.push((self.index(self.cell_of(p)), 1.0));
        }
        let total: f32 = out.iter().map(|w| w.1).sum();
        out.iter_mut().for_each(|w| w.1 /= total);
        out
    }
}

/// Lower and upper corners of the points' bounding box.
pub fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    points.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &v| (lo.min(v), hi.max(v)),
    )
}

/// Generalized winding number of a triangle mesh at `p`: the solid angle its triangles subtend,
/// over 4π (Van Oosterom and Strackee's formula per triangle). 1 inside a closed mesh wound
/// counter-clockwise seen from outside, 0 outside.
pub fn winding_number(vertices: &[Vec3], triangles: &[[u32; 3]], p: Vec3) -> f32 {
    let mut total = 0.0f64;
    for t in triangles {
        let [a, b, c] = t.map(|i| (vertices[i as usize] - p).as_dvec3());
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let det = a.dot(b.cross(c));
        let div = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        total += 2.0 * det.atan2(div);
    }
    (total / (4.0 * std::f64::consts::PI)) as f32
}

/// Whether the triangle touches the closed box of `half` extents around `centre`: the 13-axis
/// separating-axis test (box faces, triangle normal, and the 9 edge cross products).
pub fn triangle_touches_box(triangle: [Vec3; 3], centre: Vec3, half: Vec3) -> bool {
    let v = triangle.map(|p| p - centre);
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let separated = |axis: Vec3| {
        let p = v.map(|x| x.dot(axis));
        let r = half.dot(axis.abs());
        p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
    };
    for a in 0..3 {
        let axis = Vec3::AXES[a];
        for e in edges {
            if separated(axis.cross(e)) {
                return false;
            }
        }
        if separated(axis) {
            return false;
        }
    }
    !separated(edges[0].cross(edges[1]))
}

/// Reads and voxelizes the mesh of mesh garment `i` of a (validated) scene, from the scene's
/// folder, and checks the lattice cells its pins and attachments name.
pub fn place(scene: &crate::scene::Scene, i: usize, file: &str) -> Result<PlacedMesh> {
    use crate::scene::{FillMode, ParticleSelection};
    let g = &scene.garments[i];
    let fail = |field: &str, reason: String| Error::InvalidField {
        file: file.to_string(),
        field: format!("garments[{i}].{field}"),
        reason,
    };
    let name = g.mesh.clone().unwrap_or_default();
    let source = open_for_scene(
        &scene.base_dir.join(&name),
        (g.mesh_name.as_deref(), g.on.is_some()),
        file,
        format!("garments[{i}].mesh"),
    )?;
    let transform = placement(scene, g, &source);
    let placed: Vec<Vec3> = source
        .vertices
        .iter()
        .map(|&v| transform.transform_point3(v))
        .collect();
    let (plo, phi) = bounds(&placed);
    if let Some(v) = placed
        .iter()
        .find(|v| v.abs().max_element() > crate::scene::validate::MAX_EXTENT)
    {
        return Err(fail(
            "mesh",
            format!(
                "{name} has a vertex at {v} once placed, beyond ±{:.0e} m, where single precision cannot resolve a cloth",
                crate::scene::validate::MAX_EXTENT
            ),
        ));
    }
    let spacing = g
        .spacing
        .unwrap_or_else(|| ((phi - plo).max_element() / 31.0).max(1e-4));
    let across = (phi - plo).max_element();
    if across < 2.0 * spacing {
        // Two lattice cells at most along every side: a handful of particles, no cloth. Most
        // likely a mesh in other units than it is read in (a garment in metres modelled on a
        // character file in centimetres, read at its `scale` 0.01).
        let read = match &g.on {
            Some(c) => format!(
                "an `on` garment's file is read in {c}'s file units and placed by its `scale`; is {name} in other units?"
            ),
            None => format!("is {name} in other units than its `scale` ({}) reads?", g.scale),
        };
        return Err(fail(
            if g.on.is_some() { "mesh" } else { "spacing" },
            format!(
                "{name}, placed, is {across:.3e} m across, under two lattice spacings ({spacing} m): a handful of particles, no cloth; {read}"
            ),
        ));
    }
    let dims = Voxels::dims_for(plo, phi, spacing);
    let cells: f64 = dims.iter().map(|&n| n as f64).product();
    if cells > crate::scene::MAX_PARTICLES as f64 {
        return Err(fail(
            "spacing",
            format!(
                "{spacing} m lays {}×{}×{} cells over {name}, more than drape's limit of {}",
                dims[0],
                dims[1],
                dims[2],
                crate::scene::MAX_PARTICLES
            ),
        ));
    }
    let fill = match g.fill {
        FillMode::Auto => None,
        FillMode::Solid => Some(true),
        FillMode::Surface => Some(false),
    };
    let mesh = PlacedMesh::place(&name, &source, transform, spacing, fill);
    let check = |field: &str, coords: &[Vec<i64>]| -> Result<()> {
        for c in coords {
            let inside = c.len() == 3
                && (0..3).all(|a| {
                    let n = dims[a] as i64;
                    (-n..n).contains(&c[a])
                });
            if !inside {
                return Err(fail(
                    field,
                    format!(
                        "cell {c:?} is not in the {}×{}×{} lattice of {name}",
                        dims[0], dims[1], dims[2]
                    ),
                ));
            }
            let cell = super::resolve_cell(dims, c);
            if !mesh.voxels.occupied[super::index_of(dims, cell) as usize] {
                return Err(fail(
                    field,
                    format!("cell {cell:?} of {name}'s lattice holds no particle"),
                ));
            }
        }
        Ok(())
    };
    check("pins", &g.pins)?;
    for a in &g.attachments {
        if let ParticleSelection::Cells(cells) = &a.particles {
            check("attachments", cells)?;
        }
    }
    Ok(mesh)
}

/// Where garment `g`'s mesh `source` goes in the scene: modelled on a character, placed as the
/// character is, then moved by its own `position` and `rotation`; else centred, scaled by its
/// `scale` and moved.
fn placement(
    scene: &crate::scene::Scene,
    g: &crate::scene::GarmentSpec,
    source: &SourceMesh,
) -> glam::Affine3A {
    let moved = glam::Affine3A::from_translation(Vec3::from(g.position))
        * glam::Affine3A::from_mat3(super::rotation_of(g.rotation));
    match g.on.as_ref().and_then(|on| character_named(scene, on)) {
        Some(c) => moved * glam::Affine3A::from_mat4(c.options().transform()),
        None => {
            let (lo, hi) = source.bounds();
            moved
                * glam::Affine3A::from_scale(Vec3::splat(g.scale))
                * glam::Affine3A::from_translation(-0.5 * (lo + hi))
        }
    }
}

/// The character of `scene` called `name`.
fn character_named<'s>(
    scene: &'s crate::scene::Scene,
    name: &str,
) -> Option<&'s crate::scene::CharacterSpec> {
    (0..scene.characters.len())
        .find(|&k| scene.character_name(k) == name)
        .map(|k| &scene.characters[k])
}

/// Reads a garment mesh for a scene (the file's meshes that `mesh_name` names, in the bind
/// pose when `bind`), naming the scene file and field on failure.
pub fn open_for_scene(
    path: &Path,
    (mesh_name, bind): (Option<&str>, bool),
    scene_file: &str,
    field: String,
) -> Result<SourceMesh> {
    let mesh = SourceMesh::open_in(path, mesh_name, bind).map_err(|e| Error::InvalidField {
        file: scene_file.to_string(),
        field: field.clone(),
        reason: format!("cannot use {}: {e}", path.display()),
    })?;
    if mesh.triangles.is_empty() {
        return Err(Error::InvalidField {
            file: scene_file.to_string(),
            field,
            reason: format!("{} has no triangles", path.display()),
        });
    }
    Ok(mesh)
}

/// A mesh garment as its scene places it: the surface in scene coordinates and its voxels.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedMesh {
    /// The file, as the scene names it.
    pub file: String,
    /// Vertices after scale, rotation and translation [m].
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// The file's texture coordinates, or a projection onto the two longest bounding-box axes.
    pub uvs: Vec<[f32; 2]>,
    /// Whether the mesh bounds a solid (every edge shared by two triangles).
    pub closed: bool,
    pub voxels: Voxels,
}

impl PlacedMesh {
    /// Moves `source` into the scene by `transform`, then voxelizes it at `spacing` (filling it
    /// when `fill`, or when `fill` is None and the mesh is closed).
    pub fn place(
        file: &str,
        source: &SourceMesh,
        transform: glam::Affine3A,
        spacing: f32,
        fill: Option<bool>,
    ) -> PlacedMesh {
        // A closed mesh's inside stays inside under any placement, so `closed` is the file's.
        let vertices: Vec<Vec3> = source
            .vertices
            .iter()
            .map(|&v| transform.transform_point3(v))
            .collect();
        let closed = source.is_closed();
        let voxels = Voxels::build(
            &vertices,
            &source.triangles,
            spacing,
            fill.unwrap_or(closed),
        );
        let uvs = source
            .uvs
            .clone()
            .unwrap_or_else(|| planar_uvs(&source.vertices));
        PlacedMesh {
            file: file.to_string(),
            vertices,
            triangles: source.triangles.clone(),
            uvs,
            closed,
            voxels,
        }
    }
}

/// Texture coordinates projecting the mesh onto its two longest bounding-box axes (0…1).
fn planar_uvs(vertices: &[Vec3]) -> Vec<[f32; 2]> {
    let (lo, hi) = bounds(vertices);
    let extent = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE));
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| extent[b].total_cmp(&extent[a]));
    vertices
        .iter()
        .map(|v| {
            let t = (*v - lo) / extent;
            [t[axes[0]], t[axes[1]]]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_touches_triangles_that_cross_it_and_not_ones_beside_it() {
        let t = [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        assert!(triangle_touches_box(t, Vec3::ZERO, Vec3::splat(0.1)));
        assert!(!triangle_touches_box(
            t,
            Vec3::new(0.0, 0.2, 0.0),
            Vec3::splat(0.1)
        ));
        // Beside the hypotenuse, inside the triangle's bounding box: only an edge axis separates.
        assert!(!triangle_touches_box(
            t,
            Vec3::new(0.9, 0.0, 0.9),
            Vec3::splat(0.1)
        ));
    }

    #[test]
    fn the_winding_number_of_a_tetrahedron_is_one_inside_and_zero_outside() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let t = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        assert!((winding_number(&v, &t, Vec3::splat(0.1)) - 1.0).abs() < 1e-5);
        assert!(winding_number(&v, &t, Vec3::splat(2.0)).abs() < 1e-5);
    }
}
