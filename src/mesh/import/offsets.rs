//! Joint offsets (`characters[].joint_offsets`): rotations added to joints in every frame of a
//! clip, never to the bind pose. Clips made without cloth in mind pass limbs into the body
//! (CesiumMan's hands sink 12.7 mm into his thighs); no cloth caught there can be outside both.
//! Technical animators spread such limbs a few degrees before a simulation, and this is that
//! layer.
//!
//! An offset is given as Euler degrees about the file's axes as the joint lies in the bind
//! pose, the joint its pivot: what an artist would type rotating the joint in the bind pose.
//! It is carried into the joint's own frame (B⁻¹ Q B, B the joint's bind rotation) and
//! multiplied after its local transform in every pose, so it turns with the joint as the clip
//! moves it.

use super::{joints::listing, Asset};
use crate::error::{Error, Result};
use glam::{EulerRot, Quat};
use std::collections::BTreeMap;
use std::path::Path;

impl Asset {
    /// Sets the joint offsets: `offsets` maps a joint name (one of [`Asset::joint_names`]) to
    /// Euler degrees X then Y then Z about the file's axes in the bind pose. Every node of that
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
            for node in self.topmost_named(name) {
                let (_, joint, _) = bind[node].to_scale_rotation_translation();
                let joint = joint.normalize();
                turns.push((
                    node,
                    (joint.inverse() * about_file_axes * joint).normalize(),
                ));
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
