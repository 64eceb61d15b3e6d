//! The frames spooled to disk for the outputs that need a mesh's frames together or every
//! frame's extent before the first image: the USD layer (each attribute's time samples in one
//! block) and the preview (a camera that frames the whole bake). The bake writes each frame
//! once as raw `f32` positions into a hidden file of its staging folder; the readers take one
//! frame of one mesh at a time back from it, and the file is removed when they are done.
//!
//! Layout: frame 0 holds every mesh in turn; each later frame holds the animated meshes only
//! (a static mesh's vertices are read from frame 0).

use super::sink::{Frame, MeshInfo};
use crate::error::{Error, Result};
use glam::Vec3;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::PathBuf;

/// Faces of a mesh whenever they changed: (first frame index, triangles), in order.
pub type Topology = Vec<(usize, Vec<[u32; 3]>)>;

/// Writes frames into the spool file.
pub struct Spool {
    path: PathBuf,
    out: BufWriter<File>,
    meshes: Vec<MeshInfo>,
    topology: Vec<Topology>,
    /// Per mesh, which vertices its current faces draw (all, for a mesh without faces).
    drawn: Vec<Vec<bool>>,
    bounds: Option<(Vec3, Vec3)>,
    frames: usize,
}

/// Which of `vertices` vertices the faces draw (every one when there are none: a polyline).
fn drawn(vertices: usize, triangles: &[[u32; 3]]) -> Vec<bool> {
    let mut d = vec![triangles.is_empty(); vertices];
    for &i in triangles.iter().flatten() {
        d[i as usize] = true;
    }
    d
}

impl Spool {
    /// Creates `path` for frames of `meshes`.
    pub fn create(path: PathBuf, meshes: &[MeshInfo]) -> Result<Spool> {
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(|e| Error::io(&path, "cannot create", e))?;
        Ok(Spool {
            out: BufWriter::with_capacity(1 << 20, file),
            path,
            topology: meshes
                .iter()
                .map(|m| vec![(0, m.triangles.clone())])
                .collect(),
            drawn: meshes
                .iter()
                .map(|m| drawn(m.vertices, &m.triangles))
                .collect(),
            meshes: meshes.to_vec(),
            bounds: None,
            frames: 0,
        })
    }

    /// The frames written, ready to read back.
    pub fn into_recorded(self) -> Result<Recorded> {
        let io = |e| Error::io(&self.path, "cannot read", e);
        let file = self.out.into_inner().map_err(|e| io(e.into_error()))?;
        let mut recorded = Recorded {
            file,
            path: self.path,
            statics: Vec::new(),
            meshes: self.meshes,
            topology: self.topology,
            bounds: self.bounds,
            frames: self.frames,
        };
        recorded.statics = (0..recorded.meshes.len())
            .map(
                |m| match recorded.meshes[m].animated || recorded.frames == 0 {
                    true => Ok(Vec::new()),
                    false => recorded.read(m, 0),
                },
            )
            .collect::<Result<_>>()?;
        Ok(recorded)
    }
}

impl Spool {
    /// Appends the next frame.
    pub fn frame(&mut self, frame: &Frame) -> Result<()> {
        for ((m, positions), drawn) in self.meshes.iter().zip(&frame.positions).zip(&self.drawn) {
            if frame.index > 0 && !m.animated {
                continue;
            }
            for (p, _) in positions.iter().zip(drawn).filter(|(_, d)| **d) {
                let (lo, hi) = self.bounds.get_or_insert((*p, *p));
                *lo = lo.min(*p);
                *hi = hi.max(*p);
            }
            self.out
                .write_all(bytemuck::cast_slice(positions))
                .map_err(|e| Error::io(&self.path, "cannot write", e))?;
        }
        self.frames += 1;
        Ok(())
    }

    /// From frame index `from` on, mesh `mesh` has these faces.
    pub fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) {
        self.topology[mesh].push((from, triangles.to_vec()));
        self.drawn[mesh] = drawn(self.meshes[mesh].vertices, triangles);
    }
}

/// Spooled frames read back; the file is removed when this is dropped.
pub struct Recorded {
    file: File,
    path: PathBuf,
    pub meshes: Vec<MeshInfo>,
    /// Per mesh, its faces whenever they changed.
    pub topology: Vec<Topology>,
    /// The box of every drawn vertex of every frame.
    pub bounds: Option<(Vec3, Vec3)>,
    pub frames: usize,
    /// Static meshes' vertices (empty for animated ones).
    statics: Vec<Vec<Vec3>>,
}

impl Recorded {
    /// Where mesh `mesh`'s frame `k` starts in the file [bytes].
    fn offset(&self, mesh: usize, k: usize) -> u64 {
        let bytes = |m: &MeshInfo| m.vertices as u64 * 12;
        let before = &self.meshes[..mesh];
        if k == 0 {
            return before.iter().map(bytes).sum();
        }
        let first: u64 = self.meshes.iter().map(bytes).sum();
        let animated =
            |ms: &[MeshInfo]| -> u64 { ms.iter().filter(|m| m.animated).map(bytes).sum() };
        first + (k as u64 - 1) * animated(&self.meshes) + animated(before)
    }

    fn read(&mut self, mesh: usize, k: usize) -> Result<Vec<Vec3>> {
        let mut positions = vec![Vec3::ZERO; self.meshes[mesh].vertices];
        let at = self.offset(mesh, k);
        self.file
            .seek(SeekFrom::Start(at))
            .and_then(|_| {
                self.file
                    .read_exact(bytemuck::cast_slice_mut(&mut positions))
            })
            .map_err(|e| Error::io(&self.path, "cannot read", e))?;
        Ok(positions)
    }

    /// Mesh `mesh`'s vertices at frame index `k`.
    pub fn positions(&mut self, mesh: usize, k: usize) -> Result<Vec<Vec3>> {
        if !self.meshes[mesh].animated && !self.statics[mesh].is_empty() {
            return Ok(self.statics[mesh].clone());
        }
        self.read(mesh, if self.meshes[mesh].animated { k } else { 0 })
    }

    /// Mesh `mesh`'s faces at frame index `k`.
    pub fn triangles_at(&self, mesh: usize, k: usize) -> &[[u32; 3]] {
        let history = &self.topology[mesh];
        history
            .iter()
            .rev()
            .find(|(first, _)| *first <= k)
            .map_or(&self.meshes[mesh].triangles, |(_, t)| t)
    }

    /// Mesh `mesh`'s faces at the end.
    pub fn last_triangles(&self, mesh: usize) -> &[[u32; 3]] {
        self.triangles_at(mesh, usize::MAX)
    }
}

impl Drop for Recorded {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
