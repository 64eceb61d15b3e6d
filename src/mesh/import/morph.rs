//! Morph targets (blend shapes) applied as glTF defines them: each vertex is displaced by the
//! weighted sum of its targets' displacements before it is skinned or placed. A body shape left
//! on by default weights (a heavier build, a corrective shape) is the body the cloth must
//! meet: without it drape collided with the base mesh while the DCC shows the shaped one.
//!
//! Weights come, per copy of a mesh, from the clip's weights channel on the node that places
//! it, else that node's `weights`, else the mesh's, else zeros (glTF's order). The bind pose
//! uses the default weights. Read from glTF only: assimp 5.2.5's anim meshes are not read
//! (russimp does not expose their positions), and a file with them gets a warning.

use super::{bracket, Asset, Mesh};
use glam::Vec3;
use std::borrow::Cow;

/// Each mesh's weights per copy ([`Asset::pose`]'s layout): `weights[mesh][copy][target]`.
pub(super) type Weights = Vec<Vec<Vec<f32>>>;

impl Mesh {
    /// The vertices with the targets weighted by `weights` added (the mesh's own where it has
    /// no target or every weight is zero).
    pub(super) fn shaped(&self, weights: &[f32]) -> Cow<'_, [Vec3]> {
        if weights.iter().all(|&w| w == 0.0) || self.targets.is_empty() {
            return Cow::Borrowed(&self.vertices);
        }
        let mut out = self.vertices.clone();
        for (target, &w) in self.targets.iter().zip(weights) {
            if w != 0.0 {
                out.iter_mut().zip(target).for_each(|(v, d)| *v += *d * w);
            }
        }
        Cow::Owned(out)
    }

    /// Copy `copy`'s default weights, one per target.
    fn default_weights(&self, copy: usize) -> Vec<f32> {
        let mut w = self.target_weights.get(copy).cloned().unwrap_or_default();
        w.resize(self.targets.len(), 0.0);
        w
    }
}

impl Asset {
    /// Every copy's default weights (the bind pose's).
    pub(super) fn default_weights(&self) -> Weights {
        (self.meshes.iter())
            .map(|m| (0..m.copies()).map(|c| m.default_weights(c)).collect())
            .collect()
    }

    /// Every copy's weights at time `t` of `clip` (the defaults without one).
    pub(super) fn weights_at(&self, clip: Option<usize>, t: f64) -> Weights {
        let channels = clip.and_then(|c| self.clips.get(c)).map(|c| &c.channels);
        (self.meshes.iter())
            .map(|m| {
                (0..m.copies())
                    .map(|copy| {
                        let mut w = m.default_weights(copy);
                        let node = m.instances.get(copy);
                        let keys = (channels.into_iter().flatten())
                            .find(|ch| Some(&ch.node) == node && !ch.weights.is_empty());
                        if let Some(keys) = keys {
                            for (w, keys) in w.iter_mut().zip(&keys.weights) {
                                *w = sample_f32(keys, t).unwrap_or(*w);
                            }
                        }
                        w
                    })
                    .collect()
            })
            .collect()
    }
}

/// Linear interpolation of scalar keys at `t`, holding the ends.
pub(super) fn sample_f32(keys: &[(f64, f32)], t: f64) -> Option<f32> {
    let (i, f) = bracket(keys.iter().map(|k| k.0), keys.len(), t)?;
    Some(match f {
        Some(f) => keys[i].1 + (keys[i + 1].1 - keys[i].1) * f as f32,
        None => keys[i].1,
    })
}

/// `a` a fraction `w` of the way to `b`, weight by weight.
pub(super) fn blend(a: &Weights, b: &Weights, w: f32) -> Weights {
    (a.iter().zip(b))
        .map(|(a, b)| {
            (a.iter().zip(b))
                .map(|(a, b)| a.iter().zip(b).map(|(a, b)| a + (b - a) * w).collect())
                .collect()
        })
        .collect()
}
