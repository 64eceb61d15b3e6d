//! Resuming a bake: find the checkpoint to start from, check that it belongs to this scene, and
//! replay the frames before it into the new bake's exports.
//!
//! Where checkpoints are looked for: the output folder itself (a finished or interrupted bake,
//! or one that is now asked for more frames) and the staging folders that runs killed without
//! a chance to finish left beside it. Of the checkpoints made for this scene, the latest one at
//! or before the frame asked for wins.

use super::checkpoint::{self, Loaded, Record, Writer};
use super::output::Exports;
use crate::error::{Error, Result};
use crate::export::sequence::BakeMeshes;
use crate::scene::Scene;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Where a bake starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Resume {
    /// From the first frame.
    #[default]
    No,
    /// From the latest checkpoint of this scene (from the first frame when there is none).
    Last,
    /// Simulating again from this shot frame: from the latest checkpoint before it, keeping
    /// the frames up to that checkpoint.
    From(u32),
}

/// The checkpoint a bake resumes from.
pub struct Source {
    /// The bake folder it is in.
    pub folder: PathBuf,
    pub checkpoint: PathBuf,
    pub loaded: Loaded,
}

/// What the scene is checked against.
pub struct Identity<'a> {
    pub scene: &'a Scene,
    /// Names the scene in errors.
    pub file: &'a str,
    pub scene_hash: String,
    /// [`checkpoint::characters_hashes`] of the scene's shells (checked through a checkpoint's
    /// frame).
    pub characters: Vec<String>,
}

/// Finds the checkpoint to resume from in `folders` (bake folders); `None` when none of them
/// holds one. A checkpoint of another scene or of changed characters is refused (exit 2 naming
/// the difference) unless another folder holds one of this scene; with [`Resume::From`],
/// changed characters are allowed (the frames after it follow the new ones) with a warning.
pub fn find(
    folders: &[PathBuf],
    want: Resume,
    id: &Identity,
    warnings: &mut Vec<String>,
) -> Result<Option<Source>> {
    let last = id.scene.frame_start + id.scene.frames.saturating_sub(1);
    let limit = match want {
        Resume::No => return Ok(None),
        Resume::Last => last,
        // Frame k itself is simulated again: the state after frame k − 1 at the latest.
        Resume::From(k) => k.saturating_sub(1).min(last),
    };
    let mut best: Option<Source> = None;
    let mut refusal: Option<Error> = None;
    for folder in folders {
        let dir = folder.join(checkpoint::FOLDER);
        let Some((_, path)) = checkpoint::list(&dir)
            .into_iter()
            .rev()
            .find(|(frame, _)| *frame <= limit)
        else {
            continue;
        };
        let loaded = match checkpoint::load(&path) {
            Ok(l) => l,
            Err(e) => {
                warnings.push(format!("cannot resume from {}: {e}", path.display()));
                continue;
            }
        };
        if let Err(e) = check(&loaded, &dir, want, id, warnings) {
            refusal.get_or_insert(e);
            continue;
        }
        if best
            .as_ref()
            .is_none_or(|b| loaded.meta.frame > b.loaded.meta.frame)
        {
            best = Some(Source {
                folder: folder.clone(),
                checkpoint: path,
                loaded,
            });
        }
    }
    match (best, refusal) {
        (Some(b), _) => Ok(Some(b)),
        (None, Some(e)) => Err(e),
        (None, None) => Ok(None),
    }
}

/// Ok when `loaded` (in checkpoint folder `dir`) was made for this scene.
fn check(
    loaded: &Loaded,
    dir: &Path,
    want: Resume,
    id: &Identity,
    warnings: &mut Vec<String>,
) -> Result<()> {
    let meta = &loaded.meta;
    let refuse = |field: String, reason: String| Error::InvalidField {
        file: id.file.to_string(),
        field,
        reason,
    };
    if meta.scene_hash != id.scene_hash {
        let now = checkpoint::canonical_scene(id.scene);
        let then: Option<Value> = std::fs::read_to_string(dir.join("scene.json"))
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok());
        let (field, what) = match then.as_ref().and_then(|t| difference(t, &now, "")) {
            Some((path, a, b)) => (path, format!("is {b}, the checkpoint's scene has {a}")),
            None => ("scene".into(), "differs from the checkpoint's scene".into()),
        };
        return Err(refuse(
            field,
            format!(
                "{what}: the checkpoints in {} were made for another scene (resume only the scene a checkpoint was made for, or bake without --resume)",
                dir.display()
            ),
        ));
    }
    if meta.drape_version != env!("CARGO_PKG_VERSION") {
        warnings.push(format!(
            "the checkpoints in {} were made by drape {}: the frames after frame {} are this version's",
            dir.display(),
            meta.drape_version,
            meta.frame
        ));
    }
    if meta.characters_hash != checkpoint::characters_hash(&id.characters, meta.progress.baked) {
        let what = format!(
            "the characters' animation differs from the one the checkpoints in {} were made with",
            dir.display()
        );
        if matches!(want, Resume::From(_)) {
            warnings.push(format!(
                "{what}: frames after frame {} follow the new animation",
                meta.frame
            ));
        } else {
            return Err(refuse(
                "characters".into(),
                format!("{what} (re-simulate the changed frames with --from-frame)"),
            ));
        }
    }
    Ok(())
}

/// The first place where `a` and `b` differ: (path, value in `a`, value in `b`).
fn difference(a: &Value, b: &Value, path: &str) -> Option<(String, String, String)> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let here = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match (x.get(k), y.get(k)) {
                    (Some(a), Some(b)) => difference(a, b, &here),
                    _ => Some((here, show(x, k), show(y, k))),
                }
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (p, q))| difference(p, q, &format!("{path}[{i}]"))),
        _ => (a != b).then(|| (path.to_string(), a.to_string(), b.to_string())),
    }
}

fn show(map: &serde_json::Map<String, Value>, key: &str) -> String {
    map.get(key).map_or("nothing".into(), Value::to_string)
}

/// Replays the frames `source` holds into `exports` (and into the new bake's checkpoint log),
/// with `meshes` following the garments' torn faces; copies the checkpoints up to it into the
/// new bake's `checkpoints/` (`into`) so later resumes can go back as far as before.
pub fn replay(
    source: &Source,
    meshes: &mut BakeMeshes,
    exports: &mut Exports,
    mut writer: Option<&mut Writer>,
    frame_start: u32,
    into: &Path,
) -> Result<()> {
    let dir = source.folder.join(checkpoint::FOLDER);
    let vertices = meshes.garment_particles();
    let end = source.loaded.meta.frames_bytes;
    checkpoint::replay(&dir.join("frames.bin"), end, vertices, |record| {
        match record {
            Record::Frame { index, positions } => {
                if let Some(w) = writer.as_deref_mut() {
                    w.frame(index, &positions)?;
                }
                if !exports.is_empty() {
                    let frame = meshes.frame(index as usize, frame_start + index, &positions);
                    exports.frame(frame)?;
                }
            }
            Record::Faces {
                garment,
                index,
                faces,
            } => {
                if garment >= meshes.garment_count() {
                    return Err(Error::InvalidField {
                        file: dir.join("frames.bin").display().to_string(),
                        field: "frames".into(),
                        reason: format!("it tears garment {garment}, which is not there"),
                    });
                }
                meshes.set_faces(garment, &faces);
                exports.faces(garment, index as usize, &faces)?;
                if let Some(w) = writer.as_deref_mut() {
                    w.faces(garment, index, &faces)?;
                }
            }
        }
        Ok(())
    })?;
    if writer.is_some() {
        let last = source.loaded.meta.frame;
        for (frame, path) in checkpoint::list(&dir) {
            if frame > last {
                continue;
            }
            let to = into.join(checkpoint::file_name(frame));
            if std::fs::hard_link(&path, &to).is_err() {
                std::fs::copy(&path, &to).map_err(|e| Error::io(&to, "cannot write", e))?;
            }
        }
    }
    Ok(())
}
