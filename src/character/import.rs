//! Importing animated characters through assimp (russimp, linking the system libassimp): the node
//! hierarchy, meshes, bones and clips, turned into plain drape data that can be posed at any time.
//!
//! The three traps of real files (`shared/assets/MANIFEST.md`) are handled here:
//! 1. a skinned mesh's vertices are Σ wᵢ · G(boneᵢ) · offsetᵢ · v: its own node transform is *not*
//!    applied (only rigid meshes use their node's global transform);
//! 2. animation channels and bones name nodes, and names can repeat: each name means the first
//!    node of that name in depth-first pre-order (what assimp's `aiNode::FindNode` returns);
//! 3. skin weights are normalised per vertex (some files sum to 1.755).
//!
//! Time: assimp gives key times in ticks; seconds = ticks / ticks_per_second (glTF: 1000). Rotation
//! keys are interpolated with slerp, translation and scale linearly.

use crate::error::{Error, Result};
use glam::{Mat4, Quat, Vec3};
use russimp::scene::{PostProcess, Scene as AiScene};
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

/// One mesh as posed by the hierarchy.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub bones: Vec<Bone>,
    /// Per vertex: (bone index, normalised weight).
    pub weights: Vec<Vec<(u32, f32)>>,
    /// Nodes that place this mesh (rigid meshes only; a skinned mesh is placed by its bones).
    pub instances: Vec<usize>,
    /// First texture coordinate set, one per vertex, when the file has one.
    pub uvs: Option<Vec<[f32; 2]>>,
}

/// Keys of one animated node, times in seconds.
#[derive(Clone, Debug, Default)]
pub struct Channel {
    pub node: usize,
    pub translation: Vec<(f64, Vec3)>,
    pub rotation: Vec<(f64, Quat)>,
    pub scale: Vec<(f64, Vec3)>,
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
}

fn mat4(m: &russimp::Matrix4x4) -> Mat4 {
    // assimp matrices are row-major with the translation in the fourth column.
    Mat4::from_cols_array(&[
        m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2, m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4,
        m.d4,
    ])
}

fn vec3(v: &russimp::Vector3D) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}

/// Flattens the hierarchy under `node` in depth-first pre-order.
fn flatten(
    node: &russimp::node::Node,
    parent: Option<usize>,
    out: &mut Vec<Node>,
    meshes: &mut Vec<(usize, u32)>,
) {
    let index = out.len();
    out.push(Node {
        name: node.name.clone(),
        parent,
        local: mat4(&node.transformation),
    });
    meshes.extend(node.meshes.iter().map(|&m| (index, m)));
    for child in node.children.borrow().iter() {
        flatten(child, Some(index), out, meshes);
    }
}

impl Asset {
    /// Reads any file assimp reads. Errors name the file and the reason.
    pub fn open(path: &Path) -> Result<Asset> {
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
        let name = path.to_str().ok_or_else(|| Error::InvalidField {
            file: path.display().to_string(),
            field: "path".into(),
            reason: "is not valid UTF-8, which assimp needs".into(),
        })?;
        // No post-processing: the MANIFEST's numbers are for flags 0 (no vertex joining, no
        // degenerate-triangle splitting); non-triangle faces are skipped below.
        let flags: Vec<PostProcess> = Vec::new();
        let scene = AiScene::from_file(name, flags).map_err(|e| Error::InvalidField {
            file: path.display().to_string(),
            field: "(file)".into(),
            reason: format!("assimp cannot import it: {e}"),
        })?;
        Asset::from_scene(&scene, &path.display().to_string())
    }

    /// One pass over assimp's scene (long: nodes, meshes with their bones, then clips, all
    /// sharing the node table).
    fn from_scene(scene: &AiScene, file: &str) -> Result<Asset> {
        let root = scene.root.as_ref().ok_or_else(|| Error::InvalidField {
            file: file.into(),
            field: "(scene)".into(),
            reason: "has no node hierarchy".into(),
        })?;
        let mut nodes = Vec::new();
        let mut placements = Vec::new();
        flatten(root, None, &mut nodes, &mut placements);
        let find = |name: &str| nodes.iter().position(|n| n.name == name);

        let mut meshes = Vec::new();
        for (m, ai) in scene.meshes.iter().enumerate() {
            let triangles: Vec<[u32; 3]> = ai
                .faces
                .iter()
                .filter(|f| f.0.len() == 3)
                .map(|f| [f.0[0], f.0[1], f.0[2]])
                .collect();
            check_mesh(ai, &triangles, file)?;
            let mut weights = vec![Vec::new(); ai.vertices.len()];
            let mut bones = Vec::new();
            for bone in &ai.bones {
                let node = find(&bone.name).ok_or_else(|| Error::InvalidField {
                    file: file.into(),
                    field: format!("mesh {:?} bone {:?}", ai.name, bone.name),
                    reason: "names no node of the hierarchy".into(),
                })?;
                for w in &bone.weights {
                    if let Some(list) = weights.get_mut(w.vertex_id as usize) {
                        list.push((bones.len() as u32, w.weight));
                    }
                }
                bones.push(Bone {
                    node,
                    offset: mat4(&bone.offset_matrix),
                });
            }
            for list in &mut weights {
                let sum: f32 = list.iter().map(|w| w.1).sum();
                if sum > 0.0 {
                    list.iter_mut().for_each(|w| w.1 /= sum);
                }
            }
            meshes.push(Mesh {
                name: ai.name.clone(),
                vertices: ai.vertices.iter().map(vec3).collect(),
                triangles,
                bones,
                weights,
                instances: placements
                    .iter()
                    .filter(|p| p.1 as usize == m)
                    .map(|p| p.0)
                    .collect(),
                uvs: ai
                    .texture_coords
                    .first()
                    .and_then(|set| set.as_ref())
                    .map(|set| set.iter().map(|t| [t.x, t.y]).collect()),
            });
        }
        if meshes.iter().all(|m| m.triangles.is_empty()) {
            return Err(Error::InvalidField {
                file: file.into(),
                field: "(meshes)".into(),
                reason: "has no triangles to collide with".into(),
            });
        }

        let clips = scene
            .animations
            .iter()
            .map(|a| {
                let tps = if a.ticks_per_second > 0.0 {
                    a.ticks_per_second
                } else {
                    25.0
                };
                let channels = a
                    .channels
                    .iter()
                    .filter_map(|c| {
                        Some(Channel {
                            node: find(&c.name)?,
                            translation: c
                                .position_keys
                                .iter()
                                .map(|k| (k.time / tps, vec3(&k.value)))
                                .collect(),
                            rotation: c
                                .rotation_keys
                                .iter()
                                .map(|k| {
                                    (
                                        k.time / tps,
                                        Quat::from_xyzw(k.value.x, k.value.y, k.value.z, k.value.w),
                                    )
                                })
                                .collect(),
                            scale: c
                                .scaling_keys
                                .iter()
                                .map(|k| (k.time / tps, vec3(&k.value)))
                                .collect(),
                        })
                    })
                    .collect();
                Clip {
                    name: a.name.clone(),
                    duration: a.duration / tps,
                    channels,
                }
            })
            .collect();
        Ok(Asset {
            nodes,
            meshes,
            clips,
        })
    }

    /// Index of the clip called `name`, or given as a number ("0" for an unnamed clip).
    pub fn clip_index(&self, name: &str) -> Option<usize> {
        self.clips
            .iter()
            .position(|c| c.name == name)
            .or_else(|| name.parse::<usize>().ok().filter(|&i| i < self.clips.len()))
    }

    /// Global transform of every node at time `t` [s] of `clip` (rest pose without a clip).
    pub fn node_transforms(&self, clip: Option<usize>, t: f64) -> Vec<Mat4> {
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
        let global = self.node_transforms(clip, t);
        let mut out = Vec::new();
        for m in &self.meshes {
            if m.bones.is_empty() {
                for &node in &m.instances {
                    out.extend(m.vertices.iter().map(|&v| global[node].transform_point3(v)));
                }
                continue;
            }
            let skins: Vec<Mat4> = m.bones.iter().map(|b| global[b.node] * b.offset).collect();
            out.extend(m.vertices.iter().zip(&m.weights).map(|(&v, w)| {
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

    /// Texture coordinates over the vertices of [`Asset::pose`], when every mesh has them.
    pub fn uvs(&self) -> Option<Vec<[f32; 2]>> {
        let mut out = Vec::new();
        for m in &self.meshes {
            let copies = if m.bones.is_empty() {
                m.instances.len()
            } else {
                1
            };
            for _ in 0..copies {
                out.extend_from_slice(m.uvs.as_ref()?);
            }
        }
        Some(out)
    }

    /// Triangles over the vertices of [`Asset::pose`].
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        let mut base = 0u32;
        for m in &self.meshes {
            let copies = if m.bones.is_empty() {
                m.instances.len()
            } else {
                1
            };
            for _ in 0..copies {
                out.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
                base += m.vertices.len() as u32;
            }
        }
        out
    }
}

/// Refuses a mesh with a non-finite vertex or texture coordinate, or a triangle that names a
/// vertex it does not have: nothing downstream can make sense of them.
fn check_mesh(ai: &russimp::mesh::Mesh, triangles: &[[u32; 3]], file: &str) -> Result<()> {
    let bad = |reason: String| Error::InvalidField {
        file: file.into(),
        field: format!("mesh {:?}", ai.name),
        reason,
    };
    if let Some(k) = ai
        .vertices
        .iter()
        .position(|v| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()))
    {
        return Err(bad(format!("vertex {k} is not finite (NaN or infinite)")));
    }
    if let Some(t) = triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= ai.vertices.len()))
    {
        return Err(bad(format!(
            "triangle {t:?} names a vertex past its {}",
            ai.vertices.len()
        )));
    }
    let uvs_finite = ai
        .texture_coords
        .first()
        .and_then(|set| set.as_ref())
        .is_none_or(|set| set.iter().all(|t| t.x.is_finite() && t.y.is_finite()));
    if !uvs_finite {
        return Err(bad(
            "a texture coordinate is not finite (NaN or infinite)".into()
        ));
    }
    Ok(())
}

/// Linear interpolation of vector keys at `t`, holding the ends.
fn sample_vec(keys: &[(f64, Vec3)], t: f64) -> Option<Vec3> {
    let (i, f) = bracket(keys.iter().map(|k| k.0), keys.len(), t)?;
    Some(match f {
        Some(f) => keys[i].1.lerp(keys[i + 1].1, f as f32),
        None => keys[i].1,
    })
}

/// Spherical interpolation of rotation keys at `t`, holding the ends.
fn sample_quat(keys: &[(f64, Quat)], t: f64) -> Option<Quat> {
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
