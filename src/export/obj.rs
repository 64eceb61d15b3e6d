//! Wavefront OBJ frames: one file per garment (and, when asked, character) per frame,
//! `<name>_<frame:04>.obj`, vertices in grid order (the order of `report.json` and of every
//! other export), with per-vertex normals, UVs, and triangles (a rope, which has no faces, is written as one polyline).
//!
//! Coordinates are printed in their shortest round-trip form (`ryu`: `1.0`, `-0.25`,
//! `1.5e-5`), so a reader gets back the exact `f32` values the simulation produced; `ryu` and
//! `itoa` write them a few times faster than `write!` (the OBJ frames were 4.2 ms of
//! `poncho_walk`'s frame of 17 ms).

use super::sink::{Frame, FrameSink, MeshInfo, Role, Written};
use crate::error::{Error, Result};
use glam::Vec3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The material library every OBJ frame refers to.
pub const MATERIALS: &str = "materials.mtl";

/// Writes `dir/materials.mtl`: one diffuse material per garment (and character), named after it.
pub fn write_materials(dir: &Path, materials: &[(String, [f32; 3])]) -> Result<PathBuf> {
    let path = dir.join(MATERIALS);
    let mut s = String::from("# drape materials: one per garment, named after it\n");
    for (name, [r, g, b]) in materials {
        let _ = writeln!(
            s,
            "\nnewmtl {name}\nKa 0 0 0\nKd {r} {g} {b}\nKs 0.1 0.1 0.1\nNs 32\nd 1\nillum 2"
        );
    }
    std::fs::write(&path, s).map_err(|e| Error::io(&path, "cannot write", e))?;
    Ok(path)
}

/// File name of `mesh`'s frame `frame` (the shot's number, four digits at least).
pub fn frame_file_name(mesh: &str, frame: u32) -> String {
    format!("{mesh}_{frame:04}.obj")
}

/// The OBJ text of one frame of a mesh: vertices in the order given, UVs when it has them,
/// smooth normals and faces, or one polyline for a mesh without faces (a rope).
pub fn frame_text(
    name: &str,
    frame: u32,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    uvs: Option<&[[f32; 2]]>,
) -> String {
    let mut s = String::with_capacity(positions.len() * 96 + triangles.len() * 40);
    let _ = writeln!(
        s,
        "# drape bake: {name}, frame {frame}\nmtllib {MATERIALS}\no {name}\nusemtl {name}"
    );
    let mut line = Line::default();
    for p in positions {
        line.floats(&mut s, "v", &p.to_array());
    }
    for uv in uvs.unwrap_or(&[]) {
        line.floats(&mut s, "vt", uv);
    }
    let textured = uvs.is_some();
    if triangles.is_empty() {
        s.push('l');
        for i in 1..=positions.len() as u32 {
            s.push(' ');
            line.corner(&mut s, i, textured, false);
        }
        s.push('\n');
        return s;
    }
    for n in crate::mesh::vertex_normals(triangles, positions) {
        line.floats(&mut s, "vn", &n.to_array());
    }
    for t in triangles {
        s.push('f');
        for i in t.map(|i| i + 1) {
            s.push(' ');
            line.corner(&mut s, i, textured, true);
        }
        s.push('\n');
    }
    s
}

/// The number formatters of one OBJ text.
#[derive(Default)]
struct Line {
    float: ryu::Buffer,
    int: itoa::Buffer,
}

impl Line {
    /// `tag x y z…` and a new line.
    fn floats(&mut self, s: &mut String, tag: &str, values: &[f32]) {
        s.push_str(tag);
        for &v in values {
            s.push(' ');
            s.push_str(self.float.format(v));
        }
        s.push('\n');
    }

    /// A face corner or polyline point: `i`, `i/i` (textured), and with `normal` `i//i` or
    /// `i/i/i`.
    fn corner(&mut self, s: &mut String, i: u32, textured: bool, normal: bool) {
        let i = self.int.format(i);
        s.push_str(i);
        match (textured, normal) {
            (false, false) => {}
            (true, false) => {
                s.push('/');
                s.push_str(i);
            }
            (false, true) => {
                s.push_str("//");
                s.push_str(i);
            }
            (true, true) => {
                s.push('/');
                s.push_str(i);
                s.push('/');
                s.push_str(i);
            }
        }
    }
}

/// Writes every garment's frame (and every character's, when asked) as
/// `<mesh>_<frame>.obj`, with `materials.mtl` beside them.
pub struct ObjFrames {
    dir: PathBuf,
    meshes: Vec<MeshInfo>,
    characters: bool,
    /// `materials.mtl`, then the garments' and the characters' frames.
    library: PathBuf,
    written: (Vec<PathBuf>, Vec<PathBuf>),
}

impl ObjFrames {
    /// Writes `dir/materials.mtl` for `meshes` (garments and characters) and returns the sink;
    /// `characters`: write the characters' frames too.
    pub fn new(dir: PathBuf, meshes: &[MeshInfo], characters: bool) -> Result<ObjFrames> {
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, "cannot create", e))?;
        let materials: Vec<(String, [f32; 3])> = meshes
            .iter()
            .filter(|m| m.role != Role::Collider)
            .map(|m| (m.name.clone(), [m.colour[0], m.colour[1], m.colour[2]]))
            .collect();
        let library = write_materials(&dir, &materials)?;
        Ok(ObjFrames {
            dir,
            meshes: meshes.to_vec(),
            characters,
            library,
            written: Default::default(),
        })
    }
}

impl FrameSink for ObjFrames {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        for (m, positions) in self.meshes.iter().zip(&frame.positions) {
            let files = match m.role {
                Role::Garment => &mut self.written.0,
                Role::Character if self.characters && !positions.is_empty() => &mut self.written.1,
                _ => continue,
            };
            let path = self.dir.join(frame_file_name(&m.name, frame.number));
            let text = frame_text(
                &m.name,
                frame.number,
                positions,
                &m.triangles,
                m.uvs.as_deref(),
            );
            std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
            files.push(path);
        }
        Ok(())
    }

    fn faces(&mut self, mesh: usize, _from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        self.meshes[mesh].triangles = triangles.to_vec();
        Ok(())
    }

    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>> {
        if frames == 0 {
            let _ = std::fs::remove_file(&self.library);
            return Ok(Vec::new());
        }
        let (garments, characters) = self.written;
        let mut out = vec![
            Written {
                format: "obj",
                files: garments,
                warnings: Vec::new(),
            },
            Written {
                format: "obj_materials",
                files: vec![self.library],
                warnings: Vec::new(),
            },
        ];
        if self.characters && !characters.is_empty() {
            out.push(Written {
                format: "character_obj",
                files: characters,
                warnings: Vec::new(),
            });
        }
        Ok(out)
    }
}
