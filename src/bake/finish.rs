//! After the frame loop: the exports that need every frame (glTF, PC2, USD, materials, character
//! OBJs) and the preview render, recorded in the report.

use super::frames::Frames;
use crate::error::Result;
use crate::export::gltf::AnimatedMesh;
use crate::export::sequence::{collider_meshes, garment_meshes, write_exports, Recording};
use crate::gpu::GpuContext;
use crate::render::{render_sequence, RenderOptions};
use crate::report::Report;
use crate::scene::Scene;
use crate::sim::schedule;
use crate::sim::Simulation;
use glam::Vec3;
use std::path::Path;
use std::time::Instant;

/// Writes the exports of the baked frames into `dir` and renders the preview when asked;
/// `rest` holds the garments' positions before the first frame (export order).
pub fn write(
    scene: &Scene,
    sim: &Simulation,
    frames: &mut Frames,
    character_meshes: Vec<AnimatedMesh>,
    rest: &[Vec3],
    dir: &Path,
    report: &mut Report,
) -> Result<()> {
    let model = sim.model();
    let mut meshes = garment_meshes(&model.garments, &frames.recorded);
    for (mesh, history) in meshes.iter_mut().zip(std::mem::take(&mut frames.topology)) {
        if history.len() > 1 {
            mesh.topology = history;
        }
    }
    let baked = report.frames_baked as usize;
    for mut c in character_meshes {
        // Character frame k is the pose at garment frame k (frame 0 is the start); a static
        // mesh (one frame, like a stool) stays one frame.
        if c.frames.len() > 1 {
            c.frames = c.frames.into_iter().skip(1).take(baked).collect();
        }
        if c.frames.len() == baked || c.frames.len() == 1 {
            meshes.push(c);
        }
    }
    let characters = meshes.len() - model.garments.len();
    let times: Vec<f32> = (1..=baked).map(|k| k as f32 / scene.fps).collect();
    meshes.extend(collider_meshes(&scene.colliders, &times));
    let rest: Vec<Vec<Vec3>> = model
        .garments
        .iter()
        .map(|g| rest[g.export.clone()].to_vec())
        .collect();
    let mut materials: Vec<(String, [f32; 3])> = model
        .garments
        .iter()
        .map(|g| (g.name.clone(), g.colour))
        .collect();
    materials.extend(
        meshes[model.garments.len()..]
            .iter()
            .map(|m| (m.name.clone(), [m.colour[0], m.colour[1], m.colour[2]])),
    );
    let recorded = Recording {
        meshes: if super::records(&scene.output) {
            &meshes
        } else {
            &[]
        },
        garments: model.garments.len(),
        characters,
        rest: &rest,
        materials: &materials,
        fps: scene.fps,
        first_frame: scene.frame_start,
    };
    let exporting = Instant::now();
    let (outputs, exports) = write_exports(dir, &scene.name, &scene.output, &recorded)?;
    frames.around.lap(schedule::timed("export"), exporting);
    report.outputs = outputs;
    report.exports = exports;
    if scene.output.preview {
        preview(scene, &meshes, dir, report);
    }
    Ok(())
}

/// Renders the preview. One that cannot be made (no adapter at all) costs the bake nothing
/// else: the frames and exports stay, and the report says why there are no images.
fn preview(scene: &Scene, meshes: &[AnimatedMesh], dir: &Path, report: &mut Report) {
    let out = &scene.output;
    let options = RenderOptions {
        width: out.preview_size[0],
        height: out.preview_size[1],
        wireframe: out.wireframe,
    };
    match GpuContext::new(false)
        .and_then(|ctx| render_sequence(ctx, meshes, options, dir, scene.frame_start))
    {
        Ok(summary) => {
            report.outputs.preview = Some(summary.contact_sheet.clone());
            report.preview = Some(summary);
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(dir.join("preview"));
            report.warnings.push(format!("preview not rendered: {e}"));
        }
    }
}
