//! `report.json`: what a bake did and how well, for people and for pipelines.
//! The schema is versioned ([`SCHEMA`]) and documented in `docs/report-format.md`; fields are only
//! ever added within one version.

use crate::collide::Penetration;
use crate::scene::{IntegratorKind, SolverSettings};
use serde::Serialize;

/// The schema identifier written into every report.
pub const SCHEMA: &str = "drape.report/1";

/// A bake's report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub schema: &'static str,
    pub drape_version: &'static str,
    pub scene: String,
    pub scene_file: String,
    pub backend: Backend,
    pub solver: SolverSettings,
    pub integrator: IntegratorKind,
    pub fps: f32,
    pub substeps: u32,
    pub step_seconds: f32,
    pub particles: usize,
    pub springs: usize,
    pub garments: Vec<GarmentReport>,
    /// The shot's number of the first frame; every `frame` in the report is a shot frame number.
    pub frame_start: u32,
    pub frames_requested: u32,
    pub frames_baked: u32,
    pub ms_per_frame: Timing,
    /// FNV-1a (64 bits, hex) of every baked frame's positions: equal for runs that baked the
    /// same numbers (see `docs/report-format.md` for which runs promise that).
    pub frames_hash: String,
    /// Wall time per stage ([`crate::sim::schedule::TIMED`]): the simulation's stages on the
    /// CPU backend (the GPU runs them in one command buffer, untimed), and what runs around them
    /// on both.
    pub stages_ms: Vec<StageTiming>,
    /// GPU backend: bytes written to the GPU per frame, on average (what the CPU computes for
    /// the kernels: targets of attachments that ride skins, characters' shells, where the frame
    /// starts); absent on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_upload_bytes_per_frame: Option<u64>,
    /// GPU backend: compute dispatches and queue submissions per frame, on average (the launch
    /// overhead a hardware GPU pays); absent on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_dispatches_per_frame: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_submissions_per_frame: Option<f64>,
    /// Metrics after the last baked frame.
    pub last_frame: Option<FrameMetrics>,
    /// The frame with the largest structural strain.
    pub worst_frame: Option<FrameMetrics>,
    /// Deepest penetration of each collider over the whole bake.
    pub worst_penetrations: Vec<ColliderPenetration>,
    /// Every baked frame's penetrations: per collider (the scene's `colliders`, then the
    /// characters), the particles inside and the deepest of them [m].
    pub penetrations_per_frame: Vec<FramePenetrations>,
    /// Per character shown in the exports, the most garment particles inside its own mesh at
    /// once and the deepest [m] over the bake (measured against its triangles, not its shell).
    pub worst_mesh_penetrations: Vec<MeshPenetration>,
    /// Every baked frame's particles inside each character's mesh (in `worst_mesh_penetrations`
    /// order) and the deepest [m]; empty without characters.
    pub mesh_penetrations_per_frame: Vec<FramePenetrations>,
    /// Per character shown, the most pinned or attached garment particles (waistbands, collars,
    /// held edges) inside its own mesh at once and the deepest [m] over the bake, measured as
    /// `worst_mesh_penetrations` is. They follow their targets, so no budget moves them and the
    /// accuracy targets leave them out; empty without characters or without held particles.
    pub worst_held_mesh_penetrations: Vec<MeshPenetration>,
    /// Every baked frame's held particles inside each character's mesh (in
    /// `worst_mesh_penetrations` order) and the deepest [m]; empty without characters or
    /// without held particles.
    pub held_mesh_penetrations_per_frame: Vec<FramePenetrations>,
    /// Every baked frame's pairs of garment triangles passing through each other.
    pub crossings_per_frame: Vec<FrameCrossings>,
    /// Every baked frame's pairs of each character's own colliding triangles passing through
    /// each other that lay apart where the bake started (in `worst_mesh_penetrations` order;
    /// [`crate::collide::crossings::SelfCrossings`]): where one part of a body sinks into
    /// another, cloth caught between them cannot stay outside the mesh. Empty without
    /// characters.
    #[serde(default)]
    pub character_crossings_per_frame: Vec<FrameSelfCrossings>,
    /// The frames in which `solver.strain_limit` pulled springs back, with how many (each
    /// counted once per substep it was past the limit); empty without a limit or when it was
    /// never reached.
    pub strain_limited_per_frame: Vec<FrameStrainLimited>,
    /// The frames in which a spring from a pinned or attached particle was stretched past
    /// 100 % while every spring between free particles stayed within it, with the most stretched
    /// (`|l − L| / L`): the animation carried the held end through the body (a limb through the
    /// attached edge) while the skin held the free end out. The stability rule leaves those
    /// springs out (no solver can keep them short), so the bake goes on; a warning names the
    /// frames. Empty when it never happened.
    #[serde(default)]
    pub forced_strain_per_frame: Vec<FrameForcedStrain>,
    /// Every baked frame's deepest vertex of each character's mesh inside the scene's
    /// analytic colliders [m] (0 when none is), in `worst_mesh_penetrations` order: soles
    /// through the floor, a body lying on it. Cloth pressed between the two is kept out of the
    /// collider, so it is inside the body there. Empty without characters or colliders.
    #[serde(default)]
    pub character_in_colliders_per_frame: Vec<FrameCharacterDepth>,
    /// Springs broken by tearing over the bake.
    pub torn_springs: usize,
    /// The characters' pre-roll, simulated before the first frame (numbered before
    /// `frame_start`); absent without one. The per-frame lists and the worst values above
    /// cover it too.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preroll: Option<PrerollReport>,
    /// Garment particles moved out of the characters before the first substep (a fresh bake
    /// with characters; absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clean_start: Option<CleanStart>,
    pub stable: bool,
    pub failure: Option<Failure>,
    /// Set when a signal (SIGINT, SIGTERM) stopped the bake early: the frames before it are
    /// written and `stable` still says how they went.
    pub interrupted: Option<Interruption>,
    /// The shot frame the bake was asked to stop after (`--until`: a chunk of a farm job that
    /// the next chunk resumes), when it was.
    pub until: Option<u32>,
    /// Set when the bake continued from a checkpoint: the frames up to it were replayed from
    /// that bake's frame log, not simulated again.
    pub resumed: Option<Resumed>,
    /// With accuracy targets, or a budget left to drape (`bake::budget`): the budget
    /// chosen for every frame, why, and what it reached.
    pub budget: Option<BudgetReport>,
    /// Checkpoints this run wrote into `checkpoints/` (none when `checkpoint_every` is 0).
    pub checkpoints: Option<CheckpointReport>,
    /// Things the user should know, e.g. that `auto` fell back to the CPU and why.
    pub warnings: Vec<String>,
    /// The characters the garments collided with.
    pub characters: Vec<CharacterReport>,
    /// Total squared error after every sweep, one list per frame (when the scene asks for it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residuals: Option<Vec<Vec<f64>>>,
    pub outputs: Outputs,
    /// Size and time of each export written after the simulation (OBJ frames are written as the
    /// bake goes and are not listed).
    pub exports: Vec<ExportReport>,
    /// The preview render, if one was made.
    pub preview: Option<RenderSummary>,
}

/// The pre-roll of a bake ([`Report::preroll`]).
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct PrerollReport {
    /// Frames of pre-roll before `frame_start`.
    pub frames: u32,
    /// How many of them were baked (fewer when the bake stopped inside it).
    pub frames_baked: u32,
    /// Whether they are in the exports (`output.preroll`).
    pub exported: bool,
    /// The largest structural strain in any pre-roll frame.
    pub max_strain: f64,
    /// Per character shown, the most garment particles inside its mesh at once during the
    /// pre-roll and the deepest [m].
    pub mesh_penetrations: Vec<MeshPenetration>,
    /// Simulation time of the pre-roll frames this run baked [ms].
    pub ms: f64,
}

/// What the clean start did ([`Report::clean_start`]).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct CleanStart {
    /// Garment particles moved out of a character.
    pub moved: usize,
    /// How many of them were inside its mesh (the rest were only inside its shell).
    pub inside_mesh: usize,
    /// The largest move [m].
    pub largest_move_m: f32,
    /// Particles then moved out over a garment put on before theirs (garments on one
    /// character, layered in the scene's order).
    pub layered: usize,
    /// The largest of those moves [m].
    pub largest_layering_m: f32,
}

/// A bake stopped by a signal.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Interruption {
    /// The signal's number (2: SIGINT, 15: SIGTERM).
    pub signal: i32,
    /// The last frame baked (a shot frame number).
    pub after_frame: u32,
}

/// Where a resumed bake continued from.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Resumed {
    /// The checkpoint file (in the output folder, or in a dead run's staging folder).
    pub checkpoint: String,
    /// The last frame it holds (a shot frame number); simulation continued after it.
    pub after_frame: u32,
    /// Time writing the frames up to it again, replayed from its frame log [ms].
    pub replay_ms: f64,
}

/// The checkpoints one run wrote.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CheckpointReport {
    /// How many, and the shot frame of each.
    pub frames: Vec<u32>,
    /// Size of the last one [bytes] (`frames.bin`, the log of every frame, not included).
    pub bytes: u64,
    /// Time writing them, all together [ms].
    pub ms: f64,
    /// Size of `frames.bin` [bytes].
    pub frames_log_bytes: u64,
}

/// One stage's wall time over the bake.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StageTiming {
    pub stage: &'static str,
    /// Over the whole bake [ms].
    pub total: f64,
    /// Mean per baked frame [ms].
    pub per_frame: f64,
}

impl StageTiming {
    /// The stages of `times` over `frames` frames, in [`crate::sim::schedule::TIMED`] order.
    pub fn of(times: &crate::sim::schedule::StageTimes, frames: u32) -> Vec<StageTiming> {
        crate::sim::schedule::TIMED
            .iter()
            .zip(times.seconds)
            .map(|(&stage, s)| StageTiming {
                stage,
                total: s * 1e3,
                per_frame: s * 1e3 / frames.max(1) as f64,
            })
            .collect()
    }
}

/// Where the simulation ran.
#[derive(Clone, Debug, Serialize)]
pub struct Backend {
    /// `"cpu"` or `"gpu"`.
    pub kind: &'static str,
    /// Worker threads of the CPU (which also measures and exports on the GPU backend).
    pub threads: usize,
    /// Frames the CPU backend ran on one of them because the machine was busy (the team's
    /// threads kept waiting for each other: `sim::team::Sharing`); the same frames either way.
    pub frames_on_one_thread: u32,
    /// The share of the CPU team's waits that spun out over the bake: asleep at a barrier, or
    /// yielding the core while waiting for another thread's hand-off between barriers (null on
    /// one thread and on the GPU). Near 0 on an otherwise idle machine, high when other work held
    /// its cores (another bake, a busy virtual machine's host). Timings of a bake with a high
    /// share say more about the machine than about drape.
    pub team_waits_asleep: Option<f64>,
    /// The GPU adapter, on the GPU backend.
    pub adapter: Option<Adapter>,
}

/// A GPU adapter as wgpu reports it.
#[derive(Clone, Debug, Serialize)]
pub struct Adapter {
    pub name: String,
    /// `"DiscreteGpu"`, `"IntegratedGpu"`, `"VirtualGpu"`, `"Cpu"` (software, e.g. lavapipe) or `"Other"`.
    pub device_type: String,
    pub driver: String,
    pub backend: String,
}

/// A character and its collision shell.
#[derive(Clone, Debug, Serialize)]
pub struct CharacterReport {
    pub name: String,
    pub file: String,
    pub frames: usize,
    pub shell_particles: usize,
    pub shell_radius: f32,
    /// `"reused"` (an up-to-date cache), `"built"`, or why none was used.
    pub shell_cache: &'static str,
    /// Height [m] of its first frame after `scale` (extent along Y).
    pub height_m: f32,
}

/// One garment's counts.
#[derive(Clone, Debug, Serialize)]
pub struct GarmentReport {
    pub name: String,
    pub particles: usize,
    pub pinned: usize,
    pub stretch_springs: usize,
    pub shear_springs: usize,
    pub bend_springs: usize,
    pub colours: u32,
}

/// Wall-clock time of the simulation per frame [ms] (file writing excluded).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timing {
    pub median: f64,
    pub max: f64,
    pub mean: f64,
    pub total: f64,
}

impl Timing {
    /// Statistics of per-frame times [ms].
    pub fn of(frame_ms: &[f64]) -> Timing {
        if frame_ms.is_empty() {
            return Timing::default();
        }
        let mut sorted = frame_ms.to_vec();
        sorted.sort_by(f64::total_cmp);
        let total: f64 = sorted.iter().sum();
        let mid = sorted.len() / 2;
        let median = if sorted.len() % 2 == 1 {
            sorted[mid]
        } else {
            0.5 * (sorted[mid - 1] + sorted[mid])
        };
        Timing {
            median,
            max: *sorted.last().unwrap_or(&0.0),
            mean: total / sorted.len() as f64,
            total,
        }
    }
}

/// Accuracy after one frame.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct FrameMetrics {
    /// 1-based frame number.
    pub frame: u32,
    /// Σ (|q_a − q_b| − L)² over structural springs [m²].
    pub total_squared_error: f64,
    pub mean_strain: f64,
    pub max_strain: f64,
    /// Largest (l − L) / L over structural springs: stretch alone (`max_strain` also counts
    /// compression).
    #[serde(default)]
    pub max_stretch: f64,
    /// Mean and largest |90° − angle| of the garments' lattice cells [degrees] (shear, which
    /// structural strain does not see).
    #[serde(default)]
    pub mean_shear_deg: f64,
    #[serde(default)]
    pub max_shear_deg: f64,
    /// Pairs of the garments' exported triangles passing through each other
    /// ([`crate::collide::crossings`]): cloth through itself or another garment.
    #[serde(default)]
    pub crossings: usize,
    pub penetrations: Vec<ColliderPenetration>,
}

/// One frame's cloth–cloth crossings ([`FrameMetrics::crossings`]).
#[derive(Clone, Copy, Debug, Serialize, serde::Deserialize)]
pub struct FrameCrossings {
    pub frame: u32,
    pub crossings: usize,
}

/// One frame's crossings of each character's mesh through itself
/// ([`Report::character_crossings_per_frame`]).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FrameSelfCrossings {
    pub frame: u32,
    pub crossings: Vec<usize>,
}

/// A frame in which the strain limit pulled springs back.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FrameStrainLimited {
    pub frame: u32,
    /// Springs pulled back, summed over the frame's substeps.
    pub springs: u64,
}

/// How deep each character's mesh is inside the scene's colliders in a frame.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FrameCharacterDepth {
    pub frame: u32,
    /// Per character [m].
    pub deepest_m: Vec<f32>,
}

/// A frame in which a spring from a pinned or attached particle was stretched past 100 %.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FrameForcedStrain {
    pub frame: u32,
    /// The largest strain of those springs in the frame.
    pub strain: f64,
}

/// Penetration into one collider.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ColliderPenetration {
    /// Index in the scene's `colliders`, then the `characters` after them.
    pub collider: usize,
    #[serde(flatten)]
    pub penetration: Penetration,
}

/// Garment particles inside one character's own mesh.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct MeshPenetration {
    pub character: String,
    #[serde(flatten)]
    pub penetration: Penetration,
}

/// One frame's penetrations, collider by collider.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct FramePenetrations {
    pub frame: u32,
    pub inside: Vec<usize>,
    pub deepest_m: Vec<f32>,
}

/// Why a bake stopped early.
#[derive(Clone, Debug, Serialize)]
pub struct Failure {
    /// The frame at which instability was detected (1-based).
    pub frame: u32,
    pub reason: String,
}

/// Files written, relative to the bake folder.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct Outputs {
    /// Folder of the OBJ sequences, if written.
    pub obj: Option<String>,
    /// The glTF file (`.glb`, or `.gltf` beside its `.bin`), if written.
    pub gltf: Option<String>,
    /// Folder of the PC2 caches and rest OBJs, if written.
    pub pc2: Option<String>,
    /// The USD layer, if written.
    pub usd: Option<String>,
    /// The Alembic cache, if written.
    pub alembic: Option<String>,
    /// The contact sheet of the preview frames (`preview/frame_0001.png …` beside it), if rendered.
    pub preview: Option<String>,
}

/// One export format's cost: files written, their total size and the time to write them.
#[derive(Clone, Debug, Serialize)]
pub struct ExportReport {
    pub format: &'static str,
    pub files: usize,
    pub bytes: u64,
    pub ms: f64,
}

/// What `render::render_sequence` did (the report's `preview`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderSummary {
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    pub adapter: String,
    /// Wall time per frame, render and PNG encoding [ms].
    pub ms_per_frame: f64,
    /// `preview/…` files, relative to the folder rendered into.
    pub contact_sheet: String,
}

/// What the report says of each frame's budget.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct FrameBudget {
    pub frame: u32,
    pub substeps: u32,
    pub iterations: u32,
    pub contact_passes: u32,
    /// Times the frame was simulated (1: the first budget met the targets).
    pub attempts: u32,
    /// Why the budget changed before or during this frame (empty when it did not).
    pub why: String,
    /// Its worst structural strain, deepest penetration [m] and worst cell shear [degrees].
    pub max_strain: f64,
    pub deepest_penetration: f32,
    #[serde(default)]
    pub max_shear_deg: f64,
    /// Kinetic energy the frame's settling took out [J] (0 when it did not settle).
    #[serde(default)]
    pub settled_joules: f64,
    /// It missed a target and was kept at its budget, not simulated again at the larger one
    /// there was: the bake was descending from the cap, or holding the level it went back up
    /// to after one (`drape::bake::budget`).
    #[serde(default)]
    pub kept_missing: bool,
}

/// What moves a bake's budget.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum BudgetKind {
    /// The scene's accuracy targets (`accuracy`, `--max-strain` and the like).
    Targets,
    /// Stability alone: a scene without targets that leaves drape its substeps or iterations
    /// keeps its budget, and only a frame that goes unstable is simulated again at a larger one.
    Stability,
}

/// The report's account of the budget.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BudgetReport {
    /// What moves it.
    pub kind: BudgetKind,
    /// The targets.
    pub max_strain: Option<f64>,
    pub max_penetration: Option<f32>,
    pub max_shear: Option<f64>,
    /// The levels the budget could take, cheapest first: (substeps, iterations).
    pub levels: Vec<(u32, u32)>,
    /// True when every frame met the targets.
    pub met: bool,
    /// Frames that missed a target and were kept at their budget (`FrameBudget::kept_missing`).
    pub kept_missing: usize,
    /// The worst strain, deepest penetration [m] and worst cell shear [degrees] over the bake.
    pub max_strain_reached: f64,
    pub deepest_penetration_reached: f32,
    pub max_shear_reached: f64,
    /// Every frame's budget.
    pub per_frame: Vec<FrameBudget>,
}
