//! Constraint solvers: Projective Dynamics (local/global, thesis algorithm 4) solved by sequential
//! Gauss-Seidel, Jacobi or multi-colour Gauss-Seidel, each with over-relaxation ω; and Position
//! Based Dynamics with Jacobi averaging (thesis algorithm 3) as the classic reference.
//!
//! Projective Dynamics minimises, over the positions q of one step of length h,
//!   Σ_i m_i/(2h²) |q_i − s_i|² + Σ_springs w/2 |q_a − q_b − d_ab|²,
//! with s the inertial prediction and d_ab the spring's projection onto its rest length. Each
//! *outer* iteration refreshes every d once per spring (the local step, [`project`]); each *inner*
//! iteration sweeps the linear global system once, a gather per particle:
//!   q_i ← (a_i s_i + Σ_k w_k (q_k ± d_k)) / (a_i + Σ_k w_k),  a_i = m_i / h².
//!
//! **Delta form.** The unknown is the displacement Δ = q − x over the step, not q itself. With 100
//! steps per frame a step moves a particle by about 10⁻⁴ m, which single precision resolves to
//! 10⁻¹¹ m as a displacement but only to 6·10⁻⁸ m as a position near 1 m: solving for positions
//! quantised the constraint forces to whole ulps and made energy drift. Substituting q = x + Δ,
//! the row becomes Δ_i ← (a_i t_i + Σ_k w_k (Δ_k ± g_k)) / (a_i + Σ_k w_k) with t_i = s_i − x_i and
//! g = d − (x_a − x_b): the same sweep, on small, precise numbers.
//!
//! Every stage runs on a [`team`](super::team): each thread takes its share of the indices, and
//! [`Member::sync`] ends the stage.

mod gauss_seidel;
mod jacobi;
mod pbd;
mod rbgs;
mod seams;
pub(crate) mod two;

use super::constraint::{spring_projection_scale, spring_row_solve};
use super::model::{Model, ModelSpring};
use super::team::{Member, Shared};
use crate::scene::{SolverKind, SolverSettings};
use glam::Vec4;

/// The arrays one solve reads and writes, shared by the team (storage order).
#[derive(Clone, Copy)]
pub struct Buffers {
    /// Positions at the start of the step, x (read-only during the solve).
    pub x: Shared<Vec4>,
    /// Displacements over the step being solved, Δ = q − x.
    pub delta: Shared<Vec4>,
    /// Inertial displacement t = s − x (the prediction's).
    pub target: Shared<Vec4>,
    /// Per spring, g = d − (x_a − x_b): its projection d relative to its start-of-step edge.
    pub projection: Shared<Vec4>,
    /// Second displacement buffer of the Jacobi-style solvers.
    pub scratch: Shared<Vec4>,
}

/// A solver with the per-particle system of one step size, built once per bake.
pub struct Solver {
    pub settings: SolverSettings,
    /// a_i = m_i / h² (0 without time integration or for pinned particles) [kg/s²].
    inertia: Vec<f32>,
    /// 1 / (a_i + Σ_k w_k), or 0 for particles that never move.
    diag_inv: Vec<f32>,
    /// Red-black Gauss-Seidel on a team: each thread's springs for a local step that needs no
    /// barrier of its own (see [`Owned`]); None until [`Solver::prepare_for`] makes them.
    owned: Option<Owned>,
}

/// Each thread's springs for the local step of red-black Gauss-Seidel: every spring goes to the
/// thread that sweeps its end of the lower colour. A thread then projects its springs and goes
/// straight on to sweep its particles of the first colour: every spring those particles read is
/// its own, and the springs it projects never touch a particle another thread sweeps in that
/// colour (their other ends have later colours). The barrier between the local step and the
/// first colour goes: one of the four stages per iteration of P, H or the blanket. The same
/// numbers as the shared local step: each spring's projection does not depend on who makes it.
/// A small model in two domains gives each thread the springs its side reads instead (see
/// [`Owned::by_domain`]).
#[derive(Clone, Debug)]
struct Owned {
    threads: usize,
    /// The springs, thread by thread (in the model's order within each), and each one's index
    /// in the model (where its projection goes).
    springs: Vec<ModelSpring>,
    index: Vec<u32>,
    /// Where each thread's springs start (one more than the threads).
    start: Vec<usize>,
    /// In a model in two domains, how many of thread 1's springs come before the ones with an
    /// end on the separator (0 otherwise): those it projects while thread 0 still sweeps the
    /// separator ([`two::Two`]).
    clear_of_separator: usize,
    /// A model in one domain: where each thread's share of each colour has springs to the
    /// others', for sweeps handed over at those seams ([`seams::Seams`]).
    seams: Option<seams::Seams>,
}

impl Owned {
    fn new(model: &Model, threads: usize) -> Owned {
        match &model.domains {
            Some(_) => Owned::by_domain(model, threads),
            None => Owned::by_colour(model, threads),
        }
    }

    /// A model in two domains, swept by two threads from the first colour to the last without a
    /// barrier: a spring with an end on the high side goes to thread 1, which sweeps that side;
    /// every other one to thread 0 (the separator's own springs are read after a barrier).
    fn by_domain(model: &Model, threads: usize) -> Owned {
        let (low, high) = (model.side_of(0), model.side_of(1));
        let on_separator = |p: u32| !low[p as usize] && !high[p as usize];
        let mut lists = vec![Vec::new(); threads];
        // Thread 1's springs within the high side first, then those that reach the separator.
        let mut reaching = Vec::new();
        for (k, s) in model.springs.iter().enumerate() {
            if !high[s.a as usize] && !high[s.b as usize] {
                lists[0].push(k as u32);
            } else if on_separator(s.a) || on_separator(s.b) {
                reaching.push(k as u32);
            } else {
                lists[1].push(k as u32);
            }
        }
        let clear_of_separator = lists[1].len();
        lists[1].extend(reaching);
        Owned {
            clear_of_separator,
            ..Owned::from_lists(model, threads, lists)
        }
    }

    /// Every spring to the thread that sweeps its end of the lower colour.
    fn by_colour(model: &Model, threads: usize) -> Owned {
        // Particle p's colour range.
        let range = |p: usize| {
            (model.colour_ranges.iter())
                .find(|r| r.contains(&p))
                .expect("every particle has a colour")
        };
        // The thread that sweeps particle p: the share of its colour holding it, as
        // `Member::share` cuts a colour's range.
        let owner = |p: usize| {
            let r = range(p);
            let len = r.end - r.start;
            (0..threads)
                .rev()
                .find(|&t| r.start + len * t / threads <= p)
                .unwrap_or(0)
        };
        let mut lists = vec![Vec::new(); threads];
        for (k, s) in model.springs.iter().enumerate() {
            let (a, b) = (s.a as usize, s.b as usize);
            // Colours are stored in order: the lower colour's range starts first.
            let first = if range(a).start <= range(b).start {
                a
            } else {
                b
            };
            lists[owner(first)].push(k as u32);
        }
        Owned {
            seams: (threads > 1).then(|| seams::Seams::new(model, threads)),
            ..Owned::from_lists(model, threads, lists)
        }
    }

    fn from_lists(model: &Model, threads: usize, lists: Vec<Vec<u32>>) -> Owned {
        let mut start = vec![0];
        let mut index = Vec::with_capacity(model.springs.len());
        for list in lists {
            index.extend(list);
            start.push(index.len());
        }
        Owned {
            threads,
            springs: index.iter().map(|&k| model.springs[k as usize]).collect(),
            index,
            start,
            clear_of_separator: 0,
            seams: None,
        }
    }

    /// Thread `t`'s springs and their indices in the model.
    #[inline(always)]
    fn of(&self, t: usize) -> (&[ModelSpring], &[u32]) {
        let mine = self.start[t]..self.start[t + 1];
        (&self.springs[mine.clone()], &self.index[mine])
    }
}

impl Solver {
    /// Prepares the system for steps of `step` seconds (`None`: no inertia, scene E).
    ///
    /// The model must not change afterwards: the sweeps index it without bounds checks, which is
    /// sound because [`Model::validate`] checked every index here, and `Simulation` owns both
    /// and never hands out the model mutably.
    pub(crate) fn new(model: &Model, settings: SolverSettings, step: Option<f32>) -> Solver {
        model.validate();
        // Parallel Gauss-Seidel writes one colour while reading the others: that is only a
        // data-race-free Gauss-Seidel sweep if no spring joins two particles of one colour.
        if let Err(s) = model.check_colouring() {
            panic!("invalid colouring: spring {s:?} joins two particles of one colour");
        }
        let n = model.particle_count();
        let inertia: Vec<f32> = (0..n)
            .map(|i| match step {
                Some(h) if model.inv_mass[i] > 0.0 => model.mass[i] / (h * h),
                _ => 0.0,
            })
            .collect();
        let diag_inv = (0..n)
            .map(|i| {
                let d: f32 = inertia[i] + model.slots(i).iter().map(|s| s.weight).sum::<f32>();
                if model.inv_mass[i] > 0.0 && d > 0.0 {
                    1.0 / d
                } else {
                    0.0
                }
            })
            .collect();
        Solver {
            settings,
            inertia,
            diag_inv,
            owned: None,
        }
    }

    /// Readies red-black Gauss-Seidel's local step for a team of `threads` (see [`Owned`]);
    /// nothing for the other solvers.
    pub fn prepare_for(&mut self, model: &Model, threads: usize) {
        let ready = self.owned.as_ref().is_some_and(|o| o.threads == threads);
        if self.settings.kind == SolverKind::Rbgs && threads > 1 && !ready {
            self.owned = Some(Owned::new(model, threads));
        }
    }

    /// Runs every iteration of one step on `b.delta`. `observe` runs on every thread of the team
    /// after each of its sweeps (inner iteration, or PBD iteration); sweeps handed over point to
    /// point (`two`, `seams`) do not end at a barrier, so an `observe` that reads the state
    /// syncs first.
    pub fn solve(
        &self,
        m: &Member,
        model: &Model,
        b: &Buffers,
        observe: &(dyn Fn(&Member) + Sync),
    ) {
        self.iterate(m, model, b, observe, self.settings.iterations);
    }

    /// Red-black Gauss-Seidel of a model in two domains on a team of exactly two threads,
    /// handed over point to point ([`two::Two`]: the same numbers as [`Self::iterate`]); None
    /// otherwise. Apart from [`Self::iterate`], whose loop compiles as it did without it (with
    /// it inside, scene H's solve on one thread was 8 % slower).
    pub(crate) fn in_two<'a>(&'a self, m: &Member, model: &'a Model) -> Option<two::Two<'a>> {
        let domains = model.domains.as_ref()?;
        let owned = self.owned.as_ref()?;
        (self.settings.kind == SolverKind::Rbgs && m.count == 2 && owned.threads == 2).then_some(
            two::Two {
                domains,
                solver: self,
                owned,
            },
        )
    }

    /// Runs `iterations` outer iterations on `b.delta` (a share of a step's, when collisions
    /// run between shares).
    pub fn iterate(
        &self,
        m: &Member,
        model: &Model,
        b: &Buffers,
        observe: &(dyn Fn(&Member) + Sync),
        iterations: u32,
    ) {
        let s = &self.settings;
        let owned = self.owned.as_ref();
        let seamed = owned.filter(|o| s.kind == SolverKind::Rbgs && o.threads == m.count);
        if let Some(seams) = seamed.and_then(|o| o.seams.as_ref()) {
            return seams.iterate(m, model, self, b, observe, iterations);
        }
        for _ in 0..iterations {
            if s.kind == SolverKind::Pbd {
                pbd::iterate(m, model, b, s.omega);
                observe(m);
                continue;
            }
            match &self.owned {
                // No barrier: this thread's first colour reads only its own springs.
                Some(o) if s.kind == SolverKind::Rbgs && o.threads == m.count => {
                    let (springs, index) = o.of(m.index);
                    project_springs(b, springs, |k| index[k] as usize);
                }
                _ => project(m, model, b),
            }
            for _ in 0..s.inner_iterations {
                self.sweep(m, model, b);
                observe(m);
            }
        }
    }

    /// Per particle, the inertia a_i and 1/(a_i + Σ w) of its row.
    pub fn rows(&self) -> (&[f32], &[f32]) {
        (&self.inertia, &self.diag_inv)
    }

    /// One inner iteration of the global step with the current projections.
    pub(crate) fn sweep(&self, m: &Member, model: &Model, b: &Buffers) {
        let omega = self.settings.omega;
        match self.settings.kind {
            SolverKind::Gs => gauss_seidel::sweep(m, model, self, b, omega),
            SolverKind::Rbgs => rbgs::sweep(m, model, self, b, omega),
            SolverKind::Jacobi => jacobi::sweep(m, model, self, b, omega),
            SolverKind::Pbd => pbd::iterate(m, model, b, omega),
        }
    }

    /// The new displacement of particle `i` from the Gauss-Seidel row, reading displacements with
    /// `read` (which decides between old and new values), or `None` for a particle that never
    /// moves.
    #[inline(always)]
    pub(crate) fn row(
        &self,
        model: &Model,
        i: usize,
        target: &[Vec4],
        projection: &[Vec4],
        read: impl Fn(usize) -> Vec4,
    ) -> Option<Vec4> {
        // SAFETY: `i` and every slot's neighbour and spring are below the lengths checked by
        // Model::validate (in Solver::new) and by the assertion in Solver::solve.
        unsafe {
            let diag_inv = *self.diag_inv.get_unchecked(i);
            if diag_inv == 0.0 {
                return None;
            }
            let row = *model.slot_start.get_unchecked(i) as usize
                ..*model.slot_start.get_unchecked(i + 1) as usize;
            let rhs = *target.get_unchecked(i) * *self.inertia.get_unchecked(i);
            Some(spring_row_solve(
                rhs,
                model.slot.get_unchecked(row).iter().map(|s| {
                    let d = *projection.get_unchecked(s.spring_index()) * s.sign();
                    (s.weight, read(s.neighbour as usize) + d)
                }),
                diag_inv,
            ))
        }
    }
}

/// The local step: every spring's projection d = L (q_a − q_b) / |q_a − q_b|, once per spring,
/// stored as g = d − (x_a − x_b). The edge q_a − q_b is formed as (x_a − x_b) + (Δ_a − Δ_b), so
/// neither term loses the small displacement.
pub(crate) fn project(m: &Member, model: &Model, b: &Buffers) {
    let mine = m.share(0..model.springs.len());
    project_springs(b, &model.springs[mine.clone()], |k| mine.start + k);
    m.sync();
}

/// The local step for `springs`, the projection of `springs[k]` going to index `at(k)`.
#[inline(always)]
fn project_springs(b: &Buffers, springs: &[ModelSpring], at: impl Fn(usize) -> usize) {
    // SAFETY: this stage writes only `projection`, each spring by one thread; x and Δ are read.
    let (x, delta) = unsafe { (b.x.read_all(), b.delta.read_all()) };
    let mut start = 0;
    // Batches of 8 springs: the gathers stay per spring, while the square roots and divisions of
    // a batch run as packed SIMD (the same correctly rounded results as one at a time).
    let mut edge = [Vec4::ZERO; PROJECT_BATCH];
    let mut rest_edge = [Vec4::ZERO; PROJECT_BATCH];
    let mut scale = [0.0f32; PROJECT_BATCH];
    while start < springs.len() {
        let batch = &springs[start..springs.len().min(start + PROJECT_BATCH)];
        for (k, s) in batch.iter().enumerate() {
            let (a, bb) = (s.a as usize, s.b as usize);
            // SAFETY: spring ends are below the particle count (Model::validate, Solver::solve).
            let (xa, xb, da, db) = unsafe {
                (
                    *x.get_unchecked(a),
                    *x.get_unchecked(bb),
                    *delta.get_unchecked(a),
                    *delta.get_unchecked(bb),
                )
            };
            rest_edge[k] = xa - xb;
            edge[k] = rest_edge[k] + (da - db);
            scale[k] = edge[k].length_squared();
        }
        for (f, s) in scale.iter_mut().zip(batch) {
            *f = spring_projection_scale(*f, s.rest);
        }
        for k in 0..batch.len() {
            // SAFETY: each spring's projection is written by one thread.
            unsafe {
                b.projection
                    .set(at(start + k), edge[k] * scale[k] - rest_edge[k])
            };
        }
        start += batch.len();
    }
}

/// Springs per batch of the local step.
const PROJECT_BATCH: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::test_sheet;

    /// Every spring goes to exactly one thread, and each thread owns every spring its share of
    /// the first colour reads, with the axis stencil and with shear and bend springs (more
    /// colours), on teams of 2 to 5.
    #[test]
    fn each_thread_projects_every_spring_its_first_colour_reads() {
        for stiffness in [
            r#"{ "stretch": 100 }"#,
            r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#,
        ] {
            let garment = test_sheet([9, 7], stiffness);
            let model = Model::new(std::slice::from_ref(&garment));
            for threads in 2..=5 {
                let owned = Owned::by_colour(&model, threads);
                let mut times = vec![0; model.springs.len()];
                for t in 0..threads {
                    let (springs, index) = owned.of(t);
                    for (s, &k) in springs.iter().zip(index) {
                        times[k as usize] += 1;
                        assert_eq!(*s, model.springs[k as usize]);
                    }
                    let first = &model.colour_ranges[0];
                    let len = first.end - first.start;
                    let share =
                        first.start + len * t / threads..first.start + len * (t + 1) / threads;
                    for p in share {
                        for slot in model.slots(p) {
                            assert!(
                                index.contains(&(slot.spring_index() as u32)),
                                "{stiffness}, {threads} threads: particle {p}'s spring is not thread {t}'s"
                            );
                        }
                    }
                }
                assert!(
                    times.iter().all(|&n| n == 1),
                    "{stiffness}, {threads} threads"
                );
            }
        }
    }

    /// In a model of two domains, every spring goes to exactly one thread, and each of the two
    /// sweeping threads owns every spring its side's particles read.
    #[test]
    fn each_domain_projects_every_spring_its_side_reads() {
        let garment = test_sheet([12, 9], r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#);
        let model = Model::new(std::slice::from_ref(&garment));
        let domains = model.domains.as_ref().expect("a small model has domains");
        for threads in 2..=4 {
            let owned = Owned::new(&model, threads);
            let mut times = vec![0; model.springs.len()];
            for t in 0..threads {
                let (_, index) = owned.of(t);
                for &k in index {
                    times[k as usize] += 1;
                }
                if t < 2 {
                    for p in domains
                        .side(&model.colour_ranges, t)
                        .iter()
                        .flat_map(|r| r.clone())
                    {
                        for slot in model.slots(p) {
                            assert!(index.contains(&(slot.spring_index() as u32)));
                        }
                    }
                }
            }
            assert!(times.iter().all(|&n| n == 1), "{threads} threads");
        }
    }
}
