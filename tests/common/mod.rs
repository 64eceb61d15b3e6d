//! Helpers shared by the integration tests: scenes from JSON text, bakes in temporary folders,
//! and running the `drape` binary.
#![allow(dead_code)]

use drape::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::Output;

/// Parses a scene written in the test (panics with the parse error if it is invalid).
pub fn scene(json: &str) -> Scene {
    Scene::parse(json, "<test scene>").unwrap_or_else(|e| panic!("test scene invalid: {e}"))
}

/// A fresh temporary folder, removed when dropped.
pub fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary folder")
}

/// Runs the drape binary with `args` in `dir`.
pub fn drape(dir: &Path, args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("drape runs")
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write test file");
    path
}

/// stderr of a finished command as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Largest distance any vertex of a character moves between consecutive frames [m].
pub fn largest_step(c: &drape::character::Character) -> f32 {
    c.frames
        .windows(2)
        .map(|w| {
            w[0].iter()
                .zip(&w[1])
                .map(|(p, q)| p.distance(*q))
                .fold(0.0, f32::max)
        })
        .fold(0.0, f32::max)
}

/// A GPU context on any adapter (lavapipe here and in CI), or None after printing "skipped" when
/// the machine has none.
pub fn gpu_context() -> Option<drape::gpu::GpuContext> {
    match drape::gpu::GpuContext::new(false) {
        Ok(c) => Some(c),
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

/// Largest distance between the particles of two simulations of one scene [m].
pub fn largest_gap(a: &drape::sim::Simulation, b: &drape::sim::Simulation) -> f32 {
    a.state
        .positions
        .iter()
        .zip(&b.state.positions)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}
