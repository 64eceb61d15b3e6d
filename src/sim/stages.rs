//! The per-particle work of a substep's stages (prediction, collision passes, particle
//! collisions, `finish`), with what each reads and writes: the team runs them in the order
//! [`super::schedule::substep`] lists, each particle's on one thread.

use super::integrate::Verlet;
use super::team::{Member, Shared};
use super::{constraint, solver, Model};
use crate::collide::particles::{
    lists_from_pairs_from, Finding, Grid, List, ListState, Near, ParticleCollisions,
};
use crate::collide::{Collider, ShellCollider};
use glam::Vec4;
use std::sync::RwLock;

/// How much nearer than its gap less the reach a particle must stay for a collision pass to
/// leave its shell test out [m]: a micrometre, far above the rounding of the distances (positions
/// of a few metres round to 10⁻⁷ m), far below anything a contact resolves.
const GAP_SLACK: f32 = 1e-6;

/// True when the focus holds for a garment particle at `p` moving at `v` before a substep of
/// `h` seconds under gravity `g`: it is within what its `origin` allows it (its place and
/// allowance when the focus was made), less twice its own motion in a substep and twice the
/// shells' fastest (`carried`).
#[inline]
pub(super) fn focus_holds_for(
    p: Vec4,
    v: Vec4,
    (origin, allowed): (Vec4, f32),
    (h, g, carried): (f32, f32, f32),
) -> bool {
    let within = 2.0 * (v.length() * h + g * h * h + carried);
    p.distance(origin) + within <= allowed
}

/// The focus's check for the next substep ([`super::drivers::Drivers::focus_shells`]), made by
/// `finish` as it commits each particle: `outran` is set when a particle is not within its
/// origin's allowance.
pub(super) struct FocusCheck<'a> {
    pub(super) origins: &'a [(Vec4, f32)],
    /// The substep, gravity and the shells' fastest motion in it.
    pub(super) terms: (f32, f32, f32),
    pub(super) outran: &'a std::sync::atomic::AtomicBool,
}

impl FocusCheck<'_> {
    #[inline]
    fn check(&self, i: usize, p: Vec4, v: Vec4) {
        if !focus_holds_for(p, v, self.origins[i], self.terms) {
            self.outran
                .store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// A patched substep's movers ([`crate::collide::particles::Patch`]).
pub(super) struct Movers<'a> {
    /// 1 for a particle that has moved too far for the lists (written by its thread when the
    /// lists are checked, read by all after).
    pub(super) moving: Shared<u8>,
    /// How many particles are movers in this substep (the lists are stale when it is not zero).
    pub(super) count: &'a std::sync::atomic::AtomicU32,
    /// Set by a mover's thread on each particle the mover touches; cleared by the particle's.
    pub(super) touched: &'a [std::sync::atomic::AtomicBool],
    /// The movers, ascending (made by the leader).
    pub(super) list: &'a RwLock<Vec<u32>>,
}

/// The per-particle stages of a substep, with what they read and write.
pub(super) struct Stages<'a> {
    pub(super) model: &'a Model,
    pub(super) verlet: Option<&'a Verlet>,
    pub(super) colliders: &'a [Collider],
    pub(super) shells: &'a [ShellCollider],
    pub(super) b: solver::Buffers,
    pub(super) velocities: Shared<Vec4>,
    /// Particle–particle pushes of this substep, when those collisions are on.
    pub(super) pushes: Option<Shared<Vec4>>,
    /// Their hash grid, as the neighbour lists were made in it.
    pub(super) grid: &'a RwLock<Grid>,
    /// Each particle's neighbour list, and where it was when the lists were made.
    pub(super) lists: Shared<List>,
    pub(super) anchors: Shared<Vec4>,
    /// The pairs a remake finds, each once, to make the lists from (every thread adds those
    /// it found, then reads them all; the leader empties it at the stage's end).
    pub(super) pairs: &'a RwLock<Vec<(u32, u32)>>,
    /// The slots of the lists' grid, 0..particles (the order a remake shares out).
    pub(super) slots: &'a [u32],
    /// How the substeps have been finding the pairs (written by the leader after the stage).
    pub(super) list_state: &'a std::sync::Mutex<ListState>,
    /// Whether they may keep lists (else every substep finds its pairs directly), and how many
    /// substeps reused lists.
    pub(super) particle_lists: bool,
    pub(super) lists_reused: &'a std::sync::atomic::AtomicU64,
    /// The particles that moved too far for the lists, for a patched substep.
    pub(super) movers: Movers<'a>,
    /// Nearby shell particles of each garment particle, per shell (empty with one pass).
    pub(super) nearby: Shared<crate::collide::shell::Nearby>,
    /// How many entries each nearby list holds.
    pub(super) listed: Shared<u8>,
    /// Each list's gap ([`super::workspace::Workspace`]'s `listed_gap`).
    pub(super) listed_gap: Shared<f32>,
    /// Each particle's clearance from the quiet colliders (with collision passes).
    pub(super) clearance: Shared<f32>,
    /// Each particle's slack in the substep's later collision passes, and its lists
    /// ([`Stages::contact_pass`]).
    pub(super) pass_slack: Shared<(f32, u8)>,
    /// Whether later passes use it, and how many particles they left out by it.
    pub(super) slack_skips: bool,
    pub(super) left_out: &'a std::sync::atomic::AtomicU64,
    /// Which colliders are quiet ([`Collider::is_quiet`]), and whether all are.
    pub(super) quiet: &'a [bool],
    pub(super) all_quiet: bool,
    /// Each particle's acceleration by the force fields (empty without).
    pub(super) external: &'a [Vec4],
    /// Where the next substep ends (fractional frame), when `finish` places the shells for it
    /// ahead ([`ShellCollider::place_ahead`]); and the largest contact radius they are gridded
    /// for.
    pub(super) place_ahead: Option<f32>,
    /// Time the leader spent placing them [ns] (moved from `finish` to `shells` in the stage
    /// times: see [`super::Simulation`]'s `run_substeps`).
    pub(super) placing_ns: &'a std::sync::atomic::AtomicU64,
    pub(super) contact_reach: f32,
    /// Whether the shells' focus holds for the next substep, checked per particle.
    pub(super) focus_check: Option<FocusCheck<'a>>,
}

impl Stages<'_> {
    /// Particle–particle collisions at q = x + Δ, the pairs found as [`ListState`] says: from
    /// the neighbour lists while no particle has moved too far from where they were made
    /// ([`ParticleCollisions::lists_stale`]); from them while the particles that have (the
    /// movers) are few, the movers searching the lists' grid and marking the particles they
    /// touch ([`Finding::Patch`]); else one thread sorts q into the grid and every thread makes
    /// its particles' lists again, or finds their pairs in the grid directly. Every thread then
    /// computes its particles' pushes (added by `finish`).
    pub(super) fn particle_collisions(&self, m: &Member, pc: &ParticleCollisions) {
        use std::sync::atomic::Ordering::Relaxed;
        let (model, b, grid) = (self.model, &self.b, self.grid);
        // SAFETY: between two syncs nobody writes x or Δ.
        let (x, d) = unsafe { (b.x.read_all(), b.delta.read_all()) };
        let q = |i: usize| x[i] + d[i];
        let (lists, anchors, movers) = (&self.lists, &self.anchors, &self.movers);
        let state = *self.list_state.lock().expect("not poisoned");
        // SAFETY (here and below): each particle's list, anchor and mover flag are written by
        // its own thread only, and the flags read by others after a sync.
        if state.valid {
            let mut moved = 0;
            for i in model.particles_of(m.index, m.count) {
                let far = unsafe { q(i).truncate().distance(anchors.get(i).truncate()) };
                let far = pc.lists_stale(far);
                unsafe { movers.moving.set(i, far as u8) };
                moved += far as u32;
            }
            if moved > 0 {
                movers.count.fetch_add(moved, Relaxed);
            }
            m.sync();
        }
        // Stale: some particle moved too far (or by NaN) for the lists.
        let moved = movers.count.load(Relaxed);
        let stale = moved > 0;
        let finding = match self.particle_lists {
            true => state.finding(stale, moved, model.particle_count()),
            false => Finding::Direct,
        };
        let moving = |j: usize| unsafe { movers.moving.get(j) } != 0;
        match finding {
            Finding::Reuse => {}
            Finding::Patch => {
                if m.leads() {
                    let mut list = movers.list.write().expect("not poisoned");
                    list.clear();
                    let all = 0..model.particle_count() as u32;
                    list.extend(all.filter(|&i| moving(i as usize)));
                }
                let g = grid.read().expect("not poisoned");
                for i in model.particles_of(m.index, m.count).filter(|&i| moving(i)) {
                    pc.touched_by_mover(i, q, &moving, &g, |j| {
                        movers.touched[j].store(true, Relaxed)
                    });
                }
                drop(g);
                m.sync();
            }
            Finding::Remake | Finding::Direct => {
                if m.leads() {
                    let remake = finding == Finding::Remake;
                    pc.build(q, &mut grid.write().expect("not poisoned"), remake);
                }
                m.sync();
            }
        }
        if finding == Finding::Remake {
            self.remake_lists(m, pc, &q);
        }
        let g = grid.read().expect("not poisoned");
        let mover_list = movers.list.read().expect("not poisoned");
        let patch = crate::collide::particles::Patch {
            moving: &moving,
            movers: &mover_list,
        };
        let pushes = self.pushes.expect("particle collisions have pushes");
        // Shared by what it costs (`Member::balanced`): a particle's pushes cost as many
        // neighbours as it has, and the folds are where they are.
        m.balanced(&model.work_order, |i| unsafe {
            let list = lists.get_ref(i);
            let near = match finding {
                Finding::Direct => Near::Grid,
                Finding::Patch if movers.touched[i].swap(false, Relaxed) || moving(i) => {
                    Near::Patched(list, anchors.get(i), patch)
                }
                _ => Near::List(list, anchors.get(i)),
            };
            pushes.set(i, pc.push_out(i, near, (|k| x[k], q), &model.inv_mass, &g));
        });
        drop((g, mover_list));
        m.sync();
        // Every thread has read the state and the movers' count; none reads them again before
        // the next substep's stage, after `finish`'s sync.
        if m.leads() && self.particle_lists {
            if finding == Finding::Remake {
                self.pairs.write().expect("not poisoned").clear();
            }
            *self.list_state.lock().expect("not poisoned") = state.after(finding, stale);
            movers.count.store(0, Relaxed);
            if matches!(finding, Finding::Reuse | Finding::Patch) {
                self.lists_reused.fetch_add(1, Relaxed);
            }
        }
    }

    /// Makes the neighbour lists again at `q` from the lists' grid, just built there: every
    /// thread anchors particles and finds their pairs, each pair once (a pinned particle too:
    /// it is never pushed, but others' lists hold it), slot by slot of the grid, shared by what
    /// it costs ([`Member::balanced`]: a fold's particles have more candidates than a flat
    /// stretch's); then every thread fills its own stretch of the lists from all the pairs.
    fn remake_lists(&self, m: &Member, pc: &ParticleCollisions, q: &impl Fn(usize) -> Vec4) {
        let g = self.grid.read().expect("not poisoned");
        let mut found = Vec::new();
        m.balanced(self.slots, |k| {
            let i = g.items[k] as usize;
            // SAFETY: each particle's anchor is written by one thread here, and read by others
            // only after the syncs below.
            unsafe { self.anchors.set(i, q(i)) };
            pc.forward_pairs(k, &g, &mut found);
        });
        drop(g);
        if !found.is_empty() {
            self.pairs.write().expect("not poisoned").extend(found);
        }
        m.sync();
        let pairs = self.pairs.read().expect("not poisoned");
        let mine = m.share(0..self.lists.len());
        // SAFETY: each thread writes only its own stretch of the lists, which no thread reads
        // before the sync below.
        let lists = unsafe { self.lists.write_range(mine.clone()) };
        lists.fill(List::EMPTY);
        lists_from_pairs_from(&pairs, mine.start, lists);
        drop(pairs);
        m.sync();
    }

    /// This thread's particles the simulation moves (pinned and attached ones are never
    /// written, so other threads may read them in any stage).
    fn free_particles<'m>(&'m self, m: &'m Member) -> impl Iterator<Item = usize> + 'm {
        self.model
            .particles_of(m.index, m.count)
            .filter(|&i| self.model.inv_mass[i] != 0.0)
    }

    /// Predicts this thread's free particles: Δ and t become the inertial displacement (zero
    /// without integration). Pinned particles keep Δ = t = 0 from the start and are never written,
    /// so other threads may read them in any stage.
    pub(super) fn predict(&self, m: &Member) {
        for i in self.free_particles(m) {
            // SAFETY: a free particle is read and written by its own thread only.
            unsafe { self.predict_one(i) };
        }
    }

    /// # Safety
    /// `i` is a free particle of the calling thread.
    #[inline(always)]
    unsafe fn predict_one(&self, i: usize) {
        let t = match self.verlet {
            Some(v) if !self.external.is_empty() => {
                v.inertial_displacement(self.velocities.get(i))
                    + self.external[i] * (v.step * v.step)
            }
            Some(v) => v.inertial_displacement(self.velocities.get(i)),
            None => Vec4::ZERO,
        };
        self.b.delta.set(i, t);
        self.b.target.set(i, t);
    }

    /// A collision pass inside the solve, for the free particles (shared out by their cost,
    /// [`Member::balanced`]): collisions and friction on Δ as at the end of the substep, the
    /// characters' shells tested only against each particle's nearby shell particles.
    ///
    /// The quiet colliders (static, swept, with an exact distance: a floor) are skipped for a
    /// particle whose displacement is shorter than its clearance, the least of their distances
    /// from where it starts the substep less its contact radius (measured at the substep's
    /// first pass): exactly where `Collider::resolve` would return the displacement unchanged
    /// from its first test, at a tenth of the cost (P's floor cost 3.4 of its 40 ms per frame).
    pub(super) fn contact_pass(&self, m: &Member, first: bool) {
        let (model, b) = (self.model, &self.b);
        let particles = model.particle_count();
        let mut left_out = 0;
        m.balanced(&model.work_order, |i| {
            if model.inv_mass[i] == 0.0 {
                return;
            }
            // SAFETY: particle i is this thread's alone in this stage.
            unsafe {
                // Moved less than its slack since the substep's start (most of a garment, near
                // no shell and clear of the quiet colliders): every test below would be left out,
                // and each listed shell's gives its untouched result.
                if !first && self.all_quiet && self.slack_skips {
                    let (slack, lists) = self.pass_slack.get(i);
                    let mut d = b.delta.get(i);
                    if d.truncate().length() < slack {
                        if lists > 0 {
                            let x = b.x.get(i);
                            for _ in 0..lists {
                                d = ShellCollider::untouched(x, d);
                            }
                            b.delta.set(i, d);
                        }
                        left_out += 1;
                        return;
                    }
                }
                let x = b.x.get(i);
                let mut d = b.delta.get(i);
                let r = model.contact_radius[i];
                let clearance = if first {
                    let c = self.clearance_of(x, r);
                    self.clearance.set(i, c);
                    c
                } else {
                    self.clearance.get(i)
                };
                d = self.resolve_colliders(x, d, r, clearance);
                // The least slack of the colliders and listed shells, less a margin far above
                // the rounding of the comparisons it stands for (see `GAP_SLACK`).
                let mut slack = if self.colliders.is_empty() {
                    f32::INFINITY
                } else {
                    clearance
                };
                let mut lists = 0;
                for (k, s) in self.shells.iter().enumerate() {
                    let at = k * particles + i;
                    if self.listed.get(at) == 0 {
                        continue;
                    }
                    // The shell stands still within the substep: a particle nearer its start
                    // than its gap less the reach meets none of its listed shell particles (three
                    // in four passes on P), and the test is left out, with its result.
                    let gap = if first {
                        let g = s.nearest_listed(x, &self.nearby.get(at));
                        self.listed_gap.set(at, g);
                        g
                    } else {
                        self.listed_gap.get(at)
                    };
                    let clear = s.radius + r + GAP_SLACK;
                    slack = slack.min(gap - clear);
                    lists += 1;
                    d = if gap - d.truncate().length() > clear {
                        ShellCollider::untouched(x, d)
                    } else {
                        s.resolve_nearby(x, d, r, &self.nearby.get(at))
                    };
                }
                if first {
                    self.pass_slack.set(i, (slack - GAP_SLACK, lists));
                }
                b.delta.set(i, d);
            }
        });
        self.left_out
            .fetch_add(left_out, std::sync::atomic::Ordering::Relaxed);
    }

    /// Every collider's `resolve` in turn, skipping the quiet ones while the displacement is
    /// shorter than `clearance` (−∞: none skipped, and no length computed).
    #[inline]
    fn resolve_colliders(&self, x: Vec4, mut d: Vec4, r: f32, clearance: f32) -> Vec4 {
        if clearance == f32::NEG_INFINITY {
            for c in self.colliders {
                d = c.resolve(x, d, r);
            }
            return d;
        }
        let mut length = d.truncate().length();
        for (c, &quiet) in self.colliders.iter().zip(self.quiet) {
            if quiet && clearance >= length {
                continue;
            }
            d = c.resolve(x, d, r);
            length = d.truncate().length();
        }
        d
    }

    /// The displacement of a particle at `x` pressed between a shell and a collider of surface
    /// normal `n` ([`crate::collide::INTO_COLLIDER`]), from `before`, where the colliders left it:
    /// carried along the surface by the first shell (in the scene's order) in reach of it
    /// there, which with one character is the one that pushed. None in reach (a swept test
    /// stopped the path short of where the colliders left it): `before`, the collider's.
    fn pressed(&self, x: Vec4, before: Vec4, radius: f32, n: glam::Vec3) -> Vec4 {
        let p = (x + before).truncate();
        (self.shells.iter())
            .find_map(|s| {
                let (skin, squeeze) = s.pressing(p, radius)?;
                Some(crate::collide::pressed_motion(
                    before,
                    n,
                    (skin, squeeze, s.friction),
                ))
            })
            .unwrap_or(before)
    }

    /// The least distance of `x` from the quiet colliders less `radius` (−∞ without any).
    #[inline]
    fn clearance_of(&self, x: Vec4, radius: f32) -> f32 {
        let x = x.truncate();
        (self.colliders.iter().zip(self.quiet))
            .filter(|(_, &quiet)| quiet)
            .map(|(c, _)| c.distance(x).0 - radius)
            .reduce(f32::min)
            .unwrap_or(f32::NEG_INFINITY)
    }

    /// Ends the substep for the free particles (shared out by their cost, [`Member::balanced`]):
    /// long-range attachments to the pins, collisions, then x += Δ and v = Δ/h; and, when
    /// `predict_next`, the next prediction.
    pub(super) fn finish(&self, m: &Member, predict_next: bool) {
        let (model, b) = (self.model, &self.b);
        // Every thread places its part of the shells for the next substep first, and the leader
        // grids them once all are placed, while the others finish particles (see
        // `ShellCollider::place_ahead_part`).
        let place_ahead = || {
            let Some(to) = self.place_ahead else {
                return;
            };
            let start = std::time::Instant::now();
            for s in self.shells {
                s.place_ahead_part(to, self.contact_reach, m.index, m.count);
            }
            if m.leads() {
                for s in self.shells.iter().filter(|s| s.ahead_prepared()) {
                    m.wait_until(|| s.ahead_parts_placed() >= m.count);
                    s.finish_ahead(to, self.contact_reach);
                }
            }
            let took = start.elapsed().as_nanos() as u64;
            self.placing_ns
                .fetch_add(took, std::sync::atomic::Ordering::Relaxed);
        };
        m.balanced_after(&model.work_order, place_ahead, |i| {
            if model.inv_mass[i] == 0.0 {
                if let Some(c) = &self.focus_check {
                    // SAFETY: pinned and attached particles are never written in a stage.
                    unsafe { c.check(i, b.x.get(i), self.velocities.get(i)) };
                }
                return;
            }
            // SAFETY: particle i is this thread's alone in this stage; the pins read by the
            // tethers are never written.
            unsafe {
                let x = b.x.get(i);
                let mut d = b.delta.get(i);
                if let Some(p) = &self.pushes {
                    d += p.get(i);
                }
                let tethers = model.tether_start[i] as usize..model.tether_start[i + 1] as usize;
                for t in &model.tethers[tethers] {
                    let p = t.pin as usize;
                    let offset = (x - b.x.get(p)) + (d - b.target.get(p));
                    d += constraint::tether_correction(offset, t.rest);
                }
                let r = model.contact_radius[i];
                // The clearance the substep's first collision pass measured (−∞ without passes).
                let clearance = if self.clearance.is_empty() {
                    f32::NEG_INFINITY
                } else {
                    self.clearance.get(i)
                };
                d = self.resolve_colliders(x, d, r, clearance);
                let by_colliders = d;
                let particles = model.particle_count();
                for (k, s) in self.shells.iter().enumerate() {
                    // With collision passes, list the shell particles near i for the next ones.
                    let at = k * particles + i;
                    if self.nearby.is_empty()
                        || (self.listed.get(at) == 0 && s.out_of_reach(x, d, r))
                    {
                        // Without passes; or far from the shell with an empty list, which
                        // stays empty (untouched: most of P's lists, 265 KB a substep, are the
                        // stool's).
                        d = s.resolve(x, d, r, None);
                    } else {
                        let list = self.nearby.get_mut(at);
                        d = s.resolve(x, d, r, Some(&mut *list));
                        self.listed.set(at, crate::collide::shell::listed(list));
                    }
                }
                if !self.shells.is_empty() {
                    if let Some(n) =
                        crate::collide::pressed_into(self.colliders, x, by_colliders, d, r)
                    {
                        d = self.pressed(x, by_colliders, r, n);
                    }
                }
                b.x.set(i, x + d);
                if let Some(v) = self.verlet {
                    self.velocities.set(i, v.velocity(d));
                }
                if let Some(c) = &self.focus_check {
                    c.check(i, x + d, self.velocities.get(i));
                }
                if predict_next {
                    self.predict_one(i);
                }
            }
        });
    }
}
