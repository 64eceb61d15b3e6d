//! The command line: `args` holds what was typed, `resolve` folds it into the scene, and each
//! command has its own file.

mod args;
mod bake;
mod bench;
mod inspect;
mod plan;
mod render;
mod resolve;
mod shell;

use clap::Parser;

/// Parses the command line and runs the command; returns the exit code.
pub fn run() -> anyhow::Result<i32> {
    let cli = args::Cli::parse();
    match cli.command {
        args::Command::Bake(a) => bake::run(a),
        args::Command::Inspect(a) => inspect::run(a),
        args::Command::Bench(a) => bench::run(a),
        args::Command::Shell(a) => shell::run(a),
        args::Command::Mannequin(a) => shell::mannequin(a),
        args::Command::Render(a) => render::run(a),
        args::Command::Plan(a) => plan::run(a),
    }
}
