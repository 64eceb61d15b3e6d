//! Multi-colour (red-black) Gauss-Seidel: one pass per colour, each colour's particles updated in
//! parallel. No spring joins two particles of one colour (checked when the solver is built), so a
//! pass reads only particles it does not write, and its result does not depend on the order or the
//! number of threads: the same sweep as sequential Gauss-Seidel in colour order.

use super::{row, PARALLEL_CHUNK};
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use glam::Vec4;
use rayon::prelude::*;

/// Positions shared by the tasks of one colour pass.
#[derive(Clone, Copy)]
struct SharedPositions(*mut Vec4);
// SAFETY: see `sweep`: within one pass every index is written by exactly one task and the
// indices written are never read by another task.
unsafe impl Send for SharedPositions {}
unsafe impl Sync for SharedPositions {}

/// One sweep: every colour in turn.
pub fn sweep(model: &Model, rhs: &[Vec4], diag_inv: &[f32], q: &mut [Vec4], omega: f32) {
    assert_eq!(q.len(), model.particle_count());
    let shared = SharedPositions(q.as_mut_ptr());
    for range in &model.colour_ranges {
        range
            .clone()
            .into_par_iter()
            .with_min_len(PARALLEL_CHUNK)
            .for_each(move |i| {
                let p = shared;
                if diag_inv[i] == 0.0 {
                    return;
                }
                // SAFETY: `i` lies in this colour's range and is written by this task alone; the
                // neighbours read have other colours (Solver::new checked the colouring), so no task
                // writes them during this pass. All indices are below q.len() (model invariant).
                unsafe {
                    let new = row(model, i, rhs[i], diag_inv[i], |j| *p.0.add(j));
                    let qi = p.0.add(i);
                    *qi = over_relax(*qi, new, omega);
                }
            });
    }
}
