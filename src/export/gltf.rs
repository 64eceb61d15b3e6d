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
//! Layout: one buffer, written frame by frame as the bake runs (frame 1's positions, normals and
//! UVs, then each later frame's deltas, then the faces and the animation); one buffer view per
//! accessor (4-byte aligned); positions and normals f32, indices u32; cloth materials are
//! double-sided. Positions are in metres, Y up (drape's frame). Long bakes grow as F·V·24 bytes
//! (positions and normals) plus 4·F² per animated mesh for the weights: split long sequences
//! into several bakes.

use super::sink::{Frame, FrameSink, MeshInfo, Written};
use crate::error::{Error, Result};
use crate::mesh::{vertex_normals, AnimatedMesh};
use glam::Vec3;
use serde_json::{json, Value};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// glTF container.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    /// One `.glb` file.
    Binary,
    /// `.gltf` JSON beside a `.bin` buffer.
    Separate,
}

/// Appends buffer views and accessors to a binary buffer as it is written out.
struct Builder<W: Write> {
    out: W,
    /// Bytes written so far.
    len: u64,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

/// glTF component types and targets.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The smallest and largest of `values`, per component.
fn extent(values: &[Vec3]) -> (Vec3, Vec3) {
    values.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    )
}

impl<W: Write> Builder<W> {
    /// Appends `bytes` (whole 4-byte values, so views stay aligned) as a buffer view and
    /// returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> io::Result<usize> {
        debug_assert_eq!(bytes.len() % 4, 0);
        let mut view = json!({ "buffer": 0, "byteOffset": self.len, "byteLength": bytes.len() });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.out.write_all(bytes)?;
        self.len += bytes.len() as u64;
        self.views.push(view);
        Ok(self.views.len() - 1)
    }

    fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A VEC3 float accessor, with min and max (required for positions).
    fn vec3(&mut self, values: &[Vec3], bounds: bool) -> io::Result<usize> {
        let view = self.view(bytemuck::cast_slice(values), Some(ARRAY_BUFFER))?;
        let mut a = json!({ "bufferView": view, "componentType": FLOAT, "count": values.len(), "type": "VEC3" });
        if bounds {
            let (lo, hi) = extent(values);
            a["min"] = json!(lo.to_array());
            a["max"] = json!(hi.to_array());
        }
        Ok(self.accessor(a))
    }

    fn vec2(&mut self, values: &[[f32; 2]]) -> io::Result<usize> {
        let view = self.view(bytemuck::cast_slice(values), Some(ARRAY_BUFFER))?;
        Ok(self.accessor(json!({ "bufferView": view, "componentType": FLOAT, "count": values.len(), "type": "VEC2" })))
    }

    fn indices(&mut self, triangles: &[[u32; 3]]) -> io::Result<usize> {
        let view = self.view(bytemuck::cast_slice(triangles), Some(ELEMENT_ARRAY_BUFFER))?;
        // The indices actually used (a torn garment may leave some vertices out).
        let all = triangles.iter().flatten();
        let (lo, hi) = (
            all.clone().min().copied().unwrap_or(0),
            all.max().copied().unwrap_or(0),
        );
        Ok(self.accessor(json!({
            "bufferView": view, "componentType": UNSIGNED_INT, "count": triangles.len() * 3,
            "type": "SCALAR", "min": [lo], "max": [hi]
        })))
    }

    /// The key times of `frames` frames at `fps`, with min and max.
    fn times(&mut self, frames: usize, fps: f32) -> io::Result<usize> {
        let times: Vec<f32> = (0..frames).map(|k| k as f32 / fps).collect();
        let view = self.view(bytemuck::cast_slice(&times), None)?;
        Ok(self.accessor(json!({
            "bufferView": view, "componentType": FLOAT, "count": frames, "type": "SCALAR",
            "min": [times[0]], "max": [times[frames - 1]]
        })))
    }

    /// The morph weights of `frames` keys over `frames − 1` targets: key j (frame j + 1)
    /// weighs target j − 1 fully, key 0 none. Written a key at a time (the whole is F² floats).
    fn weights(&mut self, frames: usize) -> io::Result<usize> {
        let t = frames - 1;
        let start = self.len;
        let mut key = vec![0.0f32; t];
        for j in 0..frames {
            if j > 0 {
                key[j - 1] = 1.0;
            }
            self.out.write_all(bytemuck::cast_slice(&key))?;
            if j > 0 {
                key[j - 1] = 0.0;
            }
        }
        self.len += (frames * t * 4) as u64;
        self.views
            .push(json!({ "buffer": 0, "byteOffset": start, "byteLength": frames * t * 4 }));
        let view = self.views.len() - 1;
        Ok(self.accessor(json!({ "bufferView": view, "componentType": FLOAT, "count": frames * t, "type": "SCALAR" })))
    }
}

/// One mesh of the document being written.
struct MeshState {
    info: MeshInfo,
    /// The first frame's positions and normals, which every target is a delta from.
    base: Vec<Vec3>,
    base_normals: Option<Vec<Vec3>>,
    attributes: Value,
    targets: Vec<Value>,
}

/// A glTF document written as frames arrive: the binary buffer goes to `W` frame by frame
/// (frame 1 as each mesh's base, later frames as morph targets), and [`Morphs::finish`] adds
/// the faces, the animation and the JSON. Memory: one frame of each mesh.
pub struct Morphs<W: Write> {
    b: Builder<W>,
    meshes: Vec<MeshState>,
    frames: usize,
}

impl<W: Write> Morphs<W> {
    pub fn new(out: W, meshes: &[MeshInfo]) -> Morphs<W> {
        Morphs {
            b: Builder {
                out,
                len: 0,
                views: Vec::new(),
                accessors: Vec::new(),
            },
            meshes: meshes
                .iter()
                .map(|info| MeshState {
                    info: info.clone(),
                    base: Vec::new(),
                    base_normals: None,
                    attributes: Value::Null,
                    targets: Vec::new(),
                })
                .collect(),
            frames: 0,
        }
    }

    /// Appends the next frame (positions of every mesh; a static one's only in the first).
    pub fn frame(&mut self, positions: &[Vec<Vec3>]) -> io::Result<()> {
        let first = self.frames == 0;
        for (mesh, frame) in self.meshes.iter_mut().zip(positions) {
            let triangles = &mesh.info.triangles;
            if first {
                mesh.attributes = json!({ "POSITION": self.b.vec3(frame, true)? });
                if !triangles.is_empty() {
                    let normals = vertex_normals(triangles, frame);
                    mesh.attributes["NORMAL"] = json!(self.b.vec3(&normals, false)?);
                    mesh.base_normals = Some(normals);
                }
                if let Some(uv) = &mesh.info.uvs {
                    mesh.attributes["TEXCOORD_0"] = json!(self.b.vec2(uv)?);
                }
                mesh.base = frame.clone();
                continue;
            }
            if !mesh.info.animated {
                continue;
            }
            let delta: Vec<Vec3> = frame.iter().zip(&mesh.base).map(|(p, q)| *p - *q).collect();
            let mut target = json!({ "POSITION": self.b.vec3(&delta, true)? });
            if let Some(n0) = &mesh.base_normals {
                let normals = vertex_normals(triangles, frame);
                let delta: Vec<Vec3> = normals.iter().zip(n0).map(|(n, m)| *n - *m).collect();
                target["NORMAL"] = json!(self.b.vec3(&delta, false)?);
            }
            mesh.targets.push(target);
        }
        self.frames += 1;
        Ok(())
    }

    /// Mesh `mesh` has these faces from now on (glTF keeps one topology: the last).
    pub fn faces(&mut self, mesh: usize, triangles: &[[u32; 3]]) {
        self.meshes[mesh].info.triangles = triangles.to_vec();
    }

    /// Writes the faces and the animation at `fps` and returns the JSON and the writer.
    pub fn finish(mut self, fps: f32, generator: &str) -> io::Result<(Value, W)> {
        let frames = self.frames;
        let input = if frames > 1 {
            Some(self.b.times(frames, fps)?)
        } else {
            None
        };
        let weights = if frames > 1 {
            Some(self.b.weights(frames)?)
        } else {
            None
        };
        let (mut gltf_meshes, mut nodes, mut materials, mut channels, mut samplers) =
            (vec![], vec![], vec![], vec![], vec![]);
        for (index, mesh) in self.meshes.into_iter().enumerate() {
            let mut primitive = json!({ "attributes": mesh.attributes, "material": index });
            if mesh.info.triangles.is_empty() {
                primitive["mode"] = json!(3); // LINE_STRIP
            } else {
                primitive["indices"] = json!(self.b.indices(&mesh.info.triangles)?);
            }
            let mut gltf_mesh = json!({ "name": mesh.info.name, "primitives": [primitive] });
            if let (Some(output), false) = (weights, mesh.targets.is_empty()) {
                gltf_mesh["weights"] = json!(vec![0.0; mesh.targets.len()]);
                gltf_mesh["primitives"][0]["targets"] = json!(mesh.targets);
                samplers
                    .push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
                channels.push(json!({ "sampler": samplers.len() - 1, "target": { "node": index, "path": "weights" } }));
            }
            gltf_meshes.push(gltf_mesh);
            nodes.push(json!({ "name": mesh.info.name, "mesh": index }));
            materials.push(json!({
                "name": mesh.info.name,
                "pbrMetallicRoughness": { "baseColorFactor": mesh.info.colour, "metallicFactor": 0.0, "roughnessFactor": 0.8 },
                "doubleSided": true
            }));
        }
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": generator },
            "scene": 0,
            "scenes": [{ "name": "drape bake", "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
            "nodes": nodes,
            "meshes": gltf_meshes,
            "materials": materials,
            "buffers": [{ "byteLength": self.b.len }],
            "bufferViews": self.b.views,
            "accessors": self.b.accessors,
        });
        if !channels.is_empty() {
            doc["animations"] =
                json!([{ "name": "bake", "channels": channels, "samplers": samplers }]);
        }
        Ok((doc, self.b.out))
    }
}

/// The most a `.glb` holds: its header and chunk lengths are 32-bit.
const GLB_LIMIT: u64 = u32::MAX as u64;

/// The bake's glTF: the binary buffer streams into a part file beside the output as frames
/// arrive; at the end it becomes `<stem>.bin` beside `<stem>.gltf`, or is copied into
/// `<stem>.glb` after the JSON (a `.glb` over 4 GiB cannot exist: such a bake is written as
/// `.gltf` + `.bin`, with a warning).
pub struct GltfFile {
    files: GltfFiles,
    container: Container,
    fps: f32,
    morphs: Morphs<BufWriter<File>>,
}

/// Where a bake's glTF goes: `dir/<stem>.*`, and the part file the buffer streams into.
struct GltfFiles {
    dir: PathBuf,
    stem: String,
    part: PathBuf,
}

impl GltfFile {
    pub fn create(
        dir: &Path,
        stem: &str,
        container: Container,
        fps: f32,
        meshes: &[MeshInfo],
    ) -> Result<GltfFile> {
        let part = dir.join(format!(".{stem}.bin.part"));
        let file = File::create(&part).map_err(|e| Error::io(&part, "cannot create", e))?;
        Ok(GltfFile {
            files: GltfFiles {
                dir: dir.to_path_buf(),
                stem: stem.to_string(),
                part,
            },
            container,
            fps,
            morphs: Morphs::new(BufWriter::with_capacity(1 << 20, file), meshes),
        })
    }
}

impl GltfFiles {
    /// Writes `<stem>.gltf` naming `<stem>.bin` (the part file, renamed).
    fn separate(&self, mut doc: Value) -> Result<Vec<PathBuf>> {
        let bin_name = format!("{}.bin", self.stem);
        let bin = self.dir.join(&bin_name);
        std::fs::rename(&self.part, &bin).map_err(|e| Error::io(&bin, "cannot write", e))?;
        doc["buffers"][0]["uri"] = json!(bin_name);
        let path = self.dir.join(format!("{}.gltf", self.stem));
        let text = serde_json::to_string(&doc).expect("glTF JSON serialises");
        std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
        Ok(vec![path, bin])
    }

    /// Writes `<stem>.glb`: header, JSON chunk, and the part file as the binary chunk.
    fn binary(&self, json: Vec<u8>, bin: u64) -> Result<Vec<PathBuf>> {
        let path = self.dir.join(format!("{}.glb", self.stem));
        let io = |e| Error::io(&path, "cannot write", e);
        let mut out = BufWriter::new(File::create(&path).map_err(io)?);
        let pad = (4 - bin % 4) % 4;
        out.write_all(&glb_header(&json, bin + pad)).map_err(io)?;
        let mut part =
            File::open(&self.part).map_err(|e| Error::io(&self.part, "cannot read", e))?;
        std::io::copy(&mut part, &mut out).map_err(io)?;
        out.write_all(&vec![0; pad as usize]).map_err(io)?;
        out.into_inner().map_err(|e| io(e.into_error()))?;
        let _ = std::fs::remove_file(&self.part);
        Ok(vec![path])
    }
}

impl FrameSink for GltfFile {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        self.morphs
            .frame(&frame.positions)
            .map_err(|e| Error::io(&self.files.part, "cannot write", e))
    }

    fn faces(&mut self, mesh: usize, _from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        self.morphs.faces(mesh, triangles);
        Ok(())
    }

    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>> {
        let GltfFile {
            files: target,
            container,
            fps,
            morphs,
        } = *self;
        if frames == 0 {
            drop(morphs);
            let _ = std::fs::remove_file(&target.part);
            return Ok(Vec::new());
        }
        let generator = format!("drape {}", env!("CARGO_PKG_VERSION"));
        let failed = |e| Error::io(&target.part, "cannot write", e);
        let (doc, out) = morphs.finish(fps, &generator).map_err(failed)?;
        let bin = doc["buffers"][0]["byteLength"].as_u64().unwrap_or(0);
        out.into_inner().map_err(|e| failed(e.into_error()))?;
        let mut warnings = Vec::new();
        let files = match container {
            Container::Separate => target.separate(doc)?,
            Container::Binary => {
                let json = padded_json(&doc);
                if 28 + json.len() as u64 + bin + 3 <= GLB_LIMIT {
                    target.binary(json, bin)?
                } else {
                    warnings.push(format!(
                        "{}.glb would hold {:.1} GB, over the 4 GiB a .glb can (its lengths are 32-bit): written as {0}.gltf + {0}.bin instead",
                        target.stem,
                        bin as f64 / 1e9
                    ));
                    target.separate(doc)?
                }
            }
        };
        Ok(vec![Written {
            format: "gltf",
            files,
            warnings,
        }])
    }
}

/// The JSON chunk's bytes: the document padded with spaces to 4 bytes.
fn padded_json(doc: &Value) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("glTF JSON serialises");
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    json
}

/// The GLB container up to the binary chunk's data: a 12-byte header, the JSON chunk (already
/// padded) and the binary chunk's header for `bin` bytes (a multiple of 4).
fn glb_header(json: &[u8], bin: u64) -> Vec<u8> {
    let total = 12 + 8 + json.len() as u64 + 8 + bin;
    let mut out = Vec::with_capacity(28 + json.len());
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.extend_from_slice(&(bin as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
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
            solid: None,
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
