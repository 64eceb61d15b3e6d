//! What the user typed (clap derive). Nothing here reads files; `resolve` does.

use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

/// drape: bakes garment animation with Projective Dynamics and red-black Gauss-Seidel.
#[derive(Parser, Debug)]
#[command(name = "drape", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Simulate a scene and write OBJ frames and report.json.
    Bake(BakeArgs),
    /// Validate a scene and print its counts, colours and memory estimate.
    Inspect(InspectArgs),
    /// Time the solvers on the reference scenes.
    Bench(BenchArgs),
    /// Sample a character's collision shell over its frames and write it as a cache file.
    Shell(ShellArgs),
    /// Write drape's procedural mannequin (clips raise_arms, sit and poncho) and its stool as OBJ frames.
    Mannequin(MannequinArgs),
    /// Render preview images of an existing bake (its glTF) into BAKE_DIR/preview.
    Render(RenderArgs),
    /// Write a farm plan: one bake per wedge variant in DIR/jobs.txt, the variants' scenes, and
    /// an Open Job Description template (DIR/job.yaml).
    Plan(PlanArgs),
}

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Scene file (JSON).
    #[arg(required_unless_present = "status")]
    pub scene: Option<PathBuf>,
    /// A scene field and the values to bake it with, e.g. `solver.iterations=5,10`,
    /// `garments[0].mass=0.1,0.2` or `garments[0].position=[0,1,0],[0,2,0]` (a comma inside
    /// brackets, braces or quotes belongs to the value); several wedges make every combination.
    #[arg(long, value_name = "FIELD=V1,V2,...")]
    pub wedge: Vec<String>,
    /// Split each bake into sequential chunks of N frames, each resuming the previous one's
    /// checkpoint (`chunks/chunk_NN.txt`, `jobs.txt` all of them in order).
    #[arg(long, allow_hyphen_values = true)]
    pub chunk: Option<u32>,
    /// Cores each bake takes (`--threads` in its command, the Slurm recipe's
    /// `--cpus-per-task`, GNU parallel's bakes at a time). Default 2.
    #[arg(long, default_value_t = 2, allow_hyphen_values = true)]
    pub cpus: u32,
    /// Folder to write the plan into (created; must be empty or absent).
    #[arg(long, required_unless_present = "status")]
    pub out: Option<PathBuf>,
    /// Instead of planning: each variant's state in plan folder DIR, from its report.json
    /// (done, stable, frames baked of requested, interrupted, failed); exits 0 only when every
    /// variant is done.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["scene", "wedge", "chunk", "out"])]
    pub status: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A folder `drape bake` wrote (with a glTF export).
    pub bake_dir: PathBuf,
    /// Image size, e.g. 1280x720.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Draw the triangles' edges over the shading.
    #[arg(long)]
    pub wireframe: bool,
}

/// Parses `WIDTHxHEIGHT`.
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X', '×'])
        .ok_or_else(|| format!("{text:?}: expected WIDTHxHEIGHT, e.g. 1280x720"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=8192).contains(n))
            .ok_or_else(|| {
                format!("{text:?}: each side must be a whole number of pixels in 1…8192")
            })
    };
    Ok((parse(w)?, parse(h)?))
}

#[derive(Args, Debug)]
pub struct MannequinArgs {
    /// Folder to write (`<clip>/frame_0001.obj …`, `stool.obj`).
    #[arg(long, default_value = "characters/mannequin")]
    pub out: PathBuf,
}

/// A character: a file assimp reads, a folder of per-frame files, or a `%04d` pattern.
#[derive(Args, Debug)]
pub struct CharacterArgs {
    /// The character (e.g. walker.glb, frames/, frames/body_%04d.obj); or a scene (`.json`):
    /// then every character's shell of that scene goes into the folder `--out`, exactly as its
    /// bake with `--shell-cache` that folder would build it (the scene says how to load them).
    pub character: PathBuf,
    #[command(flatten)]
    pub look: CharacterLook,
    /// Placement after scale and up axis [m], e.g. `--position 0,0,0.5`.
    #[arg(long, value_parser = three_numbers, default_value = "0,0,0", allow_hyphen_values = true)]
    pub position: [f32; 3],
    /// Rotation after scale and up axis, Euler degrees applied X, Y, Z, e.g. `--rotation 0,90,0`.
    #[arg(long, value_parser = three_numbers, default_value = "0,0,0", allow_hyphen_values = true)]
    pub rotation: [f32; 3],
    /// Clip time at the first frame [s].
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub time_offset: f32,
    /// Clip seconds per second.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub speed: f32,
    /// Loop the clip instead of holding its last pose.
    #[arg(long)]
    pub r#loop: bool,
    /// Frames per second to sample at.
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
    pub fps: f32,
    /// Frames to sample (default: the clip's length, or 1 for a static mesh).
    #[arg(long, allow_hyphen_values = true)]
    pub frames: Option<usize>,
}

/// How to read a character and how fine its shell is (shared by `shell` and `inspect`).
#[derive(Args, Debug)]
pub struct CharacterLook {
    /// Character: clip name (or index, e.g. 0 for an unnamed clip); without one, the rest pose.
    #[arg(long, allow_hyphen_values = true)]
    pub clip: Option<String>,
    /// Character: file units to metres.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub scale: f32,
    /// Character: the file's up axis.
    #[arg(long, value_enum, default_value_t = UpArg::Y)]
    pub up: UpArg,
    /// Character: frame rate of a sequence of files (default: one file per sampled frame).
    #[arg(long, allow_hyphen_values = true)]
    pub sequence_fps: Option<f32>,
    /// Character: collision particle radius [m].
    #[arg(long, default_value_t = 0.01, allow_hyphen_values = true)]
    pub radius: f32,
}

/// A file's up axis.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpArg {
    Y,
    Z,
}

#[derive(Args, Debug)]
pub struct ShellArgs {
    #[command(flatten)]
    pub character: CharacterArgs,
    /// The cache file to write (reused when its inputs have not changed).
    #[arg(long)]
    pub out: PathBuf,
}

/// Which solver to use (overrides the scene's `solver.kind`).
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum SolverArg {
    /// Projective Dynamics, sequential Gauss-Seidel.
    Gs,
    /// Projective Dynamics, Jacobi.
    Jacobi,
    /// Projective Dynamics, red-black (multi-colour) Gauss-Seidel.
    Rbgs,
    /// Position Based Dynamics, Jacobi.
    Pbd,
}

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// Scene file (JSON). Without one, the embedded default scene (scene P, the poncho).
    pub scene: Option<PathBuf>,
    /// Solver, overriding the scene's.
    #[arg(long, value_enum)]
    pub solver: Option<SolverArg>,
    /// Number of frames, overriding the scene's (1 to 1 000 000).
    #[arg(long, allow_hyphen_values = true, value_parser = frame_count)]
    pub frames: Option<u32>,
    /// The shot's number of the first frame (e.g. 1001), overriding the scene's `frame_start`.
    #[arg(long, allow_hyphen_values = true)]
    pub frame_start: Option<u32>,
    /// Outer solver iterations per substep, overriding the scene's (the scene's collision
    /// passes are capped at this number).
    #[arg(long, allow_hyphen_values = true)]
    pub iterations: Option<u32>,
    /// Collision passes per substep (1 to the iterations), overriding the scene's.
    #[arg(long, allow_hyphen_values = true)]
    pub contact_passes: Option<u32>,
    /// Over-relaxation factor ω in (0, 2), overriding the scene's.
    #[arg(long, allow_hyphen_values = true)]
    pub omega: Option<f32>,
    /// Substeps per frame, overriding the scene's.
    #[arg(long, allow_hyphen_values = true)]
    pub substeps: Option<u32>,
    /// Accuracy target: the largest structural strain any frame may have (0.05: 5 %); drape
    /// then chooses the substeps and iterations the scene leaves out.
    #[arg(long, allow_hyphen_values = true)]
    pub max_strain: Option<f32>,
    /// Accuracy target: the deepest any garment particle may be inside a collider, shell or
    /// character [m].
    #[arg(long, allow_hyphen_values = true)]
    pub max_penetration: Option<f32>,
    /// Accuracy target: the largest |90° − angle| any lattice cell may have [degrees] (needs
    /// shear springs).
    #[arg(long, allow_hyphen_values = true)]
    pub max_shear: Option<f32>,
}

#[derive(Args, Debug)]
pub struct BakeArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output folder (created; a previous bake there is replaced). Default: out/<scene name>.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (default: every core; more than the cores are clamped, with a warning).
    #[arg(long, allow_hyphen_values = true)]
    pub threads: Option<usize>,
    /// Run every frame on all the threads, even while the machine looks busy (for timing a
    /// given number of threads; by default frames go to one thread while the team's waits keep
    /// sleeping, and the report counts them in `backend.frames_on_one_thread`).
    #[arg(long)]
    pub fixed_threads: bool,
    /// Folder of characters' shell caches (default `$XDG_CACHE_HOME/drape`, else
    /// `~/.cache/drape`); a farm plan's bakes share the one its `shells.txt` fills.
    #[arg(long)]
    pub shell_cache: Option<PathBuf>,
    /// Where to simulate, overriding the scene's `backend`: `gpu` takes any adapter (software
    /// ones too), `auto` a hardware GPU when there is one, else the CPU.
    #[arg(long, value_enum)]
    pub backend: Option<BackendArg>,
    /// Also render preview images (`preview/frame_0001.png …`, `preview/contact_sheet.png`).
    #[arg(long)]
    pub preview: bool,
    /// Preview size, e.g. 1280x720 (overrides the scene's `output.preview_size`).
    #[arg(long, value_parser = parse_size)]
    pub preview_size: Option<(u32, u32)>,
    /// Draw the triangles' edges over the preview.
    #[arg(long)]
    pub wireframe: bool,
    /// glTF container, overriding the scene's `output.gltf`.
    #[arg(long, value_enum)]
    pub gltf: Option<GltfArg>,
    /// Also write PC2 point caches with rest OBJs into `pc2/`.
    #[arg(long)]
    pub pc2: bool,
    /// Also write a USD layer with time-sampled points.
    #[arg(long)]
    pub usd: bool,
    /// Also write an Alembic cache (`<scene>.abc`).
    #[arg(long)]
    pub alembic: bool,
    /// Print `drape: K of N frames` on stderr after each frame instead of drawing a bar (for a
    /// program that shows its own progress, such as the Blender add-on).
    #[arg(long)]
    pub progress_lines: bool,
    /// Continue the bake in `--out` from its latest checkpoint (after an interrupt, a crash or
    /// a pre-emption, or to add frames to a finished bake); from the first frame when there is
    /// none.
    #[arg(long)]
    pub resume: bool,
    /// Re-simulate from the checkpoint at or before this shot frame, keeping the frames before
    /// it (implies --resume).
    #[arg(long, allow_hyphen_values = true)]
    pub from_frame: Option<u32>,
    /// Stop after this shot frame, with a checkpoint (a chunk of a farm job: the next chunk
    /// bakes the same scene with --resume).
    #[arg(long, allow_hyphen_values = true)]
    pub until: Option<u32>,
    /// A checkpoint every this many frames (0: none), overriding the scene's `checkpoint_every`.
    #[arg(long, allow_hyphen_values = true)]
    pub checkpoint_every: Option<u32>,
}

/// glTF container on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum GltfArg {
    Glb,
    Gltf,
    None,
}

/// Where to simulate.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendArg {
    Cpu,
    Gpu,
    Auto,
}

#[derive(Args, Debug)]
pub struct InspectArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// For a character (any file but .json).
    #[command(flatten)]
    pub look: CharacterLook,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// What to time.
    #[arg(value_enum)]
    pub what: BenchWhat,
    /// Thread counts to compare, e.g. `--threads 1,2` (default: 1 and every core;
    /// `characters`: every core).
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
    /// Frames of scenes H and S to bake (default 120, as the scenes define); `budget`,
    /// `characters`: frames of every scene (default: each scene's own).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Iterations to time on scene E.
    #[arg(long, default_value_t = 200)]
    pub iterations: u32,
    /// Write the results as CSV here too.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// `sizes`: grid edges to time (n × n particles).
    #[arg(long, value_delimiter = ',', default_values_t = [100u32, 316, 1000])]
    pub sizes: Vec<u32>,
    /// `convergence`, `integrators`: folder for the CSV and SVG charts (default docs/bench);
    /// `docs`: folder for accuracy-vs-speed.md, with the charts in its `bench/` (default docs);
    /// `budget`, `peers`, `characters`: the same docs folder, their files in its `bench/`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// `convergence`, `integrators`, `docs`: a reduced study (few iterations, small grids) that
    /// finishes in seconds; its numbers are not the ones the docs show. `characters`: H and a
    /// cape without its pre-roll. `peers`: small scenes, a few frames.
    #[arg(long)]
    pub quick: bool,
    /// `sizes`: backends to time; `gpu` uses any adapter (software ones too).
    #[arg(long, value_delimiter = ',', value_enum, default_values_t = [BackendArg::Cpu, BackendArg::Gpu])]
    pub backends: Vec<BackendArg>,
    /// `peers`: Blender's executable (default: `$BLENDER`, then `blender` on the PATH).
    #[arg(long)]
    pub blender: Option<PathBuf>,
    /// `peers`: keep both tools' bakes (OBJ frames and Blender's jobs) in OUT/bench/peers-frames.
    #[arg(long)]
    pub keep: bool,
    /// `characters`: interleaved rounds (every scene once per round).
    #[arg(long, default_value_t = 3)]
    pub rounds: u32,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchWhat {
    /// Every solver on scenes E (µs per iteration), H and S (ms per frame and stretch).
    Solvers,
    /// Every backend and parallel solver at 10 000, 100 000 and 1 000 000 particles.
    Sizes,
    /// Error after each iteration of every solver on scenes E and H, against iterations and
    /// wall time, with 1/2/4/8 ms budgets (CSV + SVG).
    Convergence,
    /// Explicit Euler, midpoint, RK4, Verlet, implicit Euler and Projective Dynamics on scenes W
    /// and F: stability limits, cost to equilibrium, accuracy against speed (CSV + SVG).
    Integrators,
    /// Both studies, then docs/accuracy-vs-speed.md from their results.
    Docs,
    /// Scenes H, P, curtain and flag as shipped against accuracy targets choosing the budget,
    /// and P at a fixed 40 × 20: CSV and SVG in docs/bench, the table in
    /// docs/accuracy-vs-speed.md (`--frames`: fewer).
    Budget,
    /// drape against Blender's cloth (`blender` on the PATH, or `--blender`) on scene H with
    /// shear springs and two character scenes: the same metrics from both tools' OBJ frames,
    /// CSV and SVG in docs/bench, the table in docs/accuracy-vs-speed.md (`--quick`: small
    /// scenes, a few frames).
    Peers,
    /// Every shipped character scene against scene H with shear springs: ns per
    /// particle-iteration and per spring-iteration, ratios within interleaved rounds
    /// (`--rounds`), collisions and shells against the solve; CSV in docs/bench
    /// (`--threads 1,2`: each count; `--quick`: H and a cape without its pre-roll).
    Characters,
}

/// `X,Y,Z`: three numbers in one argument (so `--position 0,0,0.5 --out p.shell` leaves
/// `--out` alone).
fn three_numbers(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("{text:?} is not three numbers X,Y,Z"));
    };
    let number = |t: &str| {
        t.parse::<f32>()
            .map_err(|_| format!("{t:?} in {text:?} is not a number"))
    };
    Ok([number(x)?, number(y)?, number(z)?])
}

/// A number of frames: 1 to drape's limit.
fn frame_count(text: &str) -> Result<u32, String> {
    let max = drape::scene::MAX_FRAMES;
    text.trim()
        .parse::<i64>()
        .ok()
        .filter(|n| (1..=max as i64).contains(n))
        .map(|n| n as u32)
        .ok_or_else(|| format!("{text:?} is not a number of frames from 1 to {max}"))
}
