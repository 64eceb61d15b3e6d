//! Wavefront OBJ frames: one file per garment per frame, `<garment>_<frame:04>.obj`, vertices in
//! grid order (the order of `report.json` and of every other export), with per-vertex normals,
//! UVs, and triangles (a rope, which has no faces, is written as one polyline).
//!
//! Coordinates are printed with Rust's shortest round-trip formatting, so a reader gets back the
//! exact `f32` values the simulation produced.

use crate::error::{Error, Result};
use crate::sim::model::GarmentRange;
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

/// Writes a mesh frame with no UVs (a character) as `dir/<name>_<frame:04>.obj`.
pub fn write_mesh_frame(
    dir: &Path,
    name: &str,
    frame: u32,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<PathBuf> {
    let path = dir.join(frame_file_name(name, frame));
    let mut s = String::with_capacity(positions.len() * 80 + triangles.len() * 40);
    let _ = writeln!(
        s,
        "# drape bake: {name}, frame {frame}\nmtllib {MATERIALS}\no {name}\nusemtl {name}"
    );
    for p in positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for n in vertex_normals(triangles, positions) {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    for t in triangles {
        let [a, b, c] = t.map(|i| i + 1);
        let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
    }
    std::fs::write(&path, s).map_err(|e| Error::io(&path, "cannot write", e))?;
    Ok(path)
}

/// File name of `garment`'s frame `frame` (1-based).
pub fn frame_file_name(garment: &str, frame: u32) -> String {
    format!("{garment}_{frame:04}.obj")
}

/// Writes one garment's frame into `dir`; `positions` are the garment's particles in grid order
/// (a mesh garment writes its embedded surface).
pub fn write_frame(
    dir: &Path,
    garment: &GarmentRange,
    frame: u32,
    positions: &[Vec3],
) -> Result<PathBuf> {
    let path = dir.join(frame_file_name(&garment.name, frame));
    let text = frame_text(garment, frame, positions);
    std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
    Ok(path)
}

/// The OBJ text of one frame; `particles` are the garment's particles in grid order.
pub fn frame_text(garment: &GarmentRange, frame: u32, particles: &[Vec3]) -> String {
    let surface = garment.surface(particles);
    let positions = &surface[..];
    let mut s = String::with_capacity(positions.len() * 96);
    let _ = writeln!(s, "# drape bake: garment {}, frame {frame}", garment.name);
    let _ = writeln!(s, "mtllib {MATERIALS}");
    let _ = writeln!(s, "o {}", garment.name);
    let _ = writeln!(s, "usemtl {}", garment.name);
    for p in positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for uv in &garment.uvs {
        let _ = writeln!(s, "vt {} {}", uv[0], uv[1]);
    }
    if garment.triangles.is_empty() {
        s.push('l');
        for i in 1..=positions.len() {
            let _ = write!(s, " {i}/{i}");
        }
        s.push('\n');
        return s;
    }
    for n in vertex_normals(&garment.triangles, positions) {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    for t in &garment.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        let _ = writeln!(s, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
    }
    s
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
