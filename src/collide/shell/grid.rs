//! The shell's grid: points bucketed by hashed cell (or, for a focused shell, by cell of a dense
//! box), rebuilt each substep by a counting sort, and the walks that visit the cells around a
//! point or along a path (`shell.wgsl`'s `near` and `near_segment` on the GPU read the same
//! buckets).

use super::*;
use crate::collide::floor_cell;
use glam::{IVec3, Vec3, Vec3A};

/// The candidate shell particles of one query, visited in a fixed order (generic, so each
/// test's loop compiles with its visit inlined).
pub(super) trait Candidates {
    fn each(&self, visit: impl FnMut(usize));
}

/// Indices gathered before the tests.
pub(super) struct Listed<'a>(pub(super) &'a [u32]);

impl Candidates for Listed<'_> {
    #[inline(always)]
    fn each(&self, mut visit: impl FnMut(usize)) {
        self.0.iter().for_each(|&i| visit(i as usize));
    }
}

/// The 27 cells around a point.
pub(super) struct Around<'a>(pub(super) &'a HashGrid, pub(super) Vec3);

impl Candidates for Around<'_> {
    #[inline]
    fn each(&self, visit: impl FnMut(usize)) {
        self.0.near(self.1, visit);
    }
}

/// The cells around a path.
pub(super) struct AlongPath<'a>(pub(super) &'a HashGrid, pub(super) Vec3, pub(super) Vec3);

impl Candidates for AlongPath<'_> {
    #[inline]
    fn each(&self, visit: impl FnMut(usize)) {
        self.0.near_segment(self.1, self.2, visit);
    }
}

/// Points bucketed by hashed cell, in one array (counting sort).
#[derive(Clone, Debug, Default)]
pub(super) struct HashGrid {
    pub(super) cell: f32,
    /// Each bucket's start and end in `items`, side by side (a lookup touches one cache line).
    /// After a full build the starts are a prefix sum, as the GPU reads them.
    pub(super) ranges: Vec<[u32; 2]>,
    pub(super) items: Vec<u32>,
    /// Each point's bucket (a buffer kept between builds).
    pub(super) keys: Vec<u32>,
    /// After a sparse build, the buckets it filled (the others are empty: start = end = 0);
    /// None after a full build.
    pub(super) filled: Option<Vec<u32>>,
    /// Cells in a dense box instead of hashed buckets, when its starts take no more memory than
    /// the table's ranges: up to two cells per bucket (a focused shell on the CPU; see
    /// [`Dense`]).
    pub(super) dense: Option<Dense>,
    /// Each point's cell (a buffer kept between builds).
    pub(super) cells: Vec<IVec3>,
}

/// A dense box of cells: each cell's start in `items`, z fastest, so the cells a walk visits
/// along z are one run of `items`, found by two neighbouring loads. Hashed buckets scatter the
/// cells a walk visits over a table larger than a core's cache: loading their ranges was a
/// quarter of P's shell tests.
#[derive(Clone, Debug, Default)]
pub(super) struct Dense {
    /// The box's first cell and its size in cells.
    pub(super) lo: IVec3,
    pub(super) size: IVec3,
    /// Start of each cell's points in `items` (one more than the cells: the last is the end).
    pub(super) start: Starts,
}

/// A dense box's starts: two bytes each while the points number fewer than 65 536 (every focus
/// of the shipped scenes: P's 7 300), which halves what a build clears and sums and what the walks
/// load (P's box has up to 164 000 cells); four bytes otherwise.
#[derive(Clone, Debug)]
pub(super) enum Starts {
    Narrow(Vec<u16>),
    Wide(Vec<u32>),
}

impl Default for Starts {
    fn default() -> Starts {
        Starts::Narrow(Vec::new())
    }
}

/// A start of a dense box's cell, in two or four bytes.
pub(super) trait Start: Copy + Default {
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
pub(super) fn sort_by_cell<T: Start>(
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
    pub(super) fn rows(&self, lo: IVec3, hi: IVec3, row: impl FnMut(usize, usize)) {
        match &self.start {
            Starts::Narrow(start) => self.rows_with(start, lo, hi, row),
            Starts::Wide(start) => self.rows_with(start, lo, hi, row),
        }
    }

    #[inline]
    pub(super) fn rows_with<T: Start>(
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
pub(super) const DENSE_CELLS_PER_BUCKET: i64 = 2;

/// Runs `work` (serial) while the pool's other threads, just back from the parallel move, wait
/// awake for it instead of falling asleep: the team's region that follows would otherwise wait
/// 30–45 µs for them to wake (measured per substep on P and the blanket). They wait yielding
/// their core, as the pool's own idle threads do.
pub(super) fn keeping_the_pool_awake(work: impl FnOnce() + Send) {
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
pub(super) fn bucket(c: IVec3, buckets: usize) -> usize {
    (crate::collide::hash_cell(c.to_array()) as usize) & (buckets - 1)
}

/// The lattice cell of `p`: `(p / cell).floor().as_ivec3()` without a call to the C library's
/// `floorf` per component (the default x86-64 target has no SSE4.1 rounding instruction; it was
/// 3 % of scene P). Equal for every input, NaN and out-of-range values included.
#[inline]
pub(super) fn cell_index(p: Vec3, cell: f32) -> IVec3 {
    floor_cell(Vec3A::from(p) / cell)
}

/// [`bucket`] of the cell holding `p`, as the grid stores it.
#[inline]
pub(super) fn key_of(p: Vec3, cell: f32, buckets: usize) -> u32 {
    bucket(cell_index(p, cell), buckets) as u32
}

impl HashGrid {
    pub(super) fn build(&mut self, points: &[Vec3], cell: f32, buckets: usize) {
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
    pub(super) fn build_sparse(&mut self, keys: &[u32], cell: f32, buckets: usize) {
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
    pub(super) fn build_cells(
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
    pub(super) fn build_from_keys(&mut self, keys: &[u32], cell: f32, buckets: usize) {
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
    pub(super) fn fill_items(&mut self, keys: &[u32]) {
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
    pub(super) fn bucket_items(&self, b: usize) -> &[u32] {
        let [start, end] = self.ranges[b];
        &self.items[start as usize..end as usize]
    }

    /// Calls `visit` with every point index in the cells around the segment from `a` to `b`
    /// (its bounding box grown by one cell; a bucket may be visited twice).
    #[inline]
    pub(super) fn near_segment(&self, a: Vec3, b: Vec3, mut visit: impl FnMut(usize)) {
        self.segment_runs(a, b, |first, end| {
            for &i in &self.items[first..end] {
                visit(i as usize);
            }
        });
    }

    /// Calls `run` with the range in `items` of each run of cells [`Self::near_segment`] visits,
    /// in its order.
    #[inline]
    pub(super) fn segment_runs(&self, a: Vec3, b: Vec3, mut run: impl FnMut(usize, usize)) {
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
    pub(super) fn gather_segment(&self, a: Vec3, b: Vec3, found: &mut Found) -> usize {
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
    pub(super) fn near(&self, p: Vec3, mut visit: impl FnMut(usize)) {
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
