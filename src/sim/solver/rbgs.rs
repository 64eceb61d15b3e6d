//! Multi-colour (red-black) Gauss-Seidel: one stage per colour, each colour's particles shared out
//! among the team. No spring joins two particles of one colour (checked when the solver is built),
//! so a stage reads only particles it does not write, and its result depends neither on the order
//! nor on the number of threads: the same sweep as sequential Gauss-Seidel in colour order.
//!
//! A small model laid out in two domains ([`crate::sim::separator`]) is swept by two threads
//! without a barrier between its interior colours: the first thread takes every colour's low side,
//! the second its high side, then the first the separator's colours. The same colour order, so the
//! same numbers. On a team of exactly two ([`Two`]) the threads hand each sweep over point to
//! point instead of at barriers: the first waits only for the high side before the separator,
//! the second only for the separator before what reads it, and meanwhile projects its springs
//! that do not reach it; on larger teams, two barriers a sweep.

use super::{project_springs, Buffers, Owned, Solver};
use crate::sim::constraint::over_relax;
use crate::sim::model::{Domains, Model};
use crate::sim::team::Member;
use std::ops::Range;

/// One sweep: every colour in turn.
pub fn sweep(m: &Member, model: &Model, solver: &Solver, b: &Buffers, omega: f32) {
    if let Some(domains) = model.domains.as_ref().filter(|_| m.count > 1) {
        return sweep_domains(m, model, domains, solver, b, omega);
    }
    for range in &model.colour_ranges {
        // SAFETY: `i` is this thread's alone in this stage; the neighbours read have other
        // colours, which no thread writes during this stage.
        unsafe { update(model, solver, b, omega, m.share(range.clone())) };
        m.sync();
    }
}

/// One sweep of a model in two domains: thread 0 the low side of every interior colour, thread 1
/// the high side, then thread 0 the separator's colours (other threads wait).
fn sweep_domains(
    m: &Member,
    model: &Model,
    domains: &Domains,
    solver: &Solver,
    b: &Buffers,
    omega: f32,
) {
    let ranges = &model.colour_ranges;
    if m.index < 2 {
        for range in domains.side(ranges, m.index) {
            // SAFETY: a side's particles have springs only to their own side and to the
            // separator (Model::validate), which no thread writes in this stage; within the side
            // this thread goes colour by colour, as the team would.
            unsafe { update(model, solver, b, omega, range.clone()) };
        }
    }
    m.sync();
    if m.leads() {
        for range in domains.separator(ranges) {
            // SAFETY: only this thread writes during this stage.
            unsafe { update(model, solver, b, omega, range.clone()) };
        }
    }
    m.sync();
}

/// Red-black Gauss-Seidel's iterations of a model in two domains on a team of two threads,
/// handed over point to point ([`Member::hand_off`]): the same projections and sweeps in the
/// same order as the team's ([`Solver::iterate`] with [`sweep_domains`]), so the same numbers.
/// Per sweep, thread 0 sweeps the low side, waits for thread 1's high side, sweeps the separator
/// and hands off; thread 1 waits for the separator of the sweep before (which its next rows and
/// the springs that reach the separator read), sweeps the high side and hands off. Thread 1
/// projects its springs within the high side before that wait, while thread 0 still sweeps the
/// separator: that sweep reads none of them.
pub(super) struct Two<'a> {
    pub(super) domains: &'a Domains,
    pub(super) solver: &'a Solver,
    pub(super) owned: &'a Owned,
}

impl Two<'_> {
    /// Runs `iterations` outer iterations on `b.delta`, then waits for the team (the stage's
    /// end); `observe` as in [`Solver::iterate`].
    pub(super) fn iterate(
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

/// Updates the rows of `particles`, all of one colour, in place.
///
/// # Safety
/// No other thread may write `particles` or any particle they read, nor read `particles`,
/// while this runs.
#[inline(always)]
unsafe fn update(model: &Model, solver: &Solver, b: &Buffers, omega: f32, particles: Range<usize>) {
    // SAFETY: target and projection are not written during a sweep.
    let (target, projection) = unsafe { (b.target.read_all(), b.projection.read_all()) };
    for i in particles {
        let read = |j: usize| unsafe { b.delta.get(j) };
        if let Some(new) = solver.row(model, i, target, projection, read) {
            unsafe { b.delta.set(i, over_relax(b.delta.get(i), new, omega)) };
        }
    }
}
