//! `drape bake`: simulate a scene and write its frames and report.

use super::args::BakeArgs;
use super::resolve;
use drape::bake::{bake, BakeOptions};
use std::path::PathBuf;

pub fn run(args: BakeArgs) -> anyhow::Result<i32> {
    let (scene, scene_file) = resolve::scene(&args.scene)?;
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    let options = BakeOptions {
        out,
        scene_file,
        threads: args.threads,
        progress: true,
    };
    let result = bake(&scene, &options)?;
    let r = &result.report;
    println!(
        "baked {} of {} frames of '{}' into {}: {} particles, {:.2} ms per frame (median, {} threads)",
        r.frames_baked,
        r.frames_requested,
        r.scene,
        result.out.display(),
        r.particles,
        r.ms_per_frame.median,
        r.backend.threads,
    );
    if let Some(last) = &r.last_frame {
        println!(
            "last frame: mean strain {:.3} %, max strain {:.3} %, total squared error {:.3e} m²",
            last.mean_strain * 100.0,
            last.max_strain * 100.0,
            last.total_squared_error
        );
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
