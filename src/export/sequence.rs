//! The exports written once the simulation is done, from the frames a bake recorded: glTF, PC2
//! caches with rest meshes, USD, and the characters' OBJ frames; each timed and measured for the
//! report.

use super::gltf::{self, AnimatedMesh, Container};
use super::{obj, pointcache};
use crate::error::{Error, Result};
use crate::report::{ExportReport, Outputs};
use crate::scene::{ColliderKind, ColliderSpec, GltfOutput, OutputSpec};
use crate::sim::model::GarmentRange;
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Colour of characters in exports and previews (linear RGB).
pub const CHARACTER_COLOUR: [f32; 3] = [0.72, 0.66, 0.60];

/// One animated mesh per garment from per-frame positions in export order.
pub fn garment_meshes(garments: &[GarmentRange], frames: &[Vec<Vec3>]) -> Vec<AnimatedMesh> {
    garments
        .iter()
        .map(|g| AnimatedMesh {
            name: g.name.clone(),
            triangles: g.triangles.clone(),
            uvs: Some(g.uvs.clone()),
            colour: [g.colour[0], g.colour[1], g.colour[2], 1.0],
            frames: frames
                .iter()
                .map(|f| g.surface(&f[g.export.clone()]))
                .collect(),
            topology: Vec::new(),
        })
        .collect()
}

/// Colour of analytic colliders in exports and previews (linear RGB).
pub const COLLIDER_COLOUR: [f32; 3] = [0.45, 0.47, 0.52];

/// Meshes of the scene's sphere, box, capsule, funnel and wedge colliders, so exports and previews show what
/// the cloth meets: one frame for a static collider, one per time in `times` [s] for a keyframed
/// one. Planes are left out: the preview's floor stands for them.
pub fn collider_meshes(colliders: &[ColliderSpec], times: &[f32]) -> Vec<AnimatedMesh> {
    colliders
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let v = |a: Option<[f32; 3]>| a.map(Vec3::from);
            let (positions, triangles) = match c.kind {
                ColliderKind::Plane => return None,
                ColliderKind::Sphere => rounded(v(c.center)?, v(c.center)?, c.radius?),
                ColliderKind::Capsule => rounded(v(c.start)?, v(c.end)?, c.radius?),
                ColliderKind::Box | ColliderKind::Wedge => {
                    // Built at the origin, then turned and placed like the collider.
                    let half = v(c.size)? * 0.5;
                    let (p, t) = if c.kind == ColliderKind::Box {
                        cuboid(Vec3::ZERO, half)
                    } else {
                        prism(half)
                    };
                    let shape = crate::collide::Collider::from_spec(c).shape;
                    let (crate::collide::Shape::Box {
                        center, rotation, ..
                    }
                    | crate::collide::Shape::Wedge {
                        center, rotation, ..
                    }) = shape
                    else {
                        return None;
                    };
                    (p.iter().map(|q| center + rotation * *q).collect(), t)
                }
                ColliderKind::Funnel => frustum(v(c.center)?, c.radius?, c.top_radius?, c.height?),
            };
            let frames = if c.keyframes.is_empty() {
                vec![positions]
            } else {
                let pivot = crate::collide::Collider::from_spec(c).shape.centre();
                let track = crate::sim::attach::Track::new(&c.keyframes, pivot);
                times
                    .iter()
                    .map(|&t| positions.iter().map(|p| track.apply(*p, t)).collect())
                    .collect()
            };
            Some(AnimatedMesh {
                name: format!("collider{i}"),
                triangles,
                uvs: None,
                colour: [
                    COLLIDER_COLOUR[0],
                    COLLIDER_COLOUR[1],
                    COLLIDER_COLOUR[2],
                    1.0,
                ],
                frames,
                topology: Vec::new(),
            })
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

/// Total size of `files` [bytes].
fn size_of(files: &[PathBuf]) -> u64 {
    files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum()
}

/// What [`write_exports`] writes from.
pub struct Recording<'a> {
    /// The garments followed by the characters, every frame (empty when only OBJ frames were
    /// asked for: nothing else needs them).
    pub meshes: &'a [AnimatedMesh],
    /// How many of `meshes` are garments, and how many characters follow them (colliders come
    /// last).
    pub garments: usize,
    pub characters: usize,
    /// Each garment's rest positions (the PC2 rest meshes).
    pub rest: &'a [Vec<Vec3>],
    /// Name and colour of every garment and character (the OBJ material library).
    pub materials: &'a [(String, [f32; 3])],
    pub fps: f32,
    /// The shot's number of the first frame (`frame_start`).
    pub first_frame: u32,
}

/// Writes the exports `spec` asks for into `dir`, named after `stem`.
pub fn write_exports(
    dir: &Path,
    stem: &str,
    spec: &OutputSpec,
    recording: &Recording,
) -> Result<(Outputs, Vec<ExportReport>)> {
    let (meshes, garments, rest, fps) = (
        recording.meshes,
        recording.garments,
        recording.rest,
        recording.fps,
    );
    let mut outputs = Outputs {
        obj: spec.obj.then(|| "obj".to_string()),
        ..Outputs::default()
    };
    let mut reports = Vec::new();
    let mut timed = |format: &'static str, write: &mut dyn FnMut() -> Result<Vec<PathBuf>>| {
        let start = Instant::now();
        let files = write()?;
        reports.push(ExportReport {
            format,
            files: files.len(),
            bytes: size_of(&files),
            ms: start.elapsed().as_secs_f64() * 1e3,
        });
        Ok::<_, Error>(files)
    };
    if spec.gltf != GltfOutput::None {
        let container = match spec.gltf {
            GltfOutput::Gltf => Container::Separate,
            _ => Container::Binary,
        };
        let files = timed("gltf", &mut || {
            gltf::write(dir, stem, meshes, fps, container)
        })?;
        outputs.gltf = files
            .first()
            .and_then(|f| f.file_name())
            .map(|f| f.to_string_lossy().into_owned());
    }
    if spec.pc2 {
        let folder = dir.join("pc2");
        std::fs::create_dir(&folder).map_err(|e| Error::io(&folder, "cannot create", e))?;
        timed("pc2", &mut || {
            pointcache::write_pc2(&folder, &meshes[..garments], rest, recording.first_frame)
        })?;
        outputs.pc2 = Some("pc2".into());
    }
    if spec.usd {
        let files = timed("usd", &mut || {
            Ok(vec![pointcache::write_usda(
                dir,
                stem,
                meshes,
                fps,
                recording.first_frame,
            )?])
        })?;
        outputs.usd = files
            .first()
            .and_then(|f| f.file_name())
            .map(|f| f.to_string_lossy().into_owned());
    }
    if spec.obj {
        let folder = dir.join("obj");
        timed("obj_materials", &mut || {
            Ok(vec![obj::write_materials(&folder, recording.materials)?])
        })?;
        let characters = &meshes
            [garments.min(meshes.len())..(garments + recording.characters).min(meshes.len())];
        if spec.character_obj && !characters.is_empty() {
            timed("character_obj", &mut || {
                let mut files = Vec::new();
                for m in characters {
                    for (k, frame) in m.frames.iter().enumerate() {
                        files.push(obj::write_mesh_frame(
                            &folder,
                            &m.name,
                            recording.first_frame + k as u32,
                            frame,
                            &m.triangles,
                        )?);
                    }
                }
                Ok(files)
            })?;
        }
    }
    Ok((outputs, reports))
}

/// An indexed mesh: vertices that sit at the same place on every frame become one, and faces
/// that collapse to a line or point are dropped. Importers split a vertex per face corner (an
/// OBJ without vertex joining: the mannequin has 5 040 vertices for 858 positions), and every
/// copy would be stored in every frame of the exports. A vertex that only starts at the same
/// place (a seam a skin pulls apart) stays apart.
pub fn weld(triangles: &[[u32; 3]], frames: &[Vec<Vec3>]) -> (Vec<[u32; 3]>, Vec<Vec<Vec3>>) {
    let Some(first) = frames.first() else {
        return (triangles.to_vec(), Vec::new());
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
    let faces = triangles
        .iter()
        .map(|t| t.map(|i| map[i as usize]))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    let frames = frames
        .iter()
        .map(|f| kept.iter().map(|&v| f[v]).collect())
        .collect();
    (faces, frames)
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
