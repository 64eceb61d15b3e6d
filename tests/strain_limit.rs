//! `solver.strain_limit`: a particle dragged far from its neighbours comes back to within the
//! limit in the same substep (every spring with a free end, the moved particle's velocity with
//! it), a scene that never reaches the limit bakes the same frames as without one, and the GPU
//! backend limits as the CPU does; bad values are refused.

mod common;

const DRAG: f32 = 0.05;

/// A 12 × 12 sheet of 2 cm cells hanging from its top edge, with `solver` settings.
fn hanging(solver: &str) -> String {
    format!(
        r#"{{ "name": "hanging", "frames": 20, "substeps": 10, "solver": {{ {solver} }},
            "garments": [{{ "name": "sheet", "resolution": [12, 12], "size": [0.22, 0.22],
                            "mass": 0.05, "position": [0, 1, 0], "rotation": [90, 0, 0],
                            "pins": [[0, -1], [3, -1], [6, -1], [9, -1], [11, -1]] }}] }}"#
    )
}

/// The sheet after a frame, one of its free particles (the lowest) then dragged `DRAG` down
/// and one more substep simulated: the worst stretch of its springs after that substep, and
/// the particle's velocity then [m/s].
fn dragged(solver: &str) -> (f64, f32) {
    let dir = common::temp_dir();
    let scene = common::scene(&hanging(solver));
    let mut sim = common::simulation(&scene, dir.path());
    sim.step_frame();
    let model = sim.model();
    let lowest = (0..model.particle_count())
        .filter(|&i| model.inv_mass[i] > 0.0)
        .min_by(|&a, &b| {
            sim.state.positions[a]
                .y
                .total_cmp(&sim.state.positions[b].y)
        })
        .unwrap();
    sim.state.positions[lowest].y -= DRAG;
    sim.substep();
    (stretch(&sim), sim.state.velocities[lowest].y)
}

/// The largest stretch (l − L) / L of a structural spring with a free end (compression, which
/// the limit leaves to the solver, apart).
fn stretch(sim: &drape::sim::Simulation) -> f64 {
    let model = sim.model();
    let x = &sim.state.positions;
    let free = |i: u32| model.inv_mass[i as usize] > 0.0;
    (model.springs[..model.structural_springs].iter())
        .filter(|s| free(s.a) || free(s.b))
        .map(|s| ((x[s.a as usize] - x[s.b as usize]).length() / s.rest - 1.0) as f64)
        .fold(f64::MIN, f64::max)
}

#[test]
fn a_dragged_particle_is_pulled_back_to_the_limit_in_the_same_substep() {
    // Without a limit the springs stay far past both limits after the substep (the premise).
    let (free, _) = dragged(r#""iterations": 2"#);
    assert!(free > 0.3, "without a limit: {free}");
    for limit in [0.05f64, 0.15] {
        let (strain, velocity) = dragged(&format!(r#""iterations": 2, "strain_limit": {limit}"#));
        assert!(
            strain <= limit * 1.01 && strain > 0.5 * limit,
            "limit {limit}: worst stretch {strain}"
        );
        // Pulled back up by most of the 5 cm within the substep (1/600 s): its velocity
        // carries that motion, upward, at more than half of 5 cm per substep (30 m/s).
        eprintln!("limit {limit}: worst strain {strain}, velocity {velocity} m/s");
        assert!(velocity > 15.0, "limit {limit}: velocity {velocity}");
    }
}

#[test]
fn a_limit_never_reached_bakes_the_same_frames() {
    let hash = |solver: &str| {
        let dir = common::temp_dir();
        common::write(dir.path(), "scene.json", &hanging(solver));
        let report = common::bake_report(dir.path());
        let limited = report["strain_limited_per_frame"].as_array().unwrap().len();
        (report["frames_hash"].as_str().unwrap().to_string(), limited)
    };
    let (plain, _) = hash(r#""iterations": 10"#);
    let (loose, limited) = hash(r#""iterations": 10, "strain_limit": 0.5"#);
    assert_eq!(limited, 0);
    assert_eq!(plain, loose);
    // A limit below the strain the sheet hangs at changes them, and says where.
    let (tight, limited) = hash(r#""iterations": 2, "strain_limit": 0.001"#);
    let (loose_two, _) = hash(r#""iterations": 2"#);
    assert!(limited > 0);
    assert_ne!(tight, loose_two);
}

#[test]
fn the_gpu_limits_strain_as_the_cpu_does() {
    let Some(ctx) = common::gpu_context() else {
        return;
    };
    // 0.5 %: the sheet's own weight at two iterations stretches it past that every substep.
    let scene = common::scene(&hanging(r#""iterations": 2, "strain_limit": 0.005"#));
    let dir = common::temp_dir();
    let mut cpu = common::simulation(&scene, dir.path());
    let mut on_gpu = common::simulation(&scene, dir.path());
    let mut gpu = drape::gpu::GpuSimulation::new(ctx, &on_gpu).expect("GPU simulation");
    for frame in 0..10 {
        cpu.step_frame();
        gpu.step_frame(on_gpu.frame_parts()).expect("GPU frame");
        let (a, b) = (cpu.strain_limited, on_gpu.strain_limited);
        assert!(
            a > 0 || frame < 2,
            "frame {frame}: the limit acts on the CPU"
        );
        assert!(
            a.abs_diff(b) * 20 <= a,
            "frame {frame}: {a} springs on the CPU, {b} on the GPU"
        );
    }
    let gap = common::largest_gap(&cpu, &on_gpu);
    assert!(gap < 1e-4, "positions {gap} m apart");
    let (a, b) = (stretch(&cpu), stretch(&on_gpu));
    assert!(
        (a - b).abs() < 1e-4,
        "worst stretch {a} on the CPU, {b} on the GPU"
    );
}

#[test]
fn bad_limits_are_refused() {
    let dir = common::temp_dir();
    for bad in ["0", "1.5", "-0.1"] {
        common::write(
            dir.path(),
            "scene.json",
            &hanging(&format!(r#""strain_limit": {bad}"#)),
        );
        let out = common::drape(dir.path(), &["bake", "scene.json"]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let text = common::stderr(&out);
        assert!(text.contains("solver.strain_limit"), "{bad}: {text}");
    }
    // A tear strain the limit keeps every structural spring from reaching is refused.
    let torn = hanging(r#""strain_limit": 0.2"#)
        .replace(r#""mass": 0.05,"#, r#""mass": 0.05, "tear_strain": 0.3,"#);
    common::write(dir.path(), "scene.json", &torn);
    let out = common::drape(dir.path(), &["bake", "scene.json"]);
    assert_eq!(out.status.code(), Some(2));
    let text = common::stderr(&out);
    assert!(
        text.contains("garments[0].tear_strain") && text.contains("strain_limit"),
        "{text}"
    );
}
