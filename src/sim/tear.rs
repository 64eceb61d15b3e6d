//! Tearing: a spring stretched past its garment's `tear_strain` breaks. Checked after every
//! frame; broken springs leave the model, the triangles that used a broken edge leave the mesh
//! (so exported faces follow the torn topology), and a torn garment loses its long-range
//! attachments (a piece torn off must not stay tied to the pins).

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
    garment.triangles.retain(|t| {
        (0..3).all(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            !broken.contains(&(a.min(b), a.max(b)))
        })
    });
    garment.tethers.clear();
    broken.len()
}
