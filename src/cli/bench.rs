//! `drape bench solvers`: µs per iteration on scene E and ms per frame with stretch on scenes H
//! and S, for every solver and thread count; printed and optionally written as CSV.

use super::args::{BackendArg, BenchArgs, BenchWhat};
use drape::bench::{
    convergence, integrator_report, studies, time_frames, time_iterations, time_size, SOLVERS,
};
use drape::scene::reference;
use drape::scene::SolverKind;
use std::fmt::Write as _;

pub fn run(args: BenchArgs) -> anyhow::Result<i32> {
    match args.what {
        BenchWhat::Sizes => return sizes(&args),
        BenchWhat::Budget => return budget(&args),
        BenchWhat::Peers => return peers(&args),
        BenchWhat::Characters => return characters(&args),
        BenchWhat::Convergence | BenchWhat::Integrators | BenchWhat::Docs => return studies(&args),
        BenchWhat::Solvers => {}
    }
    let threads = if args.threads.is_empty() {
        let all = std::thread::available_parallelism().map_or(1, |n| n.get());
        if all > 1 {
            vec![1, all]
        } else {
            vec![1]
        }
    } else {
        args.threads.clone()
    };
    let e = reference::load(reference::ENLARGED_CLOTH, "enlarged_cloth.json");
    let h = reference::load(reference::HANGING_CLOTH, "hanging_cloth.json");
    let s = reference::load(reference::SPHERE_DRAPE, "sphere_drape.json");
    let mut csv = String::from("scene,solver,threads,iterations_or_frames,us_per_iteration,ms_per_frame_median,total_squared_error,mean_strain,max_strain,inside,deepest_m,stable,mean_shear_deg\n");

    iteration_rows(&e, &threads, args.iterations, &mut csv)?;
    frame_rows(&[&h, &s], &threads, args.frames.unwrap_or(120), &mut csv)?;
    if let Some(path) = &args.csv {
        std::fs::write(path, csv).map_err(|e| drape::Error::io(path, "cannot write", e))?;
        println!("wrote {}", path.display());
    }
    Ok(0)
}

/// Scene E's rows of `drape bench solvers`: µs per iteration for every solver and thread count,
/// printed and added to `csv`.
fn iteration_rows(
    e: &drape::scene::Scene,
    threads: &[usize],
    iterations: u32,
    csv: &mut String,
) -> anyhow::Result<()> {
    println!(
        "scene E ({} iterations from the 5x-stretched start):",
        iterations
    );
    println!(
        "  {:<8} {:>7} {:>14} {:>16}",
        "solver", "threads", "µs/iteration", "squared error"
    );
    for &t in threads {
        for kind in SOLVERS {
            let r = time_iterations(e, kind, t, iterations)?;
            println!(
                "  {:<8} {:>7} {:>14.1} {:>16.4e}",
                r.solver, t, r.us_per_iteration, r.residual
            );
            let _ = writeln!(
                csv,
                "E,{},{t},{},{:.3},,{:e},,,,,,",
                r.solver, r.iterations, r.us_per_iteration, r.residual
            );
        }
    }
    Ok(())
}

/// The frame rows of `drape bench solvers` for `scenes`: ms per frame and accuracy for every
/// solver and thread count, printed and added to `csv`.
fn frame_rows(
    scenes: &[&drape::scene::Scene],
    threads: &[usize],
    frames: u32,
    csv: &mut String,
) -> anyhow::Result<()> {
    for scene in scenes {
        println!(
            "scene {} ({} frames, {} substeps x {} iterations):",
            scene.name,
            frames,
            scene.substeps_per_frame(),
            scene.solver.iterations
        );
        println!(
            "  {:<8} {:>7} {:>10} {:>12} {:>12} {:>11} {:>8} {:>10} {:>7}",
            "solver",
            "threads",
            "ms/frame",
            "mean strain",
            "max strain",
            "cell shear",
            "inside",
            "deepest",
            "stable"
        );
        for &t in threads {
            for kind in SOLVERS {
                let r = time_frames(scene, kind, t, frames)?;
                println!(
                    "  {:<8} {:>7} {:>10.2} {:>11.3}% {:>11.2}% {:>10.2}° {:>8} {:>8.1}mm {:>7}",
                    r.solver,
                    t,
                    r.ms_per_frame_median,
                    r.mean_strain * 100.0,
                    r.max_strain * 100.0,
                    r.mean_shear_deg,
                    r.inside,
                    r.deepest * 1e3,
                    r.stable
                );
                let _ = writeln!(
                    csv,
                    "{},{},{t},{},,{:.3},,{:e},{:e},{},{:e},{},{:.3}",
                    r.scene,
                    r.solver,
                    r.frames,
                    r.ms_per_frame_median,
                    r.mean_strain,
                    r.max_strain,
                    r.inside,
                    r.deepest,
                    r.stable,
                    r.mean_shear_deg
                );
            }
        }
    }
    Ok(())
}

/// `drape bench sizes`: µs per iteration and ms per frame for each backend and parallel solver at
/// each size. Iterations and frames shrink with size so a software GPU finishes in minutes.
fn sizes(args: &BenchArgs) -> anyhow::Result<i32> {
    let mut csv = String::from("backend,solver,particles,us_per_iteration,ms_per_frame\n");
    println!(
        "{:<44} {:<7} {:>10} {:>14} {:>10}",
        "backend", "solver", "particles", "µs/iteration", "ms/frame"
    );
    let open = || drape::gpu::GpuContext::new(false);
    for &backend in &args.backends {
        for &n in &args.sizes {
            let particles = (n as u64) * (n as u64);
            let iterations = if particles >= 1_000_000 { 20 } else { 100 };
            let frames = if particles >= 1_000_000 { 1 } else { 3 };
            for kind in [SolverKind::Rbgs, SolverKind::Jacobi, SolverKind::Pbd] {
                let gpu: Option<&dyn Fn() -> drape::Result<drape::gpu::GpuContext>> =
                    (backend != BackendArg::Cpu).then_some(&open as _);
                let r = time_size(kind, n, iterations, frames, gpu)?;
                println!(
                    "{:<44} {:<7} {:>10} {:>14.1} {:>10.2}",
                    r.backend, r.solver, r.particles, r.us_per_iteration, r.ms_per_frame
                );
                let _ = writeln!(
                    csv,
                    "{},{},{},{:.3},{:.3}",
                    r.backend, r.solver, r.particles, r.us_per_iteration, r.ms_per_frame
                );
            }
        }
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, csv).map_err(|e| drape::Error::io(path, "cannot write", e))?;
        println!("wrote {}", path.display());
    }
    Ok(0)
}

/// `drape bench convergence|integrators|docs`: the speed-against-accuracy studies.
fn studies(args: &BenchArgs) -> anyhow::Result<i32> {
    let mut log = |line: &str| println!("{line}");
    let (conv, integ) = if args.quick {
        (
            convergence::Config::quick(),
            integrator_report::Config::quick(),
        )
    } else {
        (
            convergence::Config::full(),
            integrator_report::Config::full(),
        )
    };
    match args.what {
        BenchWhat::Convergence => {
            let out = args.out.clone().unwrap_or_else(|| "docs/bench".into());
            convergence::report(&conv, &out, &mut log)?;
            println!("wrote {}/convergence-*", out.display());
        }
        BenchWhat::Integrators => {
            let out = args.out.clone().unwrap_or_else(|| "docs/bench".into());
            integrator_report::report(&integ, &out, &mut log)?;
            println!("wrote {}/integrators-*", out.display());
        }
        _ => {
            let out = args.out.clone().unwrap_or_else(|| "docs".into());
            let page = studies::write_docs(&conv, &integ, &out, args.quick, &mut log)?;
            println!("wrote {}", page.display());
        }
    }
    Ok(0)
}

/// `drape bench budget`: the comparison's CSV and SVG into `OUT/bench` and its table into
/// `OUT/accuracy-vs-speed.md` (OUT: `docs`).
fn budget(args: &BenchArgs) -> anyhow::Result<i32> {
    let out = args.out.clone().unwrap_or_else(|| "docs".into());
    let mut log = |line: &str| println!("{line}");
    let table = drape::bench::budget::run(
        std::path::Path::new("."),
        &out.join("bench"),
        args.frames,
        &mut log,
    )?;
    let page = out.join("accuracy-vs-speed.md");
    drape::bench::studies::set_budget_section(&page, &table)?;
    println!(
        "wrote {}/bench/budget.csv, budget.svg and the table in {}",
        out.display(),
        page.display()
    );
    Ok(0)
}

/// `drape bench peers`: drape against Blender's cloth; CSV and SVG into `OUT/bench`, the table
/// into `OUT/accuracy-vs-speed.md` (OUT: `docs`).
fn peers(args: &BenchArgs) -> anyhow::Result<i32> {
    let out = args.out.clone().unwrap_or_else(|| "docs".into());
    let mut log = |line: &str| println!("{line}");
    let options = drape::bench::peers::Options {
        blender: args.blender.clone(),
        frames: args.frames,
        quick: args.quick,
        keep: args.keep,
    };
    drape::bench::peers::run(std::path::Path::new("."), &out, &options, &mut log)?;
    println!(
        "wrote {0}/bench/peers.csv, {0}/bench/peers-mean.svg, peers-worst.svg and the table in {0}/accuracy-vs-speed.md",
        out.display()
    );
    Ok(0)
}

/// `drape bench characters`: every character scene against H with shear springs; the CSV into
/// `OUT/bench/characters.csv` (OUT: `docs`), the table on stdout.
fn characters(args: &BenchArgs) -> anyhow::Result<i32> {
    let out = args.out.clone().unwrap_or_else(|| "docs".into());
    let mut log = |line: &str| println!("{line}");
    let threads = match args.threads.is_empty() {
        true => vec![rayon::current_num_threads().max(1)],
        false => args.threads.clone(),
    };
    let options = drape::bench::characters::Options {
        rounds: args.rounds,
        threads,
        frames: args.frames,
        quick: args.quick,
    };
    let table = drape::bench::characters::run(
        std::path::Path::new("."),
        &out.join("bench"),
        &options,
        &mut log,
    )?;
    println!("\n{table}");
    println!("wrote {}/bench/characters.csv", out.display());
    Ok(0)
}
