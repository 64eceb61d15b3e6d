//! What a bake shows, frame by frame: its garments, characters and analytic colliders as
//! meshes ([`BakeMeshes`]), each frame made into a [`Frame`] for the sinks. Also the welding of
//! imported meshes and the collider shapes' meshes.

use super::sink::{Frame, MeshInfo, Role};
use crate::mesh::AnimatedMesh;
use crate::scene::ColliderSpec;
use crate::sim::attach::Track;
use crate::sim::model::GarmentRange;
use glam::Vec3;

/// Colour of characters in exports and previews (linear RGB).
pub const CHARACTER_COLOUR: [f32; 3] = [0.72, 0.66, 0.60];

/// Colour of analytic colliders in exports and previews (linear RGB).
pub const COLLIDER_COLOUR: [f32; 3] = [0.45, 0.47, 0.52];

/// A collider's mesh at its start, and how keyframes move it.
pub struct ColliderMesh {
    pub mesh: AnimatedMesh,
    pub track: Option<Track>,
}

impl ColliderMesh {
    /// The mesh's vertices at time `t` [s].
    pub fn at(&self, t: f32) -> Vec<Vec3> {
        let rest = &self.mesh.frames[0];
        match &self.track {
            Some(track) => rest.iter().map(|p| track.apply(*p, t)).collect(),
            None => rest.clone(),
        }
    }
}

/// Meshes of the scene's sphere, box, capsule, funnel and wedge colliders, so exports and
/// previews show what the cloth meets (one frame: where it starts). Planes are left out: the
/// preview's floor stands for them.
pub fn collider_meshes(colliders: &[ColliderSpec]) -> Vec<ColliderMesh> {
    colliders
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            use crate::collide::Shape;
            let turned = |(p, t): Mesh, centre: Vec3, rotation: glam::Quat| -> Mesh {
                (p.iter().map(|q| centre + rotation * *q).collect(), t)
            };
            // Built at the origin, then turned and placed like the collider.
            let shape = crate::collide::Collider::from_spec(c).shape;
            let (positions, triangles) = match shape {
                Shape::Plane { .. } => return None,
                Shape::Sphere { centre, radius } => rounded(centre, centre, radius),
                Shape::Capsule { start, end, radius } => rounded(start, end, radius),
                Shape::Box {
                    centre,
                    half,
                    rotation,
                } => turned(cuboid(Vec3::ZERO, half), centre, rotation),
                Shape::Wedge {
                    centre,
                    half,
                    rotation,
                } => turned(prism(half), centre, rotation),
                Shape::Funnel {
                    centre,
                    radius,
                    top_radius,
                    height,
                    ..
                } => frustum(centre, radius, top_radius, height),
            };
            let track = (!c.keyframes.is_empty()).then(|| Track::new(&c.keyframes, shape.centre()));
            let mesh = AnimatedMesh {
                name: format!("collider{i}"),
                triangles,
                uvs: None,
                colour: [
                    COLLIDER_COLOUR[0],
                    COLLIDER_COLOUR[1],
                    COLLIDER_COLOUR[2],
                    1.0,
                ],
                frames: vec![positions],
                topology: Vec::new(),
                solid: None,
            };
            Some(ColliderMesh { mesh, track })
        })
        .collect()
}

type Mesh = (Vec<Vec3>, Vec<[u32; 3]>);

/// A sphere of `radius` split at its equator, the half facing `end` moved to `end` and the
/// other to `start`: a capsule (a sphere when the two coincide).
fn rounded(start: Vec3, end: Vec3, radius: f32) -> Mesh {
    let (rings, segments) = (16u32, 32u32);
    let axis = (end - start).try_normalize().unwrap_or(Vec3::Y);
    let (u, w) = axis.any_orthonormal_pair();
    let mut positions = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        let centre = if r <= rings / 2 { end } else { start };
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let d = axis * theta.cos() + (u * phi.cos() + w * phi.sin()) * theta.sin();
            positions.push(centre + d * radius);
        }
    }
    let mut triangles = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            let (c, d) = (a + segments, b + segments);
            triangles.push([a, c, b]);
            triangles.push([b, c, d]);
        }
    }
    // Face outwards whatever the handedness of (u, w, axis): check one triangle off the pole.
    let [a, b, c] = triangles[2 * segments as usize].map(|i| positions[i as usize]);
    if (b - a).cross(c - a).dot(a - end) < 0.0 {
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }
    (positions, triangles)
}

/// A wedge of half extents `half` at the origin: blade down along Z, faces outward.
fn prism(half: Vec3) -> Mesh {
    let tri = [
        Vec3::new(0.0, -half.y, 0.0),
        Vec3::new(half.x, half.y, 0.0),
        Vec3::new(-half.x, half.y, 0.0),
    ];
    let positions: Vec<Vec3> = [-half.z, half.z]
        .iter()
        .flat_map(|&z| tri.iter().map(move |p| Vec3::new(p.x, p.y, z)))
        .collect();
    // Caps (back −Z: 0 1 2 seen from −Z is clockwise, so reversed), then the three sides.
    let mut triangles = vec![[0, 2, 1], [3, 4, 5]];
    for k in 0..3u32 {
        let (a, b) = (k, (k + 1) % 3);
        triangles.push([a, b, b + 3]);
        triangles.push([a, b + 3, a + 3]);
    }
    (positions, triangles)
}

/// An upright funnel wall (a cone frustum surface, open at both ends) around `centre`.
fn frustum(centre: Vec3, radius: f32, top_radius: f32, height: f32) -> Mesh {
    let segments = 48u32;
    let mut positions = Vec::new();
    for (r, y) in [(radius, 0.0), (top_radius, height)] {
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(centre + Vec3::new(r * phi.cos(), y, r * phi.sin()));
        }
    }
    let mut triangles = Vec::new();
    for s in 0..segments {
        let (a, b) = (s, (s + 1) % segments);
        triangles.push([a, b + segments, b]);
        triangles.push([a, a + segments, b + segments]);
    }
    (positions, triangles)
}

/// An axis-aligned box of half extents `half` around `centre`.
fn cuboid(centre: Vec3, half: Vec3) -> Mesh {
    let positions = (0..8)
        .map(|k| {
            let sign = |bit: u32| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            centre + half * Vec3::new(sign(0), sign(1), sign(2))
        })
        .collect();
    // Two triangles per face, counter-clockwise seen from outside.
    let faces = [
        [0, 4, 6, 2], // −X
        [1, 3, 7, 5], // +X
        [0, 1, 5, 4], // −Y
        [2, 6, 7, 3], // +Y
        [0, 2, 3, 1], // −Z
        [4, 5, 7, 6], // +Z
    ];
    let triangles = faces
        .iter()
        .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
        .collect();
    (positions, triangles)
}

/// Everything a bake shows, in the order of its sinks' meshes: garments, characters,
/// colliders.
pub struct BakeMeshes {
    pub info: Vec<MeshInfo>,
    garments: Vec<GarmentRange>,
    /// Characters' meshes over frames 0…N (frame 0: the start; one frame: static).
    characters: Vec<AnimatedMesh>,
    colliders: Vec<ColliderMesh>,
    fps: f32,
}

impl BakeMeshes {
    /// The meshes of `garments`, `characters` (those with a frame for every baked frame, or
    /// static) and the colliders, for a bake of `frames` frames at `fps`.
    pub fn new(
        garments: &[GarmentRange],
        characters: Vec<AnimatedMesh>,
        colliders: &[ColliderSpec],
        frames: usize,
        fps: f32,
    ) -> BakeMeshes {
        let characters: Vec<AnimatedMesh> = characters
            .into_iter()
            .filter(|c| c.frames.len() == 1 || c.frames.len() > frames)
            .collect();
        let colliders = collider_meshes(colliders);
        let mut info: Vec<MeshInfo> = garments
            .iter()
            .map(|g| MeshInfo {
                name: g.name.clone(),
                role: Role::Garment,
                triangles: g.triangles.clone(),
                uvs: Some(g.uvs.clone()),
                colour: [g.colour[0], g.colour[1], g.colour[2], 1.0],
                vertices: g.surface(&vec![Vec3::ZERO; g.export.len()]).len(),
                animated: true,
            })
            .collect();
        let shown = |m: &AnimatedMesh, role, animated| MeshInfo {
            name: m.name.clone(),
            role,
            triangles: m.triangles.clone(),
            uvs: m.uvs.clone(),
            colour: m.colour,
            vertices: m.frames[0].len(),
            animated,
        };
        info.extend(
            characters
                .iter()
                .map(|c| shown(c, Role::Character, c.frames.len() > 1)),
        );
        info.extend(
            colliders
                .iter()
                .map(|c| shown(&c.mesh, Role::Collider, c.track.is_some())),
        );
        BakeMeshes {
            info,
            garments: garments.to_vec(),
            characters,
            colliders,
            fps,
        }
    }

    /// Baked frame `index` (shot frame `number`) from the garments' particles (export order).
    pub fn frame(&self, index: usize, number: u32, particles: &[Vec3]) -> Frame {
        let first = index == 0;
        let mut positions: Vec<Vec<Vec3>> = self
            .garments
            .iter()
            .map(|g| g.surface(&particles[g.export.clone()]))
            .collect();
        // Character frame k + 1 is the pose at baked frame k (frame 0 is the start).
        positions.extend(self.characters.iter().map(|c| match c.frames.len() {
            1 if first => c.frames[0].clone(),
            1 => Vec::new(),
            _ => c.frames[index + 1].clone(),
        }));
        // Baked frame k is at time (k + 1) / fps.
        let t = (index + 1) as f32 / self.fps;
        positions.extend(self.colliders.iter().map(|c| match c.track {
            Some(_) => c.at(t),
            None if first => c.mesh.frames[0].clone(),
            None => Vec::new(),
        }));
        Frame {
            index,
            number,
            positions,
        }
    }

    /// Every character shown, at baked frame `index`: name, vertices, and the faces that
    /// collide (all of them without a mesh selection).
    pub fn characters_at(
        &self,
        index: usize,
    ) -> impl Iterator<Item = (&str, &[Vec3], &[[u32; 3]])> {
        self.characters_on(index + 1)
    }

    /// Each character's name, vertices and colliding triangles on its frame `k` (0: where the
    /// bake starts, before the first frame).
    pub fn characters_on(&self, k: usize) -> impl Iterator<Item = (&str, &[Vec3], &[[u32; 3]])> {
        self.characters.iter().map(move |c| {
            let frame = &c.frames[if c.frames.len() == 1 { 0 } else { k }];
            let solid = c.solid.as_deref().unwrap_or(&c.triangles);
            (c.name.as_str(), &frame[..], solid)
        })
    }

    /// Each garment's surface from the particles (export order), in garment order.
    pub fn garment_surfaces(&self, particles: &[Vec3]) -> Vec<Vec<Vec3>> {
        self.garments
            .iter()
            .map(|g| g.surface(&particles[g.export.clone()]))
            .collect()
    }

    /// The garments' faces, in garment order.
    pub fn garment_faces(&self) -> impl Iterator<Item = &[[u32; 3]]> {
        self.garments.iter().map(|g| &g.triangles[..])
    }

    /// Garment `g` has `faces` from now on (a resumed bake replaying a tear).
    pub fn set_faces(&mut self, g: usize, faces: &[[u32; 3]]) {
        self.garments[g].triangles = faces.to_vec();
    }

    /// The number of garments.
    pub fn garment_count(&self) -> usize {
        self.garments.len()
    }

    /// The number of garment particles a frame takes (export order).
    pub fn garment_particles(&self) -> usize {
        self.garments.iter().map(|g| g.export.len()).sum()
    }

    /// Takes the garments' faces after tearing; returns the garments whose faces changed.
    /// Every garment's exported surface as one mesh ([`Self::garment_surfaces`] one after
    /// another, with the faces over them as torn so far).
    pub fn garments_as_one(&self, particles: &[Vec3]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
        for (surface, faces) in self
            .garment_surfaces(particles)
            .into_iter()
            .zip(self.garment_faces())
        {
            let first = vertices.len() as u32;
            triangles.extend(faces.iter().map(|t| t.map(|i| i + first)));
            vertices.extend(surface);
        }
        (vertices, triangles)
    }

    pub fn tear(&mut self, garments: &[GarmentRange]) -> Vec<usize> {
        let mut changed = Vec::new();
        for (i, (old, new)) in self.garments.iter_mut().zip(garments).enumerate() {
            if old.triangles != new.triangles {
                old.triangles = new.triangles.clone();
                changed.push(i);
            }
        }
        changed
    }
}

/// An indexed mesh: vertices that sit at the same place on every frame become one, and faces
/// that collapse to a line or point are dropped. Importers split a vertex per face corner (an
/// OBJ without vertex joining: the mannequin has 5 040 vertices for 858 positions), and every
/// copy would be stored in every frame of the exports. A vertex that only starts at the same
/// place (a seam a skin pulls apart) stays apart.
pub fn weld(triangles: &[[u32; 3]], frames: &[Vec<Vec3>]) -> (Vec<[u32; 3]>, Vec<Vec<Vec3>>) {
    let welding = Welding::new(frames);
    (welding.faces(triangles), welding.frames(frames))
}

/// Which vertices [`weld`] merges: those at the same position in every frame.
pub struct Welding {
    /// Per vertex, its welded index.
    map: Vec<u32>,
    /// Per welded vertex, the vertex that stands for it.
    kept: Vec<usize>,
}

impl Welding {
    /// Finds the vertices of `frames` that share a position in every frame.
    pub fn new(frames: &[Vec<Vec3>]) -> Welding {
        let Some(first) = frames.first() else {
            return Welding {
                map: Vec::new(),
                kept: Vec::new(),
            };
        };
        let same = |a: usize, b: usize| frames.iter().all(|f| f[a] == f[b]);
        let mut by_position: std::collections::HashMap<[u32; 3], Vec<u32>> = Default::default();
        let mut kept: Vec<usize> = Vec::new();
        let mut map = Vec::with_capacity(first.len());
        for (v, p) in first.iter().enumerate() {
            let candidates = by_position
                .entry(p.to_array().map(f32::to_bits))
                .or_default();
            let k = match candidates.iter().find(|&&k| same(kept[k as usize], v)) {
                Some(&k) => k,
                None => {
                    kept.push(v);
                    candidates.push(kept.len() as u32 - 1);
                    kept.len() as u32 - 1
                }
            };
            map.push(k);
        }
        Welding { map, kept }
    }

    /// `triangles` over the welded vertices, those that collapsed left out.
    pub fn faces(&self, triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
        if self.map.is_empty() {
            return triangles.to_vec();
        }
        triangles
            .iter()
            .map(|t| t.map(|i| self.map[i as usize]))
            .filter(|[a, b, c]| a != b && b != c && a != c)
            .collect()
    }

    /// The welded vertices of each frame.
    pub fn frames(&self, frames: &[Vec<Vec3>]) -> Vec<Vec<Vec3>> {
        frames
            .iter()
            .map(|f| self.kept.iter().map(|&v| f[v]).collect())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weld_joins_what_coincides_on_every_frame() {
        // A quad as two triangles with split corners (6 vertices, 4 places) over two frames; in
        // the second frame vertex 5 leaves vertex 2's place, so they stay apart.
        let quad = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
        ];
        let mut moved = quad.to_vec();
        moved[5] = Vec3::new(0.0, 2.0, 0.0);
        let triangles = [[0, 1, 2], [3, 4, 5]];
        let (faces, frames) = weld(&triangles, &[quad.to_vec(), quad.to_vec()]);
        assert_eq!(frames[0].len(), 4);
        assert_eq!(faces.len(), 2);
        for (face, original) in faces.iter().zip(triangles) {
            for (i, o) in face.iter().zip(original) {
                assert_eq!(frames[1][*i as usize], quad[o as usize]);
            }
        }
        let (_, apart) = weld(&triangles, &[quad.to_vec(), moved]);
        assert_eq!(apart[0].len(), 5);
        // A face whose corners weld together is dropped.
        let (faces, _) = weld(&[[0, 1, 3]], &[quad.to_vec()]);
        assert!(faces.is_empty());
    }
}
