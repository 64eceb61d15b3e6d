//! A team of threads that runs a whole frame in one parallel region, the way OpenMP runs a
//! `parallel` block: every thread of the current rayon pool executes the same stage list on its
//! own static share of each index range, and a barrier (spin, then sleep) separates the stages.
//!
//! Why not a parallel iterator per stage: a substep has five to six stages of a few microseconds
//! each, and waking sleeping pool threads for every one cost more than the work (measured: two
//! threads were no faster than one on scene E). The static shares also make every run touch the
//! same indices from the same thread, so results never depend on scheduling (nor on the team's
//! size: on a busy machine [`Sharing`] runs frames on one thread). Stages that compute
//! each particle alone at a cost that varies over the cloth (collisions) share their particles by
//! cost instead ([`Member::balanced`]): which thread computes a particle changes nothing there.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

/// Barrier for the threads of one team: spins briefly (a stage of a substep lasts microseconds,
/// and on idle cores the others arrive within that), then sleeps on a condition variable until
/// the last thread arrives, so a machine shared with other jobs lends the core to whoever has
/// work (spinning or yielding there made a bake 10–20 × slower than alone). The last thread
/// wakes the sleepers only when there are any: no system call on the fast path.
///
/// A member that panics breaks it, and every member waiting at it (or arriving later) panics
/// too: the region ends with the panic instead of the others waiting forever for a thread that
/// is gone.
pub struct SpinBarrier {
    threads: usize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
    broken: AtomicBool,
    /// Threads asleep in `wait`.
    sleepers: AtomicUsize,
    /// Waits that ended asleep (spun out), over the barrier's life.
    slept: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

/// What the members that did not panic say when another one did.
const BROKEN: &str = "another thread of the team panicked";

/// Spins before sleeping (about 10–30 µs). Measured on 2 cores: 256 slowed scene H alone by 60 %
/// (threads slept between stages and waited to be woken); 4 096 left two bakes at once 2.4–3.0 ×
/// slower than one alone; 1 024 keeps P and H alone within the noise of the old spinning barrier
/// and two bakes at once at 1.6–1.9 × (on a Zen 5 VM later: 3.0–3.5 ×, 2.5 × with 64 spins but
/// P alone 5 % slower, 1.9 × with 16 but P alone 40 % slower: hence [`Sharing`]).
const SPINS: u32 = 1 << 10;

impl SpinBarrier {
    fn new(threads: usize) -> SpinBarrier {
        SpinBarrier {
            threads,
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            broken: AtomicBool::new(false),
            sleepers: AtomicUsize::new(0),
            slept: AtomicUsize::new(0),
            lock: Mutex::new(()),
            wake: Condvar::new(),
        }
    }

    fn check(&self) {
        if self.broken.load(Ordering::Acquire) {
            panic!("{BROKEN}");
        }
    }

    /// Marks the barrier broken and wakes every sleeper (which then panics).
    fn break_it(&self) {
        self.broken.store(true, Ordering::SeqCst);
        let _guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        self.wake.notify_all();
    }

    /// Blocks until every thread of the team has arrived. Everything written before `wait` by any
    /// thread is visible to every thread after it (release on arrival, acquire on departure).
    fn wait(&self) {
        if self.threads == 1 {
            return;
        }
        self.check();
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == self.threads {
            self.arrived.store(0, Ordering::Relaxed);
            // SeqCst with the sleepers' count: either a sleeper sees the new generation before
            // it sleeps, or this thread sees the sleeper and wakes it.
            self.generation.fetch_add(1, Ordering::SeqCst);
            if self.sleepers.load(Ordering::SeqCst) > 0 {
                let _guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
                self.wake.notify_all();
            }
            return;
        }
        for _ in 0..SPINS {
            if self.generation.load(Ordering::Acquire) != generation {
                return;
            }
            std::hint::spin_loop();
        }
        self.slept.fetch_add(1, Ordering::Relaxed);
        let mut guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        self.sleepers.fetch_add(1, Ordering::SeqCst);
        while self.generation.load(Ordering::SeqCst) == generation {
            if self.broken.load(Ordering::SeqCst) {
                self.sleepers.fetch_sub(1, Ordering::SeqCst);
                drop(guard);
                panic!("{BROKEN}");
            }
            guard = self.wake.wait(guard).unwrap_or_else(|e| e.into_inner());
        }
        self.sleepers.fetch_sub(1, Ordering::SeqCst);
    }
}

/// One thread's view of the team.
pub struct Member<'a> {
    /// This thread's index, 0..count.
    pub index: usize,
    /// Threads in the team.
    pub count: usize,
    barrier: &'a SpinBarrier,
    /// Per thread, what is left of its particles in the current balanced stage.
    left: &'a [Left],
    /// Per thread, the handoffs it has made in this region ([`Member::hand_off`]).
    handed: &'a [Left],
    /// This thread's handoffs so far.
    handoffs: std::cell::Cell<u64>,
    /// This thread's balanced stages so far in this region, wrapping (which stage `left`'s
    /// words are of).
    balanced_stages: std::cell::Cell<u8>,
    /// This thread's waits for another's progress outside the barrier ([`Member::wait_until`])
    /// in this region, and those that spun out and yielded the core.
    waits: std::cell::Cell<u64>,
    waits_spun_out: std::cell::Cell<u64>,
}

/// What is left of one thread's particles in a balanced stage ([`Member::balanced`]): the
/// positions `front..back` in its own list and the stage they are of, packed in one word so that
/// the owner (taking from the front) and a thread done early (taking from the back) never take
/// the same particle. Whichever thread comes to a share first in a stage opens it (the owner at
/// its start, or a thread done with its own), so a thread that starts late (woken late from the
/// last barrier, or descheduled) finds its share taken from the back instead of the others idle
/// at the next barrier. Padded to a cache line of its own: the owner updates it for every chunk.
#[repr(align(64))]
#[derive(Default)]
struct Left(AtomicU64);

/// Particles taken at a time in a balanced stage.
const CHUNK: u64 = 32;

/// Bits of a share's front and back each ([`Left`]; the stage takes the 8 above them).
const POSITION_BITS: u32 = 28;
const POSITION_MASK: u64 = (1 << POSITION_BITS) - 1;

/// The most particles one thread's share of a balanced stage may hold.
pub const MOST_PER_SHARE: usize = POSITION_MASK as usize;

impl Left {
    fn pack(stage: u8, front: u64, back: u64) -> u64 {
        (stage as u64) << (2 * POSITION_BITS) | front << POSITION_BITS | back
    }

    /// Opens the share for `stage` with `len` positions, unless a thread opened it already.
    fn open(&self, stage: u8, len: usize) {
        let mut now = self.0.load(Ordering::Acquire);
        while (now >> (2 * POSITION_BITS)) as u8 != stage {
            let next = Self::pack(stage, 0, len as u64);
            match (self.0).compare_exchange_weak(now, next, Ordering::AcqRel, Ordering::Acquire) {
                Ok(_) => return,
                Err(seen) => now = seen,
            }
        }
    }

    /// Takes up to [`CHUNK`] positions from the front (`owner`) or the back; None when none is
    /// left.
    fn take(&self, owner: bool) -> Option<std::ops::Range<u64>> {
        let mut now = self.0.load(Ordering::Acquire);
        loop {
            let stage = (now >> (2 * POSITION_BITS)) as u8;
            let (front, back) = (now >> POSITION_BITS & POSITION_MASK, now & POSITION_MASK);
            if front >= back {
                return None;
            }
            let n = CHUNK.min(back - front);
            let (next, taken) = if owner {
                (Self::pack(stage, front + n, back), front..front + n)
            } else {
                (Self::pack(stage, front, back - n), back - n..back)
            };
            match self
                .0
                .compare_exchange_weak(now, next, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => return Some(taken),
                Err(seen) => now = seen,
            }
        }
    }
}

impl Member<'_> {
    /// This thread's contiguous share of `range` (shares differ by at most one index).
    pub fn share(&self, range: Range<usize>) -> Range<usize> {
        share_of(range, self.index, self.count)
    }

    /// Calls `each` for every particle of a stage in which each particle is computed alone, in
    /// the order `order` gives them (storage indices), sharing the work by what it costs: every
    /// thread starts on its own contiguous share of `order`, and a thread done with its share
    /// takes chunks from the far end of the others'. For stages whose cost per particle differs
    /// across the cloth (collisions: in P, the thread with the shoulders had a third more `finish`
    /// work than the other). Which thread computes a particle changes nothing in the result. The
    /// stage must end with [`Member::sync`] before the next balanced one.
    pub fn balanced(&self, order: &[u32], each: impl FnMut(usize)) {
        self.balanced_after(order, || {}, each);
    }

    /// [`Self::balanced`], with `first` run on this thread before its first particle: work
    /// of its own (placing a shell ahead), during which the others take its particles.
    pub fn balanced_after(&self, order: &[u32], first: impl FnOnce(), mut each: impl FnMut(usize)) {
        let (index, count) = (self.index, self.count);
        let share = |t: usize| order.len() * t / count..order.len() * (t + 1) / count;
        let mut visit = |t: usize, taken: std::ops::Range<u64>| {
            let mine = &order[share(t)];
            for &i in &mine[taken.start as usize..taken.end as usize] {
                each(i as usize);
            }
        };
        if count == 1 {
            first();
            return visit(0, 0..order.len() as u64);
        }
        assert!(
            order.len().div_ceil(count) <= MOST_PER_SHARE,
            "a balanced stage of {} particles on {count} threads",
            order.len()
        );
        let stage = self.balanced_stages.get().wrapping_add(1);
        self.balanced_stages.set(stage);
        self.left[index].open(stage, share(index).len());
        first();
        while let Some(taken) = self.left[index].take(true) {
            visit(index, taken);
        }
        for other in (1..count).map(|k| (index + k) % count) {
            self.left[other].open(stage, share(other).len());
            while let Some(taken) = self.left[other].take(false) {
                visit(other, taken);
            }
        }
    }

    /// Spins until `done` holds, yielding the core after a while (a team larger than the
    /// machine's cores); panics when another thread of the team has panicked, which then
    /// never makes it hold. Every call counts as a wait in the region's [`RegionStats`] (a
    /// meeting point, as a barrier is one for each thread but the last to arrive, however
    /// short), and as spun out once it yields.
    pub fn wait_until(&self, done: impl Fn() -> bool) {
        self.waits.set(self.waits.get() + 1);
        let mut spins = 0u32;
        while !done() {
            self.barrier.check();
            spins += 1;
            if spins < SPINS {
                std::hint::spin_loop();
            } else {
                if spins == SPINS {
                    self.waits_spun_out.set(self.waits_spun_out.get() + 1);
                }
                std::thread::yield_now();
            }
        }
    }

    /// Tells the team this thread has done one more step of a sequence every thread counts
    /// alike (a sweep): what [`Member::wait_for`] waits for. Everything written before it is
    /// visible to the thread that saw it (release, acquire).
    pub fn hand_off(&self) {
        let n = self.handoffs.get() + 1;
        self.handoffs.set(n);
        self.handed[self.index].0.store(n, Ordering::Release);
    }

    /// The handoffs this thread has made in this region.
    pub fn handoffs(&self) -> u64 {
        self.handoffs.get()
    }

    /// Waits until thread `other` has made at least `n` handoffs in this region.
    pub fn wait_for(&self, other: usize, n: u64) {
        let handed = &self.handed[other].0;
        self.wait_until(|| handed.load(Ordering::Acquire) >= n);
    }

    /// Waits for the whole team: ends a stage.
    pub fn sync(&self) {
        self.barrier.wait();
    }

    /// True on the one thread that does serial work (sequential Gauss-Seidel, metrics).
    pub fn leads(&self) -> bool {
        self.index == 0
    }
}

/// Thread `index`'s contiguous share of `range` on a team of `count` ([`Member::share`]; for
/// plans made before the team runs).
pub fn share_of(range: Range<usize>, index: usize, count: usize) -> Range<usize> {
    let len = range.end - range.start;
    range.start + len * index / count..range.start + len * (index + 1) / count
}

/// How a team region went: its barriers and the waits at them that spun out and slept, and
/// its threads' waits for each other's progress between barriers (hand-offs, a placement's
/// parts) and those of them that spun out and yielded the core.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RegionStats {
    /// Barriers the team passed.
    pub barriers: u64,
    /// Waits (of the threads not last to arrive) that ended asleep.
    pub slept: u64,
    /// Waits between barriers ([`Member::wait_until`]), and those that yielded the core.
    pub waits_between: u64,
    pub yielded: u64,
    /// Threads in the team.
    pub threads: usize,
}

impl RegionStats {
    /// Every wait of the region: each barrier's, for all but the last thread to arrive, and
    /// those between barriers.
    pub fn waits(&self) -> u64 {
        self.barriers * (self.threads.max(1) as u64 - 1) + self.waits_between
    }

    /// The waits that spun out: asleep at a barrier, or yielding the core between barriers
    /// (the thread waited for had no core, or a long stretch of work).
    pub fn spun_out(&self) -> u64 {
        self.slept + self.yielded
    }
}

/// Who runs the team's regions, frame by frame: the whole pool, or the calling thread alone
/// while the machine is busy. A team of two on a 2-core machine shared with another bake waits
/// at nearly every barrier for a thread the OS has descheduled: measured on P, its waits slept
/// at 0–0.2 % of the barriers alone and at 45–100 % with a second bake running, and two bakes
/// at once each took 3.0–3.5 × one alone, where one thread each would take 1.9 ×. So a frame
/// more than a quarter of whose waits spun out ([`RegionStats::spun_out`]: asleep at a barrier,
/// or yielding at a hand-off between barriers) sends the next frames to one thread;
/// then one frame tries the whole team again, and a busy machine doubles the solo stretch (up to
/// [`MOST_SOLO`] frames), unless that frame took less than three quarters of the last solo
/// frame's time: a team slowed by the machine but still faster keeps going. Frames are the same
/// bits on any team size (`tests/determinism.rs`).
#[derive(Clone, Debug)]
pub struct Sharing {
    /// Frames still to run on one thread.
    solo_left: u32,
    /// The next solo stretch, frames.
    stretch: u32,
    /// The last solo frame's time [s].
    solo_seconds: Option<f64>,
    /// False: always the whole pool ([`Sharing::whole_team`]).
    adaptive: bool,
    /// Frames run on one thread so far.
    pub solo_frames: u32,
    /// Over every region so far: the team's waits ([`RegionStats::waits`]), and those that
    /// spun out (the thread waited for had no core): asleep at a barrier or yielding.
    pub waits: u64,
    pub waits_asleep: u64,
    /// The current frame's regions: their waits, and those that spun out.
    frame: RegionStats,
}

/// The first solo stretch, frames.
const FIRST_SOLO: u32 = 8;
/// The longest solo stretch, frames.
const MOST_SOLO: u32 = 64;

impl Default for Sharing {
    fn default() -> Self {
        Sharing {
            solo_left: 0,
            stretch: FIRST_SOLO,
            solo_seconds: None,
            adaptive: true,
            solo_frames: 0,
            waits: 0,
            waits_asleep: 0,
            frame: RegionStats::default(),
        }
    }
}

impl Sharing {
    /// Always the whole pool, busy or not: for benchmarks that time a given number of threads.
    pub fn whole_team() -> Sharing {
        Sharing {
            adaptive: false,
            ..Sharing::default()
        }
    }

    /// Threads for the coming frame's regions: the pool's, or 1.
    pub fn threads(&self) -> usize {
        if self.adaptive && self.solo_left > 0 {
            1
        } else {
            rayon::current_num_threads().max(1)
        }
    }

    /// Starts counting a frame's regions.
    pub fn begin_frame(&mut self) {
        self.frame = RegionStats {
            threads: self.threads(),
            ..RegionStats::default()
        };
    }

    /// Counts one region of the current frame.
    pub fn count(&mut self, region: RegionStats) {
        self.frame.barriers += region.barriers;
        self.frame.slept += region.slept;
        self.frame.waits_between += region.waits_between;
        self.frame.yielded += region.yielded;
        self.waits += region.waits();
        self.waits_asleep += region.spun_out();
    }

    /// The share of the team's waits so far that spun out, asleep at a barrier or yielding
    /// between barriers (None before any wait): near 0 on an otherwise idle machine, high when
    /// its cores run other work.
    pub fn asleep_share(&self) -> Option<f64> {
        (self.waits > 0).then(|| self.waits_asleep as f64 / self.waits as f64)
    }

    /// After the current frame, which took `seconds` ([`Sharing::after_frame`] with the
    /// regions counted since [`Sharing::begin_frame`]).
    pub fn end_frame(&mut self, seconds: f64) {
        self.after_frame(self.frame, seconds);
    }

    /// After a frame that took `seconds`, whose regions went as `stats` (summed) on
    /// [`Sharing::threads`] threads.
    pub fn after_frame(&mut self, stats: RegionStats, seconds: f64) {
        if !self.adaptive {
            return;
        }
        if self.solo_left > 0 {
            self.solo_left -= 1;
            self.solo_frames += 1;
            self.solo_seconds = Some(seconds);
            return;
        }
        let waits = stats.waits();
        if waits == 0 {
            return;
        }
        let team_pays = self.solo_seconds.is_some_and(|solo| seconds < 0.75 * solo);
        if stats.spun_out() * 4 > waits && !team_pays {
            self.solo_left = self.stretch;
            self.stretch = (self.stretch * 2).min(MOST_SOLO);
        } else {
            self.stretch = FIRST_SOLO;
        }
    }
}

/// Runs `body` on `threads` threads at once: the current rayon pool's (all of them), or the
/// calling thread alone (1).
pub fn run(threads: usize, body: impl Fn(&Member) + Sync) -> RegionStats {
    let threads = if threads <= 1 {
        1
    } else {
        rayon::current_num_threads().max(1)
    };
    let barrier = SpinBarrier::new(threads);
    let left: Vec<Left> = (0..threads).map(|_| Left::default()).collect();
    let handed: Vec<Left> = (0..threads).map(|_| Left::default()).collect();
    if threads == 1 {
        body(&Member {
            index: 0,
            count: 1,
            barrier: &barrier,
            left: &left,
            handed: &handed,
            handoffs: Default::default(),
            balanced_stages: Default::default(),
            waits: Default::default(),
            waits_spun_out: Default::default(),
        });
        return RegionStats {
            threads,
            ..RegionStats::default()
        };
    }
    let (waits_between, yielded) = (AtomicU64::new(0), AtomicU64::new(0));
    rayon::broadcast(|ctx| {
        let member = Member {
            index: ctx.index(),
            count: ctx.num_threads(),
            barrier: &barrier,
            left: &left,
            handed: &handed,
            handoffs: Default::default(),
            balanced_stages: Default::default(),
            waits: Default::default(),
            waits_spun_out: Default::default(),
        };
        if let Err(panic) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| body(&member)))
        {
            barrier.break_it();
            std::panic::resume_unwind(panic);
        }
        // Once per thread and region: the counts stay off the shared lines while it runs.
        waits_between.fetch_add(member.waits.get(), Ordering::Relaxed);
        yielded.fetch_add(member.waits_spun_out.get(), Ordering::Relaxed);
    });
    RegionStats {
        barriers: barrier.generation.load(Ordering::Acquire) as u64,
        slept: barrier.slept.load(Ordering::Relaxed) as u64,
        waits_between: waits_between.into_inner(),
        yielded: yielded.into_inner(),
        threads,
    }
}

/// A slice shared by the threads of a team, each writing only its own indices in a stage.
///
/// The team's discipline makes this sound: within one stage an index is written by at most one
/// thread and read by no other thread (except what colouring guarantees for Gauss-Seidel), and
/// stages are separated by [`Member::sync`], which orders all memory accesses.
#[derive(Clone, Copy)]
pub struct Shared<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: access follows the stage discipline above; T is plain data.
unsafe impl<T: Send> Send for Shared<T> {}
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T: Copy> Shared<T> {
    /// Shares `slice` for the duration of one team region.
    pub fn new(slice: &mut [T]) -> Shared<T> {
        Shared {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Reads element `i`.
    ///
    /// # Safety
    /// No other thread writes `i` in the current stage.
    #[inline(always)]
    pub unsafe fn get(&self, i: usize) -> T {
        debug_assert!(i < self.len);
        *self.ptr.add(i)
    }

    /// Element `i`, read in place (for elements too large to copy for a look).
    ///
    /// # Safety
    /// No other thread writes `i` while the reference lives.
    #[inline(always)]
    pub unsafe fn get_ref(&self, i: usize) -> &T {
        debug_assert!(i < self.len);
        &*self.ptr.add(i)
    }

    /// Writes element `i`.
    ///
    /// # Safety
    /// No other thread reads or writes `i` in the current stage.
    #[inline(always)]
    pub unsafe fn set(&self, i: usize, value: T) {
        debug_assert!(i < self.len);
        *self.ptr.add(i) = value;
    }

    /// Element `i`, for writing in place.
    ///
    /// # Safety
    /// No other thread reads or writes `i` while the reference lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn get_mut(&self, i: usize) -> &mut T {
        debug_assert!(i < self.len);
        &mut *self.ptr.add(i)
    }

    /// The whole slice, for reading.
    ///
    /// # Safety
    /// No thread writes any element in the current stage.
    pub unsafe fn read_all(&self) -> &[T] {
        std::slice::from_raw_parts(self.ptr, self.len)
    }

    /// The whole slice, for one thread to write.
    ///
    /// # Safety
    /// No other thread reads or writes any element while the reference lives.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn write_all(&self) -> &mut [T] {
        std::slice::from_raw_parts_mut(self.ptr, self.len)
    }

    /// Elements `range`, for one thread to write.
    ///
    /// # Safety
    /// No other thread reads or writes any of them while the reference lives.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn write_range(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.end - range.start)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_busy_team_goes_solo_for_growing_stretches_and_back_when_it_waits_little() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| {
            let team = |slept| RegionStats {
                barriers: 800,
                slept,
                threads: 2,
                ..RegionStats::default()
            };
            let solo = RegionStats {
                threads: 1,
                ..RegionStats::default()
            };
            let mut s = Sharing::default();
            // Waits that sleep at a quarter of the barriers or fewer: the team stays.
            s.after_frame(team(200), 0.01);
            assert_eq!(s.threads(), 2);
            // More: FIRST_SOLO frames on one thread, then one frame on the team again.
            s.after_frame(team(201), 0.01);
            for _ in 0..FIRST_SOLO {
                assert_eq!(s.threads(), 1);
                s.after_frame(solo, 0.02);
            }
            assert_eq!((s.threads(), s.solo_frames), (2, FIRST_SOLO));
            // Still busy and no faster than solo: twice as long alone.
            s.after_frame(team(700), 0.02);
            for _ in 0..2 * FIRST_SOLO {
                assert_eq!(s.threads(), 1);
                s.after_frame(solo, 0.02);
            }
            // Busy but faster than three quarters of a solo frame: the team keeps going.
            s.after_frame(team(700), 0.014);
            assert_eq!(s.threads(), 2);
            // Quiet again: the stretch starts over.
            s.after_frame(team(0), 0.01);
            s.after_frame(team(700), 0.03);
            let alone = (0..MOST_SOLO).take_while(|_| {
                let t = s.threads();
                s.after_frame(solo, 0.02);
                t == 1
            });
            assert_eq!(alone.count() as u32, FIRST_SOLO);
            // Waits between barriers count with them: quiet barriers, but hand-offs that yield
            // at more than a quarter of all waits, send the next frames to one thread.
            s.after_frame(team(0), 0.01);
            assert_eq!(s.threads(), 2);
            let handing = |yielded| RegionStats {
                waits_between: 200,
                yielded,
                ..team(0)
            };
            s.after_frame(handing(250), 0.02);
            assert_eq!(s.threads(), 2, "a quarter exactly");
            s.after_frame(handing(251), 0.02);
            assert_eq!(s.threads(), 1);
            // A benchmark's team stays whole.
            let mut whole = Sharing::whole_team();
            whole.after_frame(team(800), 0.05);
            assert_eq!((whole.threads(), whole.solo_frames), (2, 0));
        });
    }

    /// The share of waits asleep counts every region of a team of more than one, solo or whole
    /// team alike: each barrier is a wait for all but the last thread to arrive.
    #[test]
    fn waits_asleep_are_a_share_of_every_region_s_waits() {
        let mut s = Sharing::whole_team();
        assert_eq!(s.asleep_share(), None);
        s.count(RegionStats {
            threads: 1,
            ..RegionStats::default()
        });
        assert_eq!(s.asleep_share(), None, "one thread waits for nobody");
        s.count(RegionStats {
            barriers: 10,
            slept: 3,
            threads: 2,
            ..RegionStats::default()
        });
        s.count(RegionStats {
            barriers: 10,
            slept: 9,
            threads: 4,
            ..RegionStats::default()
        });
        assert_eq!((s.waits, s.waits_asleep), (40, 12));
        assert_eq!(s.asleep_share(), Some(0.3));
        // Waits between barriers (hand-offs) and those that yielded count too.
        s.count(RegionStats {
            barriers: 5,
            slept: 0,
            waits_between: 55,
            yielded: 18,
            threads: 2,
        });
        assert_eq!((s.waits, s.waits_asleep), (100, 30));
    }

    /// Every wait for another thread's hand-off counts, met already or not, and one spun out
    /// when the other is long in coming (here it sleeps).
    #[test]
    fn a_region_counts_its_waits_between_barriers_and_those_that_yielded() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool");
        let stats = pool.install(|| {
            run(2, |m: &Member| {
                if m.index == 0 {
                    std::thread::sleep(std::time::Duration::from_millis(20));
                    m.hand_off();
                } else {
                    m.wait_for(0, 0);
                    m.wait_for(0, 1);
                }
                m.sync();
                // Both past the barrier: thread 0's hand-off is there already.
                if m.index == 1 {
                    m.wait_for(0, 1);
                }
            })
        });
        assert_eq!((stats.waits_between, stats.yielded), (3, 1));
        assert_eq!(stats.waits(), 4, "one at the barrier, three between");
    }

    /// Every particle of a balanced stage is visited exactly once, whatever the team's size and
    /// however uneven the work (the first particles cost far more, so the others' threads take
    /// from their shares), stage after stage.
    #[test]
    fn a_balanced_stage_visits_every_particle_once() {
        let order: Vec<u32> = (0..1000u32).rev().collect();
        for threads in [1, 2, 3, 5] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            let visits: Vec<AtomicUsize> = (0..order.len()).map(|_| AtomicUsize::new(0)).collect();
            let stolen = AtomicUsize::new(0);
            let rounds = AtomicUsize::new(0);
            pool.install(|| {
                run(threads, |m: &Member| {
                    // Four stages at least, and on until some thread has taken work from a
                    // share not its own (up to 100): whether a given stage steals depends on
                    // how the OS schedules the team. A thread that starts late has its share
                    // taken from the back (before shares were opened by whoever came first,
                    // the early thread found nothing to take: no steal in 100 stages, half the
                    // runs on a 2-core VM whose threads slept at each barrier).
                    for round in 1..=100 {
                        m.balanced(&order, |i| {
                            visits[i].fetch_add(1, Ordering::Relaxed);
                            let owner = order.len() - 1 - i;
                            if owner * m.count / order.len() != m.index {
                                stolen.fetch_add(1, Ordering::Relaxed);
                            }
                            if i >= 900 {
                                std::thread::sleep(std::time::Duration::from_micros(200));
                            }
                        });
                        m.sync();
                        // Every thread reads the count between two barriers, where no thread
                        // adds to it, so all of them stop after the same stage.
                        let any = stolen.load(Ordering::Relaxed) > 0;
                        m.sync();
                        if round >= 4 && (any || m.count == 1) {
                            if m.leads() {
                                rounds.store(round, Ordering::Relaxed);
                            }
                            break;
                        }
                    }
                })
            });
            let rounds = rounds.load(Ordering::Relaxed);
            assert!(rounds >= 4, "{rounds} on {threads} threads");
            for (i, v) in visits.iter().enumerate() {
                assert_eq!(
                    v.load(Ordering::Relaxed),
                    rounds,
                    "particle {i} on {threads} threads"
                );
            }
            if threads > 1 {
                assert!(
                    stolen.load(Ordering::Relaxed) > 0,
                    "{threads} threads shared no work"
                );
            }
        }
    }

    /// The owner takes from the front and another thread from the back, never the same position.
    #[test]
    fn owner_and_thief_take_disjoint_chunks() {
        let left = Left::default();
        left.open(1, 100);
        assert_eq!(left.take(true), Some(0..32));
        assert_eq!(left.take(false), Some(68..100));
        assert_eq!(left.take(true), Some(32..64));
        assert_eq!(left.take(false), Some(64..68));
        assert_eq!(left.take(true), None);
        assert_eq!(left.take(false), None);
        // Opened again for the same stage (its owner, late): what was taken stays taken.
        left.open(1, 100);
        assert_eq!(left.take(true), None);
        // The next stage starts afresh.
        left.open(2, 40);
        assert_eq!(left.take(false), Some(8..40));
        assert_eq!(left.take(true), Some(0..8));
    }
}
