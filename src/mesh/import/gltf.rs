//! glTF 2.0 (`.gltf`, `.glb`) read by the `gltf` crate, by node index as the format means it.
//!
//! Skins name their joints and animation channels their target by node *index*, so a file
//! whose mesh node and pelvis bone are both called "Body" binds each to the right node (assimp,
//! which binds by name, cannot). Layout: meshes in file order, one drape mesh per triangle
//! primitive (named after its mesh), a skinned mesh once, a rigid one once per node that places
//! it (depth-first). assimp's import of the same file gives the same vertices within 1e-5 m in
//! every shipped clip, but orders some meshes otherwise and names primitives "Torso-0".
//!
//! As in assimp's glTF importer, texture V is flipped (glTF's origin is top-left, OBJ's
//! bottom-left). Morph targets' position displacements are read with their default and
//! animated weights, and applied before skinning ([`super::morph`]). Samplers: linear keys as
//! they are, step keys doubled (the value held until the next key's time), cubic-spline keys
//! sampled eight times per interval on their Hermite curve.

use super::{Asset, Bone, Channel, Clip, Mesh, Node};
use crate::error::{Error, Result};
use ::gltf::animation::{util::ReadOutputs, Interpolation};
use ::gltf::mesh::Mode;
use glam::{Mat4, Quat, Vec3};
use std::path::Path;

/// Reads a glTF or GLB file (with its external buffers beside it; images are not read).
pub fn open(path: &Path) -> Result<Asset> {
    let file = path.display().to_string();
    let bad = |field: &str, reason: String| Error::InvalidField {
        file: file.clone(),
        field: field.into(),
        reason,
    };
    let ::gltf::Gltf { document, blob } = ::gltf::Gltf::open(path)
        .map_err(|e| bad("(file)", format!("is not readable glTF: {e}")))?;
    let buffers = ::gltf::import_buffers(&document, path.parent(), blob)
        .map_err(|e| bad("buffers", format!("cannot be read: {e}")))?;
    let (nodes, index) = hierarchy(&document, &file)?;
    let meshes = meshes(&document, &nodes, &index, &buffers, &file)?;
    let clips = document
        .animations()
        .map(|a| clip(&a, &index, &buffers))
        .collect();
    Ok(Asset {
        nodes,
        meshes,
        clips,
        warnings: Vec::new(),
        offsets: Vec::new(),
    })
}

/// The bytes of a buffer, as the `gltf` crate's readers ask for them.
fn data<'s>(
    buffers: &'s [::gltf::buffer::Data],
) -> impl Clone + for<'a> Fn(::gltf::Buffer<'a>) -> Option<&'s [u8]> {
    move |b| buffers.get(b.index()).map(|d| &d.0[..])
}

/// The default scene's nodes (else the first scene's, else every node without a parent)
/// flattened in depth-first pre-order, and each glTF node's place in that list.
fn hierarchy(doc: &::gltf::Document, file: &str) -> Result<(Vec<Node>, Vec<Option<usize>>)> {
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                n.children().for_each(|c| child[c.index()] = true);
            }
            doc.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    let mut nodes = Vec::new();
    let mut index = vec![None; doc.nodes().len()];
    // An explicit stack: a hostile file's deep or cyclic hierarchy cannot overflow ours.
    let mut stack: Vec<(::gltf::Node, Option<usize>)> =
        roots.into_iter().rev().map(|n| (n, None)).collect();
    while let Some((node, parent)) = stack.pop() {
        if index[node.index()].is_some() {
            return Err(Error::InvalidField {
                file: file.into(),
                field: format!("nodes[{}]", node.index()),
                reason: "is reached twice: the node hierarchy must be a tree".into(),
            });
        }
        let at = nodes.len();
        index[node.index()] = Some(at);
        nodes.push(Node {
            name: node.name().unwrap_or_default().to_string(),
            parent,
            local: Mat4::from_cols_array_2d(&node.transform().matrix()),
        });
        let children: Vec<_> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, Some(at))));
    }
    Ok((nodes, index))
}

/// Every triangle primitive as a drape mesh, in assimp's order.
fn meshes(
    doc: &::gltf::Document,
    nodes: &[Node],
    index: &[Option<usize>],
    buffers: &[::gltf::buffer::Data],
    file: &str,
) -> Result<Vec<Mesh>> {
    let bad = |field: String, reason: String| Error::InvalidField {
        file: file.into(),
        field,
        reason,
    };
    // The scene's nodes that place each mesh, depth-first.
    let mut placed: Vec<Vec<::gltf::Node>> = vec![Vec::new(); doc.meshes().len()];
    let mut order: Vec<::gltf::Node> = doc.nodes().filter(|n| index[n.index()].is_some()).collect();
    order.sort_by_key(|n| index[n.index()]);
    for n in order {
        if let Some(m) = n.mesh() {
            placed[m.index()].push(n);
        }
    }
    let mut out = Vec::new();
    for mesh in doc.meshes() {
        let users = &placed[mesh.index()];
        let skin = users.iter().find_map(|n| n.skin());
        let bones = match &skin {
            Some(skin) => skin_bones(skin, index, buffers, file)?,
            None => Vec::new(),
        };
        let name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("mesh{}", mesh.index()));
        for (k, primitive) in mesh.primitives().enumerate() {
            let field = || format!("meshes[{}].primitives[{k}]", mesh.index());
            let reader = primitive.reader(data(buffers));
            let Some(positions) = reader.read_positions() else {
                return Err(bad(field(), "has no POSITION attribute".into()));
            };
            let vertices: Vec<Vec3> = positions.map(Vec3::from).collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..vertices.len() as u32).collect(),
            };
            // Points and lines are no surface to collide with.
            let Some(triangles) = triangles_of(primitive.mode(), &indices) else {
                continue;
            };
            let mut weights = vec![Vec::new(); vertices.len()];
            if skin.is_some() {
                for set in 0.. {
                    let (Some(joints), Some(w)) =
                        (reader.read_joints(set), reader.read_weights(set))
                    else {
                        break;
                    };
                    for (v, (j, w)) in joints.into_u16().zip(w.into_f32()).enumerate() {
                        let Some(list) = weights.get_mut(v) else {
                            break;
                        };
                        for (&j, &w) in j.iter().zip(&w) {
                            if w > 0.0 {
                                if j as usize >= bones.len() {
                                    return Err(bad(
                                        field(),
                                        format!(
                                            "vertex {v} names joint {j} of a skin with {}",
                                            bones.len()
                                        ),
                                    ));
                                }
                                list.push((j as u32, w));
                            }
                        }
                    }
                }
                super::normalise(&mut weights);
            }
            let targets: Vec<Vec<Vec3>> = (reader.read_morph_targets())
                .map(|(positions, _, _)| match positions {
                    Some(d) => d.map(Vec3::from).collect(),
                    None => vec![Vec3::ZERO; vertices.len()],
                })
                .collect();
            let mut target_weights = Vec::new();
            for n in users.iter().filter(|n| index[n.index()].is_some()) {
                let w = n.weights().or(mesh.weights()).unwrap_or_default();
                if !w.is_empty() && w.len() != targets.len() {
                    let field = match n.weights() {
                        Some(_) => format!("nodes[{}].weights", n.index()),
                        None => format!("meshes[{}].weights", mesh.index()),
                    };
                    return Err(bad(
                        field,
                        format!(
                            "has {} weights for {} morph targets",
                            w.len(),
                            targets.len()
                        ),
                    ));
                }
                target_weights.push(w.to_vec());
            }
            out.push(Mesh {
                name: name.clone(),
                node: users
                    .first()
                    .and_then(|n| index[n.index()])
                    .map(|n| nodes[n].name.clone())
                    .unwrap_or_default(),
                material: primitive.material().name().unwrap_or_default().to_string(),
                vertices,
                triangles,
                bones: bones.clone(),
                weights,
                instances: users.iter().filter_map(|n| index[n.index()]).collect(),
                flipped: Vec::new(),
                targets,
                target_weights,
                uvs: reader
                    .read_tex_coords(0)
                    .map(|t| t.into_f32().map(|[u, v]| [u, 1.0 - v]).collect()),
            });
        }
    }
    Ok(out)
}

/// The triangles of a primitive drawn in `mode` from `indices` (None for points and lines).
fn triangles_of(mode: Mode, indices: &[u32]) -> Option<Vec<[u32; 3]>> {
    Some(match mode {
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| match i % 2 {
                0 => [indices[i - 2], indices[i - 1], indices[i]],
                _ => [indices[i - 1], indices[i - 2], indices[i]],
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len())
            .map(|i| [indices[0], indices[i - 1], indices[i]])
            .collect(),
        _ => return None,
    })
}

/// A skin's joints as bones: the node each names and its inverse bind matrix.
fn skin_bones(
    skin: &::gltf::Skin,
    index: &[Option<usize>],
    buffers: &[::gltf::buffer::Data],
    file: &str,
) -> Result<Vec<Bone>> {
    let inverse: Vec<Mat4> = skin
        .reader(data(buffers))
        .read_inverse_bind_matrices()
        .map(|m| m.map(|c| Mat4::from_cols_array_2d(&c)).collect())
        .unwrap_or_default();
    skin.joints()
        .enumerate()
        .map(|(j, joint)| {
            let node = index[joint.index()].ok_or_else(|| Error::InvalidField {
                file: file.into(),
                field: format!("skins[{}].joints[{j}]", skin.index()),
                reason: format!("names node {}, which is not in the scene", joint.index()),
            })?;
            Ok(Bone {
                node,
                offset: inverse.get(j).copied().unwrap_or(Mat4::IDENTITY),
            })
        })
        .collect()
}

/// An animation as one channel per animated node, times in seconds.
fn clip(
    animation: &::gltf::Animation,
    index: &[Option<usize>],
    buffers: &[::gltf::buffer::Data],
) -> Clip {
    let mut channels: Vec<Channel> = Vec::new();
    let mut duration = 0.0f64;
    for ch in animation.channels() {
        let Some(node) = index[ch.target().node().index()] else {
            continue;
        };
        let reader = ch.reader(data(buffers));
        let (Some(times), Some(outputs)) = (reader.read_inputs(), reader.read_outputs()) else {
            continue;
        };
        let times: Vec<f64> = times.map(f64::from).collect();
        if let Some(&last) = times.last() {
            duration = duration.max(last);
        }
        let at = match channels.iter().position(|c| c.node == node) {
            Some(i) => i,
            None => {
                channels.push(Channel {
                    node,
                    ..Channel::default()
                });
                channels.len() - 1
            }
        };
        let how = ch.sampler().interpolation();
        let target = &mut channels[at];
        match outputs {
            ReadOutputs::Translations(v) => {
                target.translation = keys(&times, v.map(Vec3::from).collect(), how)
            }
            ReadOutputs::Scales(v) => target.scale = keys(&times, v.map(Vec3::from).collect(), how),
            ReadOutputs::Rotations(r) => {
                let values = r.into_f32().map(Quat::from_array).collect();
                target.rotation = keys(&times, values, how);
            }
            ReadOutputs::MorphTargetWeights(w) => {
                target.weights = weight_keys(&times, w.into_f32().collect(), how)
            }
        }
    }
    Clip {
        name: animation.name().unwrap_or_default().to_string(),
        duration,
        channels,
    }
}

/// A weights sampler's keys per morph target: its outputs hold every target's weight at each
/// key (with a cubic spline, every in-tangent, then every value, then every out-tangent).
fn weight_keys(times: &[f64], flat: Vec<f32>, how: Interpolation) -> Vec<Vec<(f64, f32)>> {
    let per_key = if how == Interpolation::CubicSpline {
        3
    } else {
        1
    };
    let targets = flat.len() / (per_key * times.len()).max(1);
    (0..targets)
        .map(|k| {
            let values = (0..times.len() * per_key)
                .filter_map(|slot| flat.get(slot * targets + k).copied())
                .collect();
            keys(times, values, how)
        })
        .collect()
}

/// What a cubic spline needs of a key value: sums of scaled values (component-wise for
/// rotations, renormalised after).
trait Mix: Copy {
    fn scaled(self, s: f32) -> Self;
    fn plus(self, o: Self) -> Self;
    fn tidy(self) -> Self {
        self
    }
}

impl Mix for Vec3 {
    fn scaled(self, s: f32) -> Self {
        self * s
    }
    fn plus(self, o: Self) -> Self {
        self + o
    }
}

impl Mix for f32 {
    fn scaled(self, s: f32) -> Self {
        self * s
    }
    fn plus(self, o: Self) -> Self {
        self + o
    }
}

impl Mix for Quat {
    fn scaled(self, s: f32) -> Self {
        Quat::from_vec4(glam::Vec4::from(self) * s)
    }
    fn plus(self, o: Self) -> Self {
        Quat::from_vec4(glam::Vec4::from(self) + glam::Vec4::from(o))
    }
    fn tidy(self) -> Self {
        self.normalize()
    }
}

/// Cubic-spline intervals are sampled this many times each.
const SPLINE_SAMPLES: usize = 8;

/// A sampler's keys as (time, value) pairs that drape's linear sampler reproduces.
fn keys<T: Mix>(times: &[f64], values: Vec<T>, how: Interpolation) -> Vec<(f64, T)> {
    match how {
        Interpolation::Linear => times.iter().copied().zip(values).collect(),
        Interpolation::Step => {
            let mut out = Vec::with_capacity(2 * times.len());
            for (i, (&t, &v)) in times.iter().zip(&values).enumerate() {
                if i > 0 {
                    out.push((t, values[i - 1]));
                }
                out.push((t, v));
            }
            out
        }
        Interpolation::CubicSpline => {
            // Triples per key: in-tangent, value, out-tangent.
            let n = times.len().min(values.len() / 3);
            let value = |i: usize| values[3 * i + 1];
            let mut out = Vec::with_capacity(n * SPLINE_SAMPLES);
            for i in 0..n {
                if i + 1 == n {
                    out.push((times[i], value(i).tidy()));
                    break;
                }
                let dt = (times[i + 1] - times[i]) as f32;
                let (b, a) = (values[3 * i + 2], values[3 * (i + 1)]);
                for k in 0..SPLINE_SAMPLES {
                    let s = k as f32 / SPLINE_SAMPLES as f32;
                    let (s2, s3) = (s * s, s * s * s);
                    let p = value(i)
                        .scaled(2.0 * s3 - 3.0 * s2 + 1.0)
                        .plus(b.scaled((s3 - 2.0 * s2 + s) * dt))
                        .plus(value(i + 1).scaled(-2.0 * s3 + 3.0 * s2))
                        .plus(a.scaled((s3 - s2) * dt));
                    out.push((times[i] + s as f64 * dt as f64, p.tidy()));
                }
            }
            out
        }
    }
}
