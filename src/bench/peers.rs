//! `drape bench peers`: drape against Blender's cloth on the same scenes, each tool's frames
//! measured by the same code.
//!
//! For each scene, drape writes a job (`bench/peers/blender_cloth.py` reads it): the garment's
//! own lattice as a quad mesh (vertex order kept), its pins, mass, stiffness and damping, and
//! the character (the same file, clip and placement) over a ground plane. Blender bakes it at
//! three of its quality settings, drape at its shipped settings and at accuracy targets. Both
//! tools write OBJ frames of the cloth and of the character's evaluated mesh; this module reads
//! them back and computes for both, with `sim::metrics` and `collide::mesh`, the strain and cell
//! shear of the lattice's springs and the cloth vertices inside the tool's own character mesh.
//! Times are each tool's own per-frame wall clock with the export excluded. The CSV, a chart
//! and a table go into `docs/bench/peers.*` and `docs/accuracy-vs-speed.md`.

use super::chart::{write_atomically, Chart, Series, Style};
use crate::bake::{bake, BakeOptions, Resume};
use crate::collide::mesh::Surface;
use crate::error::{Error, Result};
use crate::garment::{Garment, SpringFamily};
use crate::scene::{AccuracySpec, BackendKind, ColliderShape, GarmentKind, GltfOutput, Scene};
use crate::sim::metrics::constraint_error;
use crate::sim::model::Model;
use glam::{Vec3, Vec4};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where the table sits in `accuracy-vs-speed.md`.
pub const BEGIN: &str = "<!-- drape bench peers -->";
pub const END: &str = "<!-- /drape bench peers -->";

/// Blender's script, carried in the binary so the command runs from any folder.
const BLENDER_SCRIPT: &str = include_str!("../../bench/peers/blender_cloth.py");

/// Blender's cloth `quality` settings compared: steps per frame (5 is Blender's default).
const QUALITIES: [u32; 3] = [5, 10, 20];

/// What `drape bench peers` is asked.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Blender's executable (default: `$BLENDER`, then `blender` on the PATH).
    pub blender: Option<PathBuf>,
    /// Frames of every scene (default: each scene's own).
    pub frames: Option<u32>,
    /// Small scenes, a few frames, one Blender quality and drape as shipped: the whole path
    /// in under a minute (its figures are not the docs').
    pub quick: bool,
    /// Keep both tools' bakes (OBJ frames, Blender's jobs) in `OUT/bench/peers-frames`.
    pub keep: bool,
}

/// Blender to run: `given`, else `$BLENDER`, else `blender` on the PATH. Without one the
/// bench cannot run, and says how to get it (exit 2).
pub fn find_blender(given: Option<&Path>) -> Result<PathBuf> {
    let missing = |reason: String| Error::InvalidArgument {
        flag: "--blender".into(),
        reason,
    };
    if let Some(path) = given {
        return if path.is_file() {
            Ok(path.to_path_buf())
        } else {
            Err(missing(format!("{} is not a file", path.display())))
        };
    }
    if let Some(path) = std::env::var_os("BLENDER").filter(|p| !p.is_empty()) {
        let path = PathBuf::from(path);
        return if path.is_file() {
            Ok(path)
        } else {
            Err(missing(format!(
                "$BLENDER is {}, which is not a file",
                path.display()
            )))
        };
    }
    std::env::var_os("PATH")
        .into_iter()
        .flat_map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
        .map(|dir| dir.join("blender"))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            missing(
                "drape bench peers needs Blender, and there is no `blender` on the PATH: \
                 install it (Debian/Ubuntu: `sudo apt install blender python3-numpy`) or pass \
                 --blender PATH"
                    .into(),
            )
        })
}

/// One scene of the comparison, with the garment it compares.
struct Peer {
    label: String,
    scene: Scene,
    garment: Garment,
    model: Model,
}

/// The scenes compared: free cloth with shear springs (H as the peers model it), a blanket
/// dropped on a small robot running, and a poncho dropped on a man walking.
fn peers(root: &Path, options: &Options) -> Result<Vec<Peer>> {
    let names = [
        ("H (shear springs)", "hanging_cloth_shear.json"),
        ("blanket on RobotExpressive", "blanket_run.json"),
        ("poncho on CesiumMan", "poncho_walk.json"),
    ];
    let mut out = Vec::new();
    for (label, file) in names {
        if options.quick && file == "poncho_walk.json" {
            continue;
        }
        let path = root.join("scenes").join(file);
        let mut scene = Scene::load(&path)?;
        // Blender's cloth runs without self-collision (`blender_cloth.py`): drape too, so both
        // tools bake the same model.
        scene.particle_collisions = false;
        if let Some(frames) = options.frames {
            scene.frames = frames;
        }
        if options.quick {
            scene.frames = options.frames.unwrap_or(6);
            scene.garments[0].resolution = vec![16, 16];
        }
        let shown = path.display().to_string();
        let garment = comparable(&scene, &shown)?;
        let model = Model::new(std::slice::from_ref(&garment));
        out.push(Peer {
            label: label.into(),
            scene,
            garment,
            model,
        });
    }
    Ok(out)
}

/// The scene's one sheet, if Blender can model what drape does with it.
fn comparable(scene: &Scene, file: &str) -> Result<Garment> {
    let refuse = |field: &str, reason: &str| Error::InvalidField {
        file: file.into(),
        field: field.into(),
        reason: format!("drape bench peers: {reason}"),
    };
    if scene.garments.len() != 1 || scene.garments[0].kind != GarmentKind::Sheet {
        return Err(refuse("garments", "compares scenes of one sheet"));
    }
    if !scene.garments[0].attachments.is_empty() {
        return Err(refuse(
            "garments[0].attachments",
            "Blender's pins do not follow skin",
        ));
    }
    if scene.characters.len() > 1 {
        return Err(refuse("characters", "compares one character at most"));
    }
    if let Some(c) = scene.characters.first() {
        if c.time_offset != 0.0 || c.speed != 1.0 || c.preroll.is_some() {
            return Err(refuse(
                "characters[0]",
                "compares a clip played from its start at its own speed, with no pre-roll",
            ));
        }
    }
    for (i, c) in scene.colliders.iter().enumerate() {
        let ground = matches!(c.shape, ColliderShape::Plane { point, normal }
            if point.is_none_or(|p| p == [0.0; 3]) && normal.is_none_or(|n| n[0] == 0.0 && n[2] == 0.0 && n[1] > 0.0));
        if !ground {
            return Err(refuse(
                &format!("colliders[{i}]"),
                "compares a ground plane through the origin only",
            ));
        }
    }
    let mut garments = crate::garment::build_all(scene, file)?;
    Ok(garments.remove(0))
}

/// What the same code reads from one bake's frames, whichever tool made them.
#[derive(Clone, Copy, Debug, Default)]
struct Reading {
    frames: usize,
    /// Mean over frames of each frame's mean structural strain.
    mean_strain: f64,
    /// The worst frame's largest structural strain.
    max_strain: f64,
    /// Mean over frames of each frame's mean cell shear [degrees].
    mean_shear_deg: f64,
    /// Frames with a cloth vertex inside the tool's own character mesh.
    frames_inside: usize,
    /// The deepest such vertex [m].
    deepest: f32,
}

/// One bake of the comparison.
struct Run {
    scene: String,
    tool: String,
    setting: String,
    ms_per_frame: f64,
    reading: Reading,
    /// Blender's character against drape's: the mean distance of its vertices from drape's
    /// character mesh, on the worst of the first, middle and last frames [m].
    body_offset: Option<f32>,
    /// drape with accuracy targets: whether every frame met them.
    met: Option<bool>,
    /// Why the bake stopped early (its figures cover the frames before).
    failed: Option<String>,
}

/// Blender's character must lie on drape's within this [m], or the two tools baked different
/// scenes and the bench stops.
const BODY_TOLERANCE: f32 = 0.002;

/// Bakes every scene in both tools, writes `out/bench/peers.csv` and `peers-{mean,worst}.svg`,
/// and puts the table into `out/accuracy-vs-speed.md`. Returns the table.
pub fn run(
    root: &Path,
    out: &Path,
    options: &Options,
    log: &mut dyn FnMut(&str),
) -> Result<String> {
    let path = find_blender(options.blender.as_deref())?;
    let version = blender_version(&path)?;
    log(&format!("Blender: {} ({version})", path.display()));
    let bench = out.join("bench");
    std::fs::create_dir_all(&bench).map_err(|e| Error::io(&bench, "cannot create", e))?;
    let work = if options.keep {
        let kept = bench.join("peers-frames");
        let _ = std::fs::remove_dir_all(&kept);
        kept
    } else {
        bench.join(format!(".peers-{}", std::process::id()))
    };
    let result = (|| {
        let script = work.join("blender_cloth.py");
        std::fs::create_dir_all(&work).map_err(|e| Error::io(&work, "cannot create", e))?;
        std::fs::write(&script, BLENDER_SCRIPT)
            .map_err(|e| Error::io(&script, "cannot write", e))?;
        let blender = Blender {
            path: path.clone(),
            version: version.clone(),
            script,
        };
        let mut runs = Vec::new();
        for (i, peer) in peers(root, options)?.iter().enumerate() {
            let dir = work.join(format!("scene{i}"));
            for run in drape_runs(peer, &dir, options.quick)? {
                log(&line(&run));
                runs.push(run);
            }
            let job = dir.join("job.json");
            write_job(peer, &job)?;
            let qualities: &[u32] = if options.quick { &[5] } else { &QUALITIES };
            for &quality in qualities {
                let run = blender.bake(peer, &job, quality, &dir)?;
                log(&line(&run));
                runs.push(run);
            }
        }
        Ok(runs)
    })();
    if !options.keep {
        let _ = std::fs::remove_dir_all(&work);
    }
    let runs = result?;
    write_atomically(&bench.join("peers.csv"), csv(&runs).as_bytes())?;
    for (measure, value) in MEASURES {
        let file = format!("peers-{}.svg", measure.split(' ').next().unwrap_or(measure));
        chart(&runs, measure, value).write_svg(&bench.join(file))?;
    }
    let table = table(&runs);
    super::studies::set_section(
        &out.join("accuracy-vs-speed.md"),
        BEGIN,
        END,
        &format!(
            "## drape against Blender's cloth (`drape bench peers`)\n\n\
             Generated by `drape bench peers` on {} with {version}. The same lattice, mass, \
             stiffness and damping in both tools (conversions in `bench/peers/blender_cloth.py`), \
             the character imported by each from the same file; strain and shear of the \
             lattice's springs and cloth vertices inside each tool's own character mesh, \
             computed by the same code from both tools' OBJ frames. ms per frame: each tool's \
             simulation (Blender: `frame_set`, the character's evaluation included; drape: its \
             frame, the character's shells included), export excluded, CPU, every core.\n\n\
             ![ms per frame against mean strain](bench/peers-mean.svg)\n\n\
             ![ms per frame against worst strain](bench/peers-worst.svg)\n\n{table}",
            super::studies::machine()
        ),
    )?;
    Ok(table)
}

fn line(r: &Run) -> String {
    format!(
        "{} {} {}: {:.2} ms/frame, mean strain {:.3} %, worst {:.2} %, shear {:.2}°, {} frames inside, deepest {:.1} mm{}",
        r.scene,
        r.tool,
        r.setting,
        r.ms_per_frame,
        r.reading.mean_strain * 100.0,
        r.reading.max_strain * 100.0,
        r.reading.mean_shear_deg,
        r.reading.frames_inside,
        r.reading.deepest * 1e3,
        r.failed.as_ref().map_or(String::new(), |f| format!(" ({f})"))
    )
}

/// `blender --version`'s first line ("Blender 3.4.1").
fn blender_version(blender: &Path) -> Result<String> {
    let out = Command::new(blender)
        .arg("--version")
        .output()
        .map_err(|e| Error::io(blender, "cannot run", e))?;
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find(|l| l.starts_with("Blender"))
        .map(|l| l.trim().to_string())
        .ok_or_else(|| Error::InvalidArgument {
            flag: "--blender".into(),
            reason: format!(
                "{} --version printed no Blender version: {}",
                blender.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        })
}

/// drape's settings: as shipped, then worst-strain targets choosing the budget, down to the
/// worst strain Blender's settings reach on H.
fn drape_settings(quick: bool) -> Vec<(String, Option<AccuracySpec>)> {
    let target = |strain: f32| AccuracySpec {
        max_strain: Some(strain),
        max_penetration: None,
        max_shear: None,
    };
    let mut v = vec![("as shipped".to_string(), None)];
    if !quick {
        for strain in [0.10, 0.05, 0.02, 0.01] {
            v.push((
                format!("max_strain {} %", strain * 100.0),
                Some(target(strain)),
            ));
        }
    }
    v
}

/// drape's bakes of `peer`, each measured from its OBJ frames.
fn drape_runs(peer: &Peer, dir: &Path, quick: bool) -> Result<Vec<Run>> {
    let mut runs = Vec::new();
    for (k, (setting, accuracy)) in drape_settings(quick).into_iter().enumerate() {
        let mut s = peer.scene.clone();
        s.backend = BackendKind::Cpu;
        s.output.obj = true;
        s.output.character_obj = true;
        s.output.gltf = GltfOutput::None;
        s.output.preview = false;
        s.checkpoint_every = Some(0);
        if accuracy.is_some() {
            s.substeps = None;
            s.timestep = None;
            s.iterations_given = false;
        }
        s.accuracy = accuracy;
        let out = dir.join(format!("drape{k}"));
        let options = BakeOptions {
            out: out.clone(),
            scene_file: format!("{} ({setting})", peer.label),
            threads: None,
            progress: crate::bake::ProgressView::Hidden,
            shell_cache: Some(dir.join("cache")),
            resume: Resume::No,
            until: None,
            // Timed against Blender on every core: none of its frames sent to one thread.
            fixed_team: true,
        };
        let report = bake(&s, &options)?.report;
        let body = s.characters.first().map(|_| s.character_name(0));
        let reading = read_frames(peer, &out.join("obj"), &peer.garment.name, body.as_deref())?;
        runs.push(Run {
            scene: peer.label.clone(),
            tool: "drape".into(),
            setting,
            ms_per_frame: report.ms_per_frame.mean,
            reading,
            body_offset: None,
            met: report.budget.as_ref().map(|b| b.met),
            failed: report.failure.as_ref().map(|f| {
                format!(
                    "unstable at frame {} of {}: {}",
                    f.frame, report.frames_requested, f.reason
                )
            }),
        });
    }
    Ok(runs)
}

/// Blender, ready to bake jobs: its executable, version and the script it runs.
struct Blender {
    path: PathBuf,
    version: String,
    script: PathBuf,
}

impl Blender {
    /// Blender's bake of `peer` (its job written to `job`) at `quality` into
    /// `dir/blender-qQUALITY`, measured from its OBJ frames; its character is checked against
    /// drape's first bake in `dir/drape0`.
    fn bake(&self, peer: &Peer, job: &Path, quality: u32, dir: &Path) -> Result<Run> {
        let (blender, version, script) = (&self.path, &self.version, &self.script);
        let drape_bodies = dir.join("drape0").join("obj");
        let out = dir.join(format!("blender-q{quality}"));
        let run = Command::new(blender)
            .args([
                "-b",
                "--factory-startup",
                "--python-exit-code",
                "1",
                "--python",
            ])
            .arg(script)
            .arg("--")
            .arg(job)
            .arg(&out)
            .arg(quality.to_string())
            .output()
            .map_err(|e| Error::io(blender, "cannot run", e))?;
        let timing = out.join("timing.json");
        if !run.status.success() || !timing.is_file() {
            let err = String::from_utf8_lossy(&run.stderr);
            let tail: Vec<&str> = err.lines().rev().take(12).collect();
            return Err(Error::io(
                script,
                "Blender failed to bake",
                std::io::Error::other(format!(
                    "{} (exit {:?}) on {}:\n{}",
                    version,
                    run.status.code(),
                    job.display(),
                    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                )),
            ));
        }
        let text =
            std::fs::read_to_string(&timing).map_err(|e| Error::io(&timing, "cannot read", e))?;
        let json: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::io(&timing, "cannot parse", std::io::Error::other(e)))?;
        let ms: Vec<f64> = json["frame_ms"]
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
            .unwrap_or_default();
        let body = (!peer.scene.characters.is_empty()).then_some("body");
        let reading = read_frames(peer, &out, "cloth", body)?;
        let body_offset = match body {
            Some(body) => {
                let offset = body_offset(peer, &drape_bodies, &out, body)?;
                if offset > BODY_TOLERANCE {
                    return Err(Error::io(
                        &out,
                        "Blender's character does not line up with drape's",
                        std::io::Error::other(format!(
                            "its vertices lie {:.1} mm from drape's character on average (more than {:.1} mm): the two tools would bake different scenes",
                            offset * 1e3,
                            BODY_TOLERANCE * 1e3
                        )),
                    ));
                }
                Some(offset)
            }
            None => None,
        };
        Ok(Run {
            scene: peer.label.clone(),
            tool: version.to_string(),
            setting: format!("quality {quality}"),
            ms_per_frame: ms.iter().sum::<f64>() / ms.len().max(1) as f64,
            reading,
            body_offset,
            met: None,
            failed: None,
        })
    }
}

/// The job Blender's script reads: the garment's lattice as quads in grid order, its pins,
/// mass and springs, the character's file, clip and placement, and the ground.
fn write_job(peer: &Peer, path: &Path) -> Result<()> {
    let s = &peer.scene;
    let g = &peer.garment;
    let spec = &s.garments[0];
    let stretch: Vec<f32> = g
        .springs
        .iter()
        .filter(|sp| sp.family == SpringFamily::Stretch)
        .map(|sp| sp.rest)
        .collect();
    let mean_edge = stretch.iter().sum::<f32>() / stretch.len().max(1) as f32;
    let character = match s.characters.first() {
        None => serde_json::Value::Null,
        Some(c) => {
            let file = s.character_path(0);
            let asset = crate::mesh::import::Asset::open_character(&file)?;
            let clip = match &c.clip {
                Some(name) => Some(asset.clip_index(name).ok_or_else(|| Error::InvalidField {
                    file: file.display().to_string(),
                    field: "clip".into(),
                    reason: format!("no clip {name:?}"),
                })?),
                None => None,
            };
            // Blender's importer names an unnamed animation `Anim_<index>`.
            let animation = clip.map(|i| match asset.clips[i].name.as_str() {
                "" => format!("Anim_{i}"),
                name => name.to_string(),
            });
            let options = c.options();
            let m = options.transform().transpose().to_cols_array();
            serde_json::json!({
                "file": std::fs::canonicalize(&file).unwrap_or(file).display().to_string(),
                "animation": animation,
                "seconds": clip.map_or(0.0, |i| asset.clips[i].duration),
                "loop": c.looping,
                "matrix": m,
                "radius": c.radius,
                "friction": c.friction,
            })
        }
    };
    let quads = quads(g);
    let edges = loose_edges(g, &quads);
    let job = serde_json::json!({
        "fps": s.fps,
        "frames": s.frames,
        "frame_start": s.frame_start,
        "gravity": s.gravity,
        "damping": s.damping,
        "plane": !s.colliders.is_empty(),
        "cloth": {
            "vertices": g.positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
            "quads": quads,
            "edges": edges,
            "pins": g.pins,
            "vertex_mass": g.particle_mass,
            "stretch": spec.stiffness.stretch,
            "shear": spec.stiffness.shear,
            "bend": spec.stiffness.bend,
            "mean_edge": mean_edge,
            "contact_radius": g.contact_radius,
        },
        "character": character,
    });
    std::fs::write(path, job.to_string()).map_err(|e| Error::io(path, "cannot write", e))
}

/// The sheet's cells as quads over its particles (grid order), counter-clockwise seen from the
/// sheet's +Y like drape's triangles; a cell with a corner cut away (a hole) has none.
fn quads(g: &Garment) -> Vec<[u32; 4]> {
    let [nx, ny, nz] = g.dims;
    let mut at = vec![u32::MAX; (nx * ny * nz) as usize];
    for (k, c) in g.cells.iter().enumerate() {
        at[(c[0] + nx * (c[1] + ny * c[2])) as usize] = k as u32;
    }
    let (u, v) = if nz > 1 { (nx, nz) } else { (nx, ny) };
    let index = |i: u32, j: u32| {
        if nz > 1 {
            at[(i + nx * ny * j) as usize]
        } else {
            at[(i + nx * j) as usize]
        }
    };
    let mut quads = Vec::new();
    for j in 0..v.saturating_sub(1) {
        for i in 0..u.saturating_sub(1) {
            let q = [
                index(i, j),
                index(i, j + 1),
                index(i + 1, j + 1),
                index(i + 1, j),
            ];
            if q.iter().all(|&k| k != u32::MAX) {
                quads.push(q);
            }
        }
    }
    // Wind each quad as drape's triangles over the same corners are wound.
    if let Some(t) = g.triangles.first() {
        let normal = |a: u32, b: u32, c: u32| {
            let p = |k: u32| g.positions[k as usize];
            (p(b) - p(a)).cross(p(c) - p(a))
        };
        let drape = normal(t[0], t[1], t[2]);
        if let Some(q) = quads.first() {
            if normal(q[0], q[1], q[2]).dot(drape) < 0.0 {
                for q in &mut quads {
                    q.reverse();
                }
            }
        }
    }
    quads
}

/// The structural springs on no quad's side (where a hole cut a cell in half): Blender makes a
/// structural spring of every mesh edge, loose ones included.
fn loose_edges(g: &Garment, quads: &[[u32; 4]]) -> Vec<[u32; 2]> {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let sides: std::collections::HashSet<(u32, u32)> = quads
        .iter()
        .flat_map(|q| (0..4).map(move |k| key(q[k], q[(k + 1) % 4])))
        .collect();
    g.springs
        .iter()
        .filter(|sp| sp.family == SpringFamily::Stretch && !sides.contains(&key(sp.a, sp.b)))
        .map(|sp| [sp.a, sp.b])
        .collect()
}

/// Reads `dir/<cloth>_NNNN.obj` (and `dir/<body>_NNNN.obj`) for every frame and measures them.
fn read_frames(peer: &Peer, dir: &Path, cloth: &str, body: Option<&str>) -> Result<Reading> {
    let s = &peer.scene;
    let mut reading = Reading::default();
    let n = peer.garment.particle_count();
    let mut storage = vec![Vec4::ZERO; n];
    for k in 0..s.frames {
        let number = s.frame_start + k;
        let file = dir.join(crate::export::obj::frame_file_name(cloth, number));
        if !file.is_file() {
            break;
        }
        let (vertices, _) = read_obj(&file)?;
        if vertices.len() != n {
            return Err(Error::io(
                &file,
                "cannot measure",
                std::io::Error::other(format!(
                    "{} vertices, not the {n} particles",
                    vertices.len()
                )),
            ));
        }
        for (e, v) in vertices.iter().enumerate() {
            storage[peer.model.storage_of[e] as usize] = v.extend(1.0);
        }
        let error = constraint_error(&peer.model, &storage);
        reading.frames += 1;
        reading.mean_strain += error.mean_strain;
        reading.max_strain = reading.max_strain.max(error.max_strain);
        reading.mean_shear_deg += error.mean_shear_deg;
        if let Some(body) = body {
            let file = dir.join(crate::export::obj::frame_file_name(body, number));
            let (body_vertices, triangles) = read_obj(&file)?;
            let p = Surface::new(&body_vertices, &triangles).penetration(&vertices);
            if p.inside > 0 {
                reading.frames_inside += 1;
                reading.deepest = reading.deepest.max(p.deepest);
            }
        }
    }
    let frames = reading.frames.max(1) as f64;
    reading.mean_strain /= frames;
    reading.mean_shear_deg /= frames;
    Ok(reading)
}

/// How far Blender's character (`blender/<body>_NNNN.obj`) lies from drape's (`drape`): the
/// mean distance of its vertices from drape's mesh, on the worst of the first, middle and last
/// frames [m].
fn body_offset(peer: &Peer, drape: &Path, blender: &Path, body: &str) -> Result<f32> {
    let s = &peer.scene;
    let name = s.character_name(0);
    let mut worst = 0.0f32;
    for k in [0, s.frames / 2, s.frames.saturating_sub(1)] {
        let number = s.frame_start + k;
        let (ours, triangles) =
            read_obj(&drape.join(crate::export::obj::frame_file_name(&name, number)))?;
        let (theirs, _) =
            read_obj(&blender.join(crate::export::obj::frame_file_name(body, number)))?;
        let nearest = Surface::new(&ours, &triangles).nearest_signed(&theirs);
        let mean = nearest.iter().map(|n| n.distance.abs() as f64).sum::<f64>()
            / nearest.len().max(1) as f64;
        worst = worst.max(mean as f32);
    }
    Ok(worst)
}

/// The vertices and triangles (faces fanned) of an OBJ file.
fn read_obj(path: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let bad = |line: usize| {
        Error::io(
            path,
            "cannot parse",
            std::io::Error::other(format!("line {}", line + 1)),
        )
    };
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    for (i, l) in text.lines().enumerate() {
        let mut words = l.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words.take(3).filter_map(|w| w.parse().ok()).collect();
                let [x, y, z] = c[..] else { return Err(bad(i)) };
                vertices.push(Vec3::new(x, y, z));
            }
            Some("f") => {
                let ids: Vec<u32> = words
                    .filter_map(|w| w.split('/').next()?.parse::<u32>().ok())
                    .map(|k| k - 1)
                    .collect();
                if ids.len() < 3 {
                    return Err(bad(i));
                }
                for k in 1..ids.len() - 1 {
                    triangles.push([ids[0], ids[k], ids[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok((vertices, triangles))
}

fn csv(runs: &[Run]) -> String {
    let mut csv = String::from(
        "scene,tool,setting,ms_per_frame,frames,mean_strain,max_strain,mean_shear_deg,frames_inside,deepest_m,body_offset_m,targets_met,failed\n",
    );
    for r in runs {
        let m = &r.reading;
        csv.push_str(&format!(
            "{},{},{},{:.4},{},{:.6},{:.6},{:.4},{},{:.6},{},{},{}\n",
            r.scene,
            r.tool,
            r.setting,
            r.ms_per_frame,
            m.frames,
            m.mean_strain,
            m.max_strain,
            m.mean_shear_deg,
            m.frames_inside,
            m.deepest,
            r.body_offset.map_or(String::new(), |o| format!("{o:.6}")),
            r.met.map_or(String::new(), |m| m.to_string()),
            r.failed.is_some()
        ));
    }
    csv
}

fn table(runs: &[Run]) -> String {
    let mut md = String::from(
        "| scene | tool | setting | ms per frame | mean strain | worst strain | mean cell shear | frames with cloth inside | deepest |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in runs {
        let m = &r.reading;
        md.push_str(&format!(
            "| {} | {} | {}{}{} | {:.2} | {:.3} % | {:.2} % | {:.2}° | {} of {} | {:.1} mm |\n",
            r.scene,
            r.tool,
            r.setting,
            if r.met == Some(false) {
                " (not met in every frame)"
            } else {
                ""
            },
            r.failed
                .as_ref()
                .map_or(String::new(), |f| format!(" (**{f}**)")),
            r.ms_per_frame,
            m.mean_strain * 100.0,
            m.max_strain * 100.0,
            m.mean_shear_deg,
            m.frames_inside,
            m.frames,
            m.deepest * 1e3,
        ));
    }
    md.push('\n');
    md.push_str(&speedups(runs));
    md
}

/// A reading's figure of one accuracy.
type Measure = fn(&Reading) -> f64;

/// The two accuracies compared: a name and the reading's figure.
const MEASURES: [(&str, Measure); 2] = [
    ("mean strain", |r| r.mean_strain),
    ("worst strain", |r| r.max_strain),
];

/// The fastest of `runs`.
fn cheapest<'a>(runs: impl Iterator<Item = &'a Run>) -> Option<&'a Run> {
    runs.min_by(|x, y| x.ms_per_frame.total_cmp(&y.ms_per_frame))
}

/// Per scene and measure: how much faster drape is at each Blender setting's accuracy (its
/// cheapest bake that is no less accurate), and what Blender needs for drape's shipped one.
fn speedups(runs: &[Run]) -> String {
    let mut text = String::new();
    let mut scenes: Vec<&str> = runs.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        let of = |drape: bool| {
            runs.iter().filter(move |r| {
                r.scene == scene && (r.tool == "drape") == drape && r.failed.is_none()
            })
        };
        for (measure, value) in MEASURES {
            text.push_str(&format!("- **{scene}**, {measure}:"));
            for b in of(false) {
                let at = of(true).filter(|d| value(&d.reading) <= value(&b.reading));
                text.push_str(&match cheapest(at) {
                    Some(d) => format!(
                        " at Blender's {} ({:.3} %, {:.0} ms/frame) drape {} takes {:.1} ms/frame ({:.1} × faster);",
                        b.setting,
                        value(&b.reading) * 100.0,
                        b.ms_per_frame,
                        d.setting,
                        d.ms_per_frame,
                        b.ms_per_frame / d.ms_per_frame
                    ),
                    None => format!(
                        " no drape setting reaches Blender's {} ({:.3} %);",
                        b.setting,
                        value(&b.reading) * 100.0
                    ),
                });
            }
            let Some(d) = of(true).find(|r| r.setting == "as shipped") else {
                text.push('\n');
                continue;
            };
            let reached = of(false).filter(|b| value(&b.reading) <= value(&d.reading));
            text.push_str(&match cheapest(reached) {
                Some(b) => format!(
                    " at drape's shipped {:.3} % ({:.1} ms/frame) Blender needs {} ({:.0} ms/frame, {:.1} × slower).\n",
                    value(&d.reading) * 100.0,
                    d.ms_per_frame,
                    b.setting,
                    b.ms_per_frame,
                    b.ms_per_frame / d.ms_per_frame
                ),
                None => format!(
                    " no Blender setting compared reaches drape's shipped {:.3} % ({:.1} ms/frame).\n",
                    value(&d.reading) * 100.0,
                    d.ms_per_frame
                ),
            });
        }
    }
    text
}

/// `measure` (of [`MEASURES`]) against ms per frame: a colour per scene, drape's settings
/// joined by a line, Blender's by a dashed one, each point named by its setting.
fn chart(runs: &[Run], measure: &str, value: Measure) -> Chart {
    let mut series: Vec<Series> = Vec::new();
    let mut scenes: Vec<&str> = Vec::new();
    for r in runs {
        let colour = match scenes.iter().position(|s| *s == r.scene) {
            Some(c) => c,
            None => {
                scenes.push(&r.scene);
                scenes.len() - 1
            }
        };
        let drape = r.tool == "drape";
        let name = format!("{}: {}", r.scene, if drape { "drape" } else { &r.tool });
        let point = (
            r.ms_per_frame.max(1e-3),
            (value(&r.reading) * 100.0).max(1e-4),
        );
        let s = match series.iter().position(|s| s.name == name) {
            Some(k) => &mut series[k],
            None => {
                let style = if drape { Style::Line } else { Style::Dashed };
                series.push(Series::new(name, Vec::new(), style, colour));
                series.last_mut().expect("just added")
            }
        };
        s.points.push(point);
        s.notes.push((point.0, point.1, r.setting.clone()));
    }
    for s in &mut series {
        let mut order: Vec<usize> = (0..s.points.len()).collect();
        order.sort_by(|&a, &b| s.points[a].0.total_cmp(&s.points[b].0));
        s.points = order.iter().map(|&k| s.points[k]).collect();
    }
    Chart {
        title: format!("drape and Blender's cloth on the same scenes: {measure}"),
        x_label: "ms per frame (CPU)".into(),
        y_label: format!("{measure} [%]"),
        x_log: true,
        y_log: true,
        series,
        ..Chart::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sheet_with_a_hole_is_its_springs_as_quads_wound_as_its_triangles_and_loose_edges() {
        let scene = Scene::parse(
            r#"{ "garments": [{ "resolution": [12, 12], "hole_radius": 0.2 }] }"#,
            "t.json",
        )
        .unwrap();
        let g = comparable(&scene, "t.json").unwrap();
        let q = quads(&g);
        let loose = loose_edges(&g, &q);
        // Each whole cell is a quad; the rim has half cells too (drape draws them as one
        // triangle), whose lattice edges are the quads' or loose edges.
        assert!(q.len() * 2 < g.triangles.len());
        let mut edges: Vec<(u32, u32)> = q
            .iter()
            .flat_map(|q| (0..4).map(move |k| (q[k].min(q[(k + 1) % 4]), q[k].max(q[(k + 1) % 4]))))
            .chain(loose.iter().map(|e| (e[0].min(e[1]), e[0].max(e[1]))))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let mut springs: Vec<(u32, u32)> = g
            .springs
            .iter()
            .filter(|s| s.family == SpringFamily::Stretch)
            .map(|s| (s.a.min(s.b), s.a.max(s.b)))
            .collect();
        springs.sort_unstable();
        // Blender's structural springs are exactly drape's.
        assert_eq!(edges, springs);
        let p = |k: u32| g.positions[k as usize];
        let t = g.triangles[0];
        let drape = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
        for q in &q {
            let n = (p(q[1]) - p(q[0])).cross(p(q[2]) - p(q[0]));
            assert!(n.dot(drape) > 0.0);
            // Neighbours along the lattice: every edge is a structural spring's length.
            for k in 0..4 {
                let d = p(q[k]).distance(p(q[(k + 1) % 4]));
                assert!((d - 1.0 / 11.0).abs() < 1e-5, "{d}");
            }
        }
    }

    #[test]
    fn without_blender_the_bench_says_how_to_get_it() {
        let e = find_blender(Some(Path::new("/nonexistent/blender"))).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("/nonexistent/blender"), "{e}");
    }
}
