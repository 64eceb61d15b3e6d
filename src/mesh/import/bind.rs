//! The bind pose: where a character's meshes lie before any clip moves them, the pose a
//! garment modelled on the character is modelled on and a pre-roll starts from.
//!
//! A skinned mesh's stored vertices are in the space its inverse bind matrices were made in.
//! glTF says those matrices are the inverses of the joints' global transforms, so the stored
//! vertices are the bind pose in the scene's space, as Blender writes them. Files converted
//! from Collada (CesiumMan) made them relative to the mesh's node instead, whose transform
//! then places them: read the glTF way, CesiumMan's bind pose stands along z (his stored
//! vertices are z up, 1.507 m along z) in a y-up scene; read his way, a Blender export of him
//! lies on his side (1.507 m along x). [`Asset::bind_place`] tells the two apart by the
//! skeleton's root joint.

use super::{morph, Asset, Mesh};
use glam::{Mat4, Vec3};

impl Asset {
    /// The bind pose over [`Asset::pose`]'s vertices: skinned meshes as stored (the pose their
    /// inverse bind matrices were made in) placed by [`Asset::bind_place`], rigid meshes by
    /// their nodes in [`Asset::bind_transforms`].
    /// It can differ from the default node pose (files whose nodes rest at a clip's first
    /// frame) and from any clip's first frame.
    pub fn bind_pose(&self) -> Vec<Vec3> {
        let rest = self.node_transforms(None, 0.0);
        let bind = self.bind_transforms();
        let weights = self.default_weights();
        let mut out = Vec::new();
        for (m, weights) in self.meshes.iter().zip(&weights) {
            if m.bones.is_empty() {
                for (&node, w) in m.instances.iter().zip(weights) {
                    let shaped = m.shaped(w);
                    out.extend(shaped.iter().map(|&v| bind[node].transform_point3(v)));
                }
            } else {
                let place = self.bind_place(m, &rest);
                let shaped = m.shaped(&weights[0]);
                out.extend(shaped.iter().map(|&v| place.transform_point3(v)));
            }
        }
        out
    }

    /// Global transform of every node in the bind pose: a bone where its skin's inverse bind
    /// matrix puts it (the first skin that names it), any other node below its parent by its
    /// default local transform.
    pub fn bind_transforms(&self) -> Vec<Mat4> {
        let rest = self.node_transforms(None, 0.0);
        let mut bound: Vec<Option<Mat4>> = vec![None; self.nodes.len()];
        for m in self.meshes.iter().filter(|m| !m.bones.is_empty()) {
            let place = self.bind_place(m, &rest);
            for b in &m.bones {
                bound[b.node].get_or_insert(place * b.offset.inverse());
            }
        }
        let mut global: Vec<Mat4> = Vec::with_capacity(self.nodes.len());
        for (i, n) in self.nodes.iter().enumerate() {
            let g = bound[i].unwrap_or_else(|| match n.parent {
                Some(p) => global[p] * n.local,
                None => n.local,
            });
            global.push(g);
        }
        global
    }

    /// The pose a fraction `w` of the way from the bind pose (0) to time `t` of `clip` (1),
    /// node by node in their parents' frames: rotations by slerp, translations and scales
    /// linearly. Exactly [`Asset::bind_pose`] at 0 and [`Asset::pose`] at 1.
    pub fn blended_pose(&self, clip: Option<usize>, t: f64, w: f32) -> Vec<Vec3> {
        if w <= 0.0 {
            return self.bind_pose();
        }
        if w >= 1.0 {
            return self.pose(clip, t);
        }
        let bind = self.bind_transforms();
        let local_bind = |i: usize| match self.nodes[i].parent {
            Some(p) => bind[p].inverse() * bind[i],
            None => bind[i],
        };
        let target = self.posed_locals(clip, t);
        let mut global: Vec<Mat4> = Vec::with_capacity(self.nodes.len());
        for (i, n) in self.nodes.iter().enumerate() {
            let (s0, r0, t0) = local_bind(i).to_scale_rotation_translation();
            let (s1, r1, t1) = target[i].to_scale_rotation_translation();
            let local = Mat4::from_scale_rotation_translation(
                s0.lerp(s1, w),
                r0.slerp(r1, w).normalize(),
                t0.lerp(t1, w),
            );
            global.push(match n.parent {
                Some(p) => global[p] * local,
                None => local,
            });
        }
        let weights = morph::blend(&self.default_weights(), &self.weights_at(clip, t), w);
        self.skin(&global, &weights)
    }

    /// Where skinned mesh `m`'s stored vertices lie in the bind pose: the mesh node's global
    /// transform in `rest` (the default node pose) or none (glTF's rule), whichever is nearer
    /// the root joint's rest global transform times its inverse bind matrix (which is that
    /// placement exactly where the root rests as bound, and stays near it where the file's
    /// nodes rest at a clip's first frame). The root joint is the bone no other bone is above:
    /// the first in depth-first order.
    pub(super) fn bind_place(&self, m: &Mesh, rest: &[Mat4]) -> Mat4 {
        let node = m.instances.first().map_or(Mat4::IDENTITY, |&n| rest[n]);
        let Some(root) = m.bones.iter().min_by_key(|b| b.node) else {
            return node;
        };
        let seen = rest[root.node] * root.offset;
        let apart = |a: Mat4| {
            (a - seen)
                .to_cols_array()
                .iter()
                .map(|x| x * x)
                .sum::<f32>()
        };
        match apart(Mat4::IDENTITY) < apart(node) {
            true => Mat4::IDENTITY,
            false => node,
        }
    }
}
