//! Alembic caches (`<scene>.abc`, Ogawa), the format every DCC and engine reads simulated
//! garments from, written by drape itself as frames arrive (no Alembic library, no Python:
//! `docs/formats.md` says why). One identity `Xform` per mesh with its `PolyMesh` under it
//! (`/cloth/clothShape`, as Blender and Maya export; a rope's is a linear `Curves` through its
//! vertices), every property sampled once per frame
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

use super::sink::{Frame, FrameSink, MeshInfo, Role, Written};
use crate::error::Result;
use crate::mesh::vertex_normals;
use archive::{Archive, Compound, Node, Pod, Property, SAMPLED};
use glam::Vec3;
use ogawa::Ogawa;
use std::path::PathBuf;

const POLYMESH: &str = "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1;schemaObjTitle=AbcGeom_PolyMesh_v1:.geom";
const GEOM: &str = "schema=AbcGeom_PolyMesh_v1;schemaBaseType=AbcGeom_GeomBase_v1";
const CURVES: &str = "schema=AbcGeom_Curve_v2;schemaBaseType=AbcGeom_GeomBase_v1;schemaObjTitle=AbcGeom_Curve_v2:.geom";
const CURVES_GEOM: &str = "schema=AbcGeom_Curve_v2;schemaBaseType=AbcGeom_GeomBase_v1";
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
}

/// One mesh's properties as they are sampled.
struct MeshCache {
    /// Index among the bake's meshes.
    mesh: usize,
    name: String,
    /// A still mesh's positions (it comes with the first frame only): kept from it.
    still: Option<Vec<Vec3>>,
    animated: bool,
    inherits: Property,
    bounds: Property,
    positions: Property,
    shape: Shape,
}

/// What a mesh is in Alembic: a `PolyMesh`, or a rope's linear `Curves`.
enum Shape {
    Faces(Box<Faces>),
    Curve(Box<Curve>),
}

/// A rope's `Curves` properties: its vertex count and its kind (linear, open).
struct Curve {
    vertices: Property,
    basis_and_type: Property,
}

/// A `PolyMesh`'s own properties.
struct Faces {
    /// Its faces now: drape's (for the normals), as Alembic wants them (corners reversed),
    /// and their corner counts (all 3).
    triangles: Vec<[u32; 3]>,
    indices: Vec<i32>,
    counts: Vec<i32>,
    uvs: Option<Vec<[f32; 2]>>,
    face_indices: Property,
    face_counts: Property,
    normals: Property,
    uv_values: Option<Property>,
    uv_indices: Option<Property>,
}

impl AlembicFile {
    /// Starts `path` for `meshes`: the garments, and the characters when `characters`;
    /// `fps`: the frame rate its time sampling counts in.
    pub fn create(
        path: PathBuf,
        scene: &str,
        fps: f32,
        meshes: &[MeshInfo],
        characters: bool,
    ) -> Result<AlembicFile> {
        let archive = Archive::new(Ogawa::create(&path)?)?;
        let mut caches: Vec<MeshCache> = Vec::new();
        for (i, m) in meshes.iter().enumerate() {
            let wanted = match m.role {
                Role::Garment => true,
                Role::Character => characters,
                Role::Collider => false,
            };
            if !wanted {
                continue;
            }
            let mut name = object_name(&m.name);
            while caches.iter().any(|c| c.name == name) {
                name.push('_');
            }
            let ts = SAMPLED;
            let shape = if m.triangles.is_empty() {
                Shape::Curve(Box::new(Curve {
                    vertices: Property::array("nVertices", "", Pod::Int32, 1, ts),
                    basis_and_type: Property::scalar("curveBasisAndType", "", Pod::Uint8, 4, ts),
                }))
            } else {
                Shape::Faces(Box::new(Faces {
                    triangles: m.triangles.clone(),
                    indices: clockwise(&m.triangles),
                    counts: vec![3; m.triangles.len()],
                    uvs: m.uvs.clone(),
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
                }))
            };
            caches.push(MeshCache {
                mesh: i,
                name,
                still: None,
                animated: m.animated,
                inherits: Property::scalar(".inherits", "", Pod::Bool, 1, ts),
                bounds: Property::scalar(".selfBnds", "interpretation=box", Pod::Float64, 6, ts),
                positions: Property::array(
                    "P",
                    "geoScope=vtx;interpretation=point",
                    Pod::Float32,
                    3,
                    ts,
                ),
                shape,
            });
        }
        Ok(AlembicFile {
            path,
            archive,
            meshes: caches,
            fps: f64::from(fps),
            description: scene.replace([';', '='], "_"),
            first: None,
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
        match &mut self.shape {
            Shape::Faces(f) => f.sample(archive, positions),
            Shape::Curve(c) => {
                let Curve {
                    vertices,
                    basis_and_type,
                } = c.as_mut();
                // One linear, open curve through every vertex (as the OBJ frames' polyline).
                vertices.set(archive, &(positions.len() as i32).to_le_bytes(), 1)?;
                basis_and_type.set(archive, &[LINEAR, NON_PERIODIC, NO_BASIS, 1], 1)
            }
        }
    }

    /// Writes the mesh's two objects: the `Xform` (returned: name, metadata, group) and the
    /// `PolyMesh` or `Curves` under it.
    fn write(self, archive: &mut Archive) -> Result<(String, String, u64)> {
        let (schema, mut geom) = match self.shape {
            Shape::Faces(_) => (POLYMESH, Compound::new(".geom", GEOM)),
            Shape::Curve(_) => (CURVES, Compound::new(".geom", CURVES_GEOM)),
        };
        for p in [self.bounds, self.positions] {
            geom.properties.push(Node::Property(p));
        }
        match self.shape {
            Shape::Faces(f) => f.write(&mut geom),
            Shape::Curve(c) => {
                geom.properties.push(Node::Property(c.vertices));
                geom.properties.push(Node::Property(c.basis_and_type));
            }
        }
        let mut shape = Compound::new("", "");
        shape.properties.push(Node::Compound(geom));
        let shape = archive.object(shape, &[])?;
        let mut xform = Compound::new(".xform", "schema=AbcGeom_Xform_v3");
        xform.properties.push(Node::Property(self.inherits));
        let mut top = Compound::new("", "");
        top.properties.push(Node::Compound(xform));
        let shape_name = format!("{}Shape", self.name);
        let group = archive.object(top, &[(shape_name, schema.to_string(), shape)])?;
        Ok((self.name, XFORM.to_string(), group))
    }
}

/// `curveBasisAndType`: a linear (not cubic), open curve, no basis.
const LINEAR: u8 = 1;
const NON_PERIODIC: u8 = 0;
const NO_BASIS: u8 = 0;

impl Faces {
    fn sample(&mut self, archive: &mut Archive, positions: &[Vec3]) -> Result<()> {
        self.face_indices.set(
            archive,
            bytemuck::cast_slice(&self.indices),
            self.indices.len(),
        )?;
        self.face_counts.set(
            archive,
            bytemuck::cast_slice(&self.counts),
            self.counts.len(),
        )?;
        let normals = vertex_normals(&self.triangles, positions);
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

    /// Adds the faces, the UVs (an indexed geometry parameter) and the normals to `geom`.
    fn write(self, geom: &mut Compound) {
        geom.properties.push(Node::Property(self.face_indices));
        geom.properties.push(Node::Property(self.face_counts));
        if let (Some(values), Some(indices)) = (self.uv_values, self.uv_indices) {
            let mut uv = Compound::new("uv", UV);
            uv.properties.push(Node::Property(values));
            uv.properties.push(Node::Property(indices));
            geom.properties.push(Node::Compound(uv));
        }
        geom.properties.push(Node::Property(self.normals));
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
        if let Some(MeshCache {
            shape: Shape::Faces(f),
            ..
        }) = self.meshes.iter_mut().find(|m| m.mesh == mesh)
        {
            f.triangles = triangles.to_vec();
            f.indices = clockwise(triangles);
            f.counts = vec![3; triangles.len()];
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
            warnings: Vec::new(),
        }])
    }
}
