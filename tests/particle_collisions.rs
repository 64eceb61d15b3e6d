//! Particle–particle collisions (CPU): a cloth dropped onto a cloth lying on a plane stays on top
//! of it, where without those collisions it falls through; a cloth folded onto itself keeps its
//! layers apart; the GPU sorts and pushes as the CPU does; neighbour lists kept between substeps
//! move the cloth exactly as a direct search every substep; shear springs keep P's cells from
//! shearing flat and folding through themselves.

mod common;

use drape::sim::Simulation;
use glam::Vec3;

/// A 1 m cloth on the floor and a 0.6 m cloth dropped onto it from 0.25 m.
fn two_cloths(collisions: bool) -> String {
    format!(
        r#"{{ "frames": 60, "substeps": 10, "backend": "cpu", "particle_collisions": {collisions},
              "garments": [
                {{ "name": "bottom", "resolution": [24, 24], "size": [1, 1], "position": [0, 0.02, 0] }},
                {{ "name": "top", "resolution": [16, 16], "size": [0.6, 0.6], "position": [0.05, 0.25, -0.03] }}
              ],
              "colliders": [{{ "kind": "plane" }}] }}"#
    )
}

/// Lowest point of the top cloth minus the highest point of the bottom one.
fn gap_between_cloths(sim: &Simulation) -> f32 {
    let garments = sim.model().garments.clone();
    let p: Vec<Vec3> = sim.export_positions();
    let bottom = p[garments[0].export.clone()]
        .iter()
        .map(|v| v.y)
        .fold(f32::MIN, f32::max);
    let top = p[garments[1].export.clone()]
        .iter()
        .map(|v| v.y)
        .fold(f32::MAX, f32::min);
    top - bottom
}

/// That gap after every frame.
fn clearance(text: &str) -> Vec<f32> {
    let scene = common::scene(text);
    let mut sim = Simulation::new(&scene).unwrap();
    (0..scene.frames)
        .map(|_| {
            sim.step_frame();
            gap_between_cloths(&sim)
        })
        .collect()
}

#[test]
fn a_cloth_dropped_on_a_cloth_stays_on_top() {
    let with = clearance(&two_cloths(true));
    let scene = common::scene(&two_cloths(true));
    let sim = Simulation::new(&scene).unwrap();
    let radius = sim.particle_collisions.as_ref().expect("on").radius;
    // Every frame, every particle of the top cloth is above every particle of the bottom one,
    // and at rest the layers are about one particle diameter apart.
    let worst = with.iter().copied().fold(f32::MAX, f32::min);
    eprintln!(
        "closest approach {worst} m, final gap {} m, radius {radius} m",
        with.last().unwrap()
    );
    assert!(
        worst > 0.5 * radius,
        "closest approach {worst} m (radius {radius} m)"
    );
    // At rest the top cloth's particles sit in the hollows between the bottom cloth's, less than
    // a diameter above them (measured 0.026 m for a 0.04 m diameter) but well clear.
    let last = *with.last().unwrap();
    assert!(
        last > radius && last < 2.2 * radius,
        "final gap {last} m, radius {radius} m"
    );
    // Without particle collisions the top cloth falls into the bottom one.
    let without = clearance(&two_cloths(false));
    assert!(
        *without.last().unwrap() < 0.1 * radius,
        "without collisions: {without:?}"
    );
}

/// The closest two particles of a strip more than two lattice steps apart come, after a strip
/// standing almost upright falls over onto the floor and folds, and the particle radius.
fn closest_non_neighbours(collisions: bool) -> (f32, f32) {
    let text = format!(
        r#"{{ "frames": 90, "substeps": 10, "backend": "cpu", "particle_collisions": {collisions},
              "particle_radius": 0.02,
              "garments": [{{ "name": "strip", "resolution": [40, 8], "size": [2, 0.4],
                              "position": [0, 1.0, 0], "rotation": [0, 0, 80] }}],
              "colliders": [{{ "kind": "plane" }}] }}"#
    );
    let scene = common::scene(&text);
    let mut sim = Simulation::new(&scene).unwrap();
    for _ in 0..scene.frames {
        sim.step_frame();
    }
    let p = sim.export_positions();
    let (nx, ny) = (40usize, 8usize);
    let mut closest = f32::MAX;
    for a in 0..nx * ny {
        for b in a + 1..nx * ny {
            let (ax, ay, bx, by) = (a % nx, a / nx, b % nx, b / nx);
            if ax.abs_diff(bx) <= 2 && ay.abs_diff(by) <= 2 {
                continue;
            }
            closest = closest.min(p[a].distance(p[b]));
        }
    }
    (closest, 0.02)
}

#[test]
fn a_cloth_folding_onto_itself_keeps_its_layers_apart() {
    let (with, radius) = closest_non_neighbours(true);
    let (without, _) = closest_non_neighbours(false);
    eprintln!("closest non-neighbours: {with} m with self-collision, {without} m without");
    // Without self-collision the folded layers pass into each other; with it no two
    // non-neighbours come closer than 80 % of a diameter.
    assert!(
        without < radius,
        "without self-collision the closest pair is {without} m apart"
    );
    assert!(
        with > 1.6 * radius,
        "closest non-neighbours {with} m, radius {radius} m"
    );
}

#[test]
fn the_gpu_sorts_and_pushes_as_the_cpu_does() {
    // The two cloths on both backends (lavapipe here and in CI): the same positions within
    // float tolerance after 30 frames (contact from frame 12), and the top cloth stays on top.
    let Some(ctx) = common::gpu_context() else {
        return;
    };
    let text = two_cloths(true).replace("\"frames\": 60", "\"frames\": 30");
    let scene = common::scene(&text);
    let mut cpu = Simulation::new(&scene).unwrap();
    let mut on_gpu = Simulation::new(&scene).unwrap();
    let mut gpu = drape::gpu::GpuSimulation::new(ctx, &on_gpu).expect("GPU simulation");
    let mut worst = 0.0f32;
    for _ in 0..scene.frames {
        cpu.step_frame();
        gpu.step_frame(on_gpu.frame_parts()).expect("GPU frame");
        worst = worst.max(common::largest_gap(&cpu, &on_gpu));
    }
    let gap = gap_between_cloths(&on_gpu);
    eprintln!(
        "particle collisions: CPU and GPU differ by at most {worst:.2e} m; GPU gap {gap:.4} m"
    );
    assert!(worst < 1e-4, "CPU and GPU positions differ by {worst} m");
    assert!(gap > 0.0, "the top cloth fell through on the GPU");
    // A second run on the GPU gives the same numbers (the buckets are put in order).
    let ctx = common::gpu_context().unwrap();
    let mut again = Simulation::new(&scene).unwrap();
    let mut gpu2 = drape::gpu::GpuSimulation::new(ctx, &again).unwrap();
    for _ in 0..scene.frames {
        gpu2.step_frame(again.frame_parts()).unwrap();
    }
    assert_eq!(again.state.positions, on_gpu.state.positions);
}

/// Scene P as the poncho falls and lands: its self-collisions find their pairs in neighbour
/// lists kept between substeps (reused in many substeps), and the poncho moves exactly as when
/// every substep finds them in a grid directly.
#[test]
fn pairs_found_through_lists_or_directly_move_the_cloth_alike() {
    let dir = common::temp_dir();
    let scene = common::scene_p(dir.path(), 40);
    assert!(scene.particle_collisions, "P ships with self-collisions");
    let (mut lists, mut direct) = common::two_simulations(&scene, dir.path());
    direct.set_particle_lists(false);
    common::step_alike(
        (&mut lists, &mut direct),
        scene.frames,
        "the lists",
        |_, _| {},
    );
    assert_eq!(direct.particle_lists_reused(), 0);
    let substeps = 20 * scene.frames as u64;
    let reused = lists.particle_lists_reused();
    assert!(
        reused * 10 > substeps,
        "lists reused in {reused} of {substeps} substeps"
    );
    eprintln!("lists reused in {reused} of {substeps} substeps");
}

/// The poncho's triangles that pass through each other after each of `frames` frames.
fn crossings_per_frame(scene: &drape::scene::Scene, dir: &std::path::Path) -> Vec<usize> {
    let mut sim = common::simulation(scene, dir);
    (0..scene.frames)
        .map(|_| {
            sim.step_frame();
            let poncho = &sim.model().garments[0];
            let p = sim.export_positions()[poncho.export.clone()].to_vec();
            drape::collide::crossings::count(&p, &poncho.triangles)
        })
        .collect()
}

/// Self-collisions skip a particle's lattice neighbours, diagonal ones included: without shear
/// springs P's cells shear flat where the poncho lands and their triangles fold through their
/// neighbours' (frames 28–40), which no collision between particles sees; with the shear springs
/// P ships with, no triangle of the poncho passes through another in any frame.
#[test]
fn cells_held_square_keep_a_landing_poncho_from_folding_through_itself() {
    let dir = common::temp_dir();
    let scene = common::scene_p(dir.path(), 40);
    assert!(
        scene.garments[0].stiffness.shear > 0.0,
        "P ships with shear springs"
    );
    let held = crossings_per_frame(&scene, dir.path());
    let mut unheld_scene = scene.clone();
    unheld_scene.garments[0].stiffness.shear = 0.0;
    let unheld = crossings_per_frame(&unheld_scene, dir.path());
    eprintln!("crossings per frame with shear springs {held:?}, without {unheld:?}");
    assert!(held.iter().all(|&c| c == 0), "with shear springs: {held:?}");
    assert!(
        unheld.iter().sum::<usize>() > 50,
        "without shear springs the landing poncho folds through itself: {unheld:?}"
    );
}
