//! Folds what was typed into the scene: loads the file (or the embedded default) and applies the
//! command-line overrides, which are validated like the scene's own fields.

use super::args::{SceneArgs, SolverArg};
use drape::scene::{self, Scene, SolverKind};
use drape::Error;

/// The scene to run and the name of its source.
pub fn scene(args: &SceneArgs) -> Result<(Scene, String), Error> {
    let (mut scene, file) = match &args.scene {
        Some(path) => (Scene::load(path)?, path.display().to_string()),
        None => (
            Scene::default_scene(&drape::bake::shell_cache_dir())?,
            scene::DEFAULT_SCENE_FILE.to_string(),
        ),
    };
    if let Some(s) = args.solver {
        scene.solver.kind = match s {
            SolverArg::Gs => SolverKind::Gs,
            SolverArg::Jacobi => SolverKind::Jacobi,
            SolverArg::Rbgs => SolverKind::Rbgs,
            SolverArg::Pbd => SolverKind::Pbd,
        };
    }
    let flag = |flag: &str, e: Error| match e {
        Error::InvalidField { reason, .. } => Error::InvalidArgument {
            flag: flag.to_string(),
            reason,
        },
        other => other,
    };
    if let Some(n) = args.frames {
        scene.frames = n;
        scene::validate(&scene, &file).map_err(|e| flag("--frames", e))?;
    }
    if let Some(n) = args.frame_start {
        scene.frame_start = n;
        scene::validate(&scene, &file).map_err(|e| flag("--frame-start", e))?;
    }
    if let Some(n) = args.iterations {
        scene.solver.iterations = n;
        scene.iterations_given = true;
        scene.solver.contact_passes = scene.solver.contact_passes.min(n.max(1));
        scene::validate(&scene, &file).map_err(|e| flag("--iterations", e))?;
    }
    if let Some(n) = args.contact_passes {
        scene.solver.contact_passes = n;
        scene::validate(&scene, &file).map_err(|e| flag("--contact-passes", e))?;
    }
    if let Some(w) = args.omega {
        scene.solver.omega = w;
        scene::validate(&scene, &file).map_err(|e| flag("--omega", e))?;
    }
    if let Some(n) = args.substeps {
        scene.substeps = Some(n);
        scene.timestep = None;
        scene::validate(&scene, &file).map_err(|e| flag("--substeps", e))?;
    }
    for (name, value) in [
        ("--max-strain", args.max_strain),
        ("--max-penetration", args.max_penetration),
        ("--max-shear", args.max_shear),
    ] {
        if let Some(v) = value {
            let a = scene.accuracy.get_or_insert_with(Default::default);
            match name {
                "--max-strain" => a.max_strain = Some(v),
                "--max-penetration" => a.max_penetration = Some(v),
                _ => a.max_shear = Some(v),
            }
            scene::validate(&scene, &file).map_err(|e| flag(name, e))?;
        }
    }
    Ok((scene, file))
}
