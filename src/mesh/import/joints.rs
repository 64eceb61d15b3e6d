//! Which of a character's triangles collide by the joints that move them
//! (`characters[].joints`): an animation whose hands pass into its own thighs leaves no room
//! for cloth between them, and a garment caught there is torn whatever the solver does, so a
//! scene can leave the hands (or any joint with everything below it) out of the collisions.
//!
//! A vertex belongs to a joint by its skin weights on that joint and the joints below it; a
//! rigid mesh belongs wholly to the joint whose node (or an ancestor of it) carries it. A
//! triangle belongs where its three vertices' mean share is more than half.

use super::Asset;
use crate::error::{Error, Result};
use crate::scene::MeshSelection;
use std::path::Path;

impl Asset {
    /// The names a joint selection may use: the skinned meshes' bones, and the nodes that
    /// carry rigid meshes with their ancestors (a rig of rigid parts), in the file's order, each
    /// name once.
    pub fn joint_names(&self) -> Vec<&str> {
        let mut joint = vec![false; self.nodes.len()];
        for m in &self.meshes {
            m.bones.iter().for_each(|b| joint[b.node] = true);
            if !m.bones.is_empty() {
                continue;
            }
            for &n in &m.instances {
                let mut at = Some(n);
                while let Some(i) = at {
                    joint[i] = true;
                    at = self.nodes[i].parent;
                }
            }
        }
        // A bone and the node of its rigid mesh often share a name: listed once, both named.
        let mut names: Vec<&str> = Vec::new();
        for (node, _) in self.nodes.iter().zip(&joint).filter(|(_, &j)| j) {
            if !node.name.is_empty() && !names.contains(&node.name.as_str()) {
                names.push(&node.name);
            }
        }
        names
    }

    /// Per node: whether it or an ancestor is called one of `names` (parents come first).
    pub fn nodes_below(&self, names: &[String]) -> Vec<bool> {
        let mut within = vec![false; self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate() {
            within[i] = names.contains(&node.name) || node.parent.is_some_and(|p| within[p]);
        }
        within
    }

    /// Per vertex of [`Asset::pose`]: the share of it that the nodes marked in `within` move
    /// (its skin weights on them; a rigid mesh's vertices 1 or 0 by the node carrying them).
    pub fn share_moved_by(&self, within: &[bool]) -> Vec<f32> {
        let mut share = Vec::new();
        for m in &self.meshes {
            if m.bones.is_empty() {
                for &node in &m.instances {
                    let w = if within[node] { 1.0 } else { 0.0 };
                    share.extend(std::iter::repeat_n(w, m.vertices.len()));
                }
            } else {
                share.extend(m.weights.iter().map(|vertex| {
                    let on = vertex
                        .iter()
                        .filter(|(b, _)| within[m.bones[*b as usize].node]);
                    on.map(|(_, w)| w).sum::<f32>()
                }));
            }
        }
        share
    }

    /// Per triangle of `triangles` (over [`Asset::pose`]'s vertices): the node that moves it
    /// most, by its three vertices' skin weights (a rigid mesh's by the node that carries it);
    /// None where no node moves it.
    pub fn triangle_joints(&self, triangles: &[[u32; 3]]) -> Vec<Option<usize>> {
        let mut weights: Vec<Vec<(usize, f32)>> = Vec::new();
        for m in &self.meshes {
            if m.bones.is_empty() {
                for &node in &m.instances {
                    weights.extend(std::iter::repeat_n(vec![(node, 1.0)], m.vertices.len()));
                }
            } else {
                weights.extend(m.weights.iter().map(|vertex| {
                    let on = vertex.iter().map(|&(b, w)| (m.bones[b as usize].node, w));
                    on.collect()
                }));
            }
        }
        (triangles.iter())
            .map(|t| {
                let mut sums: Vec<(usize, f32)> = Vec::new();
                for &(node, w) in t.iter().flat_map(|&v| &weights[v as usize]) {
                    match sums.iter_mut().find(|(n, _)| *n == node) {
                        Some(sum) => sum.1 += w,
                        None => sums.push((node, w)),
                    }
                }
                let most = sums
                    .iter()
                    .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
                most.map(|&(node, _)| node)
            })
            .collect()
    }

    /// Keeps the `triangles` (over [`Asset::pose`]'s vertices) that `joints` lets collide: with
    /// `include`, those mostly moved by the joints named and the joints below them; with
    /// `exclude`, the others. Refuses a name that is no joint of the file, and a selection
    /// that keeps no triangle, naming the file's joints.
    pub(super) fn joint_selected(
        &self,
        triangles: Vec<[u32; 3]>,
        joints: &MeshSelection,
        file: &Path,
    ) -> Result<Vec<[u32; 3]>> {
        let names = self.joint_names();
        let bad = |reason: String| Error::InvalidField {
            file: file.display().to_string(),
            field: "joints".into(),
            reason: format!("{reason}; the file's joints are {}", listing(&names)),
        };
        if let Some(name) = joints.names().iter().find(|n| !names.contains(&n.as_str())) {
            return Err(bad(format!("{name:?} is no joint of the file")));
        }
        let share = self.share_moved_by(&self.nodes_below(joints.names()));
        let include = matches!(joints, MeshSelection::Include(_));
        let kept: Vec<[u32; 3]> = triangles
            .into_iter()
            .filter(|t| {
                let mean = t.iter().map(|&i| share[i as usize]).sum::<f32>() / 3.0;
                (mean > 0.5) == include
            })
            .collect();
        if kept.is_empty() {
            return Err(bad("keeps no triangle to collide with".into()));
        }
        Ok(kept)
    }
}

/// The names, quoted, comma-separated ("none" for none).
pub(super) fn listing(names: &[&str]) -> String {
    if names.is_empty() {
        return "none".into();
    }
    let quoted: Vec<String> = names.iter().map(|n| format!("{n:?}")).collect();
    quoted.join(", ")
}
