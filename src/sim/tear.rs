//! Tearing: a spring stretched past its garment's `tear_strain` breaks. Checked after every
//! frame; broken springs leave the model, the triangles that used a broken edge leave the mesh
//! (so exported faces follow the torn topology), and a torn garment loses its long-range
//! attachments (a piece torn off must not stay tied to the pins). A voxelized mesh garment's
//! surface is carried by the lattice particles around each vertex: a surface triangle leaves
//! when a spring broke inside the lattice box of the particles that carry its corners (the cut
//! runs through the lattice under it).

use crate::garment::Garment;
use glam::Vec3;

/// Removes from `garment` every spring whose strain at `positions` (the garment's particles,
/// grid order) exceeds `threshold`, with the triangles that used one of their edges; returns
/// how many springs broke.
pub fn tear(garment: &mut Garment, positions: &[Vec3], threshold: f32) -> usize {
    let broken: std::collections::HashSet<(u32, u32)> = garment
        .springs
        .iter()
        .filter(|s| {
            let l = positions[s.a as usize].distance(positions[s.b as usize]);
            (l - s.rest) / s.rest > threshold
        })
        .map(|s| (s.a.min(s.b), s.a.max(s.b)))
        .collect();
    if broken.is_empty() {
        return 0;
    }
    garment
        .springs
        .retain(|s| !broken.contains(&(s.a.min(s.b), s.a.max(s.b))));
    match garment.embedding.clone() {
        None => garment.triangles.retain(|t| {
            (0..3).all(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                !broken.contains(&(a.min(b), a.max(b)))
            })
        }),
        Some(embedding) => {
            // The lattice box each broken spring lies in, and each face's box (the cells of the
            // particles carrying its corners): a break inside a face's box cuts the face.
            let cells = &garment.cells;
            let cuts: Vec<([u32; 3], [u32; 3])> = broken
                .iter()
                .map(|&(a, b)| {
                    let (p, q) = (cells[a as usize], cells[b as usize]);
                    (
                        [0, 1, 2].map(|k| p[k].min(q[k])),
                        [0, 1, 2].map(|k| p[k].max(q[k])),
                    )
                })
                .collect();
            garment.triangles.retain(|t| {
                let mut lo = [u32::MAX; 3];
                let mut hi = [0u32; 3];
                for &v in t {
                    let carriers = embedding.start[v as usize] as usize
                        ..embedding.start[v as usize + 1] as usize;
                    for &p in &embedding.particle[carriers] {
                        let c = cells[p as usize];
                        for k in 0..3 {
                            lo[k] = lo[k].min(c[k]);
                            hi[k] = hi[k].max(c[k]);
                        }
                    }
                }
                !cuts
                    .iter()
                    .any(|(a, b)| (0..3).all(|k| lo[k] <= a[k] && b[k] <= hi[k]))
            });
        }
    }
    garment.tethers.clear();
    broken.len()
}

/// The garments as built and as torn so far, each one's tearing strain, and the springs broken.
pub(super) struct Tearing {
    pub(super) garments: Vec<Garment>,
    /// Per garment, the strain past which its springs break (None: it does not tear).
    pub(super) strain: Vec<Option<f32>>,
    /// Springs broken so far.
    pub(super) torn_springs: usize,
}

impl Tearing {
    /// Breaks the springs of tearable garments stretched past their strain at `positions`
    /// (export order; `ranges`: each garment's share); returns how many broke.
    pub(super) fn tear(
        &mut self,
        positions: &[Vec3],
        ranges: impl Iterator<Item = std::ops::Range<usize>>,
    ) -> usize {
        let mut broken = 0;
        for ((garment, threshold), range) in self.garments.iter_mut().zip(&self.strain).zip(ranges)
        {
            let Some(threshold) = *threshold else {
                continue;
            };
            broken += tear(garment, &positions[range], threshold);
        }
        self.torn_springs += broken;
        broken
    }

    /// True when some garment can tear.
    pub(super) fn any(&self) -> bool {
        self.strain.iter().any(Option::is_some)
    }
}
