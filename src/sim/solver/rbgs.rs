//! Multi-colour (red-black) Gauss-Seidel: one stage per colour, each colour's particles shared out
//! among the team. No spring joins two particles of one colour (checked when the solver is built),
//! so a stage reads only particles it does not write, and its result depends neither on the order
//! nor on the number of threads: the same sweep as sequential Gauss-Seidel in colour order.

use super::{Buffers, Solver};
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use crate::sim::team::Member;

/// One sweep: every colour in turn.
pub fn sweep(m: &Member, model: &Model, solver: &Solver, b: &Buffers, omega: f32) {
    // SAFETY: target and projection are not written during a sweep.
    let (target, projection) = unsafe { (b.target.read_all(), b.projection.read_all()) };
    for range in &model.colour_ranges {
        for i in m.share(range.clone()) {
            // SAFETY: `i` is this thread's alone in this stage; the neighbours read have other
            // colours, which no thread writes during this stage.
            let read = |j: usize| unsafe { b.delta.get(j) };
            if let Some(new) = solver.row(model, i, target, projection, read) {
                unsafe { b.delta.set(i, over_relax(b.delta.get(i), new, omega)) };
            }
        }
        m.sync();
    }
}
