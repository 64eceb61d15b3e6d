//! Triangles turned to face out of the bodies they bound, as drape's collisions need them: a
//! character's shell pushes cloth out along the skin's normals, which its triangles' winding
//! gives (counter-clockwise seen from outside), so a body wound inside out pushes cloth into
//! itself and the bake fails on its first frame.
//!
//! Two causes, two rules:
//! 1. **A mirroring transform** (a node scaled by −1, a rig mirrored at its root): glTF says a
//!    negative determinant of the transform that places a mesh reverses its winding, and the
//!    DCCs draw such meshes so. Every importer's triangles are turned here where that holds: a
//!    rigid mesh per node that places it, a skinned one per triangle by its corners' blended
//!    skin matrices in the rest pose (what [`Asset::pose`] applies). Silent: the file is right.
//! 2. **A mesh authored inside out** (faces flipped in the DCC; unseen where materials are
//!    two-sided): a character's mesh whose signed volume about its own centre is clearly
//!    negative, measured in the rest pose against its area, is turned whole, with a warning
//!    ([`Asset::turn_inside_out_meshes`]). Only characters: a garment's winding is the user's
//!    and exported as given. A sheet or plate (volume near zero against its area) is left as
//!    rule 1 leaves it.

use super::Asset;
use glam::{Mat3, Mat4, Vec3};

/// A mesh is inside out when its signed volume about its centre is below −this × its area^1.5
/// (a sphere is 0.094, a cube 0.068, an open half cylinder 0.3 m in radius and 1 m long 0.06; a plate of
/// 1 × 1 × 0.01 is 0.0034).
pub const INSIDE_OUT: f32 = 0.01;

impl Asset {
    /// Rule 1: turns the triangles of each mesh a mirroring transform places.
    pub(super) fn orient_by_transforms(&mut self) {
        let rest = self.node_transforms(None, 0.0);
        let linear = |m: &Mat4| Mat3::from_mat4(*m);
        for mesh in &mut self.meshes {
            if mesh.bones.is_empty() {
                mesh.flipped = (mesh.instances.iter())
                    .map(|&n| linear(&rest[n]).determinant() < 0.0)
                    .collect();
                continue;
            }
            let skins: Vec<Mat3> = (mesh.bones.iter())
                .map(|b| linear(&(rest[b.node] * b.offset)))
                .collect();
            let at_vertex: Vec<Mat3> = (mesh.weights.iter())
                .map(|w| match w.is_empty() {
                    true => Mat3::IDENTITY,
                    false => (w.iter())
                        .map(|&(b, wt)| skins[b as usize] * wt)
                        .fold(Mat3::ZERO, |s, m| s + m),
                })
                .collect();
            for t in &mut mesh.triangles {
                let sum = t.iter().fold(Mat3::ZERO, |s, &i| s + at_vertex[i as usize]);
                if sum.determinant() < 0.0 {
                    t.swap(1, 2);
                }
            }
        }
    }

    /// Rule 2, for a character: turns each copy of a mesh (a rigid mesh per node) that is wound
    /// inside out in the rest pose, returning a warning for each mesh turned.
    pub fn turn_inside_out_meshes(&mut self, file: &std::path::Path) -> Vec<String> {
        let pose = self.pose(None, 0.0);
        let mut turned: Vec<(usize, usize, f32)> = Vec::new(); // (mesh, copy, measure)
        self.for_each_copy(|m, at| {
            let corners = |&t: &[u32; 3]| at.place(t).map(|i| pose[i as usize]);
            let measure = inside_out_measure(m.triangles.iter().map(corners));
            if measure < -INSIDE_OUT {
                turned.push((at.mesh, at.copy, measure));
            }
        });
        let mut warnings = Vec::new();
        for &(k, copy, measure) in &turned {
            let mesh = &mut self.meshes[k];
            if mesh.bones.is_empty() {
                mesh.flipped.resize(mesh.instances.len(), false);
                mesh.flipped[copy] = !mesh.flipped[copy];
            } else {
                mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
            }
            let place = match mesh.bones.is_empty() && mesh.instances.len() > 1 {
                true => format!(
                    " where node {:?} places it",
                    self.nodes[mesh.instances[copy]].name
                ),
                false => String::new(),
            };
            warnings.push(format!(
                "{}: mesh {:?}{place} is wound inside out (its signed volume about its centre is {measure:.3} × its area^1.5: its faces point into it), so its normals would push cloth into the body; drape turns its triangles to face out",
                file.display(),
                mesh.name
            ));
        }
        warnings
    }
}

/// A closed or nearly closed surface's signed volume about its vertices' centre over its
/// area^1.5: about +0.07–0.09 for a convex body wound outward, the opposite for one wound
/// inside out, near 0 for a sheet; 0 for no area.
pub fn inside_out_measure(triangles: impl Iterator<Item = [Vec3; 3]> + Clone) -> f32 {
    let (sum, count) = (triangles.clone())
        .flatten()
        .fold((Vec3::ZERO, 0usize), |(s, n), v| (s + v, n + 1));
    if count == 0 {
        return 0.0;
    }
    let centre = sum / count as f32;
    let (mut volume, mut area) = (0.0f64, 0.0f64);
    for [a, b, c] in triangles {
        let [a, b, c] = [a - centre, b - centre, c - centre];
        volume += f64::from(a.dot(b.cross(c))) / 6.0;
        area += f64::from((b - a).cross(c - a).length()) / 2.0;
    }
    if area <= 0.0 {
        return 0.0;
    }
    (volume / area.powf(1.5)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned box from the origin to `size`, as 12 triangles wound outward.
    fn cube(size: Vec3) -> Vec<[Vec3; 3]> {
        let (v, t) = crate::mesh::cuboid(Vec3::ZERO, size);
        t.iter().map(|t| t.map(|i| v[i as usize])).collect()
    }

    #[test]
    fn a_box_wound_outward_measures_positive_inside_out_negative_a_plate_near_zero() {
        let outward = cube(Vec3::ONE);
        let measure = inside_out_measure(outward.iter().copied());
        // 1 m³ over (6 m²)^1.5, from the geometry alone.
        assert!((measure - 1.0 / 6f32.powf(1.5)).abs() < 1e-5, "{measure}");
        let turned = outward.iter().map(|&[a, b, c]| [a, c, b]);
        assert!((inside_out_measure(turned) + measure).abs() < 1e-6);
        let plate = cube(Vec3::new(1.0, 1.0, 0.01));
        let flat = inside_out_measure(plate.iter().copied());
        assert!(flat > 0.0 && flat < INSIDE_OUT, "{flat}");
        // Away from the origin it measures the same: about its own centre.
        let moved = outward.iter().map(|t| t.map(|v| v + Vec3::splat(40.0)));
        assert!((inside_out_measure(moved) - measure).abs() < 1e-4);
    }
}
