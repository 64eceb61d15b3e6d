//! Alembic's archive layer over Ogawa, as much of it as a point cache needs: objects, compound
//! properties, scalar and array properties sampled on one uniform time sampling, and the
//! headers that describe them. Laid out as Alembic 1.8's Ogawa writer lays it out
//! (`lib/Alembic/AbcCoreOgawa`): the official library reads it back sample for sample.
//!
//! - The root group: the file version (0), the library version whose format this is (10812,
//!   Alembic 1.8.12), the top object, the archive's metadata, the time samplings and the table
//!   of metadata strings that headers point into.
//! - An object: its properties (one compound), its child objects, then a data block of the
//!   children's headers (name, metadata) and two 16-byte hashes. Readers never check the
//!   hashes, so drape writes zeros.
//! - A compound: its properties, then a data block of their headers.
//! - A property: a data block per stored sample (16-byte key, then the values; an array's is
//!   followed by an empty dimensions block). A sample equal to the one before is not stored
//!   again: the header's first and last changed indices say which samples are (`set`).

use super::ogawa::{key, Ogawa, EMPTY_DATA, EMPTY_GROUP};
use crate::error::Result;
use std::collections::HashMap;

/// Alembic's plain old data types, by their number in a property header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pod {
    Bool = 0,
    Uint8 = 1,
    Int32 = 6,
    Uint32 = 5,
    Float32 = 10,
    Float64 = 11,
}

/// The time sampling every animated property uses: index 1 (index 0 is Alembic's default, one
/// sample at time 0, which every archive holds).
pub const SAMPLED: u32 = 1;

/// The archive being written: the file, the samples already written (a sample equal to one
/// written before is a reference to it, as in Alembic) and the metadata table.
pub struct Archive {
    file: Ogawa,
    written: HashMap<SampleId, u64>,
    metadata: Vec<String>,
    /// The most samples any property on [`SAMPLED`] stores.
    max_samples: u32,
    /// The file and library version blocks.
    versions: [u64; 2],
}

impl Archive {
    /// Starts an archive in `file`: the two version blocks come first.
    pub fn new(mut file: Ogawa) -> Result<Archive> {
        let versions = [
            file.data(&[&0i32.to_le_bytes()])?,
            file.data(&[&10812i32.to_le_bytes()])?,
        ];
        Ok(Archive {
            versions,
            file,
            written: HashMap::new(),
            metadata: Vec::new(),
            max_samples: 0,
        })
    }

    /// The reference of a sample block with these bytes: written now, or the one written
    /// before with the same key.
    fn sample(&mut self, bytes: &[u8], key: [u8; 16]) -> Result<u64> {
        if bytes.is_empty() {
            return Ok(EMPTY_DATA);
        }
        if let Some(&r) = self.written.get(&(bytes.len(), key)) {
            return Ok(r);
        }
        let r = self.file.data(&[&key, bytes])?;
        self.written.insert((bytes.len(), key), r);
        Ok(r)
    }

    /// The header's index of `text` in the metadata table (0: none; 0xff: written in place).
    fn metadata_index(&mut self, text: &str) -> u8 {
        if text.is_empty() {
            return 0;
        }
        if text.len() < 256 {
            if let Some(i) = self.metadata.iter().position(|m| m == text) {
                return i as u8 + 1;
            }
            if self.metadata.len() < 254 {
                self.metadata.push(text.to_string());
                return self.metadata.len() as u8;
            }
        }
        0xff
    }

    /// Writes an object's group: its properties, its children (groups from [`Archive::object`])
    /// with their names and metadata, and the hashes readers do not check.
    pub fn object(
        &mut self,
        properties: Compound,
        children: &[(String, String, u64)],
    ) -> Result<u64> {
        let mut refs = vec![self.compound_group(properties)?];
        let mut headers = Vec::new();
        for (name, metadata, group) in children {
            refs.push(*group);
            headers.extend_from_slice(&(name.len() as u32).to_le_bytes());
            headers.extend_from_slice(name.as_bytes());
            let index = self.metadata_index(metadata);
            headers.push(index);
            if index == 0xff {
                headers.extend_from_slice(&(metadata.len() as u32).to_le_bytes());
                headers.extend_from_slice(metadata.as_bytes());
            }
        }
        headers.extend_from_slice(&[0; 32]);
        refs.push(self.file.data(&[&headers])?);
        self.file.group(&refs)
    }

    /// Writes a compound's group: each property's group, then their headers.
    fn compound_group(&mut self, compound: Compound) -> Result<u64> {
        if compound.properties.is_empty() {
            return Ok(EMPTY_GROUP);
        }
        let mut refs = Vec::new();
        let mut headers = Vec::new();
        for p in compound.properties {
            match p {
                Node::Compound(c) => {
                    let (name, metadata) = (c.name.clone(), c.metadata.clone());
                    refs.push(self.compound_group(c)?);
                    self.compound_header(&name, &metadata, &mut headers);
                }
                Node::Property(p) => {
                    refs.push(self.file.group(&p.children)?);
                    self.property_header(&p, &mut headers);
                }
            }
        }
        refs.push(self.file.data(&[&headers])?);
        self.file.group(&refs)
    }

    fn compound_header(&mut self, name: &str, metadata: &str, out: &mut Vec<u8>) {
        let index = self.metadata_index(metadata);
        let hint = size_hint(&[metadata.len(), name.len()]);
        let info = (hint << 2) | (u32::from(index) << 20);
        out.extend_from_slice(&info.to_le_bytes());
        name_and_metadata(out, hint, name, metadata, index);
    }

    fn property_header(&mut self, p: &Property, out: &mut Vec<u8>) {
        if p.time_sampling == SAMPLED {
            let stored = if p.last == 0 && p.next > 0 { 1 } else { p.next };
            self.max_samples = self.max_samples.max(stored);
        }
        let index = self.metadata_index(&p.metadata);
        let hint = size_hint(&[
            p.metadata.len(),
            p.name.len(),
            p.next as usize,
            p.time_sampling as usize,
        ]);
        let mut info = match (p.array, p.scalar_like) {
            (false, _) => 1,
            (true, false) => 2,
            (true, true) => 3,
        };
        info |= hint << 2 | (p.pod as u32) << 4 | u32::from(p.extent) << 12;
        info |= u32::from(index) << 20;
        if p.time_sampling != 0 {
            info |= 0x100;
        }
        let changed = if p.first == 0 && p.last == 0 {
            info |= 0x800;
            false
        } else if p.first != 1 || p.last + 1 != p.next {
            info |= 0x200;
            true
        } else {
            false
        };
        // Alembic's "homogenous" flag: always on scalars, on arrays of extent 1 (as its writer
        // sets it; no reader uses it).
        if !p.array || p.extent == 1 {
            info |= 0x400;
        }
        out.extend_from_slice(&info.to_le_bytes());
        sized(out, hint, p.next);
        if changed {
            sized(out, hint, p.first);
            sized(out, hint, p.last);
        }
        if p.time_sampling != 0 {
            sized(out, hint, p.time_sampling);
        }
        name_and_metadata(out, hint, &p.name, &p.metadata, index);
    }

    /// Writes the top object's `children`, the archive's `metadata`, the time samplings (the
    /// default and [`SAMPLED`]: `1/fps` apart from `start` seconds) and the metadata table, and
    /// closes the file.
    pub fn close(
        mut self,
        children: &[(String, String, u64)],
        metadata: &str,
        fps: f64,
        start: f64,
    ) -> Result<()> {
        let top = self.object(Compound::new("", ""), children)?;
        let archive_metadata = self.file.data(&[metadata.as_bytes()])?;
        let mut times = Vec::new();
        for (samples, per_cycle, first) in
            [(0u32, 1.0f64, 0.0f64), (self.max_samples, 1.0 / fps, start)]
        {
            times.extend_from_slice(&samples.to_le_bytes());
            times.extend_from_slice(&per_cycle.to_le_bytes());
            times.extend_from_slice(&1u32.to_le_bytes());
            times.extend_from_slice(&first.to_le_bytes());
        }
        let times = self.file.data(&[&times])?;
        let mut table = Vec::new();
        for m in &self.metadata {
            table.push(m.len() as u8);
            table.extend_from_slice(m.as_bytes());
        }
        let table = self.file.data(&[&table])?;
        let [file_version, library_version] = self.versions;
        self.file.close(&[
            file_version,
            library_version,
            top,
            archive_metadata,
            times,
            table,
        ])
    }
}

/// The byte width of a header's sized fields for the largest of `sizes`: 0 (one byte), 1 (two)
/// or 2 (four).
fn size_hint(sizes: &[usize]) -> u32 {
    match sizes.iter().copied().max().unwrap_or(0) {
        0..=255 => 0,
        256..=65535 => 1,
        _ => 2,
    }
}

fn sized(out: &mut Vec<u8>, hint: u32, value: u32) {
    match hint {
        0 => out.push(value as u8),
        1 => out.extend_from_slice(&(value as u16).to_le_bytes()),
        _ => out.extend_from_slice(&value.to_le_bytes()),
    }
}

fn name_and_metadata(out: &mut Vec<u8>, hint: u32, name: &str, metadata: &str, index: u8) {
    sized(out, hint, name.len() as u32);
    out.extend_from_slice(name.as_bytes());
    if index == 0xff {
        sized(out, hint, metadata.len() as u32);
        out.extend_from_slice(metadata.as_bytes());
    }
}

/// A compound property: a name, metadata and the properties in it, in order.
pub struct Compound {
    name: String,
    metadata: String,
    pub properties: Vec<Node>,
}

impl Compound {
    pub fn new(name: &str, metadata: &str) -> Compound {
        Compound {
            name: name.to_string(),
            metadata: metadata.to_string(),
            properties: Vec::new(),
        }
    }
}

/// A property in a compound.
pub enum Node {
    Compound(Compound),
    Property(Property),
}

/// A sample's identity: its size and key.
type SampleId = (usize, [u8; 16]);

/// A scalar or array property being sampled.
pub struct Property {
    name: String,
    metadata: String,
    pod: Pod,
    extent: u8,
    array: bool,
    time_sampling: u32,
    /// Samples set so far.
    next: u32,
    /// The first sample that differs from sample 0 (0: none yet), and the last that differs
    /// from the one before it.
    first: u32,
    last: u32,
    /// The last stored sample: its size and key, and its references.
    previous: Option<(SampleId, [u64; 2])>,
    /// The group's children: each stored sample (an array's with its dimensions).
    children: Vec<u64>,
    /// An array whose every stored sample has one element.
    scalar_like: bool,
}

impl Property {
    /// An array property of `pod` values in groups of `extent` on time sampling `ts`.
    pub fn array(name: &str, metadata: &str, pod: Pod, extent: u8, ts: u32) -> Property {
        Property {
            name: name.to_string(),
            metadata: metadata.to_string(),
            pod,
            extent,
            array: true,
            time_sampling: ts,
            next: 0,
            first: 0,
            last: 0,
            previous: None,
            children: Vec::new(),
            scalar_like: true,
        }
    }

    /// A scalar property (one group of `extent` values per sample).
    pub fn scalar(name: &str, metadata: &str, pod: Pod, extent: u8, ts: u32) -> Property {
        Property {
            array: false,
            ..Property::array(name, metadata, pod, extent, ts)
        }
    }

    /// Sets the next sample: `bytes` holds `elements` groups of the property's extent.
    pub fn set(&mut self, archive: &mut Archive, bytes: &[u8], elements: usize) -> Result<()> {
        let id = (bytes.len(), key(bytes));
        if self.previous.is_some_and(|(last, _)| last == id) {
            self.next += 1;
            return Ok(());
        }
        // The samples since the last change repeat it: once a change comes after them they
        // are stored again, by reference (before the first change they read as sample 0).
        if let (Some((_, refs)), true) = (self.previous, self.first != 0) {
            for _ in self.last + 1..self.next {
                self.push(refs);
            }
        }
        let refs = [archive.sample(bytes, id.1)?, EMPTY_DATA];
        self.push(refs);
        if self.array && elements != 1 {
            self.scalar_like = false;
        }
        if self.first == 0 {
            self.first = self.next;
        }
        self.last = self.next;
        self.previous = Some((id, refs));
        self.next += 1;
        Ok(())
    }

    fn push(&mut self, refs: [u64; 2]) {
        self.children.push(refs[0]);
        if self.array {
            self.children.push(refs[1]);
        }
    }
}
