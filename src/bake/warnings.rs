//! The warnings a bake adds to its report at the end, each from the report's own per-frame
//! lists: what the bake could not fix and the user can (held particles inside a body, a body
//! passing through itself or sinking into a collider where cloth is caught, springs the strain
//! limit pulled back or a held end forced).

use crate::report::{BudgetKind, Report};

/// Every warning the finished `report` calls for, in the order a user reads them: held
/// particles inside a body, a body through itself, forced springs, a body sunk into a collider,
/// the strain limit's work (with one, `strain_limit`), garments stretched into place by the
/// pre-roll, frames a budget left to drape simulated again to keep stable, and, for a bake a
/// stretched spring stopped, its substep.
pub(super) fn at_the_end(report: &Report, strain_limit: Option<f32>) -> Vec<String> {
    let mut found = held_inside_warnings(report);
    found.extend(self_crossing_warnings(report));
    found.extend(forced_strain_warning(report));
    found.extend(sunk_warnings(report));
    found.extend(strain_limit.and_then(|limit| strain_limited_warning(report, limit)));
    found.extend(stretched_in_preroll_warning(report));
    found.extend(stability_budget_warning(report));
    found.extend(substep_warning(report));
    found
}

/// Advice when a bake without accuracy targets stopped on a spring stretched past 100 %: the
/// substep is the likeliest lever. Cloth that lands on a body, or that a body pulls, moves
/// farther in one substep than the solver's iterations carry the springs' pull across the
/// garment, and the strain this leaves grows faster than the substep: `poncho_walk`'s worst
/// strain is 28 % with its 0.83 ms substeps (20 a frame at 60 fps), 49 % at 1.04 ms, 90 % at
/// 1.25 ms, and it stops at 2.08 ms (20 a frame at 24 fps, or 8 at 60). The substeps are per
/// frame, so a scene made at 60 fps and baked at 24 has substeps 2.5 times as long.
fn substep_warning(report: &Report) -> Option<String> {
    let failure = report.failure.as_ref()?;
    if !failure.reason.contains("stretched") {
        return None;
    }
    match &report.budget {
        Some(b) if b.kind == BudgetKind::Targets => return None,
        Some(b) => {
            // Stability alone: drape climbed the ladder for the frame, to its cap.
            let (substeps, iterations) = *b.levels.last()?;
            return Some(format!(
                "frame {} stopped the bake with a spring stretched past 100 % at the largest budget drape tries for a scene that leaves it the budget ({substeps} substeps × {iterations} iterations a frame): what holds that spring is likelier the scene than the budget (cloth caught between body parts, a clip that throws it); the warnings above may name it",
                failure.frame
            ));
        }
        None => {}
    }
    Some(format!(
        "frame {} stopped the bake with a spring stretched past 100 %, at substeps of {:.2} ms ({} a frame at {} fps) with {} solver iterations each: cloth landing on a body or pulled by it moves farther in a substep than that many iterations carry the springs' pull across the garment (`poncho_walk` reaches 28 % with 0.83 ms substeps and stops with 2.08 ms ones). Unless a warning above names another cause, raise `substeps` (they are per frame: a scene made at 60 fps needs 60 / fps times as many at a lower frame rate) or `solver.iterations`, or give an accuracy target (`--max-strain 0.5`) and drape raises them in the frames that need it",
        failure.frame,
        report.step_seconds * 1e3,
        report.substeps,
        report.fps,
        report.solver.iterations,
    ))
}

/// Where a budget left to drape went above the scene's own to keep the bake stable
/// (`bake::budget`'s stability alone): the first frame that went unstable at it, how many frames
/// ran at a larger budget and the largest. The bake is whole, but its cost and its frames are
/// not what the scene's budget gives, and a user who wants either fixed gives the budget.
fn stability_budget_warning(report: &Report) -> Option<String> {
    let budget = (report.budget.as_ref()).filter(|b| b.kind == BudgetKind::Stability)?;
    let own = *budget.levels.first()?;
    let raised: Vec<_> = (budget.per_frame.iter())
        .filter(|f| (f.substeps, f.iterations) != own)
        .collect();
    let first = budget.per_frame.iter().find(|f| f.attempts > 1)?;
    let most = (raised.iter())
        .map(|f| (f.substeps, f.iterations))
        .max_by_key(|&(s, i)| s * i)?;
    Some(format!(
        "frame {} went unstable at the scene's budget ({} substeps × {} iterations a frame, drape's defaults for what the scene leaves out) and was simulated again at a larger one; {} of the {} frames ran above it, up to {} × {} (budget.per_frame). Give `timestep` (or `substeps`) and `solver.iterations` for a budget that stays fixed (a bake then stops where it goes unstable), or an accuracy target",
        first.frame,
        own.0,
        own.1,
        raised.len(),
        budget.per_frame.len(),
        most.0,
        most.1,
    ))
}

/// The pre-roll's strain above which a bake warns that its garments are stretched into place
/// ([`stretched_in_preroll_warning`]): half the stability rule's 100 %. The shipped dressed
/// scenes reach 3–25 % (`top_walk` the most); `top_walk` with CesiumMan at half scale and the
/// shipped spacing and shell radius reaches 74 %, and stops at 103 % in frame 1080.
pub const PREROLL_STRETCH_WARNING: f64 = 0.5;

/// A warning when the pre-roll stretched the garments more than [`PREROLL_STRETCH_WARNING`]:
/// cloth is kept a shell radius plus its own contact radius off the skin, and a garment
/// modelled closer than that to a thin part of the body (a sleeve round an arm) gets there only
/// by stretching. On a small character that is the lattice and the shell being coarse for the
/// body (they are in metres and do not follow the character's `scale`).
fn stretched_in_preroll_warning(report: &Report) -> Option<String> {
    let preroll = report.preroll.as_ref()?;
    if preroll.max_strain <= PREROLL_STRETCH_WARNING {
        return None;
    }
    let moved = report.clean_start.as_ref().map_or(0, |c| c.moved);
    let bodies: Vec<String> = (report.characters.iter())
        .map(|c| {
            format!(
                "{}: {:.2} m tall, shell radius {:.1} mm",
                c.name,
                c.height_m,
                c.shell_radius * 1e3
            )
        })
        .collect();
    Some(format!(
        "the pre-roll stretched the garments up to {:.0} % before frame {} (a bake stops at 100 %), and the clean start moved {moved} of their {} particles out of the bodies ({}): cloth is kept a shell radius plus its own contact radius off the skin, and a garment modelled closer than that to a thin part of the body (a sleeve round an arm) gets there only by stretching; `spacing` and the characters' `radius` are in metres and do not follow a character's `scale`, so on a small character scale them with the body (or model the garment looser)",
        preroll.max_strain * 100.0,
        report.frame_start + preroll.frames,
        report.particles,
        bodies.join("; ")
    ))
}

/// A warning when the strain limit pulled springs back: something dragged or squeezed the
/// cloth farther than it stretches, and the cloth gave way to it there.
fn strain_limited_warning(report: &Report, limit: f32) -> Option<String> {
    let frames = &report.strain_limited_per_frame;
    let most = frames.iter().max_by_key(|f| f.springs)?;
    Some(format!(
        "the strain limit ({} %) pulled springs back in {} frames from frame {} (the most {} in frame {}): something drags or squeezes the cloth farther than it stretches (a body part where there is no room for it), and the cloth gives way to it there; mesh_penetrations_per_frame shows where it passes into a character",
        limit * 100.0,
        frames.len(),
        frames[0].frame,
        most.springs,
        most.frame
    ))
}

/// A warning when springs from pinned or attached particles were stretched past 100 %
/// (`forced_strain_per_frame`): what holds their ends, not the solver, stretched them, and
/// those frames did not stop the bake.
fn forced_strain_warning(report: &Report) -> Option<String> {
    let frames = &report.forced_strain_per_frame;
    let most = frames.iter().max_by(|a, b| a.strain.total_cmp(&b.strain))?;
    Some(format!(
        "springs from pinned or attached particles were stretched past 100 % in {} frames from frame {} (the most {:.0} %, in frame {}): their held ends stay where the pins or the animation put them while something holds the free ends next to them away (a body part passing through the attached edge), so no solver can keep those springs short; every spring between free particles stayed within 100 % there, so those frames did not stop the bake; attach the garment elsewhere or keep the body out of the held edge",
        frames.len(),
        frames[0].frame,
        most.strain * 100.0,
        most.frame
    ))
}

/// A warning per character whose mesh had held garment particles inside it: they follow their
/// targets, so the bake cannot move them out; the user can.
fn held_inside_warnings(report: &Report) -> Vec<String> {
    let per_frame = &report.held_mesh_penetrations_per_frame;
    let worst = report.worst_held_mesh_penetrations.iter().enumerate();
    worst
        .filter(|(_, m)| m.penetration.inside > 0)
        .map(|(c, m)| {
            let frames: Vec<u32> = per_frame
                .iter()
                .filter(|f| f.inside.get(c).is_some_and(|&n| n > 0))
                .map(|f| f.frame)
                .collect();
            format!(
                "character {}: up to {} pinned or attached garment particles inside its mesh, {:.1} mm deep at the most, in {} frames from frame {}: they follow their targets, which no budget moves; attach them farther from the skin or move the garment out",
                m.character,
                m.penetration.inside,
                m.penetration.deepest * 1e3,
                frames.len(),
                frames.first().copied().unwrap_or_default()
            )
        })
        .collect()
}

/// A warning per character whose mesh passed through itself in frames that had garment
/// particles deeper than half its shell radius inside it (issue 30's bar): cloth caught where
/// one part of the body sinks into another has no place outside the mesh, so those
/// penetrations are the animation's to fix.
fn self_crossing_warnings(report: &Report) -> Vec<String> {
    let names = report.worst_mesh_penetrations.iter().map(|m| &m.character);
    (names.enumerate())
        .filter_map(|(c, name)| {
            let crossed: Vec<(u32, usize)> = (report.character_crossings_per_frame.iter())
                .filter_map(|f| f.crossings.get(c).map(|&n| (f.frame, n)))
                .filter(|&(_, n)| n > 0)
                .collect();
            let shell = report.characters.iter().find(|r| &r.name == name)?;
            let depth = 0.5 * shell.shell_radius;
            let deep = deep_frames(report, c, depth, true);
            let both = crossed.iter().filter(|(f, _)| deep.contains(f)).count();
            if both == 0 {
                return None;
            }
            let &(worst, most) = crossed.iter().max_by_key(|&&(f, n)| (n, std::cmp::Reverse(f)))?;
            Some(format!(
                "character {name}: its mesh passes through itself in {} frames from frame {} (the most {most} pairs of its triangles, in frame {worst}), and {both} of the {} frames with garment particles more than {:.1} mm (half its shell radius) inside its mesh are among them: one part of the body sinks into another there (a hand into a thigh), and cloth caught between them has no place outside the mesh; character_crossings_per_frame lists the frames and drape inspect the joints; characters[].joint_offsets can spread the limbs clear of the body",
                crossed.len(),
                crossed[0].0,
                deep.len(),
                depth * 1e3,
            ))
        })
        .collect()
}

/// The frames with garment particles more than `depth` inside character `c`'s mesh (in
/// `worst_mesh_penetrations` order): free ones, and held ones too with `held`.
fn deep_frames(
    report: &Report,
    c: usize,
    depth: f32,
    held: bool,
) -> std::collections::BTreeSet<u32> {
    let held = (report.held_mesh_penetrations_per_frame.iter()).filter(|_| held);
    (report.mesh_penetrations_per_frame.iter())
        .chain(held)
        .filter(|f| f.deepest_m.get(c).is_some_and(|&d| d > depth))
        .map(|f| f.frame)
        .collect()
}

/// A warning per character whose mesh sank more than half its shell radius into the scene's
/// colliders (its soles through the floor, its back lying on it) in frames that had free garment
/// particles as deep inside it (cloth pressed against a collider at its contact radius can be
/// that deep inside the body only where the body sinks about that far; RobotExpressive's dance,
/// its feet 4 mm in the floor and its head through its shoulders, is not warned of): cloth pressed between the two is kept out of the collider
/// (`collide::INTO_COLLIDER`), so it is inside the body there, and raising the character or
/// lowering the collider is the user's to do.
fn sunk_warnings(report: &Report) -> Vec<String> {
    let names = report.worst_mesh_penetrations.iter().map(|m| &m.character);
    (names.enumerate())
        .filter_map(|(c, name)| {
            let shell = report.characters.iter().find(|r| &r.name == name)?;
            let depth = 0.5 * shell.shell_radius;
            let sunk: Vec<(u32, f32)> = (report.character_in_colliders_per_frame.iter())
                .filter_map(|f| f.deepest_m.get(c).map(|&d| (f.frame, d)))
                .filter(|&(_, d)| d > depth)
                .collect();
            // Pressed cloth is free: held particles inside follow their targets.
            let deep = deep_frames(report, c, depth, false);
            let both = sunk.iter().filter(|(f, _)| deep.contains(f)).count();
            if both == 0 {
                return None;
            }
            let &(worst, most) = sunk.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
            Some(format!(
                "character {name}: its mesh sinks more than {:.1} mm (half its shell radius) into the scene's colliders in {} frames from frame {} (up to {:.1} mm, in frame {worst}: feet through the floor, a body lying on it), and {both} of the {} frames with free garment particles as deep inside its mesh are among them: cloth pressed between the body and a collider is kept out of the collider, so it is inside the body there; character_in_colliders_per_frame lists the frames; raise the character (characters[].position) or lower the collider",
                depth * 1e3,
                sunk.len(),
                sunk[0].0,
                most * 1e3,
                deep.len(),
            ))
        })
        .collect()
}
