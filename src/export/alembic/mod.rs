//! Alembic caches (`<scene>.abc`, Ogawa), the format every DCC and engine reads simulated
//! garments from, written by drape itself as frames arrive (no Alembic library, no Python:
//! `docs/formats.md` says why). One identity `Xform` per mesh with its `PolyMesh` under it
//! (`/cloth/clothShape`, as Blender and Maya export), every property sampled once per frame
//! on one uniform time sampling of `1/fps` that starts at the first frame's number: positions,
//! bounds, faces (a torn garment's new faces from the frame they tear), per-vertex normals and
//! the garment's UVs (face-varying, indexed by its faces). Samples that repeat the one before
//! (constant faces, a still character) are stored once.
//!
//! Coordinates are drape's: metres, Y up, which is Alembic's convention (Blender turns them
//! Z up on import). Faces are written clockwise, as Alembic wants them: each triangle's
//! corners reversed.

mod archive;
mod ogawa;

use super::obj::vertex_normals;
use super::sink::{Frame, FrameSink, MeshInfo, Role, Written};
use crate::error::Result;
use archive::{Archive, Compound, Node, Pod, Property, SAMPLED};
use glam::Vec3;
use ogawa::Ogawa;
use std::path::PathBuf;

const POLYMESH: &str = "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1;schemaObjTitle=AbcGeom_PolyMesh_v1:.geom";
const GEOM: &str = "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1";
const XFORM: &str = "schema=AbcGeom_Xform_v3;schemaObjTitle=AbcGeom_Xform_v3:.xform";
const UV: &str = "arrayExtent=1;geoScope=fvr;interpretation=vector;isGeomParam=true;podExtent=2;podName=float32_t";
const NORMALS: &str = "arrayExtent=1;geoScope=vtx;interpretation=normal;isGeomParam=true;podExtent=3;podName=float32_t";

/// Writes `<scene>.abc`: the garments and, when asked, the characters.
pub struct AlembicFile {
    path: PathBuf,
    archive: Archive,
    meshes: Vec<MeshCache>,
    fps: f64,
    description: String,
    /// The shot frame of the first sample.
    first: Option<u32>,
    warnings: Vec<String>,
}

/// One mesh's properties as they are sampled.
struct MeshCache {
    /// Index among the bake's meshes.
    mesh: usize,
    name: String,
    /// Its faces now, as Alembic wants them (corners reversed).
    indices: Vec<i32>,
    /// A still mesh's positions (it comes with the first frame only): kept from it.
    still: Option<Vec<Vec3>>,
    animated: bool,
    uvs: Option<Vec<[f32; 2]>>,
    inherits: Property,
    bounds: Property,
    positions: Property,
    face_indices: Property,
    face_counts: Property,
    normals: Property,
    uv_values: Option<Property>,
    uv_indices: Option<Property>,
}

impl AlembicFile {
    /// Starts `path` for `meshes`: the garments with faces, and the characters when
    /// `characters`; `fps`: the frame rate its time sampling counts in.
    pub fn create(
        path: PathBuf,
        scene: &str,
        fps: f32,
        meshes: &[MeshInfo],
        characters: bool,
    ) -> Result<AlembicFile> {
        let archive = Archive::new(Ogawa::create(&path)?)?;
        let mut caches: Vec<MeshCache> = Vec::new();
        let mut warnings = Vec::new();
        for (i, m) in meshes.iter().enumerate() {
            let wanted = match m.role {
                Role::Garment => true,
                Role::Character => characters,
                Role::Collider => false,
            };
            if !wanted {
                continue;
            }
            if m.triangles.is_empty() {
                warnings.push(format!(
                    "Alembic: {} is a rope, which the cache leaves out (drape writes no Alembic curves yet)",
                    m.name
                ));
                continue;
            }
            let mut name = object_name(&m.name);
            while caches.iter().any(|c| c.name == name) {
                name.push('_');
            }
            let ts = SAMPLED;
            caches.push(MeshCache {
                mesh: i,
                name,
                indices: clockwise(&m.triangles),
                still: None,
                animated: m.animated,
                uvs: m.uvs.clone(),
                inherits: Property::scalar(".inherits", "", Pod::Bool, 1, ts),
                bounds: Property::scalar(".selfBnds", "interpretation=box", Pod::Float64, 6, ts),
                positions: Property::array(
                    "P",
                    "geoScope=vtx;interpretation=point",
                    Pod::Float32,
                    3,
                    ts,
                ),
                face_indices: Property::array(".faceIndices", "", Pod::Int32, 1, ts),
                face_counts: Property::array(".faceCounts", "", Pod::Int32, 1, ts),
                normals: Property::array("N", NORMALS, Pod::Float32, 3, ts),
                uv_values: m
                    .uvs
                    .as_ref()
                    .map(|_| Property::array(".vals", UV, Pod::Float32, 2, ts)),
                uv_indices: m
                    .uvs
                    .as_ref()
                    .map(|_| Property::array(".indices", "", Pod::Uint32, 1, ts)),
            });
        }
        Ok(AlembicFile {
            path,
            archive,
            meshes: caches,
            fps: f64::from(fps),
            description: scene.replace([';', '='], "_"),
            first: None,
            warnings,
        })
    }
}

/// A name an Alembic object may have: not empty, no `/`.
fn object_name(name: &str) -> String {
    let n = name.replace('/', "_");
    if n.is_empty() {
        "mesh".into()
    } else {
        n
    }
}

/// `triangles` as Alembic face indices: each one's corners in the reverse order.
fn clockwise(triangles: &[[u32; 3]]) -> Vec<i32> {
    triangles
        .iter()
        .flat_map(|&[a, b, c]| [c as i32, b as i32, a as i32])
        .collect()
}

impl MeshCache {
    /// Samples every property at the next frame, `positions` (empty for a still mesh after
    /// its first frame).
    fn sample(&mut self, archive: &mut Archive, positions: &[Vec3]) -> Result<()> {
        if !self.animated && self.still.is_none() {
            self.still = Some(positions.to_vec());
        }
        let positions = self.still.as_deref().unwrap_or(positions);
        let (lo, hi) = positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        let bounds: Vec<f64> = [lo, hi]
            .iter()
            .flat_map(|v| v.to_array())
            .map(f64::from)
            .collect();
        self.inherits.set(archive, &[1], 1)?;
        self.bounds.set(archive, bytemuck::cast_slice(&bounds), 1)?;
        self.positions
            .set(archive, bytemuck::cast_slice(positions), positions.len())?;
        let faces = self.indices.len() / 3;
        self.face_indices.set(
            archive,
            bytemuck::cast_slice(&self.indices),
            self.indices.len(),
        )?;
        self.face_counts
            .set(archive, bytemuck::cast_slice(&vec![3i32; faces]), faces)?;
        let triangles: Vec<[u32; 3]> = self
            .indices
            .chunks_exact(3)
            .map(|t| [t[2] as u32, t[1] as u32, t[0] as u32])
            .collect();
        let normals = vertex_normals(&triangles, positions);
        self.normals
            .set(archive, bytemuck::cast_slice(&normals), normals.len())?;
        if let (Some(uvs), Some(values), Some(indices)) =
            (&self.uvs, &mut self.uv_values, &mut self.uv_indices)
        {
            values.set(archive, bytemuck::cast_slice(uvs), uvs.len())?;
            indices.set(
                archive,
                bytemuck::cast_slice(&self.indices),
                self.indices.len(),
            )?;
        }
        Ok(())
    }

    /// Writes the mesh's two objects: the `Xform` (returned: name, metadata, group) and the
    /// `PolyMesh` under it.
    fn write(self, archive: &mut Archive) -> Result<(String, String, u64)> {
        let mut geom = Compound::new(".geom", GEOM);
        for p in [
            self.bounds,
            self.positions,
            self.face_indices,
            self.face_counts,
        ] {
            geom.properties.push(Node::Property(p));
        }
        if let (Some(values), Some(indices)) = (self.uv_values, self.uv_indices) {
            let mut uv = Compound::new("uv", UV);
            uv.properties.push(Node::Property(values));
            uv.properties.push(Node::Property(indices));
            geom.properties.push(Node::Compound(uv));
        }
        geom.properties.push(Node::Property(self.normals));
        let mut shape = Compound::new("", "");
        shape.properties.push(Node::Compound(geom));
        let shape = archive.object(shape, &[])?;
        let mut xform = Compound::new(".xform", "schema=AbcGeom_Xform_v3");
        xform.properties.push(Node::Property(self.inherits));
        let mut top = Compound::new("", "");
        top.properties.push(Node::Compound(xform));
        let shape_name = format!("{}Shape", self.name);
        let group = archive.object(top, &[(shape_name, POLYMESH.to_string(), shape)])?;
        Ok((self.name, XFORM.to_string(), group))
    }
}

impl FrameSink for AlembicFile {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        self.first.get_or_insert(frame.number);
        for m in &mut self.meshes {
            m.sample(&mut self.archive, &frame.positions[m.mesh])?;
        }
        Ok(())
    }

    fn faces(&mut self, mesh: usize, _from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        if let Some(m) = self.meshes.iter_mut().find(|m| m.mesh == mesh) {
            m.indices = clockwise(triangles);
        }
        Ok(())
    }

    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>> {
        let AlembicFile {
            path,
            mut archive,
            meshes,
            fps,
            description,
            first,
            warnings,
        } = *self;
        let mut objects = Vec::new();
        for m in meshes {
            objects.push(m.write(&mut archive)?);
        }
        let metadata = format!(
            "_ai_Application=drape {};_ai_DCC_FPS={fps:.6};_ai_Description={description}",
            env!("CARGO_PKG_VERSION")
        );
        let start = f64::from(first.unwrap_or(0)) / fps;
        archive.close(&objects, &metadata, fps, start)?;
        if frames == 0 {
            let _ = std::fs::remove_file(&path);
            return Ok(Vec::new());
        }
        Ok(vec![Written {
            format: "alembic",
            files: vec![path],
            warnings,
        }])
    }
}
