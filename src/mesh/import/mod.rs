//! Importing animated characters: the node hierarchy, meshes, bones and clips of a file, turned
//! into plain drape data ([`Asset`]) that can be posed at any time. glTF and GLB are read by the
//! `gltf` crate ([`gltf`]), every other format through assimp ([`assimp`]).
//!
//! The traps of real files (`shared/assets/MANIFEST.md`) are handled here:
//! 1. a skinned mesh's vertices are Σ wᵢ · G(boneᵢ) · offsetᵢ · v: its own node transform is *not*
//!    applied (only rigid meshes use their node's global transform);
//! 2. node names repeat: glTF binds skins and channels by node index, and so does drape; assimp
//!    binds by name, so there names are resolved to bones first (see [`assimp`]);
//! 3. skin weights are normalised per vertex (some files sum to 1.755);
//! 4. a mesh placed by a mirroring transform is wound the other way, and a character's mesh
//!    wound inside out is turned with a warning ([`orient`]);
//! 5. glTF morph targets are applied at their default or animated weights ([`morph`]).
//!
//! Times are in seconds. Rotation keys are interpolated with slerp, translation and scale
//! linearly; glTF's step and cubic-spline samplers are turned into such keys on import.

mod assimp;
mod bind;
mod gltf;
mod joints;
mod morph;
mod offsets;
mod orient;

pub use orient::{inside_out_measure, INSIDE_OUT};

use crate::error::{Error, Result};
use glam::{Mat4, Quat, Vec3};
use std::path::Path;

/// A node of the hierarchy, flattened in depth-first pre-order.
#[derive(Clone, Debug)]
pub struct Node {
    pub name: String,
    /// Index of the parent in the flattened list (always smaller), or None for the root.
    pub parent: Option<usize>,
    /// Rest transform relative to the parent.
    pub local: Mat4,
}

/// A bone of a skinned mesh: the node that moves it, its inverse bind matrix, its weights.
#[derive(Clone, Debug)]
pub struct Bone {
    pub node: usize,
    pub offset: Mat4,
}

/// One mesh as posed by the hierarchy (a glTF primitive, an assimp mesh).
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    /// Name of the node that carries it (the first instance's, for a rigid mesh).
    pub node: String,
    /// Name of its material ("" when it has none).
    pub material: String,
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub bones: Vec<Bone>,
    /// Per vertex: (bone index, normalised weight).
    pub weights: Vec<Vec<(u32, f32)>>,
    /// Nodes that place this mesh: a rigid mesh once per node; a skinned mesh is posed by its
    /// bones, and its first node places only its bind pose ([`Asset::bind_pose`]).
    pub instances: Vec<usize>,
    /// First texture coordinate set, one per vertex, when the file has one.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// A rigid mesh's instances whose triangles are turned (wound the other way) where they
    /// are placed: a mirroring node ([`orient`]). Empty: none (a skinned mesh's are turned in
    /// `triangles`).
    pub flipped: Vec<bool>,
    /// Morph targets (blend shapes): per target, each vertex's displacement, added weighted
    /// before the mesh is skinned or placed ([`morph`]). Empty without (and from assimp).
    pub targets: Vec<Vec<Vec3>>,
    /// Each instance's default target weights: its node's, else the mesh's (glTF `weights`).
    pub target_weights: Vec<Vec<f32>>,
}

/// Where [`Asset::for_each_copy`] is: the mesh's index, which copy of it (a rigid mesh's
/// instance), its first vertex in [`Asset::pose`], and whether its triangles are turned.
#[derive(Clone, Copy, Debug)]
struct Placed {
    mesh: usize,
    copy: usize,
    base: u32,
    flip: bool,
}

impl Placed {
    /// Triangle `t` of the mesh as this copy winds it (still in the mesh's own vertices).
    fn turn(&self, [a, b, c]: [u32; 3]) -> [u32; 3] {
        match self.flip {
            true => [a, c, b],
            false => [a, b, c],
        }
    }

    /// Triangle `t` of the mesh over [`Asset::pose`]'s vertices.
    fn place(&self, t: [u32; 3]) -> [u32; 3] {
        self.turn(t).map(|i| i + self.base)
    }
}

/// Keys of one animated node, times in seconds.
#[derive(Clone, Debug, Default)]
pub struct Channel {
    pub node: usize,
    pub translation: Vec<(f64, Vec3)>,
    pub rotation: Vec<(f64, Quat)>,
    pub scale: Vec<(f64, Vec3)>,
    /// Morph target weights of the mesh the node places: keys per target.
    pub weights: Vec<Vec<(f64, f32)>>,
}

/// A named animation clip.
#[derive(Clone, Debug)]
pub struct Clip {
    /// The clip's name (may be empty: then refer to it by index).
    pub name: String,
    /// Duration [s].
    pub duration: f64,
    pub channels: Vec<Channel>,
}

/// An imported file: everything needed to pose it at any time.
#[derive(Clone, Debug)]
pub struct Asset {
    pub nodes: Vec<Node>,
    pub meshes: Vec<Mesh>,
    pub clips: Vec<Clip>,
    /// What the importer found suspicious but could read (repeated node names, ...).
    pub warnings: Vec<String>,
    /// Turns multiplied after nodes' local transforms in every pose but the bind pose:
    /// (node, the turn in the node's own frame). Empty as read; see [`Asset::offset_joints`].
    pub offsets: Vec<(usize, Mat4)>,
}

/// Index of the clip called `name` among `names`: so named exactly, else so named but for
/// case when only one clip is, else given as a number ("0" for an unnamed clip).
pub fn find_clip<'a>(names: impl IntoIterator<Item = &'a str>, name: &str) -> Option<usize> {
    let names: Vec<&str> = names.into_iter().collect();
    let folded = name.to_lowercase();
    let mut same = (0..names.len()).filter(|&i| names[i].to_lowercase() == folded);
    let by_case = match (same.next(), same.next()) {
        (Some(i), None) => Some(i),
        _ => None,
    };
    names
        .iter()
        .position(|&c| c == name)
        .or(by_case)
        .or_else(|| name.parse::<usize>().ok().filter(|&i| i < names.len()))
}

/// Whether `name` is `mesh`'s mesh, node or material name.
pub fn matches(mesh: &Mesh, name: &str) -> bool {
    mesh.name == name || mesh.node == name || (!mesh.material.is_empty() && mesh.material == name)
}

/// Bumped when an importer's output changes, so shell caches of the old import are rebuilt.
pub const IMPORTER: u32 = 3;

/// Divides each vertex's skin weights by their sum (some files sum to 1.755).
fn normalise(weights: &mut [Vec<(u32, f32)>]) {
    for list in weights {
        let sum: f32 = list.iter().map(|w| w.1).sum();
        if sum > 0.0 {
            list.iter_mut().for_each(|w| w.1 /= sum);
        }
    }
}

impl Asset {
    /// Reads a character file: glTF and GLB by the `gltf` crate, which binds animation and
    /// skins by node index as the format does ([`gltf`]); every other format through assimp
    /// ([`assimp`]), where duplicate node names are told apart first. Errors name the file
    /// and the reason.
    pub fn open(path: &Path) -> Result<Asset> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("gltf" | "glb") => Asset::read(path, gltf::open),
            _ => Asset::read(path, assimp::open),
        }
    }

    /// Reads a character's file as [`Asset::open`] does, with each mesh wound inside out turned
    /// to face out and a warning of it in `warnings` ([`Asset::turn_inside_out_meshes`]).
    pub fn open_character(path: &Path) -> Result<Asset> {
        let mut asset = Asset::open(path)?;
        let turned = asset.turn_inside_out_meshes(path);
        asset.warnings.extend(turned);
        Ok(asset)
    }

    /// Reads any file through assimp, glTF included: the way drape read glTF before it bound
    /// by index, kept for comparisons in the tests.
    pub fn open_with_assimp(path: &Path) -> Result<Asset> {
        Asset::read(path, assimp::open)
    }

    /// Checks that `path` is a file, reads it with `reader`, then checks what was read.
    fn read(path: &Path, reader: fn(&Path) -> Result<Asset>) -> Result<Asset> {
        if !path.is_file() {
            let (kind, reason) = if path.exists() {
                (
                    std::io::ErrorKind::InvalidInput,
                    "not a regular file (a mesh file is needed)",
                )
            } else {
                (std::io::ErrorKind::NotFound, "no such file")
            };
            return Err(Error::io(
                path,
                "cannot read",
                std::io::Error::new(kind, reason),
            ));
        }
        let mut asset = reader(path)?;
        let file = path.display().to_string();
        for mesh in &asset.meshes {
            mesh.check(&file)?;
        }
        asset.orient_by_transforms();
        if asset.meshes.iter().all(|m| m.triangles.is_empty()) {
            return Err(Error::InvalidField {
                file,
                field: "(meshes)".into(),
                reason: "has no triangles to collide with".into(),
            });
        }
        Ok(asset)
    }

    /// Index of the clip called `name` (see [`find_clip`]).
    pub fn clip_index(&self, name: &str) -> Option<usize> {
        find_clip(self.clips.iter().map(|c| c.name.as_str()), name)
    }

    /// The triangles over [`Asset::pose`]'s vertices that collide: of the meshes `meshes`
    /// keeps (all of them without one), those the `joints` selection keeps (see `joints.rs`).
    pub fn colliding_triangles(
        &self,
        meshes: Option<&crate::scene::MeshSelection>,
        joints: Option<&crate::scene::MeshSelection>,
        file: &Path,
    ) -> Result<Vec<[u32; 3]>> {
        let triangles = self.mesh_selected(meshes, file)?;
        match joints {
            Some(joints) => self.joint_selected(triangles, joints, file),
            None => Ok(triangles),
        }
    }

    /// The triangles over [`Asset::pose`]'s vertices of the meshes `selection` keeps (all of
    /// them without one). Refuses a name that matches no mesh, node or material, and a
    /// selection that keeps no triangle, naming the file's meshes.
    fn mesh_selected(
        &self,
        selection: Option<&crate::scene::MeshSelection>,
        file: &Path,
    ) -> Result<Vec<[u32; 3]>> {
        let Some(selection) = selection else {
            return Ok(self.triangles());
        };
        let bad = |reason: String| Error::InvalidField {
            file: file.display().to_string(),
            field: "meshes".into(),
            reason,
        };
        let listing = || {
            self.meshes
                .iter()
                .map(|m| {
                    format!(
                        "{:?} (node {:?}, material {:?})",
                        m.name, m.node, m.material
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        if let Some(name) = selection
            .names()
            .iter()
            .find(|n| !self.meshes.iter().any(|m| matches(m, n)))
        {
            return Err(bad(format!(
                "{name:?} names no mesh, node or material; the file has {}",
                listing()
            )));
        }
        let mut out = Vec::new();
        self.for_each_copy(|m, at| {
            if selection.collides(m) {
                out.extend(m.triangles.iter().map(|&t| at.place(t)));
            }
        });
        if out.is_empty() {
            return Err(bad(format!(
                "keeps no triangle to collide with; the file has {}",
                listing()
            )));
        }
        Ok(out)
    }

    /// Calls `f` for each mesh as laid out in [`Asset::pose`] (rigid meshes once per instance)
    /// with where the copy is ([`Placed`]).
    fn for_each_copy<'a>(&'a self, mut f: impl FnMut(&'a Mesh, Placed)) {
        let mut base = 0u32;
        for (k, m) in self.meshes.iter().enumerate() {
            for copy in 0..m.copies() {
                let flip = m.flipped.get(copy).copied().unwrap_or(false);
                f(
                    m,
                    Placed {
                        mesh: k,
                        copy,
                        base,
                        flip,
                    },
                );
                base += m.vertices.len() as u32;
            }
        }
    }

    /// Global transform of every node at time `t` [s] of `clip` (rest pose without a clip),
    /// without the joint offsets.
    pub fn node_transforms(&self, clip: Option<usize>, t: f64) -> Vec<Mat4> {
        self.globals(&self.local_transforms(clip, t))
    }

    /// Every node's global transform from every node's transform relative to its parent.
    fn globals(&self, local: &[Mat4]) -> Vec<Mat4> {
        let mut global: Vec<Mat4> = Vec::with_capacity(local.len());
        for (i, n) in self.nodes.iter().enumerate() {
            let g = match n.parent {
                Some(p) => global[p] * local[i],
                None => local[i],
            };
            global.push(g);
        }
        global
    }

    /// Every posed vertex at time `t` of `clip`: meshes in file order, rigid meshes once per
    /// instance. The order (and count) never changes with time.
    pub fn pose(&self, clip: Option<usize>, t: f64) -> Vec<Vec3> {
        self.skin(
            &self.globals(&self.posed_locals(clip, t)),
            &self.weights_at(clip, t),
        )
    }

    /// [`Asset::local_transforms`] with the joint offsets applied: the clip as posed.
    fn posed_locals(&self, clip: Option<usize>, t: f64) -> Vec<Mat4> {
        let mut local = self.local_transforms(clip, t);
        for &(node, turn) in &self.offsets {
            local[node] *= turn;
        }
        local
    }

    /// Every node's transform relative to its parent at time `t` of `clip` (rest without one).
    fn local_transforms(&self, clip: Option<usize>, t: f64) -> Vec<Mat4> {
        let mut local: Vec<Mat4> = self.nodes.iter().map(|n| n.local).collect();
        if let Some(c) = clip.and_then(|c| self.clips.get(c)) {
            for ch in &c.channels {
                let rest = self.nodes[ch.node].local.to_scale_rotation_translation();
                let s = sample_vec(&ch.scale, t).unwrap_or(rest.0);
                let r = sample_quat(&ch.rotation, t).unwrap_or(rest.1);
                let tr = sample_vec(&ch.translation, t).unwrap_or(rest.2);
                local[ch.node] = Mat4::from_scale_rotation_translation(s, r, tr);
            }
        }
        local
    }

    /// Every vertex with the nodes at `global` and the morph targets at `weights`: rigid meshes
    /// once per instance, skinned ones by their bones.
    fn skin(&self, global: &[Mat4], weights: &morph::Weights) -> Vec<Vec3> {
        let mut out = Vec::new();
        for (m, weights) in self.meshes.iter().zip(weights) {
            if m.bones.is_empty() {
                for (&node, w) in m.instances.iter().zip(weights) {
                    let shaped = m.shaped(w);
                    out.extend(shaped.iter().map(|&v| global[node].transform_point3(v)));
                }
                continue;
            }
            let skins: Vec<Mat4> = m.bones.iter().map(|b| global[b.node] * b.offset).collect();
            let shaped = m.shaped(&weights[0]);
            out.extend(shaped.iter().zip(&m.weights).map(|(&v, w)| {
                if w.is_empty() {
                    return v;
                }
                w.iter()
                    .map(|&(b, wt)| skins[b as usize].transform_point3(v) * wt)
                    .sum()
            }));
        }
        out
    }

    /// The asset without the meshes `names` name (by mesh, node or material name).
    pub fn without(mut self, names: &[String]) -> Asset {
        self.meshes.retain(|m| !names.iter().any(|n| matches(m, n)));
        self
    }

    /// Each copy of a mesh as laid out in [`Asset::pose`] (rigid meshes once per instance):
    /// the mesh and its range of [`Asset::triangles`].
    pub fn mesh_triangle_ranges(&self) -> Vec<(&Mesh, std::ops::Range<usize>)> {
        let mut out = Vec::new();
        let mut start = 0;
        self.for_each_copy(|m, _| {
            out.push((m, start..start + m.triangles.len()));
            start += m.triangles.len();
        });
        out
    }

    /// Texture coordinates over the vertices of [`Asset::pose`], when every mesh has them.
    pub fn uvs(&self) -> Option<Vec<[f32; 2]>> {
        let mut out = Some(Vec::new());
        self.for_each_copy(|m, _| match (&mut out, &m.uvs) {
            (Some(all), Some(uvs)) => all.extend_from_slice(uvs),
            _ => out = None,
        });
        out
    }

    /// Triangles over the vertices of [`Asset::pose`].
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        self.for_each_copy(|m, at| out.extend(m.triangles.iter().map(|&t| at.place(t))));
        out
    }
}

impl Mesh {
    /// How many copies [`Asset::pose`] lays out: a rigid mesh one per node that places it, a
    /// skinned one one.
    pub fn copies(&self) -> usize {
        match self.bones.is_empty() {
            true => self.instances.len(),
            false => 1,
        }
    }

    /// Refuses a mesh with a non-finite vertex, morph target, weight or texture coordinate, a
    /// morph target of another length, or a triangle that names a vertex it does not have:
    /// nothing downstream can make sense of them.
    fn check(&self, file: &str) -> Result<()> {
        let bad = |reason: String| Error::InvalidField {
            file: file.into(),
            field: format!("mesh {:?}", self.name),
            reason,
        };
        if let Some(k) = self.vertices.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("vertex {k} is not finite (NaN or infinite)")));
        }
        let count = self.vertices.len();
        if let Some(t) = self
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= count))
        {
            return Err(bad(format!(
                "triangle {t:?} names a vertex past its {count}"
            )));
        }
        for (k, target) in self.targets.iter().enumerate() {
            if target.len() != count {
                return Err(bad(format!(
                    "morph target {k} moves {} vertices of its {count}",
                    target.len()
                )));
            }
            if target.iter().any(|d| !d.is_finite()) {
                return Err(bad(format!(
                    "morph target {k} is not finite (NaN or infinite)"
                )));
            }
        }
        if (self.target_weights.iter().flatten()).any(|w| !w.is_finite()) {
            return Err(bad(
                "a morph target weight is not finite (NaN or infinite)".into()
            ));
        }
        let uvs_finite = self
            .uvs
            .as_ref()
            .is_none_or(|set| set.iter().all(|t| t[0].is_finite() && t[1].is_finite()));
        if !uvs_finite {
            return Err(bad(
                "a texture coordinate is not finite (NaN or infinite)".into()
            ));
        }
        Ok(())
    }
}

/// Linear interpolation of vector keys at `t`, holding the ends.
pub(crate) fn sample_vec(keys: &[(f64, Vec3)], t: f64) -> Option<Vec3> {
    let (i, f) = bracket(keys.iter().map(|k| k.0), keys.len(), t)?;
    Some(match f {
        Some(f) => keys[i].1.lerp(keys[i + 1].1, f as f32),
        None => keys[i].1,
    })
}

/// Spherical interpolation of rotation keys at `t`, holding the ends.
pub(crate) fn sample_quat(keys: &[(f64, Quat)], t: f64) -> Option<Quat> {
    let (i, f) = bracket(keys.iter().map(|k| k.0), keys.len(), t)?;
    Some(match f {
        Some(f) => keys[i].1.slerp(keys[i + 1].1, f as f32).normalize(),
        None => keys[i].1.normalize(),
    })
}

/// The key at or before `t` and the fraction towards the next (None at or past the ends).
fn bracket(
    times: impl Iterator<Item = f64> + Clone,
    len: usize,
    t: f64,
) -> Option<(usize, Option<f64>)> {
    if len == 0 {
        return None;
    }
    let times: Vec<f64> = times.collect();
    // A NaN time holds the first key rather than indexing with it.
    if t.is_nan() || t <= times[0] {
        return Some((0, None));
    }
    if t >= times[len - 1] {
        return Some((len - 1, None));
    }
    let i = times.partition_point(|&k| k <= t) - 1;
    let span = times[i + 1] - times[i];
    Some((
        i,
        Some(if span > 0.0 {
            (t - times[i]) / span
        } else {
            0.0
        }),
    ))
}
