//! Outputs are written into a temporary folder beside the destination and moved into place only
//! when everything is written, so a bake that fails on bad input leaves no partial folder.
//!
//! An existing destination is replaced only if it is empty or holds a previous bake (a
//! `report.json`): drape never deletes a folder it did not write.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A temporary output folder that becomes `destination` on [`Staging::commit`] and is removed if
/// dropped uncommitted.
#[derive(Debug)]
pub struct Staging {
    destination: PathBuf,
    temp: PathBuf,
    committed: bool,
}

impl Staging {
    /// Creates `.<name>.tmp-<pid>` beside `destination` (creating missing parent folders).
    pub fn new(destination: &Path) -> Result<Staging> {
        if destination.exists() {
            let replaceable = destination.is_dir()
                && (destination.join("report.json").is_file()
                    || std::fs::read_dir(destination)
                        .map(|mut d| d.next().is_none())
                        .unwrap_or(false));
            if !replaceable {
                return Err(Error::InvalidArgument {
                    flag: "--out".into(),
                    reason: format!(
                        "{} exists and is not a drape bake (no report.json): refusing to replace it",
                        destination.display()
                    ),
                });
            }
        }
        let name = destination
            .file_name()
            .ok_or_else(|| Error::InvalidArgument {
                flag: "--out".into(),
                reason: format!("{} does not name a folder", destination.display()),
            })?
            .to_string_lossy()
            .to_string();
        let parent = match destination.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        // An output folder that cannot be made is a bad --out, like one that is not a bake.
        std::fs::create_dir_all(&parent).map_err(|e| Error::InvalidArgument {
            flag: "--out".into(),
            reason: format!("cannot create {}: {e}", parent.display()),
        })?;
        let temp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
        if temp.exists() {
            std::fs::remove_dir_all(&temp).map_err(|e| Error::io(&temp, "cannot remove", e))?;
        }
        std::fs::create_dir(&temp).map_err(|e| Error::io(&temp, "cannot create", e))?;
        Ok(Staging {
            destination: destination.to_path_buf(),
            temp,
            committed: false,
        })
    }

    /// The temporary folder to write into.
    pub fn path(&self) -> &Path {
        &self.temp
    }

    /// Moves the temporary folder to the destination, replacing a previous bake there.
    pub fn commit(mut self) -> Result<PathBuf> {
        if self.destination.exists() {
            let old = self.temp.with_extension("old");
            std::fs::rename(&self.destination, &old)
                .map_err(|e| Error::io(&self.destination, "cannot replace", e))?;
            std::fs::rename(&self.temp, &self.destination)
                .map_err(|e| Error::io(&self.destination, "cannot create", e))?;
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&self.temp, &self.destination)
                .map_err(|e| Error::io(&self.destination, "cannot create", e))?;
        }
        self.committed = true;
        Ok(self.destination.clone())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp);
        }
    }
}
