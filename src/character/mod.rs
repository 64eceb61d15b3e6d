//! Characters: animated bodies that garments collide with, imported (glTF by node index, other
//! formats through assimp) and sampled into frames at the scene's frame rate, then covered by a
//! shell of collision particles.
//!
//! - [`import`]: one file (glTF/GLB, FBX, Collada, OBJ, ... whatever assimp reads) with its node
//!   hierarchy, skinning and clips, posed at any time; [`MeshSelection`] picks the meshes that
//!   collide (`meshes`) and the body parts, by the joints that move them (`joints`);
//! - [`Character`]: frames at the scene's fps from a skinned clip, a static mesh, or a sequence of
//!   files (one mesh per frame), with unit scale, up axis, placement, time offset, speed and
//!   loop/hold applied;
//! - [`shell`]: the collision particle shell.

pub mod cache;
pub mod mannequin;
pub mod shell;

use crate::mesh::import;
pub use crate::mesh::import::Asset;
pub use cache::ShellCache;
pub use shell::Shell;

use crate::error::{Error, Result};
use crate::scene::CharacterSpec;
pub use crate::scene::{MeshSelection, Preroll, UpAxis};
use glam::{EulerRot, Mat4, Quat, Vec3};
use std::path::{Path, PathBuf};

/// How to read and place a character.
#[derive(Clone, Debug, PartialEq)]
pub struct CharacterOptions {
    /// Clip name (or index as text) of a skinned file; None for the rest pose.
    pub clip: Option<String>,
    /// File units to metres.
    pub scale: f32,
    pub up: UpAxis,
    /// Placement [m] and rotation (Euler degrees, X then Y then Z) after scale and up axis.
    pub position: [f32; 3],
    pub rotation: [f32; 3],
    /// Clip time at frame 1 [s].
    pub time_offset: f32,
    /// Clip seconds per scene second.
    pub speed: f32,
    /// Past the clip's end: loop (true) or hold the last pose (false).
    pub looping: bool,
    /// Frame rate of a sequence of files (None: one file per scene frame).
    pub sequence_fps: Option<f32>,
    /// Which of the file's meshes collide (None: all of them).
    pub meshes: Option<MeshSelection>,
    /// Which of the file's joints move triangles that collide (None: all of them).
    pub joints: Option<MeshSelection>,
    /// Meshes left out altogether, neither colliding nor shown (a garment modelled in the
    /// character's file), by mesh, node or material name.
    pub hidden: Vec<String>,
    /// The character's own pre-roll: bind pose, then a blend into the clip's first frame.
    pub preroll: Option<Preroll>,
    /// Rotations added to joints in the clip (joint name → Euler degrees about the file's
    /// axes as the joint lies in the bind pose); see [`Asset::offset_joints`].
    pub joint_offsets: std::collections::BTreeMap<String, [f32; 3]>,
    /// Frames the bake simulates before the clip's first frame (the scene's longest pre-roll):
    /// this character's pre-roll ends with them; without one it holds the clip's first frame.
    pub lead_in: usize,
}

/// Where pre-roll frame `k` (0-based, of `lead_in` before the clip's first frame) stands
/// between the bind pose (0) and the clip's first frame (1): 0 while settling, then the blend
/// eased by smoothstep, 1 for a character without a pre-roll.
pub fn preroll_weight(preroll: Option<Preroll>, lead_in: usize, k: usize) -> f32 {
    let Some(p) = preroll else {
        return 1.0;
    };
    let blend = p.blend as usize;
    // The blend ends on the clip's first frame, at `lead_in`.
    let start = lead_in.saturating_sub(blend);
    if k < start {
        return 0.0;
    }
    let u = (k - start) as f32 / blend.max(1) as f32;
    u * u * (3.0 - 2.0 * u)
}

impl MeshSelection {
    /// Whether `mesh` collides.
    pub fn collides(&self, mesh: &import::Mesh) -> bool {
        let named = |names: &[String]| names.iter().any(|n| import::matches(mesh, n));
        match self {
            MeshSelection::Include(names) => named(names),
            MeshSelection::Exclude(names) => !named(names),
        }
    }
}

impl Default for CharacterOptions {
    /// The options of a scene's character entry left at its defaults: the import defaults
    /// live in one place, [`CharacterSpec`]'s.
    fn default() -> Self {
        CharacterSpec::default().options()
    }
}

impl CharacterSpec {
    /// The import options this entry describes.
    pub fn options(&self) -> CharacterOptions {
        CharacterOptions {
            clip: self.clip.clone(),
            scale: self.scale,
            up: self.up,
            position: self.position,
            rotation: self.rotation,
            time_offset: self.time_offset,
            speed: self.speed,
            looping: self.looping,
            sequence_fps: self.sequence_fps,
            meshes: self.meshes.clone(),
            joints: self.joints.clone(),
            hidden: Vec::new(),
            preroll: self.preroll,
            joint_offsets: self.joint_offsets.clone(),
            lead_in: 0,
        }
    }
}

impl CharacterOptions {
    /// Whether a mesh or joint selection may leave triangles out of the collisions.
    pub fn selects(&self) -> bool {
        self.meshes.is_some() || self.joints.is_some()
    }

    /// Rejects impossible values: (the scene field's name, the reason). The command line maps
    /// the field to its flag (`scale` → `--scale`).
    pub fn check(&self) -> std::result::Result<(), (&'static str, String)> {
        use crate::scene::validate::{finite3, positive};
        positive(self.scale).map_err(|r| ("scale", r))?;
        positive(self.speed).map_err(|r| ("speed", r))?;
        if let Some(f) = self.sequence_fps {
            positive(f).map_err(|r| ("sequence_fps", r))?;
        }
        finite3(self.position).map_err(|r| ("position", r))?;
        finite3(self.rotation).map_err(|r| ("rotation", r))?;
        for (joint, angles) in &self.joint_offsets {
            finite3(*angles).map_err(|r| ("joint_offsets", format!("{joint:?}: {r}")))?;
        }
        if !self.time_offset.is_finite() {
            return Err((
                "time_offset",
                format!("must be finite (got {})", self.time_offset),
            ));
        }
        Ok(())
    }

    /// The placement of file coordinates in the scene.
    pub fn transform(&self) -> Mat4 {
        let up = match self.up {
            UpAxis::Y => Mat4::IDENTITY,
            UpAxis::Z => Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        };
        let [rx, ry, rz] = self.rotation.map(f32::to_radians);
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            Quat::from_euler(EulerRot::XYZ, rx, ry, rz),
            Vec3::from(self.position),
        ) * up
    }

    /// Clip time [s] of frame `k` (0-based) at `fps`, for a clip of `duration` seconds.
    pub fn clip_time(&self, k: usize, fps: f32, duration: f64) -> f64 {
        let t = self.time_offset as f64 + k as f64 * self.speed as f64 / fps as f64;
        if duration <= 0.0 {
            0.0
        } else if self.looping {
            t.rem_euclid(duration)
        } else {
            t.clamp(0.0, duration)
        }
    }
}

/// How far a looping clip's frames jump where its time wraps (`times`: each frame's clip time,
/// a frame shorter than half the clip), against its largest step between two frames within
/// the clip: (the jump [m], the step [m], the loops), when the jump is more than twice the step
/// and more than a millimetre. A clip that loops returns to its first pose (RobotExpressive's
/// walks, runs and dances and CesiumMan's walk: the wrap's step 0.01–0.53 of the largest); one
/// that does not (RobotExpressive's Death, Sitting, Standing: 11.9–14.6 times the largest)
/// throws whatever rides it at every loop.
pub fn loop_jump(frames: &[Vec<Vec3>], times: &[f64]) -> Option<(f32, f32, usize)> {
    debug_assert_eq!(frames.len(), times.len());
    let (mut jump, mut step, mut loops) = (0.0f32, 0.0f32, 0);
    for (w, t) in frames.windows(2).zip(times.windows(2)) {
        let moved = (w[0].iter().zip(&w[1]))
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max);
        if t[1] < t[0] {
            jump = jump.max(moved);
            loops += 1;
        } else {
            step = step.max(moved);
        }
    }
    (loops > 0 && jump > 2.0 * step && jump > 1e-3).then_some((jump, step, loops))
}

/// An animated body as frames of one mesh.
#[derive(Clone, Debug)]
pub struct Character {
    /// Where it came from (a file or a folder of frames).
    pub source: PathBuf,
    /// Triangles of frame 0 (a sequence with changing topology has its own per frame).
    pub triangles: Vec<Vec<[u32; 3]>>,
    /// Vertex positions [m] of every frame.
    pub frames: Vec<Vec<Vec3>>,
    /// Vertex positions [m] in the bind pose (a sequence's first file), placed like the
    /// frames: where garments modelled on the character were made.
    pub bind: Vec<Vec3>,
    /// Frames per second.
    pub fps: f32,
    /// Clip names and durations [s] of the file (empty for sequences and static meshes).
    pub clips: Vec<(String, f64)>,
    /// Every triangle of frame 0 when a mesh selection left some out of `triangles` (the
    /// exports show them all); None when `triangles` are all of them.
    pub visible: Option<Vec<[u32; 3]>>,
    /// What the import found suspicious but could read.
    pub warnings: Vec<String>,
    /// A skinned body (a file with bones), as opposed to a prop or a sequence of frames.
    pub skinned: bool,
}

/// Heights [m] of a skinned body taken without a warning.
pub const BODY_HEIGHTS: std::ops::RangeInclusive<f32> = 0.2..=2.5;

/// File extensions taken as frames of a sequence folder.
const MESH_EXTENSIONS: [&str; 9] = [
    "obj", "ply", "stl", "fbx", "dae", "gltf", "glb", "off", "3ds",
];

/// The files of a frame sequence as read: each file's vertices placed by the character's
/// options, its colliding triangles, the first file's visible triangles (when `meshes` leaves
/// some out) and the files' warnings, each once.
struct Sequence {
    stored: Vec<Vec<Vec3>>,
    triangles: Vec<Vec<[u32; 3]>>,
    visible: Option<Vec<[u32; 3]>>,
    warnings: Vec<String>,
}

impl Sequence {
    fn read(files: &[std::path::PathBuf], options: &CharacterOptions) -> Result<Sequence> {
        let transform = options.transform();
        let mut read = Sequence {
            stored: Vec::new(),
            triangles: Vec::new(),
            visible: None,
            warnings: Vec::new(),
        };
        let mut repeats: Vec<(String, usize, usize)> = Vec::new(); // (text less the file, at, more)
        for file in files {
            let asset = Asset::open_character(file)?;
            let pose = asset.pose(None, 0.0);
            (read.stored).push(
                pose.iter()
                    .map(|&v| transform.transform_point3(v))
                    .collect(),
            );
            let colliding = asset.colliding_triangles(
                options.meshes.as_ref(),
                options.joints.as_ref(),
                file,
            )?;
            (read.triangles).push(colliding);
            if options.selects() && read.visible.is_none() {
                read.visible = Some(asset.triangles());
            }
            // A warning repeated by every file (each naming its own) is given once, counted.
            let name = file.display().to_string();
            for w in asset.warnings {
                let key = w.replace(&name, "");
                match repeats.iter_mut().find(|r| r.0 == key) {
                    Some(r) => r.2 += 1,
                    None => {
                        repeats.push((key, read.warnings.len(), 0));
                        read.warnings.push(w);
                    }
                }
            }
        }
        for (_, at, more) in repeats.into_iter().filter(|r| r.2 > 0) {
            read.warnings[at] += &format!(" (and so in {more} more of the sequence's files)");
        }
        Ok(read)
    }
}

impl Character {
    /// Loads `source` (one file, or a folder or `printf`-style `%0Nd` pattern of per-frame files)
    /// as `frames` frames at `fps`.
    pub fn load(
        source: &Path,
        options: &CharacterOptions,
        fps: f32,
        frames: usize,
    ) -> Result<Character> {
        let files = sequence_files(source)?;
        if files.len() == 1 && !source.is_dir() {
            let asset = Asset::open_character(&files[0])?;
            return Character::from_asset(&asset, source, options, fps, frames);
        }
        if !options.joint_offsets.is_empty() {
            return Err(Error::InvalidField {
                file: source.display().to_string(),
                field: "joint_offsets".into(),
                reason: "a frame sequence has no joints to turn (joint offsets need a file with \
                         a skeleton or a node hierarchy)"
                    .into(),
            });
        }
        // A sequence: file k is frame k at `sequence_fps` (default: the scene's), resampled to
        // `fps` by linear interpolation; past the last file the last frame holds.
        let Sequence {
            stored,
            triangles,
            visible,
            mut warnings,
        } = Sequence::read(&files, options)?;
        let source_fps = options.sequence_fps.unwrap_or(fps);
        let same = triangles.windows(2).all(|w| w[0] == w[1]);
        let lead = options.lead_in;
        if options.preroll.is_some() && lead > 0 {
            warnings.push(format!(
                "{}: a frame sequence has no joints, so its pre-roll blends vertex by vertex from \
                 its first file into the first frame (limbs that turn far shrink on the way)",
                source.display()
            ));
        }
        let mut character = Character {
            source: source.to_path_buf(),
            triangles: Vec::new(),
            frames: Vec::new(),
            bind: stored[0].clone(),
            fps,
            clips: Vec::new(),
            visible,
            warnings,
            skinned: false,
        };
        // Without a source rate, file k is scene frame k: never more frames than files.
        let regular = frames.saturating_sub(lead).max(1);
        let count = match options.sequence_fps {
            Some(_) => regular,
            None => regular.min(stored.len()),
        };
        let vertices = stored.iter().map(Vec::len).max().unwrap_or(0);
        check_frames_memory(source, vertices, lead + count)?;
        let sample = |k: usize| -> (Vec<Vec3>, usize) {
            let at = (options.time_offset + k as f32 * options.speed / fps) * source_fps;
            let i = (at.floor().max(0.0) as usize).min(stored.len() - 1);
            let j = (i + 1).min(stored.len() - 1);
            let w = (at - i as f32).clamp(0.0, 1.0);
            let frame = if same && i != j {
                stored[i]
                    .iter()
                    .zip(&stored[j])
                    .map(|(a, b)| a.lerp(*b, w))
                    .collect()
            } else {
                stored[i].clone()
            };
            (frame, i)
        };
        let (first, first_file) = sample(0);
        for k in 0..lead {
            let w = preroll_weight(options.preroll, lead, k);
            let frame = if same && w < 1.0 {
                stored[0]
                    .iter()
                    .zip(&first)
                    .map(|(a, b)| a.lerp(*b, w))
                    .collect()
            } else {
                first.clone()
            };
            character.frames.push(frame);
            character.triangles.push(triangles[first_file].clone());
        }
        for k in 0..count {
            let (frame, i) = sample(k);
            character.frames.push(frame);
            character.triangles.push(triangles[i].clone());
        }
        Ok(character)
    }

    /// Samples a loaded file: its clip (or rest pose) at `fps` for `frames` frames.
    pub fn from_asset(
        asset: &Asset,
        source: &Path,
        options: &CharacterOptions,
        fps: f32,
        frames: usize,
    ) -> Result<Character> {
        let clip = match &options.clip {
            Some(name) => Some(asset.clip_index(name).ok_or_else(|| Error::InvalidField {
                file: source.display().to_string(),
                field: "clip".into(),
                reason: format!(
                    "no clip {name:?}; the file has {}",
                    if asset.clips.is_empty() {
                        "none".to_string()
                    } else {
                        asset
                            .clips
                            .iter()
                            .enumerate()
                            .map(|(i, c)| {
                                if c.name.is_empty() {
                                    format!("#{i} (unnamed)")
                                } else {
                                    format!("{:?}", c.name)
                                }
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    }
                ),
            })?),
            None => None,
        };
        // Garment meshes of the file left out, joint offsets set.
        let adjusted;
        let asset = if options.hidden.is_empty() && options.joint_offsets.is_empty() {
            asset
        } else {
            let mut a = asset.clone().without(&options.hidden);
            a.offset_joints(&options.joint_offsets, source)?;
            adjusted = a;
            &adjusted
        };
        let duration = clip.map_or(0.0, |c| asset.clips[c].duration);
        let transform = options.transform();
        let lead = options.lead_in;
        let animated = clip.is_some() || (options.preroll.is_some() && lead > 0);
        let count = if animated { frames.max(lead + 1) } else { 1 };
        check_frames_memory(source, asset.pose(None, 0.0).len(), count)?;
        let place = |v: Vec<Vec3>| {
            v.into_iter()
                .map(|v| transform.transform_point3(v))
                .collect()
        };
        let frames: Vec<Vec<Vec3>> = (0..count)
            .map(|k| {
                if k < lead {
                    let w = preroll_weight(options.preroll, lead, k);
                    let t = options.clip_time(0, fps, duration);
                    return place(asset.blended_pose(clip, t, w));
                }
                let t = options.clip_time(k - lead, fps, duration);
                place(asset.pose(clip, t))
            })
            .collect();
        let triangles =
            asset.colliding_triangles(options.meshes.as_ref(), options.joints.as_ref(), source)?;
        let selected = options.selects() || !options.hidden.is_empty();
        let mut warnings = asset.warnings.clone();
        // A frame must be shorter than half the clip for a wrap to tell from a step.
        let frame_time = f64::from(options.speed.abs()) / f64::from(fps);
        if let (Some(c), true) = (clip, options.looping && frame_time < 0.5 * duration) {
            let times: Vec<f64> = (lead..frames.len())
                .map(|k| options.clip_time(k - lead, fps, duration))
                .collect();
            let name = &asset.clips[c].name;
            warnings.extend(loop_jump(&frames[lead..], &times).map(|(jump, step, loops)| {
                format!(
                    "{}: clip \"{name}\" loops (`loop: true`) but does not end where it starts: it starts again {loops} time{} in the bake, each time jumping up to {jump:.3} m in one frame, where its largest step within the clip is {step:.3} m, and cloth on it is thrown; `loop: false` holds its last pose",
                    source.display(),
                    if loops == 1 { "" } else { "s" }
                )
            }));
        }
        Ok(Character {
            source: source.to_path_buf(),
            triangles: vec![triangles],
            frames,
            bind: place(asset.bind_pose()),
            fps,
            clips: asset
                .clips
                .iter()
                .map(|c| (c.name.clone(), c.duration))
                .collect(),
            visible: selected.then(|| asset.triangles()),
            warnings,
            skinned: asset.meshes.iter().any(|m| !m.bones.is_empty()),
        })
    }

    /// True when every frame shares frame 0's triangles (a shell then rides the skin).
    pub fn same_topology(&self) -> bool {
        self.triangles.windows(2).all(|w| w[0] == w[1])
            && self.frames.iter().all(|f| f.len() == self.frames[0].len())
    }

    /// Shell particle positions on every frame: one shell sampled on frame 0 and carried on its
    /// triangles when the topology never changes (continuous trajectories), else re-sampled on
    /// each frame (the particle count may then change from frame to frame).
    pub fn shell_frames(&self, radius: f32) -> Vec<Vec<Vec3>> {
        if self.same_topology() {
            let shell = Shell::sample(&self.frames[0], &self.triangles[0], radius);
            return self
                .frames
                .iter()
                .map(|f| shell.positions(f, &self.triangles[0]))
                .collect();
        }
        (0..self.frames.len())
            .map(|k| {
                let t = self.triangles_of(k);
                Shell::sample(self.frame(k), t, radius).positions(self.frame(k), t)
            })
            .collect()
    }

    /// Ok when a shell of `radius` on this character fits drape's limits (see
    /// [`Shell::check_size`]), checked from its surface area before any particle is sampled.
    pub fn check_shell(&self, radius: f32) -> std::result::Result<(), String> {
        let area = (0..self.triangles.len())
            .map(|k| shell::surface_area(self.frame(k), self.triangles_of(k)))
            .fold(0.0, f64::max);
        Shell::check_size(area, radius, self.frames.len())
    }

    /// Height [m] of frame 0 (its extent along Y, drape's up axis).
    pub fn height(&self) -> f32 {
        let (lo, hi) = self.bounds(0);
        hi.y - lo.y
    }

    /// A warning when the character is implausibly large or small for what it is in metres: a
    /// skinned body outside [`BODY_HEIGHTS`], anything else (props, frame sequences) larger
    /// than 10 m or smaller than 5 cm; with the `scale` that makes it 1.75 m tall.
    pub fn size_warning(&self, scale: f32) -> Option<String> {
        let (lo, hi) = self.bounds(0);
        let size = if self.skinned {
            hi.y - lo.y
        } else {
            (hi - lo).max_element()
        };
        let plausible = if self.skinned {
            BODY_HEIGHTS
        } else {
            0.05..=10.0
        };
        if !size.is_finite() || size <= 0.0 || plausible.contains(&size) {
            return None;
        }
        let suggested = scale * 1.75 / size;
        // Three significant digits, without an exponent for everyday values.
        let digits = (2 - suggested.log10().floor() as i32).clamp(0, 12) as usize;
        let what = if self.skinned {
            "a body taller than 2.5 m or shorter than 0.2 m is unusual"
        } else {
            "is it in other units than metres?"
        };
        // A file in centimetres, millimetres or inches is told so in plain words.
        let unit = [
            (0.01, "centimetres"),
            (0.001, "millimetres"),
            (0.0254, "inches"),
        ]
        .into_iter()
        .find(|&(u, _)| plausible.contains(&(size * u)))
        .map(|(u, name)| {
            format!(
                "; read as {name} (scale {}) it is {:.3} m tall",
                scale * u,
                size * u
            )
        })
        .unwrap_or_default();
        // A scale so extreme that it would show as 0 or overflow is not worth suggesting.
        let fix = if suggested.is_finite() && (1e-9..=1e9).contains(&suggested) {
            format!(
                "; scale {suggested:.digits$} makes it 1.75 m tall (0.01 reads centimetres, 0.001 millimetres)"
            )
        } else {
            String::new()
        };
        let tall = if (0.001..1e4).contains(&size) {
            format!("{size:.3}")
        } else {
            format!("{size:.3e}")
        };
        Some(format!(
            "{} is {tall} m tall at scale {scale}: {what}{fix}{unit}",
            self.source.display()
        ))
    }

    /// Every triangle of frame 0, those a mesh selection left out of the collisions included.
    pub fn visible_triangles(&self) -> &[[u32; 3]] {
        self.visible.as_deref().unwrap_or(self.triangles_of(0))
    }

    /// Triangles of frame `k`.
    pub fn triangles_of(&self, k: usize) -> &[[u32; 3]] {
        &self.triangles[k.min(self.triangles.len() - 1)]
    }

    /// Vertices of frame `k` (the last frame holds past the end).
    pub fn frame(&self, k: usize) -> &[Vec3] {
        &self.frames[k.min(self.frames.len() - 1)]
    }

    /// Axis-aligned bounds of frame `k`.
    pub fn bounds(&self, k: usize) -> (Vec3, Vec3) {
        self.frame(k).iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
    }

    /// Vertices at fractional frame `f` (substeps), interpolated linearly between frames.
    pub fn vertices_at(&self, f: f32) -> Vec<Vec3> {
        let k = f.floor().max(0.0) as usize;
        let (a, b) = (self.frame(k), self.frame(k + 1));
        if a.len() != b.len() {
            return a.to_vec();
        }
        let w = (f - k as f32).clamp(0.0, 1.0);
        a.iter().zip(b).map(|(p, q)| p.lerp(*q, w)).collect()
    }
}

/// Refuses `frames` frames of `vertices` vertices that would not fit in memory (exit 2 naming
/// `frames`) before they are computed: a bake keeps each frame's vertices about three times
/// (the frames, the exported mesh and the skin attachments follow).
fn check_frames_memory(source: &Path, vertices: usize, frames: usize) -> Result<()> {
    let bytes = (vertices as u64 * 12 * 3).saturating_mul(frames as u64);
    crate::limits::fits_in_memory(bytes).map_err(|reason| Error::InvalidField {
        file: source.display().to_string(),
        field: "frames".into(),
        reason: format!("{frames} frames of its {vertices} vertices {reason}"),
    })
}

/// The files of a source: itself, a folder's mesh files in name order, or a `%0Nd` pattern's
/// files from 0 or 1 up while they exist.
pub fn sequence_files(source: &Path) -> Result<Vec<PathBuf>> {
    let text = source.to_string_lossy();
    if let Some(at) = text.find('%') {
        let end = text[at..]
            .find('d')
            .map(|e| at + e)
            .ok_or_else(|| Error::InvalidField {
                file: text.to_string(),
                field: "pattern".into(),
                reason: "a frame pattern needs a printf number such as %04d".into(),
            })?;
        let width: usize = text[at + 1..end]
            .trim_start_matches('0')
            .parse()
            .unwrap_or(0);
        let name =
            |k: usize| PathBuf::from(format!("{}{k:0width$}{}", &text[..at], &text[end + 1..]));
        let first = if name(0).is_file() { 0 } else { 1 };
        let files: Vec<PathBuf> = (first..).map(name).take_while(|p| p.is_file()).collect();
        if files.is_empty() {
            return Err(not_found(source, "no file matches the frame pattern"));
        }
        return Ok(files);
    }
    if source.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(source)
            .map_err(|e| Error::io(source, "cannot read", e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| MESH_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(not_found(source, "the folder holds no mesh files"));
        }
        return Ok(files);
    }
    Ok(vec![source.to_path_buf()])
}

/// A "cannot read" error for a source that yields no frame files.
fn not_found(source: &Path, reason: &str) -> Error {
    Error::io(
        source,
        "cannot read",
        std::io::Error::new(std::io::ErrorKind::NotFound, reason.to_string()),
    )
}
