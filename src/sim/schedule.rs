//! The substep, written once: the stages in their order, which the CPU team
//! ([`crate::sim::Simulation`]) and the GPU recorder ([`crate::gpu::GpuSimulation`]) both walk,
//! and the clock that times each stage for `report.json`'s `stages_ms`.
//!
//! A frame is a prologue (predict the first substep's inertial displacement) and then, per
//! substep, the list [`substep`] returns:
//!
//! 1. `attach`: attached particles jump to their targets at the end of the substep (on the CPU
//!    they are placed before the team region starts, as characters' shells advance; on the GPU
//!    a kernel places them from the frame's uploaded targets);
//! 2. `forces`: the force fields' accelerations (wind on the faces, attractors), and with them
//!    the substep's prediction (on the CPU computed before the team region, with the shells; a
//!    frame with force fields predicts every substep here, not in the prologue and `finish`);
//! 3. `solve`: a share of the solver iterations (each: the local step projects every spring, then
//!    inner sweeps of the global step, or one PBD iteration), on displacements Δ;
//! 4. `contact_pass`: between shares, every particle pushed out of the colliders and characters'
//!    shells (the shells against each particle's nearby list of the previous substep);
//! 5. `particle_collisions`: q = x + Δ sorted into a hash grid, each particle's push;
//! 6. `finish`: tethers, collisions with the colliders and shells (swept and end point), friction,
//!    commit (x += Δ, v = Δ/h) and the next substep's prediction, each particle alone.
//!
//! Why collision passes sit between shares of the iterations: a stop at the surface reaches the
//! rest of the cloth only through the solve that follows it (see `docs/benchmarks-history.md`,
//! scene P).

use crate::scene::SolverSettings;
use std::time::Instant;

/// One stage of a substep.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Attached particles to their targets.
    Attach,
    /// The force fields' accelerations and the substep's prediction.
    Forces,
    /// This many solver iterations.
    Solve { iterations: u32 },
    /// A collision pass on the displacement so far.
    ContactPass,
    /// Particle–particle (self and garment–garment) pushes.
    ParticleCollisions,
    /// Tethers, collisions, friction, commit and the next prediction.
    Finish,
}

/// What a scene has that adds stages.
#[derive(Clone, Copy, Debug, Default)]
pub struct Features {
    pub attachments: bool,
    pub particle_collisions: bool,
    pub forces: bool,
}

/// The stages of one substep, in order.
pub fn substep(settings: &SolverSettings, features: Features) -> Vec<Stage> {
    let mut stages = Vec::new();
    if features.attachments {
        stages.push(Stage::Attach);
    }
    if features.forces {
        stages.push(Stage::Forces);
    }
    let passes = settings.contact_passes.max(1);
    for pass in 0..passes {
        stages.push(Stage::Solve {
            iterations: share(settings.iterations, passes, pass),
        });
        if pass + 1 < passes {
            stages.push(Stage::ContactPass);
        }
    }
    if features.particle_collisions {
        stages.push(Stage::ParticleCollisions);
    }
    stages.push(Stage::Finish);
    stages
}

/// Iterations in share `pass` of `passes` even shares of `iterations` (they differ by at most
/// one and add up to `iterations`).
pub fn share(iterations: u32, passes: u32, pass: u32) -> u32 {
    iterations * (pass + 1) / passes - iterations * pass / passes
}

/// Names of the timed stages, in `report.json`'s order: the prologue, the substep's stages, and
/// what runs around the solver (characters' shells, tearing, metrics, exports, checkpoints).
pub const TIMED: [&str; 12] = [
    "predict",
    "attach",
    "forces",
    "solve",
    "contact_pass",
    "particle_collisions",
    "finish",
    "shells",
    "tearing",
    "metrics",
    "export",
    "checkpoint",
];

impl Stage {
    /// The stage's index in [`TIMED`].
    pub fn timed(self) -> usize {
        match self {
            Stage::Attach => 1,
            Stage::Forces => 2,
            Stage::Solve { .. } => 3,
            Stage::ContactPass => 4,
            Stage::ParticleCollisions => 5,
            Stage::Finish => 6,
        }
    }
}

/// Index of a stage in [`TIMED`] by name.
pub fn timed(name: &str) -> usize {
    TIMED
        .iter()
        .position(|&n| n == name)
        .expect("a stage of TIMED")
}

/// Wall time spent in each of [`TIMED`]'s stages [s].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageTimes {
    pub seconds: [f64; TIMED.len()],
}

impl StageTimes {
    /// Adds the time since `since` to `stage` and returns now (the next stage's start).
    pub fn lap(&mut self, stage: usize, since: Instant) -> Instant {
        let now = Instant::now();
        self.seconds[stage] += (now - since).as_secs_f64();
        now
    }

    /// Adds `other`'s times.
    pub fn add(&mut self, other: &StageTimes) {
        for (a, b) in self.seconds.iter_mut().zip(&other.seconds) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_cover_the_iterations_evenly() {
        for iterations in 1..40 {
            for passes in 1..=iterations {
                let shares: Vec<u32> = (0..passes).map(|p| share(iterations, passes, p)).collect();
                assert_eq!(shares.iter().sum::<u32>(), iterations);
                let (lo, hi) = (shares.iter().min().unwrap(), shares.iter().max().unwrap());
                assert!(
                    hi - lo <= 1 && *lo >= 1,
                    "{iterations} in {passes}: {shares:?}"
                );
            }
        }
    }

    #[test]
    fn a_pass_follows_every_share_but_the_last() {
        let settings = SolverSettings {
            iterations: 10,
            contact_passes: 3,
            ..SolverSettings::default()
        };
        let stages = substep(
            &settings,
            Features {
                attachments: true,
                particle_collisions: true,
                forces: true,
            },
        );
        assert_eq!(
            stages,
            [
                Stage::Attach,
                Stage::Forces,
                Stage::Solve { iterations: 3 },
                Stage::ContactPass,
                Stage::Solve { iterations: 3 },
                Stage::ContactPass,
                Stage::Solve { iterations: 4 },
                Stage::ParticleCollisions,
                Stage::Finish
            ]
        );
    }
}
