//! Where a character's clip passes one part of its body into another, by the joints that move
//! them: cloth caught between the two has no place outside the mesh (CesiumMan's walk sinks his
//! hands into his thighs), so `drape inspect` lists these before a bake, and a scene can spread
//! those limbs with `characters[].joint_offsets` until none is left.

use crate::character::{sequence_files, Asset, Character};
use crate::collide::crossings::SelfCrossings;
use crate::error::Result;
use crate::scene::Scene;
use std::collections::BTreeMap;

/// Two joints whose triangles pass through each other in some frames.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyCrossing {
    /// The joints that move the two triangles most, in name order.
    pub joints: (String, String),
    /// The frames (numbered as the bake numbers them, pre-roll before `frame_start`).
    pub frames: Vec<i64>,
    /// The most pairs of their triangles through each other in one frame.
    pub most: usize,
    /// Those pairs summed over the frames.
    pub total: usize,
}

/// The frames a bake of `scene` gives character `k` (pre-roll included) and where its mesh
/// passes through itself in them (`collide::crossings::SelfCrossings`, as the bake counts
/// them), grouped by the two joints that move the triangles, most pairs first. None for a
/// frame sequence, which has no joints, and for a character that does not move.
pub fn body_crossings(scene: &Scene, k: usize) -> Result<Option<(usize, Vec<BodyCrossing>)>> {
    let path = scene.character_path(k);
    if path.is_dir() || sequence_files(&path)?.len() != 1 {
        return Ok(None);
    }
    let mut options = scene.characters[k].options();
    options.hidden = super::characters::garment_meshes_in(scene, &path);
    let lead = scene.preroll_frames() as usize;
    options.lead_in = lead;
    let asset = Asset::open(&path)?;
    let frames = lead + scene.frames as usize;
    let character = Character::from_asset(&asset, &path, &options, scene.fps, frames)?;
    if character.frames.len() < 2 {
        return Ok(None);
    }
    let triangles = character.triangles_of(0);
    let shown = asset.without(&options.hidden);
    let joint_of = shown.triangle_joints(triangles);
    let name = |t: u32| match joint_of[t as usize] {
        Some(node) if !shown.nodes[node].name.is_empty() => shown.nodes[node].name.clone(),
        Some(node) => format!("node #{node}"),
        None => "no joint".into(),
    };
    let rest = SelfCrossings::new(character.frame(0), triangles);
    let mut found: BTreeMap<(String, String), BodyCrossing> = BTreeMap::new();
    for f in 0..character.frames.len() {
        let number = scene.frame_start as i64 - lead as i64 + f as i64;
        let mut this_frame: BTreeMap<(String, String), usize> = BTreeMap::new();
        for (a, b) in rest.pairs(character.frame(f), triangles) {
            let (a, b) = (name(a), name(b));
            *this_frame
                .entry(if a <= b { (a, b) } else { (b, a) })
                .or_default() += 1;
        }
        for (joints, pairs) in this_frame {
            let entry = found.entry(joints.clone()).or_insert(BodyCrossing {
                joints,
                frames: Vec::new(),
                most: 0,
                total: 0,
            });
            entry.frames.push(number);
            entry.most = entry.most.max(pairs);
            entry.total += pairs;
        }
    }
    let mut list: Vec<BodyCrossing> = found.into_values().collect();
    list.sort_by(|a, b| b.total.cmp(&a.total).then(a.joints.cmp(&b.joints)));
    Ok(Some((character.frames.len(), list)))
}
