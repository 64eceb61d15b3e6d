//! `drape shell`: a character's collision shell over its frames, written as a cache file; and the
//! character half of `drape inspect`.

use super::args::{CharacterArgs, CharacterLook, MannequinArgs, ShellArgs, UpArg};
use drape::character::{cache, sequence_files, Character, CharacterOptions, ShellCache};
use std::path::Path;
use std::time::Instant;

/// Import options from what was typed.
pub fn options(a: &CharacterArgs) -> CharacterOptions {
    CharacterOptions {
        time_offset: a.time_offset,
        speed: a.speed,
        looping: a.r#loop,
        position: a.position,
        rotation: a.rotation,
        ..look_options(&a.look)
    }
}

/// The options `CharacterLook` sets.
pub fn look_options(look: &CharacterLook) -> CharacterOptions {
    CharacterOptions {
        clip: look.clip.clone(),
        scale: look.scale,
        up: up(look.up),
        sequence_fps: look.sequence_fps,
        ..Default::default()
    }
}

/// The up axis typed.
pub fn up(u: UpArg) -> drape::character::UpAxis {
    match u {
        UpArg::Y => drape::character::UpAxis::Y,
        UpArg::Z => drape::character::UpAxis::Z,
    }
}

/// The flag a character field is typed as (`time_offset` → `--time-offset`).
fn flag(field: &str) -> String {
    format!("--{}", field.replace('_', "-"))
}

fn bad_flag(field: &str, reason: String) -> drape::Error {
    drape::Error::InvalidArgument {
        flag: flag(field),
        reason,
    }
}

/// Checks the flags of `CharacterLook` as the scene's character fields are checked.
pub fn check_look(look: &CharacterLook) -> drape::Result<()> {
    look_options(look)
        .check()
        .map_err(|(field, reason)| bad_flag(field, reason))?;
    // The same rule as a scene's `characters[].radius`.
    drape::scene::check_length(look.radius).map_err(|reason| bad_flag("radius", reason))?;
    Ok(())
}

/// Checks every flag of `CharacterArgs`.
pub fn check_args(a: &CharacterArgs) -> drape::Result<()> {
    check_look(&a.look)?;
    options(a)
        .check()
        .map_err(|(field, reason)| bad_flag(field, reason))?;
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(bad_flag(
            "fps",
            format!("must be a finite number above zero (got {})", a.fps),
        ));
    }
    if a.frames == Some(0) {
        return Err(bad_flag("frames", "must be at least 1".into()));
    }
    Ok(())
}

/// Refuses an `--out` that is a folder or an existing file other than a shell cache: `drape
/// shell` replaces only its own caches.
/// `drape shell SCENE.json --out DIR`: every character's shell of the scene into the cache folder
/// `DIR`, through the bake's own loading (so its bakes with `--shell-cache DIR` reuse them).
fn scene_shells(scene_file: &Path, dir: &Path) -> anyhow::Result<i32> {
    let scene = drape::scene::Scene::load(scene_file)?;
    if dir.exists() && !dir.is_dir() {
        return Err(drape::Error::InvalidArgument {
            flag: "--out".into(),
            reason: format!(
                "{} is a file; with a scene, --out is the folder of its shell caches",
                dir.display()
            ),
        }
        .into());
    }
    std::fs::create_dir_all(dir).map_err(|e| drape::Error::io(dir, "cannot create", e))?;
    let start = Instant::now();
    let mut warnings = Vec::new();
    let loaded = drape::bake::load_characters(&scene, dir, &mut warnings)?;
    for w in warnings {
        eprintln!("drape: warning: {w}");
    }
    for c in &loaded {
        println!(
            "character {}: shell of {} particles over {} frames, cache {}",
            c.report.name, c.report.shell_particles, c.report.frames, c.report.shell_cache
        );
    }
    println!(
        "{} shell{} in {} ({:.1} s)",
        loaded.len(),
        if loaded.len() == 1 { "" } else { "s" },
        dir.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(0)
}

fn check_out(out: &std::path::Path) -> drape::Result<()> {
    let reason = if out.is_dir() {
        "is a folder; give the cache file's path, e.g. walker.shell"
    } else if out.exists() && !ShellCache::is_cache_file(out) {
        "exists and is not a drape shell cache: refusing to overwrite it"
    } else if out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .is_some_and(|p| !p.is_dir())
    {
        "is in a folder that does not exist"
    } else {
        return Ok(());
    };
    Err(drape::Error::InvalidArgument {
        flag: "--out".into(),
        reason: format!("{} {reason}", out.display()),
    })
}

/// Loads a character with its clip's length (or `frames`) at `fps`.
pub fn load(
    path: &Path,
    options: &CharacterOptions,
    fps: f32,
    frames: Option<usize>,
) -> drape::Result<Character> {
    // Sample one frame first to learn the clip's duration, then the whole clip.
    let probe = Character::load(path, options, fps, 1)?;
    let count = frames.unwrap_or_else(|| match (&options.clip, probe.clips.is_empty()) {
        (Some(name), false) => {
            let names = probe.clips.iter().map(|c| c.0.as_str());
            let duration =
                drape::mesh::import::find_clip(names, name).map_or(0.0, |i| probe.clips[i].1);
            ((duration / options.speed as f64) * fps as f64).ceil() as usize + 1
        }
        _ => {
            let files = sequence_files(path).map_or(1, |f| f.len());
            match options.sequence_fps {
                // The sequence's length in seconds, resampled at `fps`.
                Some(rate) => {
                    (((files - 1) as f32 / rate / options.speed) * fps).round() as usize + 1
                }
                None => files,
            }
        }
    });
    Character::load(path, options, fps, count)
}

pub fn run(args: ShellArgs) -> anyhow::Result<i32> {
    let a = &args.character;
    if a.character.extension().is_some_and(|e| e == "json") {
        return scene_shells(&a.character, &args.out);
    }
    check_args(a)?;
    check_out(&args.out)?;
    let options = options(a);
    let start = Instant::now();
    let character = load(&a.character, &options, a.fps, a.frames)?;
    if let Some(w) = character.size_warning(a.look.scale) {
        eprintln!("drape: warning: {w}");
    }
    character
        .check_shell(a.look.radius)
        .map_err(|reason| bad_flag("radius", reason))?;
    let inputs = cache::input_hash(
        &sequence_files(&a.character)?,
        &options,
        a.look.radius,
        a.fps,
        character.frames.len(),
    )?;
    if let Ok(existing) = ShellCache::read(&args.out) {
        if existing.inputs == inputs {
            println!(
                "{} is up to date ({} particles, {} frames)",
                args.out.display(),
                existing.shell.len(),
                existing.frames.len()
            );
            return Ok(0);
        }
    }
    let imported = start.elapsed();
    let cache = ShellCache::build(&character, a.look.radius, inputs)?;
    cache.write(&args.out)?;
    let bytes = std::fs::metadata(&args.out).map_or(0, |m| m.len());
    println!(
        "{}: {} particles of radius {} m over {} frames; import {:.0} ms, shell {:.0} ms; {:.2} MiB written to {}",
        a.character.display(),
        cache.shell.len(),
        a.look.radius,
        cache.frames.len(),
        imported.as_secs_f64() * 1e3,
        (start.elapsed() - imported).as_secs_f64() * 1e3,
        bytes as f64 / (1024.0 * 1024.0),
        args.out.display()
    );
    Ok(0)
}

/// `drape inspect CHARACTER`: frames, vertices, bounds, clips and the shell's size.
pub fn inspect(
    path: &Path,
    options: &CharacterOptions,
    radius: f32,
    fps: f32,
) -> anyhow::Result<i32> {
    let character = load(path, options, fps, None)?;
    if let Some(w) = character.size_warning(options.scale) {
        eprintln!("drape: warning: {w}");
    }
    for w in &character.warnings {
        eprintln!("drape: warning: {w}");
    }
    println!("character {}: valid", path.display());
    for (i, (name, duration)) in character.clips.iter().enumerate() {
        let label = if name.is_empty() {
            format!("#{i} (unnamed)")
        } else {
            format!("{name:?}")
        };
        println!("  clip {label}: {duration:.3} s");
    }
    println!(
        "  height: {:.3} m at scale {} (frame 1)",
        character.height(),
        options.scale
    );
    let clip = options.clip.as_deref().unwrap_or("rest pose");
    println!(
        "  {} frames at {fps} fps ({clip}), {} vertices, {} triangles, same topology: {}",
        character.frames.len(),
        character.frames[0].len(),
        character.triangles[0].len(),
        character.same_topology()
    );
    let shown = character.frames.len().min(8);
    for k in (0..character.frames.len()).step_by(character.frames.len().div_ceil(shown).max(1)) {
        let (lo, hi) = character.bounds(k);
        println!(
            "  frame {:>4}: {lo:.3} … {hi:.3}, size {:.3}",
            k + 1,
            hi - lo
        );
    }
    character
        .check_shell(radius)
        .map_err(|reason| bad_flag("radius", reason))?;
    if path.is_file() && !path.to_string_lossy().contains('%') {
        let asset = drape::character::Asset::open_character(path)?;
        inspect_meshes(&asset, &character, options, radius);
        inspect_joints(&asset, path);
        inspect_poses(&asset, &character, options);
    }
    let shell =
        drape::character::Shell::sample(&character.frames[0], &character.triangles[0], radius);
    let (binding, positions) = shell.memory_bytes(character.frames.len());
    println!(
        "  shell: {} particles of radius {radius} m; {:.2} MiB bound to triangles, {:.2} MiB of positions for all frames",
        shell.len(),
        binding as f64 / 1048576.0,
        positions as f64 / 1048576.0
    );
    Ok(0)
}

/// The file's meshes: names, counts, whether each collides, and the shell particles each
/// would carry on the first frame.
fn inspect_meshes(
    asset: &drape::character::Asset,
    character: &Character,
    options: &CharacterOptions,
    radius: f32,
) {
    // The shell as it would be sampled on the first frame, every mesh included (when that
    // fits drape's limits; the colliding meshes' shell was checked already).
    let triangles = asset.triangles();
    let area = drape::character::shell::surface_area(character.frame(0), &triangles);
    let shell = drape::character::Shell::check_size(area, radius, 1)
        .ok()
        .map(|_| drape::character::Shell::sample(character.frame(0), &triangles, radius));
    let ranges = asset.mesh_triangle_ranges();
    println!("  meshes ({}):", ranges.len());
    for (mesh, range) in ranges {
        let particles = shell.as_ref().map_or("?".to_string(), |s| {
            let n = s
                .triangle
                .iter()
                .filter(|&&t| range.contains(&(t as usize)));
            n.count().to_string()
        });
        let collides = options.meshes.as_ref().is_none_or(|s| s.collides(mesh));
        println!(
            "    {:?} (node {:?}, material {:?}): {} vertices, {} triangles, {}{}",
            mesh.name,
            mesh.node,
            mesh.material,
            mesh.vertices.len(),
            mesh.triangles.len(),
            if mesh.bones.is_empty() {
                "rigid".to_string()
            } else {
                format!("skinned to {} bones", mesh.bones.len())
            },
            if collides {
                format!(", {particles} shell particles")
            } else {
                ", left out of the collisions (characters[].meshes)".to_string()
            }
        );
    }
}

/// The file's joints (the names `characters[].joints` takes), each with the triangles it and
/// the joints below it mostly move (what `{"exclude": [name]}` leaves out of the collisions).
fn inspect_joints(asset: &drape::character::Asset, path: &std::path::Path) {
    let names = asset.joint_names();
    if names.is_empty() {
        return;
    }
    let all = asset.triangles().len();
    let listed: Vec<String> = names
        .iter()
        .map(|&n| {
            let exclude = drape::scene::MeshSelection::Exclude(vec![n.to_string()]);
            let kept = asset.colliding_triangles(None, Some(&exclude), path);
            let moved = kept.map_or(all, |k| all - k.len());
            format!("{n:?} ({moved})")
        })
        .collect();
    println!(
        "  joints ({}), each with the triangles it and the joints below it move (characters[].joints): {}",
        names.len(),
        listed.join(", ")
    );
}

/// The bind pose, the default node pose and the first frame side by side, with a word when
/// they differ.
fn inspect_poses(
    asset: &drape::character::Asset,
    character: &Character,
    options: &CharacterOptions,
) {
    let transform = options.transform();
    let placed = |v: Vec<glam::Vec3>| -> Vec<glam::Vec3> {
        v.iter().map(|&p| transform.transform_point3(p)).collect()
    };
    let bind = placed(asset.bind_pose());
    let rest = placed(asset.pose(None, 0.0));
    let first = character.frame(0);
    let bounds = |v: &[glam::Vec3]| {
        v.iter().fold(
            (
                glam::Vec3::splat(f32::INFINITY),
                glam::Vec3::splat(f32::NEG_INFINITY),
            ),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    };
    let apart = |a: &[glam::Vec3], b: &[glam::Vec3]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| p.distance(*q))
            .fold(0.0f32, f32::max)
    };
    let clip = options
        .clip
        .as_deref()
        .map_or("no clip".to_string(), |c| format!("clip {c:?}"));
    for (label, v) in [
        ("bind pose", &bind[..]),
        ("default pose", &rest[..]),
        (&format!("first frame ({clip})")[..], first),
    ] {
        let (lo, hi) = bounds(v);
        println!("  {label}: {lo:.3} … {hi:.3}, size {:.3}", hi - lo);
    }
    // 1 mm: poses closer than that are the same pose.
    let same = 1e-3;
    let (d_rest, d_first) = (apart(&bind, &rest), apart(&bind, first));
    if d_rest > same {
        println!(
            "  the default node pose differs from the bind pose (vertices up to {d_rest:.3} m apart): \
             garments modelled on this character are modelled on the bind pose"
        );
    }
    if first.len() == bind.len() && d_first > same {
        println!(
            "  the first frame differs from the bind pose (vertices up to {d_first:.3} m apart)"
        );
    }
}

/// `drape mannequin`: writes the mannequin's frame sequences and stool.
pub fn mannequin(args: MannequinArgs) -> anyhow::Result<i32> {
    let files = drape::character::mannequin::files();
    for (name, text) in &files {
        let path = args.out.join(name);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| drape::Error::io(dir, "cannot create", e))?;
        }
        std::fs::write(&path, text).map_err(|e| drape::Error::io(&path, "cannot write", e))?;
    }
    println!("wrote {} files into {}", files.len(), args.out.display());
    Ok(0)
}
