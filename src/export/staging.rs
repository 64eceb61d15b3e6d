//! Outputs are written into a temporary folder beside the destination and moved into place only
//! when everything is written, so a bake that fails on bad input leaves no partial folder.
//!
//! Rules a pipeline can rely on:
//! - An existing destination is replaced only if it is empty or is a previous bake: its
//!   `report.json` is a drape report and every other entry is something a bake writes. drape
//!   never deletes a folder it did not write.
//! - The destination is resolved once (`out/../out` is `out`), so the two renames that replace a
//!   previous bake always name the same folder; if the second fails the first is undone.
//! - Staging (`.NAME.tmp-PID`) and replaced (`.NAME.old-PID`) folders of processes that no longer
//!   run are cleaned up by the next bake into the same destination; a previous bake left aside by
//!   a process killed between the two renames is put back first.
//! - A destination that cannot be created or written is bad input (exit 2, naming `--out`);
//!   a write that fails later (a full disk) is a failure while running (exit 1).
//! - An interrupted bake never replaces a complete one: when the destination holds a finished
//!   bake, the interrupted one is kept beside it as `.NAME.partial` ([`Staging::park`]), where
//!   `--resume` finds it; the bake that completes it replaces the destination and removes it.
//! - A previous bake that cannot be removed once replaced (a read-only file in it) is left as
//!   `.NAME.old-PID` with a warning naming it.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Entries a bake writes into its folder (besides `report.json`): folders, and files by
/// extension.
const BAKE_FOLDERS: [&str; 4] = ["obj", "pc2", "preview", "checkpoints"];
const BAKE_EXTENSIONS: [&str; 5] = ["glb", "gltf", "bin", "usda", "abc"];

/// A temporary output folder that becomes `destination` on [`Staging::commit`] and is removed if
/// dropped uncommitted.
#[derive(Debug)]
pub struct Staging {
    /// The destination as the user named it (for messages).
    shown: PathBuf,
    /// The destination with its parent resolved (absolute, no `..`, no symbolic links).
    destination: PathBuf,
    temp: PathBuf,
    committed: bool,
    /// What was cleaned up or restored beside the destination (for the report's warnings).
    pub notes: Vec<String>,
    /// Staging folders of dead runs that hold checkpoints, left for a resumed bake to look in
    /// (only with [`Staging::resuming`]; [`Staging::commit`] removes them).
    pub resumable: Vec<PathBuf>,
}

fn bad_out(reason: String) -> Error {
    Error::InvalidArgument {
        flag: "--out".into(),
        reason,
    }
}

impl Staging {
    /// Creates `.<name>.tmp-<pid>` beside `destination` (creating missing parent folders).
    pub fn new(destination: &Path) -> Result<Staging> {
        Staging::create(destination, false)
    }

    /// As [`Staging::new`], but staging folders of dead runs that hold checkpoints are kept
    /// (listed in `resumable`) for a resumed bake to continue from.
    pub fn resuming(destination: &Path) -> Result<Staging> {
        Staging::create(destination, true)
    }

    fn create(destination: &Path, resuming: bool) -> Result<Staging> {
        let shown = destination.to_path_buf();
        let resolved = resolve(destination)?;
        let name = resolved
            .file_name()
            .expect("resolved destinations end in a name")
            .to_string_lossy()
            .to_string();
        let parent = resolved
            .parent()
            .expect("resolved destinations have a parent");
        let (notes, mut resumable) = clean_stale(parent, &name, &resolved, resuming);
        let parked = partial_folder(&resolved);
        if resuming && parked.join("checkpoints").is_dir() {
            resumable.push(parked);
        }
        if resolved.exists() || resolved.is_symlink() {
            if let Err(why) = replaceable(&resolved) {
                return Err(bad_out(format!(
                    "{} exists and is not a drape bake ({why}): refusing to replace it",
                    shown.display()
                )));
            }
        }
        let temp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
        if temp.exists() {
            std::fs::remove_dir_all(&temp).map_err(|e| Error::io(&temp, "cannot remove", e))?;
        }
        std::fs::create_dir(&temp)
            .map_err(|e| bad_out(format!("cannot write into {} ({e})", parent.display())))?;
        Ok(Staging {
            shown,
            destination: resolved,
            temp,
            committed: false,
            notes,
            resumable,
        })
    }

    /// The destination, resolved.
    pub fn destination(&self) -> &Path {
        &self.destination
    }

    /// The temporary folder to write into.
    pub fn path(&self) -> &Path {
        &self.temp
    }

    /// `e` with any path inside the staging folder shown at its place in the destination: a
    /// user never sees the hidden staging name.
    pub fn public_error(&self, e: Error) -> Error {
        match e {
            Error::Io {
                path,
                action,
                source,
            } => Error::Io {
                path: match path.strip_prefix(&self.temp) {
                    Ok(rest) => self.shown.join(rest),
                    Err(_) => path,
                },
                action,
                source,
            },
            other => other,
        }
    }

    /// Moves the temporary folder to the destination, replacing a previous bake there (and an
    /// interrupted one parked beside it). Returns the destination as the user named it, and
    /// warnings about what could not be cleaned up.
    pub fn commit(mut self) -> Result<(PathBuf, Vec<String>)> {
        let destination = self.destination.clone();
        let mut warnings = Vec::new();
        if destination.exists() {
            let old = old_folder(&destination, std::process::id());
            std::fs::rename(&destination, &old)
                .map_err(|e| Error::io(&self.shown, "cannot replace", e))?;
            if let Err(e) = std::fs::rename(&self.temp, &destination) {
                // Never lose the previous bake: put it back.
                let _ = std::fs::rename(&old, &destination);
                return Err(Error::io(&self.shown, "cannot create", e));
            }
            if let Err(e) = std::fs::remove_dir_all(&old) {
                warnings.push(format!(
                    "the previous bake could not be removed ({e}): it is left in {}; remove it by hand",
                    old.display()
                ));
            }
        } else {
            std::fs::rename(&self.temp, &destination)
                .map_err(|e| Error::io(&self.shown, "cannot create", e))?;
        }
        self.committed = true;
        // What the resumed bake took over from dead runs is in the destination now, and an
        // interrupted bake parked beside it is superseded.
        for stale in &self.resumable {
            let _ = std::fs::remove_dir_all(stale);
        }
        let parked = partial_folder(&destination);
        if parked.exists() {
            if let Err(e) = std::fs::remove_dir_all(&parked) {
                warnings.push(format!(
                    "the interrupted bake in {} could not be removed ({e})",
                    parked.display()
                ));
            }
        }
        Ok((self.shown.clone(), warnings))
    }

    /// True when the destination holds a complete bake: a drape report that says every frame
    /// asked for was baked, neither interrupted nor stopped at `--until`.
    pub fn destination_complete(&self) -> bool {
        let Ok(text) = std::fs::read_to_string(self.destination.join("report.json")) else {
            return false;
        };
        let Ok(report) = serde_json::from_str::<serde_json::Value>(&text) else {
            return false;
        };
        let frames = |k: &str| report.get(k).and_then(serde_json::Value::as_u64);
        replaceable(&self.destination).is_ok()
            && frames("frames_baked").is_some()
            && frames("frames_baked") == frames("frames_requested")
            && report
                .get("interrupted")
                .is_none_or(serde_json::Value::is_null)
            && report.get("until").is_none_or(serde_json::Value::is_null)
    }

    /// Keeps an interrupted bake beside the destination as `.NAME.partial` (replacing an
    /// older one there), leaving the complete bake in the destination as it was. Returns
    /// where it is.
    pub fn park(mut self) -> Result<PathBuf> {
        let parked = partial_folder(&self.destination);
        if parked.exists() {
            std::fs::remove_dir_all(&parked)
                .map_err(|e| Error::io(&parked, "cannot replace", e))?;
        }
        std::fs::rename(&self.temp, &parked).map_err(|e| Error::io(&parked, "cannot create", e))?;
        self.committed = true;
        Ok(parked)
    }
}

/// Where an interrupted bake is kept while a complete one stays in `destination`.
pub fn partial_folder(destination: &Path) -> PathBuf {
    let name = destination
        .file_name()
        .expect("resolved destinations end in a name")
        .to_string_lossy();
    destination.with_file_name(format!(".{name}.partial"))
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp);
        }
    }
}

/// `destination` with its parent created and resolved: absolute, without `.`, `..` or symbolic
/// links above the last name, which must be a name.
fn resolve(destination: &Path) -> Result<PathBuf> {
    // `--out .` or `--out out/..` would replace a folder the user is standing in or above.
    let name = match destination.components().next_back() {
        Some(std::path::Component::Normal(name)) => name.to_os_string(),
        _ => {
            return Err(bad_out(format!(
                "{} does not name a folder of its own (it ends in `.`, `..` or `/`)",
                destination.display()
            )))
        }
    };
    let absolute = std::path::absolute(destination)
        .map_err(|e| bad_out(format!("{}: {e}", destination.display())))?;
    let parent = absolute
        .parent()
        .expect("a path ending in a name has a parent");
    std::fs::create_dir_all(parent)
        .map_err(|e| bad_out(format!("cannot create {}: {e}", parent.display())))?;
    let parent =
        std::fs::canonicalize(parent).map_err(|e| bad_out(format!("{}: {e}", parent.display())))?;
    Ok(parent.join(name))
}

/// Ok when `dir` may be replaced: an empty folder, or a previous bake; else why not.
fn replaceable(dir: &Path) -> std::result::Result<(), String> {
    if !dir.is_dir() || dir.is_symlink() {
        return Err("not a folder".into());
    }
    let entries: Vec<std::fs::DirEntry> = std::fs::read_dir(dir)
        .map_err(|e| format!("cannot read it: {e}"))?
        .collect::<std::io::Result<_>>()
        .map_err(|e| format!("cannot read it: {e}"))?;
    if entries.is_empty() {
        return Ok(());
    }
    let report = dir.join("report.json");
    let text = std::fs::read_to_string(&report).map_err(|_| "no report.json".to_string())?;
    let schema = serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("schema")?.as_str().map(str::to_string));
    if !schema.is_some_and(|s| s.starts_with("drape.report/")) {
        return Err("its report.json is not a drape report".into());
    }
    for entry in entries {
        let name = entry.file_name().to_string_lossy().to_string();
        let kind = entry.file_type().map_err(|e| e.to_string())?;
        let ours = if kind.is_dir() {
            BAKE_FOLDERS.contains(&name.as_str())
        } else if kind.is_file() {
            name == "report.json"
                || Path::new(&name)
                    .extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| BAKE_EXTENSIONS.contains(&e))
        } else {
            false
        };
        if !ours {
            return Err(format!("it holds {name:?}, which a bake does not write"));
        }
    }
    Ok(())
}

/// Where a previous bake is set aside while the new one moves in.
fn old_folder(destination: &Path, pid: u32) -> PathBuf {
    let name = destination
        .file_name()
        .expect("resolved destinations end in a name")
        .to_string_lossy();
    destination.with_file_name(format!(".{name}.old-{pid}"))
}

/// True when process `pid` is still running (on Unix; elsewhere every process counts as alive,
/// so nothing is cleaned).
fn alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return false;
        };
        // SAFETY: signal 0 only checks that the process exists; nothing is sent.
        let result = unsafe { libc::kill(pid, 0) };
        result == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// Removes staging and set-aside folders of dead processes beside `destination`, first putting
/// back a previous bake that a killed process had set aside; when `resuming`, staging folders
/// with checkpoints are kept. Returns what it did, and the folders kept.
fn clean_stale(
    parent: &Path,
    name: &str,
    destination: &Path,
    resuming: bool,
) -> (Vec<String>, Vec<PathBuf>) {
    let mut notes = Vec::new();
    let mut kept = Vec::new();
    let Ok(entries) = std::fs::read_dir(parent) else {
        return (notes, kept);
    };
    let (tmp, old) = (format!(".{name}.tmp-"), format!(".{name}.old"));
    let mut stale: Vec<(PathBuf, bool)> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let file = e.file_name().to_string_lossy().to_string();
            let (is_old, pid) = if let Some(pid) = file.strip_prefix(&tmp) {
                (false, pid.to_string())
            } else if let Some(rest) = file.strip_prefix(&old) {
                // `.NAME.old` (drape before 0.1 kept no pid) or `.NAME.old-PID`.
                (true, rest.strip_prefix('-').unwrap_or("0").to_string())
            } else {
                return None;
            };
            let pid: u32 = pid.parse().ok()?;
            (pid == 0 || (pid != std::process::id() && !alive(pid))).then(|| (e.path(), is_old))
        })
        .collect();
    stale.sort();
    for (path, is_old) in stale {
        let shown = path.display();
        if is_old && !destination.exists() {
            if std::fs::rename(&path, destination).is_ok() {
                notes.push(format!(
                    "put back the previous bake that an interrupted run had left in {shown}"
                ));
            }
            continue;
        }
        if resuming && !is_old && path.join("checkpoints").is_dir() {
            kept.push(path);
            continue;
        }
        match std::fs::remove_dir_all(&path) {
            Ok(()) => notes.push(format!(
                "removed {shown}, left by a run that no longer exists"
            )),
            Err(e) => notes.push(format!(
                "{shown}, left by a run that no longer exists, could not be removed ({e}); remove it by hand"
            )),
        }
    }
    (notes, kept)
}
