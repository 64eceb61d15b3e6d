//! Contract: the GPU kernels compute what the CPU solvers compute. Red-black Gauss-Seidel on the
//! GPU (lavapipe here and in CI) gives the CPU's residual after every iteration within 1e-4
//! relative and the CPU's positions after a frame within 1e-5 m, on scenes E and H; Jacobi, PBD
//! and the sphere collider too. Without any adapter the tests print "skipped"; a wgpu validation
//! error fails them.

mod common;

use drape::gpu::{GpuContext, GpuSimulation};
use drape::scene::{reference, Scene, SolverKind};
use drape::sim::Simulation;

fn context() -> Option<GpuContext> {
    common::gpu_context()
}

/// Runs `frames` frames on both backends; returns (cpu, gpu) simulations.
fn both(scene: &Scene, frames: u32) -> Option<(Simulation, Simulation)> {
    let ctx = context()?;
    let mut cpu = Simulation::new(scene).unwrap();
    let mut gpu_sim = Simulation::new(scene).unwrap();
    let mut gpu = GpuSimulation::new(ctx, &gpu_sim).expect("GPU simulation");
    for _ in 0..frames {
        cpu.step_frame();
        gpu.step_frame(gpu_sim.frame_parts()).expect("GPU frame");
    }
    Some((cpu, gpu_sim))
}

fn max_distance(a: &Simulation, b: &Simulation) -> f32 {
    common::largest_gap(a, b)
}

/// Particles of `sim` within 1 cm of collider `c`'s surface.
fn touching(sim: &Simulation, c: &drape::collide::Collider) -> usize {
    sim.state
        .positions
        .iter()
        .filter(|q| c.distance(q.truncate()).0 < 0.01)
        .count()
}

/// Largest relative difference between two residual histories.
fn largest_gap(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / x)
        .fold(0.0, f64::max)
}

#[test]
fn red_black_residuals_match_on_scene_e() {
    let mut scene = reference::load(reference::ENLARGED_CLOTH, "enlarged_cloth.json");
    scene.solver.iterations = 50;
    let Some((cpu, gpu)) = both(&scene, 1) else {
        return;
    };
    let (rc, rg) = (cpu.residuals.unwrap(), gpu.residuals.unwrap());
    assert_eq!((rc.len(), rg.len()), (50, 50));
    let gap = largest_gap(&rc, &rg);
    eprintln!("scene E: largest residual gap {gap:.2e} relative");
    assert!(gap <= 1e-4, "residuals differ by {gap:.2e} relative");
}

#[test]
fn red_black_residuals_and_positions_match_on_scene_h() {
    // Frame 5: in frame 1 the springs' error is ~10 ulps of their length, so its residuals are
    // rounding noise (measured gaps up to 2e-2 relative); by frame 5 the cloth has stretched and
    // the comparison means something. Later the hanging cloth's folding amplifies the GPU's
    // different rounding (fused multiply-adds): 2e-5 m by frame 10, centimetres by frame 20, so
    // parity is a statement about the first frames, the physics metrics about the rest.
    let mut scene = reference::load(reference::HANGING_CLOTH, "hanging_cloth.json");
    scene.output.residuals = true;
    let Some((cpu, gpu)) = both(&scene, 5) else {
        return;
    };
    let d = max_distance(&cpu, &gpu);
    let (rc, rg) = (cpu.residuals.unwrap(), gpu.residuals.unwrap());
    assert_eq!(
        (rc.len(), rg.len()),
        (100, 100),
        "one residual per substep of frame 5"
    );
    let gap = largest_gap(&rc, &rg);
    eprintln!("scene H frame 5: largest residual gap {gap:.2e} relative, positions {d:.2e} m");
    assert!(gap <= 1e-4, "residuals differ by {gap:.2e} relative");
    assert!(d <= 1e-5, "positions differ by {d} m after 5 frames");
}

#[test]
fn jacobi_pbd_and_the_sphere_match() {
    for kind in [SolverKind::Jacobi, SolverKind::Pbd, SolverKind::Rbgs] {
        let mut scene = reference::load(reference::SPHERE_DRAPE, "sphere_drape.json");
        scene.solver.kind = kind;
        // 20 frames: the cloth has reached the sphere (from frame 13) and friction acts. Later,
        // stick/slip switches amplify roundoff (measured: 0 m after 10 frames, 3e-7 m after 20,
        // 1e-4 to 8e-4 m after 40), so parity is checked where it is meaningful.
        let Some((cpu, gpu)) = both(&scene, 20) else {
            return;
        };
        let d = max_distance(&cpu, &gpu);
        assert!(
            d <= 1e-5,
            "{kind:?}: positions differ by {d} m after 20 frames"
        );
        assert!(
            touching(&gpu, &gpu.drivers.colliders[0]) > 0,
            "the cloth should touch the sphere by frame 20"
        );
    }
}

#[test]
fn boxes_and_capsules_match() {
    // A cloth falling across a box and a capsule, both backends, 20 frames (contact from frame 9).
    let scene = Scene::parse(
        r#"{ "frames": 20, "substeps": 10,
             "garments": [{ "resolution": [32, 32], "size": [1.2, 1.2], "position": [0, 0.8, 0] }],
             "colliders": [
               { "kind": "box", "centre": [-0.25, 0.4, 0], "size": [0.3, 0.4, 0.8] },
               { "kind": "capsule", "start": [0.2, 0.45, -0.4], "end": [0.3, 0.45, 0.4], "radius": 0.08 }
             ] }"#,
        "test",
    )
    .expect("scene");
    let Some((cpu, gpu)) = both(&scene, 20) else {
        return;
    };
    let d = max_distance(&cpu, &gpu);
    eprintln!("box and capsule: positions differ by {d:.2e} m after 20 frames");
    assert!(d <= 1e-5, "positions differ by {d} m after 20 frames");
    for (c, name) in gpu.drivers.colliders.iter().zip(["box", "capsule"]) {
        assert!(
            touching(&gpu, c) > 0,
            "the cloth should touch the {name} by frame 20"
        );
    }
}

#[test]
fn the_swept_test_holds_cloth_on_a_thin_plate_on_the_gpu_too() {
    // One step per frame: the cloth moves farther per step than the plate is thick.
    let scene = Scene::parse(
        r#"{ "frames": 40, "substeps": 1,
             "garments": [{ "resolution": [12, 12], "size": [0.6, 0.6], "position": [0, 1.6, 0] }],
             "colliders": [{ "kind": "box", "centre": [0, 0.5, 0], "size": [1.5, 0.01, 1.5] }] }"#,
        "test",
    )
    .expect("scene");
    let Some((cpu, gpu)) = both(&scene, 40) else {
        return;
    };
    let lowest = gpu
        .state
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::MAX, f32::min);
    assert!(
        lowest > 0.5,
        "GPU: lowest particle at {lowest} m, under the plate"
    );
    let d = max_distance(&cpu, &gpu);
    assert!(d <= 1e-4, "positions differ by {d} m after 40 frames");
}

#[test]
fn a_voxelized_solid_with_six_colours_matches() {
    // The cushion of garments/ filled with particles, shear springs on (6 colours), landing on
    // a box: both backends, 20 frames (contact from frame 12).
    let text = r#"{ "frames": 20,
        "garments": [{ "kind": "mesh", "mesh": "cushion.obj", "spacing": 0.03, "mass": 0.4,
                       "position": [0, 0.75, 0], "rotation": [0, 0, 20],
                       "stiffness": { "stretch": 2000, "shear": 1000 } }],
        "colliders": [{ "kind": "box", "centre": [0, 0.3, 0], "size": [0.5, 0.6, 0.5] }] }"#;
    let garments = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("garments");
    let scene = Scene::parse_in(text, "test", &garments).expect("scene");
    let Some((cpu, gpu)) = both(&scene, 20) else {
        return;
    };
    assert_eq!(cpu.model().colour_ranges.len(), 6);
    let d = max_distance(&cpu, &gpu);
    eprintln!("voxelized cushion: positions differ by {d:.2e} m after 20 frames");
    assert!(d <= 1e-5, "positions differ by {d} m after 20 frames");
    assert!(
        touching(&gpu, &gpu.drivers.colliders[0]) > 0,
        "the cushion should reach the box"
    );
}

#[test]
fn funnels_and_wedges_match() {
    // Cloth falling onto a wedge's blade and into a funnel, both backends, 24 frames: contact
    // from frame 16. (Measured: the gap is 1e-6 m at frame 20 and grows to 1e-4 m by frame 30
    // as the cloth crumples over the blade and the spout's rim, sharp features where the
    // rounding of GPU square roots decides which side a particle falls.)
    let scene = Scene::parse(
        r#"{ "frames": 24, "substeps": 10,
             "garments": [
               { "resolution": [24, 24], "size": [0.8, 0.8], "position": [-0.6, 1.2, 0] },
               { "resolution": [24, 24], "size": [0.8, 0.8], "position": [0.6, 1.2, 0] }
             ],
             "colliders": [
               { "kind": "wedge", "centre": [-0.6, 0.7, 0], "size": [0.3, 0.4, 1.0] },
               { "kind": "funnel", "centre": [0.6, 0.4, 0], "radius": 0.08, "top_radius": 0.35,
                 "height": 0.4, "thickness": 0.02 }
             ] }"#,
        "test",
    )
    .expect("scene");
    let Some((cpu, gpu)) = both(&scene, 24) else {
        return;
    };
    let d = max_distance(&cpu, &gpu);
    eprintln!("wedge and funnel: positions differ by {d:.2e} m after 24 frames");
    assert!(d <= 1e-5, "positions differ by {d} m after 24 frames");
    for (c, name) in gpu.drivers.colliders.iter().zip(["wedge", "funnel"]) {
        assert!(
            touching(&gpu, c) > 0,
            "the cloth should touch the {name} by frame 24"
        );
    }
}

#[test]
fn moving_and_turned_colliders_match() {
    // A cloth pinned at two corners hit by a sphere thrown at 10 m/s (the swept test relative
    // to the sphere), and a cloth falling onto a turned box that spins: both backends, each
    // collider posed per substep, 24 frames. Until the sphere hits (frame 9) every
    // particle matches; after, the struck cloth flaps over its pins, a chaotic motion in which
    // rounding differences grow tenfold every 3 frames (4 cm by frame 24, measured), so from
    // then on the cloth's centroid is compared (0.3 mm apart at frame 24, measured). The GPU
    // poses the colliders from their keyframes itself (0.02 mm apart on the turning box).
    let scene = Scene::parse(
        r#"{ "frames": 24, "substeps": 10,
             "garments": [
               { "resolution": [20, 20], "size": [0.8, 0.8], "position": [-0.6, 1.0, 0],
                 "rotation": [90, 0, 0], "pins": [[0, 0], [-1, 0]] },
               { "resolution": [20, 20], "size": [0.6, 0.6], "position": [0.7, 1.0, 0] }
             ],
             "colliders": [
               { "kind": "sphere", "centre": [-0.6, 0.9, -1.0], "radius": 0.12,
                 "keyframes": [{ "time": 0.05 }, { "time": 0.25, "translation": [0, 0, 2] }] },
               { "kind": "box", "centre": [0.7, 0.6, 0], "size": [0.3, 0.2, 0.5], "rotation": [0, 0, 20],
                 "keyframes": [{ "time": 0 }, { "time": 0.4, "rotation": [0, 90, 0] }] }
             ] }"#,
        "test",
    )
    .expect("scene");
    let Some(ctx) = context() else {
        return;
    };
    let mut cpu = Simulation::new(&scene).unwrap();
    let mut on_gpu = Simulation::new(&scene).unwrap();
    let mut gpu = GpuSimulation::new(ctx, &on_gpu).expect("GPU simulation");
    let centroid = |s: &Simulation, g: usize| {
        let range = s.model().garments[g].export.clone();
        let p = s.export_positions();
        p[range.clone()].iter().sum::<glam::Vec3>() / range.len() as f32
    };
    let (mut before, mut centroid_gap) = (0.0f32, 0.0f32);
    for frame in 1..=scene.frames {
        cpu.step_frame();
        gpu.step_frame(on_gpu.frame_parts()).expect("GPU frame");
        if frame <= 8 {
            before = before.max(max_distance(&cpu, &on_gpu));
        }
        centroid_gap = centroid_gap.max(centroid(&cpu, 0).distance(centroid(&on_gpu, 0)));
    }
    let on_box = cpu.model().garments[1].export.clone();
    let box_cloth = cpu.export_positions()[on_box.clone()]
        .iter()
        .zip(&on_gpu.export_positions()[on_box])
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f32::max);
    eprintln!(
        "moving colliders: {before:.2e} m apart before the hit; struck cloth's centroid within \
         {centroid_gap:.2e} m; cloth on the turning box within {box_cloth:.2e} m"
    );
    assert!(
        before <= 1e-5,
        "positions differ by {before} m before the hit"
    );
    assert!(centroid_gap <= 2e-3, "centroids differ by {centroid_gap} m");
    assert!(
        box_cloth <= 1e-4,
        "the cloth on the turning box differs by {box_cloth} m"
    );
    // Both backends put the colliders in the same final pose, and the cloth met both.
    for (a, b) in cpu.drivers.colliders.iter().zip(&on_gpu.drivers.colliders) {
        assert_eq!(a.shape, b.shape);
        assert_eq!(a.moved, b.moved);
    }
    // The GPU poses the colliders itself (a frame uploads where it starts, 48 bytes) and
    // measures their speed as the CPU does.
    assert_eq!(gpu.uploaded_last_frame(), 48, "bytes uploaded per frame");
    let (a, b) = (cpu.driven_energy(), on_gpu.driven_energy());
    assert!(
        (a - b).abs() <= 1e-4 * a,
        "driven energy {b} J on the GPU, {a} J on the CPU"
    );
    assert!(
        centroid(&on_gpu, 0).z > 0.05,
        "the sphere should have pushed the cloth along +Z"
    );
    assert!(
        touching(&on_gpu, &on_gpu.drivers.colliders[1]) > 0,
        "the cloth should rest on the box"
    );
}

/// `stages_ms` on the GPU backend: where the device has timestamps inside passes (lavapipe has
/// them, though a software adapter times its stages only when asked), every stage a frame runs
/// gets GPU time, and the stages it does not run get none.
#[test]
fn gpu_stages_are_timed_where_the_device_has_timestamps() {
    let Some(ctx) = context() else {
        eprintln!("skipped: no GPU adapter");
        return;
    };
    let timestamps = ctx.timestamps();
    let scene = common::scene(
        r#"{ "frames": 2, "substeps": 4, "garments": [{ "resolution": [12, 12], "pins": [[0, 0]] }] }"#,
    );
    let mut sim = Simulation::new(&scene).unwrap();
    let mut gpu = GpuSimulation::new(ctx, &sim).expect("GPU simulation");
    assert_eq!(gpu.time_stages(&sim, true), timestamps);
    gpu.step_frame(sim.frame_parts()).expect("a frame");
    let t = &sim.stage_times.seconds;
    let of = |name| t[drape::sim::schedule::timed(name)];
    eprintln!(
        "timestamps {timestamps}: {:?}",
        drape::sim::schedule::TIMED
            .iter()
            .zip(t)
            .collect::<Vec<_>>()
    );
    if timestamps {
        for name in ["predict", "solve", "finish"] {
            assert!(of(name) > 0.0, "{name} untimed: {t:?}");
        }
    }
    for name in ["contact_pass", "particle_collisions"] {
        assert_eq!(of(name), 0.0, "{name} does not run here");
    }
}

#[test]
fn the_gpu_records_a_frame_as_one_submission_whatever_its_substeps() {
    // The report's launch counts: one command buffer per frame, and dispatches that grow by
    // the same number with every substep (no round trip to the CPU inside a frame).
    if common::gpu_context().is_none() {
        return;
    }
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(
        d,
        "scene.json",
        r#"{ "name": "s", "frames": 5, "backend": "gpu", "output": { "gltf": "none", "obj": false },
             "garments": [{ "resolution": [12, 8], "pins": [[0, 0], [-1, 0]] }],
             "colliders": [{ "kind": "sphere", "centre": [0, 0.5, 0], "radius": 0.3 }] }"#,
    );
    let launches = |substeps: u32| {
        let out = format!("out{substeps}");
        let run = common::drape(
            d,
            &[
                "bake",
                "scene.json",
                "--substeps",
                &substeps.to_string(),
                "--out",
                &out,
            ],
        );
        assert!(run.status.success(), "{}", common::stderr(&run));
        let r: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(d.join(out).join("report.json")).unwrap(),
        )
        .unwrap();
        (
            r["gpu_dispatches_per_frame"].as_f64().unwrap(),
            r["gpu_submissions_per_frame"].as_f64().unwrap(),
        )
    };
    let [(d10, s10), (d20, s20), (d30, s30)] = [10, 20, 30].map(launches);
    assert_eq!([s10, s20, s30], [1.0; 3]);
    let per_substep = (d20 - d10) / 10.0;
    assert!(per_substep >= 1.0, "{d10} {d20}");
    assert_eq!(
        d30 - d20,
        d20 - d10,
        "dispatches per substep change: {d10} {d20} {d30}"
    );
    eprintln!(
        "{per_substep} dispatches per substep, {} per frame besides",
        d10 - 10.0 * per_substep
    );
}
