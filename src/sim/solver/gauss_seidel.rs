//! Sequential Gauss-Seidel in grid order: the single-threaded reference every parallel solver is
//! compared with. Each particle is updated in place, so later rows see earlier rows' new values.
//! One thread of the team sweeps; the others wait at the barrier.

use super::{Buffers, Solver};
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use crate::sim::team::Member;

/// One sweep over every particle in export (grid) order.
pub fn sweep(m: &Member, model: &Model, solver: &Solver, b: &Buffers, omega: f32) {
    if m.leads() {
        // SAFETY: only this thread touches the buffers during this stage.
        let (target, projection) = unsafe { (b.target.read_all(), b.projection.read_all()) };
        for &s in &model.storage_of {
            let i = s as usize;
            let read = |j: usize| unsafe { b.delta.get(j) };
            if let Some(new) = solver.row(model, i, target, projection, read) {
                unsafe { b.delta.set(i, over_relax(b.delta.get(i), new, omega)) };
            }
        }
    }
    m.sync();
}
