//! Every format but glTF, read through assimp (russimp, linking the system libassimp).
//!
//! assimp hands bones and animation channels over by node *name*, and real files repeat names
//! (a mesh node and a bone both called "Body", exporters' "Armature" twins). Before binding,
//! every name is resolved to one node: nodes that carry no mesh (bones) before nodes that do,
//! then depth-first pre-order. Each repeated name is named in a warning.
//!
//! Time: assimp gives key times in ticks; seconds = ticks / ticks_per_second (25 when unset).

use super::{Asset, Bone, Channel, Clip, Mesh, Node};
use crate::error::{Error, Result};
use glam::{Mat4, Quat, Vec3};
use russimp::scene::{PostProcess, Scene as AiScene};
use std::collections::HashMap;
use std::path::Path;

/// Reads any file assimp reads.
pub fn open(path: &Path) -> Result<Asset> {
    let file = path.display().to_string();
    let name = path.to_str().ok_or_else(|| Error::InvalidField {
        file: file.clone(),
        field: "path".into(),
        reason: "is not valid UTF-8, which assimp needs".into(),
    })?;
    // No post-processing: the MANIFEST's numbers are for flags 0 (no vertex joining, no
    // degenerate-triangle splitting); non-triangle faces are skipped below.
    let flags: Vec<PostProcess> = Vec::new();
    let scene = AiScene::from_file(name, flags).map_err(|e| Error::InvalidField {
        file: file.clone(),
        field: "(file)".into(),
        reason: format!("assimp cannot import it: {e}"),
    })?;
    from_scene(&scene, &file)
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

/// Flattens the hierarchy under `node` in depth-first pre-order, with the (node, mesh) pairs
/// that place meshes.
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

/// Each node name to the one node it binds: of the nodes so named, the first that carries no
/// mesh in depth-first order, else the first. A warning for each name used more than once.
fn bind_names(
    nodes: &[Node],
    placements: &[(usize, u32)],
    file: &str,
) -> (HashMap<String, usize>, Vec<String>) {
    let mut by_name: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, n) in nodes.iter().enumerate() {
        by_name.entry(&n.name).or_default().push(i);
    }
    let carries_mesh = |i: usize| placements.iter().any(|p| p.0 == i);
    let mut bound = HashMap::new();
    let mut repeated = Vec::new();
    for (name, list) in by_name {
        let chosen = list
            .iter()
            .copied()
            .find(|&i| !carries_mesh(i))
            .unwrap_or(list[0]);
        if list.len() > 1 {
            repeated.push((list[0], name.to_string(), list.len(), carries_mesh(chosen)));
        }
        bound.insert(name.to_string(), chosen);
    }
    repeated.sort();
    let warnings = repeated
        .into_iter()
        .map(|(_, name, count, mesh)| {
            format!(
                "{file}: {count} nodes are named {name:?}; bones and animation channels of that \
                 name bind to the {} (assimp binds by name; glTF files are read by index)",
                if mesh {
                    "first of them in depth-first order"
                } else {
                    "first that carries no mesh (a bone)"
                }
            )
        })
        .collect();
    (bound, warnings)
}

/// The name of material `index` of the scene ("" when unnamed).
fn material_name(scene: &AiScene, index: u32) -> String {
    use russimp::material::PropertyTypeInfo;
    scene
        .materials
        .get(index as usize)
        .and_then(|m| {
            m.properties
                .iter()
                .find_map(|p| match (&p.key[..], &p.data) {
                    ("?mat.name", PropertyTypeInfo::String(s)) => Some(s.clone()),
                    _ => None,
                })
        })
        .unwrap_or_default()
}

/// One pass over assimp's scene (long: nodes, meshes with their bones, then clips, all sharing
/// the node table).
fn from_scene(scene: &AiScene, file: &str) -> Result<Asset> {
    let root = scene.root.as_ref().ok_or_else(|| Error::InvalidField {
        file: file.into(),
        field: "(scene)".into(),
        reason: "has no node hierarchy".into(),
    })?;
    let mut nodes = Vec::new();
    let mut placements = Vec::new();
    flatten(root, None, &mut nodes, &mut placements);
    let (bound, mut warnings) = bind_names(&nodes, &placements, file);
    let shaped: Vec<&str> = (scene.meshes.iter())
        .filter(|m| !m.anim_meshes.is_empty())
        .map(|m| m.name.as_str())
        .collect();
    if !shaped.is_empty() {
        warnings.push(format!(
            "{file}: meshes {shaped:?} have morph targets (blend shapes), which drape reads from glTF only: they collide in their base shape; export the character as glTF (or apply the shapes) for the body the DCC shows"
        ));
    }
    let find = |name: &str| bound.get(name).copied();

    let mut meshes = Vec::new();
    for (m, ai) in scene.meshes.iter().enumerate() {
        let triangles: Vec<[u32; 3]> = ai
            .faces
            .iter()
            .filter(|f| f.0.len() == 3)
            .map(|f| [f.0[0], f.0[1], f.0[2]])
            .collect();
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
        super::normalise(&mut weights);
        let instances: Vec<usize> = placements
            .iter()
            .filter(|p| p.1 as usize == m)
            .map(|p| p.0)
            .collect();
        meshes.push(Mesh {
            name: ai.name.clone(),
            node: instances
                .first()
                .map(|&n| nodes[n].name.clone())
                .unwrap_or_default(),
            material: material_name(scene, ai.material_index),
            vertices: ai.vertices.iter().map(vec3).collect(),
            triangles,
            bones,
            weights,
            instances,
            uvs: ai
                .texture_coords
                .first()
                .and_then(|set| set.as_ref())
                .map(|set| set.iter().map(|t| [t.x, t.y]).collect()),
            ..Mesh::default()
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
                        weights: Vec::new(),
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
        warnings,
        offsets: Vec::new(),
    })
}
