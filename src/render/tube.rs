//! Ropes as tubes: a mesh without faces (a rope, exported as a polyline) would draw as a line one
//! pixel wide, unlit and unshadowed; previews draw it as a six-sided tube instead, thick enough
//! to see (a fixed fraction of the scene's size), so ropes shade and cast shadows like cloth.

use crate::mesh::AnimatedMesh;
use glam::Vec3;

/// Sides of a tube.
const SIDES: u32 = 6;

/// Tube radius as a fraction of the scene's bounding-box diagonal: about 3 pixels across in a
/// 1280 × 720 preview.
pub const RADIUS_OF_DIAGONAL: f32 = 0.0025;

/// `meshes` with every faceless mesh of two or more vertices turned into a tube of `radius`.
pub fn ropes_as_tubes(meshes: &[AnimatedMesh], radius: f32) -> Vec<AnimatedMesh> {
    meshes
        .iter()
        .map(|m| {
            let n = m.frames.first().map_or(0, Vec::len);
            if !m.triangles.is_empty() || n < 2 {
                return m.clone();
            }
            AnimatedMesh {
                triangles: tube_triangles(n as u32),
                frames: m.frames.iter().map(|f| tube_vertices(f, radius)).collect(),
                uvs: None,
                topology: Vec::new(),
                solid: None,
                ..m.clone()
            }
        })
        .collect()
}

/// Rings of SIDES vertices around each point of the polyline.
fn tube_vertices(points: &[Vec3], radius: f32) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(points.len() * SIDES as usize);
    for i in 0..points.len() {
        let ahead = points[(i + 1).min(points.len() - 1)];
        let behind = points[i.saturating_sub(1)];
        let tangent = (ahead - behind).try_normalize().unwrap_or(Vec3::X);
        let (u, v) = tangent.any_orthonormal_pair();
        for k in 0..SIDES {
            let a = std::f32::consts::TAU * k as f32 / SIDES as f32;
            out.push(points[i] + (u * a.cos() + v * a.sin()) * radius);
        }
    }
    out
}

/// Two triangles per side between consecutive rings, facing outwards.
fn tube_triangles(points: u32) -> Vec<[u32; 3]> {
    let mut out = Vec::with_capacity(2 * SIDES as usize * (points as usize - 1));
    for i in 0..points - 1 {
        for k in 0..SIDES {
            let a = i * SIDES + k;
            let b = i * SIDES + (k + 1) % SIDES;
            let (c, d) = (a + SIDES, b + SIDES);
            out.push([a, b, d]);
            out.push([a, d, c]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rope_becomes_a_closed_tube_around_its_points() {
        let rope = AnimatedMesh {
            name: "rope".into(),
            triangles: Vec::new(),
            uvs: None,
            colour: [1.0; 4],
            frames: vec![(0..5)
                .map(|i| Vec3::new(i as f32 * 0.1, 1.0, 0.0))
                .collect()],
            topology: Vec::new(),
            solid: None,
        };
        let tube = &ropes_as_tubes(&[rope], 0.01)[0];
        assert_eq!(tube.frames[0].len(), 5 * SIDES as usize);
        assert_eq!(tube.triangles.len(), 2 * SIDES as usize * 4);
        for (i, ring) in tube.frames[0].chunks(SIDES as usize).enumerate() {
            for p in ring {
                let axis = Vec3::new(i as f32 * 0.1, 1.0, 0.0);
                assert!(((*p - axis).length() - 0.01).abs() < 1e-6);
                assert!((p.x - axis.x).abs() < 1e-6, "rings are square to the rope");
            }
        }
    }
}
