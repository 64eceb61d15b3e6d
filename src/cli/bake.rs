//! `drape bake`: simulate a scene and write its frames and report.

use super::args::{BackendArg, BakeArgs, GltfArg};
use super::resolve;
use drape::bake::{bake, BakeOptions, Resume};
use drape::report::BudgetKind;
use drape::scene::{BackendKind, GltfOutput};
use std::path::PathBuf;

/// SIGINT and SIGTERM ask the bake to stop after the current frame (see
/// [`drape::bake::INTERRUPT`]); a second one ends the process at once (the default action: the
/// next bake into the same folder cleans up the staging folder it leaves).
fn stop_on_signals() {
    #[cfg(unix)]
    {
        extern "C" fn stop(signal: libc::c_int) {
            drape::bake::INTERRUPT.store(signal, std::sync::atomic::Ordering::Relaxed);
            // SAFETY: restoring the default disposition is async-signal-safe.
            unsafe {
                libc::signal(signal, libc::SIG_DFL);
            }
        }
        for signal in [libc::SIGINT, libc::SIGTERM] {
            // SAFETY: the handler only stores an atomic and resets its own disposition.
            unsafe {
                libc::signal(
                    signal,
                    stop as extern "C" fn(libc::c_int) as libc::sighandler_t,
                );
            }
        }
    }
}

/// What the bake did, for the terminal: warnings on stderr, frames, exports, preview and the
/// last frame's accuracy on stdout.
fn print_summary(r: &drape::report::Report, out: &std::path::Path) {
    for w in &r.warnings {
        eprintln!("drape: warning: {w}");
    }
    let on = match &r.backend.adapter {
        Some(a) => format!("GPU {} ({})", a.name, a.device_type),
        None => format!("CPU, {} threads", r.backend.threads),
    };
    println!(
        "baked {} of {} frames of '{}' into {}: {} particles, {:.2} ms per frame (median, {on})",
        r.frames_baked,
        r.frames_requested,
        r.scene,
        out.display(),
        r.particles,
        r.ms_per_frame.median,
    );
    if let Some(r) = &r.resumed {
        println!(
            "resumed after frame {} from {} ({:.0} ms to replay)",
            r.after_frame, r.checkpoint, r.replay_ms
        );
    }
    for c in &r.characters {
        println!(
            "character {}: {:.2} m tall, {} shell particles of radius {} m ({})",
            c.name, c.height_m, c.shell_particles, c.shell_radius, c.shell_cache
        );
    }
    if let Some(p) = &r.preroll {
        let worst = p
            .mesh_penetrations
            .iter()
            .map(|m| m.penetration.deepest)
            .fold(0.0f32, f32::max);
        println!(
            "pre-roll: {} of {} frames before frame {} ({}): {:.0} ms, max strain {:.3} %, deepest inside a character's mesh {:.1} mm",
            p.frames_baked,
            p.frames,
            r.frame_start,
            if p.exported { "exported" } else { "not exported" },
            p.ms,
            p.max_strain * 100.0,
            worst * 1e3
        );
    }
    if let Some(c) = r.clean_start.as_ref().filter(|c| c.moved > 0) {
        println!(
            "clean start: {} garment particles moved out of the characters ({} of them inside a mesh), {:.1} mm at the most",
            c.moved,
            c.inside_mesh,
            c.largest_move_m * 1e3
        );
    }
    if let Some(c) = r.clean_start.as_ref().filter(|c| c.layered > 0) {
        println!(
            "clean start: {} garment particles moved out over a garment put on before theirs (garments on one character layered in the scene's order), {:.1} mm at the most",
            c.layered,
            c.largest_layering_m * 1e3
        );
    }
    for e in &r.exports {
        println!(
            "wrote {}: {} files, {:.1} MB in {:.0} ms",
            e.format,
            e.files,
            e.bytes as f64 / 1e6,
            e.ms
        );
    }
    if let Some(p) = &r.preview {
        println!(
            "rendered {} preview frames at {}×{} on {}: {:.0} ms per frame; contact sheet {}",
            p.frames,
            p.width,
            p.height,
            p.adapter,
            p.ms_per_frame,
            out.join(&p.contact_sheet).display()
        );
    }
    if let Some(last) = &r.last_frame {
        println!(
            "last frame: mean strain {:.3} %, max strain {:.3} % (stretch {:.3} %), cell shear {:.2}° mean, {:.2}° max, total squared error {:.3e} m²",
            last.mean_strain * 100.0,
            last.max_strain * 100.0,
            last.max_stretch * 100.0,
            last.mean_shear_deg,
            last.max_shear_deg,
            last.total_squared_error
        );
    }
    print_crossings(r);
}

/// The bake's cloth–cloth crossings: how many frames pass through themselves, and the worst.
fn print_crossings(r: &drape::report::Report) {
    if let Some(worst) = r
        .crossings_per_frame
        .iter()
        .rev()
        .max_by_key(|c| c.crossings)
    {
        let frames = r
            .crossings_per_frame
            .iter()
            .filter(|c| c.crossings > 0)
            .count();
        println!(
            "cloth crossings: {frames} of {} frames pass through themselves, the most {} triangle pairs (frame {})",
            r.crossings_per_frame.len(),
            worst.crossings,
            worst.frame
        );
    }
}

/// The command that resumes a bake of `scene` into `out`.
fn resume_command(scene: &Option<PathBuf>, out: &std::path::Path) -> String {
    let quote = |p: &std::path::Path| {
        let s = p.display().to_string();
        if s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,".contains(c))
        {
            s
        } else {
            format!("'{}'", s.replace('\'', "'\\''"))
        }
    };
    let scene = scene.as_deref().map(|s| format!(" {}", quote(s)));
    format!(
        "drape bake{} --out {} --resume (with the same flags)",
        scene.unwrap_or_default(),
        quote(out)
    )
}

/// The command line's overrides of `scene`'s backend, checkpoints and outputs.
fn apply_overrides(scene: &mut drape::scene::Scene, args: &BakeArgs) {
    if let Some(b) = args.backend {
        scene.backend = match b {
            BackendArg::Cpu => BackendKind::Cpu,
            BackendArg::Gpu => BackendKind::Gpu,
            BackendArg::Auto => BackendKind::Auto,
        };
    }
    if let Some(n) = args.checkpoint_every {
        scene.checkpoint_every = Some(n);
    }
    let o = &mut scene.output;
    o.preview |= args.preview;
    o.wireframe |= args.wireframe;
    o.pc2 |= args.pc2;
    o.usd |= args.usd;
    o.alembic |= args.alembic;
    if let Some((w, h)) = args.preview_size {
        o.preview_size = [w, h];
    }
    if let Some(g) = args.gltf {
        o.gltf = match g {
            GltfArg::Glb => GltfOutput::Glb,
            GltfArg::Gltf => GltfOutput::Gltf,
            GltfArg::None => GltfOutput::None,
        };
    }
}

pub fn run(args: BakeArgs) -> anyhow::Result<i32> {
    let (mut scene, scene_file) = resolve::scene(&args.scene)?;
    let scene_arg = args.scene.scene.clone();
    apply_overrides(&mut scene, &args);
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    let options = BakeOptions {
        out,
        scene_file,
        threads: args.threads,
        progress: if args.progress_lines {
            drape::bake::ProgressView::Lines
        } else {
            drape::bake::ProgressView::Bar
        },
        shell_cache: args.shell_cache.clone(),
        resume: match (args.from_frame, args.resume) {
            (Some(k), _) => Resume::From(k),
            (None, true) => Resume::Last,
            (None, false) => Resume::No,
        },
        until: args.until,
        fixed_team: args.fixed_threads,
    };
    stop_on_signals();
    let result = bake(&scene, &options)?;
    let r = &result.report;
    for w in &result.warnings {
        eprintln!("drape: warning: {w}");
    }
    print_summary(r, &result.out);
    if let Some(i) = &r.interrupted {
        let name = match i.signal {
            2 => "SIGINT",
            15 => "SIGTERM",
            _ => "a signal",
        };
        let (done, destination) = match &result.kept {
            Some(kept) => (
                format!(
                    "the previous complete bake is untouched in {}; this one's {} frames, report.json and a checkpoint are kept beside it in {}",
                    kept.display(),
                    r.frames_baked,
                    result.out.display()
                ),
                kept.clone(),
            ),
            None => (
                format!(
                    "the {} frames baked so far, report.json and a checkpoint are in {}",
                    r.frames_baked,
                    result.out.display()
                ),
                result.out.clone(),
            ),
        };
        eprintln!(
            "drape: interrupted by {name} after frame {}: {done}; to finish: {}",
            i.after_frame,
            resume_command(&scene_arg, &destination),
        );
        return Ok(128 + i.signal);
    }
    // A budget that answers to stability alone misses only where the bake stopped (below).
    let targets = r.budget.as_ref().filter(|b| b.kind == BudgetKind::Targets);
    if let Some(b) = targets.filter(|b| !b.met) {
        let (s, i) = b.levels[b.levels.len() - 1];
        let kept = match b.kept_missing {
            0 => String::new(),
            n => format!(
                "; {n} of them were kept at a smaller budget, where they missed by about as much as at the larger one (budget.per_frame[].kept_missing): what holds them off is then not the solver's budget but the scene (cloth pressed between body parts, or forced by its attachments), and a looser target or a change to the scene meets them, more substeps do not"
            ),
        };
        eprintln!(
            "drape: error: some frames missed the accuracy targets (the largest budget is {s} substeps × {i} iterations): worst strain {:.2} %, deepest penetration {:.2} mm{kept}; the frames and report.json (budget.per_frame) are in {}",
            b.max_strain_reached * 100.0,
            b.deepest_penetration_reached * 1e3,
            result.out.display()
        );
        return Ok(1);
    }
    match &r.failure {
        Some(f) => {
            eprintln!(
                "drape: error: the simulation became unstable at frame {}: {}; the {} frames before it and report.json are in {}",
                f.frame,
                f.reason,
                r.frames_baked,
                result.out.display()
            );
            Ok(1)
        }
        None => Ok(0),
    }
}
