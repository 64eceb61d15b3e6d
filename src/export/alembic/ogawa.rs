//! Ogawa, the container under Alembic: a file of data blocks (a size and bytes) and groups
//! (a list of children: data blocks or other groups), written child before parent and closed
//! by the root group's position in the header. Nothing is patched but the header, so a cache
//! streams to disk as frames arrive.
//!
//! Layout (little-endian, nothing aligned): `Ogawa`, a byte that is 0xff once the file is
//! closed (readers refuse it otherwise), the version bytes 0 1, the root group's position
//! (u64); a data block is its size (u64) and bytes, a group its child count (u64) and one u64
//! per child: a position, with the top bit set for data. An empty data block or group is never
//! written: its reference is [`EMPTY_DATA`] or [`EMPTY_GROUP`].

use crate::error::{Error, Result};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The reference to a group with no children.
pub const EMPTY_GROUP: u64 = 0;
/// The reference to a data block of no bytes.
pub const EMPTY_DATA: u64 = 1 << 63;

/// An Ogawa file being written.
pub struct Ogawa {
    path: PathBuf,
    out: BufWriter<File>,
    /// Where the next block starts.
    end: u64,
}

impl Ogawa {
    /// Creates `path` with an open (not yet closed) header.
    pub fn create(path: &Path) -> Result<Ogawa> {
        let file = File::create(path).map_err(|e| Error::io(path, "cannot create", e))?;
        let mut o = Ogawa {
            path: path.to_path_buf(),
            out: BufWriter::with_capacity(1 << 20, file),
            end: 0,
        };
        o.write(b"Ogawa\0\0\x01")?;
        o.write(&0u64.to_le_bytes())?;
        Ok(o)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<()> {
        self.out
            .write_all(bytes)
            .map_err(|e| Error::io(&self.path, "cannot write", e))?;
        self.end += bytes.len() as u64;
        Ok(())
    }

    /// Appends one data block of `parts` one after another; returns its reference.
    pub fn data(&mut self, parts: &[&[u8]]) -> Result<u64> {
        let size: usize = parts.iter().map(|p| p.len()).sum();
        if size == 0 {
            return Ok(EMPTY_DATA);
        }
        let at = self.end;
        self.write(&(size as u64).to_le_bytes())?;
        for p in parts {
            self.write(p)?;
        }
        Ok(at | EMPTY_DATA)
    }

    /// Appends a group of `children` (references from [`Ogawa::data`] and [`Ogawa::group`]);
    /// returns its reference.
    pub fn group(&mut self, children: &[u64]) -> Result<u64> {
        if children.is_empty() {
            return Ok(EMPTY_GROUP);
        }
        let at = self.end;
        self.write(&(children.len() as u64).to_le_bytes())?;
        for c in children {
            self.write(&c.to_le_bytes())?;
        }
        Ok(at)
    }

    /// Writes the root group of `children`, points the header at it and marks the file closed.
    pub fn close(mut self, children: &[u64]) -> Result<()> {
        let root = self.group(children)?;
        let io = |e| Error::io(&self.path, "cannot write", e);
        self.out.seek(SeekFrom::Start(8)).map_err(io)?;
        self.out.write_all(&root.to_le_bytes()).map_err(io)?;
        self.out.seek(SeekFrom::Start(5)).map_err(io)?;
        self.out.write_all(&[0xff]).map_err(io)?;
        self.out.flush().map_err(io)
    }
}

/// An Alembic sample's key: MurmurHash3 x64 128 (seed 0) of its bytes, the two 64-bit halves
/// little-endian; zero for no bytes.
pub fn key(bytes: &[u8]) -> [u8; 16] {
    if bytes.is_empty() {
        return [0; 16];
    }
    let mut reader = bytes;
    let h = murmur3::murmur3_x64_128(&mut reader, 0).expect("a slice reads");
    h.to_le_bytes()
}

#[cfg(test)]
mod tests {
    use super::key;

    fn hex(k: [u8; 16]) -> String {
        k.iter().map(|b| format!("{b:02x}")).collect()
    }

    #[test]
    fn keys_are_the_ones_the_alembic_library_writes() {
        // Keys the official library (Alembic 1.8.12) wrote beside these samples.
        assert_eq!(
            hex(key(&42i32.to_le_bytes())),
            "cf346e1ce6486f2816b8bc2b6a3dd2e2"
        );
        let indices: Vec<u8> = [0i32, 1, 2, 3]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        assert_eq!(hex(key(&indices)), "d15bd55e1bb88097646f409b63d099e2");
        assert_eq!(hex(key(b"frame0\0")), "2e1ef90ae1cb7fb92b2554b5a0792c26");
        assert_eq!(key(&[]), [0; 16]);
    }
}
