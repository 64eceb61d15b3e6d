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

use super::sink::{Frame, FrameSink, MeshInfo, Role, Written};
use super::spool::Recorded;
use crate::error::{Error, Result};
use glam::Vec3;
use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The PC2 header for `points` points per sample, `samples` samples from `start_frame`.
pub fn pc2_header(points: usize, start_frame: f32, samples: usize) -> [u8; 32] {
    let mut h = [0u8; 32];
    h[..12].copy_from_slice(b"POINTCACHE2\0");
    h[12..16].copy_from_slice(&1i32.to_le_bytes());
    h[16..20].copy_from_slice(&(points as i32).to_le_bytes());
    h[20..24].copy_from_slice(&start_frame.to_le_bytes());
    h[24..28].copy_from_slice(&1.0f32.to_le_bytes());
    h[28..32].copy_from_slice(&(samples as i32).to_le_bytes());
    h
}

/// One garment's cache being written.
struct Pc2Cache {
    mesh: usize,
    path: PathBuf,
    out: BufWriter<File>,
}

/// Writes `pc2/<garment>.pc2` a frame at a time (the header's sample count is set at the end),
/// and `pc2/<garment>_rest.obj` with the garment's faces at the end.
pub struct Pc2Files {
    dir: PathBuf,
    meshes: Vec<MeshInfo>,
    caches: Vec<Pc2Cache>,
    /// Each garment's rest positions (export order).
    rest: Vec<Vec<Vec3>>,
}

impl Pc2Files {
    /// Starts a cache per garment of `meshes` in `dir` (created), frames numbered from
    /// `first_frame`; `rest` holds each garment's rest positions, in garment order.
    pub fn create(
        dir: PathBuf,
        meshes: &[MeshInfo],
        rest: Vec<Vec<Vec3>>,
        first_frame: u32,
    ) -> Result<Pc2Files> {
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, "cannot create", e))?;
        let mut caches = Vec::new();
        for (i, m) in meshes.iter().enumerate() {
            if m.role != Role::Garment {
                continue;
            }
            let path = dir.join(format!("{}.pc2", m.name));
            let io = |e| Error::io(&path, "cannot write", e);
            let mut out = BufWriter::new(File::create(&path).map_err(io)?);
            out.write_all(&pc2_header(m.vertices, first_frame as f32, 0))
                .map_err(io)?;
            caches.push(Pc2Cache { mesh: i, path, out });
        }
        Ok(Pc2Files {
            dir,
            meshes: meshes.to_vec(),
            caches,
            rest,
        })
    }

    /// Writes `<name>_rest.obj`: the rest positions and the garment's (last) faces.
    fn rest_obj(&self, mesh: &MeshInfo, rest: &[Vec3]) -> Result<PathBuf> {
        let path = self.dir.join(format!("{}_rest.obj", mesh.name));
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
        Ok(path)
    }
}

impl FrameSink for Pc2Files {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        for c in &mut self.caches {
            c.out
                .write_all(bytemuck::cast_slice(&frame.positions[c.mesh]))
                .map_err(|e| Error::io(&c.path, "cannot write", e))?;
        }
        Ok(())
    }

    fn faces(&mut self, mesh: usize, _from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        self.meshes[mesh].triangles = triangles.to_vec();
        Ok(())
    }

    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>> {
        if frames == 0 {
            drop(self.caches);
            let _ = std::fs::remove_dir_all(&self.dir);
            return Ok(Vec::new());
        }
        let mut files = Vec::new();
        for (c, rest) in self.caches.iter().zip(&self.rest) {
            files.push(self.rest_obj(&self.meshes[c.mesh], rest)?);
        }
        for c in self.caches {
            let io = |e| Error::io(&c.path, "cannot write", e);
            let mut file = c.out.into_inner().map_err(|e| io(e.into_error()))?;
            file.seek(SeekFrom::Start(28))
                .and_then(|_| file.write_all(&(frames as i32).to_le_bytes()))
                .map_err(io)?;
            files.push(c.path);
        }
        Ok(vec![Written {
            format: "pc2",
            files,
            warnings: Vec::new(),
        }])
    }
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

/// Writes `<stem>.usda` into `dir` from the spooled frames, frames numbered from
/// `first_frame`: a mesh at a time, each attribute's samples read back a frame at a time.
pub fn write_usda(
    dir: &Path,
    stem: &str,
    recorded: &mut Recorded,
    fps: f32,
    first_frame: u32,
) -> Result<PathBuf> {
    let path = dir.join(format!("{stem}.usda"));
    let io = |e| Error::io(&path, "cannot write", e);
    let mut out = BufWriter::new(File::create(&path).map_err(io)?);
    let frames = recorded.frames;
    write!(
        out,
        "#usda 1.0\n(\n    defaultPrim = \"bake\"\n    doc = \"drape {}\"\n    metersPerUnit = 1\n    upAxis = \"Y\"\n    startTimeCode = {first_frame}\n    endTimeCode = {}\n    timeCodesPerSecond = {fps}\n    framesPerSecond = {fps}\n)\n\ndef Xform \"bake\"\n{{\n",
        env!("CARGO_PKG_VERSION"),
        first_frame as usize + frames.max(1) - 1
    )
    .map_err(io)?;
    let mut used = Vec::new();
    for m in 0..recorded.meshes.len() {
        let mut name = prim_name(&recorded.meshes[m].name);
        while used.contains(&name) {
            name.push('_');
        }
        used.push(name.clone());
        usd_mesh(&mut out, recorded, m, &name, first_frame, fps).map_err(|e| match e {
            UsdError::Write(e) => io(e),
            UsdError::Read(e) => e,
        })?;
    }
    out.write_all(b"}\n").map_err(io)?;
    out.into_inner().map_err(|e| io(e.into_error()))?;
    Ok(path)
}

/// Why a USD mesh could not be written: the layer, or the spool it is read from.
enum UsdError {
    Write(std::io::Error),
    Read(Error),
}

impl From<std::io::Error> for UsdError {
    fn from(e: std::io::Error) -> Self {
        UsdError::Write(e)
    }
}

/// Writes one mesh's prim: faces (the last), colour, UVs, and the time-sampled normals, points,
/// velocities (of an animated one) and extents.
fn usd_mesh(
    out: &mut impl Write,
    recorded: &mut Recorded,
    m: usize,
    name: &str,
    first_frame: u32,
    fps: f32,
) -> std::result::Result<(), UsdError> {
    let mesh = recorded.meshes[m].clone();
    let triangles = recorded.last_triangles(m).to_vec();
    let curves = triangles.is_empty();
    let mut s = format!(
        "    def {} \"{name}\"\n    {{\n",
        if curves { "BasisCurves" } else { "Mesh" }
    );
    if curves {
        let _ = writeln!(
            s,
            "        uniform token type = \"linear\"\n        int[] curveVertexCounts = [{}]",
            mesh.vertices
        );
    } else {
        let counts = vec!["3"; triangles.len()].join(", ");
        let indices: Vec<String> = triangles.iter().flatten().map(|i| i.to_string()).collect();
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
    let frames = if mesh.animated { recorded.frames } else { 1 };
    let first = recorded.positions(m, 0).map_err(UsdError::Read)?;
    s.push_str("        point3f[] points = ");
    points(&mut s, &first);
    s.push('\n');
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
    out.write_all(s.as_bytes())?;
    // One block of samples per attribute, each frame read back in turn.
    let mut samples = |out: &mut dyn Write,
                       head: &str,
                       value: &dyn Fn(&[Vec3]) -> Vec<Vec3>|
     -> std::result::Result<(), UsdError> {
        out.write_all(head.as_bytes())?;
        for k in 0..frames {
            let frame = recorded.positions(m, k).map_err(UsdError::Read)?;
            let mut line = format!("            {}: ", first_frame as usize + k);
            points(&mut line, &value(&frame));
            line.push_str(",\n");
            out.write_all(line.as_bytes())?;
        }
        out.write_all(b"        }\n")?;
        Ok(())
    };
    if !curves {
        samples(
            out,
            "        normal3f[] primvars:normals (\n            interpolation = \"vertex\"\n        )\n        normal3f[] primvars:normals.timeSamples = {\n",
            &|f| crate::mesh::vertex_normals(&triangles, f),
        )?;
    }
    samples(out, "        point3f[] points.timeSamples = {\n", &|f| {
        f.to_vec()
    })?;
    samples(out, "        float3[] extent.timeSamples = {\n", &|f| {
        let (lo, hi) = f.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        vec![lo, hi]
    })?;
    if frames > 1 {
        velocities(out, recorded, m, first_frame, fps)?;
    }
    out.write_all(b"    }\n")?;
    Ok(())
}

/// Writes mesh `m`'s `velocities` time samples (UsdGeom's: metres per second, so a renderer
/// blurs the motion of a frame without the frames around it): central differences of the
/// frames' points, one-sided at the first and the last frame. A neighbour with another vertex
/// count (none in a bake today) leaves the other side alone, or zeros.
fn velocities(
    out: &mut dyn Write,
    recorded: &mut Recorded,
    m: usize,
    first_frame: u32,
    fps: f32,
) -> std::result::Result<(), UsdError> {
    out.write_all(b"        vector3f[] velocities.timeSamples = {\n")?;
    let frames = recorded.frames;
    let mut read = |k: usize| recorded.positions(m, k).map_err(UsdError::Read);
    let (mut previous, mut now) = (None::<Vec<Vec3>>, read(0)?);
    for k in 0..frames {
        let next = if k + 1 < frames {
            Some(read(k + 1)?)
        } else {
            None
        };
        let n = now.len();
        let before = previous.as_ref().filter(|f| f.len() == n);
        let after = next.as_ref().filter(|f| f.len() == n);
        let velocity: Vec<Vec3> = match (before, after) {
            (Some(a), Some(b)) => a
                .iter()
                .zip(b)
                .map(|(a, b)| (*b - *a) * (0.5 * fps))
                .collect(),
            (None, Some(b)) => now.iter().zip(b).map(|(a, b)| (*b - *a) * fps).collect(),
            (Some(a), None) => a.iter().zip(&now).map(|(a, b)| (*b - *a) * fps).collect(),
            (None, None) => vec![Vec3::ZERO; now.len()],
        };
        let mut line = format!("            {}: ", first_frame as usize + k);
        points(&mut line, &velocity);
        line.push_str(",\n");
        out.write_all(line.as_bytes())?;
        if let Some(next) = next {
            previous = Some(std::mem::replace(&mut now, next));
        }
    }
    out.write_all(b"        }\n")?;
    Ok(())
}
