//! Contact response: a garment particle pushed out of the shell particles it overlaps, nearest
//! first, with Coulomb friction on its motion relative to the skin; the swept test that stops a
//! path crossing the skin; and the nearby lists the solve's collision passes test.

use super::*;
use glam::{Vec3, Vec4};

/// A garment particle's push out of a shell so far: where it is, the pushes summed, the skin's
/// motion summed over the contacts, and their count (for friction); the side of the skin the
/// first push came from and whether a later one came from the opposite side (a pinch,
/// [`PINCH`]); where the particle was before any push, and the pushes' lengths summed (how hard
/// a pinch squeezes it).
pub(super) struct Contact {
    pub(super) p: Vec3,
    pub(super) push: Vec3,
    pub(super) skin: Vec3,
    pub(super) count: u32,
    pub(super) first: Vec3,
    pub(super) pinched: bool,
    pub(super) start: Vec3,
    pub(super) pressed: f32,
}

impl Contact {
    pub(super) fn new(p: Vec3) -> Contact {
        Contact {
            p,
            push: Vec3::ZERO,
            skin: Vec3::ZERO,
            count: 0,
            first: Vec3::ZERO,
            pinched: false,
            start: p,
            pressed: 0.0,
        }
    }

    /// Counts a push of the skin at a contact whose skin moved by `motion`, from the side of
    /// the skin `side` faces (a unit normal; the push's direction where the shell has none).
    #[inline(always)]
    pub(super) fn add(&mut self, push: Vec3, motion: Vec3, side: Option<Vec3>) {
        let side = side.unwrap_or_else(|| push.normalize_or_zero());
        if side != Vec3::ZERO {
            if self.first == Vec3::ZERO {
                self.first = side;
            } else if side.dot(self.first) < PINCH {
                self.pinched = true;
            }
        }
        self.p += push;
        self.push += push;
        self.pressed += push.length();
        self.skin += motion;
        self.count += 1;
    }
}

/// Two pushes of one garment particle from sides of the skin whose normals' cosine is below this
/// (more than 120° apart) come from two sides of the skin closing on it (a hand against a hip, an arm against
/// the side, the two faces of a thin plate): the particle is *pinched*. Pushed from both sides
/// it would be squeezed out sideways, along the skin, by however far the two reaches overlap,
/// and tear its springs; instead it is held where it was, carried by the skin's mean motion
/// (`tests/pinch.rs`; docs/benchmarks.md, "Pinches").
pub const PINCH: f32 = -0.5;

/// The [`NEARBY`] shell particles nearest a point within two reaches of it, sorted by squared
/// distance and then index (so the same set in any visiting order, a particle visited twice
/// once); `u32::MAX` ends a shorter list.
pub(super) struct Nearest {
    pub(super) list: Nearby,
    pub(super) far: [f32; NEARBY],
    pub(super) len: usize,
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
    pub(super) fn gather(&mut self, now: &[Vec3], p: Vec3, reach: f32, each: &impl Candidates) {
        each.each(|i| self.offer(i as u32, (p - now[i]).length_squared(), reach));
    }

    /// Adds shell particle `i`, `dist2` from the point squared, when within two reaches.
    #[inline(always)]
    pub(super) fn offer(&mut self, i: u32, dist2: f32, reach: f32) {
        if dist2 < 4.0 * reach * reach {
            self.insert(i, dist2);
        }
    }

    #[inline(always)]
    pub(super) fn insert(&mut self, i: u32, dist2: f32) {
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

    pub(super) fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.list[..self.len].iter().map(|&i| i as usize)
    }

    pub(super) fn is_full(&self) -> bool {
        self.len == NEARBY
    }

    /// The squared distance of the first entry (∞ without any).
    pub(super) fn nearest(&self) -> f32 {
        self.far[0]
    }

    /// The squared distance of the last entry.
    pub(super) fn farthest(&self) -> f32 {
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

/// The longest path a swept test traces, in grid cells (`shells.wgsl` has the same, checked by
/// `tests/shaders.rs`): nothing in a bake moves that far in one substep.
pub const SWEPT_PATH_CELLS: f32 = 64.0;

/// Point indices a run's copy moves at once ([`HashGrid::gather_segment`]).
pub(super) const RUN_COPY: usize = 8;

/// Where a swept test gathers the shell particles around a path: [`SHELL_FOUND`] of them, and
/// room for the last run's copy.
pub(super) type Found = [std::mem::MaybeUninit<u32>; SHELL_FOUND + RUN_COPY];

/// A garment particle's [`NEARBY`] shell particles.
pub type Nearby = [u32; NEARBY];

/// How many shell particles `list` holds (its entries come first, then `u32::MAX`).
#[inline]
pub fn listed(list: &Nearby) -> u8 {
    list.iter().take_while(|&&e| e != u32::MAX).count() as u8
}

impl ShellCollider {
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
    pub(super) fn resolve_in_reach(
        &self,
        x: Vec4,
        delta: Vec4,
        radius: f32,
        mut nearby: Option<&mut Nearby>,
    ) -> Vec4 {
        // Paths longer than SWEPT_PATH_CELLS grid cells are not traced (nothing in a bake moves
        // that far in one substep); the end point is still tested.
        let reach = self.radius + radius;
        let x3 = x.truncate();
        let d = delta.truncate();
        let p = x3 + d;
        if self.swept
            && !self.now_normal.is_empty()
            && d.length() <= SWEPT_PATH_CELLS * self.grid.cell
        {
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

    /// How the shell presses a garment particle at `p` of contact `radius`: the mean motion
    /// over the substep of the shell particles it lies within reach of (of the [`NEARBY`]
    /// nearest), and their mean overlap (reach less distance) [m], taken nearest first (the
    /// same in any order of the shell's particles); None when it lies within reach of none. A particle pressed between the skin
    /// and a collider ([`crate::collide::pressed_into`]) is carried by this motion.
    pub fn pressing(&self, p: Vec3, radius: f32) -> Option<(Vec3, f32)> {
        if self.now.is_empty() {
            return None;
        }
        let reach = self.radius + radius;
        let mut nearest = Nearest::default();
        nearest.gather(&self.now, p, reach, &Around(&self.grid, p));
        let (mut motion, mut overlap, mut count) = (Vec3::ZERO, 0.0f32, 0u32);
        for i in nearest.iter() {
            let distance = (p - self.now[i]).length();
            if distance < reach {
                motion += self.motion[i];
                overlap += reach - distance;
                count += 1;
            }
        }
        (count > 0).then(|| (motion / count as f32, overlap / count as f32))
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
    pub(super) fn push_out(
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
    pub(super) fn push_from_nearest(
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
    pub(super) fn push_from(
        &self,
        contact: &mut Contact,
        reach: f32,
        indices: impl Iterator<Item = usize>,
    ) {
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
            // The side of the skin the push comes from: its normal there, or the push's
            // direction on a shell without normals.
            contact.add(push, self.motion[i], self.now_normal.get(i).copied());
        }
    }

    /// The displacement from `x3` to where `contact` ends, after friction on its motion
    /// relative to the skin, limited by μ × the push (Coulomb).
    #[inline(always)]
    pub(super) fn with_friction(&self, x3: Vec3, contact: Contact) -> Vec4 {
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
        if contact.pinched {
            // Held across the gap, carried by the skin; along it, the motion the solve wanted
            // relative to the skin slips past what friction on the squeeze holds back.
            let n = contact.first;
            let wanted = (contact.start - x3) - skin;
            let along = wanted - n * wanted.dot(n);
            let squeeze = contact.pressed / contact.count as f32;
            let held = crate::collide::friction_removed(along, n, self.friction * squeeze);
            return (skin + along - held).extend(0.0);
        }
        let relative = (p - x3) - skin;
        p -= crate::collide::friction_removed(relative, n, self.friction * push_len);
        (p - x3).extend(0.0)
    }

    /// The earliest time (fraction of the substep) at which the path from `x` along `d` crosses
    /// the skin where a shell particle covers it, when the end point lies beyond that particle's
    /// reach (so the end-point push cannot bring it back); and that particle. Needs the skin's
    /// normals (a shell re-sampled per frame has none: then only the end point is tested);
    /// `each` visits the candidates.
    /// `at_end` sees each candidate with its squared distance from the path's end (what
    /// [`Self::push_out`] would compute again).
    pub(super) fn first_contact(
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
}
