//! Scene files: what to simulate, in JSON (serde). Units are metres, seconds and kilograms; Y is up.
//!
//! A scene names only what it needs: every field has a documented default (see
//! `docs/scene-format.md`), so a hanging cloth is a dozen lines. Unknown fields are rejected, so a
//! typo never silently falls back to a default. Parsing reports file, line, column and the JSON path
//! of the field; [`validate`] then rejects impossible values, naming the field and the reason.

mod character;
mod collider;
pub mod force;
pub(crate) mod validate;

pub use character::{CharacterSpec, MeshSelection, Preroll, UpAxis};
pub use collider::{ColliderKind, ColliderShape, ColliderSpec};
pub use force::ForceSpec;
pub use validate::{
    bad_name, length as check_length, validate, MAX_COLLIDERS, MAX_FRAMES, MAX_NAME_BYTES,
    MAX_PARTICLES,
};

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The scene `drape bake` runs when no scene file is given (scene P, the poncho on the
/// mannequin).
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/poncho.json");
/// The name shown for the embedded default scene in messages and reports.
pub const DEFAULT_SCENE_FILE: &str = "<embedded poncho.json>";

/// A whole scene: timing, forces, solver, garments, colliders and outputs.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// Name used in reports. Default `"scene"`.
    pub name: String,
    /// Frames per second of the bake [1/s]. Default 60.
    pub fps: f32,
    /// Number of frames to bake. Default 120 (2 s at 60 fps).
    pub frames: u32,
    /// The shot's number of the first frame: output files, exports, previews and the report
    /// carry the shot's frame numbers (`obj/cloth_1001.obj` …). Default 1. Time (characters,
    /// keyframes) still starts at 0 on this frame.
    pub frame_start: u32,
    /// Simulation steps per frame. Default 10 when `timestep` is absent. Give one or the other.
    pub substeps: Option<u32>,
    /// Largest simulation step [s]; drape takes the smallest whole number of substeps per frame
    /// whose step is no larger. Exclusive with `substeps`.
    pub timestep: Option<f32>,
    /// Gravity [m/s²]. Default `[0, -9.81, 0]`.
    pub gravity: [f32; 3],
    /// Velocity damping rate [1/s]: velocities decay as exp(-damping · t). Default 0.5.
    pub damping: f32,
    /// Time integration. Default `"verlet"`.
    pub integrator: IntegratorKind,
    /// Constraint solver settings.
    pub solver: SolverSettings,
    /// The garments (at least one).
    pub garments: Vec<GarmentSpec>,
    /// Static analytic colliders. Default none.
    pub colliders: Vec<ColliderSpec>,
    /// Force fields on the garments: wind, attractors. Default none.
    pub forces: Vec<ForceSpec>,
    /// Accuracy the bake must reach in every frame; drape then chooses the substeps, iterations
    /// and collision passes the scene leaves out (`bake::budget`). Default none.
    pub accuracy: Option<AccuracySpec>,
    /// True when the scene (or a flag) gave `solver.iterations` (an accuracy target leaves it
    /// fixed). Not a scene field.
    #[serde(skip)]
    pub iterations_given: bool,
    /// Pre-roll frames included at the start of `frames` ([`Scene::with_preroll`]): 0 for a
    /// scene as written. Not a scene field.
    #[serde(skip)]
    pub lead_in: u32,
    /// Animated characters the garments collide with, through their particle shells. Default none.
    pub characters: Vec<CharacterSpec>,
    /// Particle–particle collisions: a garment against itself and against other garments (CPU
    /// and GPU backends). Default false.
    pub particle_collisions: bool,
    /// Radius of a garment particle in those collisions [m]; particles keep twice this apart.
    /// Default: half the smallest rest spacing of any garment.
    pub particle_radius: Option<f32>,
    /// Test each particle's path over a substep against analytic colliders, not only where it
    /// ends (analytic colliders and characters' shells), so fast colliders and large steps do
    /// not let cloth through. Default true.
    pub swept_collisions: bool,
    /// Folder that relative paths in the scene are resolved against (the scene file's folder;
    /// the working folder for scene text; `scenes/` of the materialised mannequin for the
    /// embedded default). Not a scene field.
    #[serde(skip)]
    pub base_dir: std::path::PathBuf,
    /// What to write.
    pub output: OutputSpec,
    /// Where to simulate. Default `"auto"`: a hardware GPU when there is one, else the CPU.
    pub backend: BackendKind,
    /// Write a checkpoint (`checkpoints/` in the output) every this many frames, and always
    /// after the last, so the bake can be resumed (`drape bake --resume`). Default: after the
    /// first frame that ends 10 s or more after the previous checkpoint. 0: no checkpoints
    /// (and no `checkpoints/frames.bin`, the log of every frame that a resume replays).
    pub checkpoint_every: Option<u32>,
}

/// Accuracy targets: the worst structural strain, the deepest penetration and the worst cell
/// shear any frame may have.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AccuracySpec {
    /// Largest structural strain in any frame (0.05: 5 %).
    pub max_strain: Option<f32>,
    /// Deepest a free garment particle may be inside a collider, a character's shell or its
    /// mesh in any frame [m].
    pub max_penetration: Option<f32>,
    /// Largest |90° − angle| of a lattice cell in any frame [degrees]; needs shear springs.
    pub max_shear: Option<f32>,
}

/// Where the simulation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BackendKind {
    /// The multi-threaded CPU solvers.
    Cpu,
    /// wgpu compute on any adapter, software ones (lavapipe) included.
    Gpu,
    /// A hardware GPU adapter when one exists and the solver has a GPU form, else the CPU.
    Auto,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            name: "scene".into(),
            fps: 60.0,
            frames: 120,
            frame_start: 1,
            substeps: None,
            timestep: None,
            gravity: [0.0, -9.81, 0.0],
            damping: 0.5,
            integrator: IntegratorKind::Verlet,
            solver: SolverSettings::default(),
            garments: Vec::new(),
            colliders: Vec::new(),
            characters: Vec::new(),
            particle_collisions: false,
            particle_radius: None,
            swept_collisions: true,
            base_dir: std::path::PathBuf::from("."),
            output: OutputSpec::default(),
            backend: BackendKind::Auto,
            checkpoint_every: None,
            forces: Vec::new(),
            accuracy: None,
            iterations_given: false,
            lead_in: 0,
        }
    }
}

/// How particles move between solves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorKind {
    /// Position Verlet with damping (thesis algorithm 2): inertia + gravity, then the solver.
    Verlet,
    /// No time integration: only the constraint solver moves particles (scene E).
    None,
}

/// Which constraint solver projects the particles back onto their constraints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverKind {
    /// Projective Dynamics, sequential Gauss-Seidel in grid order (the CPU reference).
    Gs,
    /// Projective Dynamics, Jacobi (every particle from the previous iterate).
    Jacobi,
    /// Projective Dynamics, multi-colour (red-black) Gauss-Seidel, colours in parallel.
    Rbgs,
    /// Position Based Dynamics, Jacobi with averaging (thesis algorithm 3).
    Pbd,
}

impl SolverKind {
    /// The name used in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Gs => "gs",
            SolverKind::Jacobi => "jacobi",
            SolverKind::Rbgs => "rbgs",
            SolverKind::Pbd => "pbd",
        }
    }
}

/// Solver settings.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Solver. Default `"rbgs"`.
    pub kind: SolverKind,
    /// Outer iterations per substep: each refreshes the spring directions (the local step).
    /// Default 10.
    pub iterations: u32,
    /// Inner iterations per outer iteration: sweeps of the global solve with fixed directions.
    /// Default 1. Ignored by `pbd`.
    pub inner_iterations: u32,
    /// Successive over-relaxation factor ω in (0, 2). Default 1 (plain Gauss-Seidel/Jacobi).
    pub omega: f32,
    /// Collision passes per substep: the iterations run in this many even shares, each followed
    /// by pushing particles out of the colliders and characters, so the solver works from
    /// positions that are out of them (friction acts once, at the end, on everything pushed).
    /// Default 1: collisions once, after the solve. Between 1 and `iterations`.
    pub contact_passes: u32,
    /// After each substep, structural springs stretched past this strain (0.2: 20 % longer
    /// than at rest) are pulled back to it (`sim::limit`). Default none. CPU backend.
    pub strain_limit: Option<f32>,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            kind: SolverKind::Rbgs,
            iterations: 10,
            inner_iterations: 1,
            omega: 1.0,
            contact_passes: 1,
            strain_limit: None,
        }
    }
}

/// Shape of a procedural garment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GarmentKind {
    /// A rectangular sheet: `resolution` [nu, nv] particles, `size` [u, v] metres, flat in its
    /// local XZ plane (horizontal before rotation), u along +X, v along +Z.
    Sheet,
    /// A rope: `resolution` [n] particles, `size` [length] metres along local +X.
    Rope,
    /// Any triangle mesh (`mesh`), voxelized at `spacing`: a thin sheet becomes one layer of
    /// particles, a closed solid is filled.
    Mesh,
}

/// Whether a mesh garment's inside is filled with particles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FillMode {
    /// Fill closed meshes (every edge shared by two triangles), not open ones.
    #[default]
    Auto,
    /// Fill what the mesh encloses (by winding number), even if it has gaps.
    Solid,
    /// Only the cells the surface passes through.
    Surface,
}

/// One garment: a particle grid with distance constraints.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct GarmentSpec {
    /// Name used for output files. Default `"garment<index>"`.
    pub name: Option<String>,
    /// Shape. Default `"sheet"`.
    pub kind: GarmentKind,
    /// Particles along each grid axis: [nu, nv] for a sheet, [n] for a rope. Default [32, 32].
    pub resolution: Vec<u32>,
    /// Rest size [m] along each grid axis, same length as `resolution`. Default 1 m per axis
    /// ([1, 1] for a sheet, [1] for a rope); read it with [`GarmentSpec::size`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<Vec<f32>>,
    /// Total mass [kg], spread evenly over the particles. Default 0.1.
    pub mass: f32,
    /// Centre of the garment [m]. Default [0, 1, 0].
    pub position: [f32; 3],
    /// Rotation, Euler angles in degrees applied in X, Y, Z order. Default [0, 0, 0].
    pub rotation: [f32; 3],
    /// Pinned particles as grid coordinates, one entry per grid axis; negative counts from the
    /// end (-1 is the last). Default none.
    pub pins: Vec<Vec<i64>>,
    /// Spring stiffness [N/m] per spring family.
    pub stiffness: Stiffness,
    /// Initial spacing as a multiple of the rest spacing (scene E lays its cloth at 5). Default 1.
    pub initial_stretch: f32,
    /// Cloth thickness [m]: particles keep thickness/2 from collider surfaces. Default 0.005.
    pub thickness: f32,
    /// Sheets: radius [m] of a round hole cut at the centre (a poncho's head hole). Default 0.
    pub hole_radius: f32,
    /// Colour in exports and previews, linear RGB in 0…1. Default: one of a palette by index.
    /// Also read as `color` (keys are spelt as in British English; the American spelling is
    /// accepted).
    #[serde(alias = "color")]
    pub colour: Option<[f32; 3]>,
    /// Springs break when stretched past this strain (0.5: 50 % longer than at rest), checked
    /// after every frame (on the CPU; a GPU bake takes the torn model afresh). Default none: the
    /// cloth never tears.
    pub tear_strain: Option<f32>,
    /// Particles that follow animated targets (a character's skin, or keyframed rigid motion).
    /// They are pinned: the solver moves the rest of the cloth after them. Default none.
    pub attachments: Vec<AttachmentSpec>,
    /// Mesh garments: the mesh file (any format assimp reads), relative to the scene's folder.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<String>,
    /// Mesh garments: the one mesh of `mesh`'s file to use (by mesh, node or material name);
    /// a character read from the same file then leaves it out. Default every mesh of the file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_name: Option<String>,
    /// Mesh garments: the character the mesh was modelled on. The file is then in that
    /// character's units and bind-pose frame, and the character's `scale`, `up`, `position` and
    /// `rotation` place it (`position` and `rotation` then move it from there; default none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on: Option<String>,
    /// Mesh garments: lattice spacing [m]. Default: the longest side of the placed mesh / 31.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spacing: Option<f32>,
    /// Mesh garments: scale from file units to metres. Default 1.
    pub scale: f32,
    /// Mesh garments: fill the inside. Default `"auto"`.
    pub fill: FillMode,
    /// Long-range attachments (Kim, Chentanez and Müller 2012): every free particle stays within
    /// its rest distance of its two nearest pins, so a pinned cloth cannot stretch away from its
    /// pins however few iterations the solver runs. Default true; no effect without pins.
    pub tethers: bool,
}

impl Default for GarmentSpec {
    fn default() -> Self {
        GarmentSpec {
            name: None,
            kind: GarmentKind::Sheet,
            resolution: vec![32, 32],
            size: None,
            mass: 0.1,
            position: [0.0, 1.0, 0.0],
            rotation: [0.0; 3],
            pins: Vec::new(),
            stiffness: Stiffness::default(),
            initial_stretch: 1.0,
            thickness: 0.005,
            hole_radius: 0.0,
            colour: None,
            attachments: Vec::new(),
            tear_strain: None,
            tethers: true,
            mesh: None,
            mesh_name: None,
            on: None,
            spacing: None,
            scale: 1.0,
            fill: FillMode::Auto,
        }
    }
}

impl GarmentSpec {
    /// Rest size [m] along each grid axis: the given one, or 1 m along each of the kind's axes.
    pub fn size(&self) -> Vec<f32> {
        self.size.clone().unwrap_or_else(|| match self.kind {
            GarmentKind::Rope => vec![1.0],
            GarmentKind::Sheet | GarmentKind::Mesh => vec![1.0, 1.0],
        })
    }
}

/// Garment particles attached to an animated target.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AttachmentSpec {
    /// Which particles: a region (`"top_edge"`, `"bottom_edge"`: the highest or lowest row at
    /// rest; `"corners"`; `"hole_rim"`: particles next to the cut hole) or grid coordinates
    /// like `pins`.
    pub particles: ParticleSelection,
    /// Follow this character's skin: each particle is bound to the nearest point of its surface
    /// at frame `frame` and keeps its offset in the skin's frame there (its smooth normal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub character: Option<String>,
    /// Character frame to bind at. Default 0.
    #[serde(default)]
    pub frame: u32,
    /// Or follow a keyframed rigid motion (linear between keys, held after the last).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keyframes: Vec<KeyframeSpec>,
    /// Point the keyframed rotation turns about [m]. Default the particles' centroid at rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot: Option<[f32; 3]>,
}

/// A named region of a garment or explicit grid coordinates.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(untagged)]
pub enum ParticleSelection {
    Region(String),
    Cells(Vec<Vec<i64>>),
    /// Every particle within a distance of a point at rest.
    Near(NearSelection),
}

/// Particles by proximity: every particle within `radius` [m] of `near` at rest.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct NearSelection {
    pub near: [f32; 3],
    pub radius: f32,
}

/// A key of a rigid motion: at `time`, translate by `translation` after rotating by `rotation`
/// (Euler degrees, X then Y then Z) about the pivot.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    /// Seconds from the start of the bake.
    pub time: f32,
    #[serde(default)]
    pub translation: [f32; 3],
    #[serde(default)]
    pub rotation: [f32; 3],
}

/// Projective Dynamics spring weights [N/m]. Shear and bend springs exist only when their
/// stiffness is above zero (Provot's mass-spring model: shear joins diagonal neighbours, bend joins
/// neighbours two apart along an axis).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Stiffness {
    /// Structural (axis neighbour) springs. Default 10 000 N/m: stiff enough that cloth barely
    /// stretches under its own weight, while Gauss-Seidel still converges in a few iterations.
    pub stretch: f32,
    /// Shear (diagonal) springs. Default 0 (off).
    pub shear: f32,
    /// Bend (two apart) springs. Default 0 (off).
    pub bend: f32,
}

impl Default for Stiffness {
    fn default() -> Self {
        Stiffness {
            stretch: 10_000.0,
            shear: 0.0,
            bend: 0.0,
        }
    }
}

/// Named regions of a sheet or rope an attachment can select.
pub const REGIONS: [&str; 4] = ["top_edge", "bottom_edge", "corners", "hole_rim"];
/// The regions that mean something on a voxelized mesh (its lattice corners are mostly empty
/// and every surface particle borders empty cells).
pub const MESH_REGIONS: [&str; 2] = ["top_edge", "bottom_edge"];

/// What a bake writes besides `report.json`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Write `obj/<garment>_<frame>.obj` (with `obj/materials.mtl`). Default true.
    pub obj: bool,
    /// Also write the characters' frames into `obj/`. Default false.
    pub character_obj: bool,
    /// glTF 2.0 of garments and characters animated over the frames (`docs/formats.md`):
    /// `"glb"` (one file), `"gltf"` (JSON + .bin) or `"none"`. Default `"glb"`.
    pub gltf: GltfOutput,
    /// Write a PC2 point cache and a rest OBJ per garment into `pc2/`. Default false.
    pub pc2: bool,
    /// Write a USD layer (`<scene>.usda`) with time-sampled points. Default false.
    pub usd: bool,
    /// Write an Alembic cache (`<scene>.abc`, Ogawa): a mesh per garment (and per character
    /// with `character_obj`) sampled every frame. Default false.
    pub alembic: bool,
    /// Render `preview/frame_0001.png …` and `preview/contact_sheet.png` (off-screen, any GPU
    /// adapter, software ones too). Default false.
    pub preview: bool,
    /// Preview size in pixels [width, height]. Default [1280, 720].
    pub preview_size: [u32; 2],
    /// Draw the triangles' edges over the preview. Default false.
    pub wireframe: bool,
    /// Record the total squared error after every solver iteration in the report. Default false.
    pub residuals: bool,
    /// Also write the characters' pre-roll frames, numbered before `frame_start`. Default false.
    pub preroll: bool,
}

/// glTF container choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GltfOutput {
    Glb,
    Gltf,
    None,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            obj: true,
            character_obj: false,
            gltf: GltfOutput::Glb,
            pc2: false,
            usd: false,
            alembic: false,
            preview: false,
            preview_size: [1280, 720],
            wireframe: false,
            residuals: false,
            preroll: false,
        }
    }
}

impl Scene {
    /// Reads, parses and validates a scene file. Garment meshes and characters are read later,
    /// when the garments are built (`garment::build_all`) and the characters loaded.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "cannot read", e))?;
        let base_dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
        Scene::parse_in(&text, &path.display().to_string(), &base_dir)
    }

    /// Where character `index`'s file is, resolved against the scene's folder.
    pub fn character_path(&self, index: usize) -> std::path::PathBuf {
        self.base_dir.join(&self.characters[index].file)
    }

    /// Parses and validates scene JSON; `file` names the source in error messages. Relative
    /// paths (garment meshes, characters) start at the working folder.
    pub fn parse(text: &str, file: &str) -> Result<Scene> {
        Scene::parse_in(text, file, Path::new("."))
    }

    /// Parses and validates scene JSON whose relative paths start at `base_dir`: pure data, no
    /// file is read.
    pub fn parse_in(text: &str, file: &str, base_dir: &Path) -> Result<Scene> {
        let mut scene = Scene::parse_only(text, file)?;
        scene.base_dir = base_dir.to_path_buf();
        Ok(scene)
    }

    fn parse_only(text: &str, file: &str) -> Result<Scene> {
        // A byte order mark is how some editors start UTF-8 files; it is not JSON.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut de = serde_json::Deserializer::from_str(text);
        let scene: Scene = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let mut reason = strip_position(&inner.to_string());
            // A collider's own check names its field: `.radius: a sphere needs a radius`.
            let mut path = path;
            if let Some((field, why)) = reason.strip_prefix('.').and_then(|r| r.split_once(": ")) {
                path = format!("{path}.{field}");
                reason = why.to_string();
            }
            if reason == "expected value" {
                if let Some(choices) = enum_choices(text, &path) {
                    reason = format!("expected {choices}");
                }
            }
            Error::SceneSyntax {
                file: file.to_string(),
                line: inner.line(),
                column: inner.column(),
                path: if path == "." {
                    "(top level)".into()
                } else {
                    path
                },
                reason,
            }
        })?;
        de.end().map_err(|e| top_level_syntax(file, &e))?;
        check_shapes(text, &scene, file)?;
        check_no_nulls(text, file)?;
        let mut scene = scene;
        let value = serde_json::from_str::<serde_json::Value>(text).ok();
        scene.iterations_given = value
            .as_ref()
            .and_then(|v| v.get("solver")?.get("iterations").cloned())
            .is_some();
        // A garment on a character is placed by the character: its own position defaults to
        // none rather than a metre up.
        for (i, g) in scene.garments.iter_mut().enumerate() {
            let given = value
                .as_ref()
                .and_then(|v| v.get("garments")?.get(i)?.get("position").cloned())
                .is_some();
            if g.on.is_some() && !given {
                g.position = [0.0; 3];
            }
        }
        validate(&scene, file)?;
        Ok(scene)
    }

    /// Substeps per frame, from `substeps` or `timestep` (validated before).
    pub fn substeps_per_frame(&self) -> u32 {
        match (self.substeps, self.timestep) {
            (Some(n), _) => n,
            (None, Some(dt)) => ((1.0 / (self.fps * dt)) - 1e-4).ceil().max(1.0) as u32,
            (None, None) => 10,
        }
    }

    /// Length of one simulation step [s].
    pub fn step_seconds(&self) -> f32 {
        1.0 / (self.fps * self.substeps_per_frame() as f32)
    }

    /// Frames simulated before the first frame: the longest of the characters' pre-rolls.
    pub fn preroll_frames(&self) -> u32 {
        self.characters
            .iter()
            .filter_map(|c| c.preroll)
            .map(|p| p.frames())
            .max()
            .unwrap_or(0)
    }

    /// The scene a bake simulates: its pre-roll frames ([`Scene::preroll_frames`]) made the
    /// first frames of the shot, numbered before `frame_start`, with every keyframe (of
    /// attachments, colliders, wind) as much later, so the first key holds through the
    /// pre-roll. `lead_in` records how many frames were added. A scene without a pre-roll, or
    /// one already expanded, is returned as it is.
    pub fn with_preroll(&self) -> Scene {
        let lead = self.preroll_frames();
        let mut scene = self.clone();
        if lead == 0 || self.lead_in > 0 {
            return scene;
        }
        scene.lead_in = lead;
        scene.frames += lead;
        scene.frame_start -= lead;
        let late = lead as f32 / self.fps;
        for g in &mut scene.garments {
            for a in &mut g.attachments {
                a.keyframes.iter_mut().for_each(|k| k.time += late);
                // A skin's frame `frame` of the scene is that many frames later.
                if a.character.is_some() {
                    a.frame += lead;
                }
            }
        }
        for c in &mut scene.colliders {
            c.keyframes.iter_mut().for_each(|k| k.time += late);
        }
        for f in &mut scene.forces {
            f.delay(late);
        }
        scene
    }

    /// The name of garment `index`, its own or the default `garment<index>`.
    pub fn garment_name(&self, index: usize) -> String {
        self.garments[index]
            .name
            .clone()
            .unwrap_or_else(|| format!("garment{index}"))
    }

    /// The name of character `index`: its own or `character<index>`.
    pub fn character_name(&self, index: usize) -> String {
        self.characters[index]
            .name
            .clone()
            .unwrap_or_else(|| format!("character{index}"))
    }
}

/// serde_json says only "expected value" when a named choice (`"solver": {"kind": 3}`) is not a
/// string. Asks the schema for the choices instead: the same text with an empty string at `path`
/// fails with "unknown variant ``, expected one of `gs`, …"; returns "one of `gs`, …".
fn enum_choices(text: &str, path: &str) -> Option<String> {
    let mut value: serde_json::Value = serde_json::from_str(text).ok()?;
    // serde_path_to_error's `garments[0].kind` as a JSON pointer `/garments/0/kind`.
    let pointer: String = path
        .replace('[', ".")
        .replace(']', "")
        .split('.')
        .filter(|p| !p.is_empty())
        .map(|p| format!("/{p}"))
        .collect();
    *value.pointer_mut(&pointer)? = serde_json::Value::String(String::new());
    let message = serde_json::from_value::<Scene>(value).err()?.to_string();
    let at = message.find("expected one of ")?;
    Some(message[at + "expected ".len()..].to_string())
}

/// serde accepts a JSON array wherever a struct is expected (`"solver": ["jacobi", 3]` would be
/// read field by field in declaration order, `[]` as all defaults). A scene is written with
/// objects: compare the text's shape with the parsed scene written back, and refuse an array where
/// the scene has an object.
fn check_shapes(text: &str, scene: &Scene, file: &str) -> Result<()> {
    use serde_json::Value;
    fn walk(given: &Value, parsed: &Value, path: &mut String) -> Option<String> {
        match (given, parsed) {
            (Value::Array(_), Value::Object(_)) => Some(path.clone()),
            (Value::Object(a), Value::Object(b)) => a.iter().find_map(|(key, v)| {
                let w = b.get(key)?;
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                let found = walk(v, w, path);
                path.truncate(len);
                found
            }),
            (Value::Array(a), Value::Array(b)) => {
                a.iter().zip(b).enumerate().find_map(|(i, (v, w))| {
                    let len = path.len();
                    path.push_str(&format!("[{i}]"));
                    let found = walk(v, w, path);
                    path.truncate(len);
                    found
                })
            }
            _ => None,
        }
    }
    let given: Value = serde_json::from_str(text).map_err(|e| top_level_syntax(file, &e))?;
    let parsed = serde_json::to_value(scene).expect("scenes serialise");
    match walk(&given, &parsed, &mut String::new()) {
        Some(path) => Err(Error::InvalidField {
            file: file.to_string(),
            field: if path.is_empty() {
                "(top level)".into()
            } else {
                path
            },
            reason: "expected an object ({ \"field\": value, … }), got an array".into(),
        }),
        None => Ok(()),
    }
}

/// One rule for `null`: it is never a value. A field left out takes its default; a `null`
/// would be read as the default by some fields and refused by others (`"size": null` against
/// `"mass": null`), so every one is refused, naming it.
fn check_no_nulls(text: &str, file: &str) -> Result<()> {
    use serde_json::Value;
    fn find(v: &Value, path: &mut String) -> bool {
        match v {
            Value::Null => true,
            Value::Object(map) => map.iter().any(|(key, v)| {
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                let found = find(v, path);
                if !found {
                    path.truncate(len);
                }
                found
            }),
            Value::Array(items) => items.iter().enumerate().any(|(i, v)| {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                let found = find(v, path);
                if !found {
                    path.truncate(len);
                }
                found
            }),
            _ => false,
        }
    }
    let value: Value = serde_json::from_str(text).map_err(|e| top_level_syntax(file, &e))?;
    let mut path = String::new();
    if find(&value, &mut path) {
        return Err(Error::InvalidField {
            file: file.to_string(),
            field: path,
            reason: "null is not a value: leave the field out for its default".into(),
        });
    }
    Ok(())
}

/// A JSON syntax error outside any field (trailing characters, nesting too deep).
fn top_level_syntax(file: &str, e: &serde_json::Error) -> Error {
    Error::SceneSyntax {
        file: file.to_string(),
        line: e.line(),
        column: e.column(),
        path: "(top level)".into(),
        reason: strip_position(&e.to_string()),
    }
}

/// serde_json appends " at line L column C" to its messages; drape prints the position itself.
fn strip_position(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message.to_string(),
    }
}

/// The reference scenes of `shared/reference/scenes.md`, embedded so benches and tests need no
/// files (the same text as `scenes/<name>.json`).
pub mod reference {
    /// Scene E: a 100 × 100 cloth laid out at 5 × its rest spacing; only the solver moves it.
    pub const ENLARGED_CLOTH: &str = include_str!("../../scenes/enlarged_cloth.json");
    /// Scene H: a 100 × 100 cloth pinned at two corners, hanging for 2 s.
    pub const HANGING_CLOTH: &str = include_str!("../../scenes/hanging_cloth.json");
    /// Scene S: a 64 × 64 cloth dropped onto a sphere.
    pub const SPHERE_DRAPE: &str = include_str!("../../scenes/sphere_drape.json");
    /// Scene W: a 1 m sheet hanging vertically from its two top corners (the mass-spring study's
    /// "sheet"), run until it comes to rest.
    pub const WASHING_LINE: &str = include_str!("../../scenes/washing_line.json");

    /// Parses one of the embedded reference scenes.
    pub fn load(text: &str, name: &str) -> super::Scene {
        super::Scene::parse(text, name).expect("reference scenes are valid")
    }
}
