//! A focused shell placed ahead: the next substep's positions, motions, normals and grid,
//! placed while the team finishes the current substep (inside `finish`), so that no thread
//! waits for it before the next one. Every thread of the team places a part of the focus's
//! particles (parts write disjoint stretches of the buffers), then the leader sorts them into
//! the grid while the others finish the substep's particles; the next [`ShellCollider::advance`]
//! takes it. One thread placing it all was the critical path of a small garment's `finish` on
//! two threads (`docs/benchmarks.md`, stop 67).

use super::placement::{merge_boxes, Piece, Placing, EMPTY_BOX};
use super::*;
use glam::IVec3;
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// A focused shell placed at the end of the next substep ahead of time
/// ([`ShellCollider::place_ahead_part`]), with the buffers it is placed into.
#[derive(Debug, Default)]
pub(super) struct Ahead {
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
    /// Where the parts write, from [`ShellCollider::prepare_ahead`] to the placement's end.
    buffers: Option<Buffers>,
}

/// The memory of a placement's buffers: per shell particle (positions, motions, normals: null
/// without normals) and per focus particle (cells). It stays put from
/// [`ShellCollider::prepare_ahead`] (which sizes them) until the leader's
/// [`ShellCollider::finish_ahead`].
#[derive(Clone, Copy, Debug)]
struct Buffers {
    now: *mut Vec3,
    motion: *mut Vec3,
    normal: *mut Vec3,
    cells: *mut IVec3,
    /// The focus it was sized for (`focus_made`).
    focus: u64,
}

/// The slot a team's threads place a shell ahead into through a shared reference, and how
/// far they are. A copy of the shell starts with it empty.
///
/// Its discipline: [`ShellCollider::prepare_ahead`] and [`ShellCollider::take_ahead`] hold the
/// shell mutably (between team regions); inside a region each part writes only the stretch
/// of the buffers its particles span, then counts itself in `placed` (release); the leader
/// reads and finishes the whole only once every part is counted (acquire), and no part
/// touches the slot after counting itself.
#[derive(Debug, Default)]
pub(super) struct AheadSlot {
    ahead: UnsafeCell<Ahead>,
    /// Parts of the placement under way that are placed.
    placed: AtomicUsize,
    /// Their boxes and fastest motions, squared (None: the frames did not fit the shell).
    parts: Mutex<Vec<Option<(Vec3, Vec3, f32)>>>,
}

// SAFETY: the slot is shared by the team's threads under the discipline above; the raw
// pointers in `Buffers` point into its own vectors.
unsafe impl Sync for AheadSlot {}
unsafe impl Send for AheadSlot {}

impl Clone for AheadSlot {
    fn clone(&self) -> AheadSlot {
        AheadSlot::default()
    }
}

impl ShellCollider {
    /// Sizes the buffers of a placement ahead for the current focus and clears the last one's
    /// parts (between team regions, before [`Self::place_ahead_part`]). Nothing for a shell
    /// without a focus.
    pub fn prepare_ahead(&mut self) {
        let Some(focus) = &self.focus else {
            return;
        };
        let n = self.frames[0].len();
        let ahead = self.ahead.ahead.get_mut();
        ahead.ready = false;
        ahead.now.resize(n, Vec3::ZERO);
        ahead.motion.resize(n, Vec3::ZERO);
        let normal = if self.normals.is_empty() {
            std::ptr::null_mut()
        } else {
            ahead.normal.resize(n, Vec3::ZERO);
            ahead.normal.as_mut_ptr()
        };
        // Every entry is written by the parts: sized, not cleared.
        ahead.grid.cells.resize(focus.active.len(), IVec3::ZERO);
        ahead.buffers = Some(Buffers {
            now: ahead.now.as_mut_ptr(),
            motion: ahead.motion.as_mut_ptr(),
            normal,
            cells: ahead.grid.cells.as_mut_ptr(),
            focus: self.focus_made,
        });
        *self.ahead.placed.get_mut() = 0;
        self.ahead
            .parts
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
    }

    /// Places part `part` of `parts` of the focus's particles at the end of the next substep
    /// (ending at fractional frame `to`), for garment particles of contact radius up to
    /// `garment_radius`: their positions, motions, normals and cells, and counts the part
    /// placed. Every part of a placement is placed by one thread of the team, once, after
    /// [`Self::prepare_ahead`]; then the leader calls [`Self::finish_ahead`]. Nothing unless
    /// [`Self::ahead_prepared`].
    pub fn place_ahead_part(&self, to: f32, garment_radius: f32, part: usize, parts: usize) {
        let (Some(out), Some(focus)) = (self.prepared(), &self.focus) else {
            return;
        };
        let placing = self.placing(&focus.active, garment_radius);
        let placed = placing.span(to).map(|span| {
            let active = &focus.active;
            let share = active.len() * part / parts..active.len() * (part + 1) / parts;
            let indices = &active[share.clone()];
            let (Some(&first), Some(&last)) = (indices.first(), indices.last()) else {
                return EMPTY_BOX;
            };
            let (first, end) = (first as usize, last as usize + 1);
            let stretch = |p: *mut Vec3| {
                if p.is_null() {
                    return &mut [][..];
                }
                // SAFETY: the focus's indices ascend and the parts' shares do not overlap, so
                // no other part writes or reads `first..end` of a buffer of the shell's size.
                unsafe { std::slice::from_raw_parts_mut(p.add(first), end - first) }
            };
            // SAFETY: `share` of the cells, sized for the focus, is this part's alone.
            let cells =
                unsafe { std::slice::from_raw_parts_mut(out.cells.add(share.start), share.len()) };
            let piece = Piece {
                indices,
                first,
                arrays: [stretch(out.now), stretch(out.motion), stretch(out.normal)],
            };
            placing.place_piece(span, piece, cells)
        });
        (self.ahead.parts.lock().unwrap_or_else(|e| e.into_inner())).push(placed);
        self.ahead.placed.fetch_add(1, Ordering::Release);
    }

    /// Whether the shell is prepared for a placement ahead ([`Self::prepare_ahead`] since its
    /// focus was made, and it has a position): then every part counts itself placed, and the
    /// leader finishes it.
    pub fn ahead_prepared(&self) -> bool {
        self.prepared().is_some()
    }

    /// The buffers of the placement under way, when [`Self::ahead_prepared`].
    fn prepared(&self) -> Option<Buffers> {
        self.focus.as_ref().and(self.now_at)?;
        // SAFETY: `buffers` is written only by `prepare_ahead` (holding the shell mutably) and
        // by `finish_ahead` once every part has read it (the slot's discipline).
        let buffers = unsafe { (*self.ahead.ahead.get()).buffers };
        buffers.filter(|b| b.focus == self.focus_made)
    }

    /// Parts of the placement under way counted placed so far.
    pub fn ahead_parts_placed(&self) -> usize {
        self.ahead.placed.load(Ordering::Acquire)
    }

    /// Once every part is placed ([`Self::ahead_parts_placed`]): the grid of the placed
    /// particles, the box around them and their fastest motion, and the placement marked ready
    /// for the substep from where the shell is now to `to` (the leader's, inside `finish`).
    pub fn finish_ahead(&self, to: f32, garment_radius: f32) {
        let (true, Some(focus), Some(from)) = (self.ahead_prepared(), &self.focus, self.now_at)
        else {
            return;
        };
        // SAFETY: every part is counted placed, and none touches the slot after that (the
        // slot's discipline): this thread has it alone until the region ends.
        let ahead = unsafe { &mut *self.ahead.ahead.get() };
        ahead.buffers = None;
        let parts =
            std::mem::take(&mut *self.ahead.parts.lock().unwrap_or_else(|e| e.into_inner()));
        let merged = parts
            .into_iter()
            .try_fold(EMPTY_BOX, |all, part| part.map(|p| merge_boxes(all, p)));
        let Some((lo, hi, fastest)) = merged else {
            return;
        };
        let placing = self.placing(&focus.active, garment_radius);
        let cells = std::mem::take(&mut ahead.grid.cells);
        placing.build(&mut ahead.grid, cells, (lo, hi), false);
        ahead.ready = true;
        ahead.span = (from, to);
        ahead.focus = self.focus_made;
        ahead.lattice = (placing.cell, placing.buckets);
        ahead.bounds = (lo, hi);
        ahead.fastest = fastest.sqrt().max(focus.left_out_fastest);
    }

    /// Places the focus's particles ahead on the calling thread alone (prepared, one part,
    /// finished): what a team of one does.
    pub fn place_ahead(&mut self, to: f32, garment_radius: f32) {
        self.prepare_ahead();
        self.place_ahead_part(to, garment_radius, 0, 1);
        self.finish_ahead(to, garment_radius);
    }

    /// What placing `active` for garment particles of contact radius up to `garment_radius`
    /// reads, from where the shell is now.
    fn placing<'a>(&'a self, active: &'a [u32], garment_radius: f32) -> Placing<'a> {
        Placing {
            frames: &self.frames,
            normals: &self.normals,
            active,
            before: &self.now,
            cell: self.cell_for(garment_radius),
            buckets: Self::buckets_for(self.most_particles()),
        }
    }

    /// Takes the shell placed ahead for the substep from `from` to `to`, when it was placed for
    /// that substep, lattice and focus; false otherwise (then nothing changed).
    pub(super) fn take_ahead(&mut self, from: f32, to: f32, cell: f32, buckets: usize) -> bool {
        let ahead = self.ahead.ahead.get_mut();
        ahead.buffers = None;
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

    /// Substeps so far that took the shell placed ahead for them.
    pub fn taken_ahead(&self) -> u64 {
        self.taken_ahead
    }
}
