//! Red-black Gauss-Seidel of a small model in two domains ([`crate::sim::separator`]) on a team
//! of exactly two threads, handed over point to point instead of at barriers: the first thread
//! waits only for the high side before the separator, the second only for the separator before
//! what reads it, and meanwhile projects its springs that do not reach it. The same projections
//! and sweeps in the same order as [`super::rbgs`]'s sweep in two domains, so the same numbers.

use super::rbgs::update;
use super::{project_springs, Buffers, Owned, Solver};
use crate::sim::model::{Domains, Model};
use crate::sim::team::Member;

/// Red-black Gauss-Seidel's iterations of a model in two domains on a team of two threads,
/// handed over point to point ([`Member::hand_off`]): the same projections and sweeps in the
/// same order as the team's ([`Solver::iterate`] with `rbgs`'s sweep in two domains), so the
/// same numbers. Per sweep, thread 0 sweeps the low side, waits for thread 1's high side, sweeps the separator
/// and hands off; thread 1 waits for the separator of the sweep before (which its next rows and
/// the springs that reach the separator read), sweeps the high side and hands off. Thread 1
/// projects its springs within the high side before that wait, while thread 0 still sweeps the
/// separator: that sweep reads none of them.
pub(crate) struct Two<'a> {
    pub(super) domains: &'a Domains,
    pub(super) solver: &'a Solver,
    pub(super) owned: &'a Owned,
}

impl Two<'_> {
    /// Runs `iterations` outer iterations on `b.delta`, then waits for the team (the stage's
    /// end); `observe` as in [`Solver::iterate`].
    #[inline(never)]
    pub(crate) fn iterate(
        &self,
        m: &Member,
        model: &Model,
        b: &Buffers,
        observe: &(dyn Fn(&Member) + Sync),
        iterations: u32,
    ) {
        let (settings, ranges) = (&self.solver.settings, &model.colour_ranges);
        let omega = settings.omega;
        let (springs, index) = self.owned.of(m.index);
        let clear = if m.index == 1 {
            self.owned.clear_of_separator
        } else {
            springs.len()
        };
        for _ in 0..iterations {
            project_springs(b, &springs[..clear], |k| index[k] as usize);
            if m.index == 1 {
                m.wait_for(0, m.handoffs());
                project_springs(b, &springs[clear..], |k| index[clear + k] as usize);
            }
            for inner in 0..settings.inner_iterations {
                if m.index == 1 && inner > 0 {
                    m.wait_for(0, m.handoffs());
                }
                for range in self.domains.side(ranges, m.index) {
                    // SAFETY: a side's particles have springs only to their own side and to the
                    // separator, which thread 0 does not write until this side is handed off;
                    // within the side this thread goes colour by colour, as the team would.
                    unsafe { update(model, self.solver, b, omega, range.clone()) };
                }
                if m.index == 0 {
                    m.wait_for(1, m.handoffs() + 1);
                    for range in self.domains.separator(ranges) {
                        // SAFETY: both sides of this sweep are handed off, and thread 1 writes
                        // nothing the separator reads until it is.
                        unsafe { update(model, self.solver, b, omega, range.clone()) };
                    }
                }
                m.hand_off();
                observe(m);
            }
        }
        m.sync();
    }
}
