//! The bake's outputs, opened before the first frame and fed each frame as it is made: the
//! sinks the scene asks for (OBJ frames, glTF, PC2) and, for the USD layer and the preview,
//! the frames spooled to disk; closed after the last frame, when the USD layer and the preview
//! are made from the spool. Each is recorded in the report.

use crate::error::Result;
use crate::export::alembic::AlembicFile;
use crate::export::gltf::{Container, GltfFile};
use crate::export::obj::ObjFrames;
use crate::export::pointcache::{write_usda, Pc2Files};
use crate::export::sequence::BakeMeshes;
use crate::export::sink::{Frame, Output, Sinks};
use crate::export::spool::{Recorded, Spool};
use crate::gpu::GpuContext;
use crate::render::{render_sequence, RenderOptions};
use crate::report::{ExportReport, Outputs, Report};
use crate::scene::{GltfOutput, Scene};
use glam::Vec3;
use std::path::Path;
use std::time::Instant;

/// The open outputs of a bake.
pub struct Exports {
    output: Output,
    spool: Option<Spool>,
    /// Baked frames before the first one written: a pre-roll the exports leave out.
    skip: usize,
}

impl Exports {
    /// Opens the outputs `scene` asks for in `dir`; `rest` holds the garments' particles before
    /// the first frame (export order). `threaded`: write on a thread of their own. `scene`
    /// is the shot the exports show: a bake's pre-roll frames (`lead_in` of the baked scene
    /// beyond this one's) are passed over.
    pub fn open(
        scene: &Scene,
        dir: &Path,
        meshes: &BakeMeshes,
        rest: &[Vec3],
        threaded: bool,
    ) -> Result<Exports> {
        let spec = &scene.output;
        let mut sinks = Sinks::default();
        if spec.obj {
            let obj = ObjFrames::new(dir.join("obj"), &meshes.info, spec.character_obj)?;
            sinks.push(Box::new(obj));
        }
        if spec.gltf != GltfOutput::None {
            let container = match spec.gltf {
                GltfOutput::Gltf => Container::Separate,
                _ => Container::Binary,
            };
            let gltf = GltfFile::create(dir, &scene.name, container, scene.fps, &meshes.info)?;
            sinks.push(Box::new(gltf));
        }
        if spec.pc2 {
            let rest = meshes.garment_surfaces(rest);
            let pc2 = Pc2Files::create(dir.join("pc2"), &meshes.info, rest, scene.frame_start)?;
            sinks.push(Box::new(pc2));
        }
        if spec.alembic {
            let path = dir.join(format!("{}.abc", scene.name));
            let abc = AlembicFile::create(
                path,
                &scene.name,
                scene.fps,
                &meshes.info,
                spec.character_obj,
            )?;
            sinks.push(Box::new(abc));
        }
        let spool = (spec.usd || spec.preview)
            .then(|| Spool::create(dir.join(".frames.spool"), &meshes.info))
            .transpose()?;
        Ok(Exports {
            output: Output::new(sinks, threaded),
            spool,
            skip: 0,
        })
    }

    /// True when nothing is written per frame.
    pub fn is_empty(&self) -> bool {
        self.spool.is_none() && matches!(&self.output, Output::Inline(s) if s.is_empty())
    }

    /// Passes over the first `frames` baked frames (a pre-roll the exports leave out).
    pub fn skipping(mut self, frames: usize) -> Exports {
        self.skip = frames;
        self
    }

    /// Writes the next frame (none of those passed over).
    pub fn frame(&mut self, mut frame: Frame) -> Result<()> {
        if frame.index < self.skip {
            return Ok(());
        }
        frame.index -= self.skip;
        if let Some(spool) = &mut self.spool {
            spool.frame(&frame)?;
        }
        self.output.frame(frame)
    }

    /// From frame index `from` on, mesh `mesh` has these faces.
    pub fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        let from = from.saturating_sub(self.skip);
        if let Some(spool) = &mut self.spool {
            spool.faces(mesh, from, triangles);
        }
        self.output.faces(mesh, from, triangles)
    }

    /// Closes every output after `frames` frames, writes the USD layer and renders the preview
    /// from the spool, and records them in `report`.
    pub fn close(
        self,
        scene: &Scene,
        dir: &Path,
        frames: usize,
        report: &mut Report,
    ) -> Result<()> {
        let frames = frames.saturating_sub(self.skip);
        let (mut exports, written) = self.output.close(frames)?;
        let spec = &scene.output;
        let mut outputs = Outputs {
            obj: spec.obj.then(|| "obj".to_string()),
            pc2: spec.pc2.then(|| "pc2".to_string()),
            ..Outputs::default()
        };
        for w in written {
            if w.format == "alembic" {
                outputs.alembic = w
                    .files
                    .first()
                    .and_then(|f| f.file_name())
                    .map(|f| f.to_string_lossy().into_owned());
            }
            if w.format == "gltf" {
                outputs.gltf = w
                    .files
                    .first()
                    .and_then(|f| f.file_name())
                    .map(|f| f.to_string_lossy().into_owned());
            }
            report.warnings.extend(w.warnings);
        }
        let recorded = self.spool.map(Spool::into_recorded).transpose()?;
        if let (Some(mut recorded), true) = (recorded, frames > 0) {
            if spec.usd {
                let start = Instant::now();
                let path = write_usda(
                    dir,
                    &scene.name,
                    &mut recorded,
                    scene.fps,
                    scene.frame_start,
                )?;
                exports.push(ExportReport {
                    format: "usd",
                    files: 1,
                    bytes: std::fs::metadata(&path).map_or(0, |m| m.len()),
                    ms: start.elapsed().as_secs_f64() * 1e3,
                });
                outputs.usd = path.file_name().map(|f| f.to_string_lossy().into_owned());
            }
            if spec.preview {
                preview(scene, &mut recorded, dir, report, &mut outputs);
            }
        }
        if frames > 0 {
            report.outputs = outputs;
            report.exports = exports;
        }
        Ok(())
    }
}

/// Renders the preview. One that cannot be made (no adapter at all) costs the bake nothing
/// else: the frames and exports stay, and the report says why there are no images.
fn preview(
    scene: &Scene,
    recorded: &mut Recorded,
    dir: &Path,
    report: &mut Report,
    outputs: &mut Outputs,
) {
    let out = &scene.output;
    let options = RenderOptions {
        width: out.preview_size[0],
        height: out.preview_size[1],
        wireframe: out.wireframe,
    };
    match GpuContext::new(false)
        .and_then(|ctx| render_sequence(ctx, recorded, options, dir, scene.frame_start))
    {
        Ok(summary) => {
            outputs.preview = Some(summary.contact_sheet.clone());
            report.preview = Some(summary);
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(dir.join("preview"));
            report.warnings.push(format!("preview not rendered: {e}"));
        }
    }
}
