//! Moving shells in time: positions and normals interpolated between character frames at each
//! substep, and the focus (only the shell particles that can come near the garments are moved
//! and gridded). The next substep's placement ahead, inside `finish`, is in `ahead`.

use super::*;
use glam::{IVec3, Vec3, Vec3A, Vec4};

/// Values per frame at fractional frame `f`, linear between frames (the last frame holds; a
/// frame whose count differs from the next holds too).
pub(super) fn interpolate(frames: &[Vec<Vec3>], f: f32) -> Vec<Vec3> {
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
pub(super) fn frame_span(frames: usize, f: f32) -> (usize, usize, f32) {
    let k = (f.floor().max(0.0) as usize).min(frames - 1);
    let j = (k + 1).min(frames - 1);
    (k, j, frame_weight(f, k, j))
}

pub(super) fn interpolate_into(frames: &[Vec<Vec3>], f: f32, out: &mut Vec<Vec3>) {
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
pub(super) const PARALLEL_FROM: usize = 4096;

/// The shell particles a frame's substeps move and grid: those whose path over the rest of the
/// frame comes within two contact distances of where the garments can be meanwhile. The others
/// are far from every garment particle, so no test would find them (a grid walk, a nearby list
/// or a penetration count sees only particles within two reaches): leaving them out changes no
/// result, and a character's legs under a cape, or a body under a hood, cost nothing.
#[derive(Clone, Debug, Default)]
pub(super) struct Focus {
    /// Their indices, ascending.
    pub(super) active: Vec<u32>,
    /// The fastest motion per substep of a particle left out (for the driven speed).
    pub(super) left_out_fastest: f32,
    /// Set when the focus changed: the next substep interpolates every particle's start, since
    /// those that joined were not moved while they were out.
    pub(super) changed: bool,
}

/// What placing a focus's particles reads: the shell's frames (and normals), the focus's
/// particles (ascending), where they start the substep, and the grid's lattice.
pub(super) struct Placing<'a> {
    pub(super) frames: &'a [Vec<Vec3>],
    pub(super) normals: &'a [Vec<Vec3>],
    pub(super) active: &'a [u32],
    pub(super) before: &'a [Vec3],
    pub(super) cell: f32,
    pub(super) buckets: usize,
}

impl Placing<'_> {
    /// Each particle's position at fractional frame `to`, its motion from `before` and its
    /// normal, into `[now, motion, normal]` (indexed by shell particle: only the focus's are
    /// written), and their grid; the box around both ends of their paths and the longest
    /// motion. None when the frames or `before` differ in size from the shell. `parallel`: on
    /// the pool's threads (else on the calling thread, inside a team region); every number is
    /// computed per particle, or is a minimum or maximum, so both give the same bits.
    pub(super) fn place(
        &self,
        to: f32,
        [now, motion, normal]: [&mut Vec<Vec3>; 3],
        grid: &mut HashGrid,
        parallel: bool,
    ) -> Option<((Vec3, Vec3), f32)> {
        let span = self.span(to)?;
        let n = self.before.len();
        now.resize(n, Vec3::ZERO);
        motion.resize(n, Vec3::ZERO);
        if !self.normals.is_empty() {
            normal.resize(n, Vec3::ZERO);
        }
        let mut cells = std::mem::take(&mut grid.cells);
        cells.clear();
        cells.resize(self.active.len(), IVec3::ZERO);
        const CHUNK: usize = 1024;
        let pieces = Piece::split(self.active, CHUNK, [now, motion, normal]);
        let place = |(piece, cells): (Piece, &mut [IVec3])| self.place_piece(span, piece, cells);
        let (lo, hi, fastest) = if parallel {
            (pieces.into_par_iter())
                .zip(cells.par_chunks_mut(CHUNK))
                .map(place)
                .reduce(|| EMPTY_BOX, merge_boxes)
        } else {
            (pieces.into_iter())
                .zip(cells.chunks_mut(CHUNK))
                .map(place)
                .fold(EMPTY_BOX, merge_boxes)
        };
        self.build(grid, cells, (lo, hi), parallel);
        Some(((lo, hi), fastest.sqrt()))
    }

    /// The two frames `to` lies between and the later one's weight ([`frame_span`]); None when
    /// they or `before` differ in size.
    pub(super) fn span(&self, to: f32) -> Option<(usize, usize, f32)> {
        let (k, j, w) = frame_span(self.frames.len(), to);
        let n = self.frames[k].len();
        (self.frames[j].len() == n && self.before.len() == n).then_some((k, j, w))
    }

    /// The grid of the focus's particles from their `cells`, which every particle's cell
    /// lies within the cells of the box `(lo, hi)` around them; `cells` go back to the grid
    /// as its buffer.
    pub(super) fn build(
        &self,
        grid: &mut HashGrid,
        cells: Vec<IVec3>,
        (lo, hi): (Vec3, Vec3),
        parallel: bool,
    ) {
        let cell = self.cell;
        let cell_box = (cell_index(lo, cell), cell_index(hi, cell));
        let (active, buckets) = (self.active, self.buckets);
        let build = |grid: &mut HashGrid| grid.build_cells(&cells, active, cell_box, cell, buckets);
        if parallel {
            keeping_the_pool_awake(|| build(grid));
        } else {
            build(grid);
        }
        grid.cells = cells;
    }

    /// One piece's particles at the frames' `span`: their positions, motions, normals and
    /// cells; the box around both ends of their paths and the longest motion, squared.
    pub(super) fn place_piece(
        &self,
        (k, j, w): (usize, usize, f32),
        piece: Piece,
        cells: &mut [IVec3],
    ) -> (Vec3, Vec3, f32) {
        let (a, b, before, cell) = (&self.frames[k], &self.frames[j], self.before, self.cell);
        let normals = (!self.normals.is_empty()).then(|| (&self.normals[k], &self.normals[j]));
        let Piece {
            indices,
            first,
            arrays: [now, motion, normal],
        } = piece;
        // In SIMD lanes (Vec3A): the same operations lane by lane, so the same bits as
        // `Vec3::lerp`, `normalize_or` and `cell_index`, at a third of the divisions.
        let lerp = |a: Vec3, b: Vec3| Vec3A::from(a) * (1.0 - w) + Vec3A::from(b) * w;
        let (mut lo, mut hi) = (Vec3A::from(EMPTY_BOX.0), Vec3A::from(EMPTY_BOX.1));
        let mut fastest = EMPTY_BOX.2;
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
    }
}

/// The box around no particle, and no motion: what [`merge_boxes`] starts from.
pub(super) const EMPTY_BOX: (Vec3, Vec3, f32) = (Vec3::MAX, Vec3::MIN, 0.0);

/// The box around two pieces' boxes, and the longer of their longest motions (exact, in any
/// order).
pub(super) fn merge_boxes(x: (Vec3, Vec3, f32), y: (Vec3, Vec3, f32)) -> (Vec3, Vec3, f32) {
    (x.0.min(y.0), x.1.max(y.1), x.2.max(y.2))
}

/// `n[l].normalize_or(Vec3A::Y)` for four vectors at once, their lengths side by side in one
/// vector: one square root and one division instruction for the four, each lane the same IEEE
/// operations in the same order as one vector's, so the same bits.
#[inline]
pub(super) fn normalize4_or_y(n: [Vec3A; 4]) -> [Vec3A; 4] {
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
pub(super) fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of every x86-64 target.
    unsafe {
        Vec4::from(std::arch::x86_64::_mm_sqrt_ps(v.into()))
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec4::from_array(v.to_array().map(f32::sqrt))
}

/// A run of a focus's particles (ascending indices from `first` on) with the stretch of each
/// per-particle array their indices span: runs do not overlap, so each is moved on its own
/// thread.
pub(super) struct Piece<'a> {
    pub(super) indices: &'a [u32],
    pub(super) first: usize,
    /// Positions, motions and normals (empty without normals) from `first` on.
    pub(super) arrays: [&'a mut [Vec3]; 3],
}

impl<'a> Piece<'a> {
    /// `active` (ascending) in runs of `chunk`, each with its stretch of `arrays`.
    pub(super) fn split(
        active: &'a [u32],
        chunk: usize,
        arrays: [&'a mut [Vec3]; 3],
    ) -> Vec<Piece<'a>> {
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

impl ShellCollider {
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
    pub(super) fn advance_in_one_pass(
        &mut self,
        to: f32,
        before: &[Vec3],
        cell: f32,
        buckets: usize,
    ) -> bool {
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
    pub(super) fn advance_focused(
        &mut self,
        to: f32,
        before: &[Vec3],
        cell: f32,
        buckets: usize,
    ) -> bool {
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

    /// Every other case (small shells, shells re-sampled per frame) step by step.
    pub(super) fn advance_in_steps(&mut self, to: f32, before: &[Vec3], cell: f32, buckets: usize) {
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
}
