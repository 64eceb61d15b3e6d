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
    /// Each frame with any (numbered as the bake numbers them, pre-roll before
    /// `frame_start`) and how many pairs of their triangles pass through each other there.
    pub frames: Vec<(i64, usize)>,
}

impl BodyCrossing {
    /// The most pairs in one frame.
    pub fn most(&self) -> usize {
        self.frames.iter().map(|f| f.1).max().unwrap_or(0)
    }

    /// The pairs summed over the frames.
    pub fn total(&self) -> usize {
        self.frames.iter().map(|f| f.1).sum()
    }
}

/// The frames a bake of `scene` gives character `k` (pre-roll included) and where its mesh
/// passes through itself in them, counted as the bake counts them (its
/// `character_crossings_per_frame`: `collide::crossings::SelfCrossings` from where the bake
/// starts), grouped by the two joints that move the triangles, most pairs first. None for a
/// frame sequence, which has no joints (refused if the scene gives it joint offsets), and for
/// a character that does not move.
pub fn body_crossings(scene: &Scene, k: usize) -> Result<Option<(usize, Vec<BodyCrossing>)>> {
    let scene = scene.with_preroll();
    let (path, options, frames) = super::characters::as_baked(&scene, k);
    if path.is_dir() || sequence_files(&path)?.len() != 1 {
        if !options.joint_offsets.is_empty() {
            // Refused as the bake refuses it.
            Character::load(&path, &options, scene.fps, 1)?;
        }
        return Ok(None);
    }
    let asset = Asset::open_character(&path)?;
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
    let baked = frames - 1;
    for b in 0..baked {
        let number = scene.frame_start as i64 + b as i64;
        let mut this_frame: BTreeMap<(String, String), usize> = BTreeMap::new();
        for (a, c) in rest.pairs(character.frame(b + 1), triangles) {
            let (a, c) = (name(a), name(c));
            *this_frame
                .entry(if a <= c { (a, c) } else { (c, a) })
                .or_default() += 1;
        }
        for (joints, pairs) in this_frame {
            let entry = found.entry(joints.clone()).or_insert(BodyCrossing {
                joints,
                frames: Vec::new(),
            });
            entry.frames.push((number, pairs));
        }
    }
    let mut list: Vec<BodyCrossing> = found.into_values().collect();
    list.sort_by(|a, b| b.total().cmp(&a.total()).then(a.joints.cmp(&b.joints)));
    Ok(Some((baked, list)))
}
