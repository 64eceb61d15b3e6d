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
                .map(|f| f[g.export.clone()].to_vec())
                .collect(),
        })
        .collect()
}

/// Colour of analytic colliders in exports and previews (linear RGB).
pub const COLLIDER_COLOUR: [f32; 3] = [0.45, 0.47, 0.52];

/// Static meshes of the scene's sphere colliders (one frame each), so exports and previews show
/// what the cloth lies on. Planes are left out: the preview's floor stands for them.
pub fn collider_meshes(colliders: &[ColliderSpec]) -> Vec<AnimatedMesh> {
    let (rings, segments) = (16u32, 32u32);
    colliders
        .iter()
        .enumerate()
        .filter(|(_, c)| c.kind == ColliderKind::Sphere)
        .filter_map(|(i, c)| {
            let (centre, radius) = (Vec3::from(c.center?), c.radius?);
            let mut positions = Vec::new();
            for r in 0..=rings {
                let theta = std::f32::consts::PI * r as f32 / rings as f32;
                for s in 0..segments {
                    let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                    let d = Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    );
                    positions.push(centre + d * radius);
                }
            }
            let mut triangles = Vec::new();
            for r in 0..rings {
                for s in 0..segments {
                    let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
                    let (c, d) = (a + segments, b + segments);
                    triangles.push([a, b, c]);
                    triangles.push([b, d, c]);
                }
            }
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
                frames: vec![positions],
            })
        })
        .collect()
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
            pointcache::write_pc2(&folder, &meshes[..garments], rest)
        })?;
        outputs.pc2 = Some("pc2".into());
    }
    if spec.usd {
        let files = timed("usd", &mut || {
            Ok(vec![pointcache::write_usda(dir, stem, meshes, fps)?])
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
                            k as u32 + 1,
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
