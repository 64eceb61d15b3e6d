//! Point caches that animation packages read: PC2 (Blender, Maya, 3ds Max) with a rest OBJ, and
//! USD (`.usda`) with time-sampled points. Both hold drape's coordinates unchanged: metres, Y up.
//!
//! PC2 (`shared/reference/formats.md`): little-endian, a 32-byte header
//! (`"POINTCACHE2\0"`, version 1, points, start frame, frames per sample, samples) and then every
//! sample's points as f32 x, y, z. Its vertex order is the rest OBJ's (grid order, as every drape
//! export). Import the rest OBJ with Y up and no axis conversion, then add the cache.
//!
//! USD: one text layer with `metersPerUnit = 1` and `upAxis = "Y"` always authored, the frame
//! range and rate, and one `Mesh` (or, for a rope, linear `BasisCurves`) per garment with
//! `points.timeSamples` and `extent.timeSamples` keyed by frame number.

use super::gltf::AnimatedMesh;
use crate::error::{Error, Result};
use glam::Vec3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The PC2 bytes of `frames` (every frame the same number of points), first frame numbered
/// `start_frame`.
pub fn pc2_bytes(frames: &[Vec<Vec3>], start_frame: f32) -> Vec<u8> {
    let points = frames.first().map_or(0, Vec::len);
    let mut out = Vec::with_capacity(32 + frames.len() * points * 12);
    out.extend_from_slice(b"POINTCACHE2\0");
    out.extend_from_slice(&1i32.to_le_bytes());
    out.extend_from_slice(&(points as i32).to_le_bytes());
    out.extend_from_slice(&start_frame.to_le_bytes());
    out.extend_from_slice(&1.0f32.to_le_bytes());
    out.extend_from_slice(&(frames.len() as i32).to_le_bytes());
    for frame in frames {
        for p in frame {
            for c in p.to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out
}

/// Writes `<name>.pc2` and `<name>_rest.obj` for each mesh into `dir` (frames numbered from
/// `first_frame`); `rest` holds each mesh's rest positions.
pub fn write_pc2(
    dir: &Path,
    meshes: &[AnimatedMesh],
    rest: &[Vec<Vec3>],
    first_frame: u32,
) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for (mesh, rest) in meshes.iter().zip(rest) {
        let path = dir.join(format!("{}.pc2", mesh.name));
        std::fs::write(&path, pc2_bytes(&mesh.frames, first_frame as f32))
            .map_err(|e| Error::io(&path, "cannot write", e))?;
        written.push(path);
        let path = dir.join(format!("{}_rest.obj", mesh.name));
        let mut text = format!(
            "# drape rest mesh of {} (vertex order of {0}.pc2)\no {0}\n",
            mesh.name
        );
        for p in rest {
            let _ = writeln!(text, "v {} {} {}", p.x, p.y, p.z);
        }
        if mesh.triangles.is_empty() {
            text.push('l');
            for i in 1..=rest.len() {
                let _ = write!(text, " {i}");
            }
            text.push('\n');
        }
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| i + 1);
            let _ = writeln!(text, "f {a} {b} {c}");
        }
        std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
        written.push(path);
    }
    Ok(written)
}

/// A USD prim name: letters, digits and underscores, not starting with a digit.
fn prim_name(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

fn points(out: &mut String, ps: &[Vec3]) {
    out.push('[');
    for (i, p) in ps.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        let _ = write!(out, "({}, {}, {})", p.x, p.y, p.z);
    }
    out.push(']');
}

/// The `.usda` text of `meshes` animated at `fps`, frames numbered from `first_frame`.
pub fn usda_text(meshes: &[AnimatedMesh], fps: f32, first_frame: u32) -> String {
    let frames = meshes.first().map_or(0, |m| m.frames.len());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "#usda 1.0\n(\n    defaultPrim = \"bake\"\n    doc = \"drape {}\"\n    metersPerUnit = 1\n    upAxis = \"Y\"\n    startTimeCode = {first_frame}\n    endTimeCode = {}\n    timeCodesPerSecond = {fps}\n    framesPerSecond = {fps}\n)\n\ndef Xform \"bake\"\n{{",
        env!("CARGO_PKG_VERSION"),
        first_frame as usize + frames.max(1) - 1
    );
    let mut used = Vec::new();
    for mesh in meshes {
        let mut name = prim_name(&mesh.name);
        while used.contains(&name) {
            name.push('_');
        }
        used.push(name.clone());
        let curves = mesh.triangles.is_empty();
        let _ = writeln!(
            s,
            "    def {} \"{name}\"\n    {{",
            if curves { "BasisCurves" } else { "Mesh" }
        );
        if curves {
            let n = mesh.frames.first().map_or(0, Vec::len);
            let _ = writeln!(
                s,
                "        uniform token type = \"linear\"\n        int[] curveVertexCounts = [{n}]"
            );
        } else {
            let counts = vec!["3"; mesh.triangles.len()].join(", ");
            let indices: Vec<String> = mesh
                .triangles
                .iter()
                .flatten()
                .map(|i| i.to_string())
                .collect();
            let _ = writeln!(s, "        int[] faceVertexCounts = [{counts}]");
            let _ = writeln!(
                s,
                "        int[] faceVertexIndices = [{}]",
                indices.join(", ")
            );
            s.push_str("        uniform token subdivisionScheme = \"none\"\n        uniform bool doubleSided = 1\n");
        }
        let [r, g, b, _] = mesh.colour;
        let _ = writeln!(
            s,
            "        color3f[] primvars:displayColor = [({r}, {g}, {b})]"
        );
        if let Some(first) = mesh.frames.first() {
            s.push_str("        point3f[] points = ");
            points(&mut s, first);
            s.push('\n');
        }
        // Texture coordinates and smooth normals per vertex, so a textured, shaded garment
        // renders from the layer alone (the normals follow every frame).
        if let (Some(uvs), false) = (&mesh.uvs, curves) {
            s.push_str("        texCoord2f[] primvars:st = [");
            for (i, [u, v]) in uvs.iter().enumerate() {
                if i > 0 {
                    s.push_str(", ");
                }
                let _ = write!(s, "({u}, {v})");
            }
            s.push_str("] (\n            interpolation = \"vertex\"\n        )\n");
        }
        if !curves {
            s.push_str("        normal3f[] primvars:normals (\n            interpolation = \"vertex\"\n        )\n");
            s.push_str("        normal3f[] primvars:normals.timeSamples = {\n");
            for (k, frame) in mesh.frames.iter().enumerate() {
                let _ = write!(s, "            {}: ", first_frame as usize + k);
                points(&mut s, &super::obj::vertex_normals(&mesh.triangles, frame));
                s.push_str(",\n");
            }
            s.push_str("        }\n");
        }
        s.push_str("        point3f[] points.timeSamples = {\n");
        for (k, frame) in mesh.frames.iter().enumerate() {
            let _ = write!(s, "            {}: ", first_frame as usize + k);
            points(&mut s, frame);
            s.push_str(",\n");
        }
        s.push_str("        }\n        float3[] extent.timeSamples = {\n");
        for (k, frame) in mesh.frames.iter().enumerate() {
            let (lo, hi) = frame.iter().fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(lo, hi), p| (lo.min(*p), hi.max(*p)),
            );
            let _ = write!(s, "            {}: ", first_frame as usize + k);
            points(&mut s, &[lo, hi]);
            s.push_str(",\n");
        }
        s.push_str("        }\n    }\n");
    }
    s.push_str("}\n");
    s
}

/// Writes `<stem>.usda` into `dir`, frames numbered from `first_frame`.
pub fn write_usda(
    dir: &Path,
    stem: &str,
    meshes: &[AnimatedMesh],
    fps: f32,
    first_frame: u32,
) -> Result<PathBuf> {
    let path = dir.join(format!("{stem}.usda"));
    std::fs::write(&path, usda_text(meshes, fps, first_frame))
        .map_err(|e| Error::io(&path, "cannot write", e))?;
    Ok(path)
}
