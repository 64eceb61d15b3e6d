//! `drape inspect`: validate a scene and print what it would simulate.

use super::args::InspectArgs;
use super::resolve;
use drape::garment::SpringFamily;
use drape::sim::Model;

pub fn run(args: InspectArgs) -> anyhow::Result<i32> {
    if let Some(path) = &args.scene.scene {
        let is_scene = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        if !is_scene {
            super::shell::check_look(&args.look)?;
            let options = super::shell::look_options(&args.look);
            return super::shell::inspect(path, &options, args.look.radius, 60.0);
        }
    }
    let (scene, file) = resolve::scene(&args.scene)?;
    let garments = drape::garment::build_all(&scene, &file)?;
    let vertices = garments
        .iter()
        .map(|g| g.uvs.len().max(g.particle_count()) as u64)
        .sum();
    drape::bake::check_disk(&scene, vertices, &file, std::path::Path::new("."))?;
    let files = drape::bake::output_bytes(&scene, vertices);
    let model = Model::new(&garments);
    println!("scene '{}' ({file}): valid", scene.name);
    println!(
        "  {} frames ({}–{}) at {} fps, {} substeps per frame ({:.3} ms steps), {:?} integrator",
        scene.frames,
        scene.frame_start,
        scene.frame_start + scene.frames - 1,
        scene.fps,
        scene.substeps_per_frame(),
        scene.step_seconds() * 1e3,
        scene.integrator
    );
    let s = &scene.solver;
    println!(
        "  solver {} with {} outer × {} inner iterations, ω = {}, {} collision pass{} per substep",
        s.kind.name(),
        s.iterations,
        s.inner_iterations,
        s.omega,
        s.contact_passes,
        if s.contact_passes == 1 { "" } else { "es" }
    );
    if let Some(t) = drape::bake::budget::Targets::stability(&scene) {
        let (top_s, top_i) = t.levels[t.levels.len() - 1];
        println!(
            "  budget left to drape (no accuracy targets, and the scene leaves out its substeps or iterations): a frame that goes unstable is simulated again at a larger one, up to {top_s} × {top_i}"
        );
    }
    print_garments(&garments);
    for line in level_of_detail(&scene, &garments) {
        println!("  {line}");
    }
    let advice = drape::garment::advice::folding_warnings(&garments, scene.particle_collisions);
    let mut crossed = drape::collide::crossings::modelled_warnings(&garments);
    crossed.extend(drape::collide::crossings::between_warnings(&garments));
    for line in advice.iter().chain(&crossed) {
        println!("  warning: {line}");
    }
    let ranges = &model.colour_ranges;
    match model.domains {
        // Small: two sides swept by two threads apart, then the separator.
        Some(d) => {
            let sizes = |side: &[std::ops::Range<usize>]| {
                let sizes: Vec<String> = side.iter().map(|r| r.len().to_string()).collect();
                sizes.join(", ")
            };
            let separator: usize = d.separator(ranges).iter().map(|r| r.len()).sum();
            println!(
                "  small model: two sides swept apart, then a separator (a sweep: {} colours of both sides, then the separator's)",
                model.sweep_colours().len()
            );
            println!(
                "  low side, particles per colour: {}",
                sizes(d.side(ranges, 0))
            );
            println!(
                "  high side, particles per colour: {}",
                sizes(d.side(ranges, 1))
            );
            println!(
                "  separator: {separator} particles in {} colours",
                d.separator(ranges).len()
            );
        }
        None => {
            for (c, r) in ranges.iter().enumerate() {
                println!("  colour {c}: {} particles", r.len());
            }
        }
    }
    println!("  colliders: {}", scene.colliders.len());
    for (i, c) in scene.characters.iter().enumerate() {
        println!(
            "  character '{}': {}",
            scene.character_name(i),
            scene.character_path(i).display()
        );
        if let Some(p) = c.preroll {
            let lead = scene.preroll_frames();
            println!(
                "    pre-roll: {} frames in the bind pose, {} blending into the clip's first frame (the bake simulates frames {}–{} first{})",
                lead - p.blend,
                p.blend,
                scene.frame_start - lead,
                scene.frame_start - 1,
                if scene.output.preroll { ", and exports them" } else { "" }
            );
        }
        if !c.joint_offsets.is_empty() {
            let turns: Vec<String> = (c.joint_offsets.iter())
                .map(|(joint, [x, y, z])| format!("{joint} ({x}°, {y}°, {z}°)"))
                .collect();
            println!(
                "    joint offsets, in every posed frame but the bind pose (about the file's axes): {}",
                turns.join(", ")
            );
        }
        if let Some(line) = body_crossings(&scene, i)? {
            println!("    {line}");
        }
    }
    for line in dressing(&scene, &garments)? {
        println!("  {line}");
    }
    let collisions = match scene.particle_collisions {
        true => drape::collide::particles::ParticleCollisions::memory_bytes(model.particle_count()),
        false => 0,
    };
    let mib = |bytes: usize| bytes as f64 / (1024.0 * 1024.0);
    println!(
        "  total: {} particles, {} springs, about {:.2} MiB of solver memory{}",
        model.particle_count(),
        model.springs.len(),
        mib(model.memory_bytes() + collisions),
        match collisions {
            0 => String::new(),
            bytes => format!(" ({:.2} MiB of it particle collisions)", mib(bytes)),
        }
    );
    println!(
        "  outputs: about {:.1} MB written over {} frames (garments; characters add theirs)",
        files as f64 / 1e6,
        scene.frames
    );
    Ok(0)
}

/// Each garment's lattice: what a mesh garment voxelizes, its particles, pins, springs and
/// colouring.
fn print_garments(garments: &[drape::garment::Garment]) {
    for g in garments {
        if let Some(m) = &g.source {
            let v = &m.voxels;
            println!(
                "  garment '{}' voxelizes {} ({} triangles, {}) at {} m: {} surface + {} interior cells",
                g.name,
                m.file,
                m.triangles.len(),
                if m.closed { "closed" } else { "open" },
                v.spacing,
                v.surface_cells,
                v.interior_cells
            );
        }
        println!(
            "  garment '{}': {} particles ({} × {} × {}), {} pinned, springs: {} stretch, {} shear, {} bend; {} colours = ({} x + {} y + {} z) mod {}",
            g.name,
            g.particle_count(),
            g.dims[0],
            g.dims[1],
            g.dims[2],
            g.pins.len(),
            g.spring_count(SpringFamily::Stretch),
            g.spring_count(SpringFamily::Shear),
            g.spring_count(SpringFamily::Bend),
            g.colour_count(),
            g.colouring.coefficients[0],
            g.colouring.coefficients[1],
            g.colouring.coefficients[2],
            g.colouring.modulus,
        );
    }
}

/// Per garment modelled `on` a character: its particles' clearance to the body in the bind
/// pose, and how many start inside it (the clean start moves those out before the first
/// substep).
fn dressing(
    scene: &drape::scene::Scene,
    garments: &[drape::garment::Garment],
) -> anyhow::Result<Vec<String>> {
    let mut lines = Vec::new();
    for (g, spec) in garments.iter().zip(&scene.garments) {
        let Some(on) = &spec.on else { continue };
        let Some(k) = (0..scene.characters.len()).find(|&k| scene.character_name(k) == *on) else {
            continue;
        };
        let c = &scene.characters[k];
        let mut options = c.options();
        options.hidden =
            drape::bake::characters::garment_meshes_in(scene, &scene.character_path(k));
        let character =
            drape::character::Character::load(&scene.character_path(k), &options, scene.fps, 1)?;
        let points: Vec<glam::Vec3> = g.positions.clone();
        let reach = c.radius + 0.5 * spec.thickness;
        let found = drape::bake::dress::clearance(
            &character.bind,
            character.triangles_of(0),
            &points,
            reach,
        );
        let body = [(on.clone(), drape::garment::voxel::bounds(&character.bind))];
        let (one_spec, one) = (std::slice::from_ref(spec), std::slice::from_ref(g));
        let odd = drape::garment::advice::on_body_warnings(one_spec, one, &body);
        lines.extend(odd.into_iter().map(|w| format!("warning: {w}")));
        lines.push(format!(
            "garment '{}' on '{on}' in the bind pose: clearance {:.1} mm at the least, {:.1} mm at the 5th percentile; {} of {} particles start inside the body, {} within its shell's reach ({:.1} mm), moved out before the first substep",
            g.name,
            found.min * 1e3,
            found.p5 * 1e3,
            found.inside,
            points.len(),
            found.within,
            reach * 1e3
        ));
    }
    Ok(lines)
}

/// Where character `k`'s mesh passes through itself over the bake's frames, by the joints that
/// move the triangles (None for a frame sequence): the limbs `joint_offsets` would spread.
fn body_crossings(scene: &drape::scene::Scene, k: usize) -> anyhow::Result<Option<String>> {
    let Some((frames, found)) = drape::bake::limbs::body_crossings(scene, k)? else {
        return Ok(None);
    };
    if found.is_empty() {
        return Ok(Some(format!(
            "its mesh passes through itself in none of the {frames} frames (pre-roll included)"
        )));
    }
    let mut crossed: Vec<i64> = (found.iter())
        .flat_map(|c| c.frames.iter().map(|f| f.0))
        .collect();
    crossed.sort_unstable();
    crossed.dedup();
    let listed: Vec<String> = (found.iter().take(4))
        .map(|c| {
            format!(
                "{} into {} in {} frames ({}–{}, up to {} pairs of triangles in one)",
                c.joints.0,
                c.joints.1,
                c.frames.len(),
                c.frames[0].0,
                c.frames[c.frames.len() - 1].0,
                c.most()
            )
        })
        .collect();
    let more = match found.len() {
        n if n > 4 => format!(" and {} more pairs of joints", n - 4),
        _ => String::new(),
    };
    Ok(Some(format!(
        "warning: its mesh passes through itself in {} of the {frames} frames (pre-roll included), by the joints that move its triangles: {}{more}; cloth caught there has no place outside the mesh (characters[].joint_offsets can spread the limbs)",
        crossed.len(),
        listed.join("; ")
    )))
}

/// Level-of-detail advice: each garment's particle spacing (its longest structural rest length)
/// against the characters' shell radii. Shell particles overlap (centres a radius apart), so a
/// garment particle falls between them only when the cloth's own gaps are wider than a shell
/// particle: spacing above 2 × the radius lets cloth slip through the shell between its
/// particles; spacing below a quarter of it resolves folds the shell cannot push on, at 16 × the
/// particles of a spacing twice the radius.
fn level_of_detail(
    scene: &drape::scene::Scene,
    garments: &[drape::garment::Garment],
) -> Vec<String> {
    let mut lines = Vec::new();
    let smallest = scene
        .characters
        .iter()
        .map(|c| c.radius)
        .fold(f32::INFINITY, f32::min);
    for g in garments {
        let structural = g
            .springs
            .iter()
            .filter(|s| s.family == SpringFamily::Stretch)
            .map(|s| s.rest);
        let spacing = structural.fold(0.0f32, f32::max);
        if spacing <= 0.0 {
            continue;
        }
        if !smallest.is_finite() {
            lines.push(format!(
                "garment '{}': particle spacing {spacing:.4} m (no characters to compare with)",
                g.name
            ));
            continue;
        }
        let ratio = spacing / smallest;
        lines.push(format!(
            "garment '{}': particle spacing {spacing:.4} m = {ratio:.2} × the smallest shell radius ({smallest} m)",
            g.name
        ));
        if ratio > 2.0 {
            lines.push(format!(
                "warning: garment '{}' is coarser than twice the shell radius: cloth can slip between shell particles; use at least {} particles per metre, or a larger character radius",
                g.name,
                (1.0 / (2.0 * smallest)).ceil()
            ));
        } else if ratio < 0.25 {
            lines.push(format!(
                "warning: garment '{}' is finer than a quarter of the shell radius: the shell cannot resolve folds that small and the particles cost time; {} particles per metre would do",
                g.name,
                (1.0 / (0.5 * smallest)).ceil()
            ));
        }
    }
    lines
}
