//! Sequential Gauss-Seidel in grid order: the single-threaded reference every parallel solver is
//! compared with. Each particle is updated in place, so later rows see earlier rows' new values.

use super::row;
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use glam::Vec4;

/// One sweep over every particle in export (grid) order.
pub fn sweep(model: &Model, rhs: &[Vec4], diag_inv: &[f32], q: &mut [Vec4], omega: f32) {
    for &s in &model.storage_of {
        let i = s as usize;
        if diag_inv[i] == 0.0 {
            continue;
        }
        let new = row(model, i, rhs[i], diag_inv[i], |j| q[j]);
        q[i] = over_relax(q[i], new, omega);
    }
}
