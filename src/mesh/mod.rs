//! Meshes as every stage sees them, below characters, garments and exports alike: the
//! animated mesh (fixed topology, a position array per frame) that characters are sampled into
//! and exports write, vertex normals (plain, for exports and previews; welded, for skins and
//! shells), and the readers of mesh files (`import`: assimp for every format it knows, drape's
//! own glTF reader for glTF) that characters and mesh garments both load through.

pub mod import;

use glam::Vec3;
use std::collections::HashMap;

/// Vertices closer than this [m] share a normal (see [`Weld`]).
pub const WELD: f32 = 1e-5;

/// An animated mesh: fixed topology, one position array per frame.
#[derive(Clone, Debug)]
pub struct AnimatedMesh {
    pub name: String,
    /// Triangles; empty for a rope, which is written as a line strip.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates per vertex, if any.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Base colour, linear RGBA.
    pub colour: [f32; 4],
    /// Positions of every vertex, per frame.
    pub frames: Vec<Vec<Vec3>>,
    /// When the faces change during the sequence (tearing): (first frame index, triangles)
    /// in order; `triangles` holds the last. Empty: `triangles` throughout. glTF keeps one
    /// topology, the last; previews and OBJ frames follow the changes.
    pub topology: Vec<(usize, Vec<[u32; 3]>)>,
    /// A character's triangles that collide, when a mesh selection left some out (the mesh
    /// penetration metric measures these); None: all of `triangles`.
    pub solid: Option<Vec<[u32; 3]>>,
}

impl AnimatedMesh {
    /// The triangles of frame `k`.
    pub fn triangles_at(&self, k: usize) -> &[[u32; 3]] {
        self.topology
            .iter()
            .rev()
            .find(|(first, _)| *first <= k)
            .map_or(&self.triangles, |(_, t)| t)
    }
}

/// Area-weighted vertex normals (unit length; +Y for a vertex with no area).
pub fn vertex_normals(triangles: &[[u32; 3]], positions: &[Vec3]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += n;
        }
    }
    normals
        .iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
        .collect()
}

/// Vertices welded for smooth normals: vertices within the same 10 µm cell share a slot (a
/// seam's two copies of a vertex rarely agree to the last bit when a generator computed them
/// from different angles).
#[derive(Clone, Debug, Default)]
pub struct Weld {
    /// Each vertex's slot.
    pub slot: Vec<u32>,
    /// Number of slots.
    pub slots: usize,
}

impl Weld {
    /// The welding of `vertices`.
    pub fn of(vertices: &[Vec3]) -> Weld {
        let mut weld: HashMap<[i64; 3], u32> = HashMap::new();
        let slot: Vec<u32> = vertices
            .iter()
            .map(|v| {
                let n = weld.len() as u32;
                *weld.entry(Weld::place(*v)).or_insert(n)
            })
            .collect();
        Weld {
            slots: weld.len(),
            slot,
        }
    }

    /// The place a vertex at `v` is welded by: vertices at one place share a slot.
    pub fn place(v: Vec3) -> [i64; 3] {
        (v / WELD).round().as_dvec3().to_array().map(|c| c as i64)
    }

    /// Each slot's triangles (compressed rows: `faces[start[s]..start[s + 1]]`), a triangle
    /// once per corner it has in the slot, in triangle order: the order [`welded_normals`]
    /// adds them in (the GPU sums each slot's normals from these).
    pub fn slot_faces(&self, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
        let mut start = vec![0u32; self.slots + 1];
        for t in triangles {
            for &i in t {
                start[self.slot[i as usize] as usize + 1] += 1;
            }
        }
        for s in 0..self.slots {
            start[s + 1] += start[s];
        }
        let mut next = start.clone();
        let mut faces = vec![0u32; 3 * triangles.len()];
        for (k, t) in triangles.iter().enumerate() {
            for &i in t {
                let at = &mut next[self.slot[i as usize] as usize];
                faces[*at as usize] = k as u32;
                *at += 1;
            }
        }
        (start, faces)
    }
}

/// Each vertex's smooth unit normal (zero where it has none): the area-weighted sum of its
/// triangles' normals, vertices welded ([`Weld`]).
pub fn smooth_normals(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    welded_normals(vertices, triangles, &Weld::of(vertices))
}

/// [`smooth_normals`] with a given welding (a character's first frame's, for all its frames:
/// `shaders/skin.wgsl` sums the same on the GPU).
pub fn welded_normals(vertices: &[Vec3], triangles: &[[u32; 3]], weld: &Weld) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; weld.slots];
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            sum[weld.slot[i as usize] as usize] += n;
        }
    }
    (weld.slot.iter())
        .map(|&s| sum[s as usize].normalize_or_zero())
        .collect()
}

/// A closed box from `lo` to `hi` as 12 triangles wound outward (8 shared vertices), for tests.
#[cfg(test)]
pub(crate) fn cuboid(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let v: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
        .map(|f| lo + f * (hi - lo))
        .collect();
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let t = faces
        .iter()
        .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
        .collect();
    (v, t)
}
