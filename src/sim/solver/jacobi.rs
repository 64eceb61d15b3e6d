//! Jacobi: every particle from the previous iterate, a gather per particle with no atomics.
//! Trivially parallel, but a correction travels one neighbour per sweep where Gauss-Seidel carries
//! it along the sweep, so it needs more iterations for the same residual.

use super::{Buffers, Solver};
use crate::sim::constraint::over_relax;
use crate::sim::model::Model;
use crate::sim::team::Member;

/// One sweep: new displacements into `scratch`, then copied back into Δ.
#[inline(never)] // a reference method: its code stays out of red-black Gauss-Seidel's loop
pub fn sweep(m: &Member, model: &Model, solver: &Solver, b: &Buffers, omega: f32) {
    // SAFETY: this stage reads Δ, target and projection and writes only scratch, each index
    // by one thread.
    let mine = model.particles_of(m.index, m.count);
    {
        let (q, target, projection) = unsafe {
            (
                b.delta.read_all(),
                b.target.read_all(),
                b.projection.read_all(),
            )
        };
        for i in mine.clone() {
            let new = match solver.row(model, i, target, projection, |j| q[j]) {
                Some(new) => over_relax(q[i], new, omega),
                None => q[i],
            };
            unsafe { b.scratch.set(i, new) };
        }
    }
    m.sync();
    for i in mine {
        // SAFETY: each index copied by its own thread; nobody reads Δ in this stage.
        unsafe { b.delta.set(i, b.scratch.get(i)) };
    }
    m.sync();
}
