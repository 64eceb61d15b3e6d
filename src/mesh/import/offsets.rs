//! Joint offsets (`characters[].joint_offsets`): rotations added to joints in every frame of a
//! clip, never to the bind pose. Clips made without cloth in mind pass limbs into the body
//! (CesiumMan's hands sink 12.7 mm into his thighs); no cloth caught there can be outside both.
//! Technical animators spread such limbs a few degrees before a simulation, and this is that
//! layer.
//!
//! An offset is given as Euler degrees X, Y, Z in the convention of the scene's `rotation`
//! (about X, then about the turned Y, then the turned Z), about the file's axes as the joint
//! lies in the bind pose, the joint its pivot: what an artist would type turning the joint in
//! the bind pose. It is carried into the joint's own frame (M⁻¹ Q M, M the joint's bind
//! transform without its translation, so a scaled or mirrored joint turns as given) and
//! multiplied after its local transform in every pose, so it turns with the joint as the clip
//! moves it.

use super::{joints::listing, Asset};
use crate::error::{Error, Result};
use glam::{EulerRot, Mat3, Mat4, Quat};
use std::collections::BTreeMap;
use std::path::Path;

impl Asset {
    /// Sets the joint offsets: `offsets` maps a joint name (one of [`Asset::joint_names`]) to
    /// Euler degrees X, Y, Z (intrinsic, as `rotation`) about the file's axes in the bind pose. Every node of that
    /// name turns (files repeat names) but one below another of its name, which that one's turn
    /// carries (a bone and the node of its rigid mesh often share a name). Refuses a name that
    /// is no joint, naming the file's joints.
    pub fn offset_joints(
        &mut self,
        offsets: &BTreeMap<String, [f32; 3]>,
        file: &Path,
    ) -> Result<()> {
        let names = self.joint_names();
        if let Some(name) = offsets.keys().find(|n| !names.contains(&n.as_str())) {
            return Err(Error::InvalidField {
                file: file.display().to_string(),
                field: "joint_offsets".into(),
                reason: format!(
                    "{name:?} is no joint of the file; the file's joints are {}",
                    listing(&names)
                ),
            });
        }
        let bind = self.bind_transforms();
        let mut turns = Vec::new();
        for (name, degrees) in offsets {
            let [x, y, z] = degrees.map(f32::to_radians);
            let about_file_axes = Quat::from_euler(EulerRot::XYZ, x, y, z);
            let nodes: Vec<usize> = self.topmost_named(name).collect();
            for node in nodes {
                turns.push((node, in_joint_frame(bind[node], about_file_axes)));
                if let Some(scale) = uneven_scale(bind[node]) {
                    self.warnings.push(format!(
                        "joint_offsets: joint {name:?} is scaled unevenly in its bind pose ({scale}): its offset turns it as given in the clip, and during a pre-roll's blend only near it"
                    ));
                }
            }
        }
        self.offsets = turns;
        Ok(())
    }

    /// The nodes called `name` that have no ancestor of that name.
    fn topmost_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = usize> + 'a {
        let nodes = &self.nodes;
        (0..nodes.len()).filter(move |&i| {
            let mut above = nodes[i].parent;
            while let Some(p) = above {
                if nodes[p].name == name {
                    return false;
                }
                above = nodes[p].parent;
            }
            nodes[i].name == name
        })
    }
}

/// `turn` (about the file's axes, the joint its pivot) in the frame of a joint whose bind
/// transform is `bind`: M⁻¹ Q M, M the bind's linear part. A joint scaled evenly and not
/// mirrored (nearly every rig) takes the rotation's own conjugate, R⁻¹ Q R.
fn in_joint_frame(bind: Mat4, turn: Quat) -> Mat4 {
    let (scale, rotation, _) = bind.to_scale_rotation_translation();
    let even = uneven_scale(bind).is_none() && scale.min_element() > 0.0;
    if even {
        let rotation = rotation.normalize();
        return Mat4::from_quat((rotation.inverse() * turn * rotation).normalize());
    }
    let linear = Mat3::from_mat4(bind);
    Mat4::from_mat3(linear.inverse() * Mat3::from_quat(turn) * linear)
}

/// The scale of `bind` when its axes are scaled differently (by more than a part in 10⁴).
fn uneven_scale(bind: Mat4) -> Option<glam::Vec3> {
    let scale = bind.to_scale_rotation_translation().0.abs();
    let spread = scale.max_element() - scale.min_element();
    (spread > 1e-4 * scale.max_element()).then_some(scale)
}
