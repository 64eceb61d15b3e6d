//! Jacobi: every particle from the previous iterate, a gather per particle with no atomics.
//! Trivially parallel, but information travels one neighbour per sweep in both directions at half
//! Gauss-Seidel's rate, so it needs more iterations for the same residual.

use super::{row, PARALLEL_CHUNK};
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use glam::Vec4;
use rayon::prelude::*;

/// One sweep: new positions into `scratch`, then copied back into `q`.
pub fn sweep(
    model: &Model,
    rhs: &[Vec4],
    diag_inv: &[f32],
    q: &mut [Vec4],
    scratch: &mut [Vec4],
    omega: f32,
) {
    let old: &[Vec4] = q;
    scratch
        .par_iter_mut()
        .with_min_len(PARALLEL_CHUNK)
        .enumerate()
        .for_each(|(i, out)| {
            *out = if diag_inv[i] == 0.0 {
                old[i]
            } else {
                over_relax(
                    old[i],
                    row(model, i, rhs[i], diag_inv[i], |j| old[j]),
                    omega,
                )
            };
        });
    q.copy_from_slice(scratch);
}
