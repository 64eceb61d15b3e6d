//! A character's shell bound to its mesh: each shell particle sits at barycentric coordinates
//! on one triangle of a mesh whose topology holds over the frames. The CPU reads the shell's
//! positions per frame (`ShellCollider::frames`); the GPU backend places the shell particles
//! itself from this binding and each frame's vertices, so a frame uploads the character's
//! vertices, not its shell particles at every substep (the GPU sums their smooth normals
//! itself, from the welding of the first frame that the CPU uses for every frame too).

use crate::mesh::{welded_normals, Weld};
use glam::Vec3;

/// What the GPU needs to place a shell's particles from the mesh's vertices.
#[derive(Clone, Debug, Default)]
pub struct Skin {
    /// Mesh triangles (vertex indices).
    pub triangles: Vec<[u32; 3]>,
    /// Each shell particle's triangle.
    pub particle_triangle: Vec<u32>,
    /// Each shell particle's barycentric (u, v): p = a + u (b − a) + v (c − a).
    pub barycentric: Vec<[f32; 2]>,
    /// The mesh's vertices on every frame.
    pub vertices: Vec<Vec<Vec3>>,
    /// The vertices welded for the smooth normals, as on the first frame.
    pub weld: Weld,
}

impl Skin {
    /// The binding of `shell` to a mesh of `triangles` over `frames` of vertices (kept).
    pub fn new(
        shell: &crate::character::Shell,
        triangles: Vec<[u32; 3]>,
        frames: Vec<Vec<Vec3>>,
    ) -> Skin {
        let weld = frames.first().map(|f| Weld::of(f)).unwrap_or_default();
        Skin {
            triangles,
            particle_triangle: shell.triangle.clone(),
            barycentric: shell.barycentric.clone(),
            vertices: frames,
            weld,
        }
    }

    /// The shell particles' unit normals on `frame` (`Shell::normals`, with the first frame's
    /// welding).
    pub fn particle_normals(&self, frame: usize) -> Vec<Vec3> {
        let vertices = &self.vertices[frame];
        let smooth = &welded_normals(vertices, &self.triangles, &self.weld);
        self.particle_triangle
            .iter()
            .zip(&self.barycentric)
            .map(|(&t, &b)| {
                crate::character::shell::particle_normal(
                    vertices,
                    smooth,
                    self.triangles[t as usize],
                    b,
                )
            })
            .collect()
    }

    /// Vertices of the mesh.
    pub fn vertex_count(&self) -> usize {
        self.vertices.first().map_or(0, Vec::len)
    }

    /// Each shell particle's triangle corners (vertex indices), as the GPU reads them.
    pub fn corners(&self) -> Vec<[u32; 4]> {
        self.particle_triangle
            .iter()
            .map(|&t| {
                let [a, b, c] = self.triangles[t as usize];
                [a, b, c, 0]
            })
            .collect()
    }
}
