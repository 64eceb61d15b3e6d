//! glTF 2.0 export of a bake: every garment (and character) is one mesh whose frames are morph
//! targets, played by a `weights` animation at the scene's frame rate.
//!
//! Why morph targets: the mesh, its materials and its topology appear once, and every frame is a
//! position (and normal) delta. Blender imports them as shape keys driven by F-curves; three.js
//! keeps morph targets in a texture (r133 on), so hundreds of targets play. The other portable
//! choice, one mesh node per frame switched by STEP-interpolated scale, duplicates the index and
//! UV data per frame and gives importers hundreds of objects. Frame 1 is the base mesh; target
//! k − 2 holds frame k − frame 1. The weights animation is LINEAR, so at frame k's time exactly
//! target k − 2 has weight 1 (frame k's positions), and between frames vertices move on straight
//! lines, which keeps playback smooth at any rate.
//!
//! Layout: one buffer; one buffer view per accessor (4-byte aligned); positions and normals f32,
//! indices u32; cloth materials are double-sided. Positions are in metres, Y up (drape's frame).
//! Long bakes grow as F·V·24 bytes (positions and normals) plus 4·F² for the weights: split long
//! sequences into several bakes.

use super::obj::vertex_normals;
use crate::error::{Error, Result};
use glam::Vec3;
use serde_json::{json, Value};
use std::path::Path;

/// An animated mesh: fixed topology, one position array per frame.
#[derive(Clone, Debug)]
pub struct AnimatedMesh {
    pub name: String,
    /// Triangles; empty for a rope, which is written as a line strip.
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates per vertex, if any.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Base colour, linear RGBA.
    pub colour: [f32; 4],
    /// Positions of every vertex, per frame.
    pub frames: Vec<Vec<Vec3>>,
    /// When the faces change during the sequence (tearing): (first frame index, triangles)
    /// in order; `triangles` holds the last. Empty: `triangles` throughout. glTF keeps one
    /// topology, the last; previews and OBJ frames follow the changes.
    pub topology: Vec<(usize, Vec<[u32; 3]>)>,
}

impl AnimatedMesh {
    /// The triangles of frame `k`.
    pub fn triangles_at(&self, k: usize) -> &[[u32; 3]] {
        self.topology
            .iter()
            .rev()
            .find(|(first, _)| *first <= k)
            .map_or(&self.triangles, |(_, t)| t)
    }
}

/// glTF container.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    /// One `.glb` file.
    Binary,
    /// `.gltf` JSON beside a `.bin` buffer.
    Separate,
}

/// Accumulates the binary buffer, buffer views and accessors.
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

/// glTF component types and targets.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

impl Builder {
    /// Appends `bytes` as a buffer view (4-byte aligned) and returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view =
            json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    /// A VEC3 float accessor, with min and max (required for positions).
    fn vec3(&mut self, values: &[Vec3], bounds: bool) -> usize {
        let view = self.view(bytemuck::cast_slice(values), Some(ARRAY_BUFFER));
        let mut a = json!({ "bufferView": view, "componentType": FLOAT, "count": values.len(), "type": "VEC3" });
        if bounds {
            let (lo, hi) = values.iter().fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(lo, hi), v| (lo.min(*v), hi.max(*v)),
            );
            a["min"] = json!(lo.to_array());
            a["max"] = json!(hi.to_array());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn vec2(&mut self, values: &[[f32; 2]]) -> usize {
        let view = self.view(bytemuck::cast_slice(values), Some(ARRAY_BUFFER));
        self.accessors.push(json!({ "bufferView": view, "componentType": FLOAT, "count": values.len(), "type": "VEC2" }));
        self.accessors.len() - 1
    }

    fn indices(&mut self, triangles: &[[u32; 3]]) -> usize {
        let view = self.view(bytemuck::cast_slice(triangles), Some(ELEMENT_ARRAY_BUFFER));
        // The indices actually used (a torn garment may leave some vertices out).
        let all = triangles.iter().flatten();
        let (lo, hi) = (
            all.clone().min().copied().unwrap_or(0),
            all.max().copied().unwrap_or(0),
        );
        self.accessors.push(json!({
            "bufferView": view, "componentType": UNSIGNED_INT, "count": triangles.len() * 3,
            "type": "SCALAR", "min": [lo], "max": [hi]
        }));
        self.accessors.len() - 1
    }

    /// Float scalars (animation input/output), with min and max when `bounds`.
    fn scalars(&mut self, values: &[f32], bounds: bool) -> usize {
        let view = self.view(bytemuck::cast_slice(values), None);
        let mut a = json!({ "bufferView": view, "componentType": FLOAT, "count": values.len(), "type": "SCALAR" });
        if bounds {
            a["min"] = json!([values.iter().copied().fold(f32::MAX, f32::min)]);
            a["max"] = json!([values.iter().copied().fold(f32::MIN, f32::max)]);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

/// The glTF JSON and binary buffer of `meshes` animated at `fps`.
pub fn document(meshes: &[AnimatedMesh], fps: f32, generator: &str) -> Result<(Value, Vec<u8>)> {
    let mut b = Builder {
        bin: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    // Animated meshes share the frame count; static ones (colliders) have one frame.
    let frames = meshes.iter().map(|m| m.frames.len()).max().unwrap_or(0);
    if frames == 0
        || meshes
            .iter()
            .any(|m| m.frames.len() != frames && m.frames.len() != 1)
    {
        return Err(Error::InvalidArgument {
            flag: "glTF export".into(),
            reason: format!(
                "every mesh needs the same number of frames, or one (got {:?})",
                meshes.iter().map(|m| m.frames.len()).collect::<Vec<_>>()
            ),
        });
    }
    let times: Vec<f32> = (0..frames).map(|k| k as f32 / fps).collect();
    let input = (frames > 1).then(|| b.scalars(&times, true));
    let (mut gltf_meshes, mut nodes, mut materials, mut channels, mut samplers) =
        (vec![], vec![], vec![], vec![], vec![]);
    for (index, mesh) in meshes.iter().enumerate() {
        let base = &mesh.frames[0];
        let lines = mesh.triangles.is_empty();
        let mut attributes = json!({ "POSITION": b.vec3(base, true) });
        let base_normals = (!lines).then(|| vertex_normals(&mesh.triangles, base));
        if let Some(n) = &base_normals {
            attributes["NORMAL"] = json!(b.vec3(n, false));
        }
        if let Some(uv) = &mesh.uvs {
            attributes["TEXCOORD_0"] = json!(b.vec2(uv));
        }
        let mut targets = Vec::new();
        for frame in &mesh.frames[1..] {
            let delta: Vec<Vec3> = frame.iter().zip(base).map(|(p, q)| *p - *q).collect();
            let mut target = json!({ "POSITION": b.vec3(&delta, true) });
            if let Some(n0) = &base_normals {
                let normals = vertex_normals(&mesh.triangles, frame);
                let delta: Vec<Vec3> = normals.iter().zip(n0).map(|(n, m)| *n - *m).collect();
                target["NORMAL"] = json!(b.vec3(&delta, false));
            }
            targets.push(target);
        }
        let mut primitive = json!({ "attributes": attributes, "material": index });
        if lines {
            primitive["mode"] = json!(3); // LINE_STRIP
        } else {
            primitive["indices"] = json!(b.indices(&mesh.triangles));
        }
        let mut gltf_mesh = json!({ "name": mesh.name, "primitives": [primitive] });
        if !targets.is_empty() {
            gltf_mesh["primitives"][0]["targets"] = json!(targets);
            gltf_mesh["weights"] = json!(vec![0.0; targets.len()]);
            // Key j (frame j + 1) weighs target j − 1 fully, key 0 none.
            let t = targets.len();
            let mut weights = vec![0.0f32; frames * t];
            for j in 1..frames {
                weights[j * t + (j - 1)] = 1.0;
            }
            let output = b.scalars(&weights, false);
            samplers.push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
            channels.push(json!({ "sampler": samplers.len() - 1, "target": { "node": index, "path": "weights" } }));
        }
        gltf_meshes.push(gltf_mesh);
        nodes.push(json!({ "name": mesh.name, "mesh": index }));
        materials.push(json!({
            "name": mesh.name,
            "pbrMetallicRoughness": { "baseColorFactor": mesh.colour, "metallicFactor": 0.0, "roughnessFactor": 0.8 },
            "doubleSided": true
        }));
    }
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": generator },
        "scene": 0,
        "scenes": [{ "name": "drape bake", "nodes": (0..meshes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "materials": materials,
        "buffers": [{ "byteLength": b.bin.len() }],
        "bufferViews": b.views,
        "accessors": b.accessors,
    });
    if !channels.is_empty() {
        doc["animations"] = json!([{ "name": "bake", "channels": channels, "samplers": samplers }]);
    }
    Ok((doc, b.bin))
}

/// Writes `meshes` as `<stem>.glb`, or `<stem>.gltf` + `<stem>.bin`, into `dir`; returns the
/// files written.
pub fn write(
    dir: &Path,
    stem: &str,
    meshes: &[AnimatedMesh],
    fps: f32,
    container: Container,
) -> Result<Vec<std::path::PathBuf>> {
    let generator = format!("drape {}", env!("CARGO_PKG_VERSION"));
    let (mut doc, bin) = document(meshes, fps, &generator)?;
    let save = |path: &Path, bytes: &[u8]| {
        std::fs::write(path, bytes).map_err(|e| Error::io(path, "cannot write", e))
    };
    match container {
        Container::Binary => {
            let path = dir.join(format!("{stem}.glb"));
            save(&path, &glb(&doc, &bin))?;
            Ok(vec![path])
        }
        Container::Separate => {
            let bin_name = format!("{stem}.bin");
            doc["buffers"][0]["uri"] = json!(bin_name);
            let (json_path, bin_path) = (dir.join(format!("{stem}.gltf")), dir.join(&bin_name));
            save(&bin_path, &bin)?;
            let text = serde_json::to_string(&doc).expect("glTF JSON serialises");
            save(&json_path, text.as_bytes())?;
            Ok(vec![json_path, bin_path])
        }
    }
}

/// The GLB container: a 12-byte header, the JSON chunk padded with spaces and the binary chunk
/// padded with zeros, each to 4 bytes.
pub fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("glTF JSON serialises");
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Reads back a glTF drape wrote: every mesh node's frames (base + each morph target in order),
/// triangles, UVs and colour, and the frame rate from the animation's key times.
pub fn read(path: &Path) -> Result<(Vec<AnimatedMesh>, f32)> {
    let bad = |reason: String| Error::InvalidField {
        file: path.display().to_string(),
        field: "glTF".into(),
        reason,
    };
    let (doc, buffers, _) = ::gltf::import(path).map_err(|e| bad(e.to_string()))?;
    let mut meshes = Vec::new();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let Some(primitive) = mesh.primitives().next() else {
            continue;
        };
        let reader = primitive.reader(|b| Some(&buffers[b.index()]));
        let base: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| bad(format!("mesh {:?} has no positions", mesh.name())))?
            .map(Vec3::from)
            .collect();
        let triangles: Vec<[u32; 3]> = match reader.read_indices() {
            Some(indices) => {
                let flat: Vec<u32> = indices.into_u32().collect();
                flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
            }
            None => Vec::new(),
        };
        let uvs = reader
            .read_tex_coords(0)
            .map(|t| t.into_f32().collect::<Vec<[f32; 2]>>());
        let mut frames = vec![base.clone()];
        for (positions, _, _) in reader.read_morph_targets() {
            let delta = positions.ok_or_else(|| bad("a morph target without positions".into()))?;
            frames.push(
                base.iter()
                    .zip(delta)
                    .map(|(b, d)| *b + Vec3::from(d))
                    .collect(),
            );
        }
        let colour = primitive
            .material()
            .pbr_metallic_roughness()
            .base_color_factor();
        meshes.push(AnimatedMesh {
            name: node.name().or(mesh.name()).unwrap_or("mesh").to_string(),
            triangles,
            uvs,
            colour,
            frames,
            topology: Vec::new(),
        });
    }
    let mut fps = 0.0;
    if let Some(channel) = doc.animations().next().and_then(|a| a.channels().next()) {
        let reader = channel.reader(|b| Some(&buffers[b.index()]));
        if let Some(times) = reader.read_inputs() {
            let t: Vec<f32> = times.take(2).collect();
            if t.len() == 2 && t[1] > t[0] {
                fps = 1.0 / (t[1] - t[0]);
            }
        }
    }
    Ok((meshes, fps))
}
