//! The scene's characters for a bake: each one imported at the scene's frame rate, its collision
//! shell sampled (or read from the shell cache when its inputs have not changed), and its mesh
//! kept for the exports and for attachments to its skin.

use crate::character::{cache::input_hash, sequence_files, Character, ShellCache};
use crate::collide::skin::Skin;
use crate::collide::ShellCollider;
use crate::error::{Error, Result};
use crate::export::sequence::{Welding, CHARACTER_COLOUR};
use crate::mesh::AnimatedMesh;
use crate::report::CharacterReport;
use crate::scene::Scene;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Character `i` of `scene` (a scene with its pre-roll made part of the shot,
/// [`Scene::with_preroll`]) as a bake loads it: its path, its import options (its pre-roll's
/// lead-in, the garment meshes of its file left out) and its frame count (frame 0 where the
/// bake starts, frame b + 1 shown by baked frame b).
pub fn as_baked(scene: &Scene, i: usize) -> (PathBuf, crate::character::CharacterOptions, usize) {
    let path = scene.character_path(i);
    let mut options = scene.characters[i].options();
    options.lead_in = scene.lead_in as usize;
    options.hidden = garment_meshes_in(scene, &path);
    (path, options, scene.frames as usize + 1)
}

/// drape's cache folder (shell caches, and the mannequin files of the embedded default scene):
/// `$XDG_CACHE_HOME/drape`, else `~/.cache/drape`, else the temp folder.
pub fn shell_cache_dir() -> PathBuf {
    std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir)
        .join("drape")
}

/// Loads the scene's characters and their collision shells over the bake's frames, reusing a
/// shell cache whose inputs have not changed.
// Long: per character in turn its frames, its shell (cached or built) and its export mesh,
// which share the loaded frames.
pub fn load_characters(
    scene: &Scene,
    cache_dir: &Path,
    warnings: &mut Vec<String>,
) -> Result<Vec<LoadedCharacter>> {
    let mut out = Vec::new();
    for (i, spec) in scene.characters.iter().enumerate() {
        let (path, options, frames) = as_baked(scene, i);
        // A joint offset the file cannot take is the scene entry's, which the error names.
        let mut character =
            Character::load(&path, &options, scene.fps, frames).map_err(|e| match e {
                Error::InvalidField {
                    file,
                    field,
                    reason,
                } if field == "joint_offsets" => Error::InvalidField {
                    file,
                    field: format!("characters[{i}].joint_offsets"),
                    reason,
                },
                e => e,
            })?;
        let name = scene.character_name(i);
        warnings.extend(std::mem::take(&mut character.warnings));
        let odd_size = character.size_warning(spec.scale);
        // Too many shell particles on a body of implausible size is the scale's fault.
        let blamed = if odd_size.is_some() {
            "scale"
        } else {
            "radius"
        };
        warnings.extend(odd_size);
        character
            .check_shell(spec.radius)
            .map_err(|reason| Error::InvalidField {
                file: path.display().to_string(),
                field: format!("characters[{i}].{blamed}"),
                reason,
            })?;
        // One shell bound to the skin serves every frame when the topology holds.
        let mut binding = None;
        let (positions, cache) = if character.same_topology() {
            let files = sequence_files(&path)?;
            let hash = input_hash(
                &files,
                &options,
                spec.radius,
                scene.fps,
                character.frames.len(),
            )?;
            let file = cache_dir.join(format!("{hash:016x}.shell"));
            let triangles = character.triangles_of(0).len();
            let (c, how) = match ShellCache::read(&file) {
                Ok(c) if c.inputs == hash && c.fits(triangles) => (c, "reused"),
                found => {
                    match &found {
                        Err(e @ Error::InvalidField { .. }) => {
                            warnings.push(format!("character {name}: {e}; rebuilt it"))
                        }
                        Ok(c) if c.inputs == hash => warnings.push(format!(
                            "character {name}: {}: the shell cache does not fit the character \
                             (a triangle past its mesh, or a number not finite); rebuilt it",
                            file.display()
                        )),
                        _ => {}
                    }
                    let c = ShellCache::build(&character, spec.radius, hash)?;
                    let written = std::fs::create_dir_all(cache_dir)
                        .map_err(|e| Error::io(cache_dir, "cannot create", e))
                        .and_then(|_| c.write(&file));
                    if let Err(e) = written {
                        warnings.push(format!("character {name}: shell cache not written: {e}"));
                    }
                    (c, "built")
                }
            };
            binding = Some(c.shell);
            (c.frames, how)
        } else {
            (
                character.shell_frames(spec.radius),
                "none (topology changes)",
            )
        };
        let report = CharacterReport {
            name: name.clone(),
            file: path.display().to_string(),
            frames: positions.len(),
            shell_particles: positions.first().map_or(0, Vec::len),
            shell_radius: spec.radius,
            shell_cache: cache,
            height_m: character.height(),
        };
        // Exports and previews show the character when its topology holds over the frames.
        let mut bind = Vec::new();
        let mesh = if character.same_topology() {
            let welding = Welding::new(&character.frames);
            bind = welding
                .frames(std::slice::from_ref(&character.bind))
                .remove(0);
            let solid = character
                .visible
                .is_some()
                .then(|| welding.faces(character.triangles_of(0)));
            Some(AnimatedMesh {
                name: name.clone(),
                triangles: welding.faces(character.visible_triangles()),
                uvs: None,
                colour: [
                    CHARACTER_COLOUR[0],
                    CHARACTER_COLOUR[1],
                    CHARACTER_COLOUR[2],
                    1.0,
                ],
                frames: welding.frames(&character.frames),
                topology: Vec::new(),
                solid,
            })
        } else {
            warnings.push(format!(
                "character {name}: its topology changes between frames, so exports and previews leave it out"
            ));
            None
        };
        let mut shell = ShellCollider::new(name, spec.radius, spec.friction, positions);
        if let Some(binding) = binding {
            // Normals ride the skin with the shell; the frames move into the skin (the GPU
            // places the shell from them).
            let triangles = character.triangles_of(0).to_vec();
            let skin = Skin::new(&binding, triangles, std::mem::take(&mut character.frames));
            shell.normals = (0..skin.vertices.len())
                .map(|f| skin.particle_normals(f))
                .collect();
            shell.skin = Some(std::sync::Arc::new(skin));
        }
        out.push(LoadedCharacter {
            shell,
            report,
            mesh,
            bind,
        });
    }
    Ok(out)
}

/// The meshes of `file` that mesh garments take for themselves (`mesh_name`): a character
/// read from the same file leaves them out.
pub fn garment_meshes_in(scene: &Scene, file: &Path) -> Vec<String> {
    let same = |a: &Path| match (a.canonicalize(), file.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == file,
    };
    scene
        .garments
        .iter()
        .filter_map(|g| {
            let mesh = g.mesh.as_ref()?;
            let name = g.mesh_name.as_ref()?;
            same(&scene.base_dir.join(mesh)).then(|| name.clone())
        })
        .collect()
}

/// A character ready for a bake: its collision shell, what the report says of it, and its mesh
/// over frames 0…N for the exports (None when its topology changes between frames).
pub struct LoadedCharacter {
    pub shell: ShellCollider,
    pub report: CharacterReport,
    pub mesh: Option<AnimatedMesh>,
    /// The mesh's vertices in the bind pose (welded as `mesh`'s; empty without a mesh).
    pub bind: Vec<Vec3>,
}
