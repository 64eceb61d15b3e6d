//! Garments against animated characters: each character is a shell of collision particles
//! (`character::Shell`) whose positions are known on every frame and interpolated at every
//! substep. A uniform grid (cell = the largest contact distance, hashed, rebuilt each substep by
//! a counting sort) finds the shell particles near a garment particle; an overlapping pair is
//! pushed apart along the line between the centres (along the skin's normal once it is past
//! the shell particle's tangent plane), the garment particle alone moving, and friction acts on
//! its motion *relative to the skin* (so cloth resting on a moving arm moves with it). Where
//! a garment particle overlaps several shell particles, they push nearest first, each from where
//! the ones before left it: the result does not depend on the order the shell's particles are
//! stored in (they are stored in Morton order of their cells, for the caches) or visited in.
//!
//! With the swept test on, each garment particle's path over the substep is also traced against
//! the shell particles *relative to their own motion*: a path that crosses the skin's tangent
//! plane within a shell particle's radius of its centre and ends beyond that particle's reach
//! (where the end-point push cannot bring it back) stops where it crosses, rides with the skin
//! for the rest of the substep, and is pushed out from there. Paths that end within reach are
//! left to the end-point push, which pushes along the skin's normal once a particle is past a
//! shell particle's tangent plane, so it never pushes cloth further into the body; cloth sliding
//! over the skin never crosses it and is never stopped.
//!
//! On the CPU backend a large moving shell is *focused* each frame: only the shell particles
//! whose path over the frame comes within two contact distances of where the garments can be
//! meanwhile are moved and gridded (the garments' reach is kept on a coarse lattice,
//! [`NearGarments`]; the simulation checks before each substep that no garment particle is
//! about to leave it, and focuses again when one is). Every test looks only within two contact
//! distances, so the frames are the same bits as without the focus; a cape on a running
//! figure's head no longer pays for its legs.

use glam::{IVec3, Vec3, Vec3A, Vec4};
use rayon::prelude::*;

mod near;
pub use near::NearGarments;

/// Values per frame at fractional frame `f`, linear between frames (the last frame holds; a
/// frame whose count differs from the next holds too).
fn interpolate(frames: &[Vec<Vec3>], f: f32) -> Vec<Vec3> {
    let mut out = Vec::new();
    interpolate_into(frames, f, &mut out);
    out
}

/// [`interpolate`] into `out`, reusing its memory; large shells on every thread of the pool
/// (each element on its own: the same numbers on any number of threads).
/// The weight of frame `j` against frame `k` at fractional frame `f`: 0 when they are one frame
/// (a static shell, or time past the last frame), so the positions are the frame's exactly
/// (`a.lerp(a, w)` is `a·(1 − w) + a·w`, off by rounding for most `w`: a static stool would sit
/// a rounding away from itself, by an amount that depends on the time a bake starts at).
pub fn frame_weight(f: f32, k: usize, j: usize) -> f32 {
    if j == k {
        0.0
    } else {
        (f - k as f32).clamp(0.0, 1.0)
    }
}

/// The two frames fractional frame `f` lies between, `k` and `j` (the last frame holds), and
/// the weight of `j` ([`frame_weight`]).
fn frame_span(frames: usize, f: f32) -> (usize, usize, f32) {
    let k = (f.floor().max(0.0) as usize).min(frames - 1);
    let j = (k + 1).min(frames - 1);
    (k, j, frame_weight(f, k, j))
}

fn interpolate_into(frames: &[Vec<Vec3>], f: f32, out: &mut Vec<Vec3>) {
    let (k, j, w) = frame_span(frames.len(), f);
    out.clear();
    if frames[k].len() != frames[j].len() {
        out.extend_from_slice(&frames[k]);
        return;
    }
    let (a, b) = (&frames[k], &frames[j]);
    if a.len() < PARALLEL_FROM {
        out.extend(a.iter().zip(b).map(|(a, b)| a.lerp(*b, w)));
    } else {
        out.par_extend(a.par_iter().zip(b).map(|(a, b)| a.lerp(*b, w)));
    }
}

/// Shells of at least this many particles are advanced on every thread of the pool.
const PARALLEL_FROM: usize = 4096;

/// A shell at the end of a substep as the GPU reads it: per particle (position, motion,
/// normal), then the grid's bucket starts and items.
pub type ShellSnapshot = (Vec<[Vec4; 3]>, Vec<u32>);

/// The candidate shell particles of one query, visited in a fixed order (generic, so each
/// test's loop compiles with its visit inlined).
trait Candidates {
    fn each(&self, visit: impl FnMut(usize));
}

/// Indices gathered before the tests.
struct Listed<'a>(&'a [u32]);

impl Candidates for Listed<'_> {
    #[inline(always)]
    fn each(&self, mut visit: impl FnMut(usize)) {
        self.0.iter().for_each(|&i| visit(i as usize));
    }
}

/// The 27 cells around a point.
struct Around<'a>(&'a HashGrid, Vec3);

impl Candidates for Around<'_> {
    #[inline]
    fn each(&self, visit: impl FnMut(usize)) {
        self.0.near(self.1, visit);
    }
}

/// The cells around a path.
struct AlongPath<'a>(&'a HashGrid, Vec3, Vec3);

impl Candidates for AlongPath<'_> {
    #[inline]
    fn each(&self, visit: impl FnMut(usize)) {
        self.0.near_segment(self.1, self.2, visit);
    }
}

/// A garment particle's push out of a shell so far: where it is, the pushes summed, the skin's
/// motion summed over the contacts, and their count (for friction).
struct Contact {
    p: Vec3,
    push: Vec3,
    skin: Vec3,
    count: u32,
}

impl Contact {
    fn new(p: Vec3) -> Contact {
        Contact {
            p,
            push: Vec3::ZERO,
            skin: Vec3::ZERO,
            count: 0,
        }
    }
}

/// The [`NEARBY`] shell particles nearest a point within two reaches of it, sorted by squared
/// distance and then index (so the same set in any visiting order, a particle visited twice
/// once); `u32::MAX` ends a shorter list.
struct Nearest {
    list: Nearby,
    far: [f32; NEARBY],
    len: usize,
}

impl Default for Nearest {
    fn default() -> Self {
        Nearest {
            list: [u32::MAX; NEARBY],
            far: [f32::INFINITY; NEARBY],
            len: 0,
        }
    }
}

impl Nearest {
    /// Adds the candidates `each` visits near `p` (positions `now`) within two reaches.
    #[inline(always)]
    fn gather(&mut self, now: &[Vec3], p: Vec3, reach: f32, each: &impl Candidates) {
        each.each(|i| self.offer(i as u32, (p - now[i]).length_squared(), reach));
    }

    /// Adds shell particle `i`, `dist2` from the point squared, when within two reaches.
    #[inline(always)]
    fn offer(&mut self, i: u32, dist2: f32, reach: f32) {
        if dist2 < 4.0 * reach * reach {
            self.insert(i, dist2);
        }
    }

    #[inline(always)]
    fn insert(&mut self, i: u32, dist2: f32) {
        let before = |f: f32, j: u32| dist2 < f || (dist2 == f && i < j);
        let (far, list) = (&mut self.far, &mut self.list);
        if self.len == NEARBY && !before(far[NEARBY - 1], list[NEARBY - 1]) {
            return;
        }
        // Shifts and compares in one pass (a `copy_within` of a few entries is a call to
        // memmove: 20 % more time in `finish` on poncho_walk).
        let last = (far[NEARBY - 1], list[NEARBY - 1]);
        let end = self.len.min(NEARBY - 1);
        let mut k = end;
        while k > 0 && before(far[k - 1], list[k - 1]) {
            far[k] = far[k - 1];
            list[k] = list[k - 1];
            k -= 1;
        }
        if k > 0 && list[k - 1] == i {
            // Visited before (a hashed walk meets a bucket twice): the shift undone. Past
            // the list's end the entries are empty, so `last` restores either case.
            for j in k..end {
                far[j] = far[j + 1];
                list[j] = list[j + 1];
            }
            (far[end], list[end]) = last;
            return;
        }
        far[k] = dist2;
        list[k] = i;
        self.len = (self.len + 1).min(NEARBY);
    }

    fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.list[..self.len].iter().map(|&i| i as usize)
    }

    fn is_full(&self) -> bool {
        self.len == NEARBY
    }

    /// The squared distance of the first entry (∞ without any).
    fn nearest(&self) -> f32 {
        self.far[0]
    }

    /// The squared distance of the last entry.
    fn farthest(&self) -> f32 {
        self.far[self.len.saturating_sub(1)]
    }
}

/// Shell particles a collision pass inside the solve tests a garment particle against: the
/// nearest ones within two reaches of it at the end of the previous substep (`u32::MAX`
/// ends a shorter list). The passes only steer the solver; the last pass of a substep tests
/// every shell particle in reach, so a missed one costs accuracy of the passes, never a
/// penetration.
pub const NEARBY: usize = 16;

/// Shell particles a swept test gathers around a path before it walks the cells a second time
/// instead (on the GPU a fixed array; `finish.wgsl` has the same, checked by `tests/shaders.rs`).
pub const SHELL_FOUND: usize = 512;

/// Point indices a run's copy moves at once ([`HashGrid::gather_segment`]).
const RUN_COPY: usize = 8;

/// Where a swept test gathers the shell particles around a path: [`SHELL_FOUND`] of them, and
/// room for the last run's copy.
type Found = [std::mem::MaybeUninit<u32>; SHELL_FOUND + RUN_COPY];

/// A garment particle's [`NEARBY`] shell particles.
pub type Nearby = [u32; NEARBY];

/// How many shell particles `list` holds (its entries come first, then `u32::MAX`).
#[inline]
pub fn listed(list: &Nearby) -> u8 {
    list.iter().take_while(|&&e| e != u32::MAX).count() as u8
}

/// The shell particles a frame's substeps move and grid: those whose path over the rest of the
/// frame comes within two contact distances of where the garments can be meanwhile. The others
/// are far from every garment particle, so no test would find them (a grid walk, a nearby list
/// or a penetration count sees only particles within two reaches): leaving them out changes no
/// result, and a character's legs under a cape, or a body under a hood, cost nothing.
#[derive(Clone, Debug, Default)]
struct Focus {
    /// Their indices, ascending.
    active: Vec<u32>,
    /// The fastest motion per substep of a particle left out (for the driven speed).
    left_out_fastest: f32,
    /// Set when the focus changed: the next substep interpolates every particle's start, since
    /// those that joined were not moved while they were out.
    changed: bool,
}

/// What placing a focus's particles reads: the shell's frames (and normals), the focus's
/// particles (ascending), where they start the substep, and the grid's lattice.
struct Placing<'a> {
    frames: &'a [Vec<Vec3>],
    normals: &'a [Vec<Vec3>],
    active: &'a [u32],
    before: &'a [Vec3],
    cell: f32,
    buckets: usize,
}

impl Placing<'_> {
    /// Each particle's position at fractional frame `to`, its motion from `before` and its
    /// normal, into `[now, motion, normal]` (indexed by shell particle: only the focus's are
    /// written), and their grid; the box around both ends of their paths and the longest
    /// motion. None when the frames or `before` differ in size from the shell. `parallel`: on
    /// the pool's threads (else on the calling thread, inside a team region); every number is
    /// computed per particle, or is a minimum or maximum, so both give the same bits.
    fn place(
        &self,
        to: f32,
        [now, motion, normal]: [&mut Vec<Vec3>; 3],
        grid: &mut HashGrid,
        parallel: bool,
    ) -> Option<((Vec3, Vec3), f32)> {
        let (k, j, w) = frame_span(self.frames.len(), to);
        let (a, b) = (&self.frames[k], &self.frames[j]);
        let n = a.len();
        if b.len() != n || self.before.len() != n {
            return None;
        }
        let before = self.before;
        now.resize(n, Vec3::ZERO);
        motion.resize(n, Vec3::ZERO);
        let normals = (!self.normals.is_empty()).then(|| (&self.normals[k], &self.normals[j]));
        if normals.is_some() {
            normal.resize(n, Vec3::ZERO);
        }
        let mut cells = std::mem::take(&mut grid.cells);
        cells.clear();
        cells.resize(self.active.len(), IVec3::ZERO);
        const CHUNK: usize = 1024;
        let pieces = Piece::split(self.active, CHUNK, [now, motion, normal]);
        let cell = self.cell;
        let empty = (Vec3::MAX, Vec3::MIN, 0.0f32);
        let place = |(piece, cells): (Piece, &mut [IVec3])| {
            let Piece {
                indices,
                first,
                arrays: [now, motion, normal],
            } = piece;
            // In SIMD lanes (Vec3A): the same operations lane by lane, so the same bits as
            // `Vec3::lerp`, `normalize_or` and `cell_index`, at a third of the divisions.
            let lerp = |a: Vec3, b: Vec3| Vec3A::from(a) * (1.0 - w) + Vec3A::from(b) * w;
            let (mut lo, mut hi) = (Vec3A::from(empty.0), Vec3A::from(empty.1));
            let mut fastest = empty.2;
            for (&i, c) in indices.iter().zip(cells) {
                let i = i as usize;
                let p = lerp(a[i], b[i]);
                let m = p - Vec3A::from(before[i]);
                now[i - first] = p.into();
                motion[i - first] = m.into();
                *c = floor_cell(p / cell);
                let start = p - m;
                lo = lo.min(p).min(start);
                hi = hi.max(p).max(start);
                fastest = fastest.max(m.length_squared());
            }
            if let Some((na, nb)) = normals {
                // Four at a time: their square roots and divisions were a third of the move.
                let mut quads = indices.chunks_exact(4);
                for quad in &mut quads {
                    let i: [usize; 4] = std::array::from_fn(|l| quad[l] as usize);
                    let units = normalize4_or_y(i.map(|i| lerp(na[i], nb[i])));
                    for (i, unit) in i.into_iter().zip(units) {
                        normal[i - first] = unit.into();
                    }
                }
                for &i in quads.remainder() {
                    let i = i as usize;
                    normal[i - first] = lerp(na[i], nb[i]).normalize_or(Vec3A::Y).into();
                }
            }
            (Vec3::from(lo), Vec3::from(hi), fastest)
        };
        let merge =
            |x: (Vec3, Vec3, f32), y: (Vec3, Vec3, f32)| (x.0.min(y.0), x.1.max(y.1), x.2.max(y.2));
        let (lo, hi, fastest) = if parallel {
            (pieces.into_par_iter())
                .zip(cells.par_chunks_mut(CHUNK))
                .map(place)
                .reduce(|| empty, merge)
        } else {
            (pieces.into_iter())
                .zip(cells.chunks_mut(CHUNK))
                .map(place)
                .fold(empty, merge)
        };
        // Every particle's cell lies within the cells of the box around the particles.
        let cell_box = (cell_index(lo, cell), cell_index(hi, cell));
        let (active, buckets) = (self.active, self.buckets);
        let build = |grid: &mut HashGrid| grid.build_cells(&cells, active, cell_box, cell, buckets);
        if parallel {
            keeping_the_pool_awake(|| build(grid));
        } else {
            build(grid);
        }
        grid.cells = cells;
        Some(((lo, hi), fastest.sqrt()))
    }
}

/// `n[l].normalize_or(Vec3A::Y)` for four vectors at once, their lengths side by side in one
/// vector: one square root and one division instruction for the four, each lane the same IEEE
/// operations in the same order as one vector's, so the same bits.
#[inline]
fn normalize4_or_y(n: [Vec3A; 4]) -> [Vec3A; 4] {
    let lanes =
        |component: fn(&Vec3A) -> f32| Vec4::from_array(std::array::from_fn(|l| component(&n[l])));
    let (x, y, z) = (lanes(|v| v.x), lanes(|v| v.y), lanes(|v| v.z));
    let rcp = (Vec4::ONE / sqrt4(x * x + y * y + z * z)).to_array();
    std::array::from_fn(|l| {
        if rcp[l].is_finite() && rcp[l] > 0.0 {
            n[l] * rcp[l]
        } else {
            Vec3A::Y
        }
    })
}

/// Each lane's square root.
#[inline]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of every x86-64 target.
    unsafe {
        Vec4::from(std::arch::x86_64::_mm_sqrt_ps(v.into()))
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec4::from_array(v.to_array().map(f32::sqrt))
}

/// A focused shell placed at the end of the next substep ahead of time
/// ([`ShellCollider::place_ahead`]), with the buffers it is placed into.
#[derive(Debug, Default)]
struct Ahead {
    /// Placed, and not taken yet.
    ready: bool,
    /// The substep it was placed for (fractional frames), with which focus and lattice.
    span: (f32, f32),
    focus: u64,
    lattice: (f32, usize),
    now: Vec<Vec3>,
    motion: Vec<Vec3>,
    normal: Vec<Vec3>,
    grid: HashGrid,
    bounds: (Vec3, Vec3),
    fastest: f32,
}

/// The slot a team thread places a shell ahead into through a shared reference (one thread
/// writes it inside `finish`; `advance` takes it between team regions). A copy of the shell
/// starts with it empty.
#[derive(Debug, Default)]
struct AheadSlot(std::sync::Mutex<Ahead>);

impl Clone for AheadSlot {
    fn clone(&self) -> AheadSlot {
        AheadSlot::default()
    }
}

/// A run of a focus's particles (ascending indices from `first` on) with the stretch of each
/// per-particle array their indices span: runs do not overlap, so each is moved on its own
/// thread.
struct Piece<'a> {
    indices: &'a [u32],
    first: usize,
    /// Positions, motions and normals (empty without normals) from `first` on.
    arrays: [&'a mut [Vec3]; 3],
}

impl<'a> Piece<'a> {
    /// `active` (ascending) in runs of `chunk`, each with its stretch of `arrays`.
    fn split(active: &'a [u32], chunk: usize, arrays: [&'a mut [Vec3]; 3]) -> Vec<Piece<'a>> {
        let mut rest = arrays.map(|a| &mut a[..]);
        let mut at = 0;
        let mut pieces = Vec::new();
        for indices in active.chunks(chunk) {
            let (first, end) = (indices[0] as usize, *indices.last().unwrap() as usize + 1);
            let arrays = std::array::from_fn(|k| {
                let whole = std::mem::take(&mut rest[k]);
                if whole.is_empty() {
                    return whole; // no normals
                }
                let (mine, after) = whole[first - at..].split_at_mut(end - first);
                rest[k] = after;
                mine
            });
            at = end;
            pieces.push(Piece {
                indices,
                first,
                arrays,
            });
        }
        pieces
    }
}

/// A character's shell as a collider.
#[derive(Clone, Debug)]
pub struct ShellCollider {
    pub name: String,
    /// Shell particle radius [m].
    pub radius: f32,
    pub friction: f32,
    /// Shell particle positions on every character frame (frame 0 at the start of the bake).
    pub frames: Vec<Vec<Vec3>>,
    /// Trace each garment particle's path, not only where it ends (the scene's
    /// `swept_collisions`).
    pub swept: bool,
    /// Outward surface normals of the shell particles on every frame, when the shell rides one
    /// mesh (empty otherwise: then every contact pushes along the line between the centres).
    pub normals: Vec<Vec<Vec3>>,
    /// The mesh the shell rides and where on it each particle sits, when its topology holds
    /// over the frames (the GPU backend places the particles from it).
    pub skin: Option<std::sync::Arc<super::skin::Skin>>,
    /// Positions at the end of the current substep.
    now: Vec<Vec3>,
    /// Normals at the end of the current substep (empty without `normals`).
    now_normal: Vec<Vec3>,
    /// Their motion over the current substep.
    motion: Vec<Vec3>,
    /// The fractional frame `now` is at (None before the first substep).
    now_at: Option<f32>,
    /// Positions at the start of the current substep (a buffer kept between substeps).
    before: Vec<Vec3>,
    /// The longest distance a shell particle moved over the current substep [m].
    fastest: f32,
    /// On the CPU backend, the shell particles that can come near the garments this frame
    /// (see [`ShellCollider::focus`]); None: all of them.
    focus: Option<Focus>,
    /// Counts the focuses made (a placement ahead is for one of them).
    focus_made: u64,
    /// The shell placed ahead for the next substep, if it was.
    ahead: AheadSlot,
    /// Substeps that took the shell placed ahead.
    taken_ahead: u64,
    /// The box around the shell particles at both ends of the current substep: a path whose
    /// box stays two reaches away meets none of them (the broad phase of `resolve`).
    bounds: (Vec3, Vec3),
    grid: HashGrid,
}

/// Points bucketed by hashed cell, in one array (counting sort).
#[derive(Clone, Debug, Default)]
struct HashGrid {
    cell: f32,
    /// Each bucket's start and end in `items`, side by side (a lookup touches one cache line).
    /// After a full build the starts are a prefix sum, as the GPU reads them.
    ranges: Vec<[u32; 2]>,
    items: Vec<u32>,
    /// Each point's bucket (a buffer kept between builds).
    keys: Vec<u32>,
    /// After a sparse build, the buckets it filled (the others are empty: start = end = 0);
    /// None after a full build.
    filled: Option<Vec<u32>>,
    /// Cells in a dense box instead of hashed buckets, when its starts take no more memory than
    /// the table's ranges: up to two cells per bucket (a focused shell on the CPU; see
    /// [`Dense`]).
    dense: Option<Dense>,
    /// Each point's cell (a buffer kept between builds).
    cells: Vec<IVec3>,
}

/// A dense box of cells: each cell's start in `items`, z fastest, so the cells a walk visits
/// along z are one run of `items`, found by two neighbouring loads. Hashed buckets scatter the
/// cells a walk visits over a table larger than a core's cache: loading their ranges was a
/// quarter of P's shell tests.
#[derive(Clone, Debug, Default)]
struct Dense {
    /// The box's first cell and its size in cells.
    lo: IVec3,
    size: IVec3,
    /// Start of each cell's points in `items` (one more than the cells: the last is the end).
    start: Starts,
}

/// A dense box's starts: two bytes each while the points number fewer than 65 536 (every focus
/// of the shipped scenes: P's 7 300), which halves what a build clears and sums and what the walks
/// load (P's box has up to 164 000 cells); four bytes otherwise.
#[derive(Clone, Debug)]
enum Starts {
    Narrow(Vec<u16>),
    Wide(Vec<u32>),
}

impl Default for Starts {
    fn default() -> Starts {
        Starts::Narrow(Vec::new())
    }
}

/// A start of a dense box's cell, in two or four bytes.
trait Start: Copy + Default {
    fn at(self) -> usize;
    /// `n`, which the caller checked fits.
    fn of(n: usize) -> Self;

    /// Each entry becomes the sum of itself and those before it (which fits: it counts points).
    fn running_sum(starts: &mut [Self]) {
        let mut total = 0;
        for s in starts {
            total += s.at();
            *s = Self::of(total);
        }
    }
}

impl Start for u16 {
    #[inline]
    fn at(self) -> usize {
        self as usize
    }
    #[inline]
    fn of(n: usize) -> u16 {
        n as u16
    }

    /// Eight at a time, in one SSE2 register: the sums within the eight by three shifted adds,
    /// plus the total so far; 32 empty cells (most of a box) are the total, stored at once.
    /// The running sum over a box of 70 000–100 000 cells was more than half of a shell's
    /// sort (60 000 of poncho_walk's 108 000 cycles per substep).
    #[cfg(target_arch = "x86_64")]
    fn running_sum(starts: &mut [u16]) {
        use std::arch::x86_64::*;
        let mut chunks = starts.chunks_exact_mut(32);
        // SAFETY: SSE2 is part of x86_64; every load and store is of eight u16 within a chunk.
        let total = unsafe {
            let zero = _mm_setzero_si128();
            // The total so far, in every lane.
            let mut total = zero;
            for chunk in &mut chunks {
                let at = chunk.as_mut_ptr() as *mut __m128i;
                let x: [__m128i; 4] = std::array::from_fn(|k| _mm_loadu_si128(at.add(k)));
                let any = _mm_or_si128(_mm_or_si128(x[0], x[1]), _mm_or_si128(x[2], x[3]));
                if _mm_movemask_epi8(_mm_cmpeq_epi16(any, zero)) == 0xFFFF {
                    (0..4).for_each(|k| _mm_storeu_si128(at.add(k), total));
                    continue;
                }
                for (k, mut x) in x.into_iter().enumerate() {
                    x = _mm_add_epi16(x, _mm_slli_si128::<2>(x));
                    x = _mm_add_epi16(x, _mm_slli_si128::<4>(x));
                    x = _mm_add_epi16(x, _mm_slli_si128::<8>(x));
                    x = _mm_add_epi16(x, total);
                    _mm_storeu_si128(at.add(k), x);
                    let last = _mm_shufflehi_epi16::<0xFF>(x);
                    total = _mm_unpackhi_epi64(last, last);
                }
            }
            _mm_extract_epi16::<0>(total) as u16
        };
        let mut total = total;
        for s in chunks.into_remainder() {
            total += *s;
            *s = total;
        }
    }
}

impl Start for u32 {
    #[inline]
    fn at(self) -> usize {
        self as usize
    }
    #[inline]
    fn of(n: usize) -> u32 {
        n as u32
    }
}

/// Counting sort of the points `ids` by their cells' indices (`index` of `cells[k]`, below
/// `len`) into `items`, leaving each cell's start in `start` (and the end in its last entry):
/// counts, then each cell's end (a running sum), then the points placed from the last, so each
/// cell's start is left where its first point went and its points ascend.
fn sort_by_cell<T: Start>(
    start: &mut Vec<T>,
    len: usize,
    cells: &[IVec3],
    ids: &[u32],
    index: impl Fn(IVec3) -> usize,
    items: &mut Vec<u32>,
) {
    start.clear();
    start.resize(len + 1, T::default());
    for &c in cells {
        let at = &mut start[index(c)];
        *at = T::of(at.at() + 1);
    }
    T::running_sum(start);
    items.clear();
    items.resize(cells.len(), 0);
    for (&id, &c) in ids.iter().zip(cells).rev() {
        let at = &mut start[index(c)];
        *at = T::of(at.at() - 1);
        items[at.at()] = id;
    }
}

impl Dense {
    /// Calls `row` with the range in `items` of each run of cells along z from `lo` to `hi`,
    /// in the order x, y (the points ascending along z, and within a cell), as the hashed walk
    /// visits them.
    #[inline]
    fn rows(&self, lo: IVec3, hi: IVec3, row: impl FnMut(usize, usize)) {
        match &self.start {
            Starts::Narrow(start) => self.rows_with(start, lo, hi, row),
            Starts::Wide(start) => self.rows_with(start, lo, hi, row),
        }
    }

    #[inline]
    fn rows_with<T: Start>(
        &self,
        start: &[T],
        lo: IVec3,
        hi: IVec3,
        mut row: impl FnMut(usize, usize),
    ) {
        let lo = lo.max(self.lo);
        let hi = hi.min(self.lo + self.size - IVec3::ONE);
        if lo.cmpgt(hi).any() {
            return;
        }
        let at = lo - self.lo;
        let span = (hi - lo).z as usize + 1;
        for x in 0..=(hi - lo).x {
            for y in 0..=(hi - lo).y {
                let first = (((at.x + x) * self.size.y + at.y + y) * self.size.z + at.z) as usize;
                row(start[first].at(), start[first + span].at());
            }
        }
    }
}

/// Cells a dense box may have per bucket of the hashed table it replaces: a cell's start takes
/// four bytes, a bucket's range eight, so the box takes no more memory than the table. With one
/// cell per bucket, 166 of P's 1 075 placements of a focus in 60 frames and 91 of the blanket's
/// 959 fell back to hashed buckets (P's focus spans 99 × 92 × 18 cells at times, 164 000 for
/// 131 072 buckets); with two, none, and P's `finish` took 5.3–5.4 ms per frame instead of
/// 6.0–6.2, the same frames.
const DENSE_CELLS_PER_BUCKET: i64 = 2;

/// Runs `work` (serial) while the pool's other threads, just back from the parallel move, wait
/// awake for it instead of falling asleep: the team's region that follows would otherwise wait
/// 30–45 µs for them to wake (measured per substep on P and the blanket). They wait yielding
/// their core, as the pool's own idle threads do.
fn keeping_the_pool_awake(work: impl FnOnce() + Send) {
    if rayon::current_num_threads() < 2 {
        return work();
    }
    let done = std::sync::atomic::AtomicBool::new(false);
    rayon::join(
        || {
            work();
            done.store(true, std::sync::atomic::Ordering::Release);
        },
        || {
            while !done.load(std::sync::atomic::Ordering::Acquire) {
                std::thread::yield_now();
            }
        },
    );
}

/// The bucket of cell `c` among a power-of-two number of `buckets` (wrapping 32-bit products,
/// as the GPU computes it too).
fn bucket(c: IVec3, buckets: usize) -> usize {
    let h =
        c.x.wrapping_mul(73_856_093) ^ c.y.wrapping_mul(19_349_663) ^ c.z.wrapping_mul(83_492_791);
    (h as u32 as usize) & (buckets - 1)
}

/// The lattice cell of `p`: `(p / cell).floor().as_ivec3()` without a call to the C library's
/// `floorf` per component (the default x86-64 target has no SSE4.1 rounding instruction; it was
/// 3 % of scene P). Equal for every input, NaN and out-of-range values included.
#[inline]
fn cell_index(p: Vec3, cell: f32) -> IVec3 {
    floor_cell(Vec3A::from(p) / cell)
}

/// The lattice cell of a point already divided by the cell's width (`p / cell`, in either
/// vector type: each lane's quotient is the same number).
#[inline]
fn floor_cell(q: impl Into<Vec3A>) -> IVec3 {
    let q: Vec3A = q.into();
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of every x86-64 target.
    unsafe {
        use std::arch::x86_64::*;
        // The three lanes at once while each is a number below 2³¹ in size, where truncation
        // is exact and the scalar conversion's saturation never applies (the rest below):
        // truncate, then one less where that rounded up (negative fractions). Three scalar
        // conversions with their checks were a fifth of placing a shell.
        let v: __m128 = q.into();
        let size = _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        if _mm_movemask_ps(_mm_cmple_ps(size, _mm_set1_ps(2_147_483_520.0))) & 7 == 7 {
            let truncated = _mm_cvttps_epi32(v);
            let above = _mm_cmplt_ps(v, _mm_cvtepi32_ps(truncated));
            let cell: [i32; 4] =
                std::mem::transmute(_mm_add_epi32(truncated, _mm_castps_si128(above)));
            return IVec3::new(cell[0], cell[1], cell[2]);
        }
    }
    let floor = |x: f32| {
        let i = x as i32;
        i.saturating_sub((x < i as f32) as i32)
    };
    IVec3::new(floor(q.x), floor(q.y), floor(q.z))
}

/// [`bucket`] of the cell holding `p`, as the grid stores it.
#[inline]
fn key_of(p: Vec3, cell: f32, buckets: usize) -> u32 {
    bucket(cell_index(p, cell), buckets) as u32
}

impl HashGrid {
    fn build(&mut self, points: &[Vec3], cell: f32, buckets: usize) {
        let key = |p: &Vec3| key_of(*p, cell, buckets);
        let mut keys = std::mem::take(&mut self.keys);
        keys.clear();
        if points.len() < PARALLEL_FROM {
            keys.extend(points.iter().map(key));
        } else {
            keys.par_extend(points.par_iter().map(key));
        }
        self.build_from_keys(&keys, cell, buckets);
        self.keys = keys;
    }

    /// [`Self::build_from_keys`] in time proportional to the points, not the buckets: only the
    /// buckets the points fill are written (the others left empty), so a few thousand points
    /// among a hundred thousand buckets cost a few thousand steps. Each bucket lists its points
    /// in the same order as the full build; the starts are no prefix sum (not for the GPU).
    fn build_sparse(&mut self, keys: &[u32], cell: f32, buckets: usize) {
        self.cell = cell;
        self.dense = None;
        let mut filled = match self.filled.take() {
            Some(f) if self.ranges.len() == buckets => f,
            _ => {
                self.ranges.clear();
                self.ranges.resize(buckets, [0, 0]);
                Vec::new()
            }
        };
        for &b in &filled {
            self.ranges[b as usize] = [0, 0];
        }
        filled.clear();
        // Count into the ends, then give each filled bucket its place in `items`.
        for &k in keys {
            let count = &mut self.ranges[k as usize][1];
            if *count == 0 {
                filled.push(k);
            }
            *count += 1;
        }
        let mut offset = 0;
        for &b in &filled {
            let range = &mut self.ranges[b as usize];
            let count = range[1];
            *range = [offset, offset];
            offset += count;
        }
        self.fill_items(keys);
        self.filled = Some(filled);
    }

    /// Points `ids` in cells `cells` (`cells[i]`: point `ids[i]`'s, within the box of cells
    /// `lo..=hi`), sorted into a dense box of cells ([`Dense`]) when the box has no more than
    /// [`DENSE_CELLS_PER_BUCKET`] cells per bucket, else into the hashed buckets as
    /// [`Self::build_sparse`] does. Each cell lists its points in the order of `cells` either
    /// way.
    fn build_cells(
        &mut self,
        cells: &[IVec3],
        ids: &[u32],
        (lo, hi): (IVec3, IVec3),
        cell: f32,
        buckets: usize,
    ) {
        let size =
            (hi.as_i64vec3() - lo.as_i64vec3() + glam::I64Vec3::ONE).max(glam::I64Vec3::ZERO);
        let hashed = |grid: &mut HashGrid| {
            let keys: Vec<u32> = cells.iter().map(|&c| bucket(c, buckets) as u32).collect();
            grid.build_sparse(&keys, cell, buckets);
            // The grid lists positions in `cells`' order: map them to the points.
            for item in &mut grid.items {
                *item = ids[*item as usize];
            }
        };
        if cells.is_empty() || size.x * size.y * size.z > DENSE_CELLS_PER_BUCKET * buckets as i64 {
            return hashed(self);
        }
        self.cell = cell;
        self.filled = None;
        let size = size.as_ivec3();
        let mut dense = self.dense.take().unwrap_or_default();
        let index = |c: IVec3| {
            let c = c - lo;
            ((c.x * size.y + c.y) * size.z + c.z) as usize
        };
        if cells.iter().any(|c| c.cmplt(lo).any() || c.cmpgt(hi).any()) {
            // Outside the box it was told (a position that is not a number): hashed.
            return hashed(self);
        }
        let len = (size.x * size.y * size.z) as usize;
        let items = &mut self.items;
        if cells.len() <= u16::MAX as usize {
            if !matches!(dense.start, Starts::Narrow(_)) {
                dense.start = Starts::Narrow(Vec::new());
            }
            if let Starts::Narrow(start) = &mut dense.start {
                sort_by_cell(start, len, cells, ids, index, items);
            }
        } else {
            if !matches!(dense.start, Starts::Wide(_)) {
                dense.start = Starts::Wide(Vec::new());
            }
            if let Starts::Wide(start) = &mut dense.start {
                sort_by_cell(start, len, cells, ids, index, items);
            }
        }
        dense.lo = lo;
        dense.size = size;
        self.dense = Some(dense);
    }

    /// Counting sort of the points by their buckets `keys` (`keys[i]`: point i's).
    fn build_from_keys(&mut self, keys: &[u32], cell: f32, buckets: usize) {
        self.filled = None;
        self.dense = None;
        self.cell = cell;
        self.ranges.clear();
        self.ranges.resize(buckets, [0, 0]);
        for &k in keys {
            self.ranges[k as usize][1] += 1;
        }
        let mut offset = 0;
        for range in &mut self.ranges {
            let count = range[1];
            *range = [offset, offset];
            offset += count;
        }
        self.fill_items(keys);
    }

    /// Puts each point into its bucket's next free slot (every bucket's range empty at its
    /// start), so each bucket lists its points in ascending order.
    fn fill_items(&mut self, keys: &[u32]) {
        self.items.clear();
        self.items.resize(keys.len(), 0);
        for (i, &k) in keys.iter().enumerate() {
            let at = &mut self.ranges[k as usize][1];
            self.items[*at as usize] = i as u32;
            *at += 1;
        }
    }

    /// The points in bucket `b`.
    #[inline]
    fn bucket_items(&self, b: usize) -> &[u32] {
        let [start, end] = self.ranges[b];
        &self.items[start as usize..end as usize]
    }

    /// Calls `visit` with every point index in the cells around the segment from `a` to `b`
    /// (its bounding box grown by one cell; a bucket may be visited twice).
    #[inline]
    fn near_segment(&self, a: Vec3, b: Vec3, mut visit: impl FnMut(usize)) {
        self.segment_runs(a, b, |first, end| {
            for &i in &self.items[first..end] {
                visit(i as usize);
            }
        });
    }

    /// Calls `run` with the range in `items` of each run of cells [`Self::near_segment`] visits,
    /// in its order.
    #[inline]
    fn segment_runs(&self, a: Vec3, b: Vec3, mut run: impl FnMut(usize, usize)) {
        let buckets = self.ranges.len();
        let lo = cell_index(a.min(b), self.cell).saturating_sub(IVec3::ONE);
        let hi = cell_index(a.max(b), self.cell).saturating_add(IVec3::ONE);
        if let Some(dense) = &self.dense {
            return dense.rows(lo, hi, run);
        }
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    let [start, end] = self.ranges[bucket(IVec3::new(x, y, z), buckets)];
                    run(start as usize, end as usize);
                }
            }
        }
    }

    /// The point indices [`Self::near_segment`] visits, in its order, into `found`; returns how
    /// many there are (more than `found` holds: the first [`SHELL_FOUND`] are written). Each
    /// run's indices are copied [`RUN_COPY`] at a time whatever their number (the entries past
    /// it are overwritten by the next run, or never read), without a loop per run: a shell's
    /// runs hold 0 to 3 points, a loop's end that branch prediction keeps missing (on P, a walk
    /// that found points took 300–350 cycles, one that found none 80–140).
    #[inline]
    fn gather_segment(&self, a: Vec3, b: Vec3, found: &mut Found) -> usize {
        let items = &self.items;
        let mut count = 0;
        self.segment_runs(a, b, |first, end| {
            let n = end - first;
            if n <= RUN_COPY && count + RUN_COPY <= found.len() && first + RUN_COPY <= items.len() {
                // SAFETY: both ranges lie within their slices (checked just above); u32 and
                // MaybeUninit<u32> share their layout.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        items.as_ptr().add(first),
                        found.as_mut_ptr().add(count).cast::<u32>(),
                        RUN_COPY,
                    );
                }
            } else {
                // A long run, or the last entries: one by one, as far as `found` goes.
                let free = &mut found[count.min(SHELL_FOUND + RUN_COPY)..];
                for (slot, &i) in free.iter_mut().zip(&items[first..end]) {
                    slot.write(i);
                }
            }
            count += n;
        });
        count
    }

    /// Calls `visit` with every point index in the 27 cells around `p`.
    #[inline]
    fn near(&self, p: Vec3, mut visit: impl FnMut(usize)) {
        let buckets = self.ranges.len();
        let c = cell_index(p, self.cell);
        if let Some(dense) = &self.dense {
            let (lo, hi) = (c.saturating_sub(IVec3::ONE), c.saturating_add(IVec3::ONE));
            return dense.rows(lo, hi, |first, end| {
                for &i in &self.items[first..end] {
                    visit(i as usize);
                }
            });
        }
        let mut seen = [usize::MAX; 27];
        let mut n = 0;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let b = bucket(c.wrapping_add(IVec3::new(dx, dy, dz)), buckets);
                    // Hash collisions can map two cells to one bucket: visit each bucket once.
                    if seen[..n].contains(&b) {
                        continue;
                    }
                    seen[n] = b;
                    n += 1;
                    for &i in self.bucket_items(b) {
                        visit(i as usize);
                    }
                }
            }
        }
    }
}

impl ShellCollider {
    /// A collider from shell positions per frame.
    pub fn new(name: String, radius: f32, friction: f32, frames: Vec<Vec<Vec3>>) -> ShellCollider {
        let now: Vec<Vec3> = frames.first().cloned().unwrap_or_default();
        let bounds = now.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
        ShellCollider {
            name,
            radius,
            friction,
            swept: true,
            normals: Vec::new(),
            skin: None,
            now_normal: Vec::new(),
            motion: vec![Vec3::ZERO; now.len()],
            now,
            now_at: None,
            before: Vec::new(),
            fastest: 0.0,
            focus: None,
            focus_made: 0,
            ahead: AheadSlot::default(),
            taken_ahead: 0,
            frames,
            bounds,
            grid: HashGrid::default(),
        }
    }

    /// Positions at fractional frame `f` (the last frame holds).
    pub fn positions_at(&self, f: f32) -> Vec<Vec3> {
        interpolate(&self.frames, f)
    }

    /// Moves the shell to the end of a substep spanning fractional frames `from` → `to`, and
    /// rebuilds the grid for garment particles of contact radius up to `garment_radius`.
    pub fn advance(&mut self, from: f32, to: f32, garment_radius: f32) {
        // A shell that never moves (one frame: a stool) stays where its first substep put it,
        // with its grid.
        if self.frames.len() == 1 && self.now_at.is_some() {
            self.now_at = Some(to);
            return;
        }
        let cell = self.cell_for(garment_radius);
        let buckets = Self::buckets_for(self.most_particles());
        if self.take_ahead(from, to, cell, buckets) {
            return;
        }
        // Substeps follow one another: where the last one ended (`now`) is where this one
        // starts, so its positions are reused rather than interpolated again; buffers are kept.
        let mut before = std::mem::take(&mut self.before);
        let refocused = self
            .focus
            .as_mut()
            .is_some_and(|f| std::mem::take(&mut f.changed));
        if self.now_at != Some(from) {
            interpolate_into(&self.frames, from, &mut before);
        } else {
            std::mem::swap(&mut before, &mut self.now);
            if let Some(focus) = self.focus.as_ref().filter(|_| refocused) {
                // Particles that joined the focus were not moved while out of it.
                let (k, j, w) = frame_span(self.frames.len(), from);
                let (a, b) = (&self.frames[k], &self.frames[j]);
                for &i in &focus.active {
                    let i = i as usize;
                    before[i] = a[i].lerp(b[i], w);
                }
            }
        }
        self.now_at = Some(to);
        if self.focus.is_some() && self.advance_focused(to, &before, cell, buckets) {
            self.before = before;
            return;
        }
        if !self.advance_in_one_pass(to, &before, cell, buckets) {
            self.advance_in_steps(to, &before, cell, buckets);
        }
        self.before = before;
    }

    /// The common case (a shell that keeps its particles, at least [`PARALLEL_FROM`] of them) in
    /// one pass on every thread: each particle's position, motion and grid bucket, the shell's
    /// box and fastest motion; then the normals and the counting sort. False when it does not
    /// apply. Every number is computed per particle (or is a minimum or maximum), so any
    /// number of threads gives the same.
    fn advance_in_one_pass(&mut self, to: f32, before: &[Vec3], cell: f32, buckets: usize) -> bool {
        let (k, j, w) = frame_span(self.frames.len(), to);
        let (a, b) = (&self.frames[k], &self.frames[j]);
        let n = a.len();
        if n < PARALLEL_FROM || b.len() != n || before.len() != n {
            return false;
        }
        self.now.resize(n, Vec3::ZERO);
        self.motion.resize(n, Vec3::ZERO);
        let mut keys = std::mem::take(&mut self.grid.keys);
        keys.resize(n, 0);
        const CHUNK: usize = 2048;
        let empty = (Vec3::MAX, Vec3::MIN, 0.0f32);
        let (lo, hi, fastest) = self
            .now
            .par_chunks_mut(CHUNK)
            .zip(self.motion.par_chunks_mut(CHUNK))
            .zip(keys.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(c, ((now, motion), keys))| {
                let (mut lo, mut hi, mut fastest) = empty;
                for (o, ((p, m), key)) in now.iter_mut().zip(motion).zip(keys).enumerate() {
                    let i = c * CHUNK + o;
                    *p = a[i].lerp(b[i], w);
                    *m = *p - before[i];
                    *key = key_of(*p, cell, buckets);
                    let start = *p - *m;
                    lo = lo.min(*p).min(start);
                    hi = hi.max(*p).max(start);
                    fastest = fastest.max(m.length_squared());
                }
                (lo, hi, fastest)
            })
            .reduce(|| empty, |x, y| (x.0.min(y.0), x.1.max(y.1), x.2.max(y.2)));
        if !self.normals.is_empty() {
            interpolate_into(&self.normals, to, &mut self.now_normal);
            self.now_normal
                .par_iter_mut()
                .for_each(|n| *n = n.normalize_or(Vec3::Y));
        }
        self.grid.build_from_keys(&keys, cell, buckets);
        self.grid.keys = keys;
        self.bounds = (lo, hi);
        self.fastest = fastest.sqrt();
        true
    }

    /// Focuses the substeps from fractional frame `from` to the end of that frame on the shell
    /// particles whose path over them comes near the garments (`near`, made for two contact
    /// distances beyond how far the garments may go meanwhile); `per_substep` is the share of a
    /// frame one substep takes. Only shells that keep their particles and move are focused, and
    /// only when the focus leaves out at least a tenth of the particles (otherwise moving them
    /// all costs no more than the focus). Fewer particles in the grid also means fewer others
    /// in the buckets a test walks (P's `finish` 10–15 % faster with 70 % of the mannequin).
    pub fn focus(&mut self, from: f32, near: &NearGarments, per_substep: f32) {
        self.focus_made += 1;
        let (k, j, _) = frame_span(self.frames.len(), from);
        let (a, b) = (&self.frames[k], &self.frames[j]);
        if self.frames.len() == 1 || a.len() != b.len() || a.len() < PARALLEL_FROM {
            self.unfocus();
            return;
        }
        // Per run of 32 particles: which take part (a bit each), and the longest motion over
        // the frame, squared, of those left out.
        let run = |r: usize| -> (u32, f32) {
            let (mut taken, mut left) = (0u32, 0.0f32);
            for (bit, i) in (r * 32..(r * 32 + 32).min(a.len())).enumerate() {
                let (p, q) = (a[i], b[i]);
                if near.touches(p.min(q), p.max(q)) {
                    taken |= 1 << bit;
                } else {
                    left = left.max(p.distance_squared(q));
                }
            }
            (taken, left)
        };
        let taken: Vec<(u32, f32)> = (0..a.len().div_ceil(32))
            .into_par_iter()
            .with_min_len(32)
            .map(run)
            .collect();
        let previous = self.focus.take();
        let mut active = Vec::new();
        for (r, &(mut bits, _)) in taken.iter().enumerate() {
            while bits != 0 {
                active.push((r * 32) as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
        if 10 * active.len() > 9 * a.len() {
            // Not worth it: every particle again; any left out so far were not moved, so the
            // next substep starts from interpolated positions.
            if previous.is_some() {
                self.now_at = None;
            }
            return;
        }
        // The longest of the distances is the root of the longest squared.
        let left_out = taken.iter().map(|(_, l)| *l).fold(0.0, f32::max).sqrt();
        // Particles that join were not moved while they were out: the next substep starts
        // from interpolated positions then.
        let changed = previous
            .as_ref()
            .is_some_and(|p| p.changed || p.active != active);
        self.focus = Some(Focus {
            changed,
            active,
            left_out_fastest: left_out * per_substep,
        });
    }

    /// True for a shell [`ShellCollider::focus`] may focus: one that moves and keeps its many
    /// particles.
    pub fn can_focus(&self) -> bool {
        self.frames.len() > 1
            && self.frames[0].len() >= PARALLEL_FROM
            && self.frames.iter().all(|f| f.len() == self.frames[0].len())
    }

    /// Particles in focus, of all (None: not focused).
    pub fn focused(&self) -> Option<(usize, usize)> {
        self.focus
            .as_ref()
            .map(|f| (f.active.len(), self.now.len()))
    }

    /// Every particle takes part again (the GPU backend reads them all).
    pub fn unfocus(&mut self) {
        self.focus_made += 1;
        if self.focus.take().is_some() {
            // The particles left out were not moved: start from interpolated positions.
            self.now_at = None;
        }
    }

    /// [`Self::advance_in_one_pass`] for the focus's particles only; false when it does not
    /// apply. The same numbers for each of them as the full pass.
    fn advance_focused(&mut self, to: f32, before: &[Vec3], cell: f32, buckets: usize) -> bool {
        let Some(focus) = &self.focus else {
            return false;
        };
        let arrays = [&mut self.now, &mut self.motion, &mut self.now_normal];
        let placed = Placing {
            frames: &self.frames,
            normals: &self.normals,
            active: &focus.active,
            before,
            cell,
            buckets,
        }
        .place(to, arrays, &mut self.grid, true);
        let Some((bounds, fastest)) = placed else {
            return false;
        };
        self.bounds = bounds;
        self.fastest = fastest.max(focus.left_out_fastest);
        true
    }

    /// Places the focus's particles at the end of the next substep (ending at fractional frame
    /// `to`) ahead of time, while the team finishes the current one: one thread does it inside
    /// `finish`, whose particles the others share out meanwhile, instead of every thread waiting
    /// for it before the next substep (its grid's sort is serial). The next [`Self::advance`]
    /// takes it when it asks for that substep with the same focus; anything else (a new focus,
    /// another substep) places the shell as usual. Only focused shells, which only the CPU
    /// backend has.
    pub fn place_ahead(&self, to: f32, garment_radius: f32) {
        let (Some(focus), Some(from)) = (&self.focus, self.now_at) else {
            return;
        };
        let (cell, buckets) = (
            self.cell_for(garment_radius),
            Self::buckets_for(self.most_particles()),
        );
        let mut slot = self.ahead.0.lock().unwrap_or_else(|e| e.into_inner());
        let ahead = &mut *slot;
        ahead.ready = false;
        let arrays = [&mut ahead.now, &mut ahead.motion, &mut ahead.normal];
        let placed = Placing {
            frames: &self.frames,
            normals: &self.normals,
            active: &focus.active,
            before: &self.now,
            cell,
            buckets,
        }
        .place(to, arrays, &mut ahead.grid, false);
        if let Some((bounds, fastest)) = placed {
            ahead.ready = true;
            ahead.span = (from, to);
            ahead.focus = self.focus_made;
            ahead.lattice = (cell, buckets);
            ahead.bounds = bounds;
            ahead.fastest = fastest.max(focus.left_out_fastest);
        }
    }

    /// Takes the shell [`Self::place_ahead`] placed for the substep from `from` to `to`, when it
    /// was placed for that substep, lattice and focus; false otherwise (then nothing changed).
    fn take_ahead(&mut self, from: f32, to: f32, cell: f32, buckets: usize) -> bool {
        let ahead = self.ahead.0.get_mut().unwrap_or_else(|e| e.into_inner());
        let valid = ahead.ready
            && ahead.span == (from, to)
            && ahead.lattice == (cell, buckets)
            && ahead.focus == self.focus_made
            && self.now_at == Some(from)
            && self.focus.as_ref().is_some_and(|f| !f.changed);
        ahead.ready = false;
        if !valid {
            return false;
        }
        // Where the shell is now starts the substep; what was placed ends it; the start's old
        // buffers take the next placement.
        std::mem::swap(&mut self.before, &mut self.now);
        std::mem::swap(&mut self.now, &mut ahead.now);
        std::mem::swap(&mut self.motion, &mut ahead.motion);
        std::mem::swap(&mut self.now_normal, &mut ahead.normal);
        std::mem::swap(&mut self.grid, &mut ahead.grid);
        self.bounds = ahead.bounds;
        self.fastest = ahead.fastest;
        self.now_at = Some(to);
        self.taken_ahead += 1;
        true
    }

    /// Substeps so far that took the shell [`Self::place_ahead`] placed for them.
    pub fn taken_ahead(&self) -> u64 {
        self.taken_ahead
    }

    /// Every other case (small shells, shells re-sampled per frame) step by step.
    fn advance_in_steps(&mut self, to: f32, before: &[Vec3], cell: f32, buckets: usize) {
        interpolate_into(&self.frames, to, &mut self.now);
        if !self.normals.is_empty() {
            interpolate_into(&self.normals, to, &mut self.now_normal);
            self.now_normal
                .iter_mut()
                .for_each(|n| *n = n.normalize_or(Vec3::Y));
        }
        self.motion.clear();
        if before.len() == self.now.len() {
            let moved = self.now.iter().zip(before).map(|(a, b)| *a - *b);
            self.motion.extend(moved);
        } else {
            self.motion.resize(self.now.len(), Vec3::ZERO);
        }
        self.grid.build(&self.now, cell, buckets);
        self.bounds =
            self.now
                .iter()
                .zip(&self.motion)
                .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), (p, m)| {
                    let start = *p - *m;
                    (lo.min(*p).min(start), hi.max(*p).max(start))
                });
        self.fastest = self
            .motion
            .iter()
            .map(|m| m.length_squared())
            .fold(0.0, f32::max)
            .sqrt();
    }

    /// Resolves a garment particle starting the step at `x` and moving by `delta`, of contact
    /// radius `radius`: pushes it out of the shell particles it ends in and applies friction to
    /// its motion relative to the skin. Returns the corrected displacement (unchanged without
    /// contact). With `nearby`, also lists the shell particles near where the particle ends, for
    /// the next substep's collision passes ([`ShellCollider::resolve_nearby`]).
    ///
    /// The broad phase is inlined where it is called (most calls end there: P's stool, far
    /// from most of the poncho, is asked about every particle in every substep); the rest is
    /// kept out of line: inlined, its grid walk bloated the per-particle loop of every scene,
    /// characters or not (measured 10.3 → 11.4 ms per frame on scene H).
    #[inline]
    pub fn resolve(&self, x: Vec4, delta: Vec4, radius: f32, nearby: Option<&mut Nearby>) -> Vec4 {
        if self.now.is_empty() {
            return delta;
        }
        // Broad phase: the result is the one the full test gives without contact.
        if self.out_of_reach(x, delta, radius) {
            if let Some(list) = nearby {
                list.fill(u32::MAX);
            }
            return Self::untouched(x, delta);
        }
        self.resolve_in_reach(x, delta, radius, nearby)
    }

    /// [`Self::resolve`] past its broad phase.
    #[inline(never)]
    fn resolve_in_reach(
        &self,
        x: Vec4,
        delta: Vec4,
        radius: f32,
        mut nearby: Option<&mut Nearby>,
    ) -> Vec4 {
        // Paths longer than 64 grid cells are not traced (nothing in a bake moves that far in
        // one substep); the end point is still tested.
        let reach = self.radius + radius;
        let x3 = x.truncate();
        let d = delta.truncate();
        let p = x3 + d;
        if self.swept && !self.now_normal.is_empty() && d.length() <= 64.0 * self.grid.cell {
            // One walk over the cells around the path serves both tests (they cover the end
            // point's neighbourhood too: a cell is as wide as the reach).
            // Not zeroed: only the first `count` entries are written and read (2 KB cleared
            // per call was 3 % of scene P).
            let mut found: Found = [std::mem::MaybeUninit::uninit(); SHELL_FOUND + RUN_COPY];
            let count = self.grid.gather_segment(x3, p, &mut found);
            if count == 0 {
                // In reach of none (most calls): what the tests below give for no candidate.
                if let Some(list) = nearby {
                    list.fill(u32::MAX);
                }
                return Self::untouched(x, delta);
            }
            if count <= SHELL_FOUND {
                // SAFETY: the first `count` entries were written just above.
                let near: &[u32] = unsafe { &*(&found[..count] as *const _ as *const [u32]) };
                let each = Listed(near);
                // The end point's neighbours, gathered in the same pass (as `push_out` would,
                // for the path's end: most paths cross nothing).
                let (mut nearest, mut any) = (Nearest::default(), false);
                let gather = nearby.is_some();
                let crossed = self.first_contact(x3, d, reach, &each, |i, distance| {
                    if gather {
                        nearest.offer(i as u32, distance, reach);
                    } else {
                        any |= distance < reach * reach;
                    }
                });
                return match crossed {
                    Some((t, i)) => {
                        let p = x3 + d * t + self.motion[i] * (1.0 - t);
                        self.push_out(x3, p, reach, &each, nearby)
                    }
                    None if !gather && !any => (p - x3).extend(0.0),
                    None => {
                        if !gather {
                            nearest.gather(&self.now, p, reach, &each);
                        }
                        self.push_from_nearest(x3, p, reach, &each, nearest, nearby)
                    }
                };
            }
            let each = AlongPath(&self.grid, x3, p);
            if let Some((t, i)) = self.first_contact(x3, d, reach, &each, |_, _| {}) {
                let p = x3 + d * t + self.motion[i] * (1.0 - t);
                return self.push_out(x3, p, reach, &Around(&self.grid, p), nearby.take());
            }
        }
        self.push_out(x3, p, reach, &Around(&self.grid, p), nearby)
    }

    /// True when the path of a garment particle of contact `radius` from `x` by `delta` stays
    /// two reaches from the box around the shell particles: it meets none of them and lists
    /// none ([`ShellCollider::resolve`]'s broad phase).
    #[inline]
    pub fn out_of_reach(&self, x: Vec4, delta: Vec4, radius: f32) -> bool {
        let (x3, p) = (x.truncate(), (x + delta).truncate());
        let margin = Vec3::splat(2.0 * (self.radius + radius));
        let (lo, hi) = (self.bounds.0 - margin, self.bounds.1 + margin);
        x3.min(p).cmpgt(hi).any() || x3.max(p).cmplt(lo).any()
    }

    /// A collision pass inside the solve: [`ShellCollider::resolve`] against the shell
    /// particles in `nearby` only, end point only (no swept test).
    pub fn resolve_nearby(&self, x: Vec4, delta: Vec4, radius: f32, nearby: &Nearby) -> Vec4 {
        if nearby[0] == u32::MAX {
            return delta;
        }
        let x3 = x.truncate();
        let mut contact = Contact::new(x3 + delta.truncate());
        let count = self.now.len();
        let listed = nearby.iter().take_while(|&&i| i != u32::MAX);
        // A shell re-sampled per frame (its topology changes) may have fewer particles than the
        // one that left the list: its missing entries are skipped.
        let indices = listed.map(|&i| i as usize).filter(|&i| i < count);
        self.push_from(&mut contact, self.radius + radius, indices);
        self.with_friction(x3, contact)
    }

    /// The distance from `x` to the nearest shell particle in `nearby` (∞ when none is left):
    /// a collision pass whose particle is nearer `x` than that less the contact reach meets none
    /// of them, while the shell stands still (within a substep).
    pub fn nearest_listed(&self, x: Vec4, nearby: &Nearby) -> f32 {
        let x3 = x.truncate();
        let count = self.now.len();
        let listed = nearby.iter().take_while(|&&i| i != u32::MAX);
        listed
            .map(|&i| i as usize)
            .filter(|&i| i < count)
            .map(|i| (x3 - self.now[i]).length_squared())
            .fold(f32::INFINITY, f32::min)
            .sqrt()
    }

    /// What [`ShellCollider::resolve_nearby`] returns for a particle in reach of none of its
    /// listed shell particles, to the bit.
    #[inline]
    pub fn untouched(x: Vec4, delta: Vec4) -> Vec4 {
        let x3 = x.truncate();
        ((x3 + delta.truncate()) - x3).extend(0.0)
    }

    /// Pushes the end point `p` of a path from `x3` out of the shell particles `each` visits
    /// that it lies within `reach` of, then applies friction; lists the nearest of them in
    /// `nearby` (see [`ShellCollider::resolve`]).
    ///
    /// The pushes go nearest first: the candidates within two reaches of `p` are gathered,
    /// sorted by distance (ties by index) and pushed from one by one, each tested against where
    /// the ones before left the particle. So the result does not depend on the order in which
    /// the grid holds the shell's particles or visits its cells (pushing in visiting order, a
    /// layout of the shell in Morton order let cloth through a thrown ball that the sampler's
    /// order caught), and a particle a hashed walk visits twice counts once.
    fn push_out(
        &self,
        x3: Vec3,
        p: Vec3,
        reach: f32,
        each: &impl Candidates,
        nearby: Option<&mut Nearby>,
    ) -> Vec4 {
        let within = reach * reach;
        if nearby.is_none() {
            // Without a list to keep, a first look for any particle in reach: most calls find
            // none, and the sorted gathering is left to the rest (poncho_walk's `finish` 13 %
            // slower with it for every call).
            let mut any = false;
            each.each(|i| any |= (p - self.now[i]).length_squared() < within);
            if !any {
                return (p - x3).extend(0.0);
            }
        }
        let mut nearest = Nearest::default();
        nearest.gather(&self.now, p, reach, each);
        self.push_from_nearest(x3, p, reach, each, nearest, nearby)
    }

    /// [`Self::push_out`] once the candidates near `p` are gathered (`nearest`).
    fn push_from_nearest(
        &self,
        x3: Vec3,
        p: Vec3,
        reach: f32,
        each: &impl Candidates,
        nearest: Nearest,
        nearby: Option<&mut Nearby>,
    ) -> Vec4 {
        let within = reach * reach;
        if let Some(list) = nearby {
            *list = nearest.list;
        }
        let mut contact = Contact::new(p);
        if nearest.nearest() >= within {
            return (p - x3).extend(0.0); // in reach of none (most calls)
        }
        self.push_from(&mut contact, reach, nearest.iter());
        // Rare (folds, two surfaces): more shell particles within two reaches than a list
        // holds, and the pushes moved the particle near ones past its end. A second round
        // from where it is.
        let moved = contact.p.distance(p);
        if nearest.is_full() && nearest.farthest() < (reach + moved) * (reach + moved) {
            let mut again = Nearest::default();
            again.gather(&self.now, contact.p, reach, each);
            self.push_from(&mut contact, reach, again.iter());
        }
        self.with_friction(x3, contact)
    }

    /// Pushes `contact` out of the shell particles `indices`, in that order, each tested
    /// against where the ones before left it.
    #[inline]
    fn push_from(&self, contact: &mut Contact, reach: f32, indices: impl Iterator<Item = usize>) {
        for i in indices {
            let s = self.now[i];
            let d = contact.p - s;
            let dist2 = d.length_squared();
            if dist2 >= reach * reach {
                continue;
            }
            let push = match self.now_normal.get(i) {
                // Beneath the skin at this particle (past its tangent plane): back out along
                // the skin's normal to the contact sphere, never further in.
                Some(&normal) if d.dot(normal) < 0.0 => {
                    let along = d - normal * d.dot(normal);
                    let height = (reach * reach - along.length_squared()).max(0.0).sqrt();
                    normal * (height - d.dot(normal))
                }
                _ => {
                    let dist = dist2.sqrt();
                    let n = if dist > 1e-9 { d / dist } else { Vec3::Y };
                    n * (reach - dist)
                }
            };
            contact.p += push;
            contact.push += push;
            contact.skin += self.motion[i];
            contact.count += 1;
        }
    }

    /// The displacement from `x3` to where `contact` ends, after friction on its motion
    /// relative to the skin, limited by μ × the push (Coulomb).
    #[inline(always)]
    fn with_friction(&self, x3: Vec3, contact: Contact) -> Vec4 {
        let mut p = contact.p;
        if contact.count == 0 {
            return (p - x3).extend(0.0);
        }
        let push_len = contact.push.length();
        let n = if push_len > 1e-12 {
            contact.push / push_len
        } else {
            Vec3::Y
        };
        let skin = contact.skin / contact.count as f32;
        let relative = (p - x3) - skin;
        let tangent = relative - n * relative.dot(n);
        let t_len = tangent.length();
        let limit = self.friction * push_len;
        p -= if t_len <= limit {
            tangent
        } else {
            tangent * (limit / t_len)
        };
        (p - x3).extend(0.0)
    }

    /// The earliest time (fraction of the substep) at which the path from `x` along `d` crosses
    /// the skin where a shell particle covers it, when the end point lies beyond that particle's
    /// reach (so the end-point push cannot bring it back); and that particle. Needs the skin's
    /// normals (a shell re-sampled per frame has none: then only the end point is tested);
    /// `each` visits the candidates.
    /// `at_end` sees each candidate with its squared distance from the path's end (what
    /// [`Self::push_out`] would compute again).
    fn first_contact(
        &self,
        x: Vec3,
        d: Vec3,
        reach: f32,
        each: &impl Candidates,
        mut at_end: impl FnMut(usize, f32),
    ) -> Option<(f32, usize)> {
        // The earliest crossing; among equal times (particles on one flat face share their
        // tangent plane) the one crossed nearest its centre, then the lowest index: the same
        // contact in any order of the shell's particles.
        let mut best: Option<(f32, f32, usize)> = None;
        each.each(|i| {
            let n = self.now_normal[i];
            let end = self.now[i];
            // Relative to the shell particle: from r0 (start) to r1 (end).
            let r0 = x - (end - self.motion[i]);
            let r1 = x + d - end;
            let end_distance = r1.length_squared();
            at_end(i, end_distance);
            let (h0, h1) = (r0.dot(n), r1.dot(n));
            if h0 < 0.0 || h1 >= 0.0 || end_distance < reach * reach {
                return; // not crossing the skin here, or the end-point push handles it
            }
            let t = h0 / (h0 - h1);
            let crossing = r0 + (r1 - r0) * t;
            if crossing.length_squared() >= reach * reach {
                return; // crosses the tangent plane beyond this particle's reach
            }
            let off = crossing.length_squared();
            if best.is_none_or(|b| (t, off, i) < b) {
                best = Some((t, off, i));
            }
        });
        best.map(|(t, _, i)| (t, i))
    }

    /// Garment particles (`q`) inside the shell's particles: count, and the deepest overlap of
    /// a contact [m] (contact distance minus centre distance), over particles closer than the
    /// shell radius to a shell particle centre.
    pub fn penetration(&self, q: &[Vec4]) -> super::Penetration {
        let depth = |p: &Vec4| {
            let p = p.truncate();
            let mut deepest = 0.0f32;
            self.grid.near(p, |i| {
                let d = p.distance(self.now[i]);
                if d < self.radius {
                    deepest = deepest.max(self.radius - d);
                }
            });
            deepest
        };
        // A count and a maximum: the same on any number of threads.
        q.par_iter()
            .with_min_len(1024)
            .map(|p| super::Penetration::of_depth(depth(p)))
            .reduce(super::Penetration::default, super::Penetration::merge)
    }

    /// The longest distance a shell particle moved over the current substep [m].
    pub fn fastest_motion(&self) -> f32 {
        self.fastest
    }

    /// The shell as the GPU reads it at the end of the current substep: per particle its
    /// position, its motion over the substep and its normal (zero without normals); then the
    /// grid's bucket starts (buckets + 1) and its items.
    /// A shell re-sampled per frame is padded to its most particles over the frames (the GPU
    /// lays every substep out alike): padding particles sit 10¹⁸ m away, where no garment
    /// particle comes within reach, and no grid bucket lists them.
    /// Of a shell that is not focused (a focused one moved only some of its particles; the GPU
    /// backend unfocuses every shell).
    pub fn gpu_snapshot(&self) -> ShellSnapshot {
        let most = self.most_particles();
        let far = [Vec4::splat(1e18), Vec4::ZERO, Vec4::ZERO];
        let mut particles: Vec<[Vec4; 3]> = self
            .now
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let n = self.now_normal.get(i).copied().unwrap_or(Vec3::ZERO);
                [p.extend(0.0), self.motion[i].extend(0.0), n.extend(0.0)]
            })
            .collect();
        particles.resize(most, far);
        assert!(
            self.grid.dense.is_none(),
            "a focused shell's grid is not the GPU's (the GPU backend unfocuses every shell)"
        );
        let mut grid: Vec<u32> = self.grid.ranges.iter().map(|r| r[0]).collect();
        grid.push(self.grid.items.len() as u32);
        grid.extend_from_slice(&self.grid.items);
        grid.resize(self.grid.ranges.len() + 1 + most, 0);
        (particles, grid)
    }

    /// True for a shell that never moves (a character of one frame: a stool).
    pub fn is_static(&self) -> bool {
        self.frames.len() == 1
    }

    /// The most shell particles of any frame (all frames' alike unless the character's topology
    /// changes and its shell is re-sampled per frame); the grid has buckets for this many.
    pub fn most_particles(&self) -> usize {
        self.frames.iter().map(Vec::len).max().unwrap_or(0)
    }

    /// Hash buckets of the grid for `particles` shell particles: eight per particle, so the
    /// buckets a test walks rarely hold particles of other cells (measured on P: `finish` 12 →
    /// 7.8 ms per frame against two per particle; sixteen gained nothing more).
    pub fn buckets_for(particles: usize) -> usize {
        (8 * particles).next_power_of_two().max(64)
    }

    /// Width of a grid cell for garment particles of contact radius up to `garment_radius`.
    pub fn cell_for(&self, garment_radius: f32) -> f32 {
        (self.radius + garment_radius).max(1e-6)
    }

    /// Number of shell particles.
    pub fn particles(&self) -> usize {
        self.now.len()
    }
}

#[cfg(test)]
mod tests;
