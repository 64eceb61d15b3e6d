//! Shell caches: a character's collision shell with its particle positions for every frame, in a
//! small binary file (layout in `docs/shell-format.md`), so a bake need not import and sample the
//! character again. A cache records a hash of its inputs (the source files' bytes and every
//! option); a cache whose hash differs from the current inputs is stale and rebuilt.

use super::{Character, CharacterOptions, Shell};
use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// The first 8 bytes of every shell cache.
pub const MAGIC: &[u8; 8] = b"DRAPESHL";
/// Layout version (2: a checksum of everything before it ends the file).
pub const VERSION: u32 = 2;
/// Header bytes before the particle bindings.
pub const HEADER_BYTES: usize = 40;
/// Bytes of the checksum that ends the file: FNV-1a (64 bits) of every byte before it.
pub const CHECKSUM_BYTES: usize = 8;

/// A shell and its positions on every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ShellCache {
    pub shell: Shell,
    pub fps: f32,
    /// Particle positions [m] per frame.
    pub frames: Vec<Vec<Vec3>>,
    /// Hash of the inputs this cache was built from.
    pub inputs: u64,
}

/// FNV-1a's starting value.
pub(crate) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a, 64 bits: a stable hash of the inputs (not for security).
pub(crate) fn fnv(hash: u64, bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(hash, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// Hash of everything a shell depends on: the source files' bytes, the options, radius, fps,
/// frame count, and the sampler's parameters.
pub fn input_hash(
    files: &[std::path::PathBuf],
    options: &CharacterOptions,
    radius: f32,
    fps: f32,
    frames: usize,
) -> Result<u64> {
    let mut h = FNV_OFFSET;
    for f in files {
        let bytes = std::fs::read(f).map_err(|e| Error::io(f, "cannot read", e))?;
        h = fnv(h, &bytes);
    }
    // The sampler's own parameters too: a new sampler must not reuse an old cache.
    let sampler = super::shell::SAMPLER;
    let importer = crate::mesh::import::IMPORTER;
    let settings =
        format!("{options:?}|{radius}|{fps}|{frames}|v{VERSION}|{sampler}|import{importer}");
    Ok(fnv(h, settings.as_bytes()))
}

impl ShellCache {
    /// Samples `character`'s first frame and carries the shell through every frame (re-sampling
    /// frames whose topology differs from the first, which then keep their own particles).
    pub fn build(character: &Character, radius: f32, inputs: u64) -> Result<ShellCache> {
        if !character.same_topology() {
            return Err(Error::InvalidField {
                file: character.source.display().to_string(),
                field: "frames".into(),
                reason: "the frames change topology; a cache holds one shell riding a fixed mesh"
                    .into(),
            });
        }
        let shell = Shell::sample(&character.frames[0], &character.triangles[0], radius);
        let frames = character
            .frames
            .iter()
            .map(|f| shell.positions(f, &character.triangles[0]))
            .collect();
        Ok(ShellCache {
            shell,
            fps: character.fps,
            frames,
            inputs,
        })
    }

    /// The file's bytes (little-endian throughout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.shell.len();
        let mut b = Vec::with_capacity(HEADER_BYTES + n * 12 + self.frames.len() * n * 12);
        b.extend_from_slice(MAGIC);
        for v in [VERSION, n as u32, self.frames.len() as u32] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.shell.radius.to_le_bytes());
        b.extend_from_slice(&self.fps.to_le_bytes());
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&self.inputs.to_le_bytes());
        for (t, [u, v]) in self.shell.triangle.iter().zip(&self.shell.barycentric) {
            b.extend_from_slice(&t.to_le_bytes());
            b.extend_from_slice(&u.to_le_bytes());
            b.extend_from_slice(&v.to_le_bytes());
        }
        for frame in &self.frames {
            for p in frame {
                p.to_array()
                    .iter()
                    .for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
            }
        }
        let checksum = fnv(FNV_OFFSET, &b);
        b.extend_from_slice(&checksum.to_le_bytes());
        b
    }

    /// True when every particle names one of `triangles` triangles with finite barycentric
    /// coordinates and every position is finite: a cache is checked against the character it is
    /// used for, so even a cache whose checksum holds cannot index past its mesh.
    pub fn fits(&self, triangles: usize) -> bool {
        self.shell
            .triangle
            .iter()
            .all(|&t| (t as usize) < triangles)
            && self
                .shell
                .barycentric
                .iter()
                .all(|b| b[0].is_finite() && b[1].is_finite())
            && self.frames.iter().flatten().all(|p| p.is_finite())
    }

    /// Parses a cache file's bytes; `file` names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &str) -> Result<ShellCache> {
        let bad = |reason: String| Error::InvalidField {
            file: file.to_string(),
            field: "(shell cache)".into(),
            reason,
        };
        if bytes.len() < HEADER_BYTES || &bytes[..8] != MAGIC {
            return Err(bad("not a drape shell cache (no DRAPESHL header)".into()));
        }
        let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
        let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
        if u32_at(8) != VERSION {
            return Err(bad(format!(
                "layout version {} (this drape reads {VERSION})",
                u32_at(8)
            )));
        }
        let (n, frames) = (u32_at(12) as u64, u32_at(16) as u64);
        let expected = (n * 12)
            .checked_mul(frames + 1)
            .and_then(|b| b.checked_add((HEADER_BYTES + CHECKSUM_BYTES) as u64));
        if expected != Some(bytes.len() as u64) {
            return Err(bad(format!(
                "{} bytes where the header promises {}",
                bytes.len(),
                expected.map_or("more than 2⁶⁴".to_string(), |e| e.to_string())
            )));
        }
        let body = bytes.len() - CHECKSUM_BYTES;
        let stored = u64::from_le_bytes(bytes[body..].try_into().expect("8 bytes"));
        if fnv(FNV_OFFSET, &bytes[..body]) != stored {
            return Err(bad(
                "its checksum does not match its contents (the file is corrupted)".into(),
            ));
        }
        let (n, frames) = (n as usize, frames as usize);
        let mut shell = Shell {
            radius: f32_at(20),
            triangle: Vec::with_capacity(n),
            barycentric: Vec::with_capacity(n),
        };
        for k in 0..n {
            let o = HEADER_BYTES + k * 12;
            shell.triangle.push(u32_at(o));
            shell.barycentric.push([f32_at(o + 4), f32_at(o + 8)]);
        }
        let base = HEADER_BYTES + n * 12;
        let frames = (0..frames)
            .map(|f| {
                (0..n)
                    .map(|k| {
                        let o = base + (f * n + k) * 12;
                        Vec3::new(f32_at(o), f32_at(o + 4), f32_at(o + 8))
                    })
                    .collect()
            })
            .collect();
        Ok(ShellCache {
            shell,
            fps: f32_at(24),
            frames,
            inputs: u64::from_le_bytes(bytes[32..40].try_into().expect("8 bytes")),
        })
    }

    /// Reads a cache file.
    pub fn read(path: &Path) -> Result<ShellCache> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
        ShellCache::from_bytes(&bytes, &path.display().to_string())
    }

    /// Writes the cache to `path` through a temporary file renamed into place (removed again
    /// if anything fails).
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut name = path.file_name().unwrap_or_default().to_os_string();
        name.push(format!(".tmp-drape-{}", std::process::id()));
        let temp = path.with_file_name(name);
        let written = std::fs::write(&temp, self.to_bytes())
            .map_err(|e| Error::io(path, "cannot write", e))
            .and_then(|()| {
                std::fs::rename(&temp, path).map_err(|e| Error::io(path, "cannot write", e))
            });
        if written.is_err() {
            let _ = std::fs::remove_file(&temp);
        }
        written
    }

    /// True when `path` holds a drape shell cache (of any version): the one kind of existing file
    /// `drape shell --out` may replace.
    pub fn is_cache_file(path: &Path) -> bool {
        use std::io::Read;
        let mut head = [0u8; 8];
        std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok_and(|()| &head == MAGIC)
    }
}
