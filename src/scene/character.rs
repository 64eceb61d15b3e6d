//! A scene's characters as the scene file gives them: the entry (`CharacterSpec`) and the
//! types its fields take (up axis, mesh selection, pre-roll). The scene owns them and checks
//! them; `character` imports and places what they describe.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// An animated character: a file assimp reads, a folder of per-frame files, or a `%04d` pattern,
/// placed in the scene and covered by a shell of collision particles.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CharacterSpec {
    /// Name in reports. Default `"character<index>"`.
    pub name: Option<String>,
    /// The character, relative to the scene file's folder. Required.
    pub file: String,
    /// Clip name (or index as text) of a skinned file. Default none: the rest pose.
    pub clip: Option<String>,
    /// File units to metres. Default 1.
    pub scale: f32,
    /// The file's up axis: `"y"` (default) or `"z"`.
    pub up: UpAxis,
    /// Placement [m] after scale and up axis. Default the origin.
    pub position: [f32; 3],
    /// Rotation, Euler degrees X then Y then Z. Default none.
    pub rotation: [f32; 3],
    /// Clip time at the start of the bake [s]. Default 0.
    pub time_offset: f32,
    /// Clip seconds per scene second. Default 1.
    pub speed: f32,
    /// Loop the clip (true) or hold its last pose (false, default).
    #[serde(rename = "loop")]
    pub looping: bool,
    /// Frame rate of a sequence of files. Default: one file per scene frame.
    pub sequence_fps: Option<f32>,
    /// Shell particle radius [m]. Default 0.01.
    pub radius: f32,
    /// Coulomb friction against the garments. Default 0.5.
    pub friction: f32,
    /// Which of the file's meshes collide: `{"include": [names]}` or `{"exclude": [names]}`,
    /// each a mesh, node or material name. Default all. Exports show the whole character.
    pub meshes: Option<MeshSelection>,
    /// Which of the file's joints collide: `{"exclude": [names]}` leaves out the triangles
    /// those joints (and the joints below them) mostly move, `{"include": [names]}` keeps only
    /// those. Default all. Exports show the whole character.
    pub joints: Option<MeshSelection>,
    /// Frames simulated before the scene's first frame: the character holds its bind pose for
    /// `settle` frames, then blends into the clip's first frame over `blend`. Default none.
    pub preroll: Option<Preroll>,
    /// Rotations added to joints in every frame of the clip, never to the bind pose: joint
    /// name → Euler degrees X, Y, Z as `rotation` takes them (about X, then the turned Y, then
    /// the turned Z), the axes the file's as the joint lies in the bind pose, turning the joint
    /// and everything below it about the joint. A sim-prep layer: arms
    /// spread a few degrees clear of a body the clip passes them into. Default none.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub joint_offsets: BTreeMap<String, [f32; 3]>,
}

impl Default for CharacterSpec {
    /// The import defaults (`character::CharacterOptions` takes its own from here).
    fn default() -> Self {
        CharacterSpec {
            name: None,
            file: String::new(),
            clip: None,
            scale: 1.0,
            up: UpAxis::Y,
            position: [0.0; 3],
            rotation: [0.0; 3],
            time_offset: 0.0,
            speed: 1.0,
            looping: false,
            sequence_fps: None,
            radius: 0.01,
            friction: 0.5,
            meshes: None,
            joints: None,
            preroll: None,
            joint_offsets: BTreeMap::new(),
        }
    }
}

/// The file's up axis (drape is Y-up).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UpAxis {
    #[default]
    Y,
    /// Z up (Blender's convention): rotated −90° about X on import.
    Z,
}

/// A pre-roll (a character's `preroll`): `settle` frames in the bind pose, then `blend`
/// frames into the clip's first frame, joint by joint in the joints' local frames (rotations by
/// slerp, translations and scales linearly), eased at both ends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Preroll {
    /// Frames holding the bind pose while the garments settle. Default 0.
    pub settle: u32,
    /// Frames blending from the bind pose into the clip's first frame. Default 0.
    pub blend: u32,
}

impl Preroll {
    /// Frames in all.
    pub fn frames(&self) -> u32 {
        self.settle.saturating_add(self.blend)
    }
}

/// Which of a file's meshes collide: they alone get shell particles and are measured for
/// penetration. Exports and previews still show the whole character. A name matches a mesh by
/// its mesh, node or material name.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum MeshSelection {
    /// Only the meshes named.
    Include(Vec<String>),
    /// Every mesh but those named.
    Exclude(Vec<String>),
}

impl MeshSelection {
    /// The names in the selection.
    pub fn names(&self) -> &[String] {
        match self {
            MeshSelection::Include(n) | MeshSelection::Exclude(n) => n,
        }
    }
}
