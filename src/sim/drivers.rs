//! Drivers: what moves the garments from outside the solve (colliders and their keyframed
//! motion, characters' shells, attached particles' targets), the clock they run on, and the
//! shells' focus. The CPU backend places them substep by substep between its team regions; a
//! backend that runs whole frames elsewhere (the GPU) takes a frame of them at once
//! ([`Drivers::drive_frame`]) with the state, and nothing else of the simulation.

use super::attach::{Attachments, Track};
use super::schedule;
use super::state::State;
use crate::collide::shell::{NearGarments, ShellSnapshot};
use crate::collide::{Collider, Shape, ShellCollider};
use crate::scene::Scene;
use glam::{Vec3, Vec4};
use std::sync::atomic::{AtomicBool, Ordering};

/// How much farther than their motion predicts the garments may go before the shells' focus is
/// made again [m]: where a bake starts ([`Focus::slack`]), and the least and most it goes to.
/// A wider slack places more shell particles every substep; a narrower one makes the focus again
/// within frames more often. Which pays depends on the scene (measured in `docs/benchmarks.md`,
/// stop 66: capes, ponchos and the top faster at 0.005 m, the blanket and P at 0.02 m).
const FOCUS_SLACK: f32 = 0.02;
const FOCUS_SLACK_RANGE: (f32, f32) = (0.005, 0.08);

/// What a frame without a focus made within it keeps of the slack: it narrows slowly, and
/// doubles at each focus made within a frame.
const FOCUS_SLACK_KEPT: f32 = 0.9;

/// Everything that moves the garments from outside, on one clock.
pub struct Drivers {
    pub colliders: Vec<Collider>,
    /// Keyframed colliders: (index in `colliders`, motion, shape at rest).
    collider_motion: Vec<(usize, Track, Shape)>,
    /// Characters' collision shells.
    pub shells: Vec<ShellCollider>,
    /// Particles following animated targets.
    pub attachments: Attachments,
    pub clock: Clock,
    /// Fastest any attached particle, keyframed collider or skin has moved so far [m/s].
    pub(super) driven_speed: f32,
    pub focus: Focus,
}

/// The simulation's clock: substeps run so far, per frame, and their length.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    /// Substeps simulated since the bake's start.
    pub(super) elapsed: u64,
    pub substeps: u32,
    /// Length of one substep [s].
    pub step: f32,
    /// Frames per second (the clock of characters and keyframes).
    pub fps: f32,
}

impl Clock {
    /// The time at the end of the coming substep [s].
    pub(super) fn next_time(&self) -> f32 {
        self.end_of(self.elapsed)
    }

    /// The time at the end of substep `substep`, counted from the bake's start [s].
    pub fn end_of(&self, substep: u64) -> f32 {
        (substep + 1) as f32 / (self.substeps as f32 * self.fps)
    }

    /// The time now [s].
    pub(super) fn time(&self) -> f32 {
        self.elapsed as f32 / (self.substeps as f32 * self.fps)
    }

    /// Substeps simulated since the bake's start.
    pub fn elapsed(&self) -> u64 {
        self.elapsed
    }
}

/// The shells' focus on the garments (see `collide::shell`'s `Focus`): where the garment
/// particles were when it was made and how far it lets them go, and the check the last
/// substep's `finish` made of it.
#[derive(Default)]
pub struct Focus {
    /// Whether the CPU focuses shells at all (on by default; off shows what it saves).
    pub enabled: bool,
    /// Per particle: where it was when the focus was made, and how far from there it may go [m].
    pub(super) origin: Vec<(Vec4, f32)>,
    /// The substep count at which `outran` tells whether the focus holds (set by the last
    /// substep's `finish`, within [`super::Simulation::step_frame`] only).
    pub(super) checked_at: Option<u64>,
    pub(super) outran: AtomicBool,
    /// How much farther than its motion predicts a particle may go [m]; adapts as the bake
    /// goes ([`FOCUS_SLACK_KEPT`]). The frames do not depend on it, only what placing costs.
    pub(super) slack: f32,
    /// Whether the focus was made again within the frame under way.
    pub(super) remade_within: bool,
}

impl Focus {
    /// Before the focus is made: at a frame's start (`frame_start`), the slack narrows unless
    /// the last frame made it again within; within a frame, it doubles.
    fn adapt_slack(&mut self, frame_start: bool) {
        let (least, most) = FOCUS_SLACK_RANGE;
        self.slack = match (frame_start, self.remade_within) {
            (true, true) => self.slack,
            (true, false) => (self.slack * FOCUS_SLACK_KEPT).max(least),
            (false, _) => (self.slack * 2.0).min(most),
        };
        self.remade_within = !frame_start;
    }
}

/// What drives one frame, substep by substep, that only the CPU can place (see
/// [`Drivers::drive_frame`]).
#[derive(Clone, Debug, Default)]
pub struct DrivenFrame {
    /// Per substep, per character shell: [`ShellCollider::gpu_snapshot`] (None for a shell
    /// that never moves, unless asked for, then with the first substep only: the GPU keeps it
    /// from its first upload; and None for a shell the GPU places itself).
    pub shells: Vec<Vec<Option<ShellSnapshot>>>,
}

impl Drivers {
    /// The colliders of `scene` (swept as it says) with their keyframed motion, `attachments`,
    /// no shells yet, and the clock at zero.
    pub(super) fn new(scene: &Scene, attachments: Attachments) -> Drivers {
        let colliders = (scene.colliders.iter())
            .map(|spec| Collider {
                swept: scene.swept_collisions,
                ..Collider::from_spec(spec)
            })
            .collect();
        let collider_motion = (scene.colliders.iter().enumerate())
            .filter(|(_, spec)| !spec.keyframes.is_empty())
            .map(|(i, spec)| {
                let shape = Collider::from_spec(spec).shape;
                (i, Track::new(&spec.keyframes, shape.centre()), shape)
            })
            .collect();
        let substeps = scene.substeps_per_frame();
        Drivers {
            colliders,
            collider_motion,
            shells: Vec::new(),
            attachments,
            clock: Clock {
                elapsed: 0,
                substeps,
                step: scene.step_seconds(),
                fps: scene.fps,
            },
            driven_speed: 0.0,
            focus: Focus {
                enabled: true,
                slack: FOCUS_SLACK,
                ..Focus::default()
            },
        }
    }

    /// True when anything here moves between substeps (a frame then runs substep by substep
    /// on the CPU).
    pub(super) fn move_within_frames(&self) -> bool {
        !self.shells.is_empty() || !self.attachments.list.is_empty() || self.moving_colliders()
    }

    /// True when some collider follows keyframes.
    pub fn moving_colliders(&self) -> bool {
        !self.collider_motion.is_empty()
    }

    /// The keyframed colliders: (index in `colliders`, motion, shape at rest).
    pub fn collider_motion(&self) -> &[(usize, Track, Shape)] {
        &self.collider_motion
    }

    /// Puts every attached particle of `state` where its target is at the end of the coming
    /// substep, with the velocity that got it there, and every keyframed collider in its pose
    /// then.
    pub(super) fn place_attachments(&mut self, state: &mut State) {
        let t = self.clock.next_time();
        self.pose_colliders(t);
        let (step, fps) = (self.clock.step, self.clock.fps);
        for a in &self.attachments.list {
            let i = a.particle as usize;
            let target = self.attachments.position(a, t, fps).extend(0.0);
            state.velocities[i] = (target - state.positions[i]) / step;
            self.driven_speed = self.driven_speed.max(state.velocities[i].length());
            state.positions[i] = target;
        }
    }

    /// Starts the attached particles that were bound outside the body they started in
    /// ([`Attachments::lifted`]) at their targets now, so the first substep does not fling
    /// them out (nor count that as the driven speed).
    pub fn start_lifted(&self, state: &mut State) {
        let (t, fps) = (self.clock.time(), self.clock.fps);
        let lifted = &self.attachments.lifted;
        for a in self
            .attachments
            .list
            .iter()
            .filter(|a| lifted.contains(&a.particle))
        {
            state.positions[a.particle as usize] = self.attachments.position(a, t, fps).extend(0.0);
        }
    }

    /// Every keyframed collider in its pose at time `t` [s], with how far it moved to get there
    /// (counted in the driven speed).
    pub(super) fn pose_colliders(&mut self, t: f32) {
        self.set_collider_poses(t);
        for (i, _, _) in &self.collider_motion {
            let moved = self.colliders[*i].moved.length();
            self.driven_speed = self.driven_speed.max(moved / self.clock.step);
        }
    }

    /// Every keyframed collider back in its shape at rest, as the bake starts (not moved).
    pub(super) fn rest_colliders(&mut self) {
        for (i, _, rest) in &self.collider_motion {
            let c = &mut self.colliders[*i];
            c.shape = *rest;
            c.moved = glam::Vec3::ZERO;
        }
    }

    /// Every keyframed collider in its pose at time `t` [s], with how far it moved to get there.
    fn set_collider_poses(&mut self, t: f32) {
        for (i, track, rest) in &self.collider_motion {
            let (rotation, translation) = track.pose(t);
            let shape = rest.moved(track.pivot, rotation, translation);
            let c = &mut self.colliders[*i];
            c.moved = shape.centre() - c.shape.centre();
            c.shape = shape;
        }
    }

    /// Moves the characters' shells not marked in `skip` to the end of the coming substep,
    /// gridded for contacts of `reach` [m].
    pub(super) fn advance_shells_but(&mut self, skip: &[bool], reach: f32) {
        if self.shells.is_empty() {
            return;
        }
        let per_frame = self.clock.substeps as f32;
        let from = self.clock.elapsed as f32 / per_frame;
        let to = (self.clock.elapsed + 1) as f32 / per_frame;
        for (i, s) in self.shells.iter_mut().enumerate() {
            if skip.get(i) == Some(&true) {
                continue;
            }
            s.advance(from, to, reach);
            self.driven_speed = self.driven_speed.max(s.fastest_motion() / self.clock.step);
        }
    }

    /// Moves the shells marked in `whole` over the coming frame in one go (their positions at
    /// its end serve the metrics; their motion over it, spread over its substeps, the driven
    /// speed): for shells a GPU places itself substep by substep.
    fn advance_shells_over_frame(&mut self, whole: &[bool], reach: f32) {
        let per_frame = self.clock.substeps as f32;
        let from = self.clock.elapsed as f32 / per_frame;
        let to = (self.clock.elapsed + self.clock.substeps as u64) as f32 / per_frame;
        for (s, _) in self.shells.iter_mut().zip(whole).filter(|(_, &w)| w) {
            s.advance(from, to, reach);
            let per_substep = s.fastest_motion() / per_frame;
            self.driven_speed = self.driven_speed.max(per_substep / self.clock.step);
        }
    }

    /// The characters' shells of each substep of the next frame that the GPU does not place
    /// itself; advances the clock by a frame as if it ran, leaving the keyframed colliders in
    /// their last pose: for a backend that runs the frame elsewhere (the GPU) and copies the
    /// state back. That backend evaluates the keyframed attachments and colliders and the
    /// attachments that ride skins itself, and adds their fastest motion to the driven speed
    /// ([`Drivers::note_driven_speed`]). `static_shells`: include the shells that never move
    /// too, with the first substep (the GPU needs them once). The shells marked in
    /// `placed_elsewhere` (the GPU places them from their skins) have no snapshots: they are
    /// moved over the whole frame at once. `reach`: the largest contact radius the shells are
    /// gridded for; the shells' time goes to `times`.
    pub fn drive_frame(
        &mut self,
        reach: f32,
        static_shells: bool,
        placed_elsewhere: &[bool],
        times: &mut schedule::StageTimes,
    ) -> DrivenFrame {
        // The GPU reads every shell particle.
        for s in &mut self.shells {
            s.unfocus();
        }
        let mut frame = DrivenFrame::default();
        let start = std::time::Instant::now();
        self.advance_shells_over_frame(placed_elsewhere, reach);
        times.lap(schedule::timed("shells"), start);
        for substep in 0..self.clock.substeps {
            let start = std::time::Instant::now();
            self.advance_shells_but(placed_elsewhere, reach);
            frame.shells.push(
                (self.shells.iter().enumerate())
                    .map(|(i, s)| {
                        let elsewhere = placed_elsewhere.get(i) == Some(&true);
                        // A shell that never moves: once, with the first substep.
                        let once = static_shells && substep == 0;
                        let wanted = !elsewhere && (once || !s.is_static());
                        wanted.then(|| s.gpu_snapshot())
                    })
                    .collect(),
            );
            times.lap(schedule::timed("shells"), start);
            if substep + 1 == self.clock.substeps {
                // The last pose, and the motion of the last substep into it, as the CPU
                // leaves them (at the bake's start the colliders are at rest); their speed
                // is the backend's to measure.
                if self.clock.elapsed > 0 {
                    self.set_collider_poses(self.clock.time());
                }
                self.set_collider_poses(self.clock.next_time());
            }
            self.clock.elapsed += 1;
        }
        frame
    }

    /// Adds a motion a backend measured elsewhere (keyframed targets on the GPU) to the
    /// fastest driven motion so far [m/s].
    pub fn note_driven_speed(&mut self, speed: f32) {
        self.driven_speed = self.driven_speed.max(speed);
    }

    /// Keeps each shell focused on the particles of `state` that can come near the garments:
    /// at a frame's start (`frame_start`), or when a garment particle is about to go farther
    /// from where it was when the focus was made than the focus allows it. The focus allows
    /// each particle its own speed and gravity `g` [m/s²] over a frame, twice, plus the slack
    /// ([`Focus::slack`]); before each substep, each particle must be within that of its place
    /// then, less twice its own motion in a substep and twice the shells' fastest. `contact`:
    /// the largest contact radius [m].
    pub(super) fn focus_shells(&mut self, state: &State, g: f32, contact: f32, frame_start: bool) {
        if !self.focus.enabled || !self.shells.iter().any(|s| s.can_focus()) {
            return;
        }
        if !frame_start && self.focus.origin.len() == state.positions.len() {
            // Checked by the last substep's `finish` as it committed each particle, when it could.
            let holds = if self.focus.checked_at == Some(self.clock.elapsed) {
                !self.focus.outran.load(Ordering::Relaxed)
            } else {
                let terms = self.focus_terms(g);
                (state.positions.iter().zip(&state.velocities))
                    .zip(&self.focus.origin)
                    .all(|((p, v), o)| super::stages::focus_holds_for(*p, *v, *o, terms))
            };
            if holds {
                return;
            }
        }
        self.focus.adapt_slack(frame_start);
        let frame = 1.0 / self.clock.fps;
        let slack = self.focus.slack;
        let allowance = |v: &Vec4| 2.0 * (v.length() * frame + g * frame * frame) + slack;
        self.focus.origin.clear();
        self.focus.origin.extend(
            (state.positions.iter().zip(&state.velocities)).map(|(p, v)| (*p, allowance(v))),
        );
        let shell_radius = self.shells.iter().map(|s| s.radius).fold(0.0, f32::max);
        let reach = contact + shell_radius;
        let reaches: Vec<(Vec3, f32)> = (self.focus.origin.iter())
            .map(|(p, allowed)| (p.truncate(), allowed + 2.0 * reach))
            .collect();
        let near = NearGarments::new(&reaches, 4.0 * reach);
        let from = self.clock.elapsed as f32 / self.clock.substeps as f32;
        let per_substep = 1.0 / self.clock.substeps as f32;
        for s in &mut self.shells {
            s.focus(from, &near, per_substep);
        }
    }

    /// What `focus_holds_for` allows for besides each particle's own motion: the substep,
    /// gravity `g` and the shells' fastest motion in the current substep.
    pub(super) fn focus_terms(&self, g: f32) -> (f32, f32, f32) {
        let carried = (self.shells.iter())
            .map(|s| s.fastest_motion())
            .fold(0.0, f32::max);
        (self.clock.step, g, carried)
    }

    /// Whether the last substep's `finish` checks the focus for the next one: it is on, made
    /// for `particles` particles, and some shell is focused.
    pub(super) fn focus_checkable(&self, particles: usize) -> bool {
        self.focus.enabled
            && self.focus.origin.len() == particles
            && self.shells.iter().any(|s| s.focused().is_some())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_focus_slack_narrows_over_quiet_frames_and_doubles_when_outrun() {
        let mut focus = Focus {
            slack: FOCUS_SLACK,
            ..Focus::default()
        };
        let (least, most) = FOCUS_SLACK_RANGE;
        // Quiet frames: a frame start after a frame made no focus within it narrows the slack,
        // down to the least.
        focus.adapt_slack(true);
        assert_eq!(focus.slack, FOCUS_SLACK * FOCUS_SLACK_KEPT);
        for _ in 0..100 {
            focus.adapt_slack(true);
        }
        assert_eq!(focus.slack, least);
        // Outrun within a frame: doubled; the next frame start keeps it; then narrows again.
        focus.adapt_slack(false);
        assert_eq!(focus.slack, 2.0 * least);
        focus.adapt_slack(true);
        assert_eq!(focus.slack, 2.0 * least);
        focus.adapt_slack(true);
        assert_eq!(focus.slack, 2.0 * least * FOCUS_SLACK_KEPT);
        // Outrun again and again: up to the most.
        for _ in 0..100 {
            focus.adapt_slack(false);
        }
        assert_eq!(focus.slack, most);
    }
}
