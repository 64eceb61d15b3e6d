//! Multi-colour (red-black) Gauss-Seidel: one stage per colour, each colour's particles shared out
//! among the team. No spring joins two particles of one colour (checked when the solver is built),
//! so a stage reads only particles it does not write, and its result depends neither on the order
//! nor on the number of threads: the same sweep as sequential Gauss-Seidel in colour order.
//!
//! A small model laid out in two domains ([`crate::sim::separator`]) is swept by two threads
//! without a barrier between its interior colours: the first thread takes every colour's low side,
//! the second its high side, then the first the separator's colours. The same colour order, so the
//! same numbers, with two barriers a sweep instead of one a colour. A team of exactly two hands
//! those sweeps over point to point instead ([`super::two`]). A larger model on a team that has
//! prepared for it ([`super::Solver::prepare_for`]) hands its colours over at their seams
//! instead of at barriers (`super::seams`): the same sweep, and this one is the reference.

use super::{Buffers, Solver};
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

/// Updates the rows of `particles`, all of one colour, in place.
///
/// # Safety
/// No other thread may write `particles` or any particle they read, nor read `particles`,
/// while this runs.
#[inline(always)]
pub(super) unsafe fn update(
    model: &Model,
    solver: &Solver,
    b: &Buffers,
    omega: f32,
    particles: Range<usize>,
) {
    // SAFETY: target and projection are not written during a sweep.
    let (target, projection) = unsafe { (b.target.read_all(), b.projection.read_all()) };
    for i in particles {
        let read = |j: usize| unsafe { b.delta.get(j) };
        if let Some(new) = solver.row(model, i, target, projection, read) {
            unsafe { b.delta.set(i, over_relax(b.delta.get(i), new, omega)) };
        }
    }
}
