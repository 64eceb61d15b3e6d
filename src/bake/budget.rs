//! Accuracy targets choose the budget: with `accuracy` in the scene, drape starts each bake at a
//! cheap setting and measures every frame's worst strain and deepest penetration; a frame that
//! misses a target is simulated again from its start state at the next level of [`LADDER`],
//! a frame that comes within a quarter of a target raises the level for the next frame, and
//! after [`CALM_FRAMES`] frames in a row that met both targets with half the margin to
//! spare, the next frame tries one level lower. Substeps and iterations the scene gives itself
//! stay fixed (the ladder moves only what it leaves out); collision passes follow the iterations
//! when the scene has them on. Every decision depends only on the frames, so a bake gives the
//! same frames every time.

pub use crate::report::{BudgetReport, FrameBudget};
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

/// Frames in a row with a large margin after which a lower budget is tried.
pub const CALM_FRAMES: u32 = 10;

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
        })
    }

    /// Puts `sim` on `level`'s budget.
    pub fn apply(&self, sim: &mut Simulation, level: usize) {
        let (substeps, iterations) = self.levels[level];
        let passes = if self.passes { iterations } else { 1 };
        sim.set_budget(substeps, iterations, passes);
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

    /// True when a frame that reads `r` came within a quarter of a target: the next frame gets
    /// the next budget before it misses (a frame that misses is simulated again from its start,
    /// which cannot undo what a cheap budget let happen in the frames before it).
    pub fn close(&self, r: Reading) -> bool {
        self.max_strain.is_some_and(|t| r.strain > 0.75 * t)
            || self.max_penetration.is_some_and(|t| r.depth > 0.75 * t)
            || self.max_shear.is_some_and(|t| r.shear > 0.75 * t)
    }

    /// True when a frame that reads `r` met every target with half the margin to spare.
    pub fn calm(&self, r: Reading) -> bool {
        self.max_strain.is_none_or(|t| r.strain <= 0.5 * t)
            && self.max_penetration.is_none_or(|t| r.depth <= 0.5 * t)
            && self.max_shear.is_none_or(|t| r.shear <= 0.5 * t)
    }
}

impl BudgetReport {
    pub fn of(targets: &Targets, frames: &[FrameBudget]) -> BudgetReport {
        BudgetReport {
            max_strain: targets.max_strain,
            max_penetration: targets.max_penetration,
            max_shear: targets.max_shear,
            levels: targets.levels.clone(),
            met: frames.iter().all(|f| targets.missed(f.reading()).is_none()),
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
