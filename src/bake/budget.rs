//! Accuracy targets choose the budget: with `accuracy` in the scene, drape starts each bake at a
//! cheap setting and measures every frame's worst strain and deepest penetration; a frame that
//! misses a target is simulated again from its start state at the next level of [`LADDER`],
//! a frame that comes within a quarter of a target raises the level for the next frame, and
//! after [`CALM_FRAMES`] frames in a row that met both targets with half the margin to
//! spare, the next frame tries one level lower.
//!
//! A frame that misses even at the cap may miss for reasons no budget reaches (cloth pressed
//! between body parts, a pose that forces it), and the cap costs 16 times the cheapest level:
//! after [`CALM_FRAMES`] such frames in a row the budget descends, a window of [`CALM_FRAMES`]
//! frames a level, while each window misses the targets by no more than the one above it (by
//! less than [`FUTILE_SHARE`] of that window's margin: [`Targets::excess`]); the frames of a
//! descent are kept when they miss (the report marks them `kept_missing`). A window that misses
//! by more sends the budget back up one level, where misses are kept for [`HOLD_FRAMES`] frames
//! before raising is tried again. Windows, not one frame simulated at two budgets, since a
//! frame starts from the state the frames before it left: simulated again at a larger budget,
//! a frame whose cloth a cheap budget let tangle is no better, whatever the budget could have
//! done from the start.
//!
//! Substeps and iterations the scene gives itself stay fixed (the ladder moves only what it
//! leaves out); collision passes follow the iterations when the scene has them on. Every
//! decision depends only on the frames, so a bake gives the same frames every time.
//!
//! Without targets, a bake whose scene leaves drape its substeps or its iterations
//! starts at the scene's budget (drape's defaults for what it leaves out) and answers to the
//! stability rule alone ([`Targets::stability`]): a frame the rule rejects is simulated again at
//! the next of its levels, finer than the ladder's ([`STABILITY_STEPS`]; the three frames after
//! a raise settle, as with targets), and [`CALM_FRAMES`] frames in a row at half the rule's
//! strain ([`STABLE_STRAIN`]) or less lower the budget a level, never below the scene's. No
//! frame raises the next one's budget ahead of a miss (cloth pinched or caught keeps its strain
//! at any budget: [`Targets::close`]). A budget left to drape should not end a bake that a
//! larger one would carry; a scene that gives both keeps them, and a bake then stops where it
//! goes unstable.
//!
//! Both backends: the GPU reads a frame's start back (with its nearby shell lists) and takes
//! each new budget with the state it starts from; the frames that settle run on the CPU, which
//! caps kinetic energy substep by substep, and the GPU takes their end.

pub use crate::report::{BudgetKind, BudgetReport, FrameBudget};
use crate::scene::Scene;
use crate::sim::Simulation;
use serde::{Deserialize, Serialize};

/// The budgets tried, cheapest first: (substeps per frame, outer iterations). The last is the
/// cap: a frame that misses a target there is kept and the bake ends with exit 1.
pub const LADDER: [(u32, u32); 8] = [
    (5, 2),
    (10, 2),
    (10, 5),
    (20, 5),
    (20, 10),
    (40, 10),
    (40, 20),
    (80, 20),
];

/// The stability rule's strain (`scenes.md`: a spring stretched past 100 % stops a bake). A
/// budget that answers to stability alone lowers itself after [`CALM_FRAMES`] frames in a row
/// at half of it or less, down to the scene's own.
pub const STABLE_STRAIN: f64 = 1.0;

/// The levels of a budget that answers to stability alone, as multiples of what the scene
/// leaves out (its substeps, else its iterations): finer than [`LADDER`], whose levels double
/// the cost, since a frame that goes unstable needs a shorter substep, not an accurate one.
/// `poncho_walk` left to drape at 24 fps goes unstable at 10 substeps and bakes at 60 × 10
/// (7.3–9.7 s, 65–92 ms a frame); on the ladder it went from 40 × 10 to 40 × 20 and then the
/// cap of 80 × 20 (18.2–20.2 s, 165–224 ms a frame).
pub const STABILITY_STEPS: [f64; 7] = [1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];

/// Frames in a row with a large margin after which a lower budget is tried.
pub const CALM_FRAMES: u32 = 10;

/// How much more a window of frames one level lower may miss the targets by, as a share of the
/// margin the window above missed them by ([`Targets::excess`] less 1, in the mean), for the
/// budget to go on descending: a quarter. `top_walk` at a 10 % strain target misses in most
/// frames at any level from 10 × 5 up (its median frame: 20 % at 10 × 5, 12 % at 20 × 10, 16 %
/// at 80 × 20), while a frame of the solver's making misses by about half as much a level up.
pub const FUTILE_SHARE: f64 = 0.25;

/// Frames whose misses keep their budget after a descent found the level below missing by
/// more: half a second at 60 fps, then a miss raises again.
pub const HOLD_FRAMES: u32 = 30;

/// Frames after a raise whose kinetic energy is capped ([`Simulation::settle_frame`]): the
/// springs a cheaper budget left stretched shorten over about two frames at the next budget.
pub const SETTLE_FRAMES: u32 = 3;

/// The running state of the budget (carried through checkpoints).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct BudgetState {
    /// Index into the ladder of the coming frame.
    pub level: usize,
    /// Frames in a row that met both targets with half the margin to spare.
    pub calm: u32,
    /// Why the budget changed after the last frame, for the next frame's record.
    pub pending_why: String,
    /// Frames still to settle after the last raise ([`SETTLE_FRAMES`]; absent in checkpoints
    /// of drape before settling: none).
    #[serde(default)]
    pub settle: u32,
    /// Frames in a row that missed a target at the cap, and the sum of their
    /// [`Targets::excess`] (absent in older checkpoints: none).
    #[serde(default)]
    pub capped: (u32, f64),
    /// The descent under way, if one is.
    #[serde(default)]
    pub descent: Option<Descent>,
    /// Frames still to keep their budget when they miss, after a descent ended
    /// ([`HOLD_FRAMES`]).
    #[serde(default)]
    pub hold: u32,
}

/// A descent from the cap: the window of frames at the current level so far, against the mean
/// [`Targets::excess`] of the window at the level above.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Descent {
    pub above: f64,
    pub frames: u32,
    pub sum: f64,
}

impl BudgetState {
    /// Whether a frame that misses a target may be simulated again at a larger budget: not
    /// during a descent or a hold (a frame that goes unstable always may).
    pub fn may_raise(&self) -> bool {
        self.descent.is_none() && self.hold == 0
    }

    /// Moves to the next level up for a frame simulated again: it settles, and a descent ends.
    pub fn raise(&mut self) {
        self.level += 1;
        self.calm = 0;
        self.settle = SETTLE_FRAMES;
        self.descent = None;
    }

    /// Chooses the next frame's level from this frame's reading `r` (taken at `self.level`):
    /// returns why it changed, None when it did not. The caller applies the level.
    pub fn after_frame(&mut self, t: &Targets, r: Reading) -> Option<String> {
        let top = t.levels.len() - 1;
        let met = t.missed(r).is_none();
        let excess = t.excess(r).min(1e6);
        self.settle = self.settle.saturating_sub(1);
        self.hold = self.hold.saturating_sub(1);
        if let Some(d) = self.descent.as_mut() {
            d.frames += 1;
            d.sum += excess;
            if d.frames < CALM_FRAMES {
                return None;
            }
            let (above, here) = (d.above, d.sum / f64::from(d.frames));
            if here - above > FUTILE_SHARE * (above - 1.0).max(0.0) {
                self.raise();
                self.hold = HOLD_FRAMES;
                return Some(format!("{CALM_FRAMES} frames a level lower missed the targets by more ({here:.2} of them against {above:.2}, in the mean): raised back, misses kept for {HOLD_FRAMES} frames"));
            }
            if self.level == 0 {
                self.descent = None;
                self.hold = HOLD_FRAMES;
                return None;
            }
            *d = Descent {
                above: here,
                frames: 0,
                sum: 0.0,
            };
            self.level -= 1;
            self.calm = 0;
            return Some(format!("{CALM_FRAMES} frames missed the targets by no more than a level higher ({here:.2} of them against {above:.2}, in the mean): lowered"));
        }
        if !met && self.level == top && top > 0 && self.hold == 0 {
            self.capped = (self.capped.0 + 1, self.capped.1 + excess);
            if self.capped.0 < CALM_FRAMES {
                return None;
            }
            let above = self.capped.1 / f64::from(self.capped.0);
            self.capped = (0, 0.0);
            self.descent = Some(Descent {
                above,
                frames: 0,
                sum: 0.0,
            });
            self.level -= 1;
            self.calm = 0;
            self.settle = 0;
            return Some(format!("{CALM_FRAMES} frames missed the targets at the largest budget ({above:.2} of them, in the mean): lowered, to see whether the budget is what holds them off"));
        }
        self.capped = (0, 0.0);
        if met && t.close(r) && self.level < top && self.hold == 0 {
            self.raise();
            // Never with stability alone: `close` is false there.
            return Some("the last frame came within a quarter of a target: raised".into());
        }
        if !t.calm(r) {
            self.calm = 0;
            return None;
        }
        self.calm += 1;
        if self.calm < CALM_FRAMES || self.level == 0 {
            return None;
        }
        self.level -= 1;
        self.calm = 0;
        Some(match t.kind {
            BudgetKind::Targets => {
                format!("{CALM_FRAMES} frames with half the margin to spare: lowered")
            }
            BudgetKind::Stability => {
                format!("{CALM_FRAMES} frames at half the stability rule's strain or less: lowered")
            }
        })
    }
}

impl FrameBudget {
    /// What the targets judged this frame by.
    pub fn reading(&self) -> Reading {
        Reading {
            strain: self.max_strain,
            depth: self.deepest_penetration,
            shear: self.max_shear_deg,
        }
    }
}

/// What the targets judge a frame by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// The worst structural strain.
    pub strain: f64,
    /// The deepest a free particle is inside a collider, a shell or a character's mesh [m].
    pub depth: f32,
    /// The worst |90° − angle| of a lattice cell [degrees].
    pub shear: f64,
}

/// The targets and the ladder a scene's budget moves on.
#[derive(Clone, Debug)]
pub struct Targets {
    pub max_strain: Option<f64>,
    pub max_penetration: Option<f32>,
    pub max_shear: Option<f64>,
    /// The levels this scene can use: the ladder with its own substeps or iterations fixed.
    pub levels: Vec<(u32, u32)>,
    /// Collision passes on (then as many as iterations) or off.
    pub passes: bool,
    /// What moves the budget: the targets above, or stability alone (then there are none).
    pub kind: BudgetKind,
    /// Collision passes that stay the scene's own at every level (stability alone), instead of
    /// following the iterations.
    pub fixed_passes: Option<u32>,
}

impl Targets {
    /// The targets of `scene`, None without `accuracy`.
    pub fn of(scene: &Scene) -> Option<Targets> {
        let a = scene.accuracy.as_ref()?;
        let fixed_substeps = (scene.substeps.is_some() || scene.timestep.is_some())
            .then(|| scene.substeps_per_frame());
        let fixed_iterations = scene.iterations_given.then_some(scene.solver.iterations);
        let mut levels: Vec<(u32, u32)> = LADDER
            .iter()
            .map(|&(s, i)| (fixed_substeps.unwrap_or(s), fixed_iterations.unwrap_or(i)))
            .collect();
        levels.dedup();
        Some(Targets {
            max_strain: a.max_strain.map(f64::from),
            max_penetration: a.max_penetration,
            max_shear: a.max_shear.map(f64::from),
            levels,
            passes: scene.solver.contact_passes > 1,
            kind: BudgetKind::Targets,
            fixed_passes: None,
        })
    }

    /// Stability alone, for a bake of a scene without `accuracy` that leaves drape
    /// its substeps or its iterations (see the module's docs): no targets (the stability rule
    /// judges each frame), the first level the scene's budget as it stands, the others
    /// [`STABILITY_STEPS`] times what it leaves out (its substeps, else its iterations), and at
    /// the top twice its iterations too when it leaves out both: the same 16 × range as the
    /// ladder. What the scene gives stays fixed, its collision passes too. None when the scene
    /// gives both, or has targets.
    pub fn stability(scene: &Scene) -> Option<Targets> {
        let fixed_substeps = scene.substeps.is_some() || scene.timestep.is_some();
        let fixed_iterations = scene.iterations_given;
        if scene.accuracy.is_some() || (fixed_substeps && fixed_iterations) {
            return None;
        }
        let (s, i) = (scene.substeps_per_frame(), scene.solver.iterations);
        let times = |n: u32, k: f64| (f64::from(n) * k).ceil() as u32;
        let mut levels: Vec<(u32, u32)> = (STABILITY_STEPS.iter())
            .map(|&k| match fixed_substeps {
                false => (times(s, k), i),
                true => (s, times(i, k)),
            })
            .collect();
        if !fixed_substeps && !fixed_iterations {
            levels.push((times(s, 8.0), 2 * i));
        }
        levels.dedup();
        Some(Targets {
            max_strain: None,
            max_penetration: None,
            max_shear: None,
            levels,
            passes: scene.solver.contact_passes > 1,
            kind: BudgetKind::Stability,
            fixed_passes: Some(scene.solver.contact_passes),
        })
    }

    /// Puts `sim` on `level`'s budget.
    pub fn apply(&self, sim: &mut Simulation, level: usize) {
        let (substeps, iterations) = self.levels[level];
        let passes = match self.fixed_passes {
            Some(passes) => passes.min(iterations),
            None if self.passes => iterations,
            None => 1,
        };
        sim.set_budget(substeps, iterations, passes);
    }

    /// True when the budget answers to stability alone ([`Targets::stability`]).
    pub fn stability_only(&self) -> bool {
        self.kind == BudgetKind::Stability
    }

    /// Which target a frame that reads `r` misses, if one does.
    pub fn missed(&self, r: Reading) -> Option<String> {
        let Reading {
            strain,
            depth,
            shear,
        } = r;
        if !strain.is_finite() || !depth.is_finite() {
            return Some("the frame went unstable".into());
        }
        if let Some(t) = self.max_strain.filter(|&t| strain > t) {
            return Some(format!(
                "strain {:.2} % over the target {:.2} %",
                strain * 100.0,
                t * 100.0
            ));
        }
        if let Some(t) = self.max_penetration.filter(|&t| depth > t) {
            return Some(format!(
                "penetration {:.2} mm over the target {:.2} mm",
                depth * 1e3,
                t * 1e3
            ));
        }
        if let Some(t) = self.max_shear.filter(|&t| shear > t) {
            return Some(format!("cell shear {shear:.2}° over the target {t:.2}°"));
        }
        None
    }

    /// How far a frame that reads `r` is from the targets: the largest of its readings over its
    /// target (above 1 it misses one); infinite when a reading is not finite.
    pub fn excess(&self, r: Reading) -> f64 {
        if !r.strain.is_finite() || !r.depth.is_finite() || !r.shear.is_finite() {
            return f64::INFINITY;
        }
        let over = |value: f64, target: Option<f64>| target.map_or(0.0, |t| value / t);
        over(r.strain, self.max_strain)
            .max(over(
                f64::from(r.depth),
                self.max_penetration.map(f64::from),
            ))
            .max(over(r.shear, self.max_shear))
    }

    /// True when a frame that reads `r` came within a quarter of a target: the next frame gets
    /// the next budget before it misses (a frame that misses is simulated again from its start,
    /// which cannot undo what a cheap budget let happen in the frames before it).
    pub fn close(&self, r: Reading) -> bool {
        if self.stability_only() {
            // Cloth pinched or caught holds its strain at any budget: raised ahead of time, a
            // bake of `poncho_walk`'s poncho at drape's default budget went to the cap at frame
            // 23 and stayed there (its worst spring at 76 % in every frame), 6 × the time of
            // raising only the frames that went unstable.
            return false;
        }
        self.max_strain.is_some_and(|t| r.strain > 0.75 * t)
            || self.max_penetration.is_some_and(|t| r.depth > 0.75 * t)
            || self.max_shear.is_some_and(|t| r.shear > 0.75 * t)
    }

    /// True when a frame that reads `r` met every target with half the margin to spare (with
    /// stability alone: at half the stability rule's strain or less).
    pub fn calm(&self, r: Reading) -> bool {
        if self.stability_only() {
            return r.strain <= 0.5 * STABLE_STRAIN;
        }
        self.max_strain.is_none_or(|t| r.strain <= 0.5 * t)
            && self.max_penetration.is_none_or(|t| r.depth <= 0.5 * t)
            && self.max_shear.is_none_or(|t| r.shear <= 0.5 * t)
    }
}

impl BudgetReport {
    pub fn of(targets: &Targets, frames: &[FrameBudget]) -> BudgetReport {
        BudgetReport {
            kind: targets.kind,
            max_strain: targets.max_strain,
            max_penetration: targets.max_penetration,
            max_shear: targets.max_shear,
            levels: targets.levels.clone(),
            met: frames.iter().all(|f| targets.missed(f.reading()).is_none()),
            kept_missing: frames.iter().filter(|f| f.kept_missing).count(),
            max_strain_reached: frames.iter().map(|f| f.max_strain).fold(0.0, f64::max),
            deepest_penetration_reached: frames
                .iter()
                .map(|f| f.deepest_penetration)
                .fold(0.0, f32::max),
            max_shear_reached: frames.iter().map(|f| f.max_shear_deg).fold(0.0, f64::max),
            per_frame: frames.to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn targets() -> Targets {
        Targets {
            max_strain: Some(0.1),
            max_penetration: None,
            max_shear: None,
            levels: LADDER.to_vec(),
            passes: false,
            kind: BudgetKind::Targets,
            fixed_passes: None,
        }
    }

    fn reading(strain: f64) -> Reading {
        Reading {
            strain,
            depth: 0.0,
            shear: 0.0,
        }
    }

    /// Runs `frames` frames from the cap, each reading what `strain` gives at its level, as
    /// the bake keeps them (no frame simulated again): the levels the frames ran at.
    fn levels_from_cap(frames: usize, strain: impl Fn(usize) -> f64) -> Vec<usize> {
        let t = targets();
        let mut state = BudgetState {
            level: LADDER.len() - 1,
            ..BudgetState::default()
        };
        (0..frames)
            .map(|_| {
                let level = state.level;
                state.after_frame(&t, reading(strain(level)));
                level
            })
            .collect()
    }

    #[test]
    fn misses_no_budget_reaches_walk_the_budget_down_a_window_at_a_time() {
        // Strain that contact forces: 30 % at every level.
        let levels = levels_from_cap(100, |_| 0.3);
        let top = LADDER.len() - 1;
        assert!(levels[..10].iter().all(|&l| l == top), "{levels:?}");
        for step in 1..=top {
            let window = &levels[10 * step..10 * (step + 1)];
            assert!(window.iter().all(|&l| l == top - step), "{levels:?}");
        }
        assert!(levels[80..].iter().all(|&l| l == 0), "{levels:?}");
    }

    #[test]
    fn a_miss_of_the_solvers_making_goes_back_up_after_one_window_and_holds() {
        // Strain the budget halves a level up: 20 % over the target at the cap.
        let top = LADDER.len() - 1;
        let levels = levels_from_cap(60, |l| 0.12 * 2f64.powi((top - l) as i32));
        assert!(levels[..10].iter().all(|&l| l == top), "{levels:?}");
        assert!(levels[10..20].iter().all(|&l| l == top - 1), "{levels:?}");
        // Back at the cap, held there while it misses: no second descent for HOLD_FRAMES.
        let held = 20 + HOLD_FRAMES as usize;
        assert!(levels[20..held].iter().all(|&l| l == top), "{levels:?}");
    }

    /// Stability alone climbs from the scene's budget what it leaves out (its substeps, else
    /// its iterations); a scene that gives both, or has targets, has none.
    #[test]
    fn stability_alone_climbs_from_the_scene_budget_what_it_leaves_out() {
        let levels = |fields: &str| {
            let text = format!(r#"{{ "garments": [{{ "resolution": [4, 4] }}]{fields} }}"#);
            let scene = Scene::parse(&text, "<test>").expect("scene");
            Targets::stability(&scene).map(|t| t.levels)
        };
        let substeps = [10, 15, 20, 30, 40, 60, 80];
        let mut all: Vec<(u32, u32)> = substeps.iter().map(|&s| (s, 10)).collect();
        all.push((80, 20));
        assert_eq!(levels(""), Some(all));
        assert_eq!(
            levels(r#", "substeps": 20"#),
            Some(vec![
                (20, 10),
                (20, 15),
                (20, 20),
                (20, 30),
                (20, 40),
                (20, 60),
                (20, 80)
            ])
        );
        assert_eq!(
            levels(r#", "solver": { "iterations": 3 }"#),
            Some(substeps.iter().map(|&s| (s, 3)).collect())
        );
        assert_eq!(
            levels(r#", "timestep": 0.001, "solver": { "iterations": 30 }"#),
            None
        );
        assert_eq!(
            levels(r#", "substeps": 100, "solver": { "iterations": 30 }"#),
            None
        );
        assert_eq!(levels(r#", "accuracy": { "max_strain": 0.1 }"#), None);
    }

    #[test]
    fn frames_that_meet_the_targets_move_as_before() {
        let t = targets();
        let mut state = BudgetState {
            level: 3,
            ..BudgetState::default()
        };
        // Within a quarter of the target: one level up.
        assert!(state.after_frame(&t, reading(0.08)).is_some());
        assert_eq!((state.level, state.settle), (4, SETTLE_FRAMES));
        // Half the margin to spare for CALM_FRAMES frames: one level down.
        for _ in 1..CALM_FRAMES {
            assert!(state.after_frame(&t, reading(0.04)).is_none());
        }
        assert!(state.after_frame(&t, reading(0.04)).is_some());
        assert_eq!(state.level, 3);
        assert_eq!(state.descent, None);
    }
}
