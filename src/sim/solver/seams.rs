//! Red-black Gauss-Seidel's colours handed over at their seams instead of at barriers.
//!
//! A team sweeps a colour at a time, each thread its contiguous share of the colour (grid order).
//! With a barrier after every colour, each colour costs the slower thread's share: shares whose
//! cost differs by a few per cent (pinned particles cost nothing, a garment's edge has fewer
//! springs, a busy machine's cores run unevenly) make the other thread wait at every one of
//! them. Measured on two threads (Intel Xeon, `docs/benchmarks.md`, stop 69), each thread waited
//! at the barriers 45 000–53 000 cycles a sweep of `poncho_walk`'s 3 012 particles, against
//! 101 000–105 000 of work, and 35 000–73 000 against 76 000–94 000 on `top_walk`'s.
//!
//! But only a share's *seam*, its particles with a spring to another thread's share, reads
//! (or is read by) another thread. So each thread sweeps the rest of its share of a colour
//! first, then waits only for the threads its seam has springs to to have finished the colour
//! before, sweeps the seam and hands the colour off ([`Member::hand_off`]). The local step
//! likewise waits only for those threads to finish the sweep before it and hands off when
//! done. Every row still reads the colours before its own new and the ones after it old, and
//! the projections of this iteration, as between barriers: the same numbers on any team. A
//! thread waits only where its work, summed over the colours so far, runs ahead of the
//! other's by more than a share's inside, not at each colour; one barrier ends the stage.
//! `poncho_walk`'s waits fell to 8 000–16 000 cycles an iteration of 144 000.
//!
//! Why the values are the barrier sweep's. A seam row of colour k reads another thread's
//! particles of earlier colours once that thread has handed off colour k − 1, so they are
//! final; it reads another thread's particles of later colours before that thread writes them,
//! since the writer's seam (where they lie, springs being symmetric) waits for this thread to
//! hand off colour k first (or, for the next sweep's colours, the whole sweep). A row inside
//! its share reads only its own thread's particles, and only springs its own thread projects
//! (every spring goes to the thread that sweeps its lower-colour end, [`super::Owned`]: both
//! ends are its own). A local step reads the ends of its springs and rewrites projections
//! other threads' seams read, so it waits for those threads to finish the sweep before, and
//! their first seam waits for its hand-off.

use super::rbgs::update;
use super::{project_springs, Buffers, Solver};
use crate::sim::model::Model;
use crate::sim::team::{share_of, Member};
use std::ops::Range;

/// Where each thread's share of each colour splits into its inside and its seam, and whom each
/// seam waits for.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Seams {
    /// Per thread, per colour (thread-major).
    shares: Vec<Share>,
    colours: usize,
    /// Per thread, the other threads it shares a spring with, ascending: those its local step
    /// waits for.
    neighbours: Vec<Vec<u32>>,
}

/// One thread's share of one colour.
#[derive(Clone, Debug, Default, PartialEq)]
struct Share {
    /// The longest run of the share whose particles have no spring to another thread's share
    /// (swept first, waiting for nobody).
    inside: Range<usize>,
    /// The rest of the share, before and after it (swept once `waits` handed off the colour
    /// before).
    seam: [Range<usize>; 2],
    /// The other threads that own a particle the seam has a spring to, ascending.
    waits: Vec<u32>,
}

impl Seams {
    /// The plan for a team of `threads` sweeping `model` a colour at a time, each thread its
    /// [`Member::share`] of every colour range.
    pub(super) fn new(model: &Model, threads: usize) -> Seams {
        let ranges = &model.colour_ranges;
        // The thread whose share of its colour holds each particle.
        let mut owner = vec![0u32; model.particle_count()];
        for r in ranges {
            for t in 0..threads {
                owner[share(r, t, threads)].fill(t as u32);
            }
        }
        let mut shares = Vec::with_capacity(threads * ranges.len());
        for t in 0..threads {
            for r in ranges {
                let mine = share(r, t, threads);
                let others = |p: usize| {
                    (model.slots(p).iter())
                        .map(|s| owner[s.neighbour as usize])
                        .filter(|&o| o != t as u32)
                };
                // The longest run of particles with no spring to another thread.
                let (mut inside, mut run) = (mine.start..mine.start, mine.start);
                for p in mine.clone() {
                    if others(p).next().is_some() {
                        run = p + 1;
                    } else if p + 1 - run > inside.len() {
                        inside = run..p + 1;
                    }
                }
                let seam = [mine.start..inside.start, inside.end..mine.end];
                let mut waits: Vec<u32> = seam
                    .iter()
                    .flat_map(|s| s.clone().flat_map(others))
                    .collect();
                waits.sort_unstable();
                waits.dedup();
                shares.push(Share {
                    inside,
                    seam,
                    waits,
                });
            }
        }
        let colours = ranges.len();
        let neighbours = (0..threads)
            .map(|t| {
                let mut all: Vec<u32> = (shares[t * colours..(t + 1) * colours].iter())
                    .flat_map(|s| s.waits.iter().copied())
                    .collect();
                all.sort_unstable();
                all.dedup();
                all
            })
            .collect();
        Seams {
            shares,
            colours,
            neighbours,
        }
    }

    /// `iterations` outer iterations of `m`'s thread ([`Solver::iterate`]'s, the same numbers),
    /// handed over at the seams with one barrier at the end (the stage's). Each local step
    /// waits for the threads whose particles its springs reach to finish the sweep before (it
    /// reads their last values and rewrites projections their seams read), then hands off; each
    /// colour's seam waits for the threads it reads to hand off the colour before, or the
    /// local step before the first colour (a first colour rewrites what the others' local steps
    /// read, and reads what their last colours wrote).
    pub(super) fn iterate(
        &self,
        m: &Member,
        model: &Model,
        solver: &Solver,
        b: &Buffers,
        observe: &(dyn Fn(&Member) + Sync),
        iterations: u32,
    ) {
        // The springs this thread projects: the solver's, which holds this plan.
        let owned = solver
            .owned
            .as_ref()
            .expect("seams come with the owned springs");
        let (springs, index) = owned.of(m.index);
        let omega = solver.settings.omega;
        let mine = &self.shares[m.index * self.colours..(m.index + 1) * self.colours];
        // Every thread hands off as many times an iteration: the same count at the same point.
        for _ in 0..iterations {
            let start = m.handoffs();
            for &other in &self.neighbours[m.index] {
                m.wait_for(other as usize, start);
            }
            project_springs(b, springs, |k| index[k] as usize);
            m.hand_off();
            for _ in 0..solver.settings.inner_iterations {
                let start = m.handoffs();
                for (k, share) in mine.iter().enumerate() {
                    // SAFETY: no other thread writes or reads this share's inside (none has a
                    // spring to it), and the particles and springs it reads are this thread's
                    // (module docs).
                    unsafe { update(model, solver, b, omega, share.inside.clone()) };
                    for &other in &share.waits {
                        m.wait_for(other as usize, start + k as u64);
                    }
                    for seam in &share.seam {
                        // SAFETY: every thread this seam reads, or that reads it, has handed
                        // off the colour (or local step) before, and writes no colour after
                        // it before this thread hands off (module docs).
                        unsafe { update(model, solver, b, omega, seam.clone()) };
                    }
                    m.hand_off();
                }
                observe(m);
            }
        }
        m.sync();
    }
}

/// Thread `t`'s share of `range` on a team of `threads`, as [`Member::share`] cuts it.
fn share(range: &Range<usize>, t: usize, threads: usize) -> Range<usize> {
    share_of(range.clone(), t, threads)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::test_sheet;

    /// Each share splits into an inside with no spring to another thread's share and a seam
    /// that waits for every thread it has a spring to; the pieces cover the share; a share
    /// far larger than the stencil is mostly inside.
    #[test]
    fn a_share_s_inside_touches_no_other_thread_and_its_seam_waits_for_every_one_it_does() {
        let garment = test_sheet([70, 66], r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#);
        let model = Model::new(std::slice::from_ref(&garment));
        assert!(model.domains.is_none(), "a model in one domain");
        for threads in 2..=5 {
            let seams = Seams::new(&model, threads);
            let owner = |p: usize| {
                (0..threads)
                    .find(|&t| {
                        (model.colour_ranges.iter()).any(|r| share(r, t, threads).contains(&p))
                    })
                    .expect("an owner")
            };
            for t in 0..threads {
                for (k, r) in model.colour_ranges.iter().enumerate() {
                    let s = &seams.shares[t * seams.colours + k];
                    let mine = share(r, t, threads);
                    assert_eq!(s.seam[0].start, mine.start);
                    assert_eq!(
                        (s.seam[0].end, s.inside.end),
                        (s.inside.start, s.seam[1].start)
                    );
                    assert_eq!(s.seam[1].end, mine.end);
                    for p in s.inside.clone() {
                        assert!(model
                            .slots(p)
                            .iter()
                            .all(|n| owner(n.neighbour as usize) == t));
                    }
                    for p in s.seam.iter().flat_map(|s| s.clone()) {
                        for n in model.slots(p) {
                            let o = owner(n.neighbour as usize);
                            assert!(o == t || s.waits.contains(&(o as u32)), "{threads}: {p}");
                        }
                    }
                    assert!(!s.waits.contains(&(t as u32)));
                    assert!(
                        2 * s.inside.len() > mine.len(),
                        "{threads} threads, colour {k}"
                    );
                }
            }
        }
    }
}
